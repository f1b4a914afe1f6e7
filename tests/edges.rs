//! Reliability at the edges: gaps in a log, requests over the memory budget, wrong flags and
//! wrong files get a clear typed error or a documented behaviour (issue 17).

use std::path::PathBuf;

use clap::Parser;
use tagk::cli::diagnose::{DiagnoseArgs, diagnose_log, diagnose_logs, plan, run_diagnose};
use tagk::cli::simulate::{SimulateArgs, SimulateError, run_simulate};
use tagk::diagnose::{DiagnoseError, FlightLog, Model, Signals, fit_model};
use tagk::dynamics::deriv::{DEFAULT_HALF_WIDTH, savitzky_golay_derivative3};
use tagk::sim::{Adaptation, NoiseLevel, PayloadSchedule, SimConfig, SimError, TrajectoryKind};

#[derive(Parser)]
struct Cli {
    #[command(flatten)]
    args: SimulateArgs,
}

fn tmpdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("tagk-edges-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A noise-free figure-8 flight of `duration` s at 50 Hz without payload.
fn flight(duration: f64) -> FlightLog {
    let config = SimConfig {
        trajectory: TrajectoryKind::Figure8,
        duration,
        seed: 5,
        noise: NoiseLevel::None,
        payload: PayloadSchedule::None,
        adaptation: Adaptation::Nominal,
        record_log: true,
        stop_on_abort: false,
        ..SimConfig::default()
    };
    tagk::sim::simulate(&config).expect("simulation runs").log
}

/// The 10 s flight with the samples of `3 s < t < 7 s` cut out, and its accelerations
/// removed (so that the diagnosis differentiates the velocities).
fn gappy_log() -> FlightLog {
    let full = flight(10.0);
    let mut log = FlightLog::new();
    for s in full.samples().filter(|s| !(s.t > 3.0 && s.t < 7.0)) {
        log.push(&tagk::diagnose::LogSample {
            accel: None,
            omega_dot: None,
            ..s
        });
    }
    log
}

#[test]
fn a_log_with_a_gap_is_reported_and_split_never_differentiated_across() {
    let log = gappy_log();
    let sampling = log.sampling();
    assert_eq!(sampling.gaps.len(), 1, "{sampling}");
    let gap = sampling.gaps[0];
    assert!(gap.start < 3.0 && gap.start + gap.duration > 7.0, "{gap:?}");
    assert!(sampling.to_string().contains("gap: 4.0"), "{sampling}");

    let (split, segments) = Signals::from_log_split(&log).unwrap();
    assert_eq!(segments, sampling.segments());
    assert_eq!(split.parts().len(), 2);
    assert_eq!(split.t, log.t, "the log's own time stamps are kept");
    // Independent check: the angular acceleration after the gap is the derivative of the
    // second segment alone.
    let second = segments[1].clone();
    let alone = savitzky_golay_derivative3(
        &log.t[second.clone()],
        &log.omega[second.clone()],
        DEFAULT_HALF_WIDTH,
    );
    for (k, i) in second.clone().take(DEFAULT_HALF_WIDTH + 1).enumerate() {
        for (got, want) in split.omega_dot(i).iter().zip(alone[k]) {
            assert!(
                (got - want).abs() <= 1e-9 * (1.0 + want.abs()),
                "sample {i}"
            );
        }
    }
    // Differentiating across the gap (the whole log at once) breaks the rigid-body fit at the
    // gap; the split fit does not.
    let whole = Signals::from_log(&log).unwrap();
    let near_gap = |s: &Signals| {
        let fit = fit_model(&Model::rigid_body(), s, None).unwrap();
        (second.start - 3..second.start + 3)
            .map(|i| fit.residual[i][3].abs().max(fit.residual[i][4].abs()))
            .fold(0.0, f64::max)
    };
    let (split_residual, whole_residual) = (near_gap(&split), near_gap(&whole));
    assert!(
        split_residual * 10.0 < whole_residual,
        "torque residual at the gap: split {split_residual:e}, whole {whole_residual:e}"
    );

    // End to end: `tagk diagnose` on the file accepts it and fits the segments jointly.
    let dir = tmpdir("gap");
    let path = dir.join("gap.csv");
    log.write_csv_path(&path).unwrap();
    let mut args = DiagnoseArgs::new(&path);
    args.quiet = true;
    args.max_steps = 0;
    run_diagnose(&args).unwrap();
    let report = diagnose_log(&log, &args).unwrap();
    assert_eq!(report.before.samples, log.len());
    // The gap travels with the report: terminal, JSON and HTML name where and how long.
    assert_eq!(report.sampling.len(), 1);
    let found = &report.sampling[0];
    assert_eq!(found.segments, 2);
    assert_eq!(found.sampling.gaps, sampling.gaps);
    let table = tagk::diagnose::report_table(&report);
    assert!(table.contains("gap: 4.0"), "{table}");
    assert!(
        table.contains("split at the gaps into 2 segments"),
        "{table}"
    );
    let json: serde_json::Value = serde_json::from_str(&report.to_json().unwrap()).unwrap();
    let gap_json = &json["sampling"][0]["gaps"][0];
    assert_eq!(gap_json["index"], gap.index);
    assert!((gap_json["duration"].as_f64().unwrap() - gap.duration).abs() < 1e-12);
    assert_eq!(json["sampling"][0]["segments"], 2);
    let html = tagk::diagnose::html::render(&report);
    assert!(
        html.contains("id=\"sampling\""),
        "the HTML report has a sampling section"
    );
    assert!(html.contains("gap: 4.0"), "the HTML report names the gap");
    // With other logs, a log whose segments are all too short to stand alone is refused,
    // naming it.
    let err = diagnose_logs(
        vec![
            ("full.csv".into(), flight(6.0)),
            ("gap.csv".into(), log.clone()),
        ],
        &args,
    )
    .unwrap_err();
    assert!(err.to_string().contains("gap.csv"), "{err}");
    // Resampling (the user's choice) keeps the gap and the split.
    args.resample = Some(0.01);
    let resampled = diagnose_log(&log, &args).unwrap();
    assert!(resampled.before.samples > log.len());
    assert_eq!(resampled.sampling[0].resampled_step, Some(0.01));
    assert!(
        tagk::diagnose::report_table(&resampled).contains("uniform 0.01 s grid"),
        "the resampling is reported"
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// A log whose wrench is exactly the rigid-body model's `Y(a, ω, ω̇) θ` of the Crazyflie on the
/// simulator's motion: the rigid body fits it to rounding.
fn noise_free_log() -> FlightLog {
    use tagk::dynamics::nalgebra::{Quaternion, SVector, UnitQuaternion, Vector3};
    let mut log = flight(12.0);
    let theta = tagk::dynamics::QuadrotorModel::crazyflie_2_1().params;
    let accel = log.accel.clone().expect("the simulator logs p''");
    let omega_dot = log
        .omega_dot
        .clone()
        .expect("the simulator logs the angular acceleration");
    for i in 0..log.len() {
        let q = log.attitude[i];
        let r = UnitQuaternion::from_quaternion(Quaternion::new(q[0], q[1], q[2], q[3]));
        let a = tagk::dynamics::proper_acceleration(&r, &Vector3::from(accel[i]));
        let y = tagk::dynamics::rigid_body_regressor(
            &a,
            &Vector3::from(log.omega[i]),
            &Vector3::from(omega_dot[i]),
        );
        let w = y * SVector::<f64, 10>::from_column_slice(theta.as_slice());
        log.wrench[i] = std::array::from_fn(|k| w[k]);
    }
    log
}

#[test]
fn a_noise_free_log_lists_no_rounding_noise_as_failures() {
    let log = noise_free_log();
    let mut args = DiagnoseArgs::new("noise-free.csv");
    args.max_steps = 0;
    let report = diagnose_log(&log, &args).unwrap();
    let d = &report.before;
    assert!(d.failure_windows.is_empty(), "{:?}", d.failure_windows);
    assert!(d.whiteness.iter().all(|w| w.white), "{:?}", d.findings);
    assert!(
        !d.findings
            .iter()
            .any(|f| f.contains("not white") || f.contains("window")),
        "{:?}",
        d.findings
    );
}

#[test]
fn simulate_refuses_a_request_above_the_memory_budget() {
    let cli = Cli::try_parse_from(["tagk", "--duration", "1e9"]).unwrap();
    let err = run_simulate(&cli.args).unwrap_err();
    assert!(
        matches!(err, SimulateError::Sim(SimError::OverMemoryBudget { .. })),
        "{err}"
    );
    let message = err.to_string();
    assert!(
        message.contains("GiB") && message.contains("budget"),
        "{message}"
    );
    // The budget is stated and the estimate scales with the log rate.
    let mut config = cli.args.config().unwrap();
    config.duration = 3600.0;
    assert!(config.memory_estimate_bytes() < tagk::sim::MEMORY_BUDGET_BYTES);
    config.log_rate = tagk::sim::LogRate::Physics;
    let physics = config.memory_estimate_bytes();
    config.log_rate = tagk::sim::LogRate::Control;
    assert!(physics > 9 * config.memory_estimate_bytes());
}

#[test]
fn fixed_payload_flags_need_a_fixed_payload_and_a_positive_mass() {
    let parse = |flags: &[&str]| {
        let mut argv = vec!["tagk"];
        argv.extend_from_slice(flags);
        Cli::try_parse_from(argv).unwrap().args.config()
    };
    let err = parse(&["--payload-mass=-1"]).unwrap_err();
    assert!(matches!(err, SimError::NonPositiveMass { .. }), "{err}");
    assert!(err.to_string().contains("--payload-mass"), "{err}");
    let err = parse(&["--payload", "fixed", "--payload-mass", "-1"]).unwrap_err();
    assert!(matches!(err, SimError::NonPositiveMass { .. }), "{err}");
    let err = parse(&["--payload-mass", "0.02"]).unwrap_err();
    assert!(
        matches!(
            err,
            SimError::InvalidParameter {
                name: "payload_mass",
                ..
            }
        ),
        "{err}"
    );
    assert!(err.to_string().contains("--payload fixed"), "{err}");
    let err = parse(&["--payload", "protocol", "--attach", "2"]).unwrap_err();
    assert!(
        matches!(err, SimError::InvalidParameter { name: "attach", .. }),
        "{err}"
    );
    assert!(parse(&["--payload", "fixed", "--payload-mass", "0.02"]).is_ok());
    assert!(parse(&[]).is_ok());
}

#[test]
fn diagnose_flags_and_files_get_clear_errors() {
    let log = flight(6.0);
    let dir = tmpdir("flags");
    let path = dir.join("flight.csv");
    log.write_csv_path(&path).unwrap();

    // `--mass nan` is about `--mass`.
    let mut args = DiagnoseArgs::new(&path);
    args.mass = Some(f64::NAN.into());
    let message = plan(&args, &log).unwrap_err().to_string();
    assert!(message.contains("--mass"), "{message}");
    assert!(!message.contains("least-squares"), "{message}");

    // The same effect twice, by name and alias.
    let mut args = DiagnoseArgs::new(&path);
    args.with = vec!["linear-drag".into(), "linear-drag".into()];
    let err = diagnose_log(&log, &args).unwrap_err();
    assert!(err.to_string().contains("linear-drag"), "{err}");

    // A custom effect may not take a built-in effect's name (or alias).
    for name in ["linear-drag", "delay"] {
        let mut args = DiagnoseArgs::new(&path);
        args.custom = vec![format!("{name}=vx@fx")];
        args.with = vec![name.into()];
        let err = plan(&args, &log).unwrap_err();
        assert!(err.to_string().contains(name), "{err}");
    }

    // A custom effect naming a column the log lacks, without `--with`.
    let mut args = DiagnoseArgs::new(&path);
    args.custom = vec!["x=nosuchcol@fz".into()];
    assert!(matches!(
        plan(&args, &log),
        Err(DiagnoseError::UnknownColumn { .. })
    ));

    // A negative airframe radius.
    let mut args = DiagnoseArgs::new(&path);
    args.airframe_radius = Some(-1.0);
    assert!(matches!(
        plan(&args, &log),
        Err(DiagnoseError::InvalidOption {
            field: "airframe_radius",
            ..
        })
    ));

    // An empty file and a directory say so, naming the path.
    let empty = dir.join("empty.csv");
    std::fs::write(&empty, "").unwrap();
    let message = run_diagnose(&DiagnoseArgs::new(&empty))
        .unwrap_err()
        .to_string();
    assert!(
        message.contains("empty.csv") && message.contains("empty file"),
        "{message}"
    );
    let message = run_diagnose(&DiagnoseArgs::new(&dir))
        .unwrap_err()
        .to_string();
    assert!(message.contains("is a directory"), "{message}");
    // A content error names the file.
    let bad = dir.join("bad.csv");
    std::fs::write(&bad, "t,px\n0,0\n").unwrap();
    let message = run_diagnose(&DiagnoseArgs::new(&bad))
        .unwrap_err()
        .to_string();
    assert!(message.contains("bad.csv"), "{message}");
    std::fs::remove_dir_all(&dir).ok();
}
