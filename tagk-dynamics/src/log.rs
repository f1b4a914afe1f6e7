//! Flight logs: the in-memory [`FlightLog`], its one CSV reader and writer, and the
//! validation whose typed errors ([`LogError`]) name the file, line and column at fault.
//!
//! # Format (CSV, v1)
//!
//! One header row, one row per sample, SI units, strictly increasing `t`:
//!
//! | columns | meaning | required |
//! |---|---|---|
//! | `t` | time \[s\] | yes |
//! | `px,py,pz`, `vx,vy,vz` | world position \[m\], world velocity \[m/s\] | yes |
//! | `qw,qx,qy,qz` | attitude quaternion, Hamilton, body → world | yes |
//! | `wx,wy,wz` | body angular velocity \[rad/s\] | yes |
//! | `fx,fy,fz`, `tx,ty,tz` | actuator wrench, body frame, about the origin \[N, N m\] | yes, unless `w1..w4` are given and a [vehicle](crate::vehicle) computes it |
//! | `ax,ay,az` | world linear acceleration `p̈` \[m/s²\] (gravity removed; the diagnosis refuses columns whose mean on z is more than `g/2` from `Δv_z / T` as the specific force, [`accel_looks_like_specific_force`]) | no: derived from velocity if absent |
//! | `dwx,dwy,dwz` | body angular acceleration \[rad/s²\] | no: derived from `w` if absent |
//! | `w1..w4` | rotor speeds \[rad/s\] | no |
//!
//! Any other column is kept ([`FlightLog::extra`]) when every cell of it is a finite number.
//! One with text, a boolean or an empty cell is not read: [`FlightLog::read_csv_path`] lists
//! it with its first such cell. The simulator writes its logs with
//! [`FlightLog::write_csv`]; the diagnosis reads them with [`FlightLog::from_csv_path`].
//!
//! ```
//! use tagk_dynamics::log::{FlightLog, LogSample};
//!
//! let mut log = FlightLog::new();
//! for i in 0..250 {
//!     log.push(&LogSample {
//!         t: 0.01 * f64::from(i),
//!         attitude: [1.0, 0.0, 0.0, 0.0],
//!         wrench: [0.0, 0.0, 0.34, 0.0, 0.0, 0.0],
//!         ..LogSample::default()
//!     });
//! }
//! let mut csv = Vec::new();
//! log.write_csv(&mut csv)?;
//! assert_eq!(FlightLog::from_csv_reader(csv.as_slice())?, log);
//! # Ok::<(), tagk_dynamics::log::LogError>(())
//! ```

use std::io::{Read, Write};
use std::path::Path;

use thiserror::Error;

/// The unit quaternion of a logged attitude `[w, x, y, z]` (Hamilton, body → world),
/// normalised. The one reading of [`FlightLog::attitude`]'s convention.
pub fn attitude_quaternion(q: &[f64; 4]) -> nalgebra::UnitQuaternion<f64> {
    nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(q[0], q[1], q[2], q[3]))
}

/// Allowed deviation of the attitude quaternion's norm from 1 before a log is rejected.
pub const QUATERNION_NORM_TOLERANCE: f64 = 0.01;

/// Fewest samples a log must have to be fitted (the 10 rigid-body parameters, a few effects,
/// and the 5 blocks of the cross-validation need a few hundred samples).
pub const MIN_ROWS: usize = 200;

/// A time step longer than `GAP_FACTOR` × the log's (or stream's) median step is a gap
/// ([`Sampling`]).
pub const GAP_FACTOR: f64 = 3.0;

/// A step that differs from the median step by more than this fraction of it (and is not a
/// gap) is irregular ([`Sampling::irregular_steps`]).
pub const IRREGULAR_STEP_TOLERANCE: f64 = 0.1;

/// Most rows [`FlightLog::resample_linear`] may produce (10⁸, about 24 GB of signals would
/// be far beyond any use; this bounds a mistyped step).
pub const MAX_RESAMPLED_ROWS: usize = 100_000_000;

/// Required columns, in the order of the [format](self) (the wrench, the last six, may be
/// replaced by the rotor speeds [`ROTOR_SPEED_COLUMNS`] and a [vehicle](crate::vehicle)).
pub const REQUIRED_COLUMNS: [&str; 20] = [
    "t", "px", "py", "pz", "vx", "vy", "vz", "qw", "qx", "qy", "qz", "wx", "wy", "wz", "fx", "fy",
    "fz", "tx", "ty", "tz",
];

/// Optional columns with a meaning in the format (the three groups below, in this order).
pub const OPTIONAL_COLUMNS: [&str; 10] = [
    "ax", "ay", "az", "dwx", "dwy", "dwz", "w1", "w2", "w3", "w4",
];

/// The body-wrench group `fx..tz` (the last six [`REQUIRED_COLUMNS`]).
pub const WRENCH_COLUMNS: [&str; 6] = ["fx", "fy", "fz", "tx", "ty", "tz"];
/// Number of [`REQUIRED_COLUMNS`] before the wrench group.
const MOTION_COLUMN_COUNT: usize = REQUIRED_COLUMNS.len() - WRENCH_COLUMNS.len();

/// The optional world-acceleration group (all or none).
pub const ACCEL_COLUMNS: [&str; 3] = ["ax", "ay", "az"];
/// The optional body angular-acceleration group (all or none).
pub const OMEGA_DOT_COLUMNS: [&str; 3] = ["dwx", "dwy", "dwz"];
/// The optional rotor-speed group (all or none).
pub const ROTOR_SPEED_COLUMNS: [&str; 4] = ["w1", "w2", "w3", "w4"];

/// A flight log as read from CSV ([`FlightLog::read_csv`], [`FlightLog::read_csv_path`]).
#[derive(Debug, Clone, PartialEq)]
pub struct ReadLog {
    /// The log.
    pub log: FlightLog,
    /// The CSV line (1-based; the header is line 1) each sample was read from.
    pub lines: Vec<usize>,
    /// The columns outside the format that were not read: a cell of each is not a finite
    /// number (text, a boolean, an empty cell). The first such cell is named.
    pub unread_columns: Vec<crate::log_input::UnreadColumn>,
}

/// A flight log in memory: one entry per sample in every signal, SI units (the [format](self)).
///
/// The simulator (or any Rust program) fills it directly with [`FlightLog::push`]; CSV files
/// are read with [`FlightLog::from_csv_path`]. Call [`FlightLog::validate`] before use (the
/// diagnosis does it for you).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FlightLog {
    /// Time \[s\], strictly increasing.
    pub t: Vec<f64>,
    /// World position of the body origin \[m\].
    pub position: Vec<[f64; 3]>,
    /// World velocity of the body origin \[m/s\].
    pub velocity: Vec<[f64; 3]>,
    /// Attitude `(w, x, y, z)`, Hamilton, body → world .
    pub attitude: Vec<[f64; 4]>,
    /// Body angular velocity \[rad/s\].
    pub omega: Vec<[f64; 3]>,
    /// Actuator wrench `[fx, fy, fz, tx, ty, tz]`, body frame, about the origin [N, N m].
    /// Empty for a log read without the wrench columns (it then has rotor speeds, from which
    /// [`FlightLog::compute_wrench_from_rotor_speeds`] computes it; see
    /// [`FlightLog::has_wrench`]).
    pub wrench: Vec<[f64; 6]>,
    /// World linear acceleration `p̈` \[m/s²\]; `None`: derived from the velocity.
    pub accel: Option<Vec<[f64; 3]>>,
    /// Body angular acceleration \[rad/s²\]; `None`: derived from `omega`.
    pub omega_dot: Option<Vec<[f64; 3]>>,
    /// Rotor speeds `w1..w4` \[rad/s\], if logged.
    pub rotor_speeds: Option<Vec<[f64; 4]>>,
    /// Any other columns, by name (kept and offered as signals for custom effects).
    pub extra: Vec<(String, Vec<f64>)>,
}

/// A gap in a log's time stamps: a step longer than [`GAP_FACTOR`] × the median step.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct TimeGap {
    /// Index of the first sample after the gap (the gap lies between samples `index − 1` and
    /// `index`).
    pub index: usize,
    /// Time of the last sample before the gap \[s\].
    pub start: f64,
    /// Length of the gap \[s\] (the step across it).
    pub duration: f64,
}

/// How a log is sampled ([`FlightLog::sampling`]): its median step, its gaps and how many
/// other steps are irregular.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Sampling {
    /// Median time step \[s\] (0 for fewer than two samples).
    pub median_step: f64,
    /// Steps longer than [`GAP_FACTOR`] × the median step, in time order.
    pub gaps: Vec<TimeGap>,
    /// Steps that are not gaps but differ from the median step by more than
    /// [`IRREGULAR_STEP_TOLERANCE`] of it.
    pub irregular_steps: usize,
    /// Largest relative deviation `|Δt − median| / median` among the steps that are not gaps.
    pub max_deviation: f64,
    /// Number of steps (samples − 1).
    pub steps: usize,
}

impl Sampling {
    /// Measures the sampling of the time stamps `t` \[s\] (increasing).
    pub fn of(t: &[f64]) -> Self {
        let median_step = median_step(t);
        let mut gaps = Vec::new();
        let mut irregular_steps = 0;
        let mut max_deviation: f64 = 0.0;
        for (i, w) in t.windows(2).enumerate() {
            let d = w[1] - w[0];
            if d > GAP_FACTOR * median_step {
                gaps.push(TimeGap {
                    index: i + 1,
                    start: w[0],
                    duration: d,
                });
                continue;
            }
            let dev = if median_step > 0.0 {
                (d - median_step).abs() / median_step
            } else {
                0.0
            };
            max_deviation = max_deviation.max(dev);
            if dev > IRREGULAR_STEP_TOLERANCE {
                irregular_steps += 1;
            }
        }
        Self {
            median_step,
            gaps,
            irregular_steps,
            max_deviation,
            steps: t.len().saturating_sub(1),
        }
    }

    /// `true` without gaps and without irregular steps.
    pub fn is_regular(&self) -> bool {
        self.gaps.is_empty() && self.irregular_steps == 0
    }

    /// The sample ranges between the gaps (`0..n` for a log without gaps).
    pub fn segments(&self) -> Vec<std::ops::Range<usize>> {
        let n = self.steps + 1;
        let mut out = Vec::with_capacity(self.gaps.len() + 1);
        let mut start = 0;
        for g in &self.gaps {
            out.push(start..g.index);
            start = g.index;
        }
        out.push(start..n);
        out
    }
}

impl std::fmt::Display for Sampling {
    /// One line per finding: the median step, each gap (where, how long), the irregular steps.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "sampling: median step {:.4} s ({:.1} Hz)",
            self.median_step,
            if self.median_step > 0.0 {
                1.0 / self.median_step
            } else {
                0.0
            }
        )?;
        for g in &self.gaps {
            write!(
                f,
                "\ngap: {:.3} s long after t = {:.3} s (sample {})",
                g.duration, g.start, g.index
            )?;
        }
        if self.irregular_steps > 0 {
            write!(
                f,
                "\nirregular sampling: {} of {} steps differ from the median by more than {:.0} % (at most {:.0} %)",
                self.irregular_steps,
                self.steps,
                100.0 * IRREGULAR_STEP_TOLERANCE,
                100.0 * self.max_deviation
            )?;
        }
        Ok(())
    }
}

/// `ax..az` read as the world acceleration `p̈` that most likely hold the world-frame specific
/// force. Returned are the mean of `accel` on z over the log and the mean the velocity implies,
/// `Δv_z / T` \[m/s²\], when they differ by more than `g/2`. A flight's `p̈` averages `Δv / T`;
/// the specific force averages `+g` more on z. `None` when they agree, or for a log too short
/// or not sampled in time to tell.
pub fn accel_looks_like_specific_force(
    accel: &[[f64; 3]],
    t: &[f64],
    velocity: &[[f64; 3]],
) -> Option<(f64, f64)> {
    let n = accel.len();
    if n < 2 || velocity.len() != n || t.len() != n {
        return None;
    }
    let span = t[n - 1] - t[0];
    if span.is_nan() || span <= 0.0 {
        return None;
    }
    let mean_z = accel.iter().map(|a| a[2]).sum::<f64>() / n as f64;
    let from_velocity = (velocity[n - 1][2] - velocity[0][2]) / span;
    ((mean_z - from_velocity).abs() > 0.5 * crate::GRAVITY_WORLD.norm())
        .then_some((mean_z, from_velocity))
}

/// Median of the time steps of `t` \[s\] (0 for fewer than two samples).
pub fn median_step(t: &[f64]) -> f64 {
    let mut d: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    if d.is_empty() {
        return 0.0;
    }
    let mid = d.len() / 2;
    *d.select_nth_unstable_by(mid, f64::total_cmp).1
}

/// One sample, for [`FlightLog::push`].
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct LogSample {
    /// Time \[s\].
    pub t: f64,
    /// World position \[m\].
    pub position: [f64; 3],
    /// World velocity \[m/s\].
    pub velocity: [f64; 3],
    /// Attitude quaternion `(w, x, y, z)`.
    pub attitude: [f64; 4],
    /// Body angular velocity \[rad/s\].
    pub omega: [f64; 3],
    /// Actuator wrench `[fx, fy, fz, tx, ty, tz]` [N, N m], body frame.
    pub wrench: [f64; 6],
    /// World acceleration `p̈` \[m/s²\], if measured.
    pub accel: Option<[f64; 3]>,
    /// Body angular acceleration \[rad/s²\], if measured.
    pub omega_dot: Option<[f64; 3]>,
    /// Rotor speeds \[rad/s\], if measured.
    pub rotor_speeds: Option<[f64; 4]>,
}

impl FlightLog {
    /// An empty log.
    pub fn new() -> Self {
        Self::default()
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// `true` if there is no sample.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    /// Appends one sample. The optional signals are kept only if every sample has them: the
    /// first sample decides, and a later sample without a signal the first one had drops it.
    pub fn push(&mut self, s: &LogSample) {
        let first = self.t.is_empty();
        self.t.push(s.t);
        self.position.push(s.position);
        self.velocity.push(s.velocity);
        self.attitude.push(s.attitude);
        self.omega.push(s.omega);
        self.wrench.push(s.wrench);
        push_opt(&mut self.accel, s.accel, first);
        push_opt(&mut self.omega_dot, s.omega_dot, first);
        push_opt(&mut self.rotor_speeds, s.rotor_speeds, first);
    }

    /// Sample `i` (without the extra columns), `None` past the end or if the log has no
    /// wrench ([`FlightLog::has_wrench`]).
    pub fn sample(&self, i: usize) -> Option<LogSample> {
        Some(LogSample {
            t: *self.t.get(i)?,
            position: *self.position.get(i)?,
            velocity: *self.velocity.get(i)?,
            attitude: *self.attitude.get(i)?,
            omega: *self.omega.get(i)?,
            wrench: *self.wrench.get(i)?,
            accel: self.accel.as_ref().and_then(|a| a.get(i).copied()),
            omega_dot: self.omega_dot.as_ref().and_then(|a| a.get(i).copied()),
            rotor_speeds: self.rotor_speeds.as_ref().and_then(|a| a.get(i).copied()),
        })
    }

    /// The samples in time order (without the extra columns).
    pub fn samples(&self) -> impl Iterator<Item = LogSample> + '_ {
        (0..self.len()).map_while(|i| self.sample(i))
    }

    /// Adds an extra named signal (one value per sample).
    pub fn add_extra(&mut self, name: &str, values: Vec<f64>) {
        self.extra.push((name.to_string(), values));
    }

    /// Looks a scalar signal up by its CSV column name (standard or extra); `None` if absent.
    pub fn signal(&self, name: &str) -> Option<Vec<f64>> {
        let pick3 = |v: &Vec<[f64; 3]>, k: usize| v.iter().map(|x| x[k]).collect();
        let std3 = |name: &str| -> Option<(usize, usize)> {
            let table: [(&str, usize, usize); 12] = [
                ("px", 0, 0),
                ("py", 0, 1),
                ("pz", 0, 2),
                ("vx", 1, 0),
                ("vy", 1, 1),
                ("vz", 1, 2),
                ("wx", 2, 0),
                ("wy", 2, 1),
                ("wz", 2, 2),
                ("ax", 3, 0),
                ("ay", 3, 1),
                ("az", 3, 2),
            ];
            table
                .iter()
                .find(|(n, _, _)| *n == name)
                .map(|(_, g, k)| (*g, *k))
        };
        if name == "t" {
            return Some(self.t.clone());
        }
        if let Some((g, k)) = std3(name) {
            return match g {
                0 => Some(pick3(&self.position, k)),
                1 => Some(pick3(&self.velocity, k)),
                2 => Some(pick3(&self.omega, k)),
                _ => self.accel.as_ref().map(|a| pick3(a, k)),
            };
        }
        if let Some(k) = ["dwx", "dwy", "dwz"].iter().position(|n| *n == name) {
            return self.omega_dot.as_ref().map(|a| pick3(a, k));
        }
        if let Some(k) = ["qw", "qx", "qy", "qz"].iter().position(|n| *n == name) {
            return Some(self.attitude.iter().map(|q| q[k]).collect());
        }
        if let Some(k) = WRENCH_COLUMNS.iter().position(|n| *n == name) {
            return self
                .has_wrench()
                .then(|| self.wrench.iter().map(|w| w[k]).collect());
        }
        if let Some(k) = ["w1", "w2", "w3", "w4"].iter().position(|n| *n == name) {
            return self
                .rotor_speeds
                .as_ref()
                .map(|r| r.iter().map(|x| x[k]).collect());
        }
        self.extra
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| v.clone())
    }

    /// The sampling of the log's time stamps: median step, gaps, irregular steps.
    pub fn sampling(&self) -> Sampling {
        Sampling::of(&self.t)
    }

    /// Appends the samples of `other`, which has the same signals and extra columns (a log
    /// cut with [`FlightLog::slice`] and joined again). An optional signal or an extra column
    /// that `other` lacks stays as it is.
    pub fn append(&mut self, other: FlightLog) {
        self.t.extend(other.t);
        self.position.extend(other.position);
        self.velocity.extend(other.velocity);
        self.attitude.extend(other.attitude);
        self.omega.extend(other.omega);
        self.wrench.extend(other.wrench);
        if let (Some(x), Some(y)) = (&mut self.accel, other.accel) {
            x.extend(y);
        }
        if let (Some(x), Some(y)) = (&mut self.omega_dot, other.omega_dot) {
            x.extend(y);
        }
        if let (Some(x), Some(y)) = (&mut self.rotor_speeds, other.rotor_speeds) {
            x.extend(y);
        }
        for ((_, x), (_, y)) in self.extra.iter_mut().zip(other.extra) {
            x.extend(y);
        }
    }

    /// The samples `range` as a log of their own (every signal, extra columns included).
    ///
    /// # Panics
    /// If `range` is out of bounds for a signal (use ranges of [`Sampling::segments`]).
    pub fn slice(&self, range: std::ops::Range<usize>) -> FlightLog {
        let cut = |v: &Vec<[f64; 3]>| v[range.clone()].to_vec();
        FlightLog {
            t: self.t[range.clone()].to_vec(),
            position: cut(&self.position),
            velocity: cut(&self.velocity),
            attitude: self.attitude[range.clone()].to_vec(),
            omega: cut(&self.omega),
            wrench: if self.wrench.is_empty() {
                Vec::new()
            } else {
                self.wrench[range.clone()].to_vec()
            },
            accel: self.accel.as_ref().map(cut),
            omega_dot: self.omega_dot.as_ref().map(cut),
            rotor_speeds: self
                .rotor_speeds
                .as_ref()
                .map(|r| r[range.clone()].to_vec()),
            extra: self
                .extra
                .iter()
                .map(|(n, v)| (n.clone(), v[range.clone()].to_vec()))
                .collect(),
        }
    }

    /// The log resampled onto a uniform time grid of step `dt` \[s\] by **linear
    /// interpolation** of every signal between the two neighbouring samples (the attitude by
    /// normalised linear interpolation, after flipping the later quaternion onto the earlier
    /// one's hemisphere). Each segment between gaps ([`Sampling::segments`]) is resampled on
    /// its own grid, starting at its first sample: a gap is never bridged, it stays a gap.
    /// Segments shorter than `dt` keep their first sample only.
    ///
    /// # Errors
    ///
    /// - [`LogError::InvalidResampleStep`] for a step that is not positive and finite, or so
    ///   small that the grid would have more than [`MAX_RESAMPLED_ROWS`] rows;
    /// - the errors of the writer's check (equal signal lengths, strictly increasing time, rotor
    ///   speeds for a log without a wrench) for a log that is not a log.
    pub fn resample_linear(&self, dt: f64) -> Result<FlightLog, LogError> {
        self.check_writable()?;
        let span = match (self.t.first(), self.t.last()) {
            (Some(a), Some(b)) => b - a,
            _ => 0.0,
        };
        if !(dt > 0.0 && dt.is_finite()) || span / dt > MAX_RESAMPLED_ROWS as f64 {
            return Err(LogError::InvalidResampleStep { dt, span });
        }
        let mut out = self.slice(0..0);
        let lerp = |a: &[f64], b: &[f64], f: f64, o: &mut [f64]| {
            for ((o, x), y) in o.iter_mut().zip(a).zip(b) {
                *o = x + (y - x) * f;
            }
        };
        for seg in self.sampling().segments() {
            let (first, last) = (seg.start, seg.end - 1);
            let t0 = self.t[first];
            // A grid point within rounding of the segment's last sample is kept (at it).
            let count = ((self.t[last] - t0) / dt + 1e-9).floor() as usize + 1;
            let mut k = first;
            for j in 0..count {
                let tq = (t0 + j as f64 * dt).min(self.t[last]);
                while k + 1 < last && self.t[k + 1] <= tq {
                    k += 1;
                }
                let (i, f) = if k >= last || tq <= self.t[k] {
                    (k.min(last), 0.0)
                } else {
                    (k, ((tq - self.t[k]) / (self.t[k + 1] - self.t[k])).min(1.0))
                };
                let j2 = (i + 1).min(last);
                let v3 = |v: &Vec<[f64; 3]>| {
                    let mut o = [0.0; 3];
                    lerp(&v[i], &v[j2], f, &mut o);
                    o
                };
                out.t.push(tq);
                out.position.push(v3(&self.position));
                out.velocity.push(v3(&self.velocity));
                out.omega.push(v3(&self.omega));
                let (qa, mut qb) = (self.attitude[i], self.attitude[j2]);
                if qa.iter().zip(&qb).map(|(a, b)| a * b).sum::<f64>() < 0.0 {
                    qb = qb.map(|x| -x);
                }
                let mut q = [0.0; 4];
                lerp(&qa, &qb, f, &mut q);
                let norm_a = qa.iter().map(|x| x * x).sum::<f64>().sqrt();
                let norm = q.iter().map(|x| x * x).sum::<f64>().sqrt();
                if norm > 0.0 {
                    q = q.map(|x| x * norm_a / norm);
                }
                out.attitude.push(q);
                if !self.wrench.is_empty() {
                    let mut w = [0.0; 6];
                    lerp(&self.wrench[i], &self.wrench[j2], f, &mut w);
                    out.wrench.push(w);
                }
                if let (Some(a), Some(o)) = (&self.accel, &mut out.accel) {
                    o.push(v3(a));
                }
                if let (Some(a), Some(o)) = (&self.omega_dot, &mut out.omega_dot) {
                    o.push(v3(a));
                }
                if let (Some(r), Some(o)) = (&self.rotor_speeds, &mut out.rotor_speeds) {
                    let mut w = [0.0; 4];
                    lerp(&r[i], &r[j2], f, &mut w);
                    o.push(w);
                }
                for ((_, v), (_, o)) in self.extra.iter().zip(&mut out.extra) {
                    o.push(v[i] + (v[j2] - v[i]) * f);
                }
            }
        }
        Ok(out)
    }

    /// Checks that every signal has one value per sample.
    fn check_lengths(&self) -> Result<(), LogError> {
        let n = self.t.len();
        let check_len = |name: &str, got: usize| {
            if got == n {
                Ok(())
            } else {
                Err(LogError::LengthMismatch {
                    column: name.to_string(),
                    got,
                    expected: n,
                })
            }
        };
        check_len("position", self.position.len())?;
        check_len("velocity", self.velocity.len())?;
        check_len("attitude", self.attitude.len())?;
        check_len("omega", self.omega.len())?;
        if !(self.wrench.is_empty() && self.rotor_speeds.is_some()) {
            check_len("wrench", self.wrench.len())?;
        }
        if let Some(a) = &self.accel {
            check_len("accel", a.len())?;
        }
        if let Some(a) = &self.omega_dot {
            check_len("omega_dot", a.len())?;
        }
        if let Some(a) = &self.rotor_speeds {
            check_len("rotor_speeds", a.len())?;
        }
        for (name, v) in &self.extra {
            check_len(name, v.len())?;
        }
        Ok(())
    }

    /// Checks the log: equal signal lengths, a body wrench, finite values, strictly increasing
    /// time, unit quaternions (within [`QUATERNION_NORM_TOLERANCE`]) and at least
    /// [`MIN_ROWS`] samples.
    /// Line numbers in the errors are those of the equivalent CSV file (sample `i` is line
    /// `i + 2`).
    ///
    /// # Errors
    /// The first problem found, as a [`LogError`].
    pub fn validate(&self) -> Result<(), LogError> {
        let n = self.t.len();
        self.check_lengths()?;
        if n > 0 && self.wrench.is_empty() {
            return Err(LogError::MissingWrench {
                has_rotor_speeds: self.rotor_speeds.is_some(),
            });
        }
        for i in 0..n {
            let line = i + 2;
            let finite = |col: &str, x: f64| {
                if x.is_finite() {
                    Ok(())
                } else {
                    Err(LogError::NonFinite {
                        line,
                        column: col.to_string(),
                        value: x,
                    })
                }
            };
            finite("t", self.t[i])?;
            for (k, c) in ["px", "py", "pz"].iter().enumerate() {
                finite(c, self.position[i][k])?;
            }
            for (k, c) in ["vx", "vy", "vz"].iter().enumerate() {
                finite(c, self.velocity[i][k])?;
            }
            for (k, c) in ["qw", "qx", "qy", "qz"].iter().enumerate() {
                finite(c, self.attitude[i][k])?;
            }
            for (k, c) in ["wx", "wy", "wz"].iter().enumerate() {
                finite(c, self.omega[i][k])?;
            }
            for (k, c) in WRENCH_COLUMNS.iter().enumerate() {
                finite(c, self.wrench[i][k])?;
            }
            if let Some(a) = &self.accel {
                for (k, c) in ["ax", "ay", "az"].iter().enumerate() {
                    finite(c, a[i][k])?;
                }
            }
            if let Some(a) = &self.omega_dot {
                for (k, c) in ["dwx", "dwy", "dwz"].iter().enumerate() {
                    finite(c, a[i][k])?;
                }
            }
            if let Some(a) = &self.rotor_speeds {
                for (k, c) in ["w1", "w2", "w3", "w4"].iter().enumerate() {
                    finite(c, a[i][k])?;
                }
            }
            for (name, v) in &self.extra {
                finite(name, v[i])?;
            }
            if i > 0 && self.t[i] <= self.t[i - 1] {
                return Err(LogError::NonIncreasingTime {
                    line,
                    t: self.t[i],
                    previous: self.t[i - 1],
                });
            }
            let q = self.attitude[i];
            let norm = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]).sqrt();
            if (norm - 1.0).abs() > QUATERNION_NORM_TOLERANCE {
                return Err(LogError::QuaternionNorm {
                    line,
                    norm,
                    tolerance: QUATERNION_NORM_TOLERANCE,
                });
            }
        }
        if n < MIN_ROWS {
            return Err(LogError::TooShort {
                rows: n,
                needed: MIN_ROWS,
            });
        }
        Ok(())
    }

    /// Reads and validates a CSV flight log from a file.
    ///
    /// # Errors
    /// [`LogError::Io`] if the file cannot be opened or is a directory, otherwise the error of
    /// [`FlightLog::from_csv_reader`] wrapped in [`LogError::InFile`] (so that the message
    /// names the file as well as the line and column).
    pub fn from_csv_path(path: impl AsRef<Path>) -> Result<Self, LogError> {
        Self::read_csv_path(path).map(|read| read.log)
    }

    /// [`FlightLog::from_csv_path`], with the CSV line each sample was read from and the
    /// columns not read: a report can then name the line a user opens, and say why a column
    /// is missing.
    ///
    /// # Errors
    /// As [`FlightLog::from_csv_path`].
    pub fn read_csv_path(path: impl AsRef<Path>) -> Result<ReadLog, LogError> {
        let path = path.as_ref();
        let file = open_log_file(path)?;
        let name = path.display().to_string();
        let mut read = Self::read_csv(std::io::BufReader::new(file))
            .map_err(|e| LogError::in_file(name.clone(), e))?;
        for c in &mut read.unread_columns {
            c.stream.clone_from(&name);
        }
        Ok(read)
    }

    /// Reads and validates a CSV flight log (the [format](self)): one header row, then one row per
    /// sample. Unknown columns are kept in [`FlightLog::extra`]. A log with the rotor speeds
    /// `w1..w4` may omit the wrench `fx..tz`: it is then read with an empty
    /// [`FlightLog::wrench`], to be computed with a vehicle
    /// ([`FlightLog::compute_wrench_from_rotor_speeds`]).
    ///
    /// # Errors
    /// A [`LogError`] naming the line and column of the first problem.
    pub fn from_csv_reader<R: Read>(reader: R) -> Result<Self, LogError> {
        Self::read_csv(reader).map(|read| read.log)
    }

    /// [`FlightLog::from_csv_reader`], with the CSV line of each sample and the columns not
    /// read (their `stream` is empty).
    ///
    /// # Errors
    /// As [`FlightLog::from_csv_reader`].
    pub fn read_csv<R: Read>(reader: R) -> Result<ReadLog, LogError> {
        let mut rows = NumericRows::new(reader)?;
        let header = rows.header.clone();
        let idx = |name: &str| header.iter().position(|h| h == name);
        for c in &REQUIRED_COLUMNS[..MOTION_COLUMN_COUNT] {
            if idx(c).is_none() {
                return Err(LogError::MissingColumn {
                    column: c.to_string(),
                });
            }
        }
        // Optional groups are all-or-nothing.
        let group = |names: &[&str]| -> Result<Option<Vec<usize>>, LogError> {
            let found: Vec<Option<usize>> = names.iter().map(|n| idx(n)).collect();
            if found.iter().all(Option::is_none) {
                return Ok(None);
            }
            if let Some(k) = found.iter().position(Option::is_none) {
                return Err(LogError::MissingColumn {
                    column: names[k].to_string(),
                });
            }
            Ok(Some(found.into_iter().flatten().collect()))
        };
        let acc_cols = group(&ACCEL_COLUMNS)?;
        let dw_cols = group(&OMEGA_DOT_COLUMNS)?;
        let rot_cols = group(&ROTOR_SPEED_COLUMNS)?;
        // The wrench: all six columns, or none with the rotor speeds present.
        let wrench_cols = if rot_cols.is_some() {
            group(&WRENCH_COLUMNS)?
        } else if WRENCH_COLUMNS.iter().all(|c| idx(c).is_none()) {
            return Err(LogError::MissingWrench {
                has_rotor_speeds: false,
            });
        } else {
            group(&WRENCH_COLUMNS)?
        };
        let req: Vec<usize> = REQUIRED_COLUMNS[..MOTION_COLUMN_COUNT]
            .iter()
            .filter_map(|c| idx(c))
            .collect();
        let extra_cols: Vec<usize> = (0..header.len())
            .filter(|j| {
                let h = header[*j].as_str();
                !REQUIRED_COLUMNS.contains(&h) && !OPTIONAL_COLUMNS.contains(&h)
            })
            .collect();
        let mut log = FlightLog {
            accel: acc_cols.as_ref().map(|_| Vec::new()),
            omega_dot: dw_cols.as_ref().map(|_| Vec::new()),
            rotor_speeds: rot_cols.as_ref().map(|_| Vec::new()),
            extra: extra_cols
                .iter()
                .map(|&j| (header[j].clone(), Vec::new()))
                .collect(),
            ..FlightLog::default()
        };
        // A column outside the format is read leniently: one cell that is not a finite number
        // leaves it unread, not the file refused.
        rows.set_lenient((0..header.len()).map(|j| extra_cols.contains(&j)).collect());
        let mut values = vec![0.0; header.len()];
        let mut lines = Vec::new();
        while let Some(line) = rows.next_into(&mut values)? {
            lines.push(line);
            let v = |k: usize| values[req[k]];
            let t = v(0);
            if let Some(&prev) = log.t.last()
                && t <= prev
            {
                return Err(LogError::NonIncreasingTime {
                    line,
                    t,
                    previous: prev,
                });
            }
            let q = [v(7), v(8), v(9), v(10)];
            let norm = q.iter().map(|x| x * x).sum::<f64>().sqrt();
            if (norm - 1.0).abs() > QUATERNION_NORM_TOLERANCE {
                return Err(LogError::QuaternionNorm {
                    line,
                    norm,
                    tolerance: QUATERNION_NORM_TOLERANCE,
                });
            }
            log.t.push(t);
            log.position.push([v(1), v(2), v(3)]);
            log.velocity.push([v(4), v(5), v(6)]);
            log.attitude.push(q);
            log.omega.push([v(11), v(12), v(13)]);
            if let Some(c) = &wrench_cols {
                log.wrench.push(std::array::from_fn(|k| values[c[k]]));
            }
            if let (Some(c), Some(a)) = (&acc_cols, &mut log.accel) {
                a.push([values[c[0]], values[c[1]], values[c[2]]]);
            }
            if let (Some(c), Some(a)) = (&dw_cols, &mut log.omega_dot) {
                a.push([values[c[0]], values[c[1]], values[c[2]]]);
            }
            if let (Some(c), Some(a)) = (&rot_cols, &mut log.rotor_speeds) {
                a.push([values[c[0]], values[c[1]], values[c[2]], values[c[3]]]);
            }
            for (k, &j) in extra_cols.iter().enumerate() {
                log.extra[k].1.push(values[j]);
            }
        }
        if log.len() < MIN_ROWS {
            return Err(LogError::TooShort {
                rows: log.len(),
                needed: MIN_ROWS,
            });
        }
        let mut unread_columns = Vec::new();
        let extra = std::mem::take(&mut log.extra);
        for ((name, values), &j) in extra.into_iter().zip(&extra_cols) {
            match rows.first_bad[j].take() {
                Some((line, value)) => unread_columns.push(crate::log_input::UnreadColumn {
                    stream: String::new(),
                    column: name,
                    line,
                    value,
                }),
                None => log.extra.push((name, values)),
            }
        }
        Ok(ReadLog {
            log,
            lines,
            unread_columns,
        })
    }

    /// Checks what writing needs: equal signal lengths and strictly increasing time (a log
    /// without a wrench must have rotor speeds).
    fn check_writable(&self) -> Result<(), LogError> {
        self.check_lengths()?;
        if let Some(i) = (1..self.t.len())
            .find(|&i| self.t[i].partial_cmp(&self.t[i - 1]) != Some(std::cmp::Ordering::Greater))
        {
            return Err(LogError::NonIncreasingTime {
                line: i + 2,
                t: self.t[i],
                previous: self.t[i - 1],
            });
        }
        Ok(())
    }

    /// Writes the log as CSV: a header, then one row per sample.
    ///
    /// The header lists the required columns, then the optional groups that are present, then
    /// the extra columns. A log that has rotor speeds and no wrench has no `fx..tz`.
    /// `t` is written in plain decimal. Every other value is in Rust's shortest round-trip
    /// scientific notation, so reading it back gives the same bits.
    ///
    /// # Errors
    /// [`LogError::LengthMismatch`] or [`LogError::NonIncreasingTime`] for a log that is not
    /// a log; [`LogError::Io`] on a write failure.
    pub fn write_csv<W: Write>(&self, writer: W) -> Result<(), LogError> {
        self.write_csv_named(writer, "<csv writer>")
    }

    /// [`FlightLog::write_csv`] to a file (parent directories are created).
    ///
    /// # Errors
    /// As [`FlightLog::write_csv`]; I/O errors name the file.
    pub fn write_csv_path(&self, path: impl AsRef<Path>) -> Result<(), LogError> {
        self.check_writable()?;
        let (file, name) = create_file(path.as_ref())?;
        self.write_csv_named(file, &name)
    }

    fn write_csv_named<W: Write>(&self, writer: W, name: &str) -> Result<(), LogError> {
        self.check_writable()?;
        let io = |message: String| LogError::Io {
            path: name.to_string(),
            message,
        };
        let mut w = csv::Writer::from_writer(writer);
        let with_wrench = !self.wrench.is_empty() || self.rotor_speeds.is_none();
        let required = if with_wrench {
            &REQUIRED_COLUMNS[..]
        } else {
            &REQUIRED_COLUMNS[..MOTION_COLUMN_COUNT]
        };
        let mut header: Vec<String> = required.iter().map(|s| s.to_string()).collect();
        if self.accel.is_some() {
            header.extend(ACCEL_COLUMNS.map(String::from));
        }
        if self.omega_dot.is_some() {
            header.extend(OMEGA_DOT_COLUMNS.map(String::from));
        }
        if self.rotor_speeds.is_some() {
            header.extend(ROTOR_SPEED_COLUMNS.map(String::from));
        }
        header.extend(self.extra.iter().map(|(n, _)| n.clone()));
        w.write_record(&header).map_err(|e| io(e.to_string()))?;
        let mut row: Vec<String> = Vec::with_capacity(header.len());
        for i in 0..self.len() {
            row.clear();
            row.push(format!("{}", self.t[i]));
            let mut put = |x: f64| row.push(format!("{x:e}"));
            self.position[i].iter().for_each(|x| put(*x));
            self.velocity[i].iter().for_each(|x| put(*x));
            self.attitude[i].iter().for_each(|x| put(*x));
            self.omega[i].iter().for_each(|x| put(*x));
            if with_wrench {
                self.wrench[i].iter().for_each(|x| put(*x));
            }
            if let Some(a) = &self.accel {
                a[i].iter().for_each(|x| put(*x));
            }
            if let Some(a) = &self.omega_dot {
                a[i].iter().for_each(|x| put(*x));
            }
            if let Some(a) = &self.rotor_speeds {
                a[i].iter().for_each(|x| put(*x));
            }
            for (_, v) in &self.extra {
                put(v[i]);
            }
            w.write_record(&row).map_err(|e| io(e.to_string()))?;
        }
        w.flush().map_err(|e| io(e.to_string()))?;
        Ok(())
    }
}

/// A problem with a flight log: every variant names where it is (CSV line, 1-based, the header
/// being line 1; and the column) so that the user can fix the file.
#[derive(Debug, Error, Clone, PartialEq)]
#[non_exhaustive]
pub enum LogError {
    /// A required column (the [format](self)) is absent from the header.
    #[error("line 1: missing required column `{column}`")]
    MissingColumn {
        /// The column's name.
        column: String,
    },
    /// The same column name appears twice in the header.
    #[error("line 1: duplicate column `{column}` (columns {first} and {second}, 1-based)")]
    DuplicateColumn {
        /// The column's name.
        column: String,
        /// 1-based position of its first occurrence.
        first: usize,
        /// 1-based position of its second occurrence.
        second: usize,
    },
    /// A cell that is not a number.
    #[error("line {line}, column `{column}`: `{value}` is not a number")]
    NotANumber {
        /// CSV line (1-based; the header is line 1).
        line: usize,
        /// Column name.
        column: String,
        /// The offending text.
        value: String,
    },
    /// A cell that is NaN or infinite.
    #[error("line {line}, column `{column}`: non-finite value {value}")]
    NonFinite {
        /// CSV line (1-based; the header is line 1).
        line: usize,
        /// Column name.
        column: String,
        /// The value read.
        value: f64,
    },
    /// Time does not strictly increase.
    #[error("line {line}, column `t`: time {t} s does not increase (previous sample {previous} s)")]
    NonIncreasingTime {
        /// CSV line (1-based; the header is line 1).
        line: usize,
        /// The time on this line \[s\].
        t: f64,
        /// The previous sample's time \[s\].
        previous: f64,
    },
    /// The attitude quaternion's norm is far from one.
    #[error(
        "line {line}, columns `qw,qx,qy,qz`: quaternion norm {norm:.4} is not 1 (tolerance {tolerance}); \
         if the log's quaternions are merely not normalised, read it through a column mapping \
         with `[frames] normalize_quaternion = true` (docs/COLUMN_MAPPING.md)"
    )]
    QuaternionNorm {
        /// CSV line (1-based; the header is line 1).
        line: usize,
        /// The norm found.
        norm: f64,
        /// Allowed deviation `|‖q‖ − 1|`.
        tolerance: f64,
    },
    /// A resampling step that is not positive and finite, or far too small for the log.
    #[error(
        "resampling step {dt} s: must be positive and finite, and give at most {max} rows over the log's {span} s",
        max = MAX_RESAMPLED_ROWS
    )]
    InvalidResampleStep {
        /// The step asked for \[s\].
        dt: f64,
        /// The log's time span \[s\].
        span: f64,
    },
    /// The file has no content at all (not even a header).
    #[error("empty file: no header and no rows")]
    EmptyFile,
    /// A row with the wrong number of fields, or a CSV syntax error.
    #[error("line {line}: malformed CSV row: {message}")]
    Malformed {
        /// CSV line (1-based; the header is line 1).
        line: usize,
        /// What the CSV reader reported.
        message: String,
    },
    /// Too few samples to fit the model.
    #[error("log too short to fit: {rows} rows, at least {needed} needed")]
    TooShort {
        /// Rows in the log.
        rows: usize,
        /// Rows needed.
        needed: usize,
    },
    /// In-memory log whose signals have different lengths.
    #[error("signal `{column}` has {got} samples, expected {expected}")]
    LengthMismatch {
        /// Signal name.
        column: String,
        /// Its length.
        got: usize,
        /// The length of `t`.
        expected: usize,
    },
    /// The log has no body wrench `fx..tz`, and nothing to compute it from.
    #[error("{}", missing_wrench_message(*has_rotor_speeds))]
    MissingWrench {
        /// `true` if the log has the rotor speeds `w1..w4` (a vehicle description would turn
        /// them into the wrench).
        has_rotor_speeds: bool,
    },
    /// A rotor speed that is negative or far above the vehicle's largest speed.
    #[error(
        "line {line}, column `{column}`: rotor speed {value} rad/s outside [0, {max}] (rotor speeds are in rad/s; rpm must be converted)"
    )]
    RotorSpeedOutOfRange {
        /// CSV line (1-based; the header is line 1).
        line: usize,
        /// Column name (`w1..w4`).
        column: String,
        /// The value \[rad/s\].
        value: f64,
        /// The largest accepted speed \[rad/s\].
        max: f64,
    },
    /// A problem in a log file: the file's name and the problem (which names line and
    /// column).
    #[error("{path}: {source}")]
    InFile {
        /// The file.
        path: String,
        /// The problem.
        #[source]
        source: Box<LogError>,
    },
    /// A file could not be read or written.
    #[error("{path}: {message}")]
    Io {
        /// The path.
        path: String,
        /// The OS error.
        message: String,
    },
}

impl LogError {
    /// `source` in the file `path` ([`LogError::InFile`]).
    pub fn in_file(path: impl Into<String>, source: LogError) -> Self {
        LogError::InFile {
            path: path.into(),
            source: Box::new(source),
        }
    }

    /// The 1-based CSV line the error points at (the header is line 1), if any.
    pub fn line(&self) -> Option<usize> {
        match self {
            LogError::MissingColumn { .. }
            | LogError::EmptyFile
            | LogError::DuplicateColumn { .. }
            | LogError::MissingWrench { .. } => Some(1),
            LogError::NotANumber { line, .. }
            | LogError::NonFinite { line, .. }
            | LogError::NonIncreasingTime { line, .. }
            | LogError::QuaternionNorm { line, .. }
            | LogError::RotorSpeedOutOfRange { line, .. }
            | LogError::Malformed { line, .. } => Some(*line),
            LogError::InFile { source, .. } => source.line(),
            _ => None,
        }
    }

    /// The column the error points at, if any.
    pub fn column(&self) -> Option<&str> {
        match self {
            LogError::MissingColumn { column }
            | LogError::DuplicateColumn { column, .. }
            | LogError::NotANumber { column, .. }
            | LogError::NonFinite { column, .. }
            | LogError::RotorSpeedOutOfRange { column, .. }
            | LogError::LengthMismatch { column, .. } => Some(column),
            LogError::NonIncreasingTime { .. } => Some("t"),
            LogError::QuaternionNorm { .. } => Some("qw"),
            LogError::InFile { source, .. } => source.column(),
            _ => None,
        }
    }

    /// The file the error points at, if known.
    pub fn file(&self) -> Option<&str> {
        match self {
            LogError::InFile { path, .. } | LogError::Io { path, .. } => Some(path),
            _ => None,
        }
    }
}

/// The message of [`LogError::MissingWrench`]: the missing quantity and the columns that could
/// provide it.
fn missing_wrench_message(has_rotor_speeds: bool) -> String {
    if has_rotor_speeds {
        "line 1: the body wrench `fx,fy,fz,tx,ty,tz` is missing; the log has the rotor speeds \
         `w1,w2,w3,w4`, which give it with a vehicle description (`tagk diagnose --vehicle \
         NAME|FILE`, e.g. `--vehicle crazyflie-2.1`)"
            .to_string()
    } else {
        "line 1: the body wrench is missing: the log needs the columns `fx,fy,fz,tx,ty,tz` \
         [N, N m], or the rotor speeds `w1,w2,w3,w4` [rad/s] with a vehicle description \
         (`tagk diagnose --vehicle NAME|FILE`)"
            .to_string()
    }
}

/// Opens a log file for reading: [`LogError::Io`] naming the path if it cannot be opened or
/// is a directory (which opens, but does not read).
pub(crate) fn open_log_file(path: &Path) -> Result<std::fs::File, LogError> {
    let io = |message: String| LogError::Io {
        path: path.display().to_string(),
        message,
    };
    let file = std::fs::File::open(path).map_err(|e| io(e.to_string()))?;
    if file.metadata().is_ok_and(|m| m.is_dir()) {
        return Err(io("is a directory, not a CSV file".into()));
    }
    Ok(file)
}

fn push_opt<T: Copy>(v: &mut Option<Vec<T>>, x: Option<T>, first: bool) {
    match (first, x) {
        (true, Some(x)) => *v = Some(vec![x]),
        (true, None) => *v = None,
        (false, Some(x)) => {
            if let Some(v) = v {
                v.push(x);
            }
        }
        (false, None) => *v = None,
    }
}

/// A CSV table of numbers read row by row with the checks every log reader makes: a header
/// without duplicate names, as many fields per row as the header has, every row valid UTF-8
/// and every cell a finite number. Errors name the 1-based line (the header is line 1) and the
/// column.
///
/// Rows are read as raw bytes into one reused record. Only the header is trimmed by the CSV
/// reader. A cell is checked for UTF-8, trimmed of (Unicode) white space and parsed in one
/// pass, so a row costs no allocation. The results and errors are those of reading each row as
/// a trimmed `csv::StringRecord` (`csv::Trim::All`), which this reader replaced.
pub(crate) struct NumericRows<R: Read> {
    rdr: csv::Reader<LineCounter<R>>,
    record: csv::ByteRecord,
    /// The column names, in file order.
    pub(crate) header: Vec<String>,
    line: usize,
    /// Columns read leniently ([`NumericRows::set_lenient`]); empty: every column is strict.
    lenient: Vec<bool>,
    /// For each lenient column, its first cell that is not a finite number: line and text.
    pub(crate) first_bad: Vec<Option<(usize, String)>>,
}

/// A reader that notes where its input's lines break, so that a row's 1-based line is
/// counted from its byte offset. The CSV reader's own line count misses the blank lines and
/// counts a CRLF file one line short (and a CR-only file not at all). A line ends at `\n`,
/// or at a `\r` not followed by `\n`. The CSV reader's offset of a row is where the line
/// ends before it begin (the `\n` of a CRLF, blank lines). The row's line is the one after
/// them. Only the line ends not yet passed by the rows read are kept (at most the CSV
/// reader's buffer ahead).
pub(crate) struct LineCounter<R> {
    inner: R,
    /// Byte offset of the next byte read.
    offset: u64,
    /// The `\r` and `\n` bytes read but not yet passed: offset, and whether it ends a line.
    ends: std::collections::VecDeque<(u64, bool)>,
    /// Line ends already passed.
    passed: usize,
    /// Whether the last byte read was a `\r` (still in `ends`, as not ending a line yet).
    after_cr: bool,
}

impl<R: Read> LineCounter<R> {
    fn new(inner: R) -> Self {
        Self {
            inner,
            offset: 0,
            ends: std::collections::VecDeque::new(),
            passed: 0,
            after_cr: false,
        }
    }

    /// The 1-based line of the row the CSV reader places at byte `offset` (offsets asked for
    /// never decrease): the line ends before it, and those of the run of `\r`/`\n` bytes
    /// that starts at it.
    fn line_of(&mut self, offset: u64) -> usize {
        let mut next = offset;
        while let Some(&(at, ends)) = self.ends.front() {
            if at < offset || at == next {
                if at == next {
                    next += 1;
                }
                self.passed += usize::from(ends);
                self.ends.pop_front();
            } else {
                break;
            }
        }
        self.passed + 1
    }

    /// Marks the `\r` read last as a line end of its own (the next byte is not `\n`).
    fn close_cr(&mut self) {
        if std::mem::take(&mut self.after_cr)
            && let Some(last) = self.ends.back_mut()
        {
            last.1 = true;
        }
    }
}

impl<R: Read> Read for LineCounter<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.inner.read(buf)?;
        if n == 0 {
            self.close_cr();
            return Ok(0);
        }
        // Only the `\r` and `\n` bytes are looked at (found by `memchr`); any other byte
        // after a `\r` makes it a line end of its own.
        let mut next = 0;
        for k in memchr::memchr2_iter(b'\n', b'\r', &buf[..n]) {
            if k > next {
                self.close_cr();
            }
            let at = self.offset + k as u64;
            if buf[k] == b'\n' {
                // A CRLF is one line end, at its `\n`.
                self.after_cr = false;
                self.ends.push_back((at, true));
            } else {
                self.close_cr();
                self.ends.push_back((at, false));
                self.after_cr = true;
            }
            next = k + 1;
        }
        if n > next {
            self.close_cr();
        }
        self.offset += n as u64;
        Ok(n)
    }
}

/// A CSV reader's error message with its own line count (`line: 2,` or `line 2,`) replaced
/// by the right one.
fn with_line(message: String, csv_line: u64, line: usize) -> String {
    message
        .replacen(&format!("line: {csv_line},"), &format!("line: {line},"), 1)
        .replacen(&format!("line {csv_line},"), &format!("line {line},"), 1)
}

/// The CSV reader's input buffer \[bytes\]: large enough that a long log is read in few system
/// calls, small enough not to matter for memory.
const CSV_BUFFER_BYTES: usize = 1 << 16;

impl<R: Read> NumericRows<R> {
    /// Reads and checks the header.
    pub(crate) fn new(reader: R) -> Result<Self, LogError> {
        let mut rdr = csv::ReaderBuilder::new()
            .has_headers(true)
            .trim(csv::Trim::Headers)
            .buffer_capacity(CSV_BUFFER_BYTES)
            .from_reader(LineCounter::new(reader));
        let header: Vec<String> = rdr
            .headers()
            .map_err(|e| LogError::Malformed {
                line: 1,
                message: e.to_string(),
            })?
            .iter()
            .map(str::to_string)
            .collect();
        if header.iter().all(String::is_empty) && rdr.is_done() {
            return Err(LogError::EmptyFile);
        }
        for (j, name) in header.iter().enumerate() {
            if let Some(k) = header[..j].iter().position(|h| h == name) {
                return Err(LogError::DuplicateColumn {
                    column: name.clone(),
                    first: k + 1,
                    second: j + 1,
                });
            }
        }
        Ok(Self {
            rdr,
            record: csv::ByteRecord::new(),
            header,
            line: 1,
            lenient: Vec::new(),
            first_bad: Vec::new(),
        })
    }

    /// Reads the columns flagged `true` leniently: a cell that is not a finite number (text,
    /// a boolean, an empty cell) is read as NaN instead of being an error, and the column's
    /// first such cell is kept in `first_bad`. The other columns keep every check.
    pub(crate) fn set_lenient(&mut self, lenient: Vec<bool>) {
        self.first_bad = vec![None; lenient.len()];
        self.lenient = lenient;
    }

    /// Reads the next row into `values` (one per header column) and returns its line, or
    /// `None` at the end of the file.
    pub(crate) fn next_into(&mut self, values: &mut [f64]) -> Result<Option<usize>, LogError> {
        match self.rdr.read_byte_record(&mut self.record) {
            Ok(false) => return Ok(None),
            Ok(true) => {}
            Err(e) => {
                let (line, message) = match e.position() {
                    Some(p) => {
                        let line = self.rdr.get_mut().line_of(p.byte());
                        (line, with_line(e.to_string(), p.line(), line))
                    }
                    None => (self.line + 1, e.to_string()),
                };
                return Err(LogError::Malformed { line, message });
            }
        }
        let line = match self.record.position() {
            Some(p) => self.rdr.get_mut().line_of(p.byte()),
            None => self.line + 1,
        };
        self.line = line;
        // A row that is not all ASCII is checked for UTF-8 before any cell is parsed, as the
        // string reader did (its error comes before a non-number in an earlier column).
        if !self.record.as_slice().is_ascii()
            && let Some(e) = utf8_error(&self.record, line)
        {
            return Err(e);
        }
        let header = &self.header;
        if self.record.len() != header.len() {
            return Err(LogError::Malformed {
                line,
                message: format!("{} fields, header has {}", self.record.len(), header.len()),
            });
        }
        // Every cell is valid UTF-8, so the row is, and each cell's range in it falls on
        // character boundaries: one check of the row instead of one per cell.
        let row = std::str::from_utf8(self.record.as_slice()).unwrap_or_default();
        for (j, value) in values.iter_mut().enumerate().take(header.len()) {
            let text = self.record.range(j).and_then(|r| row.get(r)).map(trim_cell);
            if self.lenient.get(j).copied().unwrap_or(false) {
                *value = match text.map(str::parse::<f64>) {
                    Some(Ok(x)) if x.is_finite() => x,
                    _ => {
                        if self.first_bad[j].is_none() {
                            self.first_bad[j] = Some((line, text.unwrap_or_default().to_string()));
                        }
                        f64::NAN
                    }
                };
                continue;
            }
            let Some(Ok(x)) = text.map(str::parse::<f64>) else {
                return Err(LogError::NotANumber {
                    line,
                    column: header[j].clone(),
                    value: text.map_or_else(
                        || {
                            let cell = self.record.get(j).unwrap_or_default();
                            String::from_utf8_lossy(cell).trim().to_string()
                        },
                        str::to_string,
                    ),
                });
            };
            if !x.is_finite() {
                return Err(LogError::NonFinite {
                    line,
                    column: header[j].clone(),
                    value: x,
                });
            }
            *value = x;
        }
        Ok(Some(line))
    }
}

/// A cell without its leading and trailing white space: [`str::trim`], skipped when the cell
/// begins and ends with a visible ASCII character (the common case), which `str::trim` would
/// keep.
fn trim_cell(cell: &str) -> &str {
    match (cell.as_bytes().first(), cell.as_bytes().last()) {
        (Some(&first), Some(&last))
            if (0x21..0x7f).contains(&first) && (0x21..0x7f).contains(&last) =>
        {
            cell
        }
        _ => cell.trim(),
    }
}

/// The error of a row that is not valid UTF-8, worded as the CSV reader words it when it reads
/// the row as a trimmed `csv::StringRecord`. There the field's index and the byte up to which
/// it is valid are counted after ASCII trimming. `None` if the row is valid UTF-8.
fn utf8_error(record: &csv::ByteRecord, line: usize) -> Option<LogError> {
    let mut trimmed = record.clone();
    trimmed.trim();
    let err = csv::StringRecord::from_byte_record(trimmed).err()?;
    let err = err.utf8_error();
    let pos = record.position()?;
    Some(LogError::Malformed {
        line,
        message: format!(
            "CSV parse error: record {} (line {}, field: {}, byte: {}): {}",
            pos.record(),
            line,
            err.field(),
            pos.byte(),
            err
        ),
    })
}

/// Creates `path` for writing (and its parent directories), buffered, with its display name for
/// error messages. An I/O error names the file.
pub(crate) fn create_file(
    path: &Path,
) -> Result<(std::io::BufWriter<std::fs::File>, String), LogError> {
    let name = path.display().to_string();
    let io = |e: std::io::Error| LogError::Io {
        path: name.clone(),
        message: e.to_string(),
    };
    if let Some(dir) = path.parent()
        && !dir.as_os_str().is_empty()
    {
        std::fs::create_dir_all(dir).map_err(io)?;
    }
    let file = std::fs::File::create(path).map_err(io)?;
    Ok((std::io::BufWriter::new(file), name))
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// What a reader makes of a table: the header and each row's line and value bits, or the
    /// first error (its `Debug` form: every field, so line, column, value and wording).
    type Outcome = Result<(Vec<String>, Vec<(usize, Vec<u64>)>), String>;

    /// The reader this module had before rows were read as bytes, kept as the independent
    /// reference: every row a `csv::StringRecord` trimmed by the CSV crate (`Trim::All`).
    fn reference(input: &[u8]) -> Outcome {
        let err = |e: LogError| format!("{e:?}");
        let mut rdr = csv::ReaderBuilder::new()
            .has_headers(true)
            .trim(csv::Trim::All)
            .from_reader(input);
        let header: Vec<String> = rdr
            .headers()
            .map_err(|e| {
                err(LogError::Malformed {
                    line: 1,
                    message: e.to_string(),
                })
            })?
            .iter()
            .map(str::to_string)
            .collect();
        if header.iter().all(String::is_empty) && rdr.is_done() {
            return Err(err(LogError::EmptyFile));
        }
        for (j, name) in header.iter().enumerate() {
            if let Some(k) = header[..j].iter().position(|h| h == name) {
                return Err(err(LogError::DuplicateColumn {
                    column: name.clone(),
                    first: k + 1,
                    second: j + 1,
                }));
            }
        }
        let mut record = csv::StringRecord::new();
        let mut rows = Vec::new();
        let mut last = 1;
        loop {
            match rdr.read_record(&mut record) {
                Ok(false) => return Ok((header, rows)),
                Ok(true) => {}
                Err(e) => {
                    let (line, message) = match e.position() {
                        Some(p) => {
                            let line = line_at(input, p.byte());
                            (line, with_line(e.to_string(), p.line(), line))
                        }
                        None => (last + 1, e.to_string()),
                    };
                    return Err(err(LogError::Malformed { line, message }));
                }
            }
            let line = record
                .position()
                .map_or(last + 1, |p| line_at(input, p.byte()));
            last = line;
            if record.len() != header.len() {
                return Err(err(LogError::Malformed {
                    line,
                    message: format!("{} fields, header has {}", record.len(), header.len()),
                }));
            }
            let mut bits = Vec::new();
            for (j, field) in record.iter().enumerate() {
                let x: f64 = field.parse().map_err(|_| {
                    err(LogError::NotANumber {
                        line,
                        column: header[j].clone(),
                        value: field.to_string(),
                    })
                })?;
                if !x.is_finite() {
                    return Err(err(LogError::NonFinite {
                        line,
                        column: header[j].clone(),
                        value: x,
                    }));
                }
                bits.push(x.to_bits());
            }
            rows.push((line, bits));
        }
    }

    /// The 1-based line of the row the CSV reader places at byte `offset` of `input`, counted
    /// directly: one more than the `\n` and the `\r` not followed by `\n` before the row's
    /// first byte that is neither.
    fn line_at(input: &[u8], offset: u64) -> usize {
        // The row itself starts after the line ends at its offset.
        let mut start = (offset as usize).min(input.len());
        while matches!(input.get(start), Some(b'\r' | b'\n')) {
            start += 1;
        }
        let breaks = input[..start]
            .iter()
            .enumerate()
            .filter(|&(k, &b)| b == b'\n' || (b == b'\r' && input.get(k + 1) != Some(&b'\n')))
            .count();
        breaks + 1
    }

    /// The same table through [`NumericRows`].
    fn numeric_rows(input: &[u8]) -> Outcome {
        let err = |e: LogError| format!("{e:?}");
        let mut rows = NumericRows::new(input).map_err(err)?;
        let mut values = vec![0.0; rows.header.len()];
        let mut out = Vec::new();
        while let Some(line) = rows.next_into(&mut values).map_err(err)? {
            out.push((line, values.iter().map(|x| x.to_bits()).collect()));
        }
        Ok((rows.header.clone(), out))
    }

    #[test]
    fn rows_read_as_bytes_match_the_string_reader() {
        let cases: &[&[u8]] = &[
            b"a,b\n1,2\n3,4\n",
            b" a , b \n 1 ,\t2\t\n",
            // Unicode white space: trimmed by `str::trim`, not by ASCII trimming.
            "a,b\n\u{a0}1,2\u{2003}\n\u{b}3\u{c},4\u{85}\n".as_bytes(),
            b"a,b\n\"1\",\" 2 \"\n",
            b"a,b\n1,x\n",
            b"a,b\n1,\n",
            b"a,b\n1,nan\n",
            b"a,b\n1,-inf\n",
            b"a,b\n1,1e400\n",
            b"a,b\n1,2,3\n",
            b"a,b\n1\n",
            b"a,a\n1,2\n",
            b"",
            b"a,b\n",
            b"a,b\r\n1,2\r\n\r\n3,4",
            b"a,b\r\n1,2\r\n\r\n3,x\r\n",
            b"a,b\n1,2\n\n\n3,x\n",
            b"a,b\r1,2\r\r3,x\r",
            b"a,b\r\n\"1\r\n\",2\r\n3,4,5\r\n",
            b"a,b\n\n1,2\n\n3,\xff\n",
            // Not UTF-8: in a later cell than a non-number, after white space, split by a
            // delimiter, in the header, in an otherwise valid row.
            b"a,b\nx,\xff\n",
            b"a,b\n1,  \xff\n",
            b"a,b\n1\xc3,\xa92\n",
            b"a,\xffb\n1,2\n",
            b"a,b\n1,2\n\xe9,4\n",
            "a,b\n1,\u{e9}\n".as_bytes(),
        ];
        for case in cases {
            assert_eq!(
                numeric_rows(case),
                reference(case),
                "input {:?}",
                String::from_utf8_lossy(case)
            );
        }
    }

    /// A bad cell is reported on its own line of the file, whatever came before it: CRLF line
    /// ends, blank lines, a quoted field that spans two lines.
    #[test]
    fn a_bad_cell_names_its_line_after_crlf_blank_lines_and_quoted_newlines() {
        let cases: &[(&[u8], usize)] = &[
            (b"a,b\n1,2\n3,x\n", 3),
            (b"a,b\r\n1,2\r\n3,x\r\n", 3),
            (b"a,b\n1,2\n\n3,x\n", 4),
            (b"a,b\r\n1,2\r\n\r\n\r\n3,x\r\n", 5),
            (b"a,b\n\"1\",\"2\"\n\"3\",\"x\"\n", 3),
            (b"a,\"b\nc\"\n1,2\n3,x\n", 4),
            (b"a,b\n\"1\n\",2\n3,x\n", 4),
            (b"a,b\r\n\"1\r\n\",2\r\n\r\n3,x\r\n", 5),
            (b"a,b\r1,2\r\r3,x\r", 4),
        ];
        for (input, line) in cases {
            let err = numeric_rows(input).unwrap_err();
            let expected = format!(
                "{:?}",
                LogError::NotANumber {
                    line: *line,
                    column: "b".into(),
                    value: "x".into(),
                }
            );
            let expected = if input.starts_with(b"a,\"b\nc") {
                expected.replace("column: \"b\"", "column: \"b\\nc\"")
            } else {
                expected
            };
            assert_eq!(err, expected, "input {:?}", String::from_utf8_lossy(input));
        }
    }

    /// Pieces of cells and separators that exercise trimming, quoting, UTF-8 and numbers.
    const PIECES: &[&[u8]] = &[
        b"1",
        b"-2.5e3",
        b"0.1",
        b"7e-5",
        b" ",
        b"\t",
        b"\x0b",
        b"\x0c",
        "\u{a0}".as_bytes(),
        "\u{2003}".as_bytes(),
        "\u{85}".as_bytes(),
        "\u{e9}".as_bytes(),
        b"\xff",
        b"\xc3",
        b"\xa9",
        b"\"",
        b",",
        b",",
        b",",
        b"\n",
        b"\r\n",
        b"nan",
        b"inf",
        b"1e400",
        b"x",
        b".",
        b"e",
    ];

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(2000))]
        #[test]
        fn any_bytes_read_as_the_string_reader_reads_them(
            header in prop::sample::select(vec!["a,b", " a ,b", "a,b,c", "a"]),
            body in prop::collection::vec(prop::sample::select(PIECES), 0..40),
        ) {
            let mut input = header.as_bytes().to_vec();
            input.push(b'\n');
            for piece in body {
                input.extend_from_slice(piece);
            }
            prop_assert_eq!(numeric_rows(&input), reference(&input));
        }
    }
}
