//! The diagnosis workflow: compare, where it fails, what is missing.

use serde::Serialize;
use tagk_dynamics::SafetyGate;

use crate::effects::{EffectRef, builtin_effects};
use crate::error::DiagnoseError;
use crate::fit::{
    ChannelFit, Coefficient, Fit, FittedEffect, GramEngine, Model, THETA_NAMES, THETA_UNITS,
    effect_design, fit_model, rigid_design, scan_min,
};
use crate::signals::{CHANNEL_NAMES, CHANNEL_UNITS, Signals};
use crate::stats;

/// Settings of [`diagnose`].
#[derive(Debug, Clone)]
pub struct DiagnoseOptions {
    /// Blocks of the blocked cross-validation over time (default 5).
    pub folds: usize,
    /// Family-wise significance level of the candidate tests (Bonferroni over the
    /// candidates; default 0.01).
    pub alpha: f64,
    /// Smallest held-out residual reduction (fraction of the channel-normalised held-out SSE)
    /// worth recommending (default 0.02).
    pub min_reduction: f64,
    /// Radius of the airframe \[m\]: a fitted centre of mass significantly farther from the
    /// origin is flagged as evidence of an unmodelled force (default: the Crazyflie's
    /// `L_arm` = 0.0325 m).
    pub airframe_radius: f64,
    /// Candidate effects to rank (default: every built-in).
    pub candidates: Vec<EffectRef>,
}

impl Default for DiagnoseOptions {
    fn default() -> Self {
        Self {
            folds: 5,
            alpha: 0.01,
            min_reduction: 0.02,
            airframe_radius: SafetyGate::crazyflie().max_com_offset,
            candidates: builtin_effects(),
        }
    }
}

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

/// Residual whiteness of one channel.
#[derive(Debug, Clone, Serialize)]
pub struct Whiteness {
    /// Channel.
    pub channel: String,
    /// Autocorrelation at lags 1..=max_lag.
    pub autocorrelation: Vec<f64>,
    /// 95 % confidence band `±1.96/√n`.
    pub band: f64,
    /// Lags outside the band.
    pub lags_outside: usize,
    /// `true` if at most 10 % of the lags (and at least 3) are outside the band.
    pub white: bool,
}

/// A time window where the residual is significantly large.
#[derive(Debug, Clone, Serialize)]
pub struct FailureWindow {
    /// Start \[s\].
    pub t_start: f64,
    /// End \[s\].
    pub t_end: f64,
    /// Channels flagged.
    pub channels: Vec<String>,
    /// Peak ratio of the window's residual RMS to the channel's typical (median-window) RMS.
    pub peak_ratio: f64,
}

/// Residual RMS by regime bin.
#[derive(Debug, Clone, Serialize)]
pub struct RegimeStat {
    /// Regime variable, e.g. `body-frame speed`.
    pub regime: String,
    /// Unit.
    pub unit: String,
    /// Bin edges (quartiles of the variable).
    pub edges: Vec<f64>,
    /// Residual RMS per bin and channel `[bin][channel]`.
    pub rms: Vec<[f64; 6]>,
    /// Samples per bin.
    pub counts: Vec<usize>,
}

/// A rigid-body parameter estimate.
pub type Parameter = Coefficient;

/// Everything the diagnosis of one model on one log found.
#[derive(Debug, Clone, Serialize)]
pub struct Diagnosis {
    /// Model label.
    pub model: String,
    /// Samples.
    pub samples: usize,
    /// Duration \[s\].
    pub duration: f64,
    /// `true` if accelerations were derived by the Savitzky–Golay differentiator.
    pub derived_accelerations: bool,
    /// Per-channel fit.
    pub channels: Vec<ChannelFit>,
    /// Rigid-body parameter estimates (CONVENTIONS order) with standard errors.
    pub parameters: Vec<Parameter>,
    /// Centre of mass `h / m` \[m\].
    pub com: [f64; 3],
    /// Pseudo-inertia positive definite (Wensing et al.).
    pub physically_consistent: bool,
    /// Safety gate verdict (`pass` or the violation).
    pub safety_gate: String,
    /// Fitted effects of the model.
    pub effects: Vec<FittedEffect>,
    /// Implausible estimates and what they suggest.
    pub warnings: Vec<String>,
    /// Residual whiteness per channel.
    pub whiteness: Vec<Whiteness>,
    /// Windows of significantly large residual.
    pub failure_windows: Vec<FailureWindow>,
    /// Residual statistics by regime.
    pub regimes: Vec<RegimeStat>,
    /// Plain-language findings ("the fx/fy residual grows with body-frame speed").
    pub findings: Vec<String>,
    /// Candidate effects, best first.
    pub ranking: Vec<Candidate>,
    /// Candidates that could not be evaluated.
    pub unavailable: Vec<Unavailable>,
    /// The recommended effect, or `None` when the model is adequate.
    pub recommended: Option<String>,
    /// One-line verdict.
    pub verdict: String,
    /// The underlying fit (residual and prediction series, for plots).
    #[serde(skip)]
    pub fit: Fit,
    /// Time stamps \[s\] (for plots).
    #[serde(skip)]
    pub t: Vec<f64>,
    /// Measured wrench (for plots).
    #[serde(skip)]
    pub measured: Vec<[f64; 6]>,
    /// Top candidate's driver signal (for plots).
    #[serde(skip)]
    pub top_driver: Option<(String, Vec<f64>)>,
}

/// Diagnoses `model` on a log: fit and compare, where it fails, and the ranking of the
/// candidate effects not already in the model.
///
/// # Errors
/// Fit failures, or an effect of `model` that cannot be used on this log.
pub fn diagnose(
    model: &Model,
    s: &Signals,
    opts: &DiagnoseOptions,
) -> Result<Diagnosis, DiagnoseError> {
    let fit = fit_model(model, s, None)?;
    let n = s.len();
    let w = fit.weights;

    // ---------- what is missing ----------
    let (mut base_cols, _) = rigid_design(model, s);
    for (k, e) in model.effects().iter().enumerate() {
        base_cols.extend(effect_design(e.as_ref(), s, fit.params[k]));
    }
    let p_base = base_cols.len();
    let engine = GramEngine::new(s, &w, &base_cols, Some(&fit.residual), opts.folds);
    let base_ev = engine.evaluate(&[]);
    let rows = (6 * n) as f64;
    let mut ranking = Vec::new();
    let mut unavailable = Vec::new();
    let cands: Vec<&EffectRef> = opts
        .candidates
        .iter()
        .filter(|c| !model.has(c.name()))
        .collect();
    let n_tests = cands.len().max(1) as f64;
    let mut drivers = Vec::new();
    for e in cands {
        let needs_mass = e.needs_known_mass() && model.known_mass().is_none();
        if needs_mass {
            unavailable.push(Unavailable {
                effect: e.name().to_string(),
                reason: "needs a known mass (`--mass KG`): a thrust-gain error and a mass error scale the regression alike".into(),
            });
            continue;
        }
        if let Err(reason) = e.check(s) {
            unavailable.push(Unavailable {
                effect: e.name().to_string(),
                reason,
            });
            continue;
        }
        let spec = e.scan();
        let (param, cols, ev) = match &spec {
            None => {
                let cols = effect_design(e.as_ref(), s, None);
                let ev = engine.evaluate(&cols);
                (None, cols, ev)
            }
            Some(sp) => {
                let (g, _) = scan_min(&sp.grid, |g| {
                    engine
                        .evaluate(&effect_design(e.as_ref(), s, Some(g)))
                        .sse_full
                });
                let cols = effect_design(e.as_ref(), s, Some(g));
                let ev = engine.evaluate(&cols);
                (Some(g), cols, ev)
            }
        };
        let q = cols.len();
        let dof = q + usize::from(spec.is_some());
        let res = engine.residual(&cols, &ev.beta);
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
        let significant = p_value < opts.alpha / n_tests;
        let scanned = spec.map(|sp| (sp.name, param.unwrap_or(f64::NAN), sp.unit));
        let (dname, dsig) = e.driver(s);
        drivers.push((e.name().to_string(), dname.clone(), dsig));
        ranking.push(Candidate {
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
        });
    }
    // Recommendable explanations (significant, plausible, large enough) first; then by
    // held-out reduction.
    ranking.sort_by(|a, b| {
        let ka = a.significant && a.plausible && a.reduction >= opts.min_reduction;
        let kb = b.significant && b.plausible && b.reduction >= opts.min_reduction;
        kb.cmp(&ka).then(b.reduction.total_cmp(&a.reduction))
    });
    let recommended = ranking
        .iter()
        .find(|c| c.significant && c.plausible && c.reduction >= opts.min_reduction)
        .map(|c| c.effect.clone());
    for c in &mut ranking {
        c.explanation = explain(c, opts, recommended.as_deref() == Some(c.effect.as_str()));
    }
    let top_driver = ranking.first().and_then(|top| {
        drivers
            .iter()
            .find(|d| d.0 == top.effect)
            .map(|d| (d.1.clone(), d.2.clone()))
    });

    // ---------- where it fails ----------
    let whiteness = whiteness(&fit);
    let failure_windows = failure_windows(&s.t, &fit);
    let regimes = regimes(s, &fit);
    let structured: Vec<bool> = whiteness
        .iter()
        .map(|w| w.lags_outside * 4 >= w.autocorrelation.len().max(1) && w.lags_outside >= 5)
        .collect();
    let mut findings = regime_findings(&regimes, &structured);
    for wn in &whiteness {
        if !wn.white {
            findings.push(format!(
                "the {} residual is not white ({} of {} lags outside the 95 % band; lag-1 autocorrelation {:.2})",
                wn.channel,
                wn.lags_outside,
                wn.autocorrelation.len(),
                wn.autocorrelation.first().copied().unwrap_or(0.0)
            ));
        }
    }
    if !failure_windows.is_empty() {
        let total: f64 = failure_windows.iter().map(|f| f.t_end - f.t_start).sum();
        findings.push(format!(
            "{} time window(s) with a significantly large residual, {:.1} s in total",
            failure_windows.len(),
            total
        ));
    }

    // ---------- parameters and their plausibility ----------
    let theta = fit.theta;
    let parameters: Vec<Parameter> = (0..10)
        .map(|j| Coefficient {
            name: THETA_NAMES[j].into(),
            unit: THETA_UNITS[j].into(),
            value: theta.as_slice()[j],
            std_error: fit.theta_se[j],
        })
        .collect();
    let m = theta.mass();
    let h = theta.first_moment();
    let com = if m > 0.0 {
        [h.x / m, h.y / m, h.z / m]
    } else {
        [f64::NAN; 3]
    };
    let mut warnings = Vec::new();
    let physically_consistent = theta.is_physically_consistent();
    let safety_gate = match theta.safety_gate(&SafetyGate {
        max_com_offset: opts.airframe_radius,
        ..SafetyGate::crazyflie()
    }) {
        Ok(()) => "pass".to_string(),
        Err(v) => format!("{v}"),
    };
    let com_json = if m > 0.0 { com } else { [0.0; 3] };
    if m <= 0.0 {
        warnings.push(format!(
            "fitted mass {m:.4} kg is not positive: the model is missing a force, do not trust these parameters"
        ));
    } else {
        let mut outside = Vec::new();
        for (k, axis) in ["x", "y", "z"].iter().enumerate() {
            let se = fit.theta_se[1 + k].map_or(f64::INFINITY, |s| s / m);
            if com[k].abs() - 2.0 * se > opts.airframe_radius {
                outside.push(format!(
                    "c_{axis} = {:.1} cm (± {:.1})",
                    com[k] * 100.0,
                    se * 100.0
                ));
            }
        }
        if !outside.is_empty() {
            warnings.push(format!(
                "fitted centre of mass outside the airframe ({} vs radius {:.1} cm): this is evidence of an unmodelled force or torque{}, not a real centre of mass",
                outside.join(", "),
                opts.airframe_radius * 100.0,
                recommended
                    .as_ref()
                    .map(|r| format!(" (the ranking points at `{r}`)"))
                    .unwrap_or_default()
            ));
        }
    }
    if !physically_consistent && m > 0.0 {
        warnings.push(
            "the fitted parameters are not physically consistent (pseudo-inertia not positive definite)".into(),
        );
    }
    for fe in &fit.effects {
        if !fe.plausible {
            warnings.push(format!(
                "effect `{}` fitted implausibly: {}",
                fe.effect, fe.plausibility_note
            ));
        }
    }

    let verdict = match &recommended {
        Some(r) => {
            let c = ranking.iter().find(|c| &c.effect == r);
            format!(
                "missing physics: `{r}` (held-out residual {:+.0} %)",
                c.map_or(0.0, |c| -c.reduction * 100.0)
            )
        }
        None => {
            "model adequate: no candidate effect lowers the held-out residual significantly".into()
        }
    };
    Ok(Diagnosis {
        model: fit.label.clone(),
        samples: n,
        duration: s.t[n - 1] - s.t[0],
        derived_accelerations: s.derived_accel,
        channels: fit.channels.clone(),
        parameters,
        com: com_json,
        physically_consistent,
        safety_gate,
        effects: fit.effects.clone(),
        warnings,
        whiteness,
        failure_windows,
        regimes,
        findings,
        ranking,
        unavailable,
        recommended,
        verdict,
        fit,
        t: s.t.clone(),
        measured: s.wrench.clone(),
        top_driver,
    })
}

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

fn whiteness(fit: &Fit) -> Vec<Whiteness> {
    let n = fit.residual.len();
    let max_lag = 20.min(n / 4).max(1);
    let band = 1.96 / (n as f64).sqrt();
    (0..6)
        .map(|c| {
            let r = fit.residual_channel(c);
            let rho = stats::autocorrelation(&r, max_lag);
            let ac: Vec<f64> = rho[1..].to_vec();
            let outside = ac.iter().filter(|x| x.abs() > band).count();
            // At 5 % per lag, 4 or more of 20 lags outside happens by chance 1.6 % of the time.
            let allowed = ((0.1 * max_lag as f64).ceil() as usize).max(3);
            Whiteness {
                channel: CHANNEL_NAMES[c].into(),
                autocorrelation: ac,
                band,
                lags_outside: outside,
                white: outside <= allowed,
            }
        })
        .collect()
}

fn failure_windows(t: &[f64], fit: &Fit) -> Vec<FailureWindow> {
    let n = t.len();
    let dt = if n > 1 {
        (t[n - 1] - t[0]) / (n - 1) as f64
    } else {
        1.0
    };
    let win = ((1.0 / dt).round() as usize).clamp(5, (n / 4).max(5));
    let step = (win / 2).max(1);
    // flags[i] = set of channels flagged for the window starting at i
    let mut intervals: Vec<(usize, usize, usize, f64)> = Vec::new(); // (start, end, channel, ratio)
    for c in 0..6 {
        let r = fit.residual_channel(c);
        let mut starts = Vec::new();
        let mut ms = Vec::new();
        let mut i = 0;
        while i + win <= n {
            starts.push(i);
            ms.push(r[i..i + win].iter().map(|x| x * x).sum::<f64>() / win as f64);
            i += step;
        }
        let typical = stats::median(&ms);
        if typical <= 0.0 {
            continue;
        }
        let kappa = stats::batch_means_factor(&r);
        let thresh = (1.0 + 4.0 * (2.0 * kappa / win as f64).sqrt()).max(2.0);
        for (&i, &m) in starts.iter().zip(&ms) {
            if m / typical > thresh {
                intervals.push((i, i + win, c, (m / typical).sqrt()));
            }
        }
    }
    intervals.sort_by_key(|x| x.0);
    let mut out: Vec<(usize, usize, Vec<usize>, f64)> = Vec::new();
    for (a, b, c, r) in intervals {
        if let Some(last) = out.last_mut()
            && a <= last.1
        {
            last.1 = last.1.max(b);
            if !last.2.contains(&c) {
                last.2.push(c);
            }
            last.3 = last.3.max(r);
            continue;
        }
        out.push((a, b, vec![c], r));
    }
    out.into_iter()
        .map(|(a, b, mut cs, r)| {
            cs.sort_unstable();
            FailureWindow {
                t_start: t[a],
                t_end: t[(b - 1).min(n - 1)],
                channels: cs.iter().map(|c| CHANNEL_NAMES[*c].to_string()).collect(),
                peak_ratio: r,
            }
        })
        .collect()
}

fn regimes(s: &Signals, fit: &Fit) -> Vec<RegimeStat> {
    let vars: [(&str, &str, Vec<f64>); 4] = [
        (
            "body-frame speed",
            "m/s",
            s.velocity_body.iter().map(|v| v.norm()).collect(),
        ),
        ("height", "m", s.position.iter().map(|p| p.z).collect()),
        ("thrust", "N", s.channel(2)),
        (
            "angular rate",
            "rad/s",
            s.omega.iter().map(|w| w.norm()).collect(),
        ),
    ];
    vars.into_iter()
        .map(|(name, unit, x)| {
            let mut sorted = x.clone();
            sorted.sort_by(|a, b| a.total_cmp(b));
            let edges: Vec<f64> = (0..=4)
                .map(|k| stats::quantile(&sorted, k as f64 / 4.0))
                .collect();
            let mut sums = [[0.0; 6]; 4];
            let mut counts = vec![0usize; 4];
            for (i, xi) in x.iter().enumerate() {
                let mut b = 0;
                while b < 3 && *xi > edges[b + 1] {
                    b += 1;
                }
                counts[b] += 1;
                for c in 0..6 {
                    sums[b][c] += fit.residual[i][c].powi(2);
                }
            }
            let rms = sums
                .iter()
                .zip(&counts)
                .map(|(s, &k)| {
                    std::array::from_fn(|c| if k > 0 { (s[c] / k as f64).sqrt() } else { 0.0 })
                })
                .collect();
            RegimeStat {
                regime: name.into(),
                unit: unit.into(),
                edges,
                rms,
                counts,
            }
        })
        .collect()
}

/// Regime statements for the channels whose residual is structured (clearly non-white).
fn regime_findings(regimes: &[RegimeStat], structured: &[bool]) -> Vec<String> {
    let mut out = Vec::new();
    for r in regimes {
        if r.edges[4] - r.edges[0] <= 1e-12 * r.edges[4].abs().max(1.0) {
            continue;
        }
        let mut grows = Vec::new();
        let mut falls = Vec::new();
        for c in (0..6).filter(|&c| structured[c]) {
            let lo = r.rms[0][c];
            let hi = r.rms[3][c];
            if lo <= 0.0 || hi <= 0.0 {
                continue;
            }
            if hi / lo >= 2.0 {
                grows.push((c, hi / lo));
            } else if lo / hi >= 2.0 {
                falls.push((c, lo / hi));
            }
        }
        let fmt = |v: &[(usize, f64)]| {
            v.iter()
                .map(|(c, _)| CHANNEL_NAMES[*c])
                .collect::<Vec<_>>()
                .join("/")
        };
        if !grows.is_empty() {
            let max = grows.iter().map(|x| x.1).fold(0.0, f64::max);
            out.push(format!(
                "the {} residual grows with {} (up to ×{:.1} from the lowest to the highest quarter)",
                fmt(&grows),
                r.regime,
                max
            ));
        }
        if !falls.is_empty() {
            let max = falls.iter().map(|x| x.1).fold(0.0, f64::max);
            out.push(format!(
                "the {} residual grows as {} falls (up to ×{:.1} from the highest to the lowest quarter)",
                fmt(&falls),
                r.regime,
                max
            ));
        }
    }
    out
}

/// Units of the channels, re-exported for report writers.
pub fn channel_units() -> [&'static str; 6] {
    CHANNEL_UNITS
}
