//! Joint-torque logs of an arm moved along a prescribed Fourier excitation, for the
//! joint-torque diagnosis (`tagk diagnose LOG --robot …`) and its tests.
//!
//! The motion is prescribed, not simulated: `q(t)`, `q̇(t)` and `q̈(t)` are closed forms, and
//! the torque is inverse dynamics, `τ = Y(q, q̇, q̈) θ + τ_e(q̇, q̈)` with the joint effects of
//! [`tagk_dynamics::joint_effect`]. No integrator stands between the truth and the log.
//!
//! The excitation is a [`FourierTrajectory`] (Swevers' finite Fourier series). It is periodic,
//! so a log of whole periods excites every harmonic evenly.
//!
//! The sensing is the closed loop's [`JointSensing`]: encoder quantisation of `q`, white noise
//! on `q̇`, white noise and a constant offset on `τ`. Every random draw flows from the seed.

use nalgebra::DVector;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use tagk_dynamics::{DynamicsError, InertialParams, JointEffects, JointLog, KinematicTree};

use super::{FourierTrajectory, JointSensing};
use crate::sim::gaussian;

/// Writes the log of `tree` moved along `motion` for `duration` \[s\] at `rate` \[Hz\].
///
/// The true torque is `Y θ + τ_e` with `θ` the tree's parameters, `payload` added to the
/// payload body's ([`KinematicTree::payload_body`]; `None`: no payload) and `effects` the joint effects. Sensing adds its
/// quantisation, noise and offset (each joint's offset uniform in `±sensing.torque_offset`).
/// With `log_accelerations` the log carries the exact `ddq`; without, the reader derives
/// them. Every draw flows from `seed`.
///
/// # Errors
/// [`DynamicsError::DimensionMismatch`] when the motion, effects or sensing do not have one
/// entry per joint; [`DynamicsError::NonFinite`] for a non-finite input.
#[allow(clippy::too_many_arguments)]
pub fn prescribed_log(
    tree: &KinematicTree,
    payload: Option<&InertialParams>,
    effects: &JointEffects,
    motion: &FourierTrajectory,
    sensing: &JointSensing,
    log_accelerations: bool,
    rate: f64,
    duration: f64,
    seed: u64,
) -> Result<JointLog, DynamicsError> {
    let dof = tree.dof();
    for (what, len) in [("motion", motion.q0.len()), ("effects", effects.dof())] {
        if len != dof {
            return Err(DynamicsError::DimensionMismatch {
                what,
                expected: dof,
                got: len,
            });
        }
    }
    if !(rate.is_finite() && rate > 0.0 && duration.is_finite() && duration > 0.0) {
        return Err(DynamicsError::NonFinite {
            what: "rate or duration",
        });
    }
    let mut theta: DVector<f64> = tree.params_vector();
    if let Some(p) = payload {
        let Some(body) = tree.payload_body() else {
            return Err(DynamicsError::DimensionMismatch {
                what: "payload body",
                expected: 1,
                got: 0,
            });
        };
        let last = 10 * body;
        for (k, v) in p.to_array().into_iter().enumerate() {
            theta[last + k] += v;
        }
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x5eed_a4a1);
    let offset: Vec<f64> = (0..dof)
        .map(|_| match sensing.torque_offset {
            0.0 => 0.0,
            o => o * rng.random_range(-1.0..1.0),
        })
        .collect();
    let count = (duration * rate).floor() as usize;
    let step = sensing.encoder_resolution;
    let mut log = JointLog {
        qdd: log_accelerations.then(Vec::new),
        ..JointLog::default()
    };
    for i in 0..count {
        let t = i as f64 / rate;
        let r = motion.sample(t);
        let (q, qd, qdd) = (r.q, r.qd, r.qdd);
        let y = tree.joint_torque_regressor(&q, &qd, &qdd)?;
        let tau = &y * &theta + effects.torque(&qd, &qdd)?;
        log.t.push(t);
        log.q.push(
            q.iter()
                .map(|x| {
                    if step > 0.0 {
                        (x / step).round() * step
                    } else {
                        *x
                    }
                })
                .collect(),
        );
        log.qd.push(
            qd.iter()
                .map(|x| x + sensing.velocity_noise * gaussian(&mut rng))
                .collect(),
        );
        log.tau.push(
            (0..dof)
                .map(|j| tau[j] + offset[j] + sensing.torque_noise * gaussian(&mut rng))
                .collect(),
        );
        if let Some(v) = log.qdd.as_mut() {
            v.push(qdd);
        }
    }
    Ok(log)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The closed-form velocity and acceleration against central differences of the position.
    #[test]
    fn derivatives_match_finite_differences() {
        let m = FourierTrajectory::random_with_speed(3, 5, 0.1, 1.0, 4);
        let (h, t) = (1e-5, 2.3);
        let (p, mi, r) = (m.sample(t + h), m.sample(t - h), m.sample(t));
        let (qp, qdp, qm, qdm, qd, qdd) = (p.q, p.qd, mi.q, mi.qd, r.qd, r.qdd);
        for j in 0..3 {
            assert!(((qp[j] - qm[j]) / (2.0 * h) - qd[j]).abs() < 1e-8);
            assert!(((qdp[j] - qdm[j]) / (2.0 * h) - qdd[j]).abs() < 1e-7);
        }
    }
}
