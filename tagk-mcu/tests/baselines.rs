//! This crate's allocation-free RLS and Kalman filter against tagk-baselines' (heap, faer or
//! hand-written loops): the same math, so the same estimates and covariances up to round-off,
//! on the same Table III windows.

use tagk_baselines::{KalmanFilter as HostKf, Rls as HostRls};
use tagk_mcu::{
    KalmanFilter, KfConfig, OnlineEstimator, Rls, RlsConfig, SyntheticWindows,
    covariance_buffer_len,
};

/// `max |x − y|`.
fn max_abs_diff(x: &[f64], y: &[f64]) -> f64 {
    assert_eq!(x.len(), y.len());
    x.iter()
        .zip(y)
        .fold(0.0f64, |d, (a, b)| d.max((a - b).abs()))
}

/// Feeds both estimators the same `count` Table III windows (`m × n`) and returns the largest
/// differences of the estimate and of the covariance over all updates.
fn worst_differences<A, B>(
    n: usize,
    m: usize,
    count: usize,
    ours: &mut A,
    theirs: &mut B,
) -> (f64, f64)
where
    A: OnlineEstimator<f64> + Covariance,
    B: OnlineEstimator<f64> + Covariance,
{
    assert_eq!(ours.name(), theirs.name());
    let mut stream = SyntheticWindows::for_table(n, m);
    let (mut de, mut dp) = (0.0f64, 0.0f64);
    for _ in 0..count {
        let (mut a, mut b) = (vec![0.0; m * n], vec![0.0; m]);
        stream.next_window(&mut a, &mut b);
        ours.update(&a, &b).unwrap();
        theirs.update(&a, &b).unwrap();
        de = de.max(max_abs_diff(ours.estimate(), theirs.estimate()));
        dp = dp.max(max_abs_diff(ours.cov(), theirs.cov()));
    }
    (de, dp)
}

trait Covariance {
    fn cov(&self) -> &[f64];
}
impl Covariance for Rls<f64, Vec<f64>> {
    fn cov(&self) -> &[f64] {
        self.covariance()
    }
}
impl Covariance for KalmanFilter<f64, Vec<f64>> {
    fn cov(&self) -> &[f64] {
        self.covariance()
    }
}
impl Covariance for HostRls {
    fn cov(&self) -> &[f64] {
        self.covariance()
    }
}
impl Covariance for HostKf {
    fn cov(&self) -> &[f64] {
        self.covariance()
    }
}

// Tolerances. θ is O(1) here and P starts at P₀ = 10³·I, so ε·P₀ ≈ 2·10⁻¹³ is the round-off
// floor of any covariance entry. RLS's innovation covariance S = A P Aᵀ + λI is well
// conditioned. KF-low's (σ_R² = 10⁻¹⁰) has κ(S) ≈ P₀‖a‖²/σ_R² ≈ 10¹⁴ on the first window,
// which amplifies round-off of order ε to ≈ 10⁻⁶ in θ: two correct implementations with
// different summation orders (faer above n = 24) agree only to that. Covariances are compared
// to 10⁻⁹ = 10⁻¹²·P₀, a few thousand ε·P₀ (n = 120 sums 120-term products of O(P₀) values).
const WINDOWS: usize = 8;

#[test]
fn rls_agrees_with_tagk_baselines() {
    for (config, n) in [
        (RlsConfig::low(), 10),
        (RlsConfig::low(), 40),
        (RlsConfig::high(), 120),
    ] {
        let m = 30;
        let mut ours =
            Rls::with_storage(n, m, config, vec![0.0; covariance_buffer_len(n, m)]).unwrap();
        let mut theirs = match config.label {
            "RLS-low" => HostRls::rls_low(n, m),
            _ => HostRls::rls_high(n, m),
        }
        .unwrap();
        let (de, dp) = worst_differences(n, m, WINDOWS, &mut ours, &mut theirs);
        println!("{} n={n}: |Δθ| ≤ {de:.1e}, |ΔP| ≤ {dp:.1e}", config.label);
        assert!(
            de < 1e-12 && dp < 1e-9,
            "{} n={n}: {de:e} {dp:e}",
            config.label
        );
    }
}

#[test]
fn kalman_filter_agrees_with_tagk_baselines() {
    for (config, n, theta_tol) in [
        (KfConfig::low(), 10, 1e-5),
        (KfConfig::low(), 40, 1e-7),
        (KfConfig::high(), 120, 1e-12),
    ] {
        let m = 30;
        let mut ours =
            KalmanFilter::with_storage(n, m, config, vec![0.0; covariance_buffer_len(n, m)])
                .unwrap();
        let mut theirs = match config.label {
            "KF-low" => HostKf::kf_low(n, m),
            _ => HostKf::kf_high(n, m),
        }
        .unwrap();
        let (de, dp) = worst_differences(n, m, WINDOWS, &mut ours, &mut theirs);
        println!("{} n={n}: |Δθ| ≤ {de:.1e}, |ΔP| ≤ {dp:.1e}", config.label);
        assert!(
            de < theta_tol && dp < 1e-9,
            "{} n={n}: {de:e} {dp:e}",
            config.label
        );
    }
}
