//! Signals derived from a validated log: the inputs of the regressor and of the effects.

use nalgebra::{Matrix3, Quaternion, UnitQuaternion, Vector3};
use tagk_dynamics::GRAVITY_WORLD;

use crate::deriv::{DEFAULT_HALF_WIDTH, savitzky_golay_derivative3};
use crate::error::LogError;
use crate::log::FlightLog;

/// Names of the six wrench channels: body-frame force, then torque about the body origin.
pub const CHANNEL_NAMES: [&str; 6] = ["fx", "fy", "fz", "tx", "ty", "tz"];
/// Units of the six wrench channels.
pub const CHANNEL_UNITS: [&str; 6] = ["N", "N", "N", "N m", "N m", "N m"];

/// A wrench channel, `0..6` = `fx, fy, fz, tx, ty, tz` (body frame, torques about the origin).
pub type Channel = usize;

/// Half-width of the Savitzky–Golay smoothing of the velocity used by the drag effects.
pub(crate) const VELOCITY_SMOOTHING_HALF_WIDTH: usize = 7;

/// Per-sample signals computed once from a [`FlightLog`].
#[derive(Debug, Clone)]
pub struct Signals {
    /// Time \[s\].
    pub t: Vec<f64>,
    /// Rotation body → world.
    pub rotation: Vec<Matrix3<f64>>,
    /// World position \[m\].
    pub position: Vec<Vector3<f64>>,
    /// Body-frame velocity `Rᵀ v` \[m/s\], from the logged velocity smoothed by a
    /// Savitzky–Golay filter of half-width 7 (15 samples; velocity noise
    /// in a regressor column would bias drag coefficients towards zero).
    pub velocity_body: Vec<Vector3<f64>>,
    /// Proper acceleration `a = Rᵀ(p̈ − g_w)`, body frame \[m/s²\].
    pub accel_proper: Vec<Vector3<f64>>,
    /// Body angular velocity \[rad/s\].
    pub omega: Vec<Vector3<f64>>,
    /// Body angular acceleration \[rad/s²\].
    pub omega_dot: Vec<Vector3<f64>>,
    /// Measured actuator wrench `[fx, fy, fz, tx, ty, tz]`.
    pub wrench: Vec<[f64; 6]>,
    /// Rotor speeds \[rad/s\], if logged.
    pub rotor_speeds: Option<Vec<[f64; 4]>>,
    /// `true` if the accelerations were derived (Savitzky–Golay) rather than logged.
    pub derived_accel: bool,
    /// `true` if the angular accelerations were derived rather than logged.
    pub derived_omega_dot: bool,
    /// The source log (for custom effects and extra columns).
    pub log: FlightLog,
}

impl Signals {
    /// Validates the log and derives the signals (missing accelerations by the
    /// Savitzky–Golay differentiator: a local quadratic least-squares fit over 11 samples).
    ///
    /// # Errors
    /// The log's validation error.
    pub fn from_log(log: &FlightLog) -> Result<Self, LogError> {
        log.validate()?;
        let n = log.len();
        let derived_accel = log.accel.is_none();
        let accel_world = match &log.accel {
            Some(a) => a.clone(),
            None => savitzky_golay_derivative3(&log.t, &log.velocity, DEFAULT_HALF_WIDTH),
        };
        let derived_omega_dot = log.omega_dot.is_none();
        let omega_dot = match &log.omega_dot {
            Some(a) => a.clone(),
            None => savitzky_golay_derivative3(&log.t, &log.omega, DEFAULT_HALF_WIDTH),
        };
        let mut s = Signals {
            t: log.t.clone(),
            rotation: Vec::with_capacity(n),
            position: Vec::with_capacity(n),
            velocity_body: Vec::with_capacity(n),
            accel_proper: Vec::with_capacity(n),
            omega: Vec::with_capacity(n),
            omega_dot: Vec::with_capacity(n),
            wrench: log.wrench.clone(),
            rotor_speeds: log.rotor_speeds.clone(),
            derived_accel,
            derived_omega_dot,
            log: log.clone(),
        };
        let vs: Vec<Vec<f64>> = (0..3)
            .map(|k| {
                let v: Vec<f64> = log.velocity.iter().map(|x| x[k]).collect();
                crate::deriv::savitzky_golay_smooth(&log.t, &v, VELOCITY_SMOOTHING_HALF_WIDTH)
            })
            .collect();
        for i in 0..n {
            let q = log.attitude[i];
            let uq = UnitQuaternion::from_quaternion(Quaternion::new(q[0], q[1], q[2], q[3]));
            let r = uq.to_rotation_matrix().into_inner();
            let v = Vector3::new(vs[0][i], vs[1][i], vs[2][i]);
            let a = Vector3::from(accel_world[i]);
            s.rotation.push(r);
            s.position.push(Vector3::from(log.position[i]));
            s.velocity_body.push(r.transpose() * v);
            s.accel_proper.push(r.transpose() * (a - GRAVITY_WORLD));
            s.omega.push(Vector3::from(log.omega[i]));
            s.omega_dot.push(Vector3::from(omega_dot[i]));
        }
        Ok(s)
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// `true` when there are no samples.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    /// Mean sampling period \[s\].
    pub fn mean_dt(&self) -> f64 {
        let n = self.len();
        if n < 2 {
            return 0.0;
        }
        (self.t[n - 1] - self.t[0]) / (n - 1) as f64
    }

    /// One measured wrench channel as a series.
    pub fn channel(&self, c: Channel) -> Vec<f64> {
        self.wrench.iter().map(|w| w[c]).collect()
    }
}

/// Linear interpolation of a series `x(t)` at time `tq` (clamped at the ends): the
/// pointwise reference of the time-delay effect's sweep in the unit tests.
#[cfg(test)]
pub(crate) fn interp(t: &[f64], x: &[f64], tq: f64) -> f64 {
    let n = t.len();
    if n == 0 {
        return 0.0;
    }
    if tq <= t[0] {
        return x[0];
    }
    if tq >= t[n - 1] {
        return x[n - 1];
    }
    let k = t.partition_point(|&s| s <= tq);
    let (t0, t1) = (t[k - 1], t[k]);
    let f = (tq - t0) / (t1 - t0);
    x[k - 1] * (1.0 - f) + x[k] * f
}
