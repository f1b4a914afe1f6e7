//! Residual analysis on the actual inputs, as MATLAB's `resid`: the cross-correlation of
//! each channel's residual with each input of the model, against a 99 % band.
//!
//! **Inputs.** The rotor speeds `w1 … w4` \[rad/s\] (or the measured thrust `fz` \[N\]
//! when the log has none), the body-frame velocity components `vx, vy, vz` \[m/s\], signed,
//! and the body angular rates `p, q, r` \[rad/s\]. The velocity is the one the effects' columns
//! read ([`Signals::velocity_body`]); the rates are the log's own.
//!
//! **Correlation.** `ρ_ue(k) = Σᵢ ũᵢ ẽᵢ₊ₖ / √(Σ ũ² Σ ẽ²)` of the mean-removed input `u` and
//! residual `e`, at lags `k = −25 … 25` samples. Positive `k`: the input leads the residual.
//!
//! **Band.** The series are not prewhitened. Under independence of `u` and `e`, `ρ_ue(k)` has
//! variance `P / N` (Bartlett), `P = Σ_{|j| ≤ 25} (1 − |j|/26) ρ_u(j) ρ_e(j)`. The band is
//! `±z √(P/N)` with `z = 2.576` (99 % per lag, as `resid`). `P = 1` when either series is
//! white: then the band is the familiar `±z/√N`. A smooth input and a smooth residual widen it.
//!
//! **Reading it.** A residual at its noise can still correlate with the rotor speeds at lag 0.
//! The measured wrench is built from the measured rotor speeds, so their noise is in both.
//! That is the sensors', not missing physics: read the correlations with the channel's
//! distance from its noise ([`crate::ChannelAdequacy`]). Lags run across the joins of several
//! logs (a few samples of `N`).

use serde::Serialize;

use crate::error::DiagnoseError;
use crate::signals::{CHANNEL_NAMES, Signals};
use crate::stats;

/// Lags of the residual–input cross-correlation on each side of zero (25 samples, as
/// `resid`); fewer on a log shorter than 100 samples (`N/4`).
pub const INPUT_CORRELATION_LAGS: usize = 25;

/// Two-sided 99 % quantile of the standard normal (2.576): the band of
/// [`InputCorrelation::band`], `resid`'s confidence level.
pub const Z_99: f64 = 2.575_829_303_548_901;

/// One input of the model, as a series over the log.
#[derive(Debug, Clone)]
pub struct ResidualInput {
    /// Short name (`w1`, `vx`, `p`, …).
    pub name: String,
    /// Unit of the values.
    pub unit: String,
    /// The values per sample.
    pub values: Vec<f64>,
}

/// The cross-correlation of one channel's residual with one input.
#[derive(Debug, Clone, Serialize)]
pub struct InputCorrelation {
    /// Channel (`fx` … `tz`).
    pub channel: String,
    /// Input name ([`residual_inputs`]).
    pub input: String,
    /// Input unit.
    pub unit: String,
    /// Time between two lags \[s\] (the log's mean sample interval).
    pub lag_step: f64,
    /// `ρ_ue(k)` at lags `k = −L … L` (index `k + L`; dimensionless).
    pub correlation: Vec<f64>,
    /// `ρ_ue(0)`.
    pub lag0: f64,
    /// Half-width of the 99 % band, `z √(P/N)` (module docs).
    pub band: f64,
    /// `P`: the variance factor of the band (1 when either series is white).
    pub variance_factor: f64,
    /// The correlation of largest magnitude (signed).
    pub peak: f64,
    /// Its lag \[s\] (positive: the input leads the residual).
    pub peak_lag: f64,
    /// `|peak| / band`: above 1, outside the band.
    pub peak_over_band: f64,
    /// Lags with `|ρ| > band`.
    pub lags_outside: usize,
}

impl InputCorrelation {
    /// `true` when some lag is outside the band.
    pub fn outside(&self) -> bool {
        self.lags_outside > 0
    }
}

/// The inputs of the residual analysis on `s` (module docs): rotor speeds or thrust, the
/// signed body-frame velocity components, the body rates.
pub fn residual_inputs(s: &Signals) -> Vec<ResidualInput> {
    let mut out = Vec::with_capacity(10);
    let input = |name: &str, unit: &str, values: Vec<f64>| ResidualInput {
        name: name.into(),
        unit: unit.into(),
        values,
    };
    match s.rotor_speeds() {
        Some(w) => {
            for r in 0..4 {
                out.push(input(
                    &format!("w{}", r + 1),
                    "rad/s",
                    w.iter().map(|x| x[r]).collect(),
                ));
            }
        }
        None => out.push(input("thrust", "N", s.channel(2))),
    }
    for (k, name) in ["vx", "vy", "vz"].iter().enumerate() {
        out.push(input(
            name,
            "m/s",
            s.velocity_body.iter().map(|v| v[k]).collect(),
        ));
    }
    for (k, name) in ["p", "q", "r"].iter().enumerate() {
        out.push(input(
            name,
            "rad/s",
            (0..s.len()).map(|i| s.omega(i)[k]).collect(),
        ));
    }
    out
}

/// The lags of the residual–input correlation of `n` samples: 25, at most `n/4`.
pub fn input_correlation_lags(n: usize) -> usize {
    INPUT_CORRELATION_LAGS.min(n / 4)
}

/// Cross-correlation of every channel of `residual` (N, N m; one row per sample of `s`) with
/// every input of [`residual_inputs`], channel-major, with its 99 % band (module docs).
///
/// # Errors
/// [`DiagnoseError::InvalidOption`] (`residual`) if `residual` is not one row per sample of
/// `s`, or holds a value that is not finite.
pub fn input_correlation(
    s: &Signals,
    residual: &[[f64; 6]],
) -> Result<Vec<InputCorrelation>, DiagnoseError> {
    if residual.len() != s.len() {
        return Err(DiagnoseError::InvalidOption {
            field: "residual",
            reason: format!("{} rows for a log of {} samples", residual.len(), s.len()),
        });
    }
    if let Some(i) = residual
        .iter()
        .position(|r| r.iter().any(|x| !x.is_finite()))
    {
        return Err(DiagnoseError::InvalidOption {
            field: "residual",
            reason: format!("row {i} is not finite"),
        });
    }
    let n = s.len();
    let lags = input_correlation_lags(n);
    let dt = if n > 1 { s.mean_dt() } else { 0.0 };
    let inputs: Vec<(ResidualInput, Vec<f64>, Vec<f64>)> = residual_inputs(s)
        .into_iter()
        .map(|u| {
            let centred = centred(&u.values);
            let rho = stats::autocorrelation(&u.values, lags);
            (u, centred, rho)
        })
        .collect();
    let mut out = Vec::with_capacity(6 * inputs.len());
    for c in 0..6 {
        let e: Vec<f64> = residual.iter().map(|r| r[c]).collect();
        let rho_e = stats::autocorrelation(&e, lags);
        let e = centred(&e);
        for (u, uc, rho_u) in &inputs {
            let correlation = centred_cross_correlation(uc, &e, lags);
            let p = variance_factor(rho_u, &rho_e);
            let band = Z_99 * (p / n.max(1) as f64).sqrt();
            let (k, peak) =
                correlation
                    .iter()
                    .enumerate()
                    .fold((lags, 0.0f64), |(bk, bv), (k, &v)| {
                        if v.abs() > bv.abs() { (k, v) } else { (bk, bv) }
                    });
            out.push(InputCorrelation {
                channel: CHANNEL_NAMES[c].into(),
                input: u.name.clone(),
                unit: u.unit.clone(),
                lag_step: dt,
                lag0: correlation[lags],
                band,
                variance_factor: p,
                peak,
                peak_lag: (k as f64 - lags as f64) * dt,
                peak_over_band: if band > 0.0 { peak.abs() / band } else { 0.0 },
                lags_outside: correlation.iter().filter(|r| r.abs() > band).count(),
                correlation,
            });
        }
    }
    Ok(out)
}

/// A series with its mean removed.
fn centred(x: &[f64]) -> Vec<f64> {
    let m = if x.is_empty() {
        0.0
    } else {
        x.iter().sum::<f64>() / x.len() as f64
    };
    x.iter().map(|v| v - m).collect()
}

/// [`stats::cross_correlation`] of two mean-removed series of equal length, by contiguous
/// dot products (the same sums, faster on a long log). Zeros when either is constant.
fn centred_cross_correlation(x: &[f64], y: &[f64], lags: usize) -> Vec<f64> {
    let n = x.len().min(y.len());
    let mut out = vec![0.0; 2 * lags + 1];
    let norm = (x[..n].iter().map(|v| v * v).sum::<f64>()
        * y[..n].iter().map(|v| v * v).sum::<f64>())
    .sqrt();
    if norm <= 0.0 || !norm.is_finite() {
        return out;
    }
    for k in 0..=lags.min(n.saturating_sub(1)) {
        // x leads y by k: Σ x_i y_{i+k}; and the mirror lag −k: Σ x_{i+k} y_i.
        out[lags + k] = dot(&x[..n - k], &y[k..n]) / norm;
        out[lags - k] = dot(&x[k..n], &y[..n - k]) / norm;
    }
    out
}

/// `Σ aᵢ bᵢ` over the shorter slice, in four interleaved partial sums (which the compiler
/// can keep in vector registers: 60 channel–input pairs × 51 lags run over a long log).
fn dot(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len());
    let (a, b) = (&a[..n], &b[..n]);
    let mut acc = [0.0f64; 4];
    let ca = a.chunks_exact(4);
    let cb = b.chunks_exact(4);
    let tail: f64 = ca
        .remainder()
        .iter()
        .zip(cb.remainder())
        .map(|(p, q)| p * q)
        .sum();
    for (x, y) in ca.zip(cb) {
        for k in 0..4 {
            acc[k] += x[k] * y[k];
        }
    }
    (acc[0] + acc[1]) + (acc[2] + acc[3]) + tail
}

/// Bartlett's variance factor `P = Σ_{|j| ≤ L} (1 − |j|/(L+1)) ρ_u(j) ρ_e(j)` of two
/// autocorrelations at lags `0..=L` (`ρ(0) = 1`). Never below 0; 1 when both are constant
/// (their autocorrelations zero past lag 0).
fn variance_factor(rho_u: &[f64], rho_e: &[f64]) -> f64 {
    let l = rho_u.len().min(rho_e.len());
    if l == 0 {
        return 1.0;
    }
    let w = |j: usize| 1.0 - j as f64 / l as f64;
    let tail: f64 = (1..l).map(|j| w(j) * rho_u[j] * rho_e[j]).sum();
    (1.0 + 2.0 * tail).max(0.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testdata::gauss;
    use rand_chacha::ChaCha8Rng;
    use rand_core::SeedableRng;

    /// An AR(1) series `x_i = φ x_{i−1} + ε_i` (smooth for φ near 1).
    fn ar1(rng: &mut ChaCha8Rng, n: usize, phi: f64) -> Vec<f64> {
        let mut x = vec![0.0; n];
        for i in 1..n {
            x[i] = phi * x[i - 1] + gauss(rng);
        }
        x
    }

    #[test]
    fn the_fast_cross_correlation_is_the_plain_one() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let x: Vec<f64> = (0..300).map(|_| gauss(&mut rng) + 2.0).collect();
        let y: Vec<f64> = (0..300).map(|i| x[(i + 295) % 300] - 1.0).collect();
        let fast = centred_cross_correlation(&centred(&x), &centred(&y), 12);
        let plain = stats::cross_correlation(&x, &y, 12);
        for (a, b) in fast.iter().zip(&plain) {
            assert!((a - b).abs() < 1e-12, "{a} vs {b}");
        }
        // y lags x by 5 samples: the peak sits at k = +5.
        assert!(fast[12 + 5] > 0.95, "{fast:?}");
    }

    #[test]
    fn bartlett_factor_is_one_for_white_and_known_for_two_ar1() {
        let white = [1.0, 0.0, 0.0, 0.0];
        let smooth = [1.0, 0.9, 0.81, 0.729];
        assert_eq!(variance_factor(&white, &smooth), 1.0);
        // 1 + 2 Σ_{j=1..3} (1 − j/4) 0.9^j 0.8^j, by hand.
        let b = [1.0, 0.8, 0.64, 0.512];
        let hand = 1.0 + 2.0 * (0.75 * 0.72 + 0.5 * 0.72f64.powi(2) + 0.25 * 0.72f64.powi(3));
        assert!((variance_factor(&smooth, &b) - hand).abs() < 1e-12);
    }

    /// The band holds its level on independent smooth series, where `±z/√N` would not:
    /// Monte Carlo over 400 independent AR(1) pairs (φ = 0.9).
    #[test]
    fn the_band_covers_independent_smooth_series_at_its_level() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let (n, lags, trials) = (2000, 25, 400);
        let (mut outside, mut outside_white_band) = (0, 0);
        for _ in 0..trials {
            let u = ar1(&mut rng, n, 0.9);
            let e = ar1(&mut rng, n, 0.9);
            let rho = centred_cross_correlation(&centred(&u), &centred(&e), lags);
            let p = variance_factor(
                &stats::autocorrelation(&u, lags),
                &stats::autocorrelation(&e, lags),
            );
            let band = Z_99 * (p / n as f64).sqrt();
            outside += usize::from(rho[lags].abs() > band);
            outside_white_band += usize::from(rho[lags].abs() > Z_99 / (n as f64).sqrt());
        }
        eprintln!("outside: {outside} of {trials} (Bartlett band), {outside_white_band} (±z/√N)");
        // 1 % expected (4 of 400); the white band misses far more (P ≈ 9 here).
        assert!(outside <= 12, "{outside} of {trials} outside the band");
        assert!(outside_white_band >= 100, "{outside_white_band}");
    }
}
