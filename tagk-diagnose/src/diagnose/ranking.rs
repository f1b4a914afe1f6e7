//! What is missing: every candidate effect scored on held-out data (blocked
//! cross-validation) and by a partial test, then ranked; the recommendation and its
//! explanation.

use serde::Serialize;

use crate::diagnose::DiagnoseOptions;
use crate::diagnose::floor::{ModelDesign, NoiseFloor, held_out_rms, model_design};
use crate::diagnose::sanity::{SanityContext, check_refit};
use crate::effects::{Effect, EffectRef};
use crate::fit::{
    Coefficient, EffectDesign, Evaluation, Fit, GramEngine, Model, checked_effect_design,
    sampled_effect_design, scan_min,
};
use crate::format::change_percent;
use crate::signals::{CHANNEL_NAMES, Signals};
use crate::stats;

/// Where a scored candidate stands (the first that applies, in this order).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum CandidateStatus {
    /// The next step: qualifies and has the largest held-out gain.
    Recommended,
    /// Qualifies, but gains less than the recommended candidate.
    Qualifies,
    /// Makes the held-out residual worse.
    Worse,
    /// Its refit breaks a physical rule (the effect's own or the rigid body's).
    Implausible,
    /// Makes some channel's held-out RMS worse by more than [`MAX_CHANNEL_WORSENING`].
    WorsensChannel,
    /// Its gain fails the partial test (Bonferroni over the candidates).
    NotSignificant,
    /// The model is already at the noise floor on every channel.
    AtFloor,
    /// Its held-out gain is below the noise floor on every channel (or below
    /// `min_reduction` overall).
    BelowFloor,
}

impl CandidateStatus {
    /// `true` for a candidate that may be the next step.
    pub fn qualifies(self) -> bool {
        matches!(
            self,
            CandidateStatus::Recommended | CandidateStatus::Qualifies
        )
    }
}

/// Largest worsening of one channel's held-out RMS a step may cause (10 %), to above the
/// channel's noise floor (below the floor a change is noise).
pub const MAX_CHANNEL_WORSENING: f64 = 0.10;

/// `true` when a channel's held-out RMS going from `current` to `new` is a worsening that
/// counts: by more than [`MAX_CHANNEL_WORSENING`], to above the channel's floor (`floor` ×
/// (1 + [`FLOOR_MARGIN`])); below the floor a change is noise.
pub(crate) fn worsens(new: f64, current: f64, floor: f64) -> bool {
    new > (1.0 + MAX_CHANNEL_WORSENING) * current && new > (1.0 + FLOOR_MARGIN) * floor
}

/// Smallest gain worth a step: it must lower some channel's held-out RMS by at least this
/// fraction of that channel's noise floor (5 %).
pub const MIN_GAIN_OF_FLOOR: f64 = 0.05;

/// A model is at the noise floor when every channel's held-out RMS is within this fraction
/// above the floor (5 %).
pub const FLOOR_MARGIN: f64 = 0.05;

/// A ranked candidate effect.
#[derive(Debug, Clone, Serialize)]
pub struct Candidate {
    /// Effect name.
    pub effect: String,
    /// Held-out (blocked CV) reduction of the channel-normalised residual sum of squares,
    /// as a fraction (negative: it makes predictions worse).
    pub reduction: f64,
    /// Held-out reduction per channel (fraction).
    pub reduction_per_channel: Vec<f64>,
    /// Held-out residual RMS per channel with the candidate added (N, N m).
    pub held_out_rms: [f64; 6],
    /// Held-out gain in units of the noise floor: `Σ_c (rms_c² − rms_c,with²) / floor_c²`.
    pub gain_over_floor: f64,
    /// Channels whose held-out RMS grows by more than [`MAX_CHANNEL_WORSENING`] to above the
    /// floor.
    pub worsened_channels: Vec<String>,
    /// Partial test statistic (chi-square form of the partial F test, effective sample size
    /// corrected for autocorrelation).
    pub statistic: f64,
    /// Degrees of freedom of the test (columns, plus one for a scanned parameter).
    pub dof: usize,
    /// p-value.
    pub p_value: f64,
    /// `p < alpha / candidates`.
    pub significant: bool,
    /// Physical plausibility of the refit (the effect's rules and the rigid body's).
    pub plausible: bool,
    /// The rule that fired when implausible (e.g. `mass-change`, `negative-coefficient`).
    pub rule: Option<String>,
    /// Plausibility note.
    pub plausibility_note: String,
    /// Where the candidate stands.
    pub status: CandidateStatus,
    /// Scanned parameter `(name, value, unit)`.
    pub scanned: Option<(String, f64, String)>,
    /// Fitted coefficients (in-sample, all data), with 95 % confidence intervals.
    pub coefficients: Vec<Coefficient>,
    /// Channels whose held-out residual falls by at least 30 %.
    pub affected_channels: Vec<String>,
    /// One-line explanation.
    pub explanation: String,
    /// Signal the effect is driven by (name), for plots.
    pub driver: String,
}

/// A candidate that could not be evaluated on this log.
#[derive(Debug, Clone, Serialize)]
pub struct Unavailable {
    /// Effect name.
    pub effect: String,
    /// Why.
    pub reason: String,
}

/// The outcome of [`rank_candidates`].
pub(crate) struct Ranking {
    /// Scored candidates, best first.
    pub ranking: Vec<Candidate>,
    /// Candidates that could not be evaluated.
    pub unavailable: Vec<Unavailable>,
    /// The recommended effect, if any.
    pub recommended: Option<String>,
    /// The top candidate's driving signal `(name, series)`.
    pub top_driver: Option<(String, Vec<f64>)>,
    /// Held-out residual RMS per channel of the model itself.
    pub held_out_rms: [f64; 6],
    /// `true` when every channel's held-out RMS is within [`FLOOR_MARGIN`] of the floor.
    pub at_floor: bool,
}

/// The model's design and the Gram engine of the candidates' tests: the fitted model's
/// columns (at its scanned parameters) against the fit's residual, so that a candidate's
/// coefficients come after the base corrections.
struct Baseline<'a> {
    engine: GramEngine<'a>,
    evaluation: Evaluation,
    /// Columns of the model's design.
    columns: usize,
    /// Number of candidates tested (Bonferroni divisor).
    tests: f64,
    /// Held-out RMS per channel of the model.
    held_out_rms: [f64; 6],
    /// The physical rules' context.
    sanity: SanityContext<'a>,
}

/// Scored candidates before they are judged against a noise floor ([`score_candidates`]).
pub(crate) struct Scored {
    /// Scored candidates (status not yet set).
    pub ranking: Vec<Candidate>,
    /// Candidates that could not be evaluated.
    pub unavailable: Vec<Unavailable>,
    /// The scored candidates' effects (the top one's driving signal is computed once the
    /// ranking is judged, not kept for every candidate).
    effects: Vec<EffectRef>,
    /// Held-out residual RMS per channel of the model itself.
    pub held_out_rms: [f64; 6],
}

/// Scores the candidates of `opts` that are not already in `model`: held-out gains, tests,
/// coefficients and plausibility; the floor-dependent statuses come from [`judge_scored`].
pub(crate) fn score_candidates(
    model: &Model,
    s: &Signals,
    fit: &Fit,
    opts: &DiagnoseOptions,
) -> Scored {
    let candidates: Vec<&EffectRef> = opts
        .candidates
        .iter()
        .filter(|c| !model.has(c.name()))
        .collect();
    let design = model_design(model, s, fit);
    let baseline = baseline(model, s, fit, opts, &design, candidates.len());
    let mut ranking = Vec::new();
    let mut unavailable = Vec::new();
    let mut effects = Vec::new();
    for e in candidates {
        if let Some(u) = availability(e.as_ref(), model, s) {
            unavailable.push(u);
            continue;
        }
        match score_candidate(e.as_ref(), s, &baseline, opts) {
            Ok(candidate) => {
                effects.push(e.clone());
                ranking.push(candidate);
            }
            Err(reason) => unavailable.push(Unavailable {
                effect: e.name().to_string(),
                reason,
            }),
        }
    }
    Scored {
        ranking,
        unavailable,
        effects,
        held_out_rms: baseline.held_out_rms,
    }
}

/// Judges scored candidates against the noise floor `floor`: statuses, order, the
/// recommendation, explanations, and the top candidate's driving signal on `s`.
pub(crate) fn judge_scored(
    scored: Scored,
    s: &Signals,
    floor: &NoiseFloor,
    opts: &DiagnoseOptions,
) -> Ranking {
    let Scored {
        mut ranking,
        unavailable,
        effects,
        held_out_rms,
    } = scored;
    for c in ranking.iter_mut() {
        c.worsened_channels = (0..6)
            .filter(|&k| worsens(c.held_out_rms[k], held_out_rms[k], floor.rms[k]))
            .map(|k| CHANNEL_NAMES[k].to_string())
            .collect();
        c.gain_over_floor = (0..6)
            .map(|k| {
                if floor.rms[k] > 0.0 {
                    (held_out_rms[k].powi(2) - c.held_out_rms[k].powi(2)) / floor.rms[k].powi(2)
                } else {
                    0.0
                }
            })
            .sum();
    }
    let at_floor = (0..6).all(|c| held_out_rms[c] <= (1.0 + FLOOR_MARGIN) * floor.rms[c]);
    let recommended = judge(&mut ranking, &held_out_rms, floor, opts, at_floor);
    let top_driver = ranking.first().and_then(|top| {
        effects
            .iter()
            .find(|e| e.name() == top.effect)
            .map(|e| e.driver(s))
    });
    Ranking {
        ranking,
        unavailable,
        recommended,
        top_driver,
        held_out_rms,
        at_floor,
    }
}

/// Ranks the candidates of `opts` that are not already in `model` against the noise floor
/// `floor` (step 2 of [`crate::diagnose()`]): [`score_candidates`] then [`judge_scored`].
pub(crate) fn rank_candidates(
    model: &Model,
    s: &Signals,
    fit: &Fit,
    opts: &DiagnoseOptions,
    floor: &NoiseFloor,
) -> Ranking {
    judge_scored(score_candidates(model, s, fit, opts), s, floor, opts)
}

/// The baseline of the tests: the engine over the fitted model's design
/// ([`model_design`], borrowed by the engine) and its evaluation without a candidate.
fn baseline<'a>(
    model: &Model,
    s: &'a Signals,
    fit: &'a Fit,
    opts: &DiagnoseOptions,
    design: &'a ModelDesign,
    candidates: usize,
) -> Baseline<'a> {
    let base_cols = design.columns();
    let engine = GramEngine::new(s, &fit.weights, &base_cols, Some(&fit.residual), opts.folds);
    let evaluation = engine.evaluate(&[]);
    let held_out_rms = held_out_rms(&evaluation, &fit.weights, s.len());
    let mean_thrust = s.wrench().iter().map(|b| b[2]).sum::<f64>() / s.len().max(1) as f64;
    Baseline {
        engine,
        evaluation,
        columns: base_cols.len(),
        tests: candidates.max(1) as f64,
        held_out_rms,
        sanity: SanityContext {
            fit,
            mean_thrust,
            airframe_radius: opts.airframe_radius,
            known_mass: model.known_mass().is_some(),
        },
    }
}

/// Why a candidate cannot be evaluated with this model or fails its own check on this log,
/// if it does (its columns are checked where they are computed: [`best_design`]).
fn availability(e: &dyn Effect, model: &Model, s: &Signals) -> Option<Unavailable> {
    let reason = if e.needs_known_mass() && model.known_mass().is_none() {
        "needs a known mass (`--mass KG`): a thrust-gain error and a mass error scale the regression alike".into()
    } else {
        e.check(s).err()?
    };
    Some(Unavailable {
        effect: e.name().to_string(),
        reason,
    })
}

/// The candidate's columns at its best scanned parameter (if it has one) and their
/// evaluation; `Err(reason)` when its columns there cannot enter the regression
/// ([`crate::effects::check_columns`]; a scanned value whose columns have the wrong length is
/// skipped by the scan).
fn best_design(
    e: &dyn Effect,
    s: &Signals,
    engine: &GramEngine<'_>,
) -> Result<(Option<f64>, EffectDesign, Evaluation), String> {
    let param = e.scan().map(|sp| {
        let scan = engine.for_scan();
        scan_min(&sp.grid, |g| {
            sampled_effect_design(e, s, Some(g), scan.stride()).map_or(f64::INFINITY, |d| {
                scan.evaluate_sampled(&d.cols, d.offset.as_ref()).sse_full
            })
        })
        .0
    });
    let d = checked_effect_design(e, s, param)?;
    let ev = engine.evaluate_with(&d.cols, d.offset.as_ref());
    Ok((param, d, ev))
}

/// Scores one candidate: held-out reduction (overall and per channel, and against the noise
/// floor), the partial test with an autocorrelation-corrected variance, coefficients with
/// standard errors and confidence intervals, the plausibility verdict (the effect's rules,
/// then the rigid body's, [`crate::diagnose`]'s sanity rules). The status and explanation are
/// filled in by [`order_and_recommend`]. `Err(reason)` when the candidate's columns cannot
/// enter the regression on this log ([`best_design`]).
fn score_candidate(
    e: &dyn Effect,
    s: &Signals,
    base: &Baseline<'_>,
    opts: &DiagnoseOptions,
) -> Result<Candidate, String> {
    let spec = e.scan();
    let (param, design, ev) = best_design(e, s, &base.engine)?;
    let cols = &design.cols;
    let base_ev = &base.evaluation;
    let p_base = base.columns;
    let rows = (6 * s.len()) as f64;
    let q = cols.len();
    let dof = q + usize::from(spec.is_some());
    let reduction = if base_ev.sse_cv > 0.0 {
        1.0 - ev.sse_cv / base_ev.sse_cv
    } else {
        0.0
    };
    // The autocorrelation factor of the candidate's residual; a candidate that makes the
    // held-out residual worse is judged `worse` whatever its test says, so its test uses the
    // current fit's factor instead of a residual of its own.
    let kappa = if reduction < 0.0 {
        base.sanity.fit.kappa
    } else {
        let res = base.engine.residual(cols, design.offset.as_ref(), &ev.beta);
        (0..6)
            .map(|c| {
                let r: Vec<f64> = res.iter().map(|x| x[c]).collect();
                stats::batch_means_factor(&r)
            })
            .sum::<f64>()
            / 6.0
    };
    let p_tot = (p_base + q) as f64;
    let sigma2 = ev.sse_full / (rows - p_tot).max(1.0);
    let drop = (base_ev.sse_full - ev.sse_full).max(0.0);
    let statistic = if sigma2 > 0.0 {
        drop / (kappa * sigma2)
    } else {
        f64::INFINITY
    };
    let p_value = stats::chi2_survival(statistic, dof as f64);
    let reduction_per_channel: Vec<f64> = (0..6)
        .map(|c| {
            if base_ev.sse_cv_ch[c] > 0.0 {
                1.0 - ev.sse_cv_ch[c] / base_ev.sse_cv_ch[c]
            } else {
                0.0
            }
        })
        .collect();
    let held_out = held_out_rms(&ev, &base.sanity.fit.weights, s.len());
    let coef: Vec<f64> = ev.beta[p_base..].to_vec();
    let se: Vec<f64> = ev.cov_diag[p_base..]
        .iter()
        .map(|d| (d * sigma2 * kappa).sqrt())
        .collect();
    let coefficients: Vec<Coefficient> = design
        .names
        .iter()
        .enumerate()
        .map(|(i, (name, unit))| {
            Coefficient::new(name, unit, coef[i], se[i].is_finite().then_some(se[i]))
        })
        .collect();
    let own = e.plausibility(&coef, &se, param);
    let (plausible, rule, note) = if !own.plausible {
        (false, Some(own.rule.clone()), own.note)
    } else {
        // The rigid-body corrections of the refit are the first coefficients after the
        // target: the rigid columns come first in the model's design.
        let nr = 10 - usize::from(base.sanity.known_mass);
        match check_refit(&base.sanity, &ev.beta[..nr], &coefficients) {
            Some(v) => (false, Some(v.rule.to_string()), v.note),
            None => (true, None, own.note),
        }
    };
    let affected: Vec<String> = (0..6)
        .filter(|&c| reduction_per_channel[c] >= 0.3)
        .map(|c| CHANNEL_NAMES[c].to_string())
        .collect();
    let significant = p_value < opts.alpha / base.tests;
    let scanned = spec.map(|sp| {
        (
            sp.name,
            param.map_or(f64::NAN, |p| e.applied(s, p)),
            sp.unit,
        )
    });
    let (dname, _) = e.driver(s);
    Ok(Candidate {
        effect: e.name().to_string(),
        reduction,
        reduction_per_channel,
        held_out_rms: held_out,
        gain_over_floor: 0.0,
        worsened_channels: Vec::new(),
        statistic,
        dof,
        p_value,
        significant,
        plausible,
        rule,
        plausibility_note: note,
        status: CandidateStatus::BelowFloor,
        scanned,
        coefficients,
        affected_channels: affected,
        explanation: String::new(),
        driver: dname,
    })
}

/// The status of a scored candidate before the recommendation is picked (the first rule
/// that applies, in the order of [`CandidateStatus`]).
fn status_of(
    c: &Candidate,
    base_rms: &[f64; 6],
    floor: &NoiseFloor,
    opts: &DiagnoseOptions,
    at_floor: bool,
) -> CandidateStatus {
    if c.reduction < 0.0 {
        return CandidateStatus::Worse;
    }
    if !c.plausible {
        return CandidateStatus::Implausible;
    }
    if !c.worsened_channels.is_empty() {
        return CandidateStatus::WorsensChannel;
    }
    if !c.significant {
        return CandidateStatus::NotSignificant;
    }
    if at_floor {
        return CandidateStatus::AtFloor;
    }
    let above_floor = (0..6).any(|k| {
        floor.rms[k] > 0.0 && base_rms[k] - c.held_out_rms[k] >= MIN_GAIN_OF_FLOOR * floor.rms[k]
    });
    if !above_floor || c.reduction < opts.min_reduction {
        return CandidateStatus::BelowFloor;
    }
    CandidateStatus::Qualifies
}

/// Orders the ranking — qualifying candidates first, then by held-out reduction (each channel
/// normalised by the current model's residual) —
/// and writes each candidate's status and explanation. Returns the recommended effect: the
/// first qualifying candidate.
fn order_and_recommend(
    ranking: &mut [Candidate],
    opts: &DiagnoseOptions,
    at_floor: bool,
) -> Option<String> {
    ranking.sort_by(|a, b| {
        b.status
            .qualifies()
            .cmp(&a.status.qualifies())
            .then(b.reduction.total_cmp(&a.reduction))
    });
    let recommended = ranking
        .iter()
        .find(|c| c.status.qualifies())
        .map(|c| c.effect.clone());
    if let Some(first) = ranking.first_mut()
        && first.status.qualifies()
    {
        first.status = CandidateStatus::Recommended;
    }
    for c in ranking.iter_mut() {
        c.explanation = explain(c, opts, at_floor);
    }
    recommended
}

/// Sets every candidate's status (needs the model's held-out RMS and the floor), then orders
/// and recommends ([`order_and_recommend`]).
fn judge(
    ranking: &mut [Candidate],
    base_rms: &[f64; 6],
    floor: &NoiseFloor,
    opts: &DiagnoseOptions,
    at_floor: bool,
) -> Option<String> {
    for c in ranking.iter_mut() {
        c.status = status_of(c, base_rms, floor, opts, at_floor);
    }
    order_and_recommend(ranking, opts, at_floor)
}

/// The one-line explanation of a scored candidate (held-out change, coefficients, status).
fn explain(c: &Candidate, _opts: &DiagnoseOptions, _at_floor: bool) -> String {
    let chans = if c.affected_channels.is_empty() {
        String::new()
    } else {
        let per: Vec<String> = c
            .affected_channels
            .iter()
            .map(|ch| {
                let k = CHANNEL_NAMES.iter().position(|n| n == ch).unwrap_or(0);
                format!("{ch} {}", change_percent(-c.reduction_per_channel[k], 0))
            })
            .collect();
        format!(" ({})", per.join(", "))
    };
    let coefs: Vec<String> = c
        .coefficients
        .iter()
        .take(3)
        .map(|k| format!("{} = {:.3e} {}", k.name, k.value, k.unit))
        .collect();
    let scan = c
        .scanned
        .as_ref()
        .map(|(n, v, u)| format!(", {n} = {v:.3} {u}"))
        .unwrap_or_default();
    let status = match c.status {
        CandidateStatus::Recommended => "RECOMMENDED".to_string(),
        CandidateStatus::Qualifies => "qualifies, gains less than the recommended one".to_string(),
        CandidateStatus::Worse => "worse: it raises the held-out residual".to_string(),
        CandidateStatus::Implausible => format!(
            "implausible ({}): {}",
            c.rule.as_deref().unwrap_or("rule"),
            c.plausibility_note
        ),
        CandidateStatus::WorsensChannel => format!(
            "rejected: held-out RMS of {} worse by more than {:.0} %",
            c.worsened_channels.join(", "),
            100.0 * MAX_CHANNEL_WORSENING
        ),
        CandidateStatus::NotSignificant => format!("not significant (p = {:.2e})", c.p_value),
        CandidateStatus::AtFloor => "not needed: the model is at the noise floor".to_string(),
        CandidateStatus::BelowFloor => "gain below the noise floor".to_string(),
    };
    // Coefficients and the scanned value (either may be absent), comma separated.
    let mut fitted = coefs;
    fitted.extend(scan.strip_prefix(", ").map(str::to_string));
    format!(
        "{}: held-out residual {}{}; {}; {}",
        c.effect,
        change_percent(-c.reduction, 1),
        chans,
        fitted.join(", "),
        status
    )
}
