//! Joint-torque logs of an arm moved along a prescribed Fourier excitation, for the
//! joint-torque diagnosis (`tagk diagnose LOG --robot …`) and its tests.
//!
//! The motion is prescribed, not simulated: `q(t)`, `q̇(t)` and `q̈(t)` are closed forms, and
//! the torque is inverse dynamics, `τ = Y(q, q̇, q̈) θ + τ_e(q̇, q̈)` with the joint effects of
//! [`tagk_dynamics::joint_effect`]. No integrator stands between the truth and the log.
//!
//! Excitation (Swevers' finite Fourier series, one per joint `j`, `L` harmonics of the base
//! frequency `ω_f`): `q_j(t) = q0_j + Σ_l (a_jl / (l ω_f)) sin(l ω_f t) − (b_jl / (l ω_f))
//! cos(l ω_f t)`. It is periodic, so a log of whole periods excites every harmonic evenly.
//!
//! Sensing ([`JointSensing`]): encoder quantisation of `q`, white noise on `q̇`, white noise
//! and a constant offset on `τ`. Every random draw flows from the seed.

use nalgebra::DVector;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use tagk_dynamics::{DynamicsError, InertialParams, JointEffects, JointLog, KinematicTree};

/// A finite Fourier excitation of every joint (module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct FourierExcitation {
    /// Base frequency `ω_f` \[rad/s\].
    pub omega: f64,
    /// Mean position `q0_j` \[rad\].
    pub q0: Vec<f64>,
    /// Sine coefficients `a_jl` \[rad/s\], one row per joint.
    pub a: Vec<Vec<f64>>,
    /// Cosine coefficients `b_jl` \[rad/s\], one row per joint.
    pub b: Vec<Vec<f64>>,
}

impl FourierExcitation {
    /// A random excitation of `dof` joints with `harmonics` harmonics of `base_hz` \[Hz\].
    ///
    /// Each coefficient is uniform in `±speed / harmonics` \[rad/s\], so no joint's speed
    /// exceeds `2 speed`. The mean positions are uniform in ±0.5 rad.
    pub fn random(dof: usize, harmonics: usize, base_hz: f64, speed: f64, seed: u64) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let bound = speed / harmonics.max(1) as f64;
        let mut draw = |n: usize| -> Vec<f64> {
            (0..n)
                .map(|_| bound * (2.0 * rng.random::<f64>() - 1.0))
                .collect()
        };
        let a = (0..dof).map(|_| draw(harmonics)).collect();
        let b = (0..dof).map(|_| draw(harmonics)).collect();
        let q0 = draw(dof).into_iter().map(|x| 0.5 * x / bound).collect();
        Self {
            omega: 2.0 * std::f64::consts::PI * base_hz,
            q0,
            a,
            b,
        }
    }

    /// Position \[rad\], velocity \[rad/s\] and acceleration \[rad/s²\] of every joint at `t` \[s\].
    pub fn state(&self, t: f64) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
        let dof = self.q0.len();
        let (mut q, mut qd, mut qdd) = (self.q0.clone(), vec![0.0; dof], vec![0.0; dof]);
        for j in 0..dof {
            for (l, (a, b)) in self.a[j].iter().zip(&self.b[j]).enumerate() {
                let w = (l + 1) as f64 * self.omega;
                let (s, c) = (w * t).sin_cos();
                q[j] += a / w * s - b / w * c;
                qd[j] += a * c + b * s;
                qdd[j] += -a * w * s + b * w * c;
            }
        }
        (q, qd, qdd)
    }
}

/// How the joints are sensed.
#[derive(Debug, Clone, PartialEq)]
pub struct JointSensing {
    /// Encoder counts per revolution (positions are rounded to one count); 0: exact.
    pub encoder_counts: u64,
    /// Standard deviation of the velocity noise \[rad/s\].
    pub velocity_noise: f64,
    /// Standard deviation of each joint's torque noise \[N m\].
    pub torque_noise: Vec<f64>,
    /// Constant torque-sensor offset of each joint \[N m\] (an effect the diagnosis names
    /// `torque-offset`); zeros for a calibrated sensor.
    pub torque_offset: Vec<f64>,
    /// Whether the log carries the accelerations `ddq` (exact ones) or leaves them to be
    /// derived.
    pub log_accelerations: bool,
}

impl JointSensing {
    /// A UR-like sensing of `dof` joints: 2¹⁸ counts per revolution, 2·10⁻³ rad/s velocity
    /// noise, torque noise `torque_noise` on every joint, no offset, no accelerations.
    pub fn realistic(dof: usize, torque_noise: f64) -> Self {
        Self {
            encoder_counts: 1 << 18,
            velocity_noise: 2e-3,
            torque_noise: vec![torque_noise; dof],
            torque_offset: vec![0.0; dof],
            log_accelerations: false,
        }
    }
}

/// Writes the log of `tree` moved along `motion` for `duration` \[s\] at `rate` \[Hz\].
///
/// The true torque is `Y θ + τ_e` with `θ` the tree's parameters, `payload` added to the
/// last body's (`None`: no payload) and `effects` the joint effects. Sensing adds its
/// quantisation, noise and offset; every draw flows from `seed`.
///
/// # Errors
/// [`DynamicsError::DimensionMismatch`] when the motion, effects or sensing do not have one
/// entry per joint; [`DynamicsError::NonFinite`] for a non-finite input.
#[allow(clippy::too_many_arguments)]
pub fn prescribed_log(
    tree: &KinematicTree,
    payload: Option<&InertialParams>,
    effects: &JointEffects,
    motion: &FourierExcitation,
    sensing: &JointSensing,
    rate: f64,
    duration: f64,
    seed: u64,
) -> Result<JointLog, DynamicsError> {
    let dof = tree.dof();
    for (what, len) in [
        ("motion", motion.q0.len()),
        ("effects", effects.dof()),
        ("torque noise", sensing.torque_noise.len()),
        ("torque offset", sensing.torque_offset.len()),
    ] {
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
        let last = 10 * (tree.n_bodies() - 1);
        for (k, v) in p.to_array().into_iter().enumerate() {
            theta[last + k] += v;
        }
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x5eed_a4a1);
    let mut gauss = move || {
        // Box–Muller: two uniforms in (0, 1] give one standard normal.
        let u1: f64 = 1.0 - rng.random::<f64>();
        let u2: f64 = rng.random::<f64>();
        (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
    };
    let count = (duration * rate).floor() as usize;
    let step = if sensing.encoder_counts > 0 {
        2.0 * std::f64::consts::PI / sensing.encoder_counts as f64
    } else {
        0.0
    };
    let mut log = JointLog {
        qdd: sensing.log_accelerations.then(Vec::new),
        ..JointLog::default()
    };
    for i in 0..count {
        let t = i as f64 / rate;
        let (q, qd, qdd) = motion.state(t);
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
                .map(|x| x + sensing.velocity_noise * gauss())
                .collect(),
        );
        log.tau.push(
            (0..dof)
                .map(|j| tau[j] + sensing.torque_offset[j] + sensing.torque_noise[j] * gauss())
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
        let m = FourierExcitation::random(3, 5, 0.1, 1.0, 4);
        let (h, t) = (1e-5, 2.3);
        let (qp, qdp, _) = m.state(t + h);
        let (qm, qdm, _) = m.state(t - h);
        let (_, qd, qdd) = m.state(t);
        for j in 0..3 {
            assert!(((qp[j] - qm[j]) / (2.0 * h) - qd[j]).abs() < 1e-8);
            assert!(((qdp[j] - qdm[j]) / (2.0 * h) - qdd[j]).abs() < 1e-7);
        }
    }
}
