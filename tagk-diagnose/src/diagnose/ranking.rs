//! What is missing: every candidate effect scored on held-out data (blocked
//! cross-validation) and by a partial test, then ranked; the recommendation and its
//! explanation.

use serde::Serialize;

use crate::diagnose::DiagnoseOptions;
use crate::effects::{Effect, EffectRef, usable};
use crate::fit::{
    Coefficient, ColData, Evaluation, Fit, GramEngine, Model, effect_design, rigid_design, scan_min,
};
use crate::signals::{CHANNEL_NAMES, Signals};
use crate::stats;

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
    /// Partial test statistic (chi-square form of the partial F test, effective sample size
    /// corrected for autocorrelation).
    pub statistic: f64,
    /// Degrees of freedom of the test (columns, plus one for a scanned parameter).
    pub dof: usize,
    /// p-value.
    pub p_value: f64,
    /// `p < alpha / candidates`.
    pub significant: bool,
    /// Physical plausibility of the fitted coefficients.
    pub plausible: bool,
    /// Plausibility note.
    pub plausibility_note: String,
    /// Scanned parameter `(name, value, unit)`.
    pub scanned: Option<(String, f64, String)>,
    /// Fitted coefficients (in-sample, all data).
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
}

/// Ranks the candidates of `opts` that are not already in `model` (step 2 of
/// [`crate::diagnose()`]).
pub(crate) fn rank_candidates(
    model: &Model,
    s: &Signals,
    fit: &Fit,
    opts: &DiagnoseOptions,
) -> Ranking {
    let candidates: Vec<&EffectRef> = opts
        .candidates
        .iter()
        .filter(|c| !model.has(c.name()))
        .collect();
    let baseline = baseline(model, s, fit, opts.folds, candidates.len());
    let mut ranking = Vec::new();
    let mut unavailable = Vec::new();
    let mut drivers = Vec::new();
    for e in candidates {
        if let Some(u) = availability(e.as_ref(), model, s) {
            unavailable.push(u);
            continue;
        }
        let (candidate, driver) = score_candidate(e.as_ref(), s, &baseline, opts);
        drivers.push((candidate.effect.clone(), candidate.driver.clone(), driver));
        ranking.push(candidate);
    }
    let recommended = order_and_recommend(&mut ranking, opts);
    let top_driver = ranking.first().and_then(|top| {
        drivers
            .iter()
            .find(|d| d.0 == top.effect)
            .map(|d| (d.1.clone(), d.2.clone()))
    });
    Ranking {
        ranking,
        unavailable,
        recommended,
        top_driver,
    }
}

/// The baseline of the tests: the engine over the fitted model's design and its evaluation
/// without a candidate.
fn baseline<'a>(
    model: &Model,
    s: &'a Signals,
    fit: &Fit,
    folds: usize,
    candidates: usize,
) -> Baseline<'a> {
    let (mut base_cols, _) = rigid_design(model, s);
    for (k, e) in model.effects().iter().enumerate() {
        base_cols.extend(effect_design(e.as_ref(), s, fit.params[k]));
    }
    let engine = GramEngine::new(s, &fit.weights, &base_cols, Some(&fit.residual), folds);
    let evaluation = engine.evaluate(&[]);
    Baseline {
        engine,
        evaluation,
        columns: base_cols.len(),
        tests: candidates.max(1) as f64,
    }
}

/// Why a candidate cannot be evaluated on this log with this model, if it cannot.
fn availability(e: &dyn Effect, model: &Model, s: &Signals) -> Option<Unavailable> {
    if e.needs_known_mass() && model.known_mass().is_none() {
        return Some(Unavailable {
            effect: e.name().to_string(),
            reason: "needs a known mass (`--mass KG`): a thrust-gain error and a mass error scale the regression alike".into(),
        });
    }
    usable(e, s).err().map(|reason| Unavailable {
        effect: e.name().to_string(),
        reason,
    })
}

/// The candidate's columns at its best scanned parameter (if it has one) and their
/// evaluation.
fn best_design(
    e: &dyn Effect,
    s: &Signals,
    engine: &GramEngine<'_>,
) -> (Option<f64>, Vec<ColData>, Evaluation) {
    match e.scan() {
        None => {
            let cols = effect_design(e, s, None);
            let ev = engine.evaluate(&cols);
            (None, cols, ev)
        }
        Some(sp) => {
            let (g, _) = scan_min(&sp.grid, |g| {
                engine.evaluate(&effect_design(e, s, Some(g))).sse_full
            });
            let cols = effect_design(e, s, Some(g));
            let ev = engine.evaluate(&cols);
            (Some(g), cols, ev)
        }
    }
}

/// Scores one candidate: held-out reduction (overall and per channel), the partial test
/// with an autocorrelation-corrected variance, coefficients with standard errors and the
/// plausibility verdict. The explanation is filled in by [`order_and_recommend`]. Also
/// returns the series of the candidate's driving signal (for plots).
fn score_candidate(
    e: &dyn Effect,
    s: &Signals,
    base: &Baseline<'_>,
    opts: &DiagnoseOptions,
) -> (Candidate, Vec<f64>) {
    let spec = e.scan();
    let (param, cols, ev) = best_design(e, s, &base.engine);
    let base_ev = &base.evaluation;
    let p_base = base.columns;
    let rows = (6 * s.len()) as f64;
    let q = cols.len();
    let dof = q + usize::from(spec.is_some());
    let res = base.engine.residual(&cols, &ev.beta);
    let mut kappa = 0.0;
    for c in 0..6 {
        let r: Vec<f64> = res.iter().map(|x| x[c]).collect();
        kappa += stats::batch_means_factor(&r);
    }
    kappa /= 6.0;
    let p_tot = (p_base + q) as f64;
    let sigma2 = ev.sse_full / (rows - p_tot).max(1.0);
    let drop = (base_ev.sse_full - ev.sse_full).max(0.0);
    let statistic = if sigma2 > 0.0 {
        drop / (kappa * sigma2)
    } else {
        f64::INFINITY
    };
    let p_value = stats::chi2_survival(statistic, dof as f64);
    let reduction = if base_ev.sse_cv > 0.0 {
        1.0 - ev.sse_cv / base_ev.sse_cv
    } else {
        0.0
    };
    let reduction_per_channel: Vec<f64> = (0..6)
        .map(|c| {
            if base_ev.sse_cv_ch[c] > 0.0 {
                1.0 - ev.sse_cv_ch[c] / base_ev.sse_cv_ch[c]
            } else {
                0.0
            }
        })
        .collect();
    let coef: Vec<f64> = ev.beta[p_base..].to_vec();
    let se: Vec<f64> = ev.cov_diag[p_base..]
        .iter()
        .map(|d| (d * sigma2 * kappa).sqrt())
        .collect();
    let pl = e.plausibility(&coef, &se, param);
    let ecols = e.columns(s, param);
    let coefficients: Vec<Coefficient> = ecols
        .iter()
        .enumerate()
        .map(|(i, c)| Coefficient {
            name: c.name.clone(),
            unit: c.unit.clone(),
            value: coef[i],
            std_error: se[i].is_finite().then_some(se[i]),
        })
        .collect();
    let affected: Vec<String> = (0..6)
        .filter(|&c| reduction_per_channel[c] >= 0.3)
        .map(|c| CHANNEL_NAMES[c].to_string())
        .collect();
    let significant = p_value < opts.alpha / base.tests;
    let scanned = spec.map(|sp| (sp.name, param.unwrap_or(f64::NAN), sp.unit));
    let (dname, dsig) = e.driver(s);
    let candidate = Candidate {
        effect: e.name().to_string(),
        reduction,
        reduction_per_channel,
        statistic,
        dof,
        p_value,
        significant,
        plausible: pl.plausible,
        plausibility_note: pl.note,
        scanned,
        coefficients,
        affected_channels: affected,
        explanation: String::new(),
        driver: dname,
    };
    (candidate, dsig)
}

/// Orders the ranking — recommendable candidates (significant, plausible, large enough)
/// first, then by held-out reduction — and writes each candidate's explanation. Returns the
/// recommended effect: the first recommendable candidate.
fn order_and_recommend(ranking: &mut [Candidate], opts: &DiagnoseOptions) -> Option<String> {
    let recommendable =
        |c: &Candidate| c.significant && c.plausible && c.reduction >= opts.min_reduction;
    ranking.sort_by(|a, b| {
        recommendable(b)
            .cmp(&recommendable(a))
            .then(b.reduction.total_cmp(&a.reduction))
    });
    let recommended = ranking
        .iter()
        .find(|c| recommendable(c))
        .map(|c| c.effect.clone());
    for c in ranking.iter_mut() {
        c.explanation = explain(c, opts, recommended.as_deref() == Some(c.effect.as_str()));
    }
    recommended
}

/// The one-line explanation of a scored candidate (held-out change, coefficients, status).
fn explain(c: &Candidate, opts: &DiagnoseOptions, recommended: bool) -> String {
    let chans = if c.affected_channels.is_empty() {
        String::new()
    } else {
        let per: Vec<String> = c
            .affected_channels
            .iter()
            .map(|ch| {
                let k = CHANNEL_NAMES.iter().position(|n| n == ch).unwrap_or(0);
                format!("{ch} {:+.0} %", -c.reduction_per_channel[k] * 100.0)
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
    let status = if recommended {
        "RECOMMENDED".to_string()
    } else if !c.significant {
        format!("not significant (p = {:.2e})", c.p_value)
    } else if !c.plausible {
        format!("implausible: {}", c.plausibility_note)
    } else if c.reduction < opts.min_reduction {
        "significant but too small to matter".to_string()
    } else {
        "significant, explains less than the top candidate".to_string()
    };
    format!(
        "{}: held-out residual {:+.1} %{}; {}{}; {}",
        c.effect,
        -c.reduction * 100.0,
        chans,
        coefs.join(", "),
        scan,
        status
    )
}
