//! Custom effects as expressions (`--custom NAME=EXPR@CH`), time windows (`--window`) and a
//! validation log (`--validate`): each against an independent computation.

mod common;

use tagk_diagnose::effects::expression::Expression;
use tagk_diagnose::{
    CustomEffect, DiagnoseError, DiagnosisPlan, FlightLog, LogSample, Signals, TimeWindow,
    keep_windows,
};

/// A 4 s log at 100 Hz whose velocity and rates are sinusoids known in closed form
/// (`vx = 0.8 sin(1.5 t)`, `vy = 0.3 cos(0.7 t)`, `wz = 0.2 sin(t)`), with an extra column.
fn sinusoid_log() -> FlightLog {
    let mut log = FlightLog::new();
    for k in 0..400 {
        let t = k as f64 * 0.01;
        log.push(&LogSample {
            t,
            position: [0.0, 0.0, 1.0],
            velocity: [0.8 * (1.5 * t).sin(), 0.3 * (0.7 * t).cos(), 0.0],
            attitude: [1.0, 0.0, 0.0, 0.0],
            omega: [0.0, 0.0, 0.2 * t.sin()],
            wrench: [0.0, 0.0, 0.35, 0.0, 0.0, 0.0],
            accel: Some([0.0; 3]),
            omega_dot: Some([0.0; 3]),
            rotor_speeds: None,
        });
    }
    let vbat: Vec<f64> = (0..400).map(|k| 4.2 - 1e-3 * k as f64).collect();
    log.add_extra("vbat", vbat);
    log
}

fn vx(t: f64) -> f64 {
    0.8 * (1.5 * t).sin()
}

fn vy(t: f64) -> f64 {
    0.3 * (0.7 * t).cos()
}

#[test]
fn expressions_match_hand_computation() {
    let log = sinusoid_log();
    let s = Signals::from_log(&log).unwrap();
    type Exact = fn(f64) -> f64;
    let cases: [(&str, Exact); 7] = [
        ("vx*abs(vx)", |t| vx(t) * vx(t).abs()),
        ("sign(vx)*sqrt(abs(vx*vy)) + 2*vy", |t| {
            vx(t).signum() * (vx(t) * vy(t)).abs().sqrt() + 2.0 * vy(t)
        }),
        ("vx^2*sqrt(abs(vy)) - pow(abs(vy), 2.5)", |t| {
            vx(t).powi(2) * vy(t).abs().sqrt() - vy(t).abs().powf(2.5)
        }),
        ("min(vx, vy) + max(vx, vy)", |t| vx(t) + vy(t)),
        ("tanh(vx/vy) * exp(-0.5*t*wz)", |t| {
            (vx(t) / vy(t)).tanh() * (-0.5 * t * 0.2 * t.sin()).exp()
        }),
        ("sin(PI*wz*t) + cos(2.5e-1)", |t| {
            (std::f64::consts::PI * 0.2 * t.sin() * t).sin() + 0.25f64.cos()
        }),
        ("vbat*fz", |t| (4.2 - 1e-3 * (t / 0.01).round()) * 0.35),
    ];
    for (text, exact) in cases {
        let e = Expression::parse(text).unwrap();
        let v = e.evaluate(&s).unwrap();
        assert_eq!(v.len(), log.len());
        for k in [0, 1, 7, 133, 250, 399] {
            let t = log.t[k];
            assert!(
                (v[k] - exact(t)).abs() <= 1e-12 * (1.0 + exact(t).abs()),
                "{text} at t = {t}: {} against {}",
                v[k],
                exact(t)
            );
        }
    }
}

/// A value that is not a finite number is an error naming the time, never a silent NaN.
#[test]
fn a_nan_is_an_error_naming_the_time() {
    let log = sinusoid_log();
    let s = Signals::from_log(&log).unwrap();
    let err = Expression::parse("sqrt(vy)")
        .unwrap()
        .evaluate(&s)
        .unwrap_err();
    // vy = 0.3 cos(0.7 t) < 0 from t = π/1.4 ≈ 2.244 s: the first sample is 2.25 s.
    assert!(err.contains("NaN at t = 2.25 s"), "{err}");
}

/// `d(vx)` is the Savitzky–Golay derivative the diagnosis derives accelerations with: on a
/// sinusoid it matches the closed form `1.2 cos(1.5 t)` within the filter's bias.
#[test]
fn derivative_of_a_column_matches_the_closed_form() {
    let log = sinusoid_log();
    let s = Signals::from_log(&log).unwrap();
    let d = Expression::parse("d(vx)").unwrap().evaluate(&s).unwrap();
    let der = Expression::parse("der( vx )")
        .unwrap()
        .evaluate(&s)
        .unwrap();
    assert_eq!(d, der);
    let mut worst = 0.0f64;
    for (t, x) in log.t.iter().zip(&d).skip(5).take(390) {
        worst = worst.max((x - 1.2 * (1.5 * t).cos()).abs());
    }
    // A local quadratic over ±5 samples: bias ≈ A ω³ h² (10 + 1)/10 / 6 ≈ 2.5e-4 m/s².
    assert!(worst < 1e-3, "worst error {worst:e} m/s²");
    // And on wz: d(wz) = 0.2 cos(t), unit 1/s².
    let e = Expression::parse("d(wz)").unwrap();
    assert_eq!(e.unit().unwrap().to_string(), "1/s^2");
    let dw = e.evaluate(&s).unwrap();
    assert!((dw[200] - 0.2 * 2.0f64.cos()).abs() < 1e-4);
}

/// One source of truth: on a log without accelerations, `d(vx)` is the acceleration the
/// diagnosis derives itself (level attitude: the body x axis is the world's).
#[test]
fn derivative_is_the_diagnosis_own_acceleration() {
    let mut log = sinusoid_log();
    log.accel = None;
    let s = Signals::from_log(&log).unwrap();
    assert!(s.derived_accel);
    let d = Expression::parse("d(vx)").unwrap().evaluate(&s).unwrap();
    for (k, a) in s.accel_proper.iter().enumerate() {
        assert!(
            (d[k] - a.x).abs() < 1e-12,
            "sample {k}: {} against {}",
            d[k],
            a.x
        );
    }
}

#[test]
fn units_are_inferred_and_mistakes_refused() {
    let unit = |text: &str| {
        Expression::parse(text)
            .unwrap()
            .unit()
            .map(|u| u.to_string())
    };
    assert_eq!(unit("vx*abs(vx)").as_deref(), Some("m^2/s^2"));
    assert_eq!(unit("d(vx)").as_deref(), Some("m/s^2"));
    assert_eq!(unit("sqrt(vx*vx) + vy - 1").as_deref(), Some("m/s"));
    assert_eq!(unit("fz/w1^2").as_deref(), Some("kg m"));
    assert_eq!(unit("sin(wz*t)*px").as_deref(), Some("m"));
    assert_eq!(unit("vbat*fz"), None, "an extra column's unit is unknown");
    // The coefficient's unit: the channel's over the expression's.
    let drag = CustomEffect::parse("drag_x='vbx*abs(vbx)'@fx,tz").unwrap();
    assert_eq!(drag.coefficient_units(), ["kg/m", "kg"]);
    assert_eq!(
        CustomEffect::parse("v=vbat*fz@fz")
            .unwrap()
            .coefficient_units(),
        ["?"]
    );
    // Refused, naming the term.
    for (spec, why) in [
        ("bad=vx + wx@fx", "different units"),
        ("bad=max(vx, px)@fx", "different units"),
        ("bad=sin(vx)@fx", "pure number"),
        ("bad=exp(t)@fz", "pure number"),
        ("bad=vx^vy@fx", "pure number"),
    ] {
        let err = CustomEffect::parse(spec).unwrap_err();
        assert!(
            matches!(&err, DiagnoseError::CustomUnits { effect, reason, .. }
                if effect == "bad" && reason.contains(why)),
            "{spec}: {err}"
        );
        assert!(err.to_string().contains("`bad`"), "{err}");
        // Refused before any log is read.
        assert!(DiagnosisPlan::new().custom(spec).validate().is_err());
    }
    // Syntax errors and derivatives of anything but a column.
    for spec in [
        "bad=vx*@fx",
        "bad=d(vx*vy)@fx",
        "bad=foo(vx)@fx",
        "bad=vx@qq",
    ] {
        assert!(
            matches!(
                CustomEffect::parse(spec),
                Err(DiagnoseError::BadCustomSpec { .. })
            ),
            "{spec}"
        );
    }
    // An unknown column names the term, the column and the columns there are.
    let log = sinusoid_log();
    let err = CustomEffect::parse("k=d(vq)*vx@fx")
        .unwrap()
        .require_columns(&log)
        .unwrap_err();
    match &err {
        DiagnoseError::UnknownColumn {
            effect,
            column,
            available,
        } => {
            assert_eq!((effect.as_str(), column.as_str()), ("k", "vq"));
            for c in ["vx", "wz", "vbx", "vbat"] {
                assert!(available.contains(c), "{available}");
            }
        }
        other => panic!("{other}"),
    }
    // The product syntax still parses to the same product.
    let old = CustomEffect::new("p", vec!["vbat".into(), "fz".into()], vec![2]).unwrap();
    assert_eq!(old.expression().text(), "vbat*fz");
    assert_eq!(old.factors(), ["fz", "vbat"]);
}

/// The quadratic drag of the simulator (docs/CONVENTIONS.md §5: `f_x = −½ ρ (C_d A)_x |v_x|
/// v_x` on the body-frame air velocity, no wind) written as a custom expression on `fx`:
/// the fitted coefficient is `−½ ρ (C_d A)_x` within its 95 % interval.
#[test]
fn custom_quadratic_drag_recovers_the_simulated_coefficient() {
    let log = common::sim_log(Some(tagk_sim::EffectKind::QuadraticDrag), 7);
    let q = tagk_sim::plant_effects::QuadraticDrag::crazyflie();
    let truth = -0.5 * q.air_density * q.cd_area[0];
    let report = DiagnosisPlan::new()
        .log(log)
        .custom("drag_x='vbx*abs(vbx)'@fx")
        .with_effects(["drag_x"])
        .max_steps(0)
        .run()
        .unwrap();
    let after = report.after.as_ref().unwrap();
    let fitted = after
        .fit
        .effects
        .iter()
        .find(|e| e.effect == "drag_x")
        .unwrap();
    let c = &fitted.coefficients[0];
    let [lo, hi] = c.confidence_interval.unwrap();
    eprintln!(
        "drag_x: {:.4e} [{lo:.4e}, {hi:.4e}] {} (truth {truth:.4e})",
        c.value, c.unit
    );
    assert_eq!(c.unit, "kg/m");
    assert!(
        lo <= truth && truth <= hi,
        "{truth:e} outside [{lo:e}, {hi:e}]"
    );
    // The interval is the diagnosis' (floored at the data's resolution); the value itself is
    // within 2 % of the simulated coefficient.
    assert!(
        (c.value - truth).abs() < 0.02 * truth.abs(),
        "{:e} against {truth:e}",
        c.value
    );
    assert!(after.channels[0].rms < 0.5 * report.before.channels[0].rms);
}

#[test]
fn windows_keep_exactly_their_rows_and_bad_ones_are_refused() {
    let log = sinusoid_log(); // t = 0.00 .. 3.99 s
    let w: TimeWindow = "0.5..1.2".parse().unwrap();
    let kept = keep_windows(log.clone(), &[w]).unwrap();
    let expected: Vec<f64> = log
        .t
        .iter()
        .copied()
        .filter(|&t| (0.5..=1.2).contains(&t))
        .collect();
    assert_eq!(kept.t, expected);
    assert_eq!(kept.len(), expected.len());
    assert_eq!(kept.extra[0].1.len(), expected.len());
    // Two windows: the union, in time order, with the gap between them.
    let two = [
        "3..3.5".parse::<TimeWindow>().unwrap(),
        "0.2..0.4".parse().unwrap(),
    ];
    let kept = keep_windows(log.clone(), &two).unwrap();
    let expected: Vec<f64> = log
        .t
        .iter()
        .copied()
        .filter(|&t| (0.2..=0.4).contains(&t) || (3.0..=3.5).contains(&t))
        .collect();
    assert_eq!(kept.t, expected);
    // Refused: malformed, empty, reversed, outside the log, without a row.
    for text in ["5", "a..b", "2..2", "3..1"] {
        assert!(
            matches!(
                text.parse::<TimeWindow>(),
                Err(DiagnoseError::BadWindow { .. })
            ),
            "{text}"
        );
    }
    for w in [
        TimeWindow {
            start: 2.0,
            end: 9.0,
        },
        TimeWindow {
            start: 1.0001,
            end: 1.0002,
        },
    ] {
        let err = keep_windows(log.clone(), &[w]).unwrap_err();
        assert!(matches!(err, DiagnoseError::BadWindow { .. }), "{err}");
    }
}

/// A window in a diagnosis keeps its rows only: the fit sees exactly them.
#[test]
fn a_window_in_a_diagnosis_fits_only_its_rows() {
    let log = common::sim_log(Some(tagk_sim::EffectKind::LinearDrag), 5);
    let expected = log.t.iter().filter(|&&t| (5.0..=15.0).contains(&t)).count();
    let report = DiagnosisPlan::new()
        .log(log.clone())
        .window(TimeWindow::new(5.0, 15.0).unwrap())
        .max_steps(0)
        .run()
        .unwrap();
    assert_eq!(report.before.samples, expected);
    assert_eq!(report.windows, vec![[5.0, 15.0]]);
    // Several flights: the window applies to each.
    let other = common::sim_log(Some(tagk_sim::EffectKind::LinearDrag), 6);
    let expected_other = other
        .t
        .iter()
        .filter(|&&t| (5.0..=15.0).contains(&t))
        .count();
    let joint = DiagnosisPlan::new()
        .named_log("a", log.clone())
        .named_log("b", other)
        .window(TimeWindow::new(5.0, 15.0).unwrap())
        .max_steps(0)
        .run()
        .unwrap();
    assert_eq!(joint.before.samples, expected + expected_other);
    let err = DiagnosisPlan::new()
        .log(log)
        .window(TimeWindow::new(20.0, 90.0).unwrap())
        .run()
        .unwrap_err();
    assert!(matches!(err, DiagnoseError::BadWindow { .. }), "{err}");
}

/// Validation on a second flight of the same plant: the final model's error per channel is
/// close to its held-out error on the diagnosed log, and below the rigid body's.
#[test]
fn validation_on_a_second_flight_is_close_to_the_held_out_error() {
    let main = common::sim_log(Some(tagk_sim::EffectKind::QuadraticDrag), 7);
    let second = common::sim_log(Some(tagk_sim::EffectKind::QuadraticDrag), 11);
    let report = DiagnosisPlan::new()
        .log(main)
        .validation_log("second.csv", second)
        .run()
        .unwrap();
    let v = report.validation.as_ref().unwrap();
    assert_eq!(v.log, "second.csv");
    assert_eq!(v.steps.len(), report.step_fits.len());
    let held_out = report.steps.last().unwrap().held_out_rms;
    let validated = v.final_rms().unwrap();
    eprintln!("{}", v.text());
    eprintln!("held out {held_out:?}");
    for c in 0..6 {
        let ratio = validated[c] / held_out[c];
        assert!(
            (0.6..1.6).contains(&ratio),
            "channel {c}: validation {:.3e} against held-out {:.3e}",
            validated[c],
            held_out[c]
        );
    }
    let rigid = v.steps[0].rms;
    assert!(validated[0] < 0.5 * rigid[0], "{validated:?} {rigid:?}");
    // New JSON keys; the existing ones stay.
    let json: serde_json::Value = serde_json::from_str(&report.to_json().unwrap()).unwrap();
    assert!(json["validation"]["steps"].as_array().unwrap().len() >= 2);
    assert!(json.get("windows").is_none());
    assert!(json.get("steps").is_some());
}
