//! Small statistics toolbox: autocorrelation, effective sample size, chi-square tail.

/// Sample autocorrelation `ρ_k = Σ r̃ᵢ r̃ᵢ₊ₖ / Σ r̃ᵢ²` of the mean-removed series `r̃`, for
/// `k = 0..=max_lag` (`ρ₀ = 1`). A constant series gives `ρ_k = 0` for `k ≥ 1`.
pub fn autocorrelation(r: &[f64], max_lag: usize) -> Vec<f64> {
    let n = r.len();
    let mut out = vec![0.0; max_lag + 1];
    if n == 0 {
        return out;
    }
    out[0] = 1.0;
    let mean = r.iter().sum::<f64>() / n as f64;
    let c0: f64 = r.iter().map(|x| (x - mean) * (x - mean)).sum();
    if c0 <= 0.0 {
        return out;
    }
    for (k, o) in out.iter_mut().enumerate().skip(1) {
        if k >= n {
            break;
        }
        let mut s = 0.0;
        for i in 0..n - k {
            s += (r[i] - mean) * (r[i + k] - mean);
        }
        *o = s / c0;
    }
    out
}

/// Integrated autocorrelation factor `κ = 1 + 2 Σ_{k≥1} ρ_k`, the sum truncated at the first
/// non-positive `ρ_k` (initial-positive-sequence rule) or at `max_lag`; at least 1.
/// The effective sample size of `n` correlated samples is `n / κ`.
pub fn autocorrelation_factor(r: &[f64], max_lag: usize) -> f64 {
    let rho = autocorrelation(r, max_lag.min(r.len().saturating_sub(1)));
    let mut kappa = 1.0;
    for &p in rho.iter().skip(1) {
        if p <= 0.0 {
            break;
        }
        kappa += 2.0 * p;
    }
    kappa.max(1.0)
}

/// Long-run variance factor `κ` by the method of batch means: the series is cut into
/// batches of `B = max(⌊√n⌋, 10)` samples and `κ = B · var(batch means) / var(samples)`
/// (for white noise `κ ≈ 1`; for a correlated series the effective sample size is `n / κ`).
/// O(n), unlike a full autocorrelation sum. At least 1.
pub fn batch_means_factor(r: &[f64]) -> f64 {
    let n = r.len();
    let b = ((n as f64).sqrt() as usize).max(10);
    let nb = n / b;
    if nb < 4 {
        return autocorrelation_factor(r, n / 4);
    }
    let used = nb * b;
    let mean = r[..used].iter().sum::<f64>() / used as f64;
    let var = r[..used]
        .iter()
        .map(|x| (x - mean) * (x - mean))
        .sum::<f64>()
        / used as f64;
    if var <= 0.0 {
        return 1.0;
    }
    let mut vb = 0.0;
    for k in 0..nb {
        let m = r[k * b..(k + 1) * b].iter().sum::<f64>() / b as f64;
        vb += (m - mean) * (m - mean);
    }
    vb /= (nb - 1) as f64;
    (b as f64 * vb / var).max(1.0)
}

/// Natural log of the gamma function for `x > 0` (Stirling series after shifting `x ≥ 8`;
/// absolute error below 1e-12).
pub fn ln_gamma(x: f64) -> f64 {
    let mut x = x;
    let mut shift = 0.0;
    while x < 8.0 {
        shift -= x.ln();
        x += 1.0;
    }
    let x2 = x * x;
    let series = 1.0 / (12.0 * x) - 1.0 / (360.0 * x * x2) + 1.0 / (1260.0 * x * x2 * x2)
        - 1.0 / (1680.0 * x * x2 * x2 * x2);
    shift + (x - 0.5) * x.ln() - x + 0.5 * (2.0 * std::f64::consts::PI).ln() + series
}

/// Regularised upper incomplete gamma `Q(a, x) = Γ(a, x) / Γ(a)` for `a > 0`, `x ≥ 0`
/// (series for `x < a + 1`, Lentz continued fraction otherwise).
pub fn gamma_q(a: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 1.0;
    }
    let ln_pre = -x + a * x.ln() - ln_gamma(a);
    if x < a + 1.0 {
        // P(a, x) = e^{-x} x^a / Γ(a+1) Σ x^n / ((a+1)…(a+n))
        let mut term = 1.0 / a;
        let mut sum = term;
        let mut ap = a;
        for _ in 0..10_000 {
            ap += 1.0;
            term *= x / ap;
            sum += term;
            if term.abs() < sum.abs() * 1e-16 {
                break;
            }
        }
        (1.0 - sum * ln_pre.exp()).clamp(0.0, 1.0)
    } else {
        let tiny = 1e-300;
        let mut b = x + 1.0 - a;
        let mut c = 1.0 / tiny;
        let mut d = 1.0 / b;
        let mut h = d;
        for i in 1..10_000 {
            let an = -(i as f64) * (i as f64 - a);
            b += 2.0;
            d = an * d + b;
            if d.abs() < tiny {
                d = tiny;
            }
            c = b + an / c;
            if c.abs() < tiny {
                c = tiny;
            }
            d = 1.0 / d;
            let del = d * c;
            h *= del;
            if (del - 1.0).abs() < 1e-16 {
                break;
            }
        }
        (ln_pre.exp() * h).clamp(0.0, 1.0)
    }
}

/// Upper tail `P(X > x)` of a chi-square variable with `k` degrees of freedom.
pub fn chi2_survival(x: f64, k: f64) -> f64 {
    gamma_q(0.5 * k, 0.5 * x)
}

/// The `1 − p` quantile of χ² with `k` degrees of freedom (bisection on
/// [`chi2_survival`]).
pub fn chi2_quantile(p: f64, k: f64) -> f64 {
    let (mut lo, mut hi) = (0.0, 1.0);
    while chi2_survival(hi, k) > p {
        hi *= 2.0;
        if hi > 1e9 {
            return hi;
        }
    }
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if chi2_survival(mid, k) > p {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    hi
}

/// The 95 % quantile of χ²₁.
pub const CHI2_1_95: f64 = 3.841_458_820_694_124;

/// The median of χ²₁: the robust scale of squared Gaussian values.
pub const CHI2_1_MEDIAN: f64 = 0.454_936_423_119_572_8;

/// Median of a slice (NaN-free input); 0 for an empty slice.
pub fn median(x: &[f64]) -> f64 {
    if x.is_empty() {
        return 0.0;
    }
    let mut v = x.to_vec();
    v.sort_by(|a, b| a.total_cmp(b));
    let m = v.len() / 2;
    if v.len() % 2 == 1 {
        v[m]
    } else {
        0.5 * (v[m - 1] + v[m])
    }
}

/// Quantile by linear interpolation of the sorted sample (`q ∈ [0, 1]`).
pub fn quantile(sorted: &[f64], q: f64) -> f64 {
    if sorted.is_empty() {
        return 0.0;
    }
    let pos = q.clamp(0.0, 1.0) * (sorted.len() - 1) as f64;
    let lo = pos.floor() as usize;
    let hi = pos.ceil() as usize;
    let f = pos - lo as f64;
    sorted[lo] * (1.0 - f) + sorted[hi] * f
}

/// Root mean square (0 for an empty slice).
pub fn rms(x: &[f64]) -> f64 {
    if x.is_empty() {
        return 0.0;
    }
    (x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64).sqrt()
}

/// The robust high-frequency noise of one series: the median of its squared second
/// differences over `6 × 0.4549` (the estimate of the quadrotor's noise per channel, for one
/// series without joins). For white noise of deviation `σ` it is `σ`; a slowly varying part
/// adds almost nothing. 0 for fewer than 3 finite samples.
pub fn second_difference_noise(x: &[f64]) -> f64 {
    let mut d2: Vec<f64> = x
        .windows(3)
        .map(|w| w[2] - 2.0 * w[1] + w[0])
        .filter(|d| d.is_finite())
        .map(|d| d * d)
        .collect();
    noise_from_squared_second_differences(&mut d2)
}

/// The deviation `σ` of white noise whose squared second differences are `d2`: their median
/// over `6 × 0.4549` (`Δ²e` has variance `6 σ²`). The slice is reordered. 0 when it is empty.
pub fn noise_from_squared_second_differences(d2: &mut [f64]) -> f64 {
    if d2.is_empty() {
        return 0.0;
    }
    let mid = d2.len() / 2;
    let (_, m, _) = d2.select_nth_unstable_by(mid, f64::total_cmp);
    (*m / (6.0 * CHI2_1_MEDIAN)).sqrt()
}

/// Sample cross-correlation of two series at lags `−max_lag..=max_lag` (index `k + max_lag`):
/// `ρ_xy(k) = Σᵢ x̃ᵢ ỹᵢ₊ₖ / √(Σ x̃² Σ ỹ²)` of the mean-removed series (positive `k`: `x` leads
/// `y`), the normalisation of MATLAB's `resid`. Zeros when either series is constant. The
/// plain reference the residual–input correlation is checked against.
#[cfg(test)]
pub fn cross_correlation(x: &[f64], y: &[f64], max_lag: usize) -> Vec<f64> {
    let n = x.len().min(y.len());
    let mut out = vec![0.0; 2 * max_lag + 1];
    if n == 0 {
        return out;
    }
    let mx = x[..n].iter().sum::<f64>() / n as f64;
    let my = y[..n].iter().sum::<f64>() / n as f64;
    let sx: f64 = x[..n].iter().map(|v| (v - mx) * (v - mx)).sum();
    let sy: f64 = y[..n].iter().map(|v| (v - my) * (v - my)).sum();
    let norm = (sx * sy).sqrt();
    if norm <= 0.0 || !norm.is_finite() {
        return out;
    }
    for (idx, o) in out.iter_mut().enumerate() {
        let k = idx as i64 - max_lag as i64;
        let mut s = 0.0;
        for i in 0..n as i64 {
            let j = i + k;
            if j >= 0 && j < n as i64 {
                s += (x[i as usize] - mx) * (y[j as usize] - my);
            }
        }
        *o = s / norm;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A deterministic irregular series (no RNG needed).
    fn series(n: usize) -> Vec<f64> {
        (0..n)
            .map(|i| ((i * 7919 % 113) as f64 - 56.0) / 13.0 + (0.37 * i as f64).sin())
            .collect()
    }

    #[test]
    fn cross_correlation_of_a_series_with_itself_is_its_autocorrelation() {
        let x = series(400);
        let acf = autocorrelation(&x, 10);
        let ccf = cross_correlation(&x, &x, 10);
        for k in 0..=10 {
            assert!((ccf[10 + k] - acf[k]).abs() < 1e-12, "lag {k}");
            assert!((ccf[10 - k] - acf[k]).abs() < 1e-12, "lag -{k}");
        }
    }

    #[test]
    fn a_delayed_copy_peaks_at_its_delay() {
        let x = series(500);
        // y lags x by 3 samples: y[i] = x[i − 3].
        let y: Vec<f64> = (0..500)
            .map(|i| if i >= 3 { x[i - 3] } else { 0.0 })
            .collect();
        let ccf = cross_correlation(&x, &y, 6);
        let peak = (0..ccf.len())
            .max_by(|&a, &b| ccf[a].total_cmp(&ccf[b]))
            .unwrap();
        assert_eq!(peak as i64 - 6, 3);
        assert!(ccf[peak] > 0.95, "{}", ccf[peak]);
        assert!(
            cross_correlation(&x, &[1.0; 500], 2)
                .iter()
                .all(|v| *v == 0.0)
        );
    }
}
