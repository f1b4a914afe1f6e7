//! The model file (docs/MODEL_FILE.md): every number reads back bit for bit, and a wrong
//! version, an unknown effect or a malformed key is a typed error naming it.

use proptest::prelude::*;
use tagk_diagnose::model_file::{
    AccelOffsetRecord, InertialSection, ModelCoefficient, ScannedParameter, Sensing, StreamShift,
};
use tagk_diagnose::{
    EffectKind, LogSource, Model, ModelContext, ModelEffect, ModelFile, ModelFileError, Signals,
    builtin,
};
use tagk_dynamics::alignment::Sensor;
use tagk_dynamics::vehicle::Vehicle;

/// Every `f64` of a model file, in a fixed order (the vehicle's through its TOML text).
fn floats(f: &ModelFile) -> Vec<f64> {
    let i = &f.inertial;
    let mut out: Vec<f64> = i.values.clone();
    out.extend(&i.std_error);
    out.extend(i.covariance.iter().flatten());
    out.extend(i.known_mass);
    for e in &f.effects {
        if let Some(s) = &e.scanned {
            out.push(s.value);
            out.extend(s.interval.iter().flatten());
        }
        for c in &e.coefficients {
            out.push(c.value);
            out.extend(c.std_error);
            out.extend(c.interval.iter().flatten());
        }
    }
    out.extend(f.sensing.resample);
    for s in &f.sensing.shifts {
        out.push(s.seconds);
    }
    for a in &f.sensing.accelerometer_offsets {
        out.extend(a.offset);
        out.push(a.removed_z);
    }
    if let Some(v) = &f.vehicle {
        out.push(v.max_rotor_speed);
        out.push(v.airframe_radius);
        for r in &v.rotors {
            out.extend(r.position.iter());
        }
    }
    out
}

fn assert_same_bits(a: &ModelFile, b: &ModelFile) {
    let (x, y) = (floats(a), floats(b));
    assert_eq!(x.len(), y.len());
    for (k, (p, q)) in x.iter().zip(&y).enumerate() {
        assert!(
            p.to_bits() == q.to_bits() || (p.is_nan() && q.is_nan()),
            "float {k}: {p:e} read back as {q:e}"
        );
    }
    // NaN ≠ NaN: compare the rest with the NaNs out of the way.
    let strip = |f: &ModelFile| {
        let mut f = f.clone();
        f.inertial.std_error.clear();
        f.inertial.covariance.clear();
        f
    };
    assert_eq!(strip(a), strip(b));
}

fn synthetic_fit_file() -> ModelFile {
    let theta = [
        0.035, 1e-5, -2e-5, 3e-6, 1.66e-5, 0.83e-6, 1.66e-5, 0.72e-6, 1.8e-6, 2.93e-5,
    ];
    let log = tagk_diagnose_testlog::log(&theta);
    let s = Signals::from_log(&log).unwrap();
    let model = Model::rigid_body().with_ref(builtin(EffectKind::LinearDrag).unwrap());
    let fit = model.fit(&s).unwrap();
    let context = ModelContext {
        vehicle: Some(Vehicle::crazyflie_2_1()),
        logs: vec![LogSource::of_bytes("flight.csv", b"t,x\n0,1\n")],
        align: true,
        ..ModelContext::default()
    };
    ModelFile::from_fit(&fit, &fit.effects, &context)
}

/// A small analytic log (the motion of `tagk_diagnose`'s unit tests is private): a body
/// swinging and drifting, its wrench from Newton–Euler minus a linear drag.
mod tagk_diagnose_testlog {
    use nalgebra::{Rotation3, UnitQuaternion, Vector3};
    use tagk_diagnose::{FlightLog, LogSample};
    use tagk_dynamics::{GRAVITY_WORLD, InertialParams, newton_euler};

    pub fn log(theta: &[f64; 10]) -> FlightLog {
        let theta = InertialParams::from_array(*theta);
        let rot = |t: f64| {
            Rotation3::from_euler_angles(0.2 * (1.3 * t).sin(), 0.15 * (0.9 * t).sin(), 0.3 * t)
        };
        let mut log = FlightLog::new();
        for k in 0..600 {
            let t = k as f64 * 0.01;
            let p = Vector3::new((0.7 * t).sin(), 0.5 * (1.1 * t).sin(), 1.0);
            let v = Vector3::new(0.7 * (0.7 * t).cos(), 0.55 * (1.1 * t).cos(), 0.0);
            let a = Vector3::new(-0.49 * (0.7 * t).sin(), -0.605 * (1.1 * t).sin(), 0.0);
            let r = rot(t);
            let h = 1e-5;
            let omega_at = |t: f64| {
                let s = rot(t).inverse().matrix() * (rot(t + h).matrix() - rot(t - h).matrix())
                    / (2.0 * h);
                Vector3::new(s[(2, 1)], s[(0, 2)], s[(1, 0)])
            };
            let w = omega_at(t);
            let wd = (omega_at(t + 1e-4) - omega_at(t - 1e-4)) / 2e-4;
            let ab = r.inverse() * (a - GRAVITY_WORLD);
            let vb = r.inverse() * v;
            let ne = newton_euler(&theta, &ab, &w, &wd).to_array();
            let drag = [0.01, 0.012, 0.02];
            let wrench: [f64; 6] = std::array::from_fn(|c| {
                if c < 3 {
                    ne[c] + drag[c] * vb[c]
                } else {
                    ne[c]
                }
            });
            let q = UnitQuaternion::from_rotation_matrix(&r);
            log.push(&LogSample {
                t,
                position: p.into(),
                velocity: v.into(),
                attitude: [q.w, q.i, q.j, q.k],
                omega: w.into(),
                wrench,
                accel: Some(a.into()),
                omega_dot: Some(wd.into()),
                rotor_speeds: None,
            });
        }
        log
    }
}

#[test]
fn a_fitted_model_reads_back_bit_for_bit() {
    let file = synthetic_fit_file();
    assert_eq!(file.effects.len(), 1);
    assert_eq!(file.effects[0].coefficients.len(), 3);
    // The covariance was filled in (its diagonal is the square of the standard errors).
    for k in 0..10 {
        let se = file.inertial.std_error[k];
        let var = file.inertial.covariance[k][k];
        assert!(
            (var - se * se).abs() <= 1e-12 * var.abs(),
            "{k}: {var} vs {se}²"
        );
    }
    let text = file.to_toml_string().unwrap();
    let back = ModelFile::from_toml_str(&text).unwrap();
    assert_same_bits(&file, &back);
    assert_eq!(back.vehicle, Some(Vehicle::crazyflie_2_1()));
    // The effects rebuild a model of the same effects.
    let model = back.model().unwrap();
    assert_eq!(model.label(), "rigid body + linear-drag");
    // And the vehicle table is a vehicle file (docs/VEHICLE.md).
    let table: toml::Table = toml::from_str(&text).unwrap();
    let vehicle = toml::to_string(&table["vehicle"]).unwrap();
    assert_eq!(
        Vehicle::from_toml_str(&vehicle).unwrap(),
        Vehicle::crazyflie_2_1()
    );
}

#[test]
fn a_wrong_version_an_unknown_effect_and_a_bad_key_are_named() {
    let text = synthetic_fit_file().to_toml_string().unwrap();
    let v2 = text.replace("version = 1", "version = 2");
    assert_eq!(
        ModelFile::from_toml_str(&v2).unwrap_err(),
        ModelFileError::UnsupportedVersion { found: 2 }
    );
    let other = text.replace("format = \"tagk-model\"", "format = \"other\"");
    assert!(matches!(
        ModelFile::from_toml_str(&other).unwrap_err(),
        ModelFileError::WrongFormat { .. }
    ));
    let unknown = text.replace("name = \"linear-drag\"", "name = \"warp-drive\"");
    assert_eq!(
        ModelFile::from_toml_str(&unknown).unwrap_err(),
        ModelFileError::UnknownEffect {
            name: "warp-drive".into()
        }
    );
    let typo = text.replace("values = [", "valeus = [");
    let err = ModelFile::from_toml_str(&typo).unwrap_err().to_string();
    assert!(err.contains("valeus") || err.contains("values"), "{err}");
    let short = text.replace("names = [\"m\", ", "names = [");
    let err = ModelFile::from_toml_str(&short).unwrap_err();
    assert!(
        matches!(&err, ModelFileError::BadValue { key, .. } if key == "inertial.names"),
        "{err}"
    );
    assert!(matches!(
        ModelFile::from_toml_str("format = [").unwrap_err(),
        ModelFileError::Malformed { .. }
    ));
}

#[test]
fn a_custom_effect_is_rebuilt_from_its_spec() {
    let mut file = ModelFile::rigid_body([0.035, 0.0, 0.0, 0.0, 1e-5, 0.0, 1e-5, 0.0, 0.0, 2e-5]);
    file.effects.push(ModelEffect {
        name: "vbat".into(),
        spec: Some("vbat=vbat*fz@fz".into()),
        scanned: None,
        coefficients: vec![],
    });
    let back = ModelFile::from_toml_str(&file.to_toml_string().unwrap()).unwrap();
    let effects = back.effects().unwrap();
    assert_eq!(effects[0].name(), "vbat");
    file.effects[0].spec = Some("vbat=vbat".into());
    assert!(matches!(
        ModelFile::from_toml_str(&file.to_toml_string().unwrap()).unwrap_err(),
        ModelFileError::BadSpec { .. }
    ));
}

/// Any finite `f64` (every exponent, subnormals, signed zeros).
fn any_finite() -> impl Strategy<Value = f64> {
    any::<u64>()
        .prop_map(f64::from_bits)
        .prop_filter("finite", |x| x.is_finite())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]
    #[test]
    fn random_values_read_back_bit_for_bit(
        values in proptest::collection::vec(any_finite(), 10),
        cov in proptest::collection::vec(any_finite(), 100),
        se in proptest::collection::vec(any_finite(), 10),
        coef in proptest::collection::vec((any_finite(), any_finite(), any_finite(), any_finite()), 1..4),
        scanned in (any_finite(), any_finite(), any_finite()),
        sensing in (any_finite(), any_finite(), proptest::array::uniform3(any_finite()), any_finite()),
        mass in any_finite(),
    ) {
        let mut file = ModelFile::rigid_body([0.0; 10]);
        file.inertial = InertialSection {
            values: values.clone(),
            std_error: se,
            covariance: cov.chunks(10).map(<[f64]>::to_vec).collect(),
            known_mass: Some(mass.abs().max(f64::MIN_POSITIVE)),
            ..file.inertial
        };
        file.effects.push(ModelEffect {
            name: "motor-lag".into(),
            spec: None,
            scanned: Some(ScannedParameter {
                name: "tau".into(),
                unit: "s".into(),
                value: scanned.0,
                interval: Some([scanned.1, scanned.2]),
            }),
            coefficients: coef
                .iter()
                .enumerate()
                .map(|(k, (v, e, lo, hi))| ModelCoefficient {
                    name: format!("c{k}"),
                    unit: "N".into(),
                    value: *v,
                    std_error: Some(*e),
                    interval: Some([*lo, *hi]),
                })
                .collect(),
        });
        file.sensing = Sensing {
            derived_accelerations: true,
            align: false,
            resample: Some(sensing.0),
            shifts: vec![StreamShift {
                log: String::new(),
                sensor: Sensor::Gyro,
                seconds: sensing.1,
                action: "given".into(),
            }],
            accelerometer_offsets: vec![AccelOffsetRecord {
                log: "a.csv".into(),
                offset: sensing.2,
                removed_z: sensing.3,
            }],
        };
        let text = file.to_toml_string().unwrap();
        let back = ModelFile::from_toml_str(&text).unwrap();
        assert_same_bits(&file, &back);
    }
}
