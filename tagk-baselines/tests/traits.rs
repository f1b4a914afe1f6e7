//! Every estimator with owned storage is `Send + Sync + Clone + Debug`, and a clone continues
//! exactly as the original does.

mod common;

use common::*;
use tagk_baselines::{
    EstimatorKind, KalmanConfig, KalmanFilter, OnlineEstimator, Rls, RlsConfig,
    covariance_buffer_len,
};
use tagk_core::{GreedyKaczmarz, RandomizedKaczmarz, TagK, TailAveragedKaczmarz};

fn assert_owned_estimator<E: Send + Sync + Clone + core::fmt::Debug + 'static>() {}

#[test]
fn owned_estimators_are_send_sync_clone_debug() {
    assert_owned_estimator::<Rls>();
    assert_owned_estimator::<KalmanFilter>();
    assert_owned_estimator::<Rls<f32, Vec<f32>>>();
    assert_owned_estimator::<KalmanFilter<f32, [f32; covariance_buffer_len(3, 2)]>>();
    assert_owned_estimator::<TagK<f64, Vec<f64>>>();
    assert_owned_estimator::<TagK<f32, Vec<f32>>>();
    assert_owned_estimator::<GreedyKaczmarz<f64, Vec<f64>>>();
    assert_owned_estimator::<TailAveragedKaczmarz<f64, Vec<f64>>>();
    assert_owned_estimator::<RandomizedKaczmarz<f64, Vec<f64>>>();
    assert_owned_estimator::<RlsConfig>();
    assert_owned_estimator::<KalmanConfig>();
    assert_owned_estimator::<EstimatorKind>();
}

#[test]
fn a_clone_continues_bit_for_bit() {
    let (n, m) = (12, 8);
    let mut g = rng(5);
    let theta = random_vec(&mut g, n, 1.0);
    let stream = windows(&mut g, n, m, 12, &theta, 1e-3, false);
    let mut rls = Rls::rls_high(n, m).unwrap();
    let mut kf = KalmanFilter::kf_low(n, m).unwrap();
    let mut tagk = TagK::<f64, Vec<f64>>::new(n, m, tagk_core::tagk_paper_config()).unwrap();
    for w in &stream[..4] {
        rls.update(&w.a, &w.b).unwrap();
        kf.update(&w.a, &w.b).unwrap();
        tagk.update(&w.a, &w.b).unwrap();
    }
    let (mut rls2, mut kf2, mut tagk2) = (rls.clone(), kf.clone(), tagk.clone());
    assert_eq!(rls2.name(), "RLS-high");
    assert!(format!("{rls:?}").contains("RLS-high"));
    assert!(format!("{tagk:?}").contains("estimate"));
    for w in &stream[4..] {
        rls.update(&w.a, &w.b).unwrap();
        rls2.update(&w.a, &w.b).unwrap();
        assert_eq!(rls.estimate(), rls2.estimate());
        assert_eq!(rls.covariance(), rls2.covariance());
        kf.update(&w.a, &w.b).unwrap();
        kf2.update(&w.a, &w.b).unwrap();
        assert_eq!(kf.estimate(), kf2.estimate());
        assert_eq!(kf.covariance(), kf2.covariance());
        tagk.update(&w.a, &w.b).unwrap();
        tagk2.update(&w.a, &w.b).unwrap();
        assert_eq!(tagk.estimate(), tagk2.estimate());
    }
}

#[test]
fn estimator_kinds_parse_back_and_carry_the_presets() {
    for kind in EstimatorKind::ALL {
        assert_eq!(kind.name().parse::<EstimatorKind>(), Ok(kind));
        assert_eq!(kind.cli_name().parse::<EstimatorKind>(), Ok(kind));
        assert_eq!(kind.to_string(), kind.name());
        assert_eq!(
            kind.is_kaczmarz(),
            kind.rls_config().is_none() && kind.kalman_config().is_none()
        );
    }
    assert!("rls".parse::<EstimatorKind>().is_err());
    assert_eq!(EstimatorKind::RlsLow.rls_config(), Some(RlsConfig::LOW));
    assert_eq!(EstimatorKind::RlsHigh.rls_config(), Some(RlsConfig::HIGH));
    assert_eq!(
        EstimatorKind::KfLow.kalman_config(),
        Some(KalmanConfig::LOW)
    );
    assert_eq!(
        EstimatorKind::KfHigh.kalman_config(),
        Some(KalmanConfig::HIGH)
    );
    // The preset constructors are named as the kinds.
    assert_eq!(
        Rls::rls_low(3, 2).unwrap().name(),
        EstimatorKind::RlsLow.name()
    );
    assert_eq!(
        KalmanFilter::kf_high(3, 2).unwrap().name(),
        EstimatorKind::KfHigh.name()
    );
}
