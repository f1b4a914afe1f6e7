//! The flight-log CSV format: what the writer writes, the reader reads back bit for bit, and
//! the reader's errors name the file, line and column.

use proptest::prelude::*;
use tagk_dynamics::log::{FlightLog, LogError, LogSample, MIN_ROWS};

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

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    #[test]
    fn write_then_read_gives_the_same_log(log in flight_log()) {
        let mut csv = Vec::new();
        log.write_csv(&mut csv).unwrap();
        let back = FlightLog::from_csv_reader(csv.as_slice()).unwrap();
        prop_assert_eq!(back, log);
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
