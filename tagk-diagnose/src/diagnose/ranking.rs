//! What is missing: every candidate effect alone, as the search scored it
//! ([`crate::diagnose::select`]), with its status, coefficients and explanation; the
//! recommended set; the scanned parameters' intervals of a fitted model.

use serde::Serialize;

use crate::diagnose::select::{Context, Member, Refusal, Search, SetEval};
use crate::diagnose::{Confounding, DiagnoseOptions, separation_advice};
use crate::fit::{Coefficient, Fit, Model, is_start_nuisance};
use crate::format::change_percent;
use crate::signals::{CHANNEL_NAMES, Signals};

/// Where a scored candidate stands (the first that applies, in this order).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum CandidateStatus {
    /// A member of the set the search adds next.
    Recommended,
    /// Admissible alone, but the recommended set explains more.
    Qualifies,
    /// Makes the held-out error worse.
    Worse,
    /// Its refit breaks a physical rule (the effect's own or the rigid body's).
    Implausible,
    /// Its scanned parameter's best value lies at an end of its range: outside the range the
    /// data support.
    OutOfRange,
    /// The data cannot tell it apart from the rigid body's parameters (variance inflation
    /// beyond [`crate::MAX_INFLATION`]).
    Confounded,
    /// Its gain fails the significance test (Bonferroni over the candidates).
    NotSignificant,
    /// Its held-out gain is below [`crate::MIN_GAIN`] of a channel's noise variance.
    TooSmall,
}

impl CandidateStatus {
    /// `true` for a candidate that may be part of the next step.
    pub fn qualifies(self) -> bool {
        matches!(
            self,
            CandidateStatus::Recommended | CandidateStatus::Qualifies
        )
    }
}

/// A ranked candidate effect (scored alone against the model).
#[derive(Debug, Clone, Serialize)]
pub struct Candidate {
    /// Effect name.
    pub effect: String,
    /// Held-out reduction of the error in units of the noise (`1 − S_with / S_model`), as a
    /// fraction (negative: it makes predictions worse).
    pub reduction: f64,
    /// Held-out reduction per channel (fraction).
    pub reduction_per_channel: Vec<f64>,
    /// Held-out residual RMS per channel with the candidate added (N, N m).
    pub held_out_rms: [f64; 6],
    /// Held-out gain per sample in units of the noise variance (`Σ_c Δ SSE_c / σ_c² / n`).
    pub gain: f64,
    /// Significance test statistic (χ² form, scaled by the residual variance and its
    /// autocorrelation factor).
    pub statistic: f64,
    /// Degrees of freedom of the test (columns, plus one for a scanned parameter).
    pub dof: usize,
    /// p-value.
    pub p_value: f64,
    /// Passes the test at the family-wise level.
    pub significant: bool,
    /// Physical plausibility of the refit (the effect's rules and the rigid body's).
    pub plausible: bool,
    /// The rule that fired when implausible (e.g. `mass-change`, `negative-coefficient`).
    pub rule: Option<String>,
    /// Plausibility note.
    pub plausibility_note: String,
    /// Smallest variance inflation of its coefficients against the model's columns (large
    /// when the data cannot tell the effect from them).
    pub inflation: f64,
    /// Where the candidate stands.
    pub status: CandidateStatus,
    /// Scanned parameter `(name, value, unit)`.
    pub scanned: Option<(String, f64, String)>,
    /// 95 % profile interval of the scanned parameter (its unit).
    pub scanned_interval: Option<[f64; 2]>,
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

/// The outcome of [`rank`].
#[derive(Debug, Clone, Default)]
pub(crate) struct Ranking {
    /// Scored candidates, best first.
    pub ranking: Vec<Candidate>,
    /// Candidates that could not be evaluated.
    pub unavailable: Vec<Unavailable>,
    /// The recommended set, in staircase order (empty: none admissible).
    pub recommended: Vec<String>,
    /// The recommended set's held-out reduction (fraction, noise units).
    pub set_reduction: f64,
    /// Pairs the data cannot tell apart.
    pub confounded: Vec<Confounding>,
    /// Other sets that explain the data as well.
    pub alternatives: Vec<Vec<String>>,
    /// The top candidate's driving signal `(name, series)`.
    pub top_driver: Option<(String, Vec<f64>)>,
}

/// The ranking of a search: each candidate alone with its status, best first (qualifying
/// first, then by held-out reduction).
pub(crate) fn rank(ctx: &Context<'_>, found: &Search, opts: &DiagnoseOptions) -> Ranking {
    let s = ctx.s;
    let recommended: Vec<String> = found
        .chosen
        .as_ref()
        .map(SetEval::names)
        .unwrap_or_default();
    let mut ranking: Vec<Candidate> = found
        .singles
        .iter()
        .map(|set| candidate(ctx, found, set, &recommended))
        .collect();
    ranking.sort_by(|a, b| {
        let rank = |c: &Candidate| match c.status {
            CandidateStatus::Recommended => 0,
            CandidateStatus::Qualifies => 1,
            _ => 2,
        };
        rank(a)
            .cmp(&rank(b))
            .then(b.reduction.total_cmp(&a.reduction))
    });
    for c in ranking.iter_mut() {
        c.explanation = explain(c);
    }
    let top_driver = ranking.first().and_then(|top| {
        opts.candidates
            .iter()
            .find(|e| e.name() == top.effect)
            .map(|e| e.driver(s))
    });
    let set_reduction = found.chosen.as_ref().map_or(0.0, |c| {
        if found.base.cv > 0.0 {
            c.gain / found.base.cv
        } else {
            0.0
        }
    });
    let mut confounded: Vec<Confounding> = found
        .confounded
        .iter()
        .map(|(a, b, inflation)| Confounding {
            effects: [a.clone(), b.clone()],
            inflation: *inflation,
            advice: separation_advice(a, b),
        })
        .collect();
    for c in &ranking {
        if c.status == CandidateStatus::Confounded {
            confounded.push(Confounding {
                effects: [c.effect.clone(), "rigid body".into()],
                inflation: c.inflation,
                advice: separation_advice(&c.effect, "rigid body"),
            });
        }
    }
    Ranking {
        ranking,
        unavailable: found
            .unavailable
            .iter()
            .map(|(e, r)| Unavailable {
                effect: e.clone(),
                reason: r.clone(),
            })
            .collect(),
        recommended,
        set_reduction,
        confounded,
        alternatives: found.alternatives.iter().map(SetEval::names).collect(),
        top_driver,
    }
}

/// One candidate alone, from its scored set.
fn candidate(
    ctx: &Context<'_>,
    found: &Search,
    set: &SetEval,
    recommended: &[String],
) -> Candidate {
    let s = ctx.s;
    let m: &Member = &set.members[0];
    let v = &set.verdicts[0];
    let e = &m.effect;
    let n = s.len().max(1) as f64;
    let base = &found.base;
    let reduction = if base.cv > 0.0 {
        1.0 - set.score.cv / base.cv
    } else {
        0.0
    };
    let reduction_per_channel: Vec<f64> = (0..6)
        .map(|c| {
            if base.cv_ch[c] > 0.0 {
                1.0 - set.score.cv_ch[c] / base.cv_ch[c]
            } else {
                0.0
            }
        })
        .collect();
    let coefficients: Vec<Coefficient> = set.score.names[0]
        .iter()
        .enumerate()
        .map(|(i, (name, unit))| {
            Coefficient::new(
                name,
                unit,
                v.coef[i],
                v.se[i].is_finite().then_some(v.se[i]),
            )
        })
        .collect();
    let in_set = recommended.iter().any(|r| r == e.name());
    let status = if in_set {
        CandidateStatus::Recommended
    } else {
        match &v.refusal {
            None => CandidateStatus::Qualifies,
            Some(Refusal::Worse) => CandidateStatus::Worse,
            Some(Refusal::Implausible(_)) => CandidateStatus::Implausible,
            Some(Refusal::OutOfRange { .. }) => CandidateStatus::OutOfRange,
            Some(Refusal::Confounded { .. }) => CandidateStatus::Confounded,
            Some(Refusal::NotSignificant { .. }) => CandidateStatus::NotSignificant,
            Some(Refusal::Small { .. }) => CandidateStatus::TooSmall,
        }
    };
    let (plausible, rule, note) = match &v.refusal {
        Some(Refusal::Implausible(viol)) => (false, Some(viol.rule.clone()), viol.note.clone()),
        Some(Refusal::OutOfRange { value, lo, hi }) => (
            true,
            None,
            format!(
                "its best value {value:.3} lies at the end of the range {lo:.3}–{hi:.3} it was scanned over: outside the range the data support"
            ),
        ),
        Some(Refusal::Confounded { with, inflation }) => (
            true,
            None,
            format!(
                "cannot be told apart from {with} on this log (variance inflation {inflation:.0})"
            ),
        ),
        _ => (true, None, String::new()),
    };
    let scale = set.score.effect_scale(e.as_ref(), s.len() as f64);
    let scanned = e.scan().map(|sp| {
        (
            sp.name,
            m.param.map_or(f64::NAN, |p| e.applied(s, p)),
            sp.unit,
        )
    });
    let scanned_interval = set.scans[0].interval(scale);
    let affected: Vec<String> = (0..6)
        .filter(|&c| reduction_per_channel[c] >= 0.3)
        .map(|c| CHANNEL_NAMES[c].to_string())
        .collect();
    let significant =
        !matches!(v.refusal, Some(Refusal::NotSignificant { .. })) && v.p_value.is_finite();
    Candidate {
        effect: e.name().to_string(),
        reduction,
        reduction_per_channel,
        held_out_rms: ctx.held_out_rms(&set.score),
        gain: set.gain / n,
        statistic: v.statistic,
        dof: v.dof,
        p_value: v.p_value,
        significant,
        plausible,
        rule,
        plausibility_note: note,
        inflation: v.inflation,
        status,
        scanned,
        scanned_interval,
        coefficients,
        affected_channels: affected,
        explanation: String::new(),
        driver: e.driver(s).0,
    }
}

/// The one-line explanation of a scored candidate (held-out change, coefficients, status).
fn explain(c: &Candidate) -> String {
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
        .filter(|k| !is_start_nuisance(&k.name))
        .take(3)
        .map(|k| format!("{} = {:.3e} {}", k.name, k.value, k.unit))
        .collect();
    let scan = c
        .scanned
        .as_ref()
        .map(|(n, v, u)| match c.scanned_interval {
            Some([lo, hi]) => format!(", {n} = {v:.3} {u} [{lo:.3}, {hi:.3}]"),
            None => format!(", {n} = {v:.3} {u}"),
        })
        .unwrap_or_default();
    let status = match c.status {
        CandidateStatus::Recommended => "RECOMMENDED".to_string(),
        CandidateStatus::Qualifies => {
            "qualifies alone; the recommended set explains more".to_string()
        }
        CandidateStatus::Worse => "worse: it raises the held-out error".to_string(),
        CandidateStatus::Implausible => format!(
            "implausible ({}): {}",
            c.rule.as_deref().unwrap_or("rule"),
            c.plausibility_note
        ),
        CandidateStatus::OutOfRange => format!("out of range: {}", c.plausibility_note),
        CandidateStatus::Confounded => format!("not identifiable: {}", c.plausibility_note),
        CandidateStatus::NotSignificant => format!("not significant (p = {:.2e})", c.p_value),
        CandidateStatus::TooSmall => format!(
            "too small: it explains {:.1} % of a channel's noise variance (at least {:.0} % needed)",
            100.0 * c.gain,
            100.0 * crate::diagnose::MIN_GAIN
        ),
    };
    let mut fitted = coefs;
    fitted.extend(scan.strip_prefix(", ").map(str::to_string));
    format!(
        "{}: held-out error {}{}; {}; {}",
        c.effect,
        change_percent(-c.reduction, 1),
        chans,
        fitted.join(", "),
        status
    )
}

/// The 95 % profile interval of each scanned effect of a fitted model (`None` for an effect
/// without a scan): the in-sample error in units of the noise `sigma` over the effect's
/// grid, the other effects at their fitted parameters, resolved finer than the interval
/// itself ([`Context::refined_interval`]).
pub(crate) fn scanned_intervals(
    model: &Model,
    s: &Signals,
    fit: &Fit,
    floor: &crate::diagnose::NoiseFloor,
    folds: usize,
) -> Vec<Option<[f64; 2]>> {
    model
        .effects()
        .iter()
        .enumerate()
        .map(|(k, e)| {
            e.scan()?;
            let ctx = Context::without_effect(s, model, fit, k, floor, folds);
            let engine = ctx.fit_engine();
            let members = vec![Member {
                effect: e.clone(),
                param: fit.params[k],
            }];
            let scan = ctx.scan(&engine, &members, 0);
            // The scale per sample of the whole log, the profile over the scan's samples
            // (a long log's window: its interval is that of the window's evidence).
            let score = ctx.score(&ctx.engine(), &members);
            let scale = score.effect_scale(e.as_ref(), s.len() as f64);
            // The fit chose its value under its own channel weights: the interval includes it.
            ctx.refined_interval(&engine, &members, 0, &scan, scale)
                .map(|[lo, hi]| {
                    let v = fit.params[k].unwrap_or(lo);
                    [lo.min(v), hi.max(v)]
                })
        })
        .collect()
}
