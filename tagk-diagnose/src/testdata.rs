//! Synthetic logs for the unit tests of the fitting (NOT the proof on simulator data, which
//! lives in tests/hidden_effects.rs): analytic motion, the wrench from tagk-dynamics'
//! `newton_euler`, minus a hand-written hidden external wrench, plus seeded noise.

use nalgebra::{Matrix3, Rotation3, UnitQuaternion, Vector3};
use rand_chacha::ChaCha8Rng;
use rand_core::{Rng, SeedableRng};
use tagk_dynamics::{GRAVITY_WORLD, InertialParams, newton_euler};

use crate::log::{FlightLog, LogSample};

/// The Crazyflie's nominal parameters.
pub fn crazyflie() -> InertialParams {
    InertialParams::from_array([
        0.035, 0.0, 0.0, 0.0, 1.66e-5, 0.83e-6, 1.66e-5, 0.72e-6, 1.8e-6, 2.93e-5,
    ])
}

/// Kinematic state at time `t`.
pub struct State {
    /// Position, world.
    pub p: Vector3<f64>,
    /// Velocity, world.
    pub v: Vector3<f64>,
    /// Acceleration, world.
    pub acc: Vector3<f64>,
    /// Rotation body → world.
    pub r: Matrix3<f64>,
}

fn rot(t: f64) -> Matrix3<f64> {
    Rotation3::from_euler_angles(
        0.25 * (1.3 * t).sin(),
        0.2 * (0.9 * t).sin(),
        0.3 * (0.4 * t).sin(),
    )
    .into_inner()
}

/// Analytic motion.
pub fn state(t: f64) -> State {
    let (a, b, c) = (0.5, 0.4, 0.2);
    let p = Vector3::new(
        a * (0.7 * t).sin(),
        b * (1.1 * t).sin(),
        1.0 + c * (0.5 * t).sin(),
    );
    let v = Vector3::new(
        a * 0.7 * (0.7 * t).cos(),
        b * 1.1 * (1.1 * t).cos(),
        c * 0.5 * (0.5 * t).cos(),
    );
    let acc = Vector3::new(
        -a * 0.49 * (0.7 * t).sin(),
        -b * 1.21 * (1.1 * t).sin(),
        -c * 0.25 * (0.5 * t).sin(),
    );
    State {
        p,
        v,
        acc,
        r: rot(t),
    }
}

fn omega(t: f64) -> Vector3<f64> {
    let h = 1e-5;
    let rd = (rot(t + h) - rot(t - h)) / (2.0 * h);
    let s = rot(t).transpose() * rd;
    Vector3::new(s[(2, 1)], s[(0, 2)], s[(1, 0)])
}

/// A standard normal draw (Box–Muller).
pub fn gauss(rng: &mut ChaCha8Rng) -> f64 {
    let u1 = ((rng.next_u64() >> 11) as f64 + 0.5) / (1u64 << 53) as f64;
    let u2 = ((rng.next_u64() >> 11) as f64) / (1u64 << 53) as f64;
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

/// A log of `n` samples at 100 Hz of the body `theta`, with the hidden external wrench
/// `hidden(state, body velocity) -> [f; τ]` (body frame) ACTING on the body, so the logged
/// actuator wrench is `newton_euler − hidden`; accelerations logged with noise `sigma_a`.
pub fn synthetic_log(
    theta: &InertialParams,
    n: usize,
    sigma_a: f64,
    seed: u64,
    hidden: &dyn Fn(&State, &Vector3<f64>) -> [f64; 6],
) -> FlightLog {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut log = FlightLog::new();
    let dt = 0.01;
    for k in 0..n {
        let t = k as f64 * dt;
        let st = state(t);
        let w = omega(t);
        let wd = (omega(t + 1e-4) - omega(t - 1e-4)) / 2e-4;
        let a_body = st.r.transpose() * (st.acc - GRAVITY_WORLD);
        let vb = st.r.transpose() * st.v;
        let ne = newton_euler(theta, &a_body, &w, &wd).to_array();
        let ext = hidden(&st, &vb);
        let wrench: [f64; 6] = std::array::from_fn(|c| ne[c] - ext[c]);
        let q = UnitQuaternion::from_matrix(&st.r);
        let noisy = |rng: &mut ChaCha8Rng, v: Vector3<f64>, s: f64| -> [f64; 3] {
            [
                v.x + s * gauss(rng),
                v.y + s * gauss(rng),
                v.z + s * gauss(rng),
            ]
        };
        log.push(&LogSample {
            t,
            position: st.p.into(),
            velocity: st.v.into(),
            attitude: [q.w, q.i, q.j, q.k],
            omega: w.into(),
            wrench,
            accel: Some(noisy(&mut rng, st.acc, sigma_a)),
            omega_dot: Some(wd.into()),
            rotor_speeds: None,
        });
    }
    log
}
