//! The log input pipeline: frame rotations against hand-built ones, units, quaternion order,
//! several streams (interpolation, gaps, ranges), and the errors (file, line, column, close
//! names).

use std::f64::consts::PI;
use std::path::{Path, PathBuf};

use nalgebra::{Quaternion, Rotation3, UnitQuaternion, Vector3};
use tagk_dynamics::log_input::{
    BodyFrame, ColumnMapping, GAP_FACTOR, InputError, ReadOptions, WorldFrame, convert_attitude,
    read_streams, unit_factor,
};
use tagk_dynamics::vehicle::Vehicle;

fn tmpdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("tagk-log-input-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn write(dir: &Path, name: &str, header: &[&str], rows: &[Vec<f64>]) -> PathBuf {
    let mut text = header.join(",");
    text.push('\n');
    for r in rows {
        let cells: Vec<String> = r.iter().map(|x| format!("{x:e}")).collect();
        text.push_str(&cells.join(","));
        text.push('\n');
    }
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

fn rotate(q: [f64; 4], v: [f64; 3]) -> Vector3<f64> {
    UnitQuaternion::from_quaternion(Quaternion::new(q[0], q[1], q[2], q[3]))
        * Vector3::new(v[0], v[1], v[2])
}

#[test]
fn ned_and_frd_rotations_match_hand_built_ones() {
    let cw = WorldFrame::Ned.to_project();
    // North (NED x) is ENU y; east (NED y) is ENU x; down is −up.
    assert_eq!(
        cw * Vector3::new(1.0, 0.0, 0.0),
        Vector3::new(0.0, 1.0, 0.0)
    );
    assert_eq!(
        cw * Vector3::new(0.0, 1.0, 0.0),
        Vector3::new(1.0, 0.0, 0.0)
    );
    assert_eq!(
        cw * Vector3::new(0.0, 0.0, 1.0),
        Vector3::new(0.0, 0.0, -1.0)
    );
    assert!((cw.determinant() - 1.0).abs() < 1e-15, "a proper rotation");
    let cb = BodyFrame::Frd.to_project();
    // Body right (FRD y) is −left; body down is −up; forward stays.
    assert_eq!(
        cb * Vector3::new(0.0, 1.0, 0.0),
        Vector3::new(0.0, -1.0, 0.0)
    );
    assert_eq!(
        cb * Vector3::new(0.0, 0.0, 1.0),
        Vector3::new(0.0, 0.0, -1.0)
    );
    assert_eq!(
        cb * Vector3::new(1.0, 0.0, 0.0),
        Vector3::new(1.0, 0.0, 0.0)
    );

    // Identity in NED/FRD: nose north, right wing east. In ENU/FLU that is a yaw of +90°.
    let q = convert_attitude([1.0, 0.0, 0.0, 0.0], WorldFrame::Ned, BodyFrame::Frd);
    let s = 0.5f64.sqrt();
    for (a, b) in q.iter().zip([s, 0.0, 0.0, s]) {
        assert!((a - b).abs() < 1e-12, "{q:?}");
    }

    // Heading ψ (from north towards east) and pitch θ (nose up), built in NED/FRD as
    // yaw-pitch (z-y) about the NED axes; independently, in ENU the nose points at
    // (sin ψ cos θ, cos ψ cos θ, sin θ) and the left wing at (−cos ψ, sin ψ, 0).
    for &(psi, theta) in &[(0.3, 0.2), (2.0, -0.4), (-1.2, 0.7)] {
        let q_ned = UnitQuaternion::from_euler_angles(0.0, theta, psi);
        let q = convert_attitude(
            [q_ned.w, q_ned.i, q_ned.j, q_ned.k],
            WorldFrame::Ned,
            BodyFrame::Frd,
        );
        let nose = rotate(q, [1.0, 0.0, 0.0]);
        let left = rotate(q, [0.0, 1.0, 0.0]);
        let (sp, cp, st, ct) = (psi.sin(), psi.cos(), theta.sin(), theta.cos());
        assert!((nose - Vector3::new(sp * ct, cp * ct, st)).norm() < 1e-12);
        assert!((left - Vector3::new(-cp, sp, 0.0)).norm() < 1e-12);
    }
}

#[test]
fn units_convert_and_must_fit_the_quantity() {
    assert_eq!(unit_factor("rpm"), Some(2.0 * PI / 60.0));
    assert_eq!(unit_factor("ms"), Some(1e-3));
    assert_eq!(unit_factor("µs"), Some(1e-6));
    assert_eq!(unit_factor("deg/s"), Some(PI / 180.0));
    assert_eq!(unit_factor("mm"), Some(1e-3));
    let e = ColumnMapping::from_toml_str("[units]\nt = \"rpm\"\n").unwrap_err();
    assert!(e.contains("units.t") && e.contains("rpm"), "{e}");
    let e = ColumnMapping::from_toml_str("[units]\nomega = \"furlong\"\n").unwrap_err();
    assert!(e.contains("unknown unit `furlong`"), "{e}");
    let e = ColumnMapping::from_toml_str("[frames]\nworld = \"nwu\"\n").unwrap_err();
    assert!(e.contains("frames.world"), "{e}");
    let e = ColumnMapping::from_toml_str("[colums]\n").unwrap_err();
    assert!(e.contains("unknown table `colums`"), "{e}");
}

/// A smooth flight sampled at `t` in the project's layout: `(t, p, v, q(w,x,y,z), ω, f, τ)`.
fn project_row(t: f64) -> Vec<f64> {
    let q = UnitQuaternion::from_euler_angles(0.1 * t.sin(), 0.05 * t, 0.3 * (0.5 * t).cos());
    vec![
        t,
        (0.7 * t).sin(),
        0.2 * t,
        1.0 + 0.1 * t.cos(),
        0.7 * (0.7 * t).cos(),
        0.2,
        -0.1 * t.sin(),
        q.w,
        q.i,
        q.j,
        q.k,
        0.3 * t.sin(),
        -0.2,
        0.1 * t,
        0.01,
        -0.02,
        0.34 + 0.01 * t,
        1e-4,
        -2e-4,
        3e-5,
    ]
}

const PROJECT_HEADER: [&str; 20] = [
    "t", "px", "py", "pz", "vx", "vy", "vz", "qw", "qx", "qy", "qz", "wx", "wy", "wz", "fx", "fy",
    "fz", "tx", "ty", "tz",
];

#[test]
fn two_streams_in_a_foreign_layout_read_back_as_the_project_log() {
    let dir = tmpdir("two");
    let cw = WorldFrame::Ned.to_project(); // symmetric and its own inverse
    let cb = BodyFrame::Frd.to_project();
    // IMU at 200 Hz: time in ms, gyro in deg/s (FRD), wrench in mN / mNm (FRD).
    let imu: Vec<Vec<f64>> = (0..600)
        .map(|i| {
            let r = project_row(0.005 * i as f64);
            let w = cb * Vector3::new(r[11], r[12], r[13]) * (180.0 / PI);
            let f = cb * Vector3::new(r[14], r[15], r[16]) * 1e3;
            let tq = cb * Vector3::new(r[17], r[18], r[19]) * 1e3;
            vec![r[0] * 1e3, w.x, w.y, w.z, f.x, f.y, f.z, tq.x, tq.y, tq.z]
        })
        .collect();
    // Motion capture at 100 Hz with time in µs, position in mm, NED, quaternion xyzw, and no
    // velocity (derived), its clock 2.5 ms after the IMU's, starting later and ending earlier.
    let mocap: Vec<Vec<f64>> = (1..300)
        .map(|i| {
            let r = project_row(0.01 * i as f64 + 0.0025);
            let p = cw * Vector3::new(r[1], r[2], r[3]) * 1e3;
            let q = UnitQuaternion::from_quaternion(Quaternion::new(r[7], r[8], r[9], r[10]));
            // q_file = C_wᵀ q C_b, inverse of the conversion.
            let cwq = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(cw));
            let cbq = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(cb));
            let qf = cwq.inverse() * q * cbq;
            vec![r[0] * 1e6, p.x, p.y, p.z, qf.i, qf.j, qf.k, qf.w]
        })
        .collect();
    let imu_path = write(
        &dir,
        "imu.csv",
        &[
            "time_ms", "gx", "gy", "gz", "Fx", "Fy", "Fz", "Mx", "My", "Mz",
        ],
        &imu,
    );
    let mocap_path = write(
        &dir,
        "mocap.csv",
        &["time_us", "x", "y", "z", "q0", "q1", "q2", "q3"],
        &mocap,
    );
    let mapping = ColumnMapping::from_toml_str(
        r#"
[columns]
t = ["time_ms", "time_us"]
wx = "gx"
wy = "gy"
wz = "gz"
fx = "Fx"
fy = "Fy"
fz = "Fz"
tx = "Mx"
ty = "My"
tz = "Mz"
px = "x"
py = "y"
pz = "z"
q = ["q0", "q1", "q2", "q3"]

[units]
t = "ms"
omega = "deg/s"
force = "mN"
torque = "mNm"
position = "mm"

[frames]
world = "ned"
body = "frd"
quaternion = "xyzw"

[streams."mocap.csv"]
units = { t = "us" }
"#,
    )
    .unwrap();
    let (log, report) =
        read_streams(&[imu_path, mocap_path], &mapping, &ReadOptions::default()).unwrap();
    assert_eq!(report.primary, "imu.csv");
    // IMU samples before the first / after the last mocap sample are dropped, none in gaps.
    assert_eq!(report.dropped_in_gaps, 0);
    assert_eq!(report.dropped_outside, 3 + 1);
    assert!(report.gaps.is_empty(), "{:?}", report.gaps);
    assert!(report.derived.iter().any(|d| d.starts_with("velocity")));
    assert_eq!(log.len(), 600 - 4);
    // Interpolation error bound: linear interpolation over a step h errs by at most
    // h²/8 · max|x''|; here h = 0.01 s and |p''| ≤ 0.49 m/s², so 6.2e-6 m.
    let bound_p = 0.01f64.powi(2) / 8.0 * 0.49;
    for (i, &t) in log.t.iter().enumerate() {
        let r = project_row(t);
        for k in 0..3 {
            assert!((log.omega[i][k] - r[11 + k]).abs() < 1e-12);
            assert!((log.wrench[i][k] - r[14 + k]).abs() < 1e-12);
            assert!((log.wrench[i][3 + k] - r[17 + k]).abs() < 1e-12);
            assert!(
                (log.position[i][k] - r[1 + k]).abs() <= bound_p * 1.01 + 1e-12,
                "t {t} p{k}: {} vs {}",
                log.position[i][k],
                r[1 + k]
            );
        }
        let q = log.attitude[i];
        let dot: f64 = (0..4).map(|k| q[k] * r[7 + k]).sum();
        assert!(1.0 - dot.abs() < 1e-6, "t {t}: {q:?}");
        if i > 10 && i + 10 < log.len() {
            for k in 0..3 {
                assert!((log.velocity[i][k] - r[4 + k]).abs() < 1e-3, "t {t} v{k}");
            }
        }
    }
}

#[test]
fn samples_inside_a_gap_are_dropped_and_the_gap_reported() {
    let dir = tmpdir("gap");
    let rows = |range: std::ops::Range<usize>, dt: f64| -> Vec<Vec<f64>> {
        range.map(|i| project_row(dt * i as f64)).collect()
    };
    let mut all = rows(0..400, 0.01);
    // First stream: everything but the position.
    let no_pos: Vec<Vec<f64>> = all.iter().map(|r| [&r[..1], &r[4..]].concat()).collect();
    let header: Vec<&str> = [&PROJECT_HEADER[..1], &PROJECT_HEADER[4..]].concat();
    let primary = write(&dir, "a.csv", &header, &no_pos);
    // Second stream: position only, with a 0.2 s hole between 1.0 s and 1.2 s.
    all.retain(|r| !(r[0] > 1.0 + 1e-9 && r[0] < 1.2 - 1e-9));
    let pos: Vec<Vec<f64>> = all.iter().map(|r| r[..4].to_vec()).collect();
    let second = write(&dir, "b.csv", &["t", "px", "py", "pz"], &pos);
    let mut m = ColumnMapping::default();
    m.primary = Some("b.csv".into());
    let (log, report) = read_streams(&[primary, second], &m, &ReadOptions::default()).unwrap();
    assert_eq!(report.primary, "b.csv");
    assert_eq!(report.gaps.len(), 1);
    let g = &report.gaps[0];
    assert_eq!(g.stream, "b.csv");
    assert!(
        (g.start - 1.0).abs() < 1e-9 && (g.duration - 0.2).abs() < 1e-9,
        "{g:?}"
    );
    assert!(g.duration > GAP_FACTOR * 0.01);
    // b.csv is the time base: its samples bracket nothing in a.csv's gaps (none), so nothing
    // is dropped; now the other way round: a.csv's samples inside b.csv's gap are dropped.
    assert_eq!(report.dropped_in_gaps, 0);
    assert_eq!(log.len(), all.len());
    let mut m = ColumnMapping::default();
    m.primary = Some("a.csv".into());
    let (log, report) = read_streams(
        &[dir.join("a.csv"), dir.join("b.csv")],
        &m,
        &ReadOptions::default(),
    )
    .unwrap();
    assert_eq!(report.dropped_in_gaps, 19);
    assert_eq!(log.len(), 400 - 19);
    assert!(!log.t.iter().any(|&t| t > 1.0 + 1e-9 && t < 1.2 - 1e-9));
}

#[test]
fn errors_name_file_line_column_and_close_names() {
    let dir = tmpdir("errors");
    let mut rows: Vec<Vec<f64>> = (0..300).map(|i| project_row(0.01 * i as f64)).collect();
    // Attitude under foreign names and no mapping.
    let mut header = PROJECT_HEADER;
    header[7..11].copy_from_slice(&["quat_w", "quat_x", "quat_y", "quat_z"]);
    let foreign = write(&dir, "foreign.csv", &header, &rows);
    let e = read_streams(
        &[foreign],
        &ColumnMapping::default(),
        &ReadOptions::default(),
    )
    .unwrap_err();
    let msg = e.to_string();
    assert!(matches!(e, InputError::MissingQuantity { .. }));
    assert!(
        msg.starts_with("attitude: no columns qw,qx,qy,qz in foreign.csv; map them with [columns]"),
        "{msg}"
    );
    assert!(msg.contains("quat_w (foreign.csv)"), "{msg}");
    // No wrench, rotor speeds present, no vehicle.
    let mut header: Vec<&str> = PROJECT_HEADER[..14].to_vec();
    header.extend(["w1", "w2", "w3", "w4"]);
    let rot: Vec<Vec<f64>> = rows
        .iter()
        .enumerate()
        .map(|(i, r)| [&r[..14], &[1000.0, 1100.0, 1200.0, 1300.0 + i as f64]].concat())
        .collect();
    let rotors = write(&dir, "rotors.csv", &header, &rot);
    let msg = read_streams(
        std::slice::from_ref(&rotors),
        &ColumnMapping::default(),
        &ReadOptions::default(),
    )
    .unwrap_err()
    .to_string();
    assert!(
        msg.starts_with("wrench: no columns fx,fy,fz,tx,ty,tz"),
        "{msg}"
    );
    assert!(msg.contains("give a vehicle file"), "{msg}");
    // With a vehicle the wrench is computed from the rotor speeds.
    let vehicle = Vehicle::crazyflie_2_1();
    let options = ReadOptions {
        vehicle: Some(&vehicle),
    };
    let (log, report) = read_streams(&[rotors], &ColumnMapping::default(), &options).unwrap();
    assert!(report.derived.iter().any(|d| d.starts_with("wrench")));
    let b = vehicle.wrench_from_rotor_speeds(&log.rotor_speeds.as_ref().unwrap()[3]);
    assert_eq!(log.wrench[3][2], b.force.z);
    assert_eq!(log.wrench[3][5], b.torque.z);
    // A mapped time column that no stream has.
    let mut m = ColumnMapping::default();
    m.rename("t", "timestamp");
    let mut h = PROJECT_HEADER;
    h[0] = "time";
    let p = write(&dir, "notime.csv", &h, &rows[..10]);
    let msg = read_streams(&[p], &m, &ReadOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        msg.contains("time: no columns t (mapped to timestamp) in ")
            && msg.contains("notime.csv; map them with [columns]")
            && msg.ends_with("columns that could provide it: time"),
        "{msg}"
    );
    // A bad cell: file, line, column.
    rows[4][2] = f64::NAN;
    let bad = write(&dir, "bad.csv", &PROJECT_HEADER, &rows);
    let e = read_streams(&[bad], &ColumnMapping::default(), &ReadOptions::default()).unwrap_err();
    let msg = e.to_string();
    assert!(
        msg.contains("bad.csv") && msg.contains("line 6") && msg.contains("`py`"),
        "{msg}"
    );
    assert!(matches!(
        read_streams(&[], &m, &ReadOptions::default()),
        Err(InputError::NoStream)
    ));
}

/// The project's gravity `g_w` \[m/s²\] (z up), written out here so the test does not lean on
/// the constant it checks.
const G: f64 = 9.81;

/// The accelerometer of a vehicle in NED/FRD at `t`: its attitude (NED ← FRD) and its world
/// acceleration in NED \[m/s²\], and the specific force an ideal accelerometer reads, computed in
/// NED/FRD throughout (gravity `(0, 0, +g)` in NED): `f = R_nedᵀ (p̈_ned − g_ned)`.
fn ned_accelerometer(t: f64) -> (UnitQuaternion<f64>, Vector3<f64>, Vector3<f64>) {
    let r_ned = UnitQuaternion::from_euler_angles(0.4 * t.sin(), -0.3 * t.cos(), 1.2 * t);
    let a_ned = Vector3::new(0.8 * (1.3 * t).sin(), -0.5 * t.cos(), 0.2 * (0.7 * t).sin());
    let f_frd = r_ned.inverse() * (a_ned - Vector3::new(0.0, 0.0, G));
    (r_ned, a_ned, f_frd)
}

#[test]
fn the_accelerometer_in_frd_and_g_becomes_the_world_acceleration() {
    let dir = tmpdir("imu");
    let g_unit = unit_factor("g").unwrap();
    assert_eq!(g_unit, 9.80665, "the standard gravity");
    // IMU at 100 Hz: gyro (FRD, rad/s), accelerometer (FRD, in g), wrench (project frames).
    let n = 300;
    let imu: Vec<Vec<f64>> = (0..n)
        .map(|i| {
            let t = 0.01 * i as f64;
            let r = project_row(t);
            let (_, _, f) = ned_accelerometer(t);
            let f = f / g_unit;
            [
                vec![t * 1e3],
                r[11..14].to_vec(),
                vec![f.x, f.y, f.z],
                r[14..20].to_vec(),
            ]
            .concat()
        })
        .collect();
    // Motion capture on the same clock (time in µs, one sample more at each end so no IMU
    // sample falls outside its range): position, attitude xyzw (NED/FRD).
    let mocap: Vec<Vec<f64>> = (-1..=n as i32)
        .map(|i| {
            let t = 0.01 * f64::from(i);
            let r = project_row(t);
            let (q, _, _) = ned_accelerometer(t);
            vec![
                t * 1e6,
                r[1],
                r[2],
                r[3],
                r[4],
                r[5],
                r[6],
                q.i,
                q.j,
                q.k,
                q.w,
            ]
        })
        .collect();
    let imu_header = [
        "time_ms", "wx", "wy", "wz", "acc_x", "acc_y", "acc_z", "fx", "fy", "fz", "tx", "ty", "tz",
    ];
    let imu_path = write(&dir, "imu.csv", &imu_header, &imu);
    let mocap_path = write(
        &dir,
        "mocap.csv",
        &[
            "time_us", "px", "py", "pz", "vx", "vy", "vz", "qx", "qy", "qz", "qw",
        ],
        &mocap,
    );
    let map = r#"
[columns]
t = ["time_ms", "time_us"]
sfx = "acc_x"
sfy = "acc_y"
sfz = "acc_z"
q = ["qx", "qy", "qz", "qw"]

[units]
t = "ms"
specific_force = "g"

[frames]
world = "ned"
body = "frd"
quaternion = "xyzw"

[streams."mocap.csv"]
units = { t = "us" }
"#;
    let mapping = ColumnMapping::from_toml_str(map).unwrap();
    // (The wrench and the gyro are in FRD here too: the test looks at the acceleration only.)
    let (log, report) = read_streams(
        &[imu_path.clone(), mocap_path.clone()],
        &mapping,
        &ReadOptions::default(),
    )
    .unwrap();
    assert_eq!(log.len(), n);
    assert!(
        report
            .sources
            .contains(&("specific_force".into(), "imu.csv".into())),
        "{:?}",
        report.sources
    );
    assert!(
        report.derived.iter().any(|d| d
            == "accel (world, from the accelerometer's specific force of imu.csv and the \
                attitude of mocap.csv)"),
        "{:?}",
        report.derived
    );
    let accel = log.accel.as_ref().expect("the accelerometer gives p̈");
    for (i, &t) in log.t.iter().enumerate() {
        let (_, a_ned, f_frd) = ned_accelerometer(t);
        // NED → ENU by hand: x ← east, y ← north, z ← −down.
        let expected = [a_ned.y, a_ned.x, -a_ned.z];
        for k in 0..3 {
            assert!(
                (accel[i][k] - expected[k]).abs() < 1e-9,
                "t {t} a{k}: {} vs {}",
                accel[i][k],
                expected[k]
            );
        }
        // The regressor's a = Rᵀ (p̈ − g_w) is the accelerometer's reading in FLU.
        let q = log.attitude[i];
        let q = UnitQuaternion::from_quaternion(Quaternion::new(q[0], q[1], q[2], q[3]));
        let a = tagk_dynamics::proper_acceleration(&q, &Vector3::from(accel[i]));
        let f_flu = Vector3::new(f_frd.x, -f_frd.y, -f_frd.z);
        assert!((a - f_flu).norm() < 1e-9, "t {t}: {a} vs {f_flu}");
    }

    // Hand-built: level, nose north, at rest in NED/FRD (attitude the identity there), the
    // accelerometer reads −g on body z (m/s², so no unit rounding): p̈ = 0. Nose east, rolled
    // 90° right (right side down: body y along world down), it reads −g on body y.
    let level = ColumnMapping::from_toml_str(
        "[frames]\nworld = \"ned\"\nbody = \"frd\"\nquaternion = \"xyzw\"\n",
    )
    .unwrap();
    let rolled = UnitQuaternion::from_euler_angles(PI / 2.0, 0.0, PI / 2.0);
    for (q_ned, reading) in [
        (UnitQuaternion::identity(), [0.0, 0.0, -G]),
        (rolled, [0.0, -G, 0.0]),
    ] {
        // Check the hand-built reading against the attitude: body y is world down.
        if reading[1] != 0.0 {
            let y_world = q_ned * Vector3::new(0.0, 1.0, 0.0);
            assert!((y_world - Vector3::new(0.0, 0.0, 1.0)).norm() < 1e-12);
        }
        let rows: Vec<Vec<f64>> = (0..250)
            .map(|i| {
                let r = project_row(0.01 * i as f64);
                [
                    vec![r[0]],
                    r[1..7].to_vec(),
                    vec![q_ned.i, q_ned.j, q_ned.k, q_ned.w],
                    r[11..20].to_vec(),
                    reading.to_vec(),
                ]
                .concat()
            })
            .collect();
        let mut header = PROJECT_HEADER.to_vec();
        header[7..11].copy_from_slice(&["qx", "qy", "qz", "qw"]);
        header.extend(["sfx", "sfy", "sfz"]);
        let p = write(&dir, "still.csv", &header, &rows);
        let mut m = level.clone();
        m.set_unit("specific_force", "m/s2").unwrap();
        let (log, _) = read_streams(&[p], &m, &ReadOptions::default()).unwrap();
        for a in log.accel.as_ref().unwrap() {
            assert!(Vector3::from(*a).norm() < 1e-12, "{a:?}");
        }
    }

    // A stream with the world acceleration `ax..az` wins over the accelerometer.
    let mut rows = imu.clone();
    for r in &mut rows {
        r.extend([0.1, 0.2, 0.3]);
    }
    let mut header = imu_header.to_vec();
    header.extend(["ax", "ay", "az"]);
    let both = write(&dir, "both.csv", &header, &rows);
    let (log, report) = read_streams(
        &[both, mocap_path.clone()],
        &mapping,
        &ReadOptions::default(),
    )
    .unwrap();
    // NED → ENU of (0.1, 0.2, 0.3).
    assert_eq!(log.accel.as_ref().unwrap()[7], [0.2, 0.1, -0.3]);
    assert!(!report.derived.iter().any(|d| d.starts_with("accel")));
    assert!(!report.sources.iter().any(|(q, _)| q == "specific_force"));

    // Errors: a unit that is not an acceleration; a bad accelerometer cell (file, line,
    // column).
    let e = ColumnMapping::from_toml_str("[units]\nspecific_force = \"deg/s\"\n").unwrap_err();
    assert!(
        e.contains("units.specific_force") && e.contains("Acceleration"),
        "{e}"
    );
    let e = ColumnMapping::from_toml_str("[units]\nsfz = \"N\"\n").unwrap_err();
    assert!(e.contains("units.sfz"), "{e}");
    let text = std::fs::read_to_string(&imu_path).unwrap();
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    let mut cells: Vec<&str> = lines[5].split(',').collect();
    cells[5] = "n/a";
    lines[5] = cells.join(",");
    std::fs::write(&imu_path, lines.join("\n")).unwrap();
    let msg = read_streams(&[imu_path, mocap_path], &mapping, &ReadOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        msg.contains("imu.csv") && msg.contains("line 6") && msg.contains("`acc_y`"),
        "{msg}"
    );
}
