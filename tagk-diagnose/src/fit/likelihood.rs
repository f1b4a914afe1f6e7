//! The score every model is judged on: the Gaussian log-likelihood of the measured wrench,
//! channel by channel, under a noise with two sources.
//!
//! **Two sources.** The residual of a channel carries the noise of the measured wrench `ε`
//! (rotor speeds read back, or the logged command; σ_b) and the noise of the motion sensors
//! through the model `η` (accelerometer, gyro; σ_m), both white. Without a filter of the
//! target the residual is `ε − η`, of variance `σ² = σ_b² + σ_m²`, and the score is the sum
//! of squares in units of σ².
//!
//! **With a filter of the target** (a motor lag: the regression's target is the lagged
//! wrench `L b`, `L(z) = (g₀ + g₁ z⁻¹) / (1 − a z⁻¹)`), the residual `r = L ε − η` is
//! coloured: its spectrum times `|1 − a z⁻¹|²` is `A + B (z + z⁻¹)` with
//! `A = σ_b² (g₀² + g₁²) + σ_m² (1 + a²)` and `B = σ_b² g₀ g₁ − σ_m² a`, which factors as
//! `K |1 + c z⁻¹|²` (`K (1 + c²) = A`, `K c = B`, `|c| < 1`). The monic filter
//! `W(z) = (1 − a z⁻¹) / (1 + c z⁻¹)` whitens it to innovations of variance `K`, and the
//! likelihood of the *measured* wrench is that of `r` plus the Jacobian of `b → L b`
//! (`n ln g₀`): in units of σ², `−2 ln p = Σ (W r)² / K + n ln(K / σ²) − 2 n ln g₀`
//! (+ the same constant for every model). With `σ_m = 0` this is the sum of squares of
//! `L⁻¹ r`, the error of predicting `b` itself; with `σ_b = 0` that of `r` plus the cost of
//! predicting `b` through the inverse of the lag. Neither limit drifts: a longer lag
//! smooths the wrench's noise but pays for it in `K` and `g₀`.
//!
//! **Estimating a filter's parameter.** The score above compares models. A lag's time
//! constant is estimated on `Σ (W r)² / K` alone ([`crate::fit::scan_criterion`]): the
//! errors-in-variables profile over the true wrench (the innovations of `r` under its own
//! covariance `σ_b² L Lᵀ + σ_m² I`). For every time constant its expectation is the number of
//! innovations plus the model's own mismatch, so it is least at the true one. The
//! log-determinant term is not: it is the density of `b` given the motion; the density of
//! the motion given `b` has `n ln K` alone. The two differ by the Jacobian `−2 n ln g₀`, which
//! pulls the estimate towards short lags where the motion sensors dominate (all of a
//! noise-free log's resolution).

use crate::signals::Signals;

/// A first-order filter of the measured wrench on one channel, for the log's mean step:
/// `y_k = g₀ b_k + g₁ b_{k−1} + a y_{k−1}`, i.e. `L(z) = (g₀ + g₁ z⁻¹) / (1 − a z⁻¹)`
/// (a motor lag's response sampled at the interval's middle or as its mean).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TargetFilter {
    /// Direct gain `g₀` (`0 < g₀ ≤ 1`).
    pub g0: f64,
    /// Gain of the previous sample `g₁`.
    pub g1: f64,
    /// Pole `a` (`0 ≤ a < 1`).
    pub a: f64,
}

/// The filter of one channel's measured wrench by every filtering effect of a model, as a
/// ratio of polynomials in `z⁻¹`: `H(z) = N(z) / D(z)`, `D` monic.
///
/// The effects' known parts add up in the target (`b + Σ_e (H_e − 1) b`), so their filters
/// compose as `H = 1 + Σ_e (H_e − 1)`. One filter is itself (`N = g₀ + g₁ z⁻¹`,
/// `D = 1 − a z⁻¹`).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct ChannelFilter {
    /// Numerator coefficients, `z⁰` first.
    pub num: Vec<f64>,
    /// Denominator coefficients, `z⁰` first (`den[0] = 1`).
    pub den: Vec<f64>,
}

impl From<&TargetFilter> for ChannelFilter {
    fn from(f: &TargetFilter) -> Self {
        Self {
            num: vec![f.g0, f.g1],
            den: vec![1.0, -f.a],
        }
    }
}

/// The product of two polynomials in `z⁻¹`.
fn poly_mul(a: &[f64], b: &[f64]) -> Vec<f64> {
    let mut out = vec![0.0; a.len() + b.len() - 1];
    for (i, x) in a.iter().enumerate() {
        for (j, y) in b.iter().enumerate() {
            out[i + j] += x * y;
        }
    }
    out
}

/// `a + b` for polynomials in `z⁻¹` of any lengths.
fn poly_add(a: &[f64], b: &[f64]) -> Vec<f64> {
    (0..a.len().max(b.len()))
        .map(|i| a.get(i).copied().unwrap_or(0.0) + b.get(i).copied().unwrap_or(0.0))
        .collect()
}

impl ChannelFilter {
    /// The composition `1 + Σ_e (H_e − 1)` of the filters `parts` (`None` without any).
    pub fn compose(parts: &[TargetFilter]) -> Option<Self> {
        let (first, rest) = parts.split_first()?;
        let mut h = Self::from(first);
        for f in rest {
            let g = Self::from(f);
            // H + G − 1 = (N_h D_g + N_g D_h − D_h D_g) / (D_h D_g).
            let den = poly_mul(&h.den, &g.den);
            let minus: Vec<f64> = den.iter().map(|x| -x).collect();
            let num = poly_add(
                &poly_add(&poly_mul(&h.num, &g.den), &poly_mul(&g.num, &h.den)),
                &minus,
            );
            h = Self { num, den };
        }
        Some(h)
    }

    /// The direct gain `N(0)` (`D(0) = 1`).
    fn gain(&self) -> f64 {
        self.num.first().copied().unwrap_or(1.0)
    }
}

/// The two noise sources per channel (module docs): the measured wrench's σ_b and the
/// motion sensors' σ_m (N, N m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct NoiseModel {
    pub wrench: [f64; 6],
    pub motion: [f64; 6],
}

impl NoiseModel {
    /// Total variance of channel `c`, `σ_b² + σ_m²`.
    pub fn variance(&self, c: usize) -> f64 {
        self.wrench[c].powi(2) + self.motion[c].powi(2)
    }

    /// The same total σ per channel as `sigma`, split in the proportions of this model (half
    /// and half where it has none).
    pub fn scaled_to(&self, sigma: &[f64; 6]) -> NoiseModel {
        let mut out = *self;
        for c in 0..6 {
            let v = self.variance(c);
            let share = if v > 0.0 && v.is_finite() {
                self.wrench[c].powi(2) / v
            } else {
                0.5
            };
            out.wrench[c] = sigma[c] * share.sqrt();
            out.motion[c] = sigma[c] * (1.0 - share).sqrt();
        }
        out
    }
}

/// The whitening of a residual of a filtered target (module docs): the monic moving average
/// `C(z) = 1 + c₁ z⁻¹ + …` and `K` for a filter and the two variances `sb2`, `sm2`. `D r`
/// has the autocovariances `γ_k = σ_b² Σ n_i n_{i+k} + σ_m² Σ d_i d_{i+k}`, factored as
/// `K C(z) C(z⁻¹)`. First order in closed form; higher orders by the innovations algorithm
/// (the rows of the Cholesky factor of the banded Toeplitz covariance converge to `C`).
fn whitening(f: &ChannelFilter, sb2: f64, sm2: f64) -> (Vec<f64>, f64) {
    let q = f.num.len().max(f.den.len()) - 1;
    let gamma: Vec<f64> = (0..=q)
        .map(|k| {
            let auto = |p: &[f64]| {
                (0..p.len().saturating_sub(k))
                    .map(|i| p[i] * p[i + k])
                    .sum::<f64>()
            };
            sb2 * auto(&f.num) + sm2 * auto(&f.den)
        })
        .collect();
    let a_ = gamma[0];
    if a_.is_nan() || a_ <= 0.0 {
        return (vec![0.0; q], f64::MIN_POSITIVE);
    }
    if q == 1 {
        let b_ = gamma[1];
        if b_.abs() <= 1e-15 * a_ {
            return (vec![0.0], a_);
        }
        let disc = (a_ * a_ - 4.0 * b_ * b_).max(0.0).sqrt();
        let c = (a_ - disc) / (2.0 * b_);
        return (vec![c], b_ / c);
    }
    // Innovations algorithm for an MA(q): θ_{n,j} and v_n, kept for the last q rows.
    let gam = |h: usize| gamma.get(h).copied().unwrap_or(0.0);
    // rows[m] = (θ_{m,1..q}, v_m) of the rows n − q … n − 1.
    let mut rows: std::collections::VecDeque<(Vec<f64>, f64)> = std::collections::VecDeque::new();
    rows.push_back((vec![0.0; q], a_));
    let mut last = (vec![0.0; q], a_);
    for _n in 1..20_000 {
        // θ_{n,n−k} for the q most recent k: k = n − j, j = 1..q.
        let mut theta = vec![0.0; q];
        let len = rows.len();
        for j in (1..=q.min(len)).rev() {
            // Row k = n − j is rows[len − j].
            let tk = &rows[len - j].0;
            let vk = rows[len - j].1;
            let mut acc = gam(j);
            // Σ_{i} θ_{k,k−i} θ_{n,n−i} v_i over the rows i < k kept.
            for i in j + 1..=q.min(len) {
                let (_, vi) = rows[len - i];
                // θ_{k,k−i'} with i' = n − i: lag (n − j) − (n − i) = i − j.
                acc -= tk[i - j - 1] * theta[i - 1] * vi;
            }
            theta[j - 1] = acc / vk;
        }
        let v = a_
            - (1..=q.min(len))
                .map(|j| theta[j - 1] * theta[j - 1] * rows[len - j].1)
                .sum::<f64>();
        let v = v.max(f64::MIN_POSITIVE);
        let done = theta
            .iter()
            .zip(&last.0)
            .all(|(x, y)| (x - y).abs() <= 1e-13 * (1.0 + x.abs()))
            && (v - last.1).abs() <= 1e-13 * v;
        last = (theta.clone(), v);
        rows.push_back((theta, v));
        if rows.len() > q {
            rows.pop_front();
        }
        if done {
            break;
        }
    }
    last
}

/// One channel's score over one stretch of residual `r` (module docs): the innovations'
/// sum of squares in units of K, and the log-determinant term, both in units of the
/// channel's total variance `σ_b² + σ_m²`.
pub(crate) fn channel_score(
    r: &[f64],
    filter: Option<&ChannelFilter>,
    sb: f64,
    sm: f64,
) -> (f64, f64) {
    let (sb2, sm2) = (sb * sb, sm * sm);
    let total = (sb2 + sm2).max(f64::MIN_POSITIVE);
    let Some(f) = filter else {
        return (r.iter().map(|x| x * x).sum::<f64>() / total, 0.0);
    };
    let (c, k) = whitening(f, sb2, sm2);
    let k = k.max(f64::MIN_POSITIVE);
    let mut sum = 0.0;
    innovations(r, &f.den, &c, |v| sum += v * v);
    let n = r.len() as f64;
    let logdet = n * (k / total).ln() - 2.0 * n * f.gain().abs().max(f64::MIN_POSITIVE).ln();
    (sum / k, logdet)
}

/// The whitened residual of one stretch, in the channel's units (`W r · σ / √K`): white
/// with the channel's variance at the true model. Without a filter, `r` itself.
pub(crate) fn whitened(r: &[f64], filter: Option<&ChannelFilter>, sb: f64, sm: f64) -> Vec<f64> {
    let Some(f) = filter else {
        return r.to_vec();
    };
    let (sb2, sm2) = (sb * sb, sm * sm);
    let (c, k) = whitening(f, sb2, sm2);
    let scale = ((sb2 + sm2) / k.max(f64::MIN_POSITIVE)).sqrt();
    let mut out = Vec::with_capacity(r.len());
    innovations(r, &f.den, &c, |v| out.push(v * scale));
    out
}

/// The innovations of a stretch `r` under the whitening `W(z) = D(z) / C(z)` (module docs;
/// `den` = `D`, monic; `c` = `c₁ …` of the monic `C`), in order, from zero before the
/// stretch: `vᵢ = Σ_j d_j rᵢ₋ⱼ − Σ_{j≥1} c_j vᵢ₋ⱼ`. First order: `v₀ = r₀`,
/// `vᵢ = rᵢ − a rᵢ₋₁ − c vᵢ₋₁`.
fn innovations(r: &[f64], den: &[f64], c: &[f64], mut each: impl FnMut(f64)) {
    if let ([_, d1], [c1]) = (den, c) {
        let (mut prev_r, mut prev_v) = (0.0, 0.0);
        for (i, &x) in r.iter().enumerate() {
            let v = if i == 0 {
                x
            } else {
                x + d1 * prev_r - c1 * prev_v
            };
            each(v);
            prev_r = x;
            prev_v = v;
        }
        return;
    }
    let mut v: Vec<f64> = Vec::with_capacity(r.len());
    for i in 0..r.len() {
        let mut x = 0.0;
        for (j, d) in den.iter().enumerate().take(i + 1) {
            x += d * r[i - j];
        }
        for (j, cj) in c.iter().enumerate().take(i) {
            x -= cj * v[i - 1 - j];
        }
        v.push(x);
        each(x);
    }
}

/// The ratio by which a filter's inverse raises the second-difference (high-frequency)
/// power of white noise: what the noise estimate of a residual mapped back through the
/// inverse filter sees of the motion sensors' noise (a numerical integral over frequency).
pub(crate) fn inverse_gain(f: &ChannelFilter) -> f64 {
    const POINTS: usize = 512;
    // |P(e^{iω})|² of a polynomial in z⁻¹.
    let power = |p: &[f64], w: f64| {
        let (mut re, mut im) = (0.0, 0.0);
        for (k, x) in p.iter().enumerate() {
            re += x * (k as f64 * w).cos();
            im += x * (k as f64 * w).sin();
        }
        re * re + im * im
    };
    let (mut num, mut den) = (0.0, 0.0);
    for k in 0..POINTS {
        let w = std::f64::consts::PI * (k as f64 + 0.5) / POINTS as f64;
        // |1 − z⁻¹|⁴ = (2 − 2 cos ω)².
        let d2 = (2.0 - 2.0 * w.cos()).powi(2);
        // |H|⁻² = |D|² / |N|².
        num += d2 * power(&f.den, w) / power(&f.num, w).max(f64::MIN_POSITIVE);
        den += d2;
    }
    num / den
}

/// The sample ranges of the logs joined in `s` (the whole log for a single one).
pub(crate) fn part_ranges(s: &Signals) -> Vec<std::ops::Range<usize>> {
    let parts = s.parts();
    if parts.is_empty() {
        let whole = 0..s.len();
        return vec![whole];
    }
    let mut out = Vec::with_capacity(parts.len());
    let mut lo = 0;
    for p in parts {
        out.push(lo..lo + p.len());
        lo += p.len();
    }
    out
}

/// The robust high-frequency noise estimate of each channel of `series`: the median of the
/// squared second differences over `6 × 0.4549` (for white noise `Δ²e` has variance `6 σ²`;
/// a residual that varies slowly with the flight has almost none). Second differences never
/// cross a join of several logs. 0 where no part has three samples.
pub(crate) fn high_frequency_noise(s: &Signals, series: &[[f64; 6]]) -> [f64; 6] {
    let ranges = part_ranges(s);
    // One buffer for the six channels.
    let mut d2: Vec<f64> = Vec::with_capacity(series.len());
    std::array::from_fn(|c| {
        d2.clear();
        for r in &ranges {
            for w in series[r.clone()].windows(3) {
                let d = w[2][c] - 2.0 * w[1][c] + w[0][c];
                if d.is_finite() {
                    d2.push(d * d);
                }
            }
        }
        crate::stats::noise_from_squared_second_differences(&mut d2)
    })
}

/// The filter of each channel by the filtering effects of `effects` (at their parameters) on
/// `s`: all of them composed ([`ChannelFilter::compose`]; their order does not matter),
/// `None` where none filters the channel.
pub(crate) fn channel_filters(
    effects: &[(crate::EffectRef, Option<f64>)],
    s: &Signals,
) -> [Option<ChannelFilter>; 6] {
    std::array::from_fn(|c| {
        let parts: Vec<TargetFilter> = effects
            .iter()
            .filter_map(|(e, p)| e.target_filter(s, *p, c))
            .collect();
        ChannelFilter::compose(&parts)
    })
}

/// The two noise sources of each channel from a model's residual `e` of the measured wrench
/// (its filters undone): with `b` the measured wrench and `p = b − e` the prediction, both
/// share the flight's own high-frequency motion `J`, so `HF(b)² = J² + σ_b²`,
/// `HF(p)² = J² + G σ_m²` and `HF(e)² = σ_b² + G σ_m²` (`G` the inverse filter's gain of
/// the channel, [`inverse_gain`]; 1 without a filter): `σ_b² = (HF(b)² − HF(p)² + HF(e)²)/2`
/// and `σ_m² = (HF(e)² − σ_b²) / G`. Returns the model and the raw estimate `HF(e)`.
pub(crate) fn estimate_noise(
    s: &Signals,
    e: &[[f64; 6]],
    filters: &[Option<ChannelFilter>; 6],
) -> (NoiseModel, [f64; 6]) {
    let hf_e = high_frequency_noise(s, e);
    let hf_b = high_frequency_noise(s, s.target());
    let predicted: Vec<[f64; 6]> = s
        .target()
        .iter()
        .zip(e)
        .map(|(b, r)| std::array::from_fn(|c| b[c] - r[c]))
        .collect();
    let hf_p = high_frequency_noise(s, &predicted);
    let mut model = NoiseModel {
        wrench: [0.0; 6],
        motion: [0.0; 6],
    };
    for c in 0..6 {
        let e2 = hf_e[c] * hf_e[c];
        let b2 = (0.5 * (hf_b[c].powi(2) - hf_p[c].powi(2) + e2)).clamp(0.0, e2);
        let g = filters[c].as_ref().map_or(1.0, inverse_gain).max(1.0);
        model.wrench[c] = b2.sqrt();
        model.motion[c] = ((e2 - b2).max(0.0) / g).sqrt();
    }
    (model, hf_e)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand_chacha::ChaCha8Rng;
    use rand_core::SeedableRng;

    /// A filtered white noise plus a white noise: the whitening gives innovations of the
    /// stated variance, uncorrelated at lag 1, and the score's limits are those of the docs.
    #[test]
    fn the_whitening_whitens_and_its_limits_hold() {
        let f = TargetFilter {
            g0: 0.4,
            g1: 0.2,
            a: 0.4,
        };
        // A seeded pair of white sequences.
        let mut rng = ChaCha8Rng::seed_from_u64(12345);
        let mut gauss = || crate::testdata::gauss(&mut rng);
        let n = 200_000;
        let (sb, sm) = (1.0, 0.7);
        let eps: Vec<f64> = (0..n).map(|_| sb * gauss()).collect();
        let eta: Vec<f64> = (0..n).map(|_| sm * gauss()).collect();
        let mut r = vec![0.0; n];
        let mut y = 0.0;
        for k in 0..n {
            let prev = if k > 0 { eps[k - 1] } else { 0.0 };
            y = f.g0 * eps[k] + f.g1 * prev + f.a * y;
            r[k] = y - eta[k];
        }
        let w = whitened(&r, Some(&ChannelFilter::from(&f)), sb, sm);
        let total = sb * sb + sm * sm;
        let var = w.iter().map(|x| x * x).sum::<f64>() / n as f64;
        assert!((var / total - 1.0).abs() < 0.02, "whitened variance {var}");
        let lag1 = w.windows(2).map(|p| p[0] * p[1]).sum::<f64>() / n as f64 / var;
        assert!(lag1.abs() < 0.01, "lag-1 correlation {lag1}");
        // σ_m = 0: the score is the sum of squares of L⁻¹ r in units of σ_b².
        let (norm, logdet) = channel_score(&r[..10], Some(&ChannelFilter::from(&f)), 1.0, 0.0);
        let mut inv = Vec::new();
        let (mut prev_y, mut prev_u) = (0.0, 0.0);
        for (k, &x) in r[..10].iter().enumerate() {
            let u = if k == 0 {
                x / f.g0
            } else {
                (x - f.a * prev_y - f.g1 * prev_u) / f.g0
            };
            inv.push(u);
            prev_y = x;
            prev_u = u;
        }
        let direct: f64 = inv.iter().map(|u| u * u).sum();
        assert!((norm - direct).abs() <= 1e-9 * direct, "{norm} vs {direct}");
        assert!(logdet.abs() < 1e-9);
    }

    /// Without a filter the inverse gain is 1; a lag's inverse raises the high frequencies.
    #[test]
    fn the_inverse_gain_of_a_lag_exceeds_one() {
        let none = TargetFilter {
            g0: 1.0,
            g1: 0.0,
            a: 0.0,
        };
        assert!((inverse_gain(&ChannelFilter::from(&none)) - 1.0).abs() < 1e-12);
        let a: f64 = (-1.0f64).exp();
        let g = a.sqrt();
        let lag = TargetFilter {
            g0: 1.0 - g,
            g1: g - a,
            a,
        };
        assert!(inverse_gain(&ChannelFilter::from(&lag)) > 2.0);
    }

    /// Two filters of one channel (a telemetry filter's inverse and a motor lag) compose as
    /// `H = 1 + (F − 1) + (L − 1)`, in either order. Checked against a direct simulation of
    /// each filter's own recursion: the whitened residual of `H ε − η` is white with the total
    /// variance, and with `σ_m = 0` the score is the sum of squares of `H⁻¹ r` (a direct
    /// inverse recursion of the composed filter's polynomials).
    #[test]
    fn two_filters_compose_in_either_order() {
        let alpha: f64 = 0.45;
        let tel = TargetFilter {
            g0: 1.0 / (1.0 - alpha),
            g1: -alpha / (1.0 - alpha),
            a: 0.0,
        };
        let lag = TargetFilter {
            g0: 0.3,
            g1: 0.15,
            a: 0.55,
        };
        let h = ChannelFilter::compose(&[tel, lag]).unwrap();
        assert_eq!(h.num.len(), 3);
        let mut rng = ChaCha8Rng::seed_from_u64(777);
        let mut gauss = || crate::testdata::gauss(&mut rng);
        let n = 200_000;
        let (sb, sm) = (1.0, 0.6);
        let eps: Vec<f64> = (0..n).map(|_| sb * gauss()).collect();
        let eta: Vec<f64> = (0..n).map(|_| sm * gauss()).collect();
        // Each filter by its own recursion, the known parts added.
        let (mut y, mut r) = (0.0, vec![0.0; n]);
        for k in 0..n {
            let prev = if k > 0 { eps[k - 1] } else { 0.0 };
            y = lag.g0 * eps[k] + lag.g1 * prev + lag.a * y;
            let f = tel.g0 * eps[k] + tel.g1 * prev;
            r[k] = eps[k] + (f - eps[k]) + (y - eps[k]) - eta[k];
        }
        let total = sb * sb + sm * sm;
        for f in [h.clone(), ChannelFilter::compose(&[lag, tel]).unwrap()] {
            let w = whitened(&r, Some(&f), sb, sm);
            let var = w.iter().map(|x| x * x).sum::<f64>() / n as f64;
            assert!((var / total - 1.0).abs() < 0.02, "whitened variance {var}");
            for lag_k in 1..4 {
                let rho =
                    w.windows(lag_k + 1).map(|p| p[0] * p[lag_k]).sum::<f64>() / n as f64 / var;
                assert!(rho.abs() < 0.01, "lag-{lag_k} correlation {rho}");
            }
        }
        let a = channel_score(&r, Some(&h), sb, sm);
        let b = channel_score(&r, ChannelFilter::compose(&[lag, tel]).as_ref(), sb, sm);
        assert!((a.0 - b.0).abs() <= 1e-9 * a.0 && (a.1 - b.1).abs() <= 1e-9 * a.1.abs().max(1.0));
        // σ_m = 0: Σ (H⁻¹ r)² / σ_b², H⁻¹ by N u = D r.
        let m = 50;
        let (norm, _) = channel_score(&r[..m], Some(&h), 1.0, 0.0);
        let mut u: Vec<f64> = Vec::new();
        for i in 0..m {
            let mut x: f64 = (0..h.den.len())
                .filter(|j| *j <= i)
                .map(|j| h.den[j] * r[i - j])
                .sum();
            for j in 1..h.num.len() {
                if j <= i {
                    x -= h.num[j] * u[i - j];
                }
            }
            u.push(x / h.num[0]);
        }
        let direct: f64 = u.iter().map(|x| x * x).sum();
        assert!((norm - direct).abs() <= 1e-6 * direct, "{norm} vs {direct}");
    }
}
