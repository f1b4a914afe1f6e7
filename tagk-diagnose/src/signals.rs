//! Signals derived from a validated log: the inputs of the regressor and of the effects.

use std::borrow::Cow;

use nalgebra::{Matrix3, Vector3};
use tagk_dynamics::GRAVITY_WORLD;

use crate::deriv::{DEFAULT_HALF_WIDTH, savitzky_golay_derivative3};
use crate::error::{DiagnoseError, LogError};
use crate::log::FlightLog;

/// Names of the six wrench channels: body-frame force, then torque about the body origin.
pub const CHANNEL_NAMES: [&str; 6] = ["fx", "fy", "fz", "tx", "ty", "tz"];
/// Units of the six wrench channels.
pub const CHANNEL_UNITS: [&str; 6] = ["N", "N", "N", "N m", "N m", "N m"];

/// A wrench channel, `0..6` = `fx, fy, fz, tx, ty, tz` (body frame, torques about the origin).
pub type Channel = usize;

/// Fewest samples a segment between two gaps must have to be kept
/// ([`Signals::from_log_split`]): the velocity smoothing window (`2 × 7 + 1`), so that no
/// derivative or smoothing of a segment shrinks below its full window.
pub const MIN_SEGMENT_ROWS: usize = 2 * VELOCITY_SMOOTHING_HALF_WIDTH + 1;

/// Half-width of the Savitzky–Golay smoothing of the velocity used by the drag effects.
pub(crate) const VELOCITY_SMOOTHING_HALF_WIDTH: usize = 7;

/// Logs up to this many samples keep the rigid-body regressor in memory once computed
/// (39 values a sample: 78 MB at the limit); longer logs compute it block by block wherever
/// it is read.
pub(crate) const RIGID_CACHE_SAMPLES: usize = 250_000;

/// Series derived from a log by key, each computed once ([`Signals::derived`]). A clone starts
/// empty.
#[derive(Default)]
struct DerivedCache(
    std::sync::Mutex<
        std::collections::HashMap<&'static str, std::sync::Arc<dyn std::any::Any + Send + Sync>>,
    >,
);

impl Clone for DerivedCache {
    fn clone(&self) -> Self {
        Self::default()
    }
}

impl std::fmt::Debug for DerivedCache {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("DerivedCache")
    }
}

/// Per-sample signals computed once from a [`FlightLog`].
///
/// # Examples
///
/// The signals of a closed-form flight (hidden: `flight(samples, with_accel)` logs a 35 g body
/// at 100 Hz and `motion(t)` gives its exact velocity, acceleration, attitude and rates),
/// checked against the same quantities computed by hand.
///
/// ```
/// # use tagk_diagnose::{FlightLog, LogSample};
/// # use tagk_dynamics::nalgebra::{UnitQuaternion, Vector3};
/// # use tagk_dynamics::{GRAVITY_WORLD, InertialParams, newton_euler};
/// # // Closed-form motion of a 35 g body at 100 Hz; the actuators also fight a linear drag
/// # // of 0.01 N s/m. `with_accel`: log the accelerations, or leave them to be derived.
/// # fn motion(t: f64) -> (Vector3<f64>, Vector3<f64>, UnitQuaternion<f64>, Vector3<f64>, Vector3<f64>) {
/// #     let v = Vector3::new(0.5 * (0.8 * t).cos(), 0.4 * (1.1 * t).cos(), 0.1 * (0.5 * t).cos());
/// #     let acc = Vector3::new(-0.4 * (0.8 * t).sin(), -0.44 * (1.1 * t).sin(), -0.05 * (0.5 * t).sin());
/// #     let q = UnitQuaternion::from_euler_angles(0.2 * (1.3 * t).sin(), 0.15 * (0.9 * t).sin(), 0.3 * t);
/// #     let w = Vector3::new(0.26 * (1.3 * t).cos(), 0.135 * (0.9 * t).cos(), 0.3);
/// #     let wd = Vector3::new(-0.338 * (1.3 * t).sin(), -0.1215 * (0.9 * t).sin(), 0.0);
/// #     (v, acc, q, w, wd)
/// # }
/// # fn flight(samples: usize, with_accel: bool) -> FlightLog {
/// #     let theta = InertialParams::from_array([0.035, 0.0, 0.0, 0.0, 1.7e-5, 0.0, 1.7e-5, 0.0, 0.0, 2.9e-5]);
/// #     let mut log = FlightLog::new();
/// #     for k in 0..samples {
/// #         let t = k as f64 * 0.01;
/// #         let (v, acc, q, w, wd) = motion(t);
/// #         let a_body = q.inverse_transform_vector(&(acc - GRAVITY_WORLD));
/// #         let mut wrench = newton_euler(&theta, &a_body, &w, &wd).to_array();
/// #         let v_body = q.inverse_transform_vector(&v);
/// #         for c in 0..3 {
/// #             wrench[c] += 0.01 * v_body[c];
/// #         }
/// #         let p = Vector3::new(0.625 * (0.8 * t).sin(), 0.4 / 1.1 * (1.1 * t).sin(), 1.0 + 0.2 * (0.5 * t).sin());
/// #         log.push(&LogSample {
/// #             t,
/// #             position: p.into(),
/// #             velocity: v.into(),
/// #             attitude: [q.w, q.i, q.j, q.k],
/// #             omega: w.into(),
/// #             wrench,
/// #             accel: with_accel.then(|| acc.into()),
/// #             omega_dot: with_accel.then(|| wd.into()),
/// #             rotor_speeds: None,
/// #         });
/// #     }
/// #     log
/// # }
/// use tagk_diagnose::Signals;
///
/// let s = Signals::from_log(&flight(1500, true))?;
/// assert_eq!(s.len(), 1500);
/// assert!(!s.derived_accel && !s.derived_omega_dot); // both were logged
/// let i = 700;
/// let (v, acc, q, _, _) = motion(s.t[i]);
/// // Proper acceleration in the body frame, a = Rᵀ(p̈ − g_w), and the body-frame velocity.
/// let by_hand = q.inverse_transform_vector(&(acc - GRAVITY_WORLD));
/// assert!((s.accel_proper[i] - by_hand).norm() < 1e-12);
/// assert!((s.velocity_body[i] - q.inverse_transform_vector(&v)).norm() < 1e-6);
///
/// // Without logged accelerations they are derived (Savitzky–Golay), close to the exact ones.
/// let d = Signals::from_log(&flight(1500, false))?;
/// assert!(d.derived_accel && d.derived_omega_dot);
/// assert!((d.accel_proper[i] - by_hand).norm() < 1e-3);
/// # Ok::<(), tagk_diagnose::LogError>(())
/// ```
#[derive(Debug, Clone)]
pub struct Signals {
    /// Time \[s\].
    pub t: Vec<f64>,
    /// Body-frame velocity `Rᵀ v` \[m/s\], from the logged velocity smoothed by a
    /// Savitzky–Golay filter of half-width 7 (15 samples; velocity noise
    /// in a regressor column would bias drag coefficients towards zero).
    pub velocity_body: Vec<Vector3<f64>>,
    /// Proper acceleration `a = Rᵀ(p̈ − g_w)`, body frame \[m/s²\].
    pub accel_proper: Vec<Vector3<f64>>,
    /// Body angular acceleration \[rad/s²\] where it was derived ([`Signals::omega_dot`]
    /// reads the log's own otherwise).
    omega_dot_derived: Option<Vec<Vector3<f64>>>,
    /// [`Signals::target`] where some channel is smoothed (`None`: the measured wrench
    /// itself, not copied).
    target_smoothed: Option<Vec<[f64; 6]>>,
    /// Channels carrying the differentiator's smoothing: the forces when the accelerations
    /// were derived, the torques when the angular accelerations were.
    pub smoothed: [bool; 6],
    /// `true` if the accelerations were derived (Savitzky–Golay) rather than logged.
    pub derived_accel: bool,
    /// `true` if the angular accelerations were derived rather than logged.
    pub derived_omega_dot: bool,
    /// The source log (for custom effects and extra columns); private so that the samples the
    /// signals read from it cannot change under them ([`Signals::log`] reads it).
    log: FlightLog,
    /// The rotor mixer identified from the log, computed on first use.
    rotor_mixer: std::sync::OnceLock<Option<RotorMixer>>,
    /// The rigid-body regressor's entries at every sample (`[10 c + j][i]`; the entries the
    /// regressor leaves zero are empty), computed on first use for logs of at most
    /// [`RIGID_CACHE_SAMPLES`] samples: a diagnosis reads them hundreds of times.
    rigid_cache: std::sync::OnceLock<Option<std::sync::Arc<Vec<Vec<f64>>>>>,
    /// Series an effect derives from the whole log, computed on first use ([`Signals::derived`]).
    derived: DerivedCache,
    /// For several logs joined by [`Signals::concat`]: each log's own signals (empty for one
    /// log). Effects with a time history (lags, delays, start transients) are computed per
    /// log and never across the joins.
    parts: Vec<Signals>,
}

/// The rotor mixer of a log whose wrench was computed from its rotor speeds, identified by
/// least squares: `[fz, tx, ty, tz]ᵀ = M [ω₁², …, ω₄²]ᵀ`, and the hub positions it implies
/// (hubs in the body x-y plane: `M` has rows `k_f`, `k_f y_i`, `−k_f x_i`, `±k_m`).
#[derive(Debug, Clone, PartialEq)]
pub struct RotorMixer {
    /// `M` (4 channels × 4 rotors), row-major.
    pub matrix: [[f64; 4]; 4],
    /// Hub positions `(x_i, y_i)` \[m\], body frame.
    pub hubs: [[f64; 2]; 4],
}

impl RotorMixer {
    /// `M ω²` for the squared rotor speeds `sq` \[rad²/s²\]: `[fz, tx, ty, tz]`.
    pub fn apply(&self, sq: &[f64; 4]) -> [f64; 4] {
        std::array::from_fn(|r| (0..4).map(|i| self.matrix[r][i] * sq[i]).sum())
    }
}

/// Identifies the mixer from the log: least squares of `[fz, tx, ty, tz]` on the squared rotor
/// speeds. It must reproduce the logged wrench to 1e-3 relative on at least 90 % of the
/// samples (saturated samples may disagree), and every rotor must thrust upwards; otherwise
/// `None` (the wrench was not computed from these speeds by a mixer).
fn identify_mixer(w: &[[f64; 4]], wrench: &[[f64; 6]]) -> Option<RotorMixer> {
    use nalgebra::{Matrix4, Vector4};
    let sq: Vec<[f64; 4]> = w.iter().map(|x| x.map(|v| v * v)).collect();
    let mut g = Matrix4::<f64>::zeros();
    let mut rhs = Matrix4::<f64>::zeros();
    for (x, b) in sq.iter().zip(wrench) {
        let xv = Vector4::from(*x);
        let bv = Vector4::new(b[2], b[3], b[4], b[5]);
        g += xv * xv.transpose();
        rhs += xv * bv.transpose();
    }
    let mt = g.cholesky()?.solve(&rhs); // (4 rotors × 4 channels) = Mᵀ
    let mut good = 0usize;
    for (x, b) in sq.iter().zip(wrench) {
        let pred = mt.transpose() * Vector4::from(*x);
        let bv = Vector4::new(b[2], b[3], b[4], b[5]);
        if (pred - bv).norm() <= 1e-3 * bv.norm() {
            good += 1;
        }
    }
    if good * 10 < w.len() * 9 {
        return None;
    }
    let matrix: [[f64; 4]; 4] = std::array::from_fn(|r| std::array::from_fn(|i| mt[(i, r)]));
    if matrix[0].iter().any(|k| k.is_nan() || *k <= 0.0) {
        return None;
    }
    let hubs = std::array::from_fn(|i| [-matrix[2][i] / matrix[0][i], matrix[1][i] / matrix[0][i]]);
    Some(RotorMixer { matrix, hubs })
}

impl Signals {
    /// Validates the log and derives the signals (missing accelerations by the
    /// Savitzky–Golay differentiator: a local quadratic least-squares fit over 11 samples).
    ///
    /// # Errors
    /// The log's validation error.
    pub fn from_log(log: &FlightLog) -> Result<Self, LogError> {
        log.validate()?;
        Self::derive(log.clone())
    }

    /// [`Signals::from_log`] of a log the signals keep ([`Signals::log`]): no copy.
    ///
    /// # Errors
    /// The log's validation error.
    pub(crate) fn from_owned_log(log: FlightLog) -> Result<Self, LogError> {
        log.validate()?;
        Self::derive(log)
    }

    /// The signals of a validated log (or segment of one), which they keep
    /// ([`Signals::log`]).
    fn derive(log: FlightLog) -> Result<Self, LogError> {
        let n = log.len();
        let derived_accel = log.accel.is_none();
        let accel_world: Cow<'_, [[f64; 3]]> = match &log.accel {
            Some(a) => Cow::Borrowed(a),
            None => Cow::Owned(savitzky_golay_derivative3(
                &log.t,
                &log.velocity,
                DEFAULT_HALF_WIDTH,
            )),
        };
        let derived_omega_dot = log.omega_dot.is_none();
        let omega_dot: Cow<'_, [[f64; 3]]> = match &log.omega_dot {
            Some(a) => Cow::Borrowed(a),
            None => Cow::Owned(savitzky_golay_derivative3(
                &log.t,
                &log.omega,
                DEFAULT_HALF_WIDTH,
            )),
        };
        let mut s = Signals {
            t: log.t.clone(),
            velocity_body: Vec::with_capacity(n),
            accel_proper: Vec::with_capacity(n),
            omega_dot_derived: None,
            target_smoothed: None,
            smoothed: [
                derived_accel,
                derived_accel,
                derived_accel,
                derived_omega_dot,
                derived_omega_dot,
                derived_omega_dot,
            ],
            derived_accel,
            derived_omega_dot,
            log: FlightLog::new(),
            rotor_mixer: std::sync::OnceLock::new(),
            rigid_cache: std::sync::OnceLock::new(),
            derived: DerivedCache::default(),
            parts: Vec::new(),
        };
        let vs: Vec<Vec<f64>> = (0..3)
            .map(|k| {
                let v: Vec<f64> = log.velocity.iter().map(|x| x[k]).collect();
                crate::deriv::savitzky_golay_smooth(&log.t, &v, VELOCITY_SMOOTHING_HALF_WIDTH)
            })
            .collect();
        for i in 0..n {
            let r = rotation_of(&log.attitude[i]);
            let v = Vector3::new(vs[0][i], vs[1][i], vs[2][i]);
            let a = Vector3::from(accel_world[i]);
            s.velocity_body.push(r.transpose() * v);
            s.accel_proper.push(r.transpose() * (a - GRAVITY_WORLD));
        }
        if let Cow::Owned(derived) = omega_dot {
            s.omega_dot_derived = Some(derived.into_iter().map(Vector3::from).collect());
        }
        drop((accel_world, vs));
        s.log = log;
        if s.smoothed.iter().any(|x| *x) {
            let mut target = s.wrench().to_vec();
            let mut data: [Option<Vec<f64>>; 6] = std::array::from_fn(|c| {
                s.smoothed[c].then(|| s.wrench().iter().map(|b| b[c]).collect())
            });
            s.smooth_channels(&mut data);
            for (c, d) in data.iter().enumerate() {
                if let Some(v) = d {
                    for (t, x) in target.iter_mut().zip(v) {
                        t[c] = *x;
                    }
                }
            }
            s.target_smoothed = Some(target);
        }
        Ok(s)
    }

    /// [`Signals::from_log`] for a log that may have gaps in its time stamps
    /// ([`FlightLog::sampling`]): the log is validated as a whole, split at every gap into
    /// segments, each segment's signals are derived on their own (derivatives and smoothing
    /// never run across a gap) and the segments are joined like several logs
    /// ([`Signals::concat`]: effects with a time history — lags, delays, start transients —
    /// are computed per segment), keeping the log's own time stamps. Segments with fewer than
    /// [`MIN_SEGMENT_ROWS`] samples are left out. Returns the signals and the segments kept
    /// (sample ranges of `log`). A log without gaps gives [`Signals::from_log`] and one
    /// segment.
    ///
    /// # Errors
    /// The log's validation error; [`LogError::TooShort`] if the segments kept hold fewer
    /// than [`MIN_ROWS`](crate::log::MIN_ROWS) samples.
    pub fn from_log_split(
        log: &FlightLog,
    ) -> Result<(Self, Vec<std::ops::Range<usize>>), DiagnoseError> {
        Self::split(std::borrow::Cow::Borrowed(log))
    }

    /// [`Signals::from_log_split`] of a log the signals may keep (a log without gaps becomes
    /// [`Signals::log`] without a copy: one copy of a long log less in memory).
    ///
    /// # Errors
    /// As [`Signals::from_log_split`].
    pub fn from_owned_log_split(
        log: FlightLog,
    ) -> Result<(Self, Vec<std::ops::Range<usize>>), DiagnoseError> {
        Self::split(std::borrow::Cow::Owned(log))
    }

    /// [`Signals::from_log_split`] of a borrowed or owned log.
    fn split(
        log: std::borrow::Cow<'_, FlightLog>,
    ) -> Result<(Self, Vec<std::ops::Range<usize>>), DiagnoseError> {
        log.validate()?;
        let sampling = log.sampling();
        if sampling.gaps.is_empty() {
            return Ok((Self::derive(log.into_owned())?, sampling.segments()));
        }
        let kept: Vec<std::ops::Range<usize>> = sampling
            .segments()
            .into_iter()
            .filter(|r| r.len() >= MIN_SEGMENT_ROWS)
            .collect();
        let rows: usize = kept.iter().map(|r| r.len()).sum();
        if rows < crate::log::MIN_ROWS {
            return Err(LogError::TooShort {
                rows,
                needed: crate::log::MIN_ROWS,
            }
            .into());
        }
        let parts = kept
            .iter()
            .map(|r| Self::from_segment(log.slice(r.clone())))
            .collect::<Result<Vec<_>, _>>()?;
        let mut joined = Self::concat(parts)?;
        // Keep the log's own time stamps (they increase across the gaps already).
        let t: Vec<f64> = kept
            .iter()
            .flat_map(|r| log.t[r.clone()].iter().copied())
            .collect();
        joined.log.t.clone_from(&t);
        joined.t = t;
        Ok((joined, kept))
    }

    /// The signals of one segment of a validated log: [`Signals::from_log`] without the
    /// validation (a segment may be shorter than [`MIN_ROWS`](crate::log::MIN_ROWS)).
    pub(crate) fn from_segment(log: FlightLog) -> Result<Self, LogError> {
        Self::derive(log)
    }

    /// Applies the differentiator's smoothing (Savitzky–Golay, the half-width of the
    /// acceleration derivative) to the channels of `data` that carry it
    /// ([`Signals::smoothed`]), per joined log.
    pub fn smooth_channels(&self, data: &mut [Option<Vec<f64>>; 6]) {
        for (c, d) in data.iter_mut().enumerate() {
            if !self.smoothed[c] {
                continue;
            }
            let Some(v) = d else { continue };
            if self.parts.is_empty() {
                *v = crate::deriv::savitzky_golay_smooth(&self.t, v, DEFAULT_HALF_WIDTH);
            } else {
                let mut out = Vec::with_capacity(v.len());
                let mut offset = 0;
                for p in &self.parts {
                    let n = p.len();
                    out.extend(crate::deriv::savitzky_golay_smooth(
                        &p.t,
                        &v[offset..offset + n],
                        DEFAULT_HALF_WIDTH,
                    ));
                    offset += n;
                }
                *v = out;
            }
        }
    }

    /// Several logs of one vehicle as one data set (one θ, one set of effect coefficients;
    /// per-log start transients). Times are shifted so that each log starts one sampling
    /// period after the previous one ends (the series stay monotonic); every per-sample signal
    /// is concatenated; rotor speeds, accelerations and extra columns are kept only when every
    /// log has them. A single log is returned as it is.
    ///
    /// # Errors
    /// [`DiagnoseError::InvalidOption`] (field `logs`) for no logs or an empty one.
    pub fn concat(parts: Vec<Signals>) -> Result<Signals, DiagnoseError> {
        if parts.len() == 1 {
            let mut parts = parts;
            return Ok(parts.remove(0));
        }
        if let Some(k) = parts.iter().position(|p| p.is_empty()) {
            return Err(DiagnoseError::InvalidOption {
                field: "logs",
                reason: format!("log {} of {} has no samples", k + 1, parts.len()),
            });
        }
        if parts.is_empty() {
            return Err(DiagnoseError::InvalidOption {
                field: "logs",
                reason: "no log to join".into(),
            });
        }
        let mut log = FlightLog::new();
        let all_rotor = parts.iter().all(|p| p.rotor_speeds().is_some());
        let all_accel = parts.iter().all(|p| p.log.accel.is_some());
        let all_omega_dot = parts.iter().all(|p| p.log.omega_dot.is_some());
        let mut t_end = f64::NEG_INFINITY;
        let mut t = Vec::new();
        for p in &parts {
            let offset = if t_end.is_finite() {
                t_end + p.mean_dt().max(1e-6) - p.t[0]
            } else {
                0.0
            };
            for (i, sample) in p.log.samples().enumerate() {
                let mut sample = sample;
                sample.t = p.t[i] + offset;
                if !all_rotor {
                    sample.rotor_speeds = None;
                }
                if !all_accel {
                    sample.accel = None;
                }
                if !all_omega_dot {
                    sample.omega_dot = None;
                }
                log.push(&sample);
                t.push(sample.t);
            }
            t_end = *t.last().unwrap_or(&0.0);
        }
        for (name, _) in &parts[0].log.extra {
            let columns: Option<Vec<Vec<f64>>> = parts.iter().map(|p| p.log.signal(name)).collect();
            if let Some(columns) = columns {
                log.add_extra(name, columns.concat());
            }
        }
        let cat3 = |f: fn(&Signals) -> &Vec<Vector3<f64>>| -> Vec<Vector3<f64>> {
            parts.iter().flat_map(|p| f(p).iter().copied()).collect()
        };
        Ok(Signals {
            t,
            velocity_body: cat3(|p| &p.velocity_body),
            accel_proper: cat3(|p| &p.accel_proper),
            // The joined log keeps the angular accelerations only when every log has them.
            omega_dot_derived: (!all_omega_dot).then(|| {
                parts
                    .iter()
                    .flat_map(|p| (0..p.len()).map(|i| p.omega_dot(i)))
                    .collect()
            }),
            target_smoothed: parts.iter().any(|p| p.target_smoothed.is_some()).then(|| {
                parts
                    .iter()
                    .flat_map(|p| p.target().iter().copied())
                    .collect()
            }),
            smoothed: std::array::from_fn(|c| parts.iter().any(|p| p.smoothed[c])),
            derived_accel: parts.iter().any(|p| p.derived_accel),
            derived_omega_dot: parts.iter().any(|p| p.derived_omega_dot),
            log,
            rotor_mixer: std::sync::OnceLock::new(),
            rigid_cache: std::sync::OnceLock::new(),
            derived: DerivedCache::default(),
            parts,
        })
    }

    /// The logs joined by [`Signals::concat`] (empty for a single log).
    pub fn parts(&self) -> &[Signals] {
        &self.parts
    }

    /// Rotation body → world at sample `i`, from the logged attitude quaternion (computed
    /// on each call: a long log keeps its quaternions, not a matrix per sample).
    ///
    /// # Panics
    /// If `i` is not below [`Signals::len`].
    pub fn rotation(&self, i: usize) -> Matrix3<f64> {
        rotation_of(&self.log.attitude[i])
    }

    /// Rotation body → world at every sample ([`Signals::rotation`]).
    pub fn rotations(&self) -> impl ExactSizeIterator<Item = Matrix3<f64>> + '_ {
        self.log.attitude.iter().map(rotation_of)
    }

    /// World position \[m\] at sample `i` (the log's own).
    ///
    /// # Panics
    /// If `i` is not below [`Signals::len`].
    pub fn position(&self, i: usize) -> Vector3<f64> {
        Vector3::from(self.log.position[i])
    }

    /// World position \[m\] at every sample ([`Signals::position`]).
    pub fn positions(&self) -> impl ExactSizeIterator<Item = Vector3<f64>> + '_ {
        self.log.position.iter().map(|p| Vector3::from(*p))
    }

    /// Body angular velocity \[rad/s\] at sample `i` (the log's own).
    ///
    /// # Panics
    /// If `i` is not below [`Signals::len`].
    pub fn omega(&self, i: usize) -> Vector3<f64> {
        Vector3::from(self.log.omega[i])
    }

    /// Body angular acceleration \[rad/s²\] at sample `i`: the log's own, or derived by the
    /// Savitzky–Golay differentiator when the log has none ([`Signals::derived_omega_dot`]).
    ///
    /// # Panics
    /// If `i` is not below [`Signals::len`].
    pub fn omega_dot(&self, i: usize) -> Vector3<f64> {
        match &self.omega_dot_derived {
            Some(d) => d[i],
            None => match &self.log.omega_dot {
                Some(a) => Vector3::from(a[i]),
                // Every constructor derives ω̇ when the log has none, and the log is private.
                None => unreachable!("signals without a logged angular acceleration derive it"),
            },
        }
    }

    /// The source log (for custom effects and extra columns, [`FlightLog::signal`]).
    pub fn log(&self) -> &FlightLog {
        &self.log
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

    /// The rigid-body regressor's entries `[10 c + j][i]` at every sample (channel `c`,
    /// column `j`; zero entries empty), for a log of at most [`RIGID_CACHE_SAMPLES`] samples
    /// (computed once); `None` for a longer log.
    pub(crate) fn rigid_cache(&self) -> Option<&[Vec<f64>]> {
        self.rigid_cache
            .get_or_init(|| {
                let n = self.len();
                if n > RIGID_CACHE_SAMPLES {
                    return None;
                }
                let used: Vec<bool> = (0..60)
                    .map(|q| crate::fit::rigid_channels(q % 10).contains(&(q / 10)))
                    .collect();
                let mut rows: Vec<Vec<f64>> = used
                    .iter()
                    .map(|&u| if u { vec![0.0; n] } else { Vec::new() })
                    .collect();
                let mut y = [0.0; 60];
                for i in 0..n {
                    // Infallible: the buffer has 60 entries.
                    let _ = tagk_dynamics::write_rigid_body_regressor(
                        &self.accel_proper[i],
                        &self.omega(i),
                        &self.omega_dot(i),
                        &mut y,
                    );
                    for (q, row) in rows.iter_mut().enumerate() {
                        if used[q] {
                            row[i] = y[q];
                        }
                    }
                }
                Some(std::sync::Arc::new(rows))
            })
            .as_ref()
            .map(|rows| rows.as_slice())
    }

    /// [`Signals::rigid_cache`] if it was computed already (`None` otherwise: nothing is
    /// computed).
    pub(crate) fn rigid_cache_if_computed(&self) -> Option<&[Vec<f64>]> {
        self.rigid_cache
            .get()
            .and_then(|rows| rows.as_ref())
            .map(|rows| rows.as_slice())
    }

    /// A series derived from the whole log, computed by `make` on first use and kept under
    /// `key`: what an effect needs at one sample but computes from every sample (the k-step
    /// prediction asks for one sample at a time). `None` if `key` holds another type.
    pub(crate) fn derived<T: std::any::Any + Send + Sync>(
        &self,
        key: &'static str,
        make: impl FnOnce() -> T,
    ) -> Option<std::sync::Arc<T>> {
        let held = self
            .derived
            .0
            .lock()
            .ok()
            .and_then(|map| map.get(key).cloned());
        let value = match held {
            Some(v) => v,
            None => {
                let v: std::sync::Arc<dyn std::any::Any + Send + Sync> =
                    std::sync::Arc::new(make());
                if let Ok(mut map) = self.derived.0.lock() {
                    map.entry(key).or_insert_with(|| v.clone()).clone()
                } else {
                    v
                }
            }
        };
        value.downcast::<T>().ok()
    }

    /// The rotor mixer identified from the log (`None` without rotor speeds, or when the
    /// logged wrench is not a mixer of their squares), computed once.
    pub fn rotor_mixer(&self) -> Option<&RotorMixer> {
        self.rotor_mixer
            .get_or_init(|| {
                self.rotor_speeds()
                    .and_then(|w| identify_mixer(w, self.wrench()))
            })
            .as_ref()
    }

    /// One measured wrench channel as a series.
    pub fn channel(&self, c: Channel) -> Vec<f64> {
        self.wrench().iter().map(|w| w[c]).collect()
    }

    /// The measured wrench as the fit compares it with the model: [`Signals::wrench()`], except
    /// on the channels whose accelerations were derived ([`Signals::smoothed`]), where it is
    /// smoothed by the Savitzky–Golay filter that pairs with the differentiator (same
    /// half-width), so that both sides of the regression carry the same smoothing. Every
    /// effect column is smoothed alike ([`Signals::smooth_channels`]).
    pub fn target(&self) -> &[[f64; 6]] {
        self.target_smoothed.as_deref().unwrap_or(&self.log.wrench)
    }

    /// Measured actuator wrench `[fx, fy, fz, tx, ty, tz]` per sample (the log's own,
    /// [`FlightLog::wrench`]).
    pub fn wrench(&self) -> &[[f64; 6]] {
        &self.log.wrench
    }

    /// Rotor speeds \[rad/s\] per sample, if logged (the log's own,
    /// [`FlightLog::rotor_speeds`]).
    pub fn rotor_speeds(&self) -> Option<&[[f64; 4]]> {
        self.log.rotor_speeds.as_deref()
    }
}

/// The rotation body → world of a logged attitude quaternion `[w, x, y, z]` (normalised).
fn rotation_of(q: &[f64; 4]) -> Matrix3<f64> {
    tagk_dynamics::log::attitude_quaternion(q)
        .to_rotation_matrix()
        .into_inner()
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
