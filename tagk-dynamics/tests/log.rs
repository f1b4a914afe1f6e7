//! The flight-log CSV format: what the writer writes, the reader reads back bit for bit, and
//! the reader's errors name the file, line and column.

use proptest::prelude::*;
use tagk_dynamics::log::{FlightLog, GAP_FACTOR, LogError, LogSample, MIN_ROWS, Sampling};

fn finite() -> impl Strategy<Value = f64> {
    prop_oneof![-1e3..1e3f64, -1e-6..1e-6f64, Just(0.0), Just(-0.0)]
}

fn unit_quaternion() -> impl Strategy<Value = [f64; 4]> {
    (0.1..1.0f64, -1.0..1.0f64, -1.0..1.0f64, -1.0..1.0f64).prop_map(|(w, x, y, z)| {
        let n = (w * w + x * x + y * y + z * z).sqrt();
        [w / n, x / n, y / n, z / n]
    })
}

fn sample(t: f64, opt: (bool, bool, bool)) -> impl Strategy<Value = LogSample> {
    (
        prop::array::uniform3(finite()),
        prop::array::uniform3(finite()),
        unit_quaternion(),
        prop::array::uniform3(finite()),
        prop::array::uniform6(finite()),
        prop::array::uniform3(finite()),
        prop::array::uniform3(finite()),
        prop::array::uniform4(0.0..2500.0f64),
    )
        .prop_map(move |(p, v, q, w, f, a, dw, r)| LogSample {
            t,
            position: p,
            velocity: v,
            attitude: q,
            omega: w,
            wrench: f,
            accel: opt.0.then_some(a),
            omega_dot: opt.1.then_some(dw),
            rotor_speeds: opt.2.then_some(r),
        })
}

fn flight_log() -> impl Strategy<Value = FlightLog> {
    (
        MIN_ROWS..MIN_ROWS + 40,
        any::<(bool, bool, bool)>(),
        1e-4..0.1f64,
        0usize..3,
    )
        .prop_flat_map(|(n, opt, dt, n_extra)| {
            let samples: Vec<_> = (0..n).map(|i| sample(i as f64 * dt, opt)).collect();
            let extras = prop::collection::vec(prop::collection::vec(finite(), n), n_extra);
            (samples, extras)
        })
        .prop_map(|(samples, extras)| {
            let mut log = FlightLog::new();
            for s in &samples {
                log.push(s);
            }
            for (k, values) in extras.into_iter().enumerate() {
                log.add_extra(&format!("extra_{k}"), values);
            }
            log
        })
}

/// A valid log written to CSV, then damaged by a few random byte edits.
fn damaged_csv() -> impl Strategy<Value = Vec<u8>> {
    (
        flight_log(),
        prop::collection::vec((any::<prop::sample::Index>(), any::<u8>(), 0u8..3), 1..6),
    )
        .prop_map(|(log, edits)| {
            let mut csv = Vec::new();
            log.write_csv(&mut csv).unwrap();
            for (at, byte, kind) in edits {
                // A truncation may have left nothing to edit.
                if csv.is_empty() {
                    break;
                }
                let i = at.index(csv.len());
                match kind {
                    0 => csv[i] = byte,
                    1 => csv.insert(i, byte),
                    _ => {
                        csv.truncate(i);
                    }
                }
            }
            csv
        })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    /// A log cut anywhere into two slices and appended again is the log, every signal and
    /// extra column included (the glitch screen cuts and joins logs this way).
    #[test]
    fn slices_appended_give_the_log_back(log in flight_log(), cut in 0.0f64..1.0) {
        let mut log = log;
        let n = log.len();
        log.add_extra("vbat", (0..n).map(|i| 3.7 + i as f64 * 1e-3).collect());
        let k = ((n as f64) * cut) as usize;
        let mut joined = log.slice(0..k);
        joined.append(log.slice(k..n));
        prop_assert_eq!(joined, log);
    }

    #[test]
    fn write_then_read_gives_the_same_log(log in flight_log()) {
        let mut csv = Vec::new();
        log.write_csv(&mut csv).unwrap();
        let back = FlightLog::from_csv_reader(csv.as_slice()).unwrap();
        prop_assert_eq!(back, log);
    }

    /// Damaged files give a log that validates (and round-trips) or a typed error with a
    /// line: never a panic.
    #[test]
    fn damaged_files_give_a_log_or_a_typed_error(csv in damaged_csv()) {
        match FlightLog::from_csv_reader(csv.as_slice()) {
            Ok(log) => {
                let mut again = Vec::new();
                log.write_csv(&mut again).unwrap();
                prop_assert_eq!(FlightLog::from_csv_reader(again.as_slice()).unwrap(), log);
            }
            Err(e) => prop_assert!(
                e.line().is_some() || matches!(e, LogError::TooShort { .. } | LogError::EmptyFile),
                "{e}"
            ),
        }
    }

    /// Resampling a uniformly sampled log at its own step gives it back (up to rounding), and
    /// a signal linear in time is interpolated exactly at any step.
    #[test]
    fn resampling_at_the_own_step_is_the_identity(log in flight_log(), frac in 0.05..0.95f64) {
        let dt = log.t[1] - log.t[0];
        let same = log.resample_linear(dt).unwrap();
        prop_assert_eq!(same.len(), log.len());
        for (a, b) in same.t.iter().zip(&log.t) {
            prop_assert!((a - b).abs() <= 1e-9 * dt.max(b.abs()));
        }
        // px = 2 t + 1 everywhere: the resampled px at t' is 2 t' + 1 (closed form).
        let mut linear = log.clone();
        for (p, t) in linear.position.iter_mut().zip(&log.t) {
            p[0] = 2.0 * t + 1.0;
        }
        let fine = linear.resample_linear(dt * frac).unwrap();
        for (p, t) in fine.position.iter().zip(&fine.t) {
            prop_assert!((p[0] - (2.0 * t + 1.0)).abs() <= 1e-9 * (1.0 + t.abs()));
        }
        for q in &fine.attitude {
            let n = q.iter().map(|x| x * x).sum::<f64>().sqrt();
            prop_assert!((n - 1.0).abs() < 1e-9);
        }
    }
}

fn hover_log(n: usize) -> FlightLog {
    let mut log = FlightLog::new();
    for i in 0..n {
        log.push(&LogSample {
            t: 0.01 * i as f64,
            attitude: [1.0, 0.0, 0.0, 0.0],
            wrench: [0.0, 0.0, 0.34, 0.0, 0.0, 0.0],
            rotor_speeds: Some([1900.0; 4]),
            ..LogSample::default()
        });
    }
    log
}

#[test]
fn header_lists_the_required_columns_then_the_groups_present() {
    let mut csv = Vec::new();
    hover_log(3).write_csv(&mut csv).unwrap();
    let text = String::from_utf8(csv).unwrap();
    assert_eq!(
        text.lines().next().unwrap(),
        "t,px,py,pz,vx,vy,vz,qw,qx,qy,qz,wx,wy,wz,fx,fy,fz,tx,ty,tz,w1,w2,w3,w4"
    );
    assert_eq!(text.lines().nth(2).unwrap().split(',').next(), Some("0.01"));
}

#[test]
fn writer_rejects_time_that_does_not_increase() {
    let mut log = hover_log(5);
    log.t[3] = log.t[2];
    assert!(matches!(
        log.write_csv(Vec::new()),
        Err(LogError::NonIncreasingTime { line: 5, .. })
    ));
}

#[test]
fn reader_errors_name_file_line_and_column() {
    let dir = std::env::temp_dir().join(format!("tagk-log-test-{}", std::process::id()));
    let path = dir.join("bad.csv");
    let mut log = hover_log(MIN_ROWS + 5);
    log.wrench[7][2] = f64::NAN;
    // The writer only checks the shape; the reader checks every value.
    log.write_csv_path(&path).unwrap();
    let e = FlightLog::from_csv_path(&path).unwrap_err();
    assert_eq!(e.file(), Some(path.display().to_string().as_str()));
    assert_eq!(e.line(), Some(9));
    assert_eq!(e.column(), Some("fz"));
    let message = e.to_string();
    assert!(
        message.contains("bad.csv") && message.contains("line 9"),
        "{message}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `n` hover samples every 20 ms with `cut` seconds removed after `at` seconds.
fn gappy_log(n: usize, at: f64, cut: f64) -> FlightLog {
    let mut log = hover_log(n);
    for t in &mut log.t {
        *t *= 2.0;
        if *t > at {
            *t += cut;
        }
    }
    log
}

#[test]
fn sampling_reports_gaps_where_and_how_long_and_irregular_steps() {
    let log = gappy_log(500, 3.0, 4.0);
    let s = log.sampling();
    assert!((s.median_step - 0.02).abs() < 1e-12);
    assert_eq!(s.gaps.len(), 1);
    let g = s.gaps[0];
    assert_eq!(g.index, 151);
    assert!(
        (g.start - 3.0).abs() < 1e-9 && (g.duration - 4.02).abs() < 1e-9,
        "{g:?}"
    );
    assert_eq!(s.segments(), vec![0..151, 151..500]);
    assert_eq!(s.irregular_steps, 0);
    let text = s.to_string();
    assert!(
        text.contains("gap: 4.020 s long after t = 3.000 s"),
        "{text}"
    );
    // A step of 1.5 x the median is irregular, not a gap; 3 x + a bit is a gap.
    let t = [
        0.0,
        1.0,
        2.0,
        3.5,
        4.5,
        5.5,
        5.5 + GAP_FACTOR + 0.01,
        7.0 + GAP_FACTOR,
    ];
    let s = Sampling::of(&t);
    assert_eq!((s.gaps.len(), s.irregular_steps), (1, 2), "{s:?}");
    assert!(
        s.to_string().contains("irregular sampling: 2 of 7 steps"),
        "{s}"
    );
}

#[test]
fn resampling_keeps_gaps_and_rejects_bad_steps() {
    let log = gappy_log(500, 3.0, 4.0);
    let r = log.resample_linear(0.01).unwrap();
    let s = r.sampling();
    assert_eq!(s.gaps.len(), 1, "{s}");
    assert!((s.median_step - 0.01).abs() < 1e-12);
    assert!((s.gaps[0].start - 3.0).abs() < 1e-9);
    assert_eq!(r.t.first(), log.t.first());
    for dt in [0.0, -1.0, f64::NAN, f64::INFINITY, 1e-12] {
        assert!(
            matches!(
                log.resample_linear(dt),
                Err(LogError::InvalidResampleStep { .. })
            ),
            "{dt}"
        );
    }
}

#[test]
fn empty_files_and_directories_say_so() {
    let dir = std::env::temp_dir().join(format!("tagk-log-empty-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("empty.csv");
    std::fs::write(&path, "").unwrap();
    let e = FlightLog::from_csv_path(&path).unwrap_err();
    let message = e.to_string();
    assert!(
        message.contains("empty.csv") && message.contains("empty file"),
        "{message}"
    );
    let e = FlightLog::from_csv_path(&dir).unwrap_err();
    let message = e.to_string();
    assert!(
        message.contains(&dir.display().to_string()) && message.contains("is a directory"),
        "{message}"
    );
    assert!(!message.contains("line"), "{message}");
    std::fs::remove_dir_all(&dir).unwrap();
}
