//! Issue #25, strict mappings and streams: each mistake a user makes with a valid log — a
//! mapped column no stream has, a typo in a key, a `[streams."…"]` table naming no file, a
//! stream file outside the mapping's folder, eRPM, a quaternion of norm 1.013, text in an
//! unmapped column, the world-frame specific force read as `p̈`, a stream too slow, too short,
//! late or from another flight — is a typed error or a warning naming the cause.

use std::path::{Path, PathBuf};

use nalgebra::UnitQuaternion;
use tagk_dynamics::log::{FlightLog, LogError};
use tagk_dynamics::log_input::{
    ColumnMapping, InputError, MergeReport, QUATERNION_RENORMALISE_LIMIT, ReadOptions, read_streams,
};

fn tmpdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("tagk-strict-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Writes a CSV of `header` and text cells.
fn write_text(dir: &Path, name: &str, header: &[&str], rows: &[Vec<String>]) -> PathBuf {
    let mut text = header.join(",");
    text.push('\n');
    for r in rows {
        text.push_str(&r.join(","));
        text.push('\n');
    }
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

fn write(dir: &Path, name: &str, header: &[&str], rows: &[Vec<f64>]) -> PathBuf {
    let rows: Vec<Vec<String>> = rows
        .iter()
        .map(|r| r.iter().map(|x| format!("{x:e}")).collect())
        .collect();
    write_text(dir, name, header, &rows)
}

/// A smooth flight at `t`: `(t, p, v, q(w,x,y,z), ω, f, τ)`; its world acceleration is
/// [`accel`].
fn row(t: f64) -> Vec<f64> {
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

/// The world acceleration `p̈` of [`row`] at `t` \[m/s²\].
fn accel(t: f64) -> [f64; 3] {
    [-0.49 * (0.7 * t).sin(), 0.0, -0.1 * t.cos()]
}

const HEADER: [&str; 20] = [
    "t", "px", "py", "pz", "vx", "vy", "vz", "qw", "qx", "qy", "qz", "wx", "wy", "wz", "fx", "fy",
    "fz", "tx", "ty", "tz",
];

/// 1000 samples at 100 Hz.
fn rows() -> Vec<Vec<f64>> {
    (0..1000).map(|i| row(0.01 * i as f64)).collect()
}

fn read(paths: &[PathBuf], toml: &str) -> Result<(FlightLog, MergeReport), InputError> {
    let m = ColumnMapping::from_toml_str(toml).unwrap();
    read_streams(paths, &m, &ReadOptions::default())
}

/// The log with `ax, ay, az` = its world acceleration plus `extra_z` on z.
fn with_accel(dir: &Path, extra_z: f64) -> PathBuf {
    let mut header = HEADER.to_vec();
    header.extend(["ax", "ay", "az"]);
    let r: Vec<Vec<f64>> = rows()
        .into_iter()
        .map(|mut r| {
            let a = accel(r[0]);
            r.extend([a[0], a[1], a[2] + extra_z]);
            r
        })
        .collect();
    write(dir, "log.csv", &header, &r)
}

#[test]
fn a_mapped_column_no_stream_has_is_an_error_naming_the_key_and_the_nearest_header() {
    let dir = tmpdir("absent");
    let log = with_accel(&dir, 0.0);
    let e = read(
        std::slice::from_ref(&log),
        "[columns]\nax = \"no_such_column\"\n",
    )
    .unwrap_err();
    let msg = e.to_string();
    assert!(
        matches!(&e, InputError::AbsentColumn { key, .. } if key == "columns.ax"),
        "{e:?}"
    );
    assert!(
        msg.starts_with(
            "columns.ax = \"no_such_column\": no stream has this column (log.csv: t, px"
        ),
        "{msg}"
    );
    assert!(
        msg.ends_with("nearest header name: `ax` (log.csv)"),
        "{msg}"
    );
    // A list of candidates is fine when one stream has one of them, and with two streams a
    // key may be in one only.
    let (a, _) = read(
        std::slice::from_ref(&log),
        "[columns]\nax = [\"acc_x\", \"ax\"]\n",
    )
    .unwrap();
    assert!(a.accel.is_some());
    let r = rows();
    let gyro: Vec<Vec<f64>> = r.iter().map(|x| vec![x[0], x[11], x[12], x[13]]).collect();
    let rest: Vec<Vec<f64>> = r.iter().map(|x| [&x[..11], &x[14..]].concat()).collect();
    let mut rest_header = HEADER[..11].to_vec();
    rest_header.extend(&HEADER[14..]);
    let a = write(&dir, "a.csv", &rest_header, &rest);
    let b = write(&dir, "b.csv", &["t", "gx", "gy", "gz"], &gyro);
    let (merged, _) = read(
        &[a.clone(), b.clone()],
        "[columns]\nwx = \"gx\"\nwy = \"gy\"\nwz = \"gz\"\n",
    )
    .unwrap();
    assert_eq!(merged.omega[5], [r[5][11], r[5][12], r[5][13]]);
    let e = read(
        &[a, b],
        "[columns]\nwx = \"gx\"\nwy = \"gy\"\nwz = \"g_z\"\n",
    )
    .unwrap_err();
    assert!(
        e.to_string()
            .contains("columns.wz = \"g_z\": no stream has this column")
            && e.to_string().contains("nearest header name: `gz` (b.csv)"),
        "{e}"
    );
}

#[test]
fn a_typo_in_a_key_is_an_error_with_the_nearest_key() {
    let cases = [
        (
            "[units]\nomgea = \"deg/s\"\n",
            "units.omgea: unknown key `omgea`; did you mean `omega`?",
        ),
        (
            "[frames]\nwrold = \"ned\"\n",
            "frames: unknown key `wrold`; did you mean `world`?",
        ),
        (
            "[frames]\nacel = \"specific-force\"\n",
            "did you mean `accel`?",
        ),
        (
            "[columns]\npxx = \"x\"\n",
            "columns.pxx: unknown project column `pxx`; did you mean `px`?",
        ),
        (
            "[columns]\nomega = \"gyro\"\n",
            "columns.omega: columns are mapped one by one (wx, wy, wz)",
        ),
        (
            "[unit]\nt = \"ms\"\n",
            "unknown table `unit`; did you mean `units`?",
        ),
        (
            "[streams.\"a.csv\"]\nofset = 0.1\n",
            "streams.\"a.csv\": unknown key `ofset`; did you mean `offset`?",
        ),
        ("[columns]\nax = \"\"\n", "columns.ax: an empty column name"),
    ];
    for (toml, expected) in cases {
        let e = ColumnMapping::from_toml_str(toml).unwrap_err();
        assert!(e.contains(expected), "{toml}: {e}");
    }
    // An extra column's unit must name a column.
    let dir = tmpdir("unitkey");
    let log = write(&dir, "log.csv", &HEADER, &rows());
    let e = read(std::slice::from_ref(&log), "[units]\nvbat = \"deg\"\n").unwrap_err();
    assert!(
        matches!(&e, InputError::AbsentColumn { key, .. } if key == "units.vbat"),
        "{e:?}"
    );
}

#[test]
fn a_streams_table_naming_no_stream_file_is_an_error_with_the_nearest_name() {
    let dir = tmpdir("streamname");
    let log = write(&dir, "imu.csv", &HEADER, &rows());
    let e = read(
        std::slice::from_ref(&log),
        "[streams.\"imu.cvs\"]\nunits = { t = \"ms\" }\n",
    )
    .unwrap_err();
    assert!(
        matches!(&e, InputError::UnknownStream { name, .. } if name == "imu.cvs"),
        "{e:?}"
    );
    assert_eq!(
        e.to_string(),
        "streams.\"imu.cvs\": no stream file is named `imu.cvs` (the streams: imu.csv); did you \
         mean `imu.csv`?"
    );
    let e = read(std::slice::from_ref(&log), "[streams]\nprimary = \"imu\"\n").unwrap_err();
    assert!(
        e.to_string().starts_with("streams.primary: no stream file"),
        "{e}"
    );
}

#[test]
fn stream_files_outside_the_mapping_folder_are_refused() {
    for bad in ["../imu.csv", "sub/../../imu.csv", "/etc/imu.csv"] {
        let e =
            ColumnMapping::from_toml_str(&format!("[streams]\nfiles = [\"{bad}\"]\n")).unwrap_err();
        assert!(
            e.starts_with(&format!(
                "streams.files: `{bad}` is outside the mapping file's folder"
            )),
            "{e}"
        );
    }
    let dir = tmpdir("confined");
    std::fs::write(
        dir.join("map.toml"),
        "[streams]\nfiles = [\"sub/../imu.csv\", \"logs/a.csv\"]\n",
    )
    .unwrap();
    let m = ColumnMapping::from_path(dir.join("map.toml")).unwrap();
    assert_eq!(
        m.files,
        [dir.join("sub/../imu.csv"), dir.join("logs/a.csv")]
    );
    std::fs::write(dir.join("bad.toml"), "[streams]\nfiles = [\"../x.csv\"]\n").unwrap();
    let e = ColumnMapping::from_path(dir.join("bad.toml")).unwrap_err();
    assert!(matches!(e, InputError::Mapping { .. }));
    assert!(
        e.to_string()
            .contains("bad.toml: streams.files: `../x.csv`"),
        "{e}"
    );
}

#[test]
fn erpm_with_pole_pairs_and_a_scale_factor_give_rad_per_s() {
    let dir = tmpdir("erpm");
    let mut header = HEADER.to_vec();
    header.extend(["m1", "m2", "m3", "m4"]);
    let speeds = [1500.0, 1600.0, 1700.0, 1800.0]; // rad/s
    let erpm = 30.0 / std::f64::consts::PI * 7.0;
    let r: Vec<Vec<f64>> = rows()
        .into_iter()
        .map(|mut r| {
            r.extend(speeds.map(|w| w * erpm));
            r
        })
        .collect();
    let log = write(&dir, "log.csv", &header, &r);
    let columns = "[columns]\nw1 = \"m1\"\nw2 = \"m2\"\nw3 = \"m3\"\nw4 = \"m4\"\n";
    let (l, _) = read(
        std::slice::from_ref(&log),
        &format!("{columns}[units]\nrotor_speeds = {{ unit = \"erpm\", pole_pairs = 7 }}\n"),
    )
    .unwrap();
    for (k, w) in speeds.iter().enumerate() {
        assert!((l.rotor_speeds.as_ref().unwrap()[9][k] - w).abs() < 1e-9);
    }
    // A number is the factor to SI.
    let (l, _) = read(
        std::slice::from_ref(&log),
        &format!("{columns}[units]\nrotor_speeds = {}\n", 1.0 / erpm),
    )
    .unwrap();
    assert!((l.rotor_speeds.as_ref().unwrap()[9][0] - speeds[0]).abs() < 1e-9);
    let e = ColumnMapping::from_toml_str("[units]\nrotor_speeds = \"erpm\"\n").unwrap_err();
    assert!(e.contains("needs the motors' pole pairs"), "{e}");
    let e = ColumnMapping::from_toml_str("[units]\nrotor_speeds = -2\n").unwrap_err();
    assert!(e.contains("positive finite number"), "{e}");
    let e = ColumnMapping::from_toml_str("[units]\nt = { unit = \"erpm\", pole_pairs = 7 }\n")
        .unwrap_err();
    assert!(e.contains("does not fit"), "{e}");
}

#[test]
fn unmapped_columns_are_not_parsed_and_used_ones_still_are() {
    let dir = tmpdir("unmapped");
    let mut header = HEADER.to_vec();
    header.extend(["status", "body_poses", "note", "vbat"]);
    let text_rows: Vec<Vec<String>> = rows()
        .iter()
        .enumerate()
        .map(|(i, r)| {
            let mut cells: Vec<String> = r.iter().map(|x| format!("{x:e}")).collect();
            cells.push(if i % 2 == 0 { "True" } else { "False" }.into());
            cells.push(String::new());
            cells.push("ok".into());
            cells.push(format!("{}", 4.0 - 1e-4 * i as f64));
            cells
        })
        .collect();
    let log = write_text(&dir, "log.csv", &header, &text_rows);
    let (l, report) = read(std::slice::from_ref(&log), "").unwrap();
    assert_eq!(l.extra.len(), 1);
    assert_eq!(l.extra[0].0, "vbat");
    let unread: Vec<(&str, usize, &str)> = report
        .unread_columns
        .iter()
        .map(|u| (u.column.as_str(), u.line, u.value.as_str()))
        .collect();
    assert_eq!(
        unread,
        [
            ("status", 2, "True"),
            ("body_poses", 2, ""),
            ("note", 2, "ok")
        ]
    );
    assert!(
        report
            .text()
            .contains("not read (unmapped, not numeric): status (log.csv, line 2: `True`)"),
        "{}",
        report.text()
    );
    // A renamed extra column is offered under its new name.
    let (l, _) = read(std::slice::from_ref(&log), "[columns]\nv_bat = \"vbat\"\n").unwrap();
    assert_eq!(l.extra[0].0, "v_bat");
    // A bad cell in a used column is still an error with file, line and column.
    let mut bad = text_rows.clone();
    bad[4][2] = "abc".into();
    let p = write_text(&dir, "bad.csv", &header, &bad);
    let e = read(&[p], "").unwrap_err();
    assert!(
        matches!(&e, InputError::Log(le) if le.line() == Some(6) && le.column() == Some("py")),
        "{e:?}"
    );
}

#[test]
fn a_quaternion_of_norm_1_013_is_refused_or_renormalised_on_request() {
    let dir = tmpdir("qnorm");
    let r: Vec<Vec<f64>> = rows()
        .into_iter()
        .map(|mut r| {
            r[7..11].iter_mut().for_each(|x| *x *= 1.013);
            r
        })
        .collect();
    let log = write(&dir, "log.csv", &HEADER, &r);
    let e = read(std::slice::from_ref(&log), "").unwrap_err();
    assert!(
        matches!(&e, InputError::Log(LogError::InFile { source, .. })
            if matches!(**source, LogError::QuaternionNorm { .. })),
        "{e:?}"
    );
    assert!(
        e.to_string()
            .contains("`[frames] normalize_quaternion = true`"),
        "{e}"
    );
    let (l, report) = read(
        std::slice::from_ref(&log),
        "[frames]\nnormalize_quaternion = true\n",
    )
    .unwrap();
    let dev = report.quaternion_renormalised.unwrap();
    assert!((dev - 0.013).abs() < 1e-9, "{dev}");
    let q = l.attitude[3];
    assert!((q.iter().map(|x| x * x).sum::<f64>().sqrt() - 1.0).abs() < 1e-12);
    assert!(
        report
            .warnings
            .iter()
            .any(|w| w.contains("divided by their norm")
                && w.contains("largest |‖q‖ − 1| was 0.0130")),
        "{:?}",
        report.warnings
    );
    // Far from 1: not a quaternion, even with the option.
    let r: Vec<Vec<f64>> = rows()
        .into_iter()
        .map(|mut r| {
            r[7..11]
                .iter_mut()
                .for_each(|x| *x *= 1.0 + 2.0 * QUATERNION_RENORMALISE_LIMIT);
            r
        })
        .collect();
    let far = write(&dir, "far.csv", &HEADER, &r);
    let e = read(&[far], "[frames]\nnormalize_quaternion = true\n").unwrap_err();
    assert!(
        matches!(e, InputError::QuaternionFarFromUnit { line: 2, .. }),
        "{e:?}"
    );
}

#[test]
fn the_world_frame_specific_force_is_refused_as_acceleration_and_read_when_said() {
    let dir = tmpdir("specific");
    let g = 9.81;
    let log = with_accel(&dir, g);
    let e = read(std::slice::from_ref(&log), "").unwrap_err();
    assert!(
        matches!(&e, InputError::AccelLooksLikeSpecificForce { mean_z, .. } if (mean_z - g).abs() < 0.1),
        "{e:?}"
    );
    let msg = e.to_string();
    assert!(
        msg.contains("most likely the world-frame specific force")
            && msg.contains("`[frames] accel = \"specific-force\"`"),
        "{msg}"
    );
    let (l, report) = read(
        std::slice::from_ref(&log),
        "[frames]\naccel = \"specific-force\"\n",
    )
    .unwrap();
    for (i, &t) in l.t.iter().enumerate() {
        let a = accel(t);
        for (read, exact) in l.accel.as_ref().unwrap()[i].iter().zip(a) {
            assert!((read - exact).abs() < 1e-12);
        }
    }
    assert!(
        report
            .derived
            .iter()
            .any(|d| d.contains("world-frame specific force"))
    );
    // Said explicitly, `acceleration` reads p̈ as it is.
    let plain = tmpdir("specific-plain");
    let (l, _) = read(
        std::slice::from_ref(&with_accel(&plain, 0.0)),
        "[frames]\naccel = \"acceleration\"\n",
    )
    .unwrap();
    assert!((l.accel.as_ref().unwrap()[0][2] - accel(0.0)[2]).abs() < 1e-12);
    // The columns left out: the acceleration is then derived by the diagnosis.
    let (l, _) = read(
        std::slice::from_ref(&log),
        "[columns]\nignore = [\"ax\", \"ay\", \"az\"]\n",
    )
    .unwrap();
    assert!(l.accel.is_none());
    assert!(l.extra.is_empty());
}

/// `a.csv` (100 Hz, 10 s: all but the wrench) and `w.csv` (the wrench) from `wrench_rows`.
fn two_streams(dir: &Path, wrench_rows: &[Vec<f64>]) -> Vec<PathBuf> {
    let r = rows();
    let a: Vec<Vec<f64>> = r.iter().map(|x| x[..14].to_vec()).collect();
    let mut wh = vec!["t"];
    wh.extend(&HEADER[14..]);
    vec![
        write(dir, "a.csv", &HEADER[..14], &a),
        write(dir, "w.csv", &wh, wrench_rows),
    ]
}

fn wrench_at(t: f64, clock: f64) -> Vec<f64> {
    let r = row(t);
    [&[t + clock], &r[14..]].concat()
}

#[test]
fn a_wrench_stream_at_1_hz_or_of_2_rows_is_refused() {
    let dir = tmpdir("sparse");
    let slow: Vec<Vec<f64>> = (0..11).map(|i| wrench_at(i as f64, 0.0)).collect();
    let e = read(&two_streams(&dir, &slow), "").unwrap_err();
    assert!(
        matches!(&e, InputError::StreamTooSparse { stream, samples: 11, .. } if stream == "w.csv"),
        "{e:?}"
    );
    assert!(
        e.to_string().starts_with(
            "w.csv: 11 samples at a median step of 1.000 s (1.00 Hz) cannot support the fit of \
         force, torque"
        ),
        "{e}"
    );
    let two: Vec<Vec<f64>> = vec![wrench_at(0.0, 0.0), wrench_at(9.99, 0.0)];
    let e = read(&two_streams(&dir, &two), "").unwrap_err();
    assert!(
        matches!(&e, InputError::StreamTooSparse { samples: 2, .. }),
        "{e:?}"
    );
}

/// Found by the `column_mapping` fuzz target: a stream with a header and no row indexed its
/// first time stamp.
#[test]
fn a_stream_without_rows_is_a_typed_error_not_a_panic() {
    let dir = tmpdir("empty");
    // The wrench stream has its header only: it provides the wrench with no sample.
    let e = read(&two_streams(&dir, &[]), "").unwrap_err();
    assert!(
        matches!(&e, InputError::StreamTooSparse { stream, samples: 0, .. } if stream == "w.csv"),
        "{e:?}"
    );
    // The primary stream (the time base) has its header only.
    let paths = two_streams(
        &dir,
        &rows()
            .iter()
            .map(|r| wrench_at(r[0], 0.0))
            .collect::<Vec<_>>(),
    );
    write(&dir, "a.csv", &HEADER[..14], &[]);
    let e = read(&paths, "").unwrap_err();
    assert!(
        matches!(&e, InputError::Log(LogError::InFile { path, source })
            if path == "a.csv" && matches!(**source, LogError::TooShort { rows: 0, .. })),
        "{e:?}"
    );
}

#[test]
fn a_stream_of_another_flight_is_refused_and_a_late_one_warned_about() {
    let dir = tmpdir("late");
    let other: Vec<Vec<f64>> = (0..1000)
        .map(|i| wrench_at(0.01 * i as f64, 120.0))
        .collect();
    let e = read(&two_streams(&dir, &other), "").unwrap_err();
    assert!(
        matches!(&e, InputError::StreamOverlap { stream, percent, .. } if stream == "w.csv" && *percent == 0.0),
        "{e:?}"
    );
    assert!(e.to_string().contains("a stream of another flight"), "{e}");
    // 2 s late: 20 % of the time base dropped, a warning naming the stream.
    let late: Vec<Vec<f64>> = (0..1000).map(|i| wrench_at(0.01 * i as f64, 2.0)).collect();
    let paths = two_streams(&dir, &late);
    let (l, report) = read(&paths, "").unwrap();
    assert_eq!(l.len(), 800);
    let w = &report.streams[1];
    assert_eq!((w.stream.as_str(), w.dropped), ("w.csv", 200));
    assert!((w.overlap_fraction - 7.99 / 9.99).abs() < 1e-9);
    assert!((w.rate - 100.0).abs() < 1e-6);
    assert_eq!(report.warnings.len(), 1, "{:?}", report.warnings);
    assert!(
        report.warnings[0]
            .starts_with("200 of the time base's 1000 samples (20 %) dropped because of w.csv"),
        "{}",
        report.warnings[0]
    );
    assert!(report.text().contains("\nwarning: 200 of the time base's"));
    assert!(
        report.text().contains(
            "stream w.csv: 100.0 Hz, 1000 samples, t = 2.000 to 11.990 s, offset 0 s, overlap 80 % \
         of the time base, 200 samples dropped"
        ),
        "{}",
        report.text()
    );
    // The offset said: nothing dropped, no warning.
    let (l, report) = read(&paths, "[streams.\"w.csv\"]\noffset = -2.0\n").unwrap();
    assert_eq!(l.len(), 1000);
    assert!(report.warnings.is_empty());
    assert_eq!(report.streams[1].offset, -2.0);
    // The report serialises (it travels in the diagnosis report's JSON).
    let json = serde_json::to_value(&report).unwrap();
    assert_eq!(json["streams"][1]["stream"], "w.csv");
    assert_eq!(json["streams"][1]["offset"], -2.0);
}
