//! The accelerometer's offset measured against the velocity, before the fit, without any
//! model (docs/CONVENTIONS.md §7.1).
//!
//! **Why.** An accelerometer reads `a + b` with `b` a constant offset in the body frame (an
//! uncalibrated IMU: tens of mg). The wrench regression multiplies the proper acceleration by
//! the mass. A horizontal offset then shows as a constant body force (`accel-bias`). The
//! vertical one does not: in near-level flight `m b_z` is the weight again, and the fit
//! returns the mass scaled by about `1 − b_z / g`. The specific force along the body `z` axis
//! barely varies on a gentle flight (less than 1 % of `g`, below the accelerometer's
//! noise), so the wrench rows cannot tell `b_z` from the mass.
//!
//! **How.** The velocity (motion capture, or an estimator with an absolute reference) does not
//! carry the accelerometer's offset. Over a window `[t₀, t₁]` of about [`WINDOW`] seconds
//! the logged world acceleration `p̈ + R b` integrates to the velocity's change plus
//! `(∫ R dt) b`:
//!
//! ```text
//! ∫ a_log dt − (v(t₁) − v(t₀)) = (∫ R dt) b
//! ```
//!
//! (trapezoidal integrals over the samples). The windows of each segment between gaps are
//! stacked and solved for `b` by least squares. The standard errors come from the residual
//! (the sandwich form, robust to unequal noise on the axes). The windows do not overlap, so
//! their errors are independent: the velocity's noise at each end, and the integrated
//! accelerometer noise.
//!
//! **What is done.** A vertical offset beyond [`OFFSET_Z`] standard errors, and at most
//! [`MAX_OFFSET`], is removed from the log's acceleration (`a_log − R e_z b_z`), unless the
//! caller only measures (`tagk diagnose --no-align`, [`crate::AlignOptions::auto`] off). The
//! horizontal offsets stay: the fit sees them (`accel-bias`) and reports them as a sensor
//! error. A larger "offset" says the velocity and the acceleration disagree (a frame, a
//! unit): it is reported and not removed.

use nalgebra::{Matrix3, Vector3};
use serde::Serialize;

use crate::log::FlightLog;

/// Length of one window of the comparison \[s\]: long enough that the integrated acceleration
/// beats the velocity's noise at the ends, short enough for tens of windows per flight.
pub const WINDOW: f64 = 1.0;

/// Windows needed before the offset is estimated (fewer: the standard errors are not
/// trustworthy).
pub const MIN_WINDOWS: usize = 8;

/// Standard errors by which the vertical offset must differ from zero to be removed (as the
/// stream alignment's significance).
pub const OFFSET_Z: f64 = 3.0;

/// Largest offset removed \[m/s²\] (about 0.1 g, several times a MEMS accelerometer's
/// data-sheet zero-g offset). Beyond it the velocity and the acceleration disagree for
/// another reason, and nothing is removed.
pub const MAX_OFFSET: f64 = 1.0;

/// The accelerometer's offset of one flight, measured against its velocity.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AccelerometerOffset {
    /// The log (its file), for a diagnosis of several logs; empty for one.
    pub log: String,
    /// The offset `b`, body frame \[m/s²\].
    pub offset: [f64; 3],
    /// Its standard errors, body frame \[m/s²\].
    pub std_error: [f64; 3],
    /// Windows of [`WINDOW`] seconds compared.
    pub windows: usize,
    /// The vertical offset removed from the log's acceleration \[m/s²\] (0 when none was).
    pub removed_z: f64,
    /// What was done, in words.
    pub note: String,
}

impl AccelerometerOffset {
    /// One line for the terminal.
    pub fn text(&self) -> String {
        let who = if self.log.is_empty() {
            String::new()
        } else {
            format!("{}: ", self.log)
        };
        let [x, y, z] = self.offset;
        let [ex, ey, ez] = self.std_error;
        format!(
            "{who}accelerometer offset against the velocity ({} windows of {WINDOW} s): \
             b = ({x:.3} ± {ex:.3}, {y:.3} ± {ey:.3}, {z:.3} ± {ez:.3}) m/s², body frame; {}",
            self.windows, self.note
        )
    }
}

/// The offset `b` (body frame \[m/s²\]), its covariance, and the windows used: `None` when
/// the log has no logged acceleration, or fewer than [`MIN_WINDOWS`] windows fit in its
/// segments between gaps, or the normal equations are singular.
pub fn measure(log: &FlightLog) -> Option<(Vector3<f64>, Matrix3<f64>, usize)> {
    let accel = log.accel.as_ref()?;
    if log.is_empty() {
        return None;
    }
    let rotation = |i: usize| {
        tagk_dynamics::log::attitude_quaternion(&log.attitude[i])
            .to_rotation_matrix()
            .into_inner()
    };
    // Each window: M = ∫ R dt and r = ∫ a dt − Δv.
    let mut windows: Vec<(Matrix3<f64>, Vector3<f64>)> = Vec::new();
    for segment in log.sampling().segments() {
        let mut start = segment.start;
        let mut m = Matrix3::zeros();
        let mut r = Vector3::zeros();
        let mut previous = rotation(start);
        for i in segment.start + 1..segment.end {
            let dt = log.t[i] - log.t[i - 1];
            let here = rotation(i);
            m += 0.5 * dt * (previous + here);
            r += 0.5 * dt * (Vector3::from(accel[i - 1]) + Vector3::from(accel[i]));
            previous = here;
            if log.t[i] - log.t[start] >= WINDOW {
                r -= Vector3::from(log.velocity[i]) - Vector3::from(log.velocity[start]);
                windows.push((m, r));
                (m, r, start) = (Matrix3::zeros(), Vector3::zeros(), i);
            }
        }
    }
    if windows.len() < MIN_WINDOWS {
        return None;
    }
    let normal: Matrix3<f64> = windows.iter().map(|(m, _)| m.transpose() * m).sum();
    let rhs: Vector3<f64> = windows.iter().map(|(m, r)| m.transpose() * r).sum();
    let inverse = normal.try_inverse()?;
    let b = inverse * rhs;
    // Sandwich covariance: (MᵀM)⁻¹ Σ Mᵀ e eᵀ M (MᵀM)⁻¹, scaled by k / (k − 1) per window
    // count for the three parameters fitted (3 of the 3 k equations).
    let k = windows.len() as f64;
    let meat: Matrix3<f64> = windows
        .iter()
        .map(|(m, r)| {
            let u = m.transpose() * (r - m * b);
            u * u.transpose()
        })
        .sum();
    let covariance = inverse * meat * inverse * (k / (k - 1.0));
    let finite = b.iter().chain(covariance.iter()).all(|v| v.is_finite());
    finite.then_some((b, covariance, windows.len()))
}

/// Measures the offset of the log named `name` ([`measure`]) and, with `remove`, removes its
/// vertical part from the log's acceleration when it is significant and plausible (module
/// docs; without `remove` it is measured and reported only). Returns the log and what was
/// found (`None`: nothing could be measured).
pub fn remove_vertical_offset(
    name: &str,
    mut log: FlightLog,
    remove: bool,
) -> (FlightLog, Option<AccelerometerOffset>) {
    let Some((b, covariance, windows)) = measure(&log) else {
        return (log, None);
    };
    let se = [0, 1, 2].map(|j| covariance[(j, j)].max(0.0).sqrt());
    let z = b.z;
    let (removed_z, note) = if z.abs() <= OFFSET_Z * se[2] {
        (
            0.0,
            "vertical offset within its noise: nothing removed".to_string(),
        )
    } else if !remove {
        (
            0.0,
            "vertical offset kept (--no-align: measured and reported only); it scales the mass"
                .to_string(),
        )
    } else if b.norm() > MAX_OFFSET {
        (
            0.0,
            format!(
                "beyond {MAX_OFFSET} m/s², the velocity and the acceleration disagree (a frame or a unit?): \
                 nothing removed; the mass and the accelerometer's vertical offset cannot be told apart: \
                 calibrate the accelerometer or give --mass"
            ),
        )
    } else {
        if let Some(accel) = log.accel.as_mut() {
            for (a, q) in accel.iter_mut().zip(&log.attitude) {
                let shift = tagk_dynamics::log::attitude_quaternion(q) * Vector3::new(0.0, 0.0, z);
                for j in 0..3 {
                    a[j] -= shift[j];
                }
            }
        }
        let g = tagk_dynamics::GRAVITY_WORLD.norm();
        (
            z,
            format!(
                "vertical offset removed before the fit (left in, it would scale the mass by {:+.2} %; \
                 its standard error adds ±{:.2} % to the mass's)",
                -100.0 * z / g,
                100.0 * se[2] / g
            ),
        )
    };
    let found = AccelerometerOffset {
        log: name.to_string(),
        offset: b.into(),
        std_error: se,
        windows,
        removed_z,
        note,
    };
    (log, Some(found))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::log::LogSample;
    use nalgebra::UnitQuaternion;

    /// A synthetic flight at `rate` Hz for `seconds`, with a tilting, yawing attitude and a
    /// world acceleration `p̈(t)` of exact velocity. The accelerometer reads `p̈ + R b` plus
    /// white noise of `sigma_a`; the velocity has white noise of `sigma_v` (deterministic
    /// noise from `seed`).
    fn flight(
        b: Vector3<f64>,
        rate: f64,
        seconds: f64,
        sigma_a: f64,
        sigma_v: f64,
        seed: u64,
    ) -> FlightLog {
        let mut state = seed.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
        let mut normal = move || {
            // Sum of 12 uniforms minus 6: a unit-variance, near-normal draw.
            let mut s = 0.0;
            for _ in 0..12 {
                state = state
                    .wrapping_mul(6_364_136_223_846_793_005)
                    .wrapping_add(1_442_695_040_888_963_407);
                s += (state >> 11) as f64 / (1u64 << 53) as f64;
            }
            s - 6.0
        };
        let n = (seconds * rate) as usize;
        let mut log = FlightLog::new();
        for i in 0..n {
            let t = i as f64 / rate;
            let q = UnitQuaternion::from_euler_angles(
                0.2 * (0.7 * t).sin(),
                0.15 * (0.5 * t).cos(),
                0.3 * t,
            );
            // p = (sin t, 0.5 sin 2t, 0.2 sin 0.8t): velocity and acceleration exactly.
            let v = Vector3::new(t.cos(), (2.0 * t).cos(), 0.16 * (0.8 * t).cos());
            let a = Vector3::new(-t.sin(), -2.0 * (2.0 * t).sin(), -0.128 * (0.8 * t).sin());
            let noise_a = Vector3::new(normal(), normal(), normal()) * sigma_a;
            let noise_v = Vector3::new(normal(), normal(), normal()) * sigma_v;
            let reading = a + q * b + noise_a;
            let qq = q.quaternion();
            log.push(&LogSample {
                t,
                position: [t.sin(), 0.5 * (2.0 * t).sin(), 0.2 * (0.8 * t).sin()],
                velocity: (v + noise_v).into(),
                attitude: [qq.w, qq.i, qq.j, qq.k],
                omega: [0.0; 3],
                wrench: [0.0, 0.0, 0.3, 0.0, 0.0, 0.0],
                accel: Some(reading.into()),
                ..LogSample::default()
            });
        }
        log
    }

    /// A known body-frame offset is recovered on every axis, with honest standard errors.
    /// Over 40 noisy flights the truth lies within 1.96 standard errors on about 95 % of the
    /// axes (at least 100 of 120).
    #[test]
    fn a_known_offset_is_recovered_with_honest_errors() {
        let b = Vector3::new(0.12, -0.2, 0.3);
        let mut covered = 0;
        for seed in 0..40 {
            let log = flight(b, 50.0, 30.0, 0.1, 0.01, seed);
            let (est, cov, windows) = measure(&log).expect("measured");
            assert_eq!(windows, 29);
            for j in 0..3 {
                let se = cov[(j, j)].sqrt();
                assert!(se > 0.0 && se < 0.02, "{se}");
                covered += usize::from((est[j] - b[j]).abs() <= 1.96 * se);
            }
        }
        assert!(covered >= 100, "{covered} of 120 covered");
    }

    /// Noise-free, the offset comes out to the trapezoidal rule's error.
    #[test]
    fn noise_free_offset_is_exact() {
        let b = Vector3::new(-0.05, 0.08, -0.25);
        let (est, _, _) = measure(&flight(b, 200.0, 20.0, 0.0, 0.0, 1)).expect("measured");
        assert!((est - b).norm() < 1e-4, "{est} vs {b}");
    }

    /// The vertical offset is removed: measured again on the corrected log, it is within its
    /// noise, and the horizontal offsets are untouched.
    #[test]
    fn the_vertical_offset_is_removed_and_the_horizontal_kept() {
        let b = Vector3::new(0.12, -0.2, 0.3);
        let (log, found) = remove_vertical_offset("", flight(b, 50.0, 30.0, 0.1, 0.01, 3), true);
        let found = found.expect("measured");
        assert!((found.removed_z - 0.3).abs() < 0.01, "{found:?}");
        let (again, cov, _) = measure(&log).expect("measured");
        assert!(again.z.abs() < 3.0 * cov[(2, 2)].sqrt(), "{again}");
        assert!((again.x - b.x).abs() < 0.01 && (again.y - b.y).abs() < 0.01);
    }

    /// Nothing is removed from a calibrated accelerometer, and nothing is measured without a
    /// logged acceleration or on a log too short for the windows.
    #[test]
    fn nothing_is_removed_without_an_offset_or_a_measurement() {
        let (_, found) =
            remove_vertical_offset("", flight(Vector3::zeros(), 50.0, 30.0, 0.1, 0.01, 5), true);
        assert_eq!(found.expect("measured").removed_z, 0.0);
        let mut log = flight(Vector3::new(0.0, 0.0, 0.3), 50.0, 30.0, 0.1, 0.01, 5);
        log.accel = None;
        assert!(measure(&log).is_none());
        let short = flight(Vector3::new(0.0, 0.0, 0.3), 50.0, 5.0, 0.1, 0.01, 5);
        assert!(measure(&short).is_none());
    }

    /// Asked to measure only, the offset is reported and the log left as it was.
    #[test]
    fn measured_only_leaves_the_log_alone() {
        let log = flight(Vector3::new(0.1, 0.0, 0.3), 50.0, 30.0, 0.1, 0.01, 4);
        let (kept, found) = remove_vertical_offset("", log.clone(), false);
        assert_eq!(found.expect("measured").removed_z, 0.0);
        assert_eq!(kept.accel, log.accel);
    }

    /// An "offset" beyond [`MAX_OFFSET`] is reported, not removed.
    #[test]
    fn an_implausible_offset_is_not_removed() {
        let b = Vector3::new(0.0, 0.0, 2.0);
        let (log, found) = remove_vertical_offset("", flight(b, 50.0, 30.0, 0.1, 0.01, 6), true);
        let found = found.expect("measured");
        assert_eq!(found.removed_z, 0.0);
        assert!(
            found.note.contains("cannot be told apart"),
            "{}",
            found.note
        );
        assert!((measure(&log).expect("measured").0.z - 2.0).abs() < 0.02);
    }
}
