//! Time delay per stream (issue #12): a flight whose gyro stream arrives late against the pose
//! and the actuators, as a motion-capture + IMU + telemetry log does. `tagk diagnose` must
//! time the gyro against the attitude, remove the offset before the fit, say so, and then find
//! the hidden physics and nothing else; a log without an offset must be left alone.

use tagk::cli::diagnose::{DiagnoseArgs, diagnose_log};
use tagk::diagnose::{
    AlignOptions, EffectKind as Vocabulary, FlightLog, Report, Sensor, StreamAlignment,
    align_streams, streams_table,
};
use tagk::sim::{
    Adaptation, EffectKind, NoiseLevel, PayloadSchedule, PlantEffects, Sensing, SimConfig,
    TrajectoryKind,
};

/// A 25 s figure-8 with rotor drag hidden, realistic sensing (a Crazyflie's IMU, calibrated;
/// rotor speeds read as eRPM telemetry), yawing at 0.3 rad/s: the log as a user has it.
fn flight() -> FlightLog {
    let config = SimConfig {
        trajectory: TrajectoryKind::Figure8,
        duration: 25.0,
        seed: 11,
        noise: NoiseLevel::Medium,
        sensing: Sensing {
            rotor_speed_noise: 6.0,
            ..Sensing::realistic_calibrated()
        },
        payload: PayloadSchedule::None,
        effects: PlantEffects::only(EffectKind::RotorDrag).unwrap(),
        adaptation: Adaptation::Nominal,
        record_log: true,
        stop_on_abort: false,
        yaw_rate: 0.3,
        ..SimConfig::default()
    };
    let out = tagk::sim::simulate(&config).expect("simulation runs");
    assert!(!out.metrics.aborted);
    let mut csv = Vec::new();
    out.log.write_csv(&mut csv).unwrap();
    FlightLog::from_csv_reader(csv.as_slice()).unwrap()
}

/// Rows `k..n` of the log with the chosen streams `k` samples late: the row at `tᵢ` carries
/// their samples of `tᵢ₋ₖ`.
fn late(log: &FlightLog, k: usize, pose: bool, imu: bool) -> FlightLog {
    let mut out = FlightLog::new();
    for i in k..log.len() {
        let mut s = log.sample(i).unwrap();
        let old = log.sample(i - k).unwrap();
        if pose {
            s.position = old.position;
            s.attitude = old.attitude;
            s.velocity = old.velocity;
        }
        if imu {
            s.omega = old.omega;
            s.omega_dot = old.omega_dot;
            s.accel = old.accel;
        }
        out.push(&s);
    }
    out
}

fn period(log: &FlightLog) -> f64 {
    (log.t[log.len() - 1] - log.t[0]) / (log.len() - 1) as f64
}

fn families(names: &[String]) -> Vec<&'static str> {
    let mut f: Vec<&str> = names
        .iter()
        .map(|n| Vocabulary::from_name(n).unwrap().family())
        .collect();
    f.sort_unstable();
    f
}

/// The command that reproduces the report's final model.
fn command(report: &Report) -> &str {
    report
        .final_model
        .command
        .as_deref()
        .expect("the CLI fills it in")
}

/// The report's entry for one stream.
fn stream(report: &Report, sensor: Sensor) -> Option<&StreamAlignment> {
    report.streams.iter().find(|s| s.sensor == sensor)
}

fn args() -> DiagnoseArgs {
    let mut a = DiagnoseArgs::new("flight.csv");
    a.quiet = true;
    a
}

/// Motion capture late against the onboard IMU and motor telemetry: the usual case, the pose
/// comes over a network.
///
/// The log has no accelerometer, so its forces come from the motion-capture velocity and its
/// torques from the gyro. The gyro's offset against the attitude is measured. The pose and the
/// velocity are moved onto the IMU's clock. The staircase finds the drag and no timing effect.
#[test]
fn late_motion_capture_is_moved_onto_the_imu_clock() {
    let mut log = flight();
    log.accel = None;
    let dt = period(&log);
    let k = 3;
    let shifted = late(&log, k, true, false);
    let report = diagnose_log(&shifted, &args()).unwrap();
    let gyro = stream(&report, Sensor::Gyro).expect("the gyro is timed");
    let est = gyro.estimate.as_ref().expect("the gyro offset is measured");
    // The gyro is early against the late pose.
    let truth = -(k as f64) * dt;
    let (lo, hi) = est.confidence_interval;
    assert!(
        (est.delay - truth).abs() < 0.25 * dt && lo <= truth && truth <= hi,
        "pose late by {} s: gyro measured {est:?}",
        -truth
    );
    let pose = stream(&report, Sensor::Pose).expect("the pose is moved");
    assert_eq!((pose.action, pose.applied), ("measured", -est.delay));
    let velocity = stream(&report, Sensor::Velocity).unwrap();
    assert!(
        !velocity.estimate.as_ref().unwrap().significant(),
        "{velocity:?}"
    );
    assert_eq!(
        (velocity.action, velocity.applied),
        ("measured", -est.delay)
    );
    assert_eq!(
        families(&report.final_model.added),
        vec![Vocabulary::RotorDrag.family()],
        "{:?} ({})",
        report.final_model.added,
        report.stopped
    );
    let text = tagk::diagnose::report_table(&report);
    assert!(
        text.contains("stream timing") && text.contains("IMU's clock"),
        "{text}"
    );
    let html = tagk::diagnose::html::render(&report);
    assert!(
        html.contains("id=\"stream-timing\"") && html.contains("IMU's clock"),
        "no stream timing in the HTML report"
    );
    // The command that reproduces the model needs nothing extra: the alignment is the default.
    let cmd = report.final_model.command.clone().unwrap();
    assert!(
        !cmd.contains("--shift") && !cmd.contains("--no-align"),
        "{cmd}"
    );
}

/// The IMU late against motion capture and motor telemetry: the pose moves onto the IMU's
/// clock, and the actuator stream's offset against the IMU is then the staircase's
/// `time-delay`, found with its value: every stream ends on one clock.
#[test]
fn a_late_imu_leaves_the_actuator_offset_to_time_delay() {
    let log = flight();
    let dt = period(&log);
    let k = 3;
    let shifted = late(&log, k, false, true);
    let report = diagnose_log(&shifted, &args()).unwrap();
    let pose = stream(&report, Sensor::Pose).expect("the pose is moved");
    assert!((pose.applied + k as f64 * dt).abs() < 0.25 * dt, "{pose:?}");
    let mut expected = vec![
        Vocabulary::RotorDrag.family(),
        Vocabulary::TimeDelay.family(),
    ];
    expected.sort_unstable();
    assert_eq!(
        families(&report.final_model.added),
        expected,
        "{:?} ({})",
        report.final_model.added,
        report.stopped
    );
    let delay = report
        .final_diagnosis()
        .effects
        .iter()
        .find(|e| e.effect == Vocabulary::TimeDelay.name())
        .and_then(|e| e.scanned.clone())
        .expect("a scanned delay");
    assert!(
        (delay.1 - k as f64 * dt).abs() < 0.5 * dt,
        "actuators early by {} s: time-delay {delay:?}",
        k as f64 * dt
    );
}

#[test]
fn streams_in_step_are_left_alone() {
    let log = flight();
    let report = diagnose_log(&log, &args()).unwrap();
    assert!(!report.streams.is_empty());
    for s in &report.streams {
        assert_eq!(s.action, "none", "{s:?}");
        let e = s.estimate.as_ref().expect("measured");
        // The simulator logs the acceleration of each interval: half a sample behind the
        // pose, by construction; it is reported, never moved.
        if s.sensor != Sensor::Accelerometer {
            assert!(!e.significant(), "{s:?}");
        }
    }
}

#[test]
fn given_shifts_and_no_align_are_honoured_and_reproduced() {
    let log = flight();
    let shifted = late(&log, 3, true, false);
    let mut a = args();
    a.no_align = true;
    let report = diagnose_log(&shifted, &a).unwrap();
    let gyro = stream(&report, Sensor::Gyro).unwrap();
    assert_eq!(gyro.action, "none");
    assert!(gyro.estimate.as_ref().unwrap().significant());
    assert!(report.streams.iter().all(|s| s.applied == 0.0));
    assert!(command(&report).contains("--no-align"));
    let mut a = args();
    a.shift = vec!["pose=0.03".into()];
    let report = diagnose_log(&shifted, &a).unwrap();
    let pose = stream(&report, Sensor::Pose).unwrap();
    assert_eq!((pose.action, pose.applied), ("given", 0.03));
    // With a given shift nothing else moves.
    assert!(
        report
            .streams
            .iter()
            .all(|s| s.sensor == Sensor::Pose || s.applied == 0.0)
    );
    assert!(command(&report).contains("--shift pose=0.03"));
    for bad in ["gyro=1e9", "lidar=0.1", "gyro=0.01,gyro=0.02"] {
        let mut a = args();
        a.shift = bad.split(',').map(String::from).collect();
        let e = diagnose_log(&shifted, &a).unwrap_err().to_string();
        assert!(e.contains("shift"), "{bad}: {e}");
    }
}

/// A `--shift` that contradicts the measured offset (issue #25).
///
/// The pose and the velocity are 3 samples late. Shifted by the right amount, they get no
/// warning. With the wrong sign, or with a gyro shift that the gyro's own timing against the
/// pose contradicts, the stream timing says so. It does in the terminal's table, the JSON's
/// `streams[].warning` and the HTML's table.
#[test]
fn a_given_shift_that_contradicts_the_measured_offset_is_flagged() {
    let log = flight();
    let shifted = late(&log, 3, true, false);
    let late_by = 3.0 * period(&log);
    let align = |shifts: Vec<(Sensor, f64)>| {
        let options = AlignOptions {
            shifts,
            ..AlignOptions::default()
        };
        align_streams(&shifted, &options).unwrap().1
    };
    // The pose's stream carries the velocity too: both move (a pose shift alone leaves the
    // velocity late against the moved position, and is flagged for it).
    let right = align(vec![(Sensor::Pose, late_by), (Sensor::Velocity, late_by)]);
    assert!(right.iter().all(|e| e.warning.is_empty()), "{right:?}");
    let wrong = align(vec![(Sensor::Pose, -late_by)]);
    let pose = wrong.iter().find(|e| e.sensor == Sensor::Pose).unwrap();
    assert!(
        pose.warning
            .contains("the shifts given assume the gyro +60.0 ms against the pose")
            && pose.warning.contains("a wrong sign or stream in --shift?"),
        "{}",
        pose.warning
    );
    let table = streams_table(&wrong);
    assert!(
        table.contains("warning: the shifts given assume the gyro"),
        "{table}"
    );
    let json = serde_json::to_value(&wrong).unwrap();
    assert!(
        json.as_array()
            .unwrap()
            .iter()
            .any(|e| e["warning"].as_str().unwrap().contains("wrong sign")),
        "{json}"
    );
    // The gyro shifted although the pose is what is late.
    let gyro = align(vec![(Sensor::Gyro, late_by)]);
    let g = gyro.iter().find(|e| e.sensor == Sensor::Gyro).unwrap();
    assert!(
        g.warning.contains("assume the gyro +60.0 ms"),
        "{}",
        g.warning
    );
    // The pose alone: the velocity, in the pose's stream, is left behind.
    let alone = align(vec![(Sensor::Pose, late_by)]);
    let pose = alone.iter().find(|e| e.sensor == Sensor::Pose).unwrap();
    assert!(
        pose.warning.contains("assume the velocity -60.0 ms") && !pose.warning.contains("gyro"),
        "{}",
        pose.warning
    );
}
