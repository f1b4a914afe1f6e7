//! The physics-rate log (`LogRate::Physics`): one IMU-style sample per RK4 step, the same
//! flight as a control-rate log, the control-rate samples among its samples, the stated noise.

use nalgebra::{Quaternion, UnitQuaternion, Vector3};
use tagk_sim::plant_effects::TimeDelay;
use tagk_sim::*;

fn config(seed: u64, noise: NoiseLevel, sensing: Sensing, log_rate: LogRate) -> SimConfig {
    SimConfig {
        seed,
        sensing,
        log_rate,
        noise,
        payload: PayloadSchedule::None,
        adaptation: Adaptation::Nominal,
        record_log: true,
        ..SimConfig::default()
    }
}

/// Ten samples per control interval, 2 ms apart; the flight is the control-rate one (same
/// tracking errors, even with every sensor noisy); with ideal sensing the 5th sample of each
/// interval (its midpoint) carries the control-rate sample's state, gyro, accelerometer,
/// rotor speeds and wrench bit for bit; no `ω̇` columns.
#[test]
fn physics_rate_log_holds_the_control_rate_samples() {
    for (noise, sensing) in [
        (NoiseLevel::None, Sensing::ideal()),
        (NoiseLevel::Medium, Sensing::realistic()),
    ] {
        let control = simulate(&config(4, noise, sensing, LogRate::Control)).unwrap();
        let physics = simulate(&config(4, noise, sensing, LogRate::Physics)).unwrap();
        assert_eq!(control.tracking_errors, physics.tracking_errors);
        assert_eq!(physics.log.len(), 10 * control.log.len());
        assert!(physics.log.omega_dot.is_none() && control.log.omega_dot.is_some());
        for w in physics.log.t.windows(2) {
            assert!((w[1] - w[0] - 0.002).abs() < 1e-12);
        }
        physics.log.validate().unwrap();
        if sensing != Sensing::ideal() {
            continue;
        }
        for (k, c) in control.log.samples().enumerate() {
            let p = physics.log.sample(10 * k + 4).unwrap();
            assert!((p.t - c.t).abs() < 1e-12);
            assert_eq!(
                (
                    p.position,
                    p.attitude,
                    p.omega,
                    p.accel,
                    p.wrench,
                    p.rotor_speeds
                ),
                (
                    c.position,
                    c.attitude,
                    c.omega,
                    c.accel,
                    c.wrench,
                    c.rotor_speeds
                ),
                "interval {k}"
            );
        }
    }
}

/// Fresh noise on every physics-rate sample with the profile's σ (accelerometer noise does not
/// reach the controller without adaptation, so the noise-free flight is the reference), within
/// 3 % over 10 000 samples per axis.
#[test]
fn physics_rate_samples_carry_the_stated_noise() {
    let s = Sensing {
        accel_noise: 0.06,
        ..Sensing::ideal()
    };
    let ideal = simulate(&config(
        9,
        NoiseLevel::None,
        Sensing::ideal(),
        LogRate::Physics,
    ))
    .unwrap();
    let noisy = simulate(&config(9, NoiseLevel::None, s, LogRate::Physics)).unwrap();
    assert_eq!(ideal.tracking_errors, noisy.tracking_errors);
    let sigma = 0.06;
    let mut err = [vec![], vec![], vec![]];
    for (a, b) in ideal.log.samples().zip(noisy.log.samples()) {
        let q = UnitQuaternion::from_quaternion(Quaternion::new(
            a.attitude[0],
            a.attitude[1],
            a.attitude[2],
            a.attitude[3],
        ));
        let d = q.inverse() * (Vector3::from(b.accel.unwrap()) - Vector3::from(a.accel.unwrap()));
        for i in 0..3 {
            err[i].push(d[i]);
        }
    }
    for e in &err {
        let n = e.len() as f64;
        let sd = (e.iter().map(|x| x * x).sum::<f64>() / n).sqrt();
        assert!((sd / sigma - 1.0).abs() < 0.03, "{sd} vs {sigma}");
    }
}

/// With a one-period `time-delay` the physics-rate samples of interval `k` carry the wrench
/// measured in interval `k − 1`.
#[test]
fn physics_rate_log_delays_the_wrench_stream() {
    let plain = config(2, NoiseLevel::None, Sensing::ideal(), LogRate::Physics);
    let mut delayed = plain.clone();
    delayed.effects.time_delay = Some(TimeDelay { delay: 0.02 });
    let delayed = simulate(&delayed).unwrap();
    let plain = simulate(&plain).unwrap();
    assert_eq!(delayed.log.position, plain.log.position);
    for k in 1..delayed.log.len() / 10 {
        for i in 0..10 {
            assert_eq!(
                delayed.log.wrench[10 * k + i],
                plain.log.wrench[10 * (k - 1)],
                "{k} {i}"
            );
        }
    }
    assert!(matches!(
        "audio".parse::<LogRate>(),
        Err(SimError::Unknown { .. })
    ));
    assert_eq!("physics".parse::<LogRate>().unwrap(), LogRate::Physics);
}
