//! Unit tests of the fitting machinery against independent computations (ground truth of
//! synthetic data, normal equations, brute-force cross-validation, closed forms).

use nalgebra::{DMatrix, DVector, Vector3};
use proptest::prelude::*;

use crate::EffectKind;
use crate::deriv::{savitzky_golay_derivative, savitzky_golay_smooth};
use crate::diagnose::{DiagnoseOptions, diagnose};
use crate::effects::{CustomEffect, Effect, builtin, first_order_lag, shifted};
use crate::fit::{
    ColData, Column, GramEngine, Model, channel_stats, fit_model, rigid_columns, weighted_qr_solve,
};
use crate::log::FlightLog;
use crate::signals::Signals;
use crate::stats;
use crate::testdata::{crazyflie, synthetic_log};
use crate::{DiagnoseError, LogError};

/// Stored columns as design columns.
fn stored(cols: &[ColData]) -> Vec<Column<'_>> {
    Column::stored(cols).collect()
}

fn none(_: &crate::testdata::State, _: &Vector3<f64>) -> [f64; 6] {
    [0.0; 6]
}

#[test]
fn fit_recovers_true_parameters_on_noise_free_data() {
    let theta = crazyflie().with_point_mass(0.01, Vector3::new(0.008, -0.005, 0.003));
    let log = synthetic_log(&theta, 800, 0.0, 1, &none);
    let s = Signals::from_log(&log).unwrap();
    let fit = Model::rigid_body().fit(&s).unwrap();
    for (k, (a, b)) in fit
        .theta
        .as_slice()
        .iter()
        .zip(theta.as_slice())
        .enumerate()
    {
        let scale = if k == 0 {
            0.045
        } else if k < 4 {
            1e-4
        } else {
            3e-5
        };
        assert!((a - b).abs() < 1e-6 * scale, "θ[{k}] {a} vs {b}");
    }
    for c in &fit.channels {
        assert!(c.rms < 1e-7, "{c:?}");
    }
}

#[test]
fn known_mass_is_kept_and_the_rest_recovered() {
    let theta = crazyflie();
    let log = synthetic_log(&theta, 600, 0.0, 2, &none);
    let s = Signals::from_log(&log).unwrap();
    let fit = Model::rigid_body().with_known_mass(0.035).fit(&s).unwrap();
    assert_eq!(fit.theta.mass(), 0.035);
    assert!(fit.theta_se[0].is_none());
    assert!((fit.theta.as_slice()[9] - 2.93e-5).abs() < 1e-10);
}

#[test]
fn qr_solution_matches_normal_equations() {
    let log = synthetic_log(&crazyflie(), 400, 5e-3, 3, &|_, vb| {
        [-0.02 * vb.x, 0.0, 0.0, 0.0, 0.0, 0.0]
    });
    let s = Signals::from_log(&log).unwrap();
    let cols = rigid_columns(&s);
    let w = [10.0, 10.0, 5.0, 1e4, 1e4, 2e4];
    let sol = weighted_qr_solve(&s, &stored(&cols), s.wrench(), &w, 1.0).unwrap();
    // Independent: dense normal equations with nalgebra.
    let n = s.len();
    let a = DMatrix::<f64>::from_fn(6 * n, 10, |r, j| {
        let (i, c) = (r / 6, r % 6);
        cols[j][c].as_ref().map_or(0.0, |v| v[i]) * w[c]
    });
    let b = DVector::<f64>::from_fn(6 * n, |r, _| s.wrench()[r / 6][r % 6] * w[r % 6]);
    let x = (a.transpose() * &a)
        .lu()
        .solve(&(a.transpose() * b))
        .unwrap();
    for j in 0..10 {
        assert!(
            (sol.beta[j] - x[j]).abs() <= 1e-6 * x[j].abs().max(1e-9),
            "β[{j}]"
        );
    }
}

/// The blocked QR ([`weighted_qr_solve`] factors 512 samples at a time) over many blocks,
/// the last one partial: coefficients and standard errors against the dense normal equations.
#[test]
fn blocked_qr_matches_normal_equations_over_several_blocks() {
    let log = synthetic_log(&crazyflie(), 10_000, 5e-3, 5, &|_, vb| {
        [-0.02 * vb.x, -0.01 * vb.y, 0.0, 0.0, 0.0, 0.0]
    });
    let s = Signals::from_log(&log).unwrap();
    let cols = rigid_columns(&s);
    let w = [10.0, 10.0, 5.0, 1e4, 1e4, 2e4];
    let sol = weighted_qr_solve(&s, &stored(&cols), s.wrench(), &w, 1.0).unwrap();
    let n = s.len();
    let a = DMatrix::<f64>::from_fn(6 * n, 10, |r, j| {
        let (i, c) = (r / 6, r % 6);
        cols[j][c].as_ref().map_or(0.0, |v| v[i]) * w[c]
    });
    let b = DVector::<f64>::from_fn(6 * n, |r, _| s.wrench()[r / 6][r % 6] * w[r % 6]);
    let ata_inv = (a.transpose() * &a).try_inverse().unwrap();
    let x = &ata_inv * (a.transpose() * &b);
    let rss = (&b - &a * &x).norm_squared();
    let sigma2 = rss / (6 * n - 10) as f64;
    for j in 0..10 {
        assert!(
            (sol.beta[j] - x[j]).abs() <= 1e-6 * x[j].abs().max(1e-9),
            "β[{j}]: {} vs {}",
            sol.beta[j],
            x[j]
        );
        let se = (sigma2 * ata_inv[(j, j)]).sqrt();
        let got = sol.se[j].unwrap();
        assert!((got - se).abs() <= 1e-4 * se, "se[{j}]: {got} vs {se}");
    }
}

#[test]
fn gram_cross_validation_matches_brute_force() {
    let log = synthetic_log(&crazyflie(), 500, 5e-3, 4, &|_, vb| {
        [-0.01 * vb.x, -0.01 * vb.y, 0.0, 0.0, 0.0, 0.0]
    });
    let s = Signals::from_log(&log).unwrap();
    let base = rigid_columns(&s);
    let cand: Vec<ColData> =
        crate::fit::effect_design(builtin(EffectKind::LinearDrag).unwrap().as_ref(), &s, None).cols;
    let w = [100.0, 100.0, 50.0, 1e5, 1e5, 1e5];
    let folds = 5;
    let engine = GramEngine::new(&s, &w, &stored(&base), None, folds);
    let ev = engine.evaluate(&cand);
    // Brute force: for each fold, QR-fit on the training samples (fold and one buffer of
    // 1 s = 100 samples on each side removed), SSE on the held-out fold.
    let n = s.len();
    let buffer = 100usize.min(n / (4 * folds));
    let mut all = base.clone();
    all.extend(cand.clone());
    let mut sse = 0.0;
    for k in 0..folds {
        let (a, b) = (k * n / folds, (k + 1) * n / folds);
        let lo = if k == 0 { a } else { a - buffer };
        let hi = if k + 1 == folds { b } else { b + buffer };
        let train: Vec<usize> = (0..n).filter(|&i| i < lo || i >= hi).collect();
        let sub = |col: &ColData, idx: &[usize]| -> ColData {
            std::array::from_fn(|c| col[c].as_ref().map(|v| idx.iter().map(|&i| v[i]).collect()))
        };
        let tcols: Vec<ColData> = all.iter().map(|c| sub(c, &train)).collect();
        let tb: Vec<[f64; 6]> = train.iter().map(|&i| s.wrench()[i]).collect();
        let sol = weighted_qr_solve(&s, &stored(&tcols), &tb, &w, 1.0).unwrap();
        for i in a..b {
            for c in 0..6 {
                let mut pred = 0.0;
                for (j, col) in all.iter().enumerate() {
                    pred += col[c].as_ref().map_or(0.0, |v| v[i]) * sol.beta[j];
                }
                sse += ((s.wrench()[i][c] - pred) * w[c]).powi(2);
            }
        }
    }
    assert!(
        (ev.sse_cv() - sse).abs() <= 1e-6 * sse,
        "{} vs {}",
        ev.sse_cv(),
        sse
    );
}

#[test]
fn hidden_linear_drag_in_synthetic_data_is_ranked_first_and_recovered() {
    let d = 0.012;
    let log = synthetic_log(&crazyflie(), 1500, 5e-4, 5, &|_, vb| {
        [-d * vb.x, -d * vb.y, -d * vb.z, 0.0, 0.0, 0.0]
    });
    let s = Signals::from_log(&log).unwrap();
    let diag = diagnose(&Model::rigid_body(), &s, &DiagnoseOptions::default()).unwrap();
    assert_eq!(
        diag.recommended.as_deref(),
        Some("linear-drag"),
        "{:?}",
        diag.ranking[0].explanation
    );
    let fit = fit_model(
        &Model::rigid_body().with_ref(builtin(EffectKind::LinearDrag).unwrap()),
        &s,
        None,
    )
    .unwrap();
    for c in &fit.effects[0].coefficients {
        assert!((c.value - d).abs() < 0.05 * d, "{c:?}");
    }
    assert!(fit.channels[0].rms < 0.1 * diag.channels[0].rms);
}

#[test]
fn clean_synthetic_data_is_adequate() {
    for seed in 10..13 {
        let log = synthetic_log(&crazyflie(), 1500, 5e-4, seed, &none);
        let s = Signals::from_log(&log).unwrap();
        let diag = diagnose(&Model::rigid_body(), &s, &DiagnoseOptions::default()).unwrap();
        assert_eq!(
            diag.recommended, None,
            "seed {seed}: {:?}",
            diag.ranking[0].explanation
        );
    }
}

#[test]
fn torque_bias_hidden_in_the_centre_of_mass_is_flagged() {
    // 0.02 N m about x on a 35 g vehicle: a COM 5.8 cm off to the side, beyond the airframe.
    let log = synthetic_log(&crazyflie(), 1000, 5e-4, 6, &|_, _| {
        [0.0, 0.0, 0.0, 0.02, 0.0, 0.0]
    });
    let s = Signals::from_log(&log).unwrap();
    let diag = diagnose(&Model::rigid_body(), &s, &DiagnoseOptions::default()).unwrap();
    assert!(
        diag.warnings
            .iter()
            .any(|w| w.contains("centre of mass outside the airframe")),
        "{:?}",
        diag.warnings
    );
    // Adding the bias brings the centre of mass back inside.
    let diag2 = diagnose(
        &Model::rigid_body().with_ref(builtin(EffectKind::BodyBias).unwrap()),
        &s,
        &DiagnoseOptions::default(),
    )
    .unwrap();
    assert!(
        diag2.com.iter().all(|c| c.abs() < 0.0325),
        "{:?}",
        diag2.com
    );
}

#[test]
fn fit_percent_matches_the_matlab_formula() {
    let b = vec![
        [1.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        [2.0; 6],
        [3.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    ];
    let r = vec![
        [0.1, 0.0, 0.0, 0.0, 0.0, 0.0],
        [-0.1; 6],
        [0.2, 0.0, 0.0, 0.0, 0.0, 0.0],
    ];
    let ch = channel_stats(&b, &r);
    let expected = 100.0 * (1.0 - (0.06f64).sqrt() / 2f64.sqrt());
    assert!((ch[0].fit_percent.unwrap() - expected).abs() < 1e-12);
    assert!((ch[0].rms - (0.02f64).sqrt()).abs() < 1e-15);
}

#[test]
fn chi_square_tail_matches_closed_forms() {
    for &x in &[0.1, 1.0, 3.0, 10.0, 40.0] {
        let q2 = stats::chi2_survival(x, 2.0);
        assert!(
            (q2 - (-x / 2.0f64).exp()).abs() < 1e-10 * (-x / 2.0f64).exp().max(1e-300) + 1e-14,
            "{x}: {q2}"
        );
        let k4 = (-x / 2.0f64).exp() * (1.0 + x / 2.0);
        assert!((stats::chi2_survival(x, 4.0) - k4).abs() < 1e-10 * k4 + 1e-14);
    }
    let mut fact = 1.0f64;
    for n in 1..20 {
        assert!((stats::ln_gamma(n as f64) - fact.ln()).abs() < 1e-10);
        fact *= n as f64;
    }
}

#[test]
fn batch_means_factor_of_ar1_matches_theory() {
    use rand_core::{Rng, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
    let mut g = || {
        let u1 = ((rng.next_u64() >> 11) as f64 + 0.5) / (1u64 << 53) as f64;
        let u2 = ((rng.next_u64() >> 11) as f64) / (1u64 << 53) as f64;
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    };
    let white: Vec<f64> = (0..40_000).map(|_| g()).collect();
    let kw = stats::batch_means_factor(&white);
    assert!((0.6..1.6).contains(&kw), "{kw}");
    let phi = 0.8;
    let mut x = 0.0;
    let ar: Vec<f64> = (0..40_000)
        .map(|_| {
            x = phi * x + g();
            x
        })
        .collect();
    let k = stats::batch_means_factor(&ar);
    let theory = (1.0 + phi) / (1.0 - phi);
    assert!((k / theory - 1.0).abs() < 0.35, "{k} vs {theory}");
    let rho = stats::autocorrelation(&ar, 3);
    assert!((rho[1] - phi).abs() < 0.02);
}

#[test]
fn first_order_lag_matches_the_step_response() {
    let dt = 0.01;
    let t: Vec<f64> = (0..100).map(|k| k as f64 * dt).collect();
    let u: Vec<f64> = (0..100).map(|k| if k == 0 { 0.0 } else { 1.0 }).collect();
    let tau = 0.03;
    let y = first_order_lag(&t, &u, tau);
    // The command switches at t_1 − dt/2; sample k ≥ 1 is (k − 1/2) dt after the switch.
    for k in 1..100 {
        let exact = 1.0 - (-((k as f64 - 0.5) * dt) / tau).exp();
        assert!((y[k] - exact).abs() < 1e-12, "k {k}");
    }
}

#[test]
fn custom_effect_spec_parses_and_rejects() {
    let c = CustomEffect::parse("batt=vbat*fz@fz,tz").unwrap();
    assert_eq!(c.name(), "batt");
    assert_eq!(c.channels(), vec![2, 5]);
    assert!(matches!(
        CustomEffect::parse("x=a@qq"),
        Err(DiagnoseError::BadCustomSpec { .. })
    ));
    assert!(matches!(
        CustomEffect::parse("noequals"),
        Err(DiagnoseError::BadCustomSpec { .. })
    ));
}

#[test]
fn custom_effect_from_a_log_column_is_found() {
    // A hidden force along body x proportional to an extra logged signal.
    let mut log = synthetic_log(&crazyflie(), 1200, 5e-4, 7, &|st, _| {
        [0.003 * (0.37 * st.p.x * 7.0).sin(), 0.0, 0.0, 0.0, 0.0, 0.0]
    });
    let sig: Vec<f64> = log
        .position
        .iter()
        .map(|p| (0.37 * p[0] * 7.0).sin())
        .collect();
    log.add_extra("gust", sig);
    let s = Signals::from_log(&log).unwrap();
    let mut opts = DiagnoseOptions::default();
    opts.candidates.push(std::sync::Arc::new(
        CustomEffect::parse("gust=gust@fx").unwrap(),
    ));
    let d = diagnose(&Model::rigid_body(), &s, &opts).unwrap();
    assert_eq!(d.recommended.as_deref(), Some("gust"));
    // The whole loop adds a recommended custom effect as well as a built-in one.
    let report = crate::add_recommended(&s, &Model::rigid_body(), &opts).unwrap();
    assert_eq!(report.with, vec!["gust".to_string()]);
    let after = report.after.as_ref().unwrap();
    assert!(after.channels[0].rms < 0.5 * report.before.channels[0].rms);
}

fn csv_text(rows: usize) -> String {
    let log = synthetic_log(&crazyflie(), rows, 0.0, 8, &none);
    let mut buf = Vec::new();
    log.write_csv(&mut buf).unwrap();
    String::from_utf8(buf).unwrap()
}

#[test]
fn csv_round_trip() {
    let log = synthetic_log(&crazyflie(), 250, 0.0, 8, &none);
    let mut buf = Vec::new();
    log.write_csv(&mut buf).unwrap();
    let back = FlightLog::from_csv_reader(buf.as_slice()).unwrap();
    assert_eq!(back.len(), 250);
    assert_eq!(back.wrench, log.wrench);
    assert_eq!(back.accel, log.accel);
}

#[test]
fn csv_errors_name_line_and_column() {
    let text = csv_text(250);
    let lines: Vec<&str> = text.lines().collect();
    // Missing column.
    let no_fz = text.replacen("fz,", "fq,", 1);
    let e = FlightLog::from_csv_reader(no_fz.as_bytes()).unwrap_err();
    assert_eq!(
        e,
        LogError::MissingColumn {
            column: "fz".into()
        }
    );
    // Duplicate column.
    let dup = text.replacen("px,", "px,px_,", 1).replacen("px_", "px", 1);
    let e = FlightLog::from_csv_reader(dup.as_bytes()).unwrap_err();
    assert!(matches!(e, LogError::DuplicateColumn { .. }), "{e:?}");
    // Non-increasing time on line 6 (row index 5).
    let mut l2: Vec<String> = lines.iter().map(|s| s.to_string()).collect();
    let prev_t = l2[4].split(',').next().unwrap().to_string();
    let rest: Vec<&str> = l2[5].split(',').skip(1).collect();
    l2[5] = format!("{prev_t},{}", rest.join(","));
    let e = FlightLog::from_csv_reader(l2.join("\n").as_bytes()).unwrap_err();
    assert_eq!(e.line(), Some(6));
    assert_eq!(e.column(), Some("t"));
    // Non-finite value in column vy on line 10.
    let mut l3: Vec<String> = lines.iter().map(|s| s.to_string()).collect();
    let mut f: Vec<String> = l3[9].split(',').map(str::to_string).collect();
    f[5] = "NaN".into();
    l3[9] = f.join(",");
    let e = FlightLog::from_csv_reader(l3.join("\n").as_bytes()).unwrap_err();
    assert!(
        matches!(&e, LogError::NonFinite { line: 10, column, .. } if column == "vy"),
        "{e:?}"
    );
    // Not a number.
    let mut l4: Vec<String> = lines.iter().map(|s| s.to_string()).collect();
    let mut f: Vec<String> = l4[3].split(',').map(str::to_string).collect();
    f[14] = "abc".into();
    l4[3] = f.join(",");
    let e = FlightLog::from_csv_reader(l4.join("\n").as_bytes()).unwrap_err();
    assert!(
        matches!(&e, LogError::NotANumber { line: 4, column, .. } if column == "fx"),
        "{e:?}"
    );
    // Quaternion far from unit norm.
    let mut l5: Vec<String> = lines.iter().map(|s| s.to_string()).collect();
    let mut f: Vec<String> = l5[7].split(',').map(str::to_string).collect();
    f[7] = "2.0".into();
    l5[7] = f.join(",");
    let e = FlightLog::from_csv_reader(l5.join("\n").as_bytes()).unwrap_err();
    assert!(
        matches!(e, LogError::QuaternionNorm { line: 8, .. }),
        "{e:?}"
    );
    // Too short.
    let short = csv_text(50);
    let e = FlightLog::from_csv_reader(short.as_bytes()).unwrap_err();
    assert_eq!(
        e,
        LogError::TooShort {
            rows: 50,
            needed: crate::log::MIN_ROWS
        }
    );
}

#[test]
fn in_memory_validation_names_the_line() {
    let mut log = synthetic_log(&crazyflie(), 300, 0.0, 9, &none);
    log.wrench[20][3] = f64::INFINITY;
    let e = log.validate().unwrap_err();
    assert!(
        matches!(&e, LogError::NonFinite { line: 22, column, .. } if column == "tx"),
        "{e:?}"
    );
}

#[test]
fn savitzky_golay_is_exact_on_quadratics_with_uneven_time() {
    let t: Vec<f64> = (0..60)
        .map(|k| k as f64 * 0.01 + 0.003 * ((k * 7 % 5) as f64))
        .collect();
    let x: Vec<f64> = t.iter().map(|t| 2.0 - 3.0 * t + 4.5 * t * t).collect();
    let d = savitzky_golay_derivative(&t, &x, 5);
    let sm = savitzky_golay_smooth(&t, &x, 5);
    for i in 0..t.len() {
        assert!((d[i] - (-3.0 + 9.0 * t[i])).abs() < 1e-8, "i {i}");
        assert!((sm[i] - x[i]).abs() < 1e-10);
    }
}

proptest! {
    #[test]
    fn savitzky_golay_derivative_of_a_line_is_its_slope(
        a in -10.0f64..10.0, b in -5.0f64..5.0, steps in proptest::collection::vec(0.001f64..0.05, 10..40), h in 1usize..8
    ) {
        let mut t = vec![0.0];
        for s in &steps { let last = *t.last().unwrap(); t.push(last + s); }
        let x: Vec<f64> = t.iter().map(|t| a * t + b).collect();
        let d = savitzky_golay_derivative(&t, &x, h);
        for v in d { prop_assert!((v - a).abs() < 1e-6 * (1.0 + a.abs())); }
    }

    #[test]
    fn fit_percent_never_exceeds_100(
        vals in proptest::collection::vec((-1.0f64..1.0, -0.5f64..0.5), 3..50)
    ) {
        let b: Vec<[f64; 6]> = vals.iter().map(|(y, _)| [*y; 6]).collect();
        let r: Vec<[f64; 6]> = vals.iter().map(|(_, e)| [*e; 6]).collect();
        for c in channel_stats(&b, &r) {
            if let Some(f) = c.fit_percent { prop_assert!(f <= 100.0); }
            prop_assert!(c.rms >= 0.0);
        }
    }
}

proptest! {
    #[test]
    fn time_shift_sweep_matches_pointwise_interpolation(
        d in -0.2f64..0.2, steps in proptest::collection::vec(0.001f64..0.03, 5..60)
    ) {
        let mut t = vec![0.0];
        for s in &steps { let last = *t.last().unwrap(); t.push(last + s); }
        let x: Vec<f64> = t.iter().map(|t| (3.0 * t).sin() + t * t).collect();
        let fast = shifted(&t, &x, d);
        for (i, ti) in t.iter().enumerate() {
            let slow = crate::signals::interp(&t, &x, ti - d);
            prop_assert!((fast[i] - slow).abs() < 1e-12);
        }
    }
}

// ---------- validation, registry, vocabulary ----------

fn invalid_field(r: Result<(), DiagnoseError>) -> &'static str {
    match r {
        Err(DiagnoseError::InvalidOption { field, .. }) => field,
        other => panic!("expected InvalidOption, got {other:?}"),
    }
}

#[test]
fn every_option_field_is_validated() {
    assert!(DiagnoseOptions::default().validate().is_ok());
    let with = |f: &dyn Fn(&mut DiagnoseOptions)| {
        let mut o = DiagnoseOptions::default();
        f(&mut o);
        o.validate()
    };
    assert_eq!(invalid_field(with(&|o| o.folds = 0)), "folds");
    assert_eq!(invalid_field(with(&|o| o.folds = 1)), "folds");
    assert_eq!(invalid_field(with(&|o| o.alpha = f64::NAN)), "alpha");
    assert_eq!(invalid_field(with(&|o| o.alpha = 0.0)), "alpha");
    assert_eq!(invalid_field(with(&|o| o.alpha = 1.0)), "alpha");
    assert_eq!(
        invalid_field(with(&|o| o.com_vertical_limit = f64::INFINITY)),
        "com_vertical_limit"
    );
    assert_eq!(
        invalid_field(with(&|o| o.airframe_radius = 0.0)),
        "airframe_radius"
    );
    assert_eq!(
        invalid_field(with(&|o| o.airframe_radius = f64::NAN)),
        "airframe_radius"
    );
    assert_eq!(invalid_field(with(&|o| o.candidates.clear())), "candidates");
    assert_eq!(
        invalid_field(with(&|o| {
            let first = o.candidates[0].clone();
            o.candidates.push(first);
        })),
        "candidates"
    );
}

#[test]
fn online_pass_bad_input_is_a_typed_error_never_a_panic() {
    use crate::{OnlineOptions, OnlineStart, online_pass_with};
    let s = Signals::from_log(&synthetic_log(&crazyflie(), 300, 0.0, 3, &none)).unwrap();
    let fit = Model::rigid_body().fit(&s).unwrap();
    let with = |o: OnlineOptions| online_pass_with(&s, &fit, &o);
    // A log shorter than one window (the signals' time stamps cut to 3 samples).
    let mut short = s.clone();
    short.t.truncate(3);
    assert_eq!(
        crate::online_pass(&short, &fit, 5).unwrap_err(),
        DiagnoseError::OnlineTooShort {
            samples: 3,
            needed: 5
        }
    );
    // Signals whose series no longer agree in length.
    let mut cut = s.clone();
    cut.t.truncate(100);
    assert!(matches!(
        crate::online_pass(&cut, &fit, 5),
        Err(DiagnoseError::InvalidOption {
            field: "signals",
            ..
        })
    ));
    // A fit made on other signals.
    let other = Signals::from_log(&synthetic_log(&crazyflie(), 250, 0.0, 4, &none)).unwrap();
    let other_fit = Model::rigid_body().fit(&other).unwrap();
    assert!(matches!(
        crate::online_pass(&s, &other_fit, 5),
        Err(DiagnoseError::InvalidOption { field: "fit", .. })
    ));
    for arm_length in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        assert!(matches!(
            with(OnlineOptions {
                arm_length,
                ..OnlineOptions::default()
            }),
            Err(DiagnoseError::InvalidOption {
                field: "arm_length",
                ..
            })
        ));
    }
    let mut no_mass = crazyflie().to_array();
    no_mass[0] = 0.0;
    let mut nan_inertia = crazyflie().to_array();
    nan_inertia[6] = f64::NAN;
    for p in [no_mass, nan_inertia, [0.0; 10]] {
        assert!(matches!(
            with(OnlineOptions {
                prior: Some(tagk_dynamics::InertialParams::from_array(p)),
                ..OnlineOptions::default()
            }),
            Err(DiagnoseError::InvalidOption { field: "prior", .. })
        ));
    }
    // A prior so large that the scaled window overflows: the estimator rejects the first
    // window (a typed error) and the pass stops there.
    let mut huge = crazyflie().to_array();
    huge[0] = f64::MAX;
    let err = with(OnlineOptions {
        prior: Some(tagk_dynamics::InertialParams::from_array(huge)),
        start: OnlineStart::Zero,
        ..OnlineOptions::default()
    })
    .unwrap_err();
    assert!(
        matches!(&err, DiagnoseError::Online(m) if m.starts_with("window 1 ")),
        "{err}"
    );
    // A stride larger than the log: one window, whose estimate is also the tail average.
    let one = crate::online_pass(&s, &fit, 10_000).unwrap();
    assert_eq!(one.updates, 1);
    assert_eq!(one.tail_average, one.final_estimate);
}

#[test]
fn diagnose_refuses_bad_options_instead_of_clamping() {
    let s = Signals::from_log(&synthetic_log(&crazyflie(), 300, 0.0, 3, &none)).unwrap();
    let zero = DiagnoseOptions {
        folds: 0,
        ..DiagnoseOptions::default()
    };
    assert!(matches!(
        diagnose(&Model::rigid_body(), &s, &zero),
        Err(DiagnoseError::InvalidOption { field: "folds", .. })
    ));
    // More blocks than the log can hold (4 samples each).
    let many = DiagnoseOptions {
        folds: 76,
        ..DiagnoseOptions::default()
    };
    assert!(matches!(
        diagnose(&Model::rigid_body(), &s, &many),
        Err(DiagnoseError::InvalidOption { field: "folds", .. })
    ));
    let fit = Model::rigid_body().fit(&s).unwrap();
    assert!(matches!(
        crate::online_pass(&s, &fit, 0),
        Err(DiagnoseError::InvalidOption {
            field: "stride",
            ..
        })
    ));
    assert!(matches!(
        fit_model(
            &Model::rigid_body(),
            &s,
            Some([1.0, 1.0, 0.0, 1.0, 1.0, 1.0])
        ),
        Err(DiagnoseError::InvalidOption {
            field: "weights",
            ..
        })
    ));
}

#[test]
fn models_with_a_bad_mass_or_a_repeated_effect_are_refused() {
    let s = Signals::from_log(&synthetic_log(&crazyflie(), 300, 0.0, 4, &none)).unwrap();
    for m in [0.0, -0.035, f64::NAN, f64::INFINITY] {
        let model = Model::rigid_body().with_known_mass(m);
        assert!(
            matches!(model.fit(&s), Err(DiagnoseError::InvalidModel(_))),
            "{m}"
        );
    }
    let drag = builtin(EffectKind::LinearDrag).unwrap();
    let twice = Model::rigid_body().with_ref(drag.clone()).with_ref(drag);
    assert!(matches!(
        twice.validate(),
        Err(DiagnoseError::InvalidModel(_))
    ));
}

#[test]
fn the_registry_is_keyed_by_the_shared_vocabulary() {
    let all = crate::builtin_effects();
    // The vocabulary's proposed effects, then the sensor candidates.
    let proposed: Vec<EffectKind> = EffectKind::ALL
        .into_iter()
        .filter(|k| !crate::effects::NOT_PROPOSED.contains(k))
        .collect();
    assert_eq!(all.len(), proposed.len() + 1);
    assert_eq!(all[proposed.len()].name(), crate::ACCEL_BIAS);
    assert_eq!(
        crate::builtin_by_name("accelerometer_bias").unwrap().name(),
        crate::ACCEL_BIAS
    );
    for (kind, effect) in proposed.into_iter().zip(&all) {
        assert_eq!(effect.name(), kind.name());
        assert_eq!(builtin(kind).unwrap().name(), kind.name());
        for alias in kind.aliases() {
            assert_eq!(crate::builtin_by_name(alias).unwrap().name(), kind.name());
        }
    }
    assert!(matches!(
        crate::builtin_by_name("anti-gravity"),
        Err(DiagnoseError::UnknownEffect(_))
    ));
    let text = crate::builtin_by_name("drag").unwrap_err().to_string();
    for kind in EffectKind::ALL {
        assert!(text.contains(kind.name()), "{text}");
    }
}

#[test]
fn builtin_tunables_are_validated_and_used() {
    let mut o = crate::BuiltinOptions::default();
    assert!(o.validate().is_ok());
    o.time_delays = vec![0.01, 0.02];
    let delay = crate::builtin_with(EffectKind::TimeDelay, &o).unwrap();
    assert_eq!(delay.scan().unwrap().grid, vec![0.01, 0.02]);
    o.motor_lag_time_constants = vec![0.02, -0.01];
    assert_eq!(invalid_field(o.validate()), "motor_lag_time_constants");
    let mut o = crate::BuiltinOptions::default();
    o.time_delays.clear();
    assert_eq!(invalid_field(o.validate()), "time_delays");
    let o = crate::BuiltinOptions {
        rotor_radius: -1.0,
        ..Default::default()
    };
    assert_eq!(invalid_field(o.validate()), "rotor_radius");
    let mut o = crate::BuiltinOptions::default();
    o.ground_min_height = o.rotor_radius / 8.0;
    assert_eq!(invalid_field(o.validate()), "ground_min_height");
}

#[test]
fn custom_effects_check_their_channels_and_columns() {
    assert!(matches!(
        CustomEffect::new("x", vec!["fz".into()], vec![6]),
        Err(DiagnoseError::BadCustomSpec { .. })
    ));
    assert!(matches!(
        CustomEffect::new("x", vec![], vec![2]),
        Err(DiagnoseError::BadCustomSpec { .. })
    ));
    assert!(matches!(
        CustomEffect::new(" ", vec!["fz".into()], vec![2]),
        Err(DiagnoseError::BadCustomSpec { .. })
    ));
    let c = CustomEffect::new("x", vec!["fz".into()], vec![2, 2, 5]).unwrap();
    assert_eq!(c.channels(), vec![2, 5]);
    let log = synthetic_log(&crazyflie(), 300, 0.0, 5, &none);
    assert!(c.require_columns(&log).is_ok());
    let v = CustomEffect::parse("v=vbat*fz@fz").unwrap();
    let err = v.require_columns(&log).unwrap_err();
    assert!(
        matches!(&err, DiagnoseError::UnknownColumn { effect, column, available }
            if effect == "v" && column == "vbat" && available.contains("fz") && available.contains("vbx")),
        "{err}"
    );
}

#[test]
fn public_types_are_send_sync_debug_clone() {
    fn check<T: Send + Sync + std::fmt::Debug + Clone>() {}
    check::<DiagnoseOptions>();
    check::<crate::Diagnosis>();
    check::<crate::Report>();
    check::<Model>();
    check::<crate::Fit>();
    check::<crate::EffectRef>();
    check::<CustomEffect>();
    check::<crate::BuiltinOptions>();
    check::<DiagnoseError>();
    check::<Signals>();
}

/// A user-defined effect whose columns are malformed (too short, or not finite).
#[derive(Debug)]
struct Faulty {
    short: bool,
}

impl Effect for Faulty {
    fn name(&self) -> &str {
        if self.short { "short" } else { "nan" }
    }
    fn description(&self) -> &str {
        "a malformed user effect"
    }
    fn channels(&self) -> Vec<crate::Channel> {
        vec![0]
    }
    fn columns(&self, s: &Signals, _p: Option<f64>) -> Vec<crate::EffectColumn> {
        let n = if self.short { s.len() - 1 } else { s.len() };
        let mut v = vec![1.0; n];
        if !self.short {
            v[7] = f64::NAN;
        }
        vec![crate::EffectColumn::on("x", "N", 0, v)]
    }
    fn plausibility(&self, _c: &[f64], _se: &[f64], _p: Option<f64>) -> crate::Plausibility {
        crate::Plausibility::ok()
    }
    fn driver(&self, s: &Signals) -> (String, Vec<f64>) {
        ("t".into(), s.t.clone())
    }
}

#[test]
fn malformed_user_effects_are_reported_not_panicked_on() {
    let s = Signals::from_log(&synthetic_log(&crazyflie(), 300, 0.0, 6, &none)).unwrap();
    let mut opts = DiagnoseOptions::default();
    for short in [true, false] {
        opts.candidates
            .push(std::sync::Arc::new(Faulty { short }) as crate::EffectRef);
        let model = Model::rigid_body().with(Faulty { short });
        assert!(matches!(
            model.fit(&s),
            Err(DiagnoseError::EffectUnavailable { .. })
        ));
    }
    let d = diagnose(&Model::rigid_body(), &s, &opts).unwrap();
    let skipped: Vec<&str> = d.unavailable.iter().map(|u| u.effect.as_str()).collect();
    assert!(
        skipped.contains(&"short") && skipped.contains(&"nan"),
        "{skipped:?}"
    );
}

/// A known part moved to the target (`evaluate_with` and an offset) gives what an engine built
/// on the shifted target gives: the Gram algebra `(y − o)ᵀ(y − o)`, `(y − o)ᵀx` is right.
#[test]
fn an_offset_equals_a_shifted_target() {
    let log = synthetic_log(&crazyflie(), 400, 5e-3, 9, &|_, vb| {
        [-0.01 * vb.x, -0.01 * vb.y, 0.0, 0.0, 0.0, 0.0]
    });
    let s = Signals::from_log(&log).unwrap();
    let base = rigid_columns(&s);
    let cand: Vec<ColData> =
        crate::fit::effect_design(builtin(EffectKind::LinearDrag).unwrap().as_ref(), &s, None).cols;
    let offset: ColData = std::array::from_fn(|c| {
        (c % 2 == 0).then(|| {
            s.t.iter()
                .map(|t| 1e-3 * (3.0 * t + c as f64).sin())
                .collect()
        })
    });
    let w = [100.0, 100.0, 50.0, 1e5, 1e5, 1e5];
    let shifted: Vec<[f64; 6]> = s
        .target()
        .iter()
        .enumerate()
        .map(|(i, y)| std::array::from_fn(|c| y[c] - offset[c].as_ref().map_or(0.0, |v| v[i])))
        .collect();
    let with = GramEngine::new(&s, &w, &stored(&base), None, 5).evaluate_with(&cand, Some(&offset));
    let direct = GramEngine::new(&s, &w, &stored(&base), Some(&shifted), 5).evaluate(&cand);
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-9 * a.abs().max(b.abs()).max(1e-300);
    assert!(
        close(with.sse_full, direct.sse_full),
        "{} {}",
        with.sse_full,
        direct.sse_full
    );
    assert!(
        close(with.sse_cv(), direct.sse_cv()),
        "{} {}",
        with.sse_cv(),
        direct.sse_cv()
    );
    for (a, b) in with.beta.iter().zip(&direct.beta) {
        assert!((a - b).abs() <= 1e-7 * b.abs().max(1e-9), "{a} {b}");
    }
}

/// The rigid-body columns computed block by block ([`Column::Rigid`]) give the same bits as
/// the same columns stored: Gram products with folds and with a scan's stride, residuals and
/// the blocked QR, on a log of several blocks whose length is no multiple of 4.
#[test]
fn rigid_columns_by_block_equal_stored_columns_bit_for_bit() {
    let log = synthetic_log(&crazyflie(), 25_003, 5e-3, 11, &|_, vb| {
        [-0.02 * vb.x, -0.01 * vb.y, 0.0, 0.0, 0.0, 0.0]
    });
    let s = Signals::from_log(&log).unwrap();
    let stored_rigid = rigid_columns(&s);
    let by_block: Vec<Column<'_>> = (0..10).map(Column::Rigid).collect();
    let cand: Vec<ColData> =
        crate::fit::effect_design(builtin(EffectKind::LinearDrag).unwrap().as_ref(), &s, None).cols;
    let w = [100.0, 100.0, 50.0, 1e5, 1e5, 1e5];
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    for folds in [1, 5] {
        let a = GramEngine::new(&s, &w, &stored(&stored_rigid), None, folds);
        let b = GramEngine::new(&s, &w, &by_block, None, folds);
        let (ea, eb) = (a.evaluate(&cand), b.evaluate(&cand));
        assert_eq!(ea.sse_full.to_bits(), eb.sse_full.to_bits());
        assert_eq!(ea.sse_cv().to_bits(), eb.sse_cv().to_bits());
        assert_eq!(bits(&ea.sse_cv_ch), bits(&eb.sse_cv_ch));
        assert_eq!(bits(&ea.beta), bits(&eb.beta));
        assert_eq!(bits(&ea.cov_diag), bits(&eb.cov_diag));
        let (ra, rb) = (
            a.residual(&cand, None, &ea.beta),
            b.residual(&cand, None, &eb.beta),
        );
        assert!(ra.iter().zip(&rb).all(|(x, y)| bits(x) == bits(y)));
        let (sa, sb) = (a.for_scan(), b.for_scan());
        assert_eq!(
            sa.evaluate(&cand).sse_full.to_bits(),
            sb.evaluate(&cand).sse_full.to_bits()
        );
    }
    let qa = weighted_qr_solve(&s, &stored(&stored_rigid), s.wrench(), &w, 1.0).unwrap();
    let qb = weighted_qr_solve(&s, &by_block, s.wrench(), &w, 1.0).unwrap();
    assert_eq!(bits(&qa.beta), bits(&qb.beta));
    assert_eq!(qa.se, qb.se);
}

/// `P(χ²_k > x)` for an even `k` in closed form, `e^{−x/2} Σ_{i<k/2} (x/2)^i / i!`: an
/// independent check of `stats::chi2_quantile`.
fn chi2_survival_even(x: f64, k: usize) -> f64 {
    let h = 0.5 * x;
    let mut term = 1.0;
    let mut sum = 1.0;
    for i in 1..k / 2 {
        term *= h / i as f64;
        sum += term;
    }
    (-h).exp() * sum
}

#[test]
fn the_whiteness_limit_is_the_family_wise_ljung_box_bound() {
    use crate::diagnose::{ADEQUATE_AUTOCORRELATION, WHITENESS_FALSE_ALARM, whiteness_limit};
    // 20 lags from n = 80 on; the bound rules until it falls to the effect size.
    for n in [200usize, 1000, 1843, 2000] {
        let limit = whiteness_limit(n);
        let x = limit * n as f64;
        if limit > ADEQUATE_AUTOCORRELATION {
            // The tail beyond the bound is the per-channel share of the family's rate.
            let tail = chi2_survival_even(x, 20);
            let share = WHITENESS_FALSE_ALARM / 6.0;
            assert!(
                (tail / share - 1.0).abs() < 1e-6,
                "n {n}: {tail} vs {share}"
            );
        } else {
            assert!(chi2_survival_even(ADEQUATE_AUTOCORRELATION * n as f64, 20) < 1e-3 / 6.0);
        }
    }
}

#[test]
fn white_noise_fails_the_whiteness_test_about_once_in_a_thousand_logs() {
    use crate::diagnose::{residual_autocorrelation, whiteness_limit};
    use rand_chacha::ChaCha8Rng;
    use rand_chacha::rand_core::SeedableRng;
    // 3000 logs of six white channels of 400 samples: the family-wise rate is 0.1 %, so
    // about 3 logs fail; a per-channel 0.1 % would fail about 18.
    let n = 400;
    let limit = whiteness_limit(n);
    let mut rng = ChaCha8Rng::seed_from_u64(2026);
    let mut failed = 0;
    for _ in 0..3000 {
        let mut any = false;
        for _ in 0..6 {
            let r: Vec<f64> = (0..n).map(|_| crate::testdata::gauss(&mut rng)).collect();
            let sum: f64 = residual_autocorrelation(&r).iter().map(|x| x * x).sum();
            any |= sum > limit;
        }
        failed += usize::from(any);
    }
    assert!(failed <= 9, "{failed} of 3000 white logs failed");
}

/// The progress hook is told every usable candidate of each search, in order, counted from
/// 0, and the report is the same bits without it.
#[test]
fn the_progress_hook_sees_every_candidate_and_changes_nothing() {
    use std::sync::{Arc, Mutex};
    let log = synthetic_log(&crazyflie(), 2000, 1e-3, 5, &|_, vb| {
        [-0.02 * vb.x, 0.0, 0.0, 0.0, 0.0, 0.0]
    });
    let plain = crate::DiagnosisPlan::new().log(log.clone()).run().unwrap();
    let seen = Arc::new(Mutex::new(Vec::new()));
    let sink = Arc::clone(&seen);
    let hook = crate::ProgressHook::new(move |p| {
        sink.lock()
            .unwrap()
            .push((p.effects, p.judging.to_string(), p.done, p.total));
    });
    let hooked = crate::DiagnosisPlan::new()
        .log(log)
        .progress(hook)
        .run()
        .unwrap();
    assert_eq!(plain.to_json().unwrap(), hooked.to_json().unwrap());
    let seen = seen.lock().unwrap();
    // The first search, from the rigid body: each candidate once, `done` counting up.
    let first: Vec<_> = seen
        .iter()
        .take_while(|(effects, judging, _, _)| *effects == 0 && judging != "pairs")
        .collect();
    assert!(first.len() >= 5, "{seen:?}");
    for (k, (_, name, done, total)) in first.iter().enumerate() {
        assert_eq!(*done, k, "{seen:?}");
        assert_eq!(*total, first.len(), "{seen:?}");
        assert!(crate::builtin_by_name(name).is_ok(), "{name}");
    }
    // The drag found, the search goes on from a model with one effect.
    assert!(seen.iter().any(|(effects, ..)| *effects >= 1), "{seen:?}");
    assert!(
        seen.iter().all(|(_, _, done, total)| done < total),
        "{seen:?}"
    );
}
