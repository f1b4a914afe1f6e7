//! The firmware's RLS and Kalman filter (tagk-baselines' portable kernel over a borrowed
//! buffer, as `McuEstimator::build` makes them) against the host presets (faer backend): the
//! same math, so the same estimates and covariances up to round-off, on the same Table III
//! windows.

use tagk_baselines::{Backend, KalmanFilter as HostKf, Rls as HostRls};
use tagk_mcu::{
    EstimatorKind, KalmanConfig, KalmanFilter, McuEstimator, OnlineEstimator, Rls, RlsConfig,
    SyntheticWindows, buffer_len, covariance_buffer_len,
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
impl Covariance for Rls<f64, &mut [f64]> {
    fn cov(&self) -> &[f64] {
        self.covariance()
    }
}
impl Covariance for KalmanFilter<f64, &mut [f64]> {
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
    for (kind, n) in [
        (EstimatorKind::RlsLow, 10),
        (EstimatorKind::RlsLow, 40),
        (EstimatorKind::RlsHigh, 120),
    ] {
        let m = 30;
        let mut buf = vec![0.0; buffer_len(kind, n, m)];
        let McuEstimator::Rls(mut ours) = McuEstimator::build(kind, n, m, &mut buf).unwrap() else {
            panic!("{kind} is not RLS");
        };
        assert_eq!(ours.backend(), Backend::Loops);
        assert_eq!(
            ours.config(),
            &kind.rls_config().unwrap().with_backend(Backend::Loops)
        );
        let mut theirs = match kind {
            EstimatorKind::RlsLow => HostRls::rls_low(n, m),
            _ => HostRls::rls_high(n, m),
        }
        .unwrap();
        assert_eq!(theirs.backend(), Backend::Faer);
        let (de, dp) = worst_differences(n, m, WINDOWS, &mut ours, &mut theirs);
        println!("{kind} n={n}: |Δθ| ≤ {de:.1e}, |ΔP| ≤ {dp:.1e}");
        assert!(de < 1e-12 && dp < 1e-9, "{kind} n={n}: {de:e} {dp:e}");
    }
    // The presets are tagk-baselines' own.
    assert_eq!(EstimatorKind::RlsLow.rls_config(), Some(RlsConfig::LOW));
}

#[test]
fn kalman_filter_agrees_with_tagk_baselines() {
    // KF-low at n = 10 needs the information-form fallback (30 rows pin all 10 directions
    // far below P₀'s rounding level): it runs in a full buffer, which `build` accepts too;
    // `buffer_len`'s compact one refuses those windows (next test).
    for (kind, n, theta_tol, len) in [
        (
            EstimatorKind::KfLow,
            10,
            1e-5,
            covariance_buffer_len(10, 30),
        ),
        (
            EstimatorKind::KfLow,
            40,
            1e-7,
            buffer_len(EstimatorKind::KfLow, 40, 30),
        ),
        (
            EstimatorKind::KfHigh,
            120,
            1e-12,
            buffer_len(EstimatorKind::KfHigh, 120, 30),
        ),
    ] {
        let m = 30;
        let mut buf = vec![0.0; len];
        let McuEstimator::Kf(mut ours) = McuEstimator::build(kind, n, m, &mut buf).unwrap() else {
            panic!("{kind} is not a Kalman filter");
        };
        assert_eq!(ours.backend(), Backend::Loops);
        let mut theirs = match kind {
            EstimatorKind::KfLow => HostKf::kf_low(n, m),
            _ => HostKf::kf_high(n, m),
        }
        .unwrap();
        let (de, dp) = worst_differences(n, m, WINDOWS, &mut ours, &mut theirs);
        println!("{kind} n={n}: |Δθ| ≤ {de:.1e}, |ΔP| ≤ {dp:.1e}");
        assert!(de < theta_tol && dp < 1e-9, "{kind} n={n}: {de:e} {dp:e}");
    }
    assert_eq!(
        EstimatorKind::KfHigh.kalman_config(),
        Some(KalmanConfig::HIGH)
    );
}

#[test]
fn the_compact_buffer_refuses_windows_that_need_the_fallback_and_keeps_its_state() {
    let (kind, n, m) = (EstimatorKind::KfLow, 10, 30);
    let mut buf = vec![0.0; buffer_len(kind, n, m)];
    let McuEstimator::Kf(mut ours) = McuEstimator::build(kind, n, m, &mut buf).unwrap() else {
        panic!("{kind} is not a Kalman filter");
    };
    assert!(!ours.has_information_fallback());
    let mut full = HostKf::new(n, m, KalmanConfig::LOW.with_backend(Backend::Loops)).unwrap();
    assert!(full.has_information_fallback());
    let mut stream = SyntheticWindows::for_table(n, m);
    let (mut a, mut b) = (vec![0.0; m * n], vec![0.0; m]);
    stream.next_window(&mut a, &mut b);
    let (theta, p) = (ours.estimate().to_vec(), ours.covariance().to_vec());
    assert!(matches!(
        ours.update(&a, &b),
        Err(tagk_mcu::EstimatorError::NumericalFailure(_))
    ));
    assert_eq!(ours.estimate(), &theta[..]);
    assert_eq!(ours.covariance(), &p[..]);
    full.update(&a, &b).unwrap();
}
