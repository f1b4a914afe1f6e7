//! The reference heading: a constant yaw rate is tracked (bounded tracking error, the logged
//! attitude turns with the reference), and a zero yaw rate is the flight without headings.

use nalgebra::{Quaternion, UnitQuaternion};
use tagk_sim::*;

fn flight(trajectory: TrajectoryKind, yaw_rate: f64, seed: u64) -> SimOutput {
    let config = SimConfig {
        trajectory,
        seed,
        yaw_rate,
        payload: PayloadSchedule::None,
        adaptation: Adaptation::Nominal,
        record_log: true,
        stop_on_abort: false,
        ..SimConfig::default()
    };
    simulate(&config).expect("flight")
}

/// Heading of a logged attitude about world `+z` \[rad\], from the body `x` axis.
fn heading(q: [f64; 4]) -> f64 {
    let q = UnitQuaternion::from_quaternion(Quaternion::new(q[0], q[1], q[2], q[3]));
    let x = q * nalgebra::Vector3::x();
    x.y.atan2(x.x)
}

/// Wraps an angle to `(−π, π]`.
fn wrap(a: f64) -> f64 {
    let t = std::f64::consts::TAU;
    a - t * ((a + std::f64::consts::PI) / t).floor()
}

/// A circle flown while yawing at ±0.5 rad/s (the protocol's peak rate): the tracking error
/// stays within a few centimetres and within 2 cm of the same flight without yaw, and the
/// logged heading follows `ψ = ψ̇ t` to within 0.05 rad after the first second (about 1.6
/// turns in 20 s).
#[test]
fn a_circle_with_constant_yaw_rate_is_tracked_and_the_attitude_turns() {
    for (seed, yaw_rate) in [(1, 0.5), (2, -0.5), (3, 0.3)] {
        let still = flight(TrajectoryKind::Circle, 0.0, seed);
        let turning = flight(TrajectoryKind::Circle, yaw_rate, seed);
        let (e0, e1) = (
            still.metrics.position_error_cm,
            turning.metrics.position_error_cm,
        );
        assert!(!turning.metrics.aborted, "seed {seed}");
        assert!(
            e1 < 5.0 && e1 < e0 + 2.0,
            "seed {seed}: {e1} cm yawing vs {e0} cm"
        );
        assert!(turning.metrics.max_tracking_error_cm < 10.0);
        let mut worst: f64 = 0.0;
        for s in turning.log.samples().filter(|s| s.t > 1.0) {
            worst = worst.max(wrap(heading(s.attitude) - yaw_rate * s.t).abs());
        }
        assert!(worst < 0.05, "seed {seed}: heading error {worst} rad");
        // Without yaw the heading stays near 0.
        let still_worst = still
            .log
            .samples()
            .map(|s| heading(s.attitude).abs())
            .fold(0.0, f64::max);
        assert!(still_worst < 0.06, "{still_worst}");
    }
}

/// Yaw rate 0 is the default and flies exactly as a sample without heading.
#[test]
fn zero_yaw_rate_is_the_default_flight() {
    assert_eq!(SimConfig::default().yaw_rate, 0.0);
    let bad = SimConfig {
        yaw_rate: f64::NAN,
        ..SimConfig::default()
    };
    assert!(matches!(
        bad.validate(),
        Err(SimError::InvalidParameter {
            name: "yaw_rate",
            ..
        })
    ));
}
