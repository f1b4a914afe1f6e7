//! The scorer on constructed cases, the projection, and the draws.

use super::*;
use tagk_diagnose::{Coefficient, FittedEffect};
use tagk_dynamics::quadrotor::QuadrotorModel;

/// The nominal Crazyflie's parameters with a payload of 6 g.
fn params() -> [f64; 10] {
    let mut p = QuadrotorModel::crazyflie_2_1().params.to_array();
    p[0] += 0.006;
    p
}

fn true_effect(name: &str, strength: f64, detectable: bool) -> TrueEffect {
    let family = EffectKind::from_name(name).map_or(name.to_string(), |k| k.family().to_string());
    TrueEffect {
        name: name.into(),
        family,
        strength: [strength, 0.0, 0.0, 0.0, 0.0, 0.0],
        max_strength: strength,
        detectable,
        whiteness: 0.0,
    }
}

fn expected(effect: &str, name: &str, kind: CoefficientKind, value: f64) -> ExpectedCoefficient {
    ExpectedCoefficient {
        effect: effect.into(),
        name: name.into(),
        kind,
        value,
        scale: value.abs(),
        // A drag law's coefficients are ambiguous next to a wind (as the ground truth says).
        unless_with: if effect.ends_with("drag") {
            vec!["wind".into()]
        } else {
            Vec::new()
        },
    }
}

/// A flight with a detectable linear drag (d = 7e-3 N s/m on every axis) and a detectable
/// 20 ms motor lag.
fn truth() -> GroundTruth {
    let p = params();
    GroundTruth {
        sensing: SensingProfile::RealisticCalibrated,
        known_mass: false,
        noise: [1e-3, 1e-3, 1e-3, 1e-5, 1e-5, 1e-5],
        residual_rms: [1e-3, 1e-3, 1e-3, 1e-5, 1e-5, 1e-5],
        resolution: [3e-5, 3e-5, 3e-5, 1e-6, 1e-6, 1e-6],
        effects: vec![
            true_effect("linear-drag", 5.0, true),
            true_effect("motor-lag", 2.0, true),
        ],
        expected: vec![
            expected("linear-drag", "d_x", CoefficientKind::Coefficient, 7e-3),
            expected("linear-drag", "d_y", CoefficientKind::Coefficient, 7e-3),
            expected("linear-drag", "d_z", CoefficientKind::Coefficient, 8e-3),
            expected("motor-lag", "tau", CoefficientKind::Scanned, 0.02),
        ],
        mass: p[0],
        identifiable_mass: p[0],
        params: p,
        detectable_threshold: 1.0,
        constant_heading: false,
        whiteness_limit: 0.02,
        noise_whiteness: [0.0; 6],
    }
}

fn fitted(
    effect: &str,
    coefficients: Vec<Coefficient>,
    scanned: Option<(&str, f64)>,
) -> FittedEffect {
    FittedEffect {
        effect: effect.into(),
        description: String::new(),
        scanned: scanned.map(|(n, v)| (n.to_string(), v, "s".to_string())),
        scanned_interval: scanned.map(|(_, v)| [v - 0.002, v + 0.002]),
        coefficients,
        derived: Vec::new(),
        plausible: true,
        plausibility_note: String::new(),
        limited_by: String::new(),
    }
}

/// A diagnosis that reports exactly the truth, with intervals of ±2 standard errors.
fn exact_outcome() -> DiagnosisOutcome {
    let p = params();
    DiagnosisOutcome {
        final_effects: vec!["linear-drag".into(), "motor-lag".into()],
        fitted: vec![
            fitted(
                "linear-drag",
                vec![
                    Coefficient::new("d_x", "N s/m", 7e-3, Some(1e-4)),
                    Coefficient::new("d_y", "N s/m", 7.1e-3, Some(1e-4)),
                    Coefficient::new("d_z", "N s/m", 8e-3, Some(1e-4)),
                ],
                None,
            ),
            fitted(
                "motor-lag",
                vec![Coefficient::new("start_fz", "N", 0.0, Some(1.0))],
                Some(("tau", 0.021)),
            ),
        ],
        parameters: (0..10)
            .map(|j| Coefficient::new("p", "", p[j], Some(1e-9)))
            .collect(),
        adequate: true,
        held_out_rms: [1e-3, 1e-3, 1e-3, 1e-5, 1e-5, 1e-5],
        stopped: "at the floor".into(),
        equivalents: Vec::new(),
    }
}

#[test]
fn a_diagnosis_that_finds_exactly_the_truth_scores_full_marks() {
    let s = score_flight(&truth(), &exact_outcome());
    assert!(
        s.effects.iter().all(|e| e.found && e.found_in_family),
        "{s:?}"
    );
    assert!(s.false_effects.is_empty() && s.false_families.is_empty());
    assert_eq!(s.coefficients.len(), 4);
    assert!(s.coefficients.iter().all(|c| c.covered == Some(true)));
    let dy = s.coefficients.iter().find(|c| c.name == "d_y").unwrap();
    assert!((dy.relative_error.unwrap() - 0.1e-3 / 7e-3).abs() < 1e-12);
    assert_eq!(s.mass_error, 0.0);
    assert_eq!(s.inertia_error, [0.0; 3]);
    assert!(s.adequate_expected && s.adequate_right);
    assert!(s.implausible.is_empty(), "{:?}", s.implausible);
    let result = FlightResult {
        index: 0,
        spec: None,
        samples: 1000,
        score: Some(s),
        failure: None,
    };
    let summary = Summary::of(&BenchmarkOptions::default(), &[result]);
    let t = &summary.targets;
    assert_eq!((t[0].count, t[0].total, t[0].met), (2, 2, Some(true)));
    assert_eq!(t[1].total, 0); // no clean flight
    assert_eq!((t[2].count, t[2].total), (4, 4));
    assert_eq!((t[3].count, t[3].total, t[3].met), (1, 1, Some(true)));
    assert_eq!((t[4].count, t[5].count), (0, 0));
    assert_eq!((t[4].met, t[5].met), (Some(true), Some(true)));
    assert!(summary.markdown().contains(
        "| detectable effects found (own name or stand-in) | 100.0 % | 2/2 | ≥ 95 % | yes |"
    ));
}

#[test]
fn a_missing_detectable_effect_is_missed_and_adequate_is_then_wrong() {
    let mut outcome = exact_outcome();
    outcome.final_effects.retain(|e| e != "motor-lag");
    outcome.fitted.retain(|e| e.effect != "motor-lag");
    let s = score_flight(&truth(), &outcome);
    let lag = s.effects.iter().find(|e| e.name == "motor-lag").unwrap();
    assert!(!lag.found && !lag.found_in_family && lag.reported_as.is_none());
    assert!(!s.adequate_expected && !s.adequate_right);
    // The same miss of an undetectable effect is no miss for adequacy.
    let mut t = truth();
    t.effects[1].detectable = false;
    let s = score_flight(&t, &outcome);
    assert!(s.adequate_expected && s.adequate_right);
    // A time delay in its place is in the family, not by name.
    let mut outcome = exact_outcome();
    outcome.final_effects[1] = "time-delay".into();
    outcome.fitted[1].effect = "time-delay".into();
    let s = score_flight(&truth(), &outcome);
    let lag = s.effects.iter().find(|e| e.name == "motor-lag").unwrap();
    assert!(!lag.found && lag.found_in_family);
    assert_eq!(s.false_effects, vec!["time-delay".to_string()]);
    assert!(s.false_families.is_empty());
    // A delay is other physics than a lag: "adequate" was wrong.
    assert!(!s.adequate_expected && !s.adequate_right && !s.adequate_expected_by_name);
    // A drag law in another's place keeps the model adequate (the laws cannot always be told
    // apart, and another one is at the noise too).
    let mut outcome = exact_outcome();
    outcome.final_effects[0] = "rotor-drag".into();
    outcome.fitted[0].effect = "rotor-drag".into();
    let s = score_flight(&truth(), &outcome);
    assert!(s.adequate_expected && s.adequate_right && !s.adequate_expected_by_name);
}

/// "Not adequate" is right too when a missing effect lies between the adequacy factor's
/// strength and the detectability threshold.
#[test]
fn not_adequate_is_right_in_the_gray_zone() {
    let mut outcome = exact_outcome();
    outcome.final_effects.retain(|e| e != "motor-lag");
    outcome.fitted.retain(|e| e.effect != "motor-lag");
    outcome.adequate = false;
    let mut t = truth();
    t.effects[1].detectable = false;
    t.effects[1].max_strength = 0.9;
    let s = score_flight(&t, &outcome);
    assert!(s.adequate_expected && s.adequate_gray && s.adequate_right);
    t.effects[1].max_strength = 0.3;
    let s = score_flight(&t, &outcome);
    assert!(!s.adequate_gray && !s.adequate_right);
    // A weak but slow effect that makes the residual's autocorrelation exceed the whiteness
    // limit is in the gray zone too; "adequate" is then right as well.
    t.effects[1].whiteness = 0.03;
    let s = score_flight(&t, &outcome);
    assert!(s.adequate_gray && s.adequate_right);
    outcome.adequate = true;
    let s = score_flight(&t, &outcome);
    assert!(s.adequate_right);
    t.effects[1].whiteness = 0.01;
    outcome.adequate = false;
    let s = score_flight(&t, &outcome);
    assert!(!s.adequate_gray && !s.adequate_right);
}

/// A final model of the right effects whose held-out residual is beyond the adequacy factor
/// of the true noise (a form that differs from the plant's) is rightly "not adequate", and
/// "adequate" is then wrong; the rule by the effects alone said the opposite.
#[test]
fn adequate_is_judged_against_the_true_noise() {
    let mut outcome = exact_outcome();
    outcome.held_out_rms[5] = 1.3e-5;
    let s = score_flight(&truth(), &outcome);
    assert!(s.adequate_expected_by_effects && !s.at_true_noise);
    assert!(!s.adequate_expected && !s.adequate_right && s.adequate_right_by_effects);
    outcome.adequate = false;
    let s = score_flight(&truth(), &outcome);
    assert!(s.adequate_right && !s.adequate_right_by_effects);
    // Within the factor: at the noise.
    outcome.held_out_rms[5] = 1.19e-5;
    let s = score_flight(&truth(), &outcome);
    assert!(s.at_true_noise && s.adequate_expected && !s.adequate_right);
}

#[test]
fn interval_coverage_is_counted_right() {
    let mut outcome = exact_outcome();
    // d_x misses its truth (7e-3 outside [7.3e-3 ± 2e-4]); tau has no interval.
    outcome.fitted[0].coefficients[0] = Coefficient::new("d_x", "N s/m", 7.3e-3, Some(1e-4));
    outcome.fitted[1].scanned_interval = None;
    let s = score_flight(&truth(), &outcome);
    let by = |n: &str| s.coefficients.iter().find(|c| c.name == n).unwrap();
    assert_eq!(by("d_x").covered, Some(false));
    assert_eq!(by("d_y").covered, Some(true));
    assert_eq!(by("tau").covered, None);
    assert_eq!(by("tau").estimate, Some(0.021));
    let result = FlightResult {
        index: 0,
        spec: None,
        samples: 1000,
        score: Some(s),
        failure: None,
    };
    let summary = Summary::of(&BenchmarkOptions::default(), &[result]);
    let covered = &summary.targets[2];
    assert_eq!((covered.count, covered.total), (2, 3));
    let no_interval = summary
        .targets
        .iter()
        .find(|t| t.name.starts_with("compared coefficients without"))
        .unwrap();
    assert_eq!((no_interval.count, no_interval.total), (1, 4));
    // A drag next to a wind in the final model: its coefficients are not compared.
    let mut outcome = exact_outcome();
    outcome.final_effects.push("wind".into());
    let s = score_flight(&truth(), &outcome);
    assert_eq!(s.ambiguous_coefficients, 3);
    assert_eq!(s.coefficients.len(), 1);
    assert_eq!(s.false_effects, vec!["wind".to_string()]);
}

#[test]
fn an_accelerometer_bias_is_stood_for_by_a_body_bias() {
    let mut t = truth();
    t.effects = vec![true_effect(ACCEL_BIAS, 3.0, true)];
    t.expected.clear();
    let mut outcome = exact_outcome();
    outcome.final_effects = vec!["body-bias".into()];
    outcome.fitted.clear();
    let s = score_flight(&t, &outcome);
    assert!(s.effects[0].found && s.effects[0].found_in_family);
    assert_eq!(s.effects[0].reported_as.as_deref(), Some("body-bias"));
    assert!(s.false_effects.is_empty() && s.false_families.is_empty());
    // Without the sensor truth the same body bias is false.
    t.effects.clear();
    let s = score_flight(&t, &outcome);
    assert_eq!(s.false_effects, vec!["body-bias".to_string()]);
    // Adequacy is about what remains: a false effect does not make it wrong.
    assert!(s.is_clean() && s.adequate_right);
}

#[test]
fn implausible_final_models_are_flagged() {
    let mut outcome = exact_outcome();
    outcome.fitted[0].coefficients[2] = Coefficient::new("d_z", "N s/m", -3e-3, Some(5e-4));
    outcome.fitted[1].scanned = Some(("tau".into(), 0.2, "s".into()));
    let s = score_flight(&truth(), &outcome);
    assert_eq!(s.implausible.len(), 2, "{:?}", s.implausible);
    // A negative drag within its noise is plausible.
    let mut outcome = exact_outcome();
    outcome.fitted[0].coefficients[2] = Coefficient::new("d_z", "N s/m", -1e-4, Some(5e-4));
    assert!(score_flight(&truth(), &outcome).implausible.is_empty());
    // A thin body whose inertia does not fit its mass distribution: I_zz > I_xx + I_yy.
    let mut outcome = exact_outcome();
    outcome.parameters[9].value = 4e-5;
    let s = score_flight(&truth(), &outcome);
    assert!(
        s.implausible.iter().any(|m| m.contains("pseudo-inertia")),
        "{s:?}"
    );
    // The same inertia within 2 standard errors of a consistent one is no finding.
    outcome.parameters[9] = Coefficient::new("I_zz", "kg m²", 4e-5, Some(1e-5));
    assert!(score_flight(&truth(), &outcome).implausible.is_empty());
    outcome.parameters[0].value = -0.01;
    let s = score_flight(&truth(), &outcome);
    assert!(s.implausible.iter().any(|m| m.contains("not positive")));
}

/// Regressors of a wobbling flight (`a`, `ω`, `ω̇` of the same shape as the simulator's).
fn regressors(n: usize) -> Vec<[f64; 60]> {
    (0..n)
        .map(|k| {
            let t = k as f64 * 0.02;
            let a = Vector3::new(
                0.5 * (0.7 * t).sin(),
                0.4 * (1.1 * t).cos(),
                9.81 + 0.3 * (0.5 * t).sin(),
            );
            let w = Vector3::new(
                0.3 * (1.3 * t).sin(),
                0.2 * (0.9 * t).cos(),
                0.3 + 0.1 * (0.4 * t).sin(),
            );
            let wd = Vector3::new(
                0.39 * (1.3 * t).cos(),
                -0.18 * (0.9 * t).sin(),
                0.04 * (0.4 * t).cos(),
            );
            let mut y = [0.0; 60];
            tagk_dynamics::write_rigid_body_regressor(&a, &w, &wd, &mut y).unwrap();
            y
        })
        .collect()
}

#[test]
fn the_projection_removes_what_the_rigid_body_absorbs() {
    let ys = regressors(1500);
    let noise = [1e-3, 1e-3, 1e-3, 1e-5, 1e-5, 1e-5];
    // A force along the mass column, m a (a vertical bias trading with the mass): absorbed by a
    // free mass, not by a known one.
    let mass_like: Vec<[f64; 6]> = ys
        .iter()
        .map(|y| std::array::from_fn(|c| 0.003 * y[10 * c]))
        .collect();
    let free = RigidProjection::new(&ys, false, noise).strength(&mass_like);
    assert!(free.iter().all(|s| *s < 1e-9), "{free:?}");
    let known = RigidProjection::new(&ys, true, noise).strength(&mass_like);
    assert!(known[2] > 20.0, "{known:?}");
    // A constant horizontal force is not in the span: it keeps almost all its RMS.
    let bias: Vec<[f64; 6]> = ys.iter().map(|_| [2e-3, 0.0, 0.0, 0.0, 0.0, 0.0]).collect();
    let s = RigidProjection::new(&ys, false, noise).strength(&bias);
    assert!(s[0] > 1.0 && s[0] <= 2.0 + 1e-12, "{s:?}");
}

#[test]
fn draws_are_seeded_and_respect_the_physics() {
    let options = BenchmarkOptions::default();
    assert_eq!(
        draw_flight(&options, 5).unwrap(),
        draw_flight(&options, 5).unwrap()
    );
    assert_ne!(
        draw_flight(&options, 5).unwrap(),
        draw_flight(&options, 6).unwrap()
    );
    let other = BenchmarkOptions { seed: 1, ..options };
    assert_ne!(
        draw_flight(&options, 5).unwrap(),
        draw_flight(&other, 5).unwrap()
    );
    let mut counts = [0usize; 4];
    let mut sensing = [0usize; 3];
    let mut yaw_zero = 0;
    let n = 400;
    for i in 0..n {
        let f = draw_flight(&options, i).unwrap();
        let kinds = f.hidden_kinds();
        assert!(kinds.len() <= 3, "{kinds:?}");
        counts[kinds.len()] += 1;
        let drags = kinds
            .iter()
            .filter(|k| k.family() == EffectKind::LinearDrag.family())
            .count();
        assert!(drags <= 1, "{kinds:?}");
        if kinds.contains(&EffectKind::Wind) {
            assert_eq!(drags, 1, "{kinds:?}");
        }
        if kinds.contains(&EffectKind::ThrustGain) {
            assert!(f.known_mass);
        }
        if let Some(z) = f.altitude {
            assert!(
                kinds.contains(&EffectKind::GroundEffect) && z < 0.4,
                "{f:?}"
            );
        }
        assert!((10.0..40.0).contains(&f.duration));
        assert!(f.payload.mass > 0.0 && f.payload.attach_time == 0.0);
        sensing[SensingProfile::SYNTHETIC
            .iter()
            .position(|p| *p == f.sensing)
            .unwrap()] += 1;
        yaw_zero += usize::from(f.yaw_rate == 0.0);
    }
    // A quarter each, a third each, a half (loose: 400 draws).
    assert!(counts.iter().all(|c| (70..130).contains(c)), "{counts:?}");
    assert!(
        sensing.iter().all(|c| (100..170).contains(c)),
        "{sensing:?}"
    );
    assert!((160..240).contains(&yaw_zero), "{yaw_zero}");
}

/// The `Σ ρ_k²` a missing effect adds (`RigidProjection::whiteness`, from its own
/// autocorrelation) against the one measured on white noise plus that effect.
#[test]
fn a_missing_effects_whiteness_matches_a_noisy_residuals() {
    use rand::RngExt;
    use rand_chacha::rand_core::SeedableRng;
    let n = 4000;
    let ys = regressors(n);
    let noise = [1e-3, 1e-3, 1e-3, 1e-5, 1e-5, 1e-5];
    let projection = RigidProjection::new(&ys, false, noise);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    let mut gauss = || {
        // Box–Muller.
        let (u, v): (f64, f64) = (rng.random(), rng.random());
        (-2.0 * (1.0 - u).ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    };
    for amplitude in [5e-4, 1.5e-3] {
        // A slow force along x (a ground effect's kind of signal).
        let effect: Vec<[f64; 6]> = (0..n)
            .map(|k| {
                let t = k as f64 * 0.02;
                [amplitude * (0.23 * t).sin(), 0.0, 0.0, 0.0, 0.0, 0.0]
            })
            .collect();
        let predicted = projection.whiteness(&effect);
        let x: Vec<f64> = projection
            .residual(&effect)
            .iter()
            .map(|r| r[0] + gauss())
            .collect();
        let rho = tagk_diagnose::residual_autocorrelation(&x);
        let measured: f64 = rho.iter().map(|r| r * r).sum();
        // White noise alone has Σ ρ² ≈ K / n.
        let white = rho.len() as f64 / n as f64;
        assert!(
            (measured - white - predicted).abs() < 0.1 * predicted + 2.0 * white,
            "amplitude {amplitude}: measured {measured}, predicted {predicted} + {white}"
        );
        assert!(predicted > 0.02, "{predicted}");
    }
}
