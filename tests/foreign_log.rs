//! The round trip of issue #13: a simulator log rewritten into a "foreign" layout.
//!
//! The layout has three streams in three files:
//! - the gyro in deg/s, FRD;
//! - the rotor speeds in rpm, and no wrench;
//! - the motion capture in mm / NED with an `xyzw` quaternion, at half the rate on a shifted
//!   clock.
//!
//! Time stamps are in ms and µs.
//! Read back with the Crazyflie vehicle and a column mapping, it gives the same diagnosis and
//! the same fitted θ as the original log.
//! The accelerometer (specific force, FRD, in g), read back with the motion capture's
//! attitude, gives the simulator's own world acceleration.
//! And the `time-delay` effect finds a known clock offset of the rotor stream.
//!
//! The simulator logs at 50 Hz, its control rate, and this log cannot have its 500 Hz
//! integration rate. So the streams are written at the log rate or below:
//! - the gyro stream (primary) at the log's time stamps;
//! - the rotor stream at the same rate;
//! - the motion capture at 25 Hz on time stamps shifted by 10 ms.
//!
//! The motion capture's values are linearly interpolated from the log. That is what a camera
//! system on its own clock would record, up to the interpolation error.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use common::tagk_in;
use tagk::cli::diagnose::{DiagnoseArgs, diagnose_log, read_log};
use tagk::diagnose::FlightLog;
use tagk::dynamics::log_input::{BodyFrame, WorldFrame};
use tagk::dynamics::nalgebra::{self, Rotation3, UnitQuaternion, Vector3};
use tagk::sim::{
    Adaptation, EffectKind, NoiseLevel, PayloadSchedule, PlantEffects, SimConfig, TrajectoryKind,
};

fn tmpdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("tagk-foreign-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A noise-free 25 s figure-8 flight (seed 3) with `effects` in the plant, as the simulator
/// logs it (with its exact accelerations).
fn simulate(effects: PlantEffects) -> FlightLog {
    fly(&flight_config(effects))
}

/// The flights of these tests: a noise-free 25 s figure-8 (seed 3), no payload, nominal
/// controller, logged.
fn flight_config(effects: PlantEffects) -> SimConfig {
    SimConfig {
        trajectory: TrajectoryKind::Figure8,
        duration: 25.0,
        seed: 3,
        noise: NoiseLevel::None,
        payload: PayloadSchedule::None,
        effects,
        adaptation: Adaptation::Nominal,
        record_log: true,
        stop_on_abort: false,
        ..SimConfig::default()
    }
}

/// The log of a flight (panics if it aborted: the data would not be a flight).
fn fly(config: &SimConfig) -> FlightLog {
    let out = tagk::sim::simulate(config).expect("simulation runs");
    assert!(!out.metrics.aborted);
    out.log
}

/// The log without its accelerations (a log without an accelerometer: the original and the
/// read-back log both derive them from the velocity and the rates).
fn without_accelerations(mut log: FlightLog) -> FlightLog {
    log.accel = None;
    log.omega_dot = None;
    log
}

fn write_csv(path: &Path, header: &[&str], rows: impl Iterator<Item = Vec<f64>>) {
    let mut text = header.join(",");
    text.push('\n');
    for r in rows {
        let cells: Vec<String> = r.iter().map(|x| format!("{x:e}")).collect();
        text.push_str(&cells.join(","));
        text.push('\n');
    }
    std::fs::write(path, text).unwrap();
}

const MAPPING: &str = r#"
[columns]
t = ["time_ms", "timestamp_us"]
wx = "gyro_x"
wy = "gyro_y"
wz = "gyro_z"
sfx = "acc_x"
sfy = "acc_y"
sfz = "acc_z"
w1 = "m1_rpm"
w2 = "m2_rpm"
w3 = "m3_rpm"
w4 = "m4_rpm"
px = "x_mm"
py = "y_mm"
pz = "z_mm"
vx = "vx"
vy = "vy"
vz = "vz"
q = ["qx", "qy", "qz", "qw"]

[units]
t = "ms"
omega = "deg/s"
specific_force = "g"
rotor_speeds = "rpm"
position = "mm"

[frames]
world = "ned"
body = "frd"
quaternion = "xyzw"

[streams]
primary = "imu.csv"

[streams."mocap.csv"]
units = { t = "us" }
"#;

/// Standard gravity \[m/s²\]: one `g` of an accelerometer's datasheet.
const STANDARD_GRAVITY: f64 = 9.80665;

/// The specific force `f = Rᵀ (p̈ − g_w)` an accelerometer at the body origin reads (body
/// frame FLU) for the log's sample `i` \[m/s²\], from the log's world acceleration.
fn specific_force(log: &FlightLog, i: usize) -> Vector3<f64> {
    let q = log.attitude[i];
    let r = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(q[0], q[1], q[2], q[3]));
    let a = log.accel.as_ref().expect("a log with accelerations")[i];
    tagk::dynamics::proper_acceleration(&r, &Vector3::from(a))
}

/// Writes `log` as three files plus `map.toml`, and returns the mapping path.
///
/// - `imu.csv`: the gyro and, if the log has accelerations, the accelerometer `acc_x..acc_z`
///   in g, FRD, as an autopilot logs it;
/// - `motors.csv`: rpm, its clock `rotor_clock_offset` s late;
/// - `mocap.csv`: 25 Hz, on a clock 10 ms later.
fn write_foreign(log: &FlightLog, dir: &Path, rotor_clock_offset: f64) -> PathBuf {
    write_foreign_with(log, dir, rotor_clock_offset, None)
}

/// [`write_foreign`], with the motion capture at every `mocap_every`-th log sample (its own
/// time stamps, no interpolation) instead of the 25 Hz midpoints when given.
fn write_foreign_with(
    log: &FlightLog,
    dir: &Path,
    rotor_clock_offset: f64,
    mocap_every: Option<usize>,
) -> PathBuf {
    let cw = WorldFrame::Ned.to_project(); // NED <-> ENU: symmetric, its own inverse
    let cb = BodyFrame::Frd.to_project(); // FRD <-> FLU: likewise
    let rpm = 30.0 / std::f64::consts::PI;
    let n = log.len();
    let imu_header: &[&str] = if log.accel.is_some() {
        &[
            "time_ms", "gyro_x", "gyro_y", "gyro_z", "acc_x", "acc_y", "acc_z",
        ]
    } else {
        &["time_ms", "gyro_x", "gyro_y", "gyro_z"]
    };
    write_csv(
        &dir.join("imu.csv"),
        imu_header,
        (0..n).map(|i| {
            let w = cb * Vector3::from(log.omega[i]) * 180.0 / std::f64::consts::PI;
            let mut row = vec![log.t[i] * 1e3, w.x, w.y, w.z];
            if log.accel.is_some() {
                let f = cb * specific_force(log, i) / STANDARD_GRAVITY;
                row.extend([f.x, f.y, f.z]);
            }
            row
        }),
    );
    let speeds = log
        .rotor_speeds
        .as_ref()
        .expect("the simulator logs rotor speeds");
    write_csv(
        &dir.join("motors.csv"),
        &["time_ms", "m1_rpm", "m2_rpm", "m3_rpm", "m4_rpm"],
        (0..n).map(|i| {
            let s = speeds[i];
            vec![
                (log.t[i] + rotor_clock_offset) * 1e3,
                s[0] * rpm,
                s[1] * rpm,
                s[2] * rpm,
                s[3] * rpm,
            ]
        }),
    );
    let cwq = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(cw));
    let cbq = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(cb));
    // Motion capture at the midpoints t_{2j} + 10 ms: linear interpolation of the log
    // (quaternions: normalised).
    write_csv(
        &dir.join("mocap.csv"),
        &[
            "timestamp_us",
            "x_mm",
            "y_mm",
            "z_mm",
            "vx",
            "vy",
            "vz",
            "qx",
            "qy",
            "qz",
            "qw",
        ],
        (0..n - 1).step_by(mocap_every.unwrap_or(2)).map(|i| {
            // The sample itself (`j = i`) or the midpoint with the next one.
            let j = if mocap_every.is_some() { i } else { i + 1 };
            let mid = |a: [f64; 3], b: [f64; 3]| (Vector3::from(a) + Vector3::from(b)) * 0.5;
            let p = cw * mid(log.position[i], log.position[j]) * 1e3;
            let v = cw * mid(log.velocity[i], log.velocity[j]);
            let (a, b) = (log.attitude[i], log.attitude[j]);
            let q = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
                a[0] + b[0],
                a[1] + b[1],
                a[2] + b[2],
                a[3] + b[3],
            ));
            let qf = cwq.inverse() * q * cbq;
            let t = 0.5 * (log.t[i] + log.t[j]);
            vec![
                t * 1e6,
                p.x,
                p.y,
                p.z,
                v.x,
                v.y,
                v.z,
                qf.i,
                qf.j,
                qf.k,
                qf.w,
            ]
        }),
    );
    let map = dir.join("map.toml");
    std::fs::write(&map, MAPPING).unwrap();
    map
}

fn foreign_args(dir: &Path, map: PathBuf) -> DiagnoseArgs {
    let mut args = DiagnoseArgs::new(dir.join("unused.csv"));
    args.logs.clear();
    args.columns = Some(map);
    args.stream = ["imu.csv", "motors.csv", "mocap.csv"]
        .iter()
        .map(|f| dir.join(f))
        .collect();
    args.vehicle = Some("crazyflie-2.1".into());
    args.quiet = true;
    args
}

/// Largest |x'| of a sampled signal (finite differences): the `max|ẍ|` of the bound for `x'`.
fn max_rate(t: &[f64], x: &[[f64; 3]]) -> f64 {
    (1..t.len())
        .map(|i| (Vector3::from(x[i]) - Vector3::from(x[i - 1])).norm() / (t[i] - t[i - 1]))
        .fold(0.0, f64::max)
}

#[test]
fn foreign_streams_read_back_give_the_same_diagnosis_and_theta() {
    let dir = tmpdir("roundtrip");
    let sim = simulate(PlantEffects::only(EffectKind::QuadraticDrag).unwrap());
    // As an autopilot logs it: the accelerometer kept (written as specific force), the angular
    // acceleration (which no sensor measures) derived.
    let original = with_accelerometer(sim.clone());
    let map = write_foreign(&original, &dir, 0.0);
    let args = foreign_args(&dir, map);
    let (read, merge) = read_log(&args).unwrap();
    let merge = merge.unwrap();
    assert_eq!(merge.primary, "imu.csv");
    assert!(merge.gaps.is_empty(), "{:?}", merge.gaps);
    assert_eq!(merge.dropped_in_gaps, 0);
    // The first log sample precedes the first mocap sample, the last follows the last one.
    assert_eq!(merge.dropped_outside, 2 + original.len() % 2);
    assert_eq!(read.len() + merge.dropped_outside, original.len());
    let offset = 1; // read sample k is original sample k + 1

    // Signal-level bound. Written: x(t_i + h) ≈ midpoint of x_i, x_{i+1} (step h = 20 ms);
    // read back: linear interpolation between midpoints 2h apart. Linear interpolation over a
    // step s errs by at most s²/8 · max|ẍ|, so the two stages give (h² + 4h²)/8 · max|ẍ|.
    // Velocity: ẍ is the jerk, bounded by the finite differences of the simulator's exact
    // accelerations (`max_rate`); position: ẍ is the acceleration.
    let h = 0.02;
    let accel = sim.accel.as_ref().unwrap();
    let max_acc = accel
        .iter()
        .map(|a| Vector3::from(*a).norm())
        .fold(0.0, f64::max);
    let max_jerk = max_rate(&sim.t, accel);
    let stages = 5.0 * h * h / 8.0;
    let (bound_p, bound_v) = (stages * max_acc * 1.05, stages * max_jerk * 1.05);
    let mut worst = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    for k in 0..read.len() {
        let i = k + offset;
        assert!((read.t[k] - original.t[i]).abs() < 1e-12);
        let dp = (Vector3::from(read.position[k]) - Vector3::from(original.position[i])).norm();
        let dv = (Vector3::from(read.velocity[k]) - Vector3::from(original.velocity[i])).norm();
        let dw = (Vector3::from(read.omega[k]) - Vector3::from(original.omega[i])).norm();
        let db: f64 = (0..6)
            .map(|c| (read.wrench[k][c] - original.wrench[i][c]).abs())
            .fold(0.0, f64::max);
        worst = (
            worst.0.max(dp),
            worst.1.max(dv),
            worst.2.max(dw),
            worst.3.max(db),
        );
        assert!(
            dp <= bound_p + 1e-9,
            "sample {i}: position error {dp} > {bound_p}"
        );
        assert!(
            dv <= bound_v + 1e-9,
            "sample {i}: velocity error {dv} > {bound_v}"
        );
        assert!(dw < 1e-12, "sample {i}: gyro error {dw}");
        assert!(db < 1e-12, "sample {i}: wrench error {db}");
    }
    eprintln!(
        "worst |Δp| {:.3e} m (bound {bound_p:.3e}), |Δv| {:.3e} m/s (bound {bound_v:.3e}), \
         |Δω| {:.1e}, |Δb| {:.1e}",
        worst.0, worst.1, worst.2, worst.3
    );

    // The same diagnosis, and θ within the fit's own standard errors.
    let reference = trimmed(&original, offset, read.len());
    let mut plain = DiagnoseArgs::new(dir.join("unused.csv"));
    plain.quiet = true;
    let a = diagnose_log(&reference, &plain).unwrap();
    let b = diagnose_log(&read, &args).unwrap();
    assert_eq!(a.recommended, b.recommended);
    // The hidden drag ranks first on both, with the same held-out reduction within 1 point
    // (its neighbours rotor-drag and linear-drag are within 2 points of it on both logs: the
    // diagnosis does not single one out, on either log).
    assert_eq!(a.ranking[0].effect, "quadratic-drag");
    assert!((a.ranking[0].reduction - b.ranking[0].reduction).abs() < 0.01);
    let names = |r: &tagk::diagnose::Report| -> Vec<String> {
        r.ranking.iter().take(3).map(|e| e.effect.clone()).collect()
    };
    assert_eq!(names(&a), names(&b));
    let (ta, tb) = (&a.before.fit.theta, &b.before.fit.theta);
    for k in 0..10 {
        let d = (ta.as_slice()[k] - tb.as_slice()[k]).abs();
        let se = a.before.fit.theta_se[k].unwrap_or(f64::INFINITY);
        eprintln!(
            "θ[{k}] original {:.6e} read {:.6e} |Δ| {d:.2e} se {se:.2e}",
            ta.as_slice()[k],
            tb.as_slice()[k]
        );
        assert!(d <= se, "θ[{k}]: |Δ| {d:e} above its standard error {se:e}");
    }
}

/// The reference a read-back log is compared with: the original's samples `offset..offset +
/// len` (the read-back log drops the samples outside the motion capture's time range).
fn trimmed(original: &FlightLog, offset: usize, len: usize) -> FlightLog {
    let keep = offset..offset + len;
    let mut r = original.clone();
    r.t = r.t[keep.clone()].to_vec();
    r.position = r.position[keep.clone()].to_vec();
    r.velocity = r.velocity[keep.clone()].to_vec();
    r.attitude = r.attitude[keep.clone()].to_vec();
    r.omega = r.omega[keep.clone()].to_vec();
    r.wrench = r.wrench[keep.clone()].to_vec();
    r.accel = r.accel.map(|a| a[keep.clone()].to_vec());
    r.omega_dot = r.omega_dot.map(|a| a[keep.clone()].to_vec());
    r.rotor_speeds = r.rotor_speeds.map(|a| a[keep.clone()].to_vec());
    r
}

/// Issue #13's accelerometer.
///
/// The log's accelerations are written as an autopilot's accelerometer (specific force, FRD,
/// in g). Read back through the mapping with the motion capture's attitude, they give the
/// simulator's own world acceleration, within the bound of the attitude's interpolation.
/// The read-back log's diagnosis is that of the original with its exact accelerations.
#[test]
fn the_accelerometer_read_back_is_the_simulators_world_acceleration() {
    let dir = tmpdir("accelerometer");
    let sim = simulate(PlantEffects::only(EffectKind::QuadraticDrag).unwrap());
    // No IMU measures the angular acceleration: it is derived on both logs.
    let original = with_accelerometer(sim.clone());
    let map = write_foreign(&original, &dir, 0.0);
    let args = foreign_args(&dir, map);
    let (read, merge) = read_log(&args).unwrap();
    let merge = merge.unwrap();
    assert!(
        merge.derived.contains(
            &"accel (world, from the accelerometer's specific force of imu.csv and the attitude \
              of mocap.csv)"
                .to_string()
        ),
        "{:?}",
        merge.derived
    );
    let offset = 1; // read sample k is original sample k + 1 (as in the round trip above)
    assert_eq!(read.t[0], original.t[offset]);

    // Bound. p̈ = R f + g_w: the accelerometer's f comes back exactly (FRD and g undone, at
    // the IMU's own time stamps), the attitude R from the motion capture through two linear
    // interpolations of the quaternion (as the position in the round trip above), whose
    // components have |q̈| = |½ q ⊗ ω̇ + ¼ q ⊗ ω ⊗ ω| ≤ ½ max|ω̇| + ¼ max|ω|², so the
    // quaternion errs by at most 5h²/8 of that and the rotation by twice it (small angles);
    // |Δp̈| ≤ max|f| × that angle. ω, ω̇ and f are the simulator's exact ones.
    let h = 0.02;
    let norm_max = |x: &[[f64; 3]]| {
        x.iter()
            .map(|v| Vector3::from(*v).norm())
            .fold(0.0, f64::max)
    };
    let max_omega_dot = norm_max(sim.omega_dot.as_ref().unwrap());
    let max_omega = norm_max(&sim.omega);
    let max_f = (0..sim.len())
        .map(|i| specific_force(&sim, i).norm())
        .fold(0.0, f64::max);
    let angle = 2.0 * 5.0 * h * h / 8.0 * (0.5 * max_omega_dot + 0.25 * max_omega * max_omega);
    let bound = max_f * angle * 1.05;
    let read_accel = read.accel.as_ref().expect("the accelerometer gives p̈");
    let sim_accel = sim.accel.as_ref().unwrap();
    let mut worst = 0.0f64;
    for (k, a) in read_accel.iter().enumerate() {
        let i = k + offset;
        let d = (Vector3::from(*a) - Vector3::from(sim_accel[i])).norm();
        worst = worst.max(d);
        assert!(d <= bound, "sample {i}: |Δp̈| {d:e} > {bound:e}");
        // What the regressor sees, Rᵀ (p̈ − g_w) with the read-back R, is the reading itself.
        let q = read.attitude[k];
        let r = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(q[0], q[1], q[2], q[3]));
        let seen = tagk::dynamics::proper_acceleration(&r, &Vector3::from(*a));
        assert!(
            (seen - specific_force(&sim, i)).norm() < 1e-12,
            "sample {i}"
        );
    }
    eprintln!("worst |Δp̈| {worst:.3e} m/s² (bound {bound:.3e})");

    // The same diagnosis as the original log with its exact accelerations, θ within the
    // fit's own standard errors.
    let reference = trimmed(&original, offset, read.len());
    let mut plain = DiagnoseArgs::new(dir.join("unused.csv"));
    plain.quiet = true;
    let a = diagnose_log(&reference, &plain).unwrap();
    let b = diagnose_log(&read, &args).unwrap();
    assert_eq!(a.recommended, b.recommended);
    let (ta, tb) = (&a.before.fit.theta, &b.before.fit.theta);
    for k in 0..10 {
        let d = (ta.as_slice()[k] - tb.as_slice()[k]).abs();
        let se = a.before.fit.theta_se[k].unwrap_or(f64::INFINITY);
        assert!(d <= se, "θ[{k}]: |Δ| {d:e} above its standard error {se:e}");
    }
}

/// The delay the `time-delay` candidate finds on a log (its scanned parameter) [s].
fn delay_found(report: &tagk::diagnose::Report) -> f64 {
    report
        .before
        .ranking
        .iter()
        .find(|c| c.effect == "time-delay")
        .and_then(|c| c.scanned.as_ref())
        .map(|(_, d, _)| *d)
        .expect("time-delay is a candidate")
}

/// The log as an IMU logs it: its accelerations (the accelerometer) kept, the angular
/// acceleration (which no sensor measures) dropped.
fn with_accelerometer(mut log: FlightLog) -> FlightLog {
    log.omega_dot = None;
    log
}

#[test]
fn a_known_clock_offset_of_the_rotor_stream_is_found_by_time_delay() {
    let dir = tmpdir("offset");
    // With the accelerometer, as an autopilot logs it (with accelerations derived from the
    // 25 Hz motion capture the native log's candidate is rejected as implausible, gain 0.65:
    // the differentiator's smoothing looks like part of a shift).
    let original = with_accelerometer(simulate(PlantEffects::none()));
    // The rotor stream's clock runs 20 ms late: the wrench merged at t is the one of t − 20 ms.
    let map = write_foreign(&original, &dir, 0.02);
    let args = foreign_args(&dir, map.clone());
    let (read, _) = read_log(&args).unwrap();
    let report = diagnose_log(&read, &args).unwrap();
    let found = delay_found(&report);
    // The same 20 ms offset made by the simulator in its own log (the native format).
    let native = with_accelerometer(simulate(PlantEffects::only(EffectKind::TimeDelay).unwrap()));
    let mut plain = DiagnoseArgs::new(dir.join("unused.csv"));
    plain.quiet = true;
    let reference = diagnose_log(&native, &plain).unwrap();
    let found_native = delay_found(&reference);
    eprintln!("delay found: foreign {found} s, native {found_native} s");
    // Found and recommended, with the right sign (the actuator log is late: d < 0) and the
    // candidate's resolution: its column `g·(b(t − d) − b(t))` is, for a shift short against
    // the motion, identified through `g·d` only; here g = 0.95, d = −0.025 s, g·d = −0.024 s
    // (the native log: g = 0.83, d = −0.030 s, g·d = −0.025 s). The read-back log gives what
    // the native one gives, within one step of the scan.
    assert_eq!(report.recommended.as_deref(), Some("time-delay"));
    // The native log's offset is not a whole number of samples of its own time stamps (the
    // simulator delays the command by 20 ms against interval midpoints); its candidate finds
    // the same delay but its refit is refused (docs/CONVENTIONS.md §7.1), so only the found
    // delay is compared.
    assert!((-0.04..=-0.015).contains(&found), "delay {found}");
    // Delays are applied in whole samples (a fraction would average neighbouring samples'
    // noise): the two agree within one 20 ms sample.
    assert!((found - found_native).abs() <= 0.02 + 1e-9);
    // And the mapping's per-stream offset undoes it.
    let mut text = std::fs::read_to_string(&map).unwrap();
    text.push_str("\n[streams.\"motors.csv\"]\noffset = -0.02\n");
    std::fs::write(&map, text).unwrap();
    let (read, _) = read_log(&args).unwrap();
    let report = diagnose_log(&read, &args).unwrap();
    assert_ne!(report.recommended.as_deref(), Some("time-delay"));
}

#[test]
fn the_mapping_of_the_docs_parses_and_is_the_one_tested_here() {
    let doc = include_str!("../docs/COLUMN_MAPPING.md");
    let blocks: Vec<&str> = doc
        .split("```toml\n")
        .skip(1)
        .map(|b| b.split("```").next().unwrap())
        .collect();
    assert!(!blocks.is_empty());
    for b in &blocks {
        tagk::dynamics::log_input::ColumnMapping::from_toml_str(b)
            .unwrap_or_else(|e| panic!("docs/COLUMN_MAPPING.md: {e}\n{b}"));
    }
    let ours = tagk::dynamics::log_input::ColumnMapping::from_toml_str(MAPPING).unwrap();
    let documented = tagk::dynamics::log_input::ColumnMapping::from_toml_str(blocks[0]).unwrap();
    assert_eq!(ours.world, documented.world);
    assert_eq!(ours.body, documented.body);
    assert_eq!(ours.quaternion_order, documented.quaternion_order);
}

#[test]
fn the_binary_reads_streams_and_keeps_streams_apart_from_logs() {
    let dir = tmpdir("binary");
    let original = without_accelerations(simulate(PlantEffects::none()));
    let map = write_foreign(&original, &dir, 0.0);
    let out = Command::new(env!("CARGO_BIN_EXE_tagk"))
        .arg("diagnose")
        .arg("--columns")
        .arg(&map)
        .args(["--vehicle", "crazyflie-2.1"])
        .arg("--stream")
        .arg(dir.join("imu.csv"))
        .arg("--stream")
        .arg(dir.join("motors.csv"))
        .arg("--stream")
        .arg(dir.join("mocap.csv"))
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(stdout.starts_with("time base: imu.csv\n"), "{stdout}");
    assert!(stdout.contains("rotor_speeds <- motors.csv"), "{stdout}");
    assert!(
        stdout.contains("derived: wrench (from rotor speeds"),
        "{stdout}"
    );
    // A positional log and --stream do not mix: streams are one flight, a log is one flight.
    let out = Command::new(env!("CARGO_BIN_EXE_tagk"))
        .arg("diagnose")
        .arg(dir.join("imu.csv"))
        .arg("--stream")
        .arg(dir.join("mocap.csv"))
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("cannot be used with"));
    // Without the mapping the streams' columns are unknown: the error says which quantity is
    // missing and what could provide it.
    let out = Command::new(env!("CARGO_BIN_EXE_tagk"))
        .arg("diagnose")
        .arg("--stream")
        .arg(dir.join("mocap.csv"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(stderr.contains("mocap.csv"), "{stderr}");
}

/// The flight the README's "Your own flight log" walks through, shipped in
/// `examples/data/foreign-flight/`: a 25 s figure-8 with rotor drag in the plant and the
/// paper's medium sensor noise, in the foreign layout of [`write_foreign`].
const SHIPPED: &str = "examples/data/foreign-flight";

fn shipped_flight() -> FlightLog {
    let config = SimConfig {
        noise: NoiseLevel::Medium,
        ..flight_config(PlantEffects::only(EffectKind::RotorDrag).unwrap())
    };
    // The accelerometer is logged (the simulator's noisy one, as specific force in `imu.csv`).
    with_accelerometer(fly(&config))
}

/// Rewrites the shipped example files (`cargo test --test foreign_log -- --ignored`).
#[test]
#[ignore = "writes the shipped example files"]
fn regenerate_the_shipped_example() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join(SHIPPED);
    std::fs::create_dir_all(&dir).unwrap();
    write_foreign(&shipped_flight(), &dir, 0.0);
}

/// The figures the README's "Your own flight log" quotes, in one place. After a change of the
/// diagnosis, run the README's commands in `examples/data/foreign-flight` (`cargo run
/// --release -- diagnose ...`), copy the lines below from what they print, and update the
/// README's text with them.
struct ReadmeFigures {
    /// Step 2's rigid-body residual RMS lines of fx and fy.
    rigid_body_rms: [&'static str; 2],
    /// Step 2's first verdict (the starting model's).
    verdict: &'static str,
    /// Step 2's staircase: its steps and the final model.
    staircase: [&'static str; 3],
    /// The rotor-drag coefficient with its 95 % interval, as the staircase prints it.
    rotor_drag: &'static str,
    /// Step 3's before/after lines of fx and fy.
    refit: [&'static str; 2],
    /// Step 2's "what remains" lines of tx and ty (held-out RMS and its ratio to the floor).
    remains: [&'static str; 2],
    /// Without the accelerometer columns (accelerations derived): the verdict, the rotor-drag
    /// candidate's status and the final model.
    derived_verdict: &'static str,
    derived_rotor_drag: &'static str,
    derived_final_model: &'static str,
}

const README_FIGURES: ReadmeFigures = ReadmeFigures {
    rigid_body_rms: [
        "fx          n/a   0.610      2.0940e-3 N",
        "fy          n/a   0.371      1.2742e-3 N",
    ],
    verdict: "verdict: missing physics: `rotor-drag` (held-out error -100 % in units of the noise)",
    staircase: [
        "0. rigid body ",
        "1. + rotor-drag ",
        "final model: rigid body + rotor-drag\n",
    ],
    rotor_drag: "rotor-drag: k_h = 9.202e-7 [9.02e-7, 9.39e-7] N s²/(m rad)",
    refit: [
        "fx                n/a          n/a         0.610      0.00704    2.0940e-3    2.4185e-5   -98.8 %",
        "fy                n/a          n/a         0.371      0.00659    1.2742e-3    2.2648e-5   -98.2 %",
    ],
    remains: [
        "tx         28.1    52.2      1.4282e-5     1.11     no",
        "ty         25.5    51.0      1.3115e-5     1.01     no",
    ],
    derived_verdict: "verdict: not adequate: fx 16.1× its noise, fy 12.0× its noise",
    derived_rotor_drag: "rotor-drag: held-out error -80.2 % (fx -87 %, fy -73 %); \
        k_h = 9.169e-7 N s²/(m rad), k_z = -2.654e-6 N s²/(m rad); \
        implausible (negative-coefficient)",
    derived_final_model: "final model: rigid body\n",
};

/// The README's step 2 in `dir` with the vehicle file `quad`.
fn readme_diagnose(dir: &Path, quad: &str, extra: &[&str]) -> String {
    let mut args = common::foreign_flight_with(quad);
    args.extend(extra);
    tagk_in(dir, &args)
}

/// The shipped files are what the generator writes today, and the README's three commands
/// work on them as the README says: the vehicle template, the diagnosis that names the drag,
/// and the refit with it.
#[test]
fn the_readme_walkthrough_runs_on_the_shipped_files() {
    let shipped = Path::new(env!("CARGO_MANIFEST_DIR")).join(SHIPPED);
    let fresh = tmpdir("shipped");
    write_foreign(&shipped_flight(), &fresh, 0.0);
    for f in ["imu.csv", "motors.csv", "mocap.csv", "map.toml"] {
        assert!(
            std::fs::read(shipped.join(f)).unwrap() == std::fs::read(fresh.join(f)).unwrap(),
            "{SHIPPED}/{f} is stale: cargo test --test foreign_log -- --ignored"
        );
    }
    let figures = &README_FIGURES;
    // 1. The vehicle: the preset as a template (here unedited).
    let quad = fresh.join("quad.toml");
    std::fs::write(
        &quad,
        tagk_in(&shipped, &["vehicle", "show", "crazyflie-2.1"]),
    )
    .unwrap();
    let quad = quad.to_str().unwrap();
    // 2. The diagnosis through the mapping. The streams are merged as the README shows (the
    // accelerometer with the motion capture's attitude gives the world acceleration), and the
    // rotor drag of the plant is found, alone, with the simulator's coefficient (Förster's
    // 9.1785e-7 kg/rad) inside its 95 % interval: the mapping recovers the physics.
    let report = readme_diagnose(&shipped, quad, &[]);
    assert!(report.starts_with("time base: imu.csv\n"), "{report}");
    assert!(
        report.contains(
            "derived: accel (world, from the accelerometer's specific force of imu.csv and the \
             attitude of mocap.csv), wrench (from rotor speeds, vehicle `crazyflie-2.1`)"
        ),
        "{report}"
    );
    for line in figures.rigid_body_rms {
        assert!(report.contains(line), "{line} not in\n{report}");
    }
    assert!(
        report.contains(figures.verdict),
        "the verdict changed: update README_FIGURES and README.md (Your own flight log)\n{report}"
    );
    let staircase = &report[report.find("=== stepwise").expect("a staircase")..];
    for line in figures.staircase {
        assert!(staircase.contains(line), "{line} not in\n{staircase}");
    }
    assert!(!staircase.contains("2. + "), "a second step:\n{staircase}");
    let rotor_drag = staircase
        .lines()
        .find(|l| l.trim_start().starts_with("rotor-drag: k_h = "))
        .unwrap_or_else(|| panic!("no rotor-drag coefficients in\n{staircase}"));
    assert!(rotor_drag.contains(figures.rotor_drag), "{rotor_drag}");
    let interval: Vec<f64> = rotor_drag
        .split(['[', ']'])
        .nth(1)
        .and_then(|i| i.split(", ").map(|v| v.parse().ok()).collect())
        .unwrap_or_else(|| panic!("no interval in {rotor_drag}"));
    assert!(
        interval[0] <= 9.1785e-7 && 9.1785e-7 <= interval[1],
        "{rotor_drag}"
    );
    let remains = &report[report.find("=== what remains").expect("what remains")..];
    for line in figures.remains {
        assert!(remains.contains(line), "{line} not in\n{remains}");
    }
    // 3. Add the drag the plant has: the lateral residual falls.
    let refit = readme_diagnose(&shipped, quad, &["--with", "rotor-drag"]);
    assert!(refit.contains("rigid body + rotor-drag"), "{refit}");
    let after = &refit[refit
        .find("=== rigid body / with")
        .expect("a before/after table")..];
    for line in figures.refit {
        assert!(after.contains(line), "{line} not in\n{after}");
    }
}

/// The same flight without the accelerometer columns: only motion capture for the translation.
///
/// The reader derives nothing. The diagnosis differentiates the 25 Hz motion capture's
/// velocity (Savitzky–Golay). That smooths `fz` enough that every drag candidate fits a
/// negative vertical coefficient and is rejected as implausible. No effect is found: the
/// honest verdict on such a log (the README says so).
#[test]
fn without_the_accelerometer_the_derived_accelerations_still_run() {
    let dir = tmpdir("derived");
    let mut log = shipped_flight();
    log.accel = None;
    write_foreign(&log, &dir, 0.0);
    let quad = dir.join("quad.toml");
    std::fs::write(&quad, tagk_in(&dir, &["vehicle", "show", "crazyflie-2.1"])).unwrap();
    let report = readme_diagnose(&dir, quad.to_str().unwrap(), &[]);
    assert!(!report.contains("derived: accel"), "{report}");
    assert!(
        report.contains("accelerations derived by Savitzky-Golay"),
        "{report}"
    );
    let figures = &README_FIGURES;
    for line in [
        figures.derived_verdict,
        figures.derived_rotor_drag,
        figures.derived_final_model,
    ] {
        assert!(
            report.contains(line),
            "changed: update README_FIGURES and README.md\n{line}\nnot in\n{report}"
        );
    }
}

/// The proof at the issue's rates.
///
/// A simulator log is recorded at its 500 Hz integration rate (`LogRate::Physics`:
/// instantaneous IMU samples, no `ω̇`). It is rewritten into files of their own: the IMU (gyro
/// and accelerometer) and the rotor speeds at 500 Hz, the motion capture at 100 Hz. Read back
/// through the mapping and the vehicle, it gives the same staircase as the original log. Its θ
/// lies within the fit's 95 % interval of the original's. The interpolation of the 100 Hz
/// motion capture is the only difference.
#[test]
fn at_500_hz_imu_and_100_hz_motion_capture_the_diagnosis_is_the_same() {
    let dir = tmpdir("rates");
    let config = SimConfig {
        duration: 10.0,
        noise: NoiseLevel::Medium,
        log_rate: tagk::sim::LogRate::Physics,
        ..flight_config(PlantEffects::only(EffectKind::RotorDrag).unwrap())
    };
    let original = fly(&config);
    assert!(
        (original.t[1] - original.t[0] - 0.002).abs() < 1e-12,
        "500 Hz"
    );
    let map = write_foreign_with(&original, &dir, 0.0, Some(5));
    let args = foreign_args(&dir, map);
    let (read, merge) = read_log(&args).unwrap();
    assert!(merge.unwrap().gaps.is_empty());
    // The read-back log spans the motion capture's first to last sample.
    let offset = original
        .t
        .iter()
        .position(|t| (t - read.t[0]).abs() < 1e-9)
        .expect("the read-back log starts on an original sample");
    let reference = trimmed(&original, offset, read.len());
    let mut plain = DiagnoseArgs::new(dir.join("unused.csv"));
    plain.quiet = true;
    let a = diagnose_log(&reference, &plain).unwrap();
    let b = diagnose_log(&read, &args).unwrap();
    assert_eq!(
        a.final_model.effects,
        b.final_model.effects,
        "{}{}",
        tagk::diagnose::streams_table(&a.streams),
        tagk::diagnose::streams_table(&b.streams)
    );
    assert!(!a.final_model.effects.is_empty(), "{}", a.stopped);
    let (ta, tb) = (
        &a.final_diagnosis().parameters,
        &b.final_diagnosis().parameters,
    );
    for (pa, pb) in ta.iter().zip(tb) {
        let Some([lo, hi]) = pa.confidence_interval else {
            continue;
        };
        assert!(
            (lo..=hi).contains(&pb.value),
            "{}: read back {} outside the original's interval [{lo}, {hi}]",
            pa.name,
            pb.value
        );
    }
}
