//! [`DiagnosisPlan`]: from logs or files to a report in one call, its settings checked before
//! any work with the command line's typed errors.

mod common;

use tagk_diagnose::{
    CustomEffect, DiagnoseError, DiagnosisPlan, EffectKind, FlightLog, KnownMass, LogError,
};
use tagk_dynamics::vehicle::Vehicle;

fn drag_log(seed: u64) -> FlightLog {
    common::sim_log(Some(tagk_sim::EffectKind::LinearDrag), seed)
}

/// `log` without the samples of `from < t < to`.
fn cut(log: &FlightLog, from: f64, to: f64) -> FlightLog {
    let mut out = FlightLog::new();
    for s in log.samples().filter(|s| !(s.t > from && s.t < to)) {
        out.push(&s);
    }
    out
}

#[test]
fn settings_are_checked_before_any_work_with_typed_errors() {
    let log = drag_log(1);
    // An unknown effect name, with or without a log.
    let unknown = DiagnosisPlan::new().with_effects(["anti-gravity"]);
    assert_eq!(
        unknown.validate(),
        Err(DiagnoseError::UnknownEffect("anti-gravity".into()))
    );
    assert_eq!(
        unknown.log(log.clone()).run().unwrap_err(),
        DiagnoseError::UnknownEffect("anti-gravity".into())
    );
    // The vehicle's mass prior without a vehicle.
    let err = DiagnosisPlan::new()
        .known_mass(KnownMass::Vehicle)
        .validate()
        .unwrap_err();
    assert!(
        matches!(err, DiagnoseError::InvalidOption { field: "mass", .. }),
        "{err}"
    );
    assert!(err.to_string().contains("needs `--vehicle"), "{err}");
    // A mass that is not positive.
    assert!(matches!(
        DiagnosisPlan::new().known_mass(-0.035).validate(),
        Err(DiagnoseError::InvalidModel(_))
    ));
    // A custom effect on a column the log lacks: valid alone, refused against the log.
    let custom = DiagnosisPlan::new().custom("vbat=vbat*fz@fz");
    assert_eq!(custom.validate(), Ok(()));
    let missing = custom.resolve(&log).unwrap_err();
    assert!(
        matches!(&missing, DiagnoseError::UnknownColumn { effect, column, available }
            if effect == "vbat" && column == "vbat" && available.contains("vx") && available.contains("vbx")),
        "{missing}"
    );
    assert_eq!(custom.log(log.clone()).run().unwrap_err(), missing);
    // A custom effect may not take a built-in name, as a specification or as an effect.
    for plan in [
        DiagnosisPlan::new().custom("delay=vx@fx"),
        DiagnosisPlan::new().custom(CustomEffect::new("wind", vec!["vx".into()], vec![0]).unwrap()),
    ] {
        let err = plan.validate().unwrap_err();
        assert!(
            matches!(&err, DiagnoseError::BadCustomSpec { reason, .. } if reason.contains("built-in")),
            "{err}"
        );
    }
    // Six noise values, a positive airframe radius.
    assert!(matches!(
        DiagnosisPlan::new().noise_floor([1e-3; 2]).validate(),
        Err(DiagnoseError::InvalidOption {
            field: "noise_floor",
            ..
        })
    ));
    assert!(matches!(
        DiagnosisPlan::new().airframe_radius(0.0).validate(),
        Err(DiagnoseError::InvalidOption {
            field: "airframe_radius",
            ..
        })
    ));
    // No logs.
    assert!(matches!(
        DiagnosisPlan::new().run(),
        Err(DiagnoseError::InvalidOption { field: "logs", .. })
    ));
    // A log without the wrench needs a vehicle; the error names the flight.
    let mut rotors = log.clone();
    rotors.wrench.clear();
    match DiagnosisPlan::new()
        .named_log("rotors.csv", rotors.clone())
        .run()
        .unwrap_err()
    {
        DiagnoseError::Log(LogError::InFile { path, source }) => {
            assert_eq!(path, "rotors.csv");
            assert_eq!(
                *source,
                LogError::MissingWrench {
                    has_rotor_speeds: true
                }
            );
        }
        other => panic!("{other:?}"),
    }
    // Names resolve to the effects: aliases, kinds, custom effects.
    let plan = DiagnosisPlan::new()
        .custom("thrust=fz*fz@fz")
        .with_effects(["Wrench_Bias", " ", "thrust"])
        .with_effect(EffectKind::TimeDelay)
        .resolve(&log)
        .unwrap();
    let names: Vec<&str> = plan.with.iter().map(|e| e.name()).collect();
    assert_eq!(
        names,
        [
            EffectKind::BodyBias.name(),
            "thrust",
            EffectKind::TimeDelay.name()
        ]
    );
    // The vehicle's airframe radius is the default.
    let vehicle = Vehicle::preset("crazyflie-2.1").unwrap();
    let radius = vehicle.airframe_radius;
    let plan = DiagnosisPlan::new().vehicle(vehicle).resolve(&log).unwrap();
    assert_eq!(plan.options.airframe_radius, radius);
}

#[test]
fn several_logs_join_and_a_log_with_gaps_joins_segment_by_segment() {
    let a = drag_log(1);
    // 25 s at 50 Hz: a gap from 10 s to 12 s leaves segments of about 500 and 650 samples.
    let gappy = cut(&drag_log(2), 10.0, 12.0);
    let report = DiagnosisPlan::new()
        .named_log("a.csv", a.clone())
        .named_log("gappy.csv", gappy.clone())
        .max_steps(1)
        .run()
        .unwrap();
    let names: Vec<&str> = report.logs.iter().map(|l| l.log.as_str()).collect();
    assert_eq!(names.len(), 3, "{names:?}");
    assert_eq!(names[0], "a.csv");
    assert!(
        names[1].starts_with("gappy.csv (segment 1 of 2, t = 0."),
        "{names:?}"
    );
    assert!(
        names[2].starts_with("gappy.csv (segment 2 of 2, t = 12."),
        "{names:?}"
    );
    let samples: usize = report.logs.iter().map(|l| l.samples).sum();
    assert_eq!(samples, a.len() + gappy.len());
    assert_eq!(report.sampling.len(), 2);
    assert_eq!(report.sampling[1].log, "gappy.csv");
    assert_eq!(report.sampling[1].segments, 2);
    assert!(report.streams.iter().any(|s| s.log == "gappy.csv"));

    // A log whose gaps leave only short segments cannot join: the error names it.
    let mut shreds = FlightLog::new();
    for (k, s) in a.samples().enumerate() {
        // A gap every 150 samples.
        let t = s.t + (k / 150) as f64;
        shreds.push(&tagk_diagnose::LogSample { t, ..s });
    }
    let err = DiagnosisPlan::new()
        .named_log("a.csv", a)
        .named_log("shreds.csv", shreds)
        .run()
        .unwrap_err();
    assert!(
        matches!(&err, DiagnoseError::InvalidOption { field: "logs", reason } if reason.starts_with("shreds.csv:")),
        "{err}"
    );
}

#[test]
fn a_file_and_the_same_log_in_memory_give_the_same_report() {
    let dir = std::env::temp_dir().join(format!("tagk-diagnose-plan-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("flight.csv");
    let log = drag_log(3);
    log.write_csv_path(&path).unwrap();
    let from_file = DiagnosisPlan::new().file(&path).read().unwrap();
    let flight = from_file.flights().next().unwrap();
    assert_eq!(flight.name, path.display().to_string());
    assert!(flight.merge.is_none());
    let a = from_file.max_steps(1).run().unwrap();
    let b = DiagnosisPlan::new().log(log).max_steps(1).run().unwrap();
    assert_eq!(a.to_json().unwrap(), b.to_json().unwrap());
    // A missing file is the reader's error, naming it.
    let err = DiagnosisPlan::new()
        .file(dir.join("nosuch.csv"))
        .run()
        .unwrap_err();
    assert!(err.to_string().contains("nosuch.csv"), "{err}");
    std::fs::remove_dir_all(&dir).ok();
}

/// The same data twice — one log under two names — is refused before the fit, naming both
/// (counted twice, it would narrow every interval by √2); a changed sample makes it another
/// flight.
#[test]
fn the_same_flight_twice_is_refused() {
    let log = drag_log(2);
    let err = DiagnosisPlan::new()
        .named_log("a", log.clone())
        .named_log("b", log.clone())
        .run()
        .unwrap_err();
    match &err {
        DiagnoseError::InvalidOption {
            field: "logs",
            reason,
        } => assert!(reason.starts_with("a and b hold the same data"), "{reason}"),
        other => panic!("{other:?}"),
    }
    let mut other = log.clone();
    other.wrench[10][2] += 1e-9;
    let report = DiagnosisPlan::new()
        .named_log("a", log)
        .named_log("b", other)
        .max_steps(0)
        .run()
        .unwrap();
    assert_eq!(report.logs.len(), 2);
}
