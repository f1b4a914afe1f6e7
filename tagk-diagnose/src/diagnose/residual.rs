//! Where the model fails: residual whiteness, time windows of significantly large residual,
//! residual by regime, and the plain-language findings drawn from them.

use serde::Serialize;

use crate::signals::{CHANNEL_NAMES, Signals};
use crate::stats;

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
    /// Peak ratio of the window's residual RMS to the larger of the channel's typical
    /// (median-window) RMS and its noise.
    pub peak_ratio: f64,
    /// `true` for a window at the very start of the log: the start transient (take-off,
    /// filters settling) rather than a failure of the model in flight.
    pub transient: bool,
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

/// The outcome of [`where_it_fails`].
pub(crate) struct FailureAnalysis {
    /// Residual whiteness per channel.
    pub whiteness: Vec<Whiteness>,
    /// Windows of significantly large residual.
    pub failure_windows: Vec<FailureWindow>,
    /// Residual statistics by regime.
    pub regimes: Vec<RegimeStat>,
    /// Plain-language findings.
    pub findings: Vec<String>,
}

/// Where the fitted model fails (step 3 of [`crate::diagnose()`]), from its residual
/// `residual` (whitened where the model filters the measured wrench: a lag's residual of the
/// measured wrench carries the motion sensors' noise raised by the inverse lag): whiteness,
/// failure windows, regimes, and the findings — regime trends of the structured (clearly
/// non-white) channels, the non-white channels, the failure windows.
///
/// `noise` is each channel's noise σ (N, N m; [`crate::NoiseFloor::rms`]). A channel
/// `at_noise` (its held-out residual within [`crate::ADEQUACY_FACTOR`] of its noise) has no
/// findings and no failure windows: what remains there is the noise.
pub(crate) fn where_it_fails(
    s: &Signals,
    residual: &[[f64; 6]],
    noise: &[f64; 6],
    at_noise: &[bool; 6],
) -> FailureAnalysis {
    let rounding = at_rounding_level(s, residual);
    let whiteness = whiteness(residual, &rounding);
    let quiet: [bool; 6] = std::array::from_fn(|c| rounding[c] || at_noise[c]);
    let failure_windows = failure_windows(&s.t, residual, &quiet, noise);
    let regimes = regimes(s, residual);
    let structured: Vec<bool> = whiteness
        .iter()
        .zip(quiet)
        .map(|(w, q)| {
            !q && w.lags_outside * 4 >= w.autocorrelation.len().max(1) && w.lags_outside >= 5
        })
        .collect();
    let mut findings = regime_findings(&regimes, &structured);
    for (wn, q) in whiteness.iter().zip(quiet) {
        if !wn.white && !q {
            findings.push(format!(
                "the {} residual is not white ({} of {} lags outside the 95 % band; lag-1 autocorrelation {:.2})",
                wn.channel,
                wn.lags_outside,
                wn.autocorrelation.len(),
                wn.autocorrelation.first().copied().unwrap_or(0.0)
            ));
        }
    }
    let (transients, in_flight): (Vec<&FailureWindow>, Vec<&FailureWindow>) =
        failure_windows.iter().partition(|f| f.transient);
    if !in_flight.is_empty() {
        let total: f64 = in_flight.iter().map(|f| f.t_end - f.t_start).sum();
        findings.push(format!(
            "{} time window(s) with a significantly large residual, {:.1} s in total",
            in_flight.len(),
            total
        ));
    }
    if let Some(f) = transients.first() {
        findings.push(format!(
            "a start transient: the residual of {} is large for the first {:.1} s",
            f.channels.join(", "),
            f.t_end - f.t_start
        ));
    }
    FailureAnalysis {
        whiteness,
        failure_windows,
        regimes,
        findings,
    }
}

/// A residual RMS below this fraction of the measured wrench's RMS (the channel's, or its
/// group's — forces or torques — when larger) is floating-point rounding, not a model error:
/// such a channel is fitted exactly (a noise-free log), counts as white and has no failure
/// windows.
pub(crate) const ROUNDING_LEVEL: f64 = 1e-9;

/// Per channel: is the residual at the rounding level ([`ROUNDING_LEVEL`])?
pub(crate) fn at_rounding_level(s: &Signals, residual: &[[f64; 6]]) -> [bool; 6] {
    let rms = |v: &mut dyn Iterator<Item = f64>| {
        let (sum, n) = v.fold((0.0, 0usize), |(a, n), x| (a + x * x, n + 1));
        if n == 0 { 0.0 } else { (sum / n as f64).sqrt() }
    };
    let measured: [f64; 6] = std::array::from_fn(|c| rms(&mut s.target().iter().map(|w| w[c])));
    std::array::from_fn(|c| {
        let group = if c < 3 {
            &measured[..3]
        } else {
            &measured[3..]
        };
        let scale = group.iter().fold(measured[c], |a, &b| a.max(b));
        let residual = rms(&mut residual.iter().map(|r| r[c]));
        scale > 0.0 && residual <= ROUNDING_LEVEL * scale
    })
}

/// One channel of a residual, as a series.
fn channel(residual: &[[f64; 6]], c: usize) -> Vec<f64> {
    residual.iter().map(|r| r[c]).collect()
}

/// The lags of the whiteness test, at most.
const WHITENESS_LAGS: usize = 20;

/// The lags of the whiteness test of `n` samples: `1..=min(20, n/4)` (at least lag 1).
pub(crate) fn whiteness_lags(n: usize) -> usize {
    WHITENESS_LAGS.min(n / 4).max(1)
}

/// The autocorrelation of a residual series at the whiteness test's lags
/// `1..=min(20, n/4)` (dimensionless; about the series' mean): what [`Whiteness`] reports
/// and the adequacy test sums the squares of.
pub fn residual_autocorrelation(r: &[f64]) -> Vec<f64> {
    let rho = stats::autocorrelation(r, whiteness_lags(r.len()));
    rho[1..].to_vec()
}

/// Residual autocorrelation per channel at lags `1..=min(20, n/4)` against the 95 % band (a
/// channel at the rounding level counts as white).
fn whiteness(residual: &[[f64; 6]], rounding: &[bool; 6]) -> Vec<Whiteness> {
    let n = residual.len();
    let max_lag = whiteness_lags(n);
    let band = 1.96 / (n as f64).sqrt();
    (0..6)
        .map(|c| {
            let ac = residual_autocorrelation(&channel(residual, c));
            let outside = ac.iter().filter(|x| x.abs() > band).count();
            // At 5 % per lag, 4 or more of 20 lags outside happens by chance 1.6 % of the time.
            let allowed = ((0.1 * max_lag as f64).ceil() as usize).max(3);
            Whiteness {
                channel: CHANNEL_NAMES[c].into(),
                autocorrelation: ac,
                band,
                lags_outside: outside,
                white: rounding[c] || outside <= allowed,
            }
        })
        .collect()
}

/// Sliding windows (about 1 s, half overlapping) whose residual mean square exceeds both the
/// channel's median window and its noise variance `noise²` by a threshold corrected for
/// autocorrelation; overlapping flagged windows are merged. `skip`ped channels (at the
/// rounding level, or at their noise) have none.
fn failure_windows(
    t: &[f64],
    residual: &[[f64; 6]],
    skip: &[bool; 6],
    noise: &[f64; 6],
) -> Vec<FailureWindow> {
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
    for c in (0..6).filter(|&c| !skip[c]) {
        let r = channel(residual, c);
        let mut starts = Vec::new();
        let mut ms = Vec::new();
        let mut i = 0;
        while i + win <= n {
            starts.push(i);
            ms.push(r[i..i + win].iter().map(|x| x * x).sum::<f64>() / win as f64);
            i += step;
        }
        // Large against the rest of the flight and against the noise alike.
        let typical = stats::median(&ms).max(noise[c] * noise[c]);
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
                transient: a == 0,
            }
        })
        .collect()
}

/// Residual RMS per channel in the quartiles of body-frame speed, height, thrust and
/// angular rate.
fn regimes(s: &Signals, residual: &[[f64; 6]]) -> Vec<RegimeStat> {
    let vars: [(&str, &str, Vec<f64>); 4] = [
        (
            "body-frame speed",
            "m/s",
            s.velocity_body.iter().map(|v| v.norm()).collect(),
        ),
        ("height", "m", s.positions().map(|p| p.z).collect()),
        ("thrust", "N", s.channel(2)),
        (
            "angular rate",
            "rad/s",
            (0..s.len()).map(|i| s.omega(i).norm()).collect(),
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
                    sums[b][c] += residual[i][c].powi(2);
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
