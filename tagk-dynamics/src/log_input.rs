//! Foreign flight logs in: a **column mapping** (renames, units, quaternion order, frames) and
//! **several streams** (one CSV file per topic, each with its own time column and rate). The
//! streams are merged onto one time base, giving a [`FlightLog`] in the project's format (see
//! [`crate::log`]).
//!
//! # The mapping file (TOML)
//!
//! ```toml
//! [columns]                 # project column = column name in the file (or a list of names:
//! t = ["timestamp", "time"] # the first one a stream has is used)
//! px = "pos.x"
//! q = ["q0", "q1", "q2", "q3"]   # the four quaternion columns, in file order
//! vbat = "Vbat"             # not a project column: an extra signal renamed (custom effects)
//! ignore = ["ax", "ay", "az"]    # file columns never read
//!
//! [units]                   # by project column, group or extra column; SI if absent
//! t = "ms"                  # s, ms, us (µs), ns
//! position = "mm"           # m, cm, mm   (groups: position velocity accel specific_force
//! omega = "deg/s"           #   omega omega_dot force torque rotor_speeds time)
//! rotor_speeds = { unit = "erpm", pole_pairs = 7 }   # or "rpm", "rad/s", "deg/s"
//! specific_force = "g"      # the accelerometer (sfx, sfy, sfz): m/s2, mm/s2, g
//! vbat = 0.001              # a number: multiply by this to get SI
//!
//! [frames]
//! world = "ned"             # enu (default: z up) or ned
//! body = "frd"              # flu (default: x forward, y left, z up) or frd
//! quaternion = "xyzw"       # order of the `q` list: wxyz (default) or xyzw
//! accel = "specific-force"  # ax..az hold p̈ (acceleration, default) or f_w = p̈ − g_w
//! normalize_quaternion = true   # divide the quaternions by their norm (default false)
//!
//! [streams]                 # optional
//! files = ["imu.csv", "mocap.csv"]   # relative to the mapping file, inside its folder
//! primary = "imu.csv"       # whose time stamps are the time base (default: the first file)
//! [streams."mocap.csv"]     # per-stream settings, by file name
//! offset = 0.02             # [s], added to this stream's time stamps
//! units = { t = "us" }      # overrides of [units] (and `columns = {...}` of [columns])
//! ```
//!
//! Units, with their factor to SI:
//! - time: `s` 1, `ms` 1e-3, `us`/`µs` 1e-6, `ns` 1e-9;
//! - length: `m` 1, `cm` 1e-2, `mm` 1e-3; speed: `m/s`, `cm/s`, `mm/s`;
//! - acceleration: `m/s2`, `mm/s2`, `g` (9.80665);
//! - angular rate: `rad/s` 1, `deg/s` π/180, `rpm` 2π/60;
//! - electrical rpm: `{ unit = "erpm", pole_pairs = N }`, factor `2π/60 / N`;
//! - angular acceleration: `rad/s2`, `deg/s2`;
//! - force: `N`, `mN`; torque: `Nm`, `mNm`, `Nmm`; extra columns also take `rad`, `deg`.
//!
//! A positive number is the factor itself. A unit that does not fit the column's quantity (`t = "rpm"`) is an error.
//!
//! # Strictness
//!
//! A mistake in the mapping is an error, never a silent fallback:
//!
//! - a `[columns]` key whose column no stream has ([`InputError::AbsentColumn`], naming the
//!   key and the nearest header name) — a mapped column is never replaced by the file's column
//!   of the project's name. One exception: a whole optional quantity (`ax..az`, `sfx..sfz`,
//!   `dwx..dwz`, `vx..vz`) mapped and in no stream (a mapping shared by logs with and
//!   without an accelerometer) is a warning of the [`MergeReport`];
//! - an unknown key in `[units]`, `[frames]`, `[columns]`, `[streams."NAME"]` or at the top
//!   level that is a typo of a known key (within one edit for keys of up to three characters,
//!   two for longer ones): `did you mean `omega`?`. Other `[columns]` keys rename an extra
//!   column, other `[units]` keys give an extra column's unit and must name a column;
//! - a `[streams."NAME"]` table or `primary` naming no stream file ([`InputError::UnknownStream`],
//!   with the nearest file name);
//! - a stream file of `[streams] files` outside the mapping file's folder (absolute, or a
//!   `..` that leaves it).
//!
//! Only the columns the mapping uses are parsed strictly (a bad cell names file, line and
//! column). Every other column is read leniently: text, booleans (`True`/`False`) and empty
//! cells are allowed there, and such a column is not offered as an extra signal (the
//! [`MergeReport`] lists it in `unread_columns`; a custom effect naming it says why).
//!
//! # Acceleration or specific force
//!
//! The project's `ax..az` are the world acceleration `p̈` (gravity removed). Some logs store the
//! **world-frame specific force** `f_w = p̈ − g_w` under those names (`+9.81` m/s² on z at
//! hover). Say so with `[frames] accel = "specific-force"`. They are then read as
//! `p̈ = f_w + g_w`, with the project's [`GRAVITY_WORLD`] `(0, 0, −9.81)`. Read as `p̈`, columns whose mean on z differs
//! from the velocity's `Δv_z / T` by more than `g/2` are refused
//! ([`InputError::AccelLooksLikeSpecificForce`]). `[columns] ignore = ["ax", "ay", "az"]`
//! leaves them out (the acceleration is then derived).
//!
//! # Quaternion norm
//!
//! With `[frames] normalize_quaternion = true` the quaternions are divided by their norm (a
//! norm farther than [`QUATERNION_RENORMALISE_LIMIT`] from 1 is still an error) and the
//! largest deviation is reported ([`MergeReport::quaternion_renormalised`], and a warning).
//! Without it a norm off by more than [`crate::log::QUATERNION_NORM_TOLERANCE`] is refused.
//!
//! # Frames (the exact rotations)
//!
//! The project's world frame is z up (ENU is taken as is); its body frame is x forward, y left,
//! z up (FLU). With `C_w` the rotation from the file's world frame to the project's and `C_b`
//! from the file's body frame to the project's:
//!
//! - NED → ENU: `C_w = [[0,1,0],[1,0,0],[0,0,−1]]` (x ← east = NED y, y ← north = NED x,
//!   z ← up = −down), a proper rotation by π about `(1,1,0)/√2`;
//! - FRD → FLU: `C_b = diag(1, −1, −1)`, a rotation by π about x.
//!
//! World vectors (position, velocity, acceleration) become `C_w v`; body vectors (angular
//! velocity and acceleration, force, torque, the accelerometer's specific force) become
//! `C_b v`; the attitude `R` (body → world) becomes `C_w R C_bᵀ`. Rotor speeds are scalars and
//! do not change.
//!
//! # The accelerometer
//!
//! The project columns `sfx, sfy, sfz` ([`SPECIFIC_FORCE_COLUMNS`], unit group
//! `specific_force`) are what an accelerometer at the body origin measures.
//! That is the **specific force** `f = Rᵀ (p̈ − g_w)`, in the body frame.
//! A vehicle at rest, level, reads `+1 g` along body up: `(0, 0, 9.81)` m/s² in FLU,
//! `(0, 0, −9.81)` in FRD.
//! They are not the wrench `fx..fz` (a force in N) nor the world acceleration `ax..az` (`p̈`,
//! gravity removed).
//! After the merge they become the log's world acceleration `p̈ = R f + g_w`
//! ([`world_acceleration`]). It uses the merged attitude `R` and the project's
//! `g_w = (0, 0, −9.81)` m/s². The regressor subtracts that `g_w` again, so it sees `f`
//! exactly, whatever the local gravity.
//! A stream with `ax..az` wins over the accelerometer.
//! The accelerometer is taken to sit at the body origin. A lever arm `r` adds
//! `ω̇ × r + ω × (ω × r)`, not removed here. Its bias and scale errors are not corrected.
//!
//! # Several streams
//!
//! The time base is the primary stream's time stamps (after its unit and offset). Each quantity
//! (position, velocity, attitude, angular velocity, wrench, rotor speeds, …) is taken from the
//! primary stream if it has it, else from the first other stream that has it. It is linearly
//! interpolated onto the time base. Quaternions use normalised linear interpolation, after
//! flipping the later sample onto the earlier one's hemisphere. A **gap** of a stream is a
//! step longer than [`GAP_FACTOR`] times its median step. A primary sample may fall inside a
//! gap of a stream it interpolates, or outside that stream's time range. It is then
//! **dropped** (never interpolated over) and counted in the [`MergeReport`]. Gaps of the
//! primary stream itself are reported too (the diagnosis splits the log at every gap,
//! [`FlightLog::sampling`]).
//!
//! Each stream's rate (one over its median step), span, offset, overlap with the time base and
//! the samples dropped because of it are in the [`MergeReport`] ([`StreamSummary`]). A stream
//! that provides a quantity is refused:
//!
//! - with fewer than [`MIN_STREAM_SAMPLES`] samples, or with a median step above
//!   [`MAX_STREAM_STEP`] (below 10 Hz) unless it provides only position and velocity
//!   ([`InputError::StreamTooSparse`]);
//! - when its time range overlaps less than [`MIN_STREAM_OVERLAP`] of the time base's span (an
//!   implausible offset, a wrong time unit, a stream of another flight)
//!   ([`InputError::StreamOverlap`]).
//!
//! More than [`DROPPED_WARNING_FRACTION`] of the time base dropped because of one stream is a
//! warning.
//!
//! Derived columns: a stream with position but no velocity gets its velocity by the
//! Savitzky–Golay derivative ([`crate::deriv`], half-width [`crate::deriv::DEFAULT_HALF_WIDTH`])
//! on its own time base before the merge. The world acceleration comes from the accelerometer
//! when a stream has one (above). Acceleration (without an accelerometer) and angular
//! acceleration, when absent, are derived by the diagnosis (see [`FlightLog::accel`]). A log
//! without the wrench `fx..tz` but with rotor speeds `w1..w4` needs a
//! [vehicle](crate::vehicle): pass it as [`ReadOptions::vehicle`] (the wrench is then computed
//! after the merge, on the time base).

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use nalgebra::{Matrix3, Rotation3, UnitQuaternion, Vector3};
use thiserror::Error;

use crate::deriv::{DEFAULT_HALF_WIDTH, savitzky_golay_derivative3};
use crate::log::{FlightLog, LogError, NumericRows};
use crate::rigid_body::GRAVITY_WORLD;
use crate::vehicle::Vehicle;

pub use crate::log::GAP_FACTOR;
use crate::log::{Sampling, median_step};

/// The project columns of the accelerometer: the specific force `f = Rᵀ (p̈ − g_w)` of the
/// body origin, body frame \[m/s²\] (module docs, "The accelerometer"). Mapping-only: the
/// native format stores the world acceleration `ax..az` instead.
pub const SPECIFIC_FORCE_COLUMNS: [&str; 3] = ["sfx", "sfy", "sfz"];

/// The world frame a log's world vectors and attitude are expressed in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum WorldFrame {
    /// East–north–up (z up): the project's frame, taken as is.
    #[default]
    Enu,
    /// North–east–down.
    Ned,
}

/// The body frame a log's body vectors and attitude are expressed in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum BodyFrame {
    /// x forward, y left, z up: the project's frame.
    #[default]
    Flu,
    /// x forward, y right, z down.
    Frd,
}

/// The order of the four quaternion columns listed with `q = [...]`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum QuaternionOrder {
    /// Scalar first `(w, x, y, z)`: the project's order.
    #[default]
    Wxyz,
    /// Scalar last `(x, y, z, w)`.
    Xyzw,
}

impl WorldFrame {
    /// The rotation `C_w` from this frame to the project's world frame (module docs).
    pub fn to_project(self) -> Matrix3<f64> {
        match self {
            WorldFrame::Enu => Matrix3::identity(),
            WorldFrame::Ned => Matrix3::new(0.0, 1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, -1.0),
        }
    }
}

impl BodyFrame {
    /// The rotation `C_b` from this frame to the project's body frame (module docs).
    pub fn to_project(self) -> Matrix3<f64> {
        match self {
            BodyFrame::Flu => Matrix3::identity(),
            BodyFrame::Frd => Matrix3::from_diagonal(&Vector3::new(1.0, -1.0, -1.0)),
        }
    }
}

/// What a column measures (decides which units it accepts).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Quantity {
    Time,
    Length,
    Speed,
    Acceleration,
    AngularRate,
    AngularAcceleration,
    Force,
    Torque,
    Angle,
    Unitless,
}

/// Units with their factor to SI.
const UNITS: [(&str, f64, Quantity); 25] = [
    ("s", 1.0, Quantity::Time),
    ("ms", 1e-3, Quantity::Time),
    ("us", 1e-6, Quantity::Time),
    ("µs", 1e-6, Quantity::Time),
    ("ns", 1e-9, Quantity::Time),
    ("m", 1.0, Quantity::Length),
    ("cm", 1e-2, Quantity::Length),
    ("mm", 1e-3, Quantity::Length),
    ("m/s", 1.0, Quantity::Speed),
    ("cm/s", 1e-2, Quantity::Speed),
    ("mm/s", 1e-3, Quantity::Speed),
    ("m/s2", 1.0, Quantity::Acceleration),
    ("mm/s2", 1e-3, Quantity::Acceleration),
    ("g", 9.80665, Quantity::Acceleration),
    ("rad/s", 1.0, Quantity::AngularRate),
    ("deg/s", std::f64::consts::PI / 180.0, Quantity::AngularRate),
    ("rpm", std::f64::consts::PI / 30.0, Quantity::AngularRate),
    ("rad/s2", 1.0, Quantity::AngularAcceleration),
    (
        "deg/s2",
        std::f64::consts::PI / 180.0,
        Quantity::AngularAcceleration,
    ),
    ("N", 1.0, Quantity::Force),
    ("mN", 1e-3, Quantity::Force),
    ("Nm", 1.0, Quantity::Torque),
    ("mNm", 1e-3, Quantity::Torque),
    ("rad", 1.0, Quantity::Angle),
    ("deg", std::f64::consts::PI / 180.0, Quantity::Angle),
];

/// The factor to SI of a unit name (`"ms"` → 1e-3), `None` if unknown.
pub fn unit_factor(unit: &str) -> Option<f64> {
    unit_entry(unit).map(|u| u.1)
}

fn unit_entry(unit: &str) -> Option<(&'static str, f64, Quantity)> {
    let u = unit.trim();
    let u = match u {
        "m/s^2" => "m/s2",
        "mm/s^2" => "mm/s2",
        "rad/s^2" => "rad/s2",
        "deg/s^2" => "deg/s2",
        "N m" | "N·m" => "Nm",
        "Nmm" | "N mm" => "mNm",
        other => other,
    };
    UNITS.iter().copied().find(|(n, _, _)| *n == u)
}

/// The groups of project columns, in the order they are resolved.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
enum Group {
    Position,
    Velocity,
    Attitude,
    Omega,
    Force,
    Torque,
    Accel,
    OmegaDot,
    RotorSpeeds,
    SpecificForce,
}

impl Group {
    const ALL: [Group; 10] = [
        Group::Position,
        Group::Velocity,
        Group::Attitude,
        Group::Omega,
        Group::Force,
        Group::Torque,
        Group::Accel,
        Group::OmegaDot,
        Group::RotorSpeeds,
        Group::SpecificForce,
    ];
    fn columns(self) -> &'static [&'static str] {
        match self {
            Group::Position => &["px", "py", "pz"],
            Group::Velocity => &["vx", "vy", "vz"],
            Group::Attitude => &["qw", "qx", "qy", "qz"],
            Group::Omega => &["wx", "wy", "wz"],
            Group::Force => &["fx", "fy", "fz"],
            Group::Torque => &["tx", "ty", "tz"],
            Group::Accel => &["ax", "ay", "az"],
            Group::OmegaDot => &["dwx", "dwy", "dwz"],
            Group::RotorSpeeds => &["w1", "w2", "w3", "w4"],
            Group::SpecificForce => &SPECIFIC_FORCE_COLUMNS,
        }
    }
    fn key(self) -> &'static str {
        match self {
            Group::Position => "position",
            Group::Velocity => "velocity",
            Group::Attitude => "attitude",
            Group::Omega => "omega",
            Group::Force => "force",
            Group::Torque => "torque",
            Group::Accel => "accel",
            Group::OmegaDot => "omega_dot",
            Group::RotorSpeeds => "rotor_speeds",
            Group::SpecificForce => "specific_force",
        }
    }
    fn quantity(self) -> Quantity {
        match self {
            Group::Position => Quantity::Length,
            Group::Velocity => Quantity::Speed,
            Group::Attitude => Quantity::Unitless,
            Group::Omega | Group::RotorSpeeds => Quantity::AngularRate,
            Group::Force => Quantity::Force,
            Group::Torque => Quantity::Torque,
            Group::Accel | Group::SpecificForce => Quantity::Acceleration,
            Group::OmegaDot => Quantity::AngularAcceleration,
        }
    }
    /// Fragments of header names that could hold this group (for the hints of errors).
    fn hints(self) -> &'static [&'static str] {
        match self {
            Group::Position => &["pos", "x", "y", "z"],
            Group::Velocity => &["vel", "v"],
            Group::Attitude => &["q", "quat", "att", "orient"],
            Group::Omega => &["gyr", "rate", "omega", "ang", "w"],
            Group::Force | Group::Torque => &["force", "torque", "wrench", "thrust", "f", "t"],
            Group::Accel => &["acc", "a"],
            Group::OmegaDot => &["dw", "alpha"],
            Group::RotorSpeeds => &["rpm", "motor", "rotor", "esc", "w"],
            Group::SpecificForce => &["acc", "imu", "specific", "sf"],
        }
    }
}

/// Fewest samples a stream must have to provide a quantity (module docs, "Several streams").
pub const MIN_STREAM_SAMPLES: usize = 10;

/// Longest median step \[s\] of a stream that provides the attitude, the angular velocity or
/// acceleration, the wrench, the rotor speeds or an acceleration. A stream below 10 Hz cannot
/// support the fit of a quadrotor's dynamics (position and velocity may be slower).
pub const MAX_STREAM_STEP: f64 = 0.1;

/// Least fraction of the time base's span a stream must overlap: less means a wrong offset, a
/// wrong time unit or a stream of another flight.
pub const MIN_STREAM_OVERLAP: f64 = 0.5;

/// Fraction of the time base's samples dropped because of one stream (outside its range or in
/// its gaps) above which the merge report warns.
pub const DROPPED_WARNING_FRACTION: f64 = 0.05;

/// Largest deviation `|‖q‖ − 1|` that `[frames] normalize_quaternion = true` divides out:
/// farther, the columns are taken not to be a quaternion.
pub const QUATERNION_RENORMALISE_LIMIT: f64 = 0.1;

/// A problem with a column mapping or with the streams it maps: every variant names the file,
/// and where it can the line and column.
#[derive(Debug, Error, Clone, PartialEq)]
#[non_exhaustive]
pub enum InputError {
    /// The mapping file is not valid TOML or holds an unknown key or value.
    #[error("{path}: {message}")]
    Mapping {
        /// The mapping file.
        path: String,
        /// What is wrong (with its line for TOML syntax errors).
        message: String,
    },
    /// A stream file could not be read, or a cell or a time stamp is wrong (names file, line
    /// and column).
    #[error(transparent)]
    Log(#[from] LogError),
    /// A required quantity is in no stream.
    #[error(
        "{quantity}: no columns {columns} in {streams}; map them with [columns] in the mapping \
         file or give a stream that has them{candidates}"
    )]
    MissingQuantity {
        /// The quantity (`attitude`, `wrench`, …).
        quantity: String,
        /// The project columns that would provide it.
        columns: String,
        /// The stream files searched.
        streams: String,
        /// Header columns with a close name (`"; columns that could provide it: …"`), or
        /// empty.
        candidates: String,
    },
    /// A mapping names a column the stream does not have.
    #[error(
        "{path}, line 1: no column `{column}` (mapped to `{target}`); the header has: {header}"
    )]
    UnmappedColumn {
        /// The stream file.
        path: String,
        /// The column name the mapping asks for.
        column: String,
        /// The project column it was mapped to.
        target: String,
        /// The stream's header.
        header: String,
    },
    /// A key of the mapping names a column that no stream has (a typo is never replaced by
    /// the file's own column of the project's name).
    #[error("{key} = {columns}: no stream has this column ({streams}){nearest}")]
    AbsentColumn {
        /// The mapping key (`columns.ax`, `units.vbat`).
        key: String,
        /// The column name(s) it asks for, quoted.
        columns: String,
        /// The streams searched, each with its header.
        streams: String,
        /// `"; nearest header name: `ax` (log.csv)"`, or empty.
        nearest: String,
    },
    /// A `[streams."NAME"]` table or `primary` names no stream file given.
    #[error("{key}: no stream file is named `{name}` (the streams: {files}){nearest}")]
    UnknownStream {
        /// The mapping key (`streams."imu.cvs"`, `streams.primary`).
        key: String,
        /// The file name it gives.
        name: String,
        /// The stream files' names.
        files: String,
        /// `"; did you mean `imu.csv`?"`, or empty.
        nearest: String,
    },
    /// A stream that provides a quantity is too short or too slow for the fit.
    #[error(
        "{stream}: {samples} samples at a median step of {step:.3} s ({rate:.2} Hz) cannot \
         support the fit of {quantities}: a stream providing them needs at least {min} samples \
         and, but for position and velocity, a median step of at most {max} s (10 Hz)",
        min = MIN_STREAM_SAMPLES,
        max = MAX_STREAM_STEP
    )]
    StreamTooSparse {
        /// The stream's file.
        stream: String,
        /// Its samples.
        samples: usize,
        /// Its median step \[s\].
        step: f64,
        /// Its rate, `1 / step` \[Hz\].
        rate: f64,
        /// The quantities it provides.
        quantities: String,
    },
    /// A stream whose time range barely overlaps the time base.
    #[error(
        "{stream}: its time stamps ({start:.3} to {end:.3} s, offset {offset} s) overlap the \
         time base ({primary}: {base_start:.3} to {base_end:.3} s) over {overlap:.3} s, {percent:.0} % \
         of its span, less than {min:.0} %: a wrong offset or time unit, or a stream of another \
         flight",
        min = MIN_STREAM_OVERLAP * 100.0
    )]
    StreamOverlap {
        /// The stream's file.
        stream: String,
        /// Its first time stamp, offset included \[s\].
        start: f64,
        /// Its last time stamp \[s\].
        end: f64,
        /// The offset the mapping gave it \[s\].
        offset: f64,
        /// The primary stream's file.
        primary: String,
        /// The time base's first time stamp \[s\].
        base_start: f64,
        /// The time base's last time stamp \[s\].
        base_end: f64,
        /// The overlap \[s\].
        overlap: f64,
        /// The overlap as a percentage of the time base's span.
        percent: f64,
    },
    /// Columns read as the world acceleration `p̈` that average near `g` on z: most likely
    /// the world-frame specific force.
    #[error(
        "{stream}: the columns read as the world acceleration ax, ay, az (p̈) average \
         {mean_z:.2} m/s² on z over the log, while the velocity's change accounts for \
         {from_velocity:.2} m/s²: a flight's p̈ cannot average that, so these are most likely the \
         world-frame specific force (+9.81 m/s² on z at hover). Say so in the mapping with \
         `[frames] accel = \"specific-force\"`, or leave them out with \
         `[columns] ignore = [\"ax\", \"ay\", \"az\"]` (docs/COLUMN_MAPPING.md)"
    )]
    AccelLooksLikeSpecificForce {
        /// The stream the columns come from.
        stream: String,
        /// The mean of `p̈_z` over the merged log \[m/s²\].
        mean_z: f64,
        /// The mean `p̈_z` the velocity implies, `Δv_z / T` \[m/s²\].
        from_velocity: f64,
    },
    /// A quaternion too far from unit norm to be renormalised.
    #[error(
        "{path}, line {line}: quaternion norm {norm:.4} is too far from 1 to be renormalised \
         (`normalize_quaternion` divides out at most |‖q‖ − 1| = {limit}): the columns mapped \
         to the quaternion are probably not a quaternion",
        limit = QUATERNION_RENORMALISE_LIMIT
    )]
    QuaternionFarFromUnit {
        /// The stream file.
        path: String,
        /// The CSV line (1-based; the header is line 1).
        line: usize,
        /// The norm found.
        norm: f64,
    },
    /// No stream was given.
    #[error("no stream file: give a log, `--stream FILE`, or `files` in the mapping's [streams]")]
    NoStream,
}

/// What the columns `ax, ay, az` of a log hold (`[frames] accel`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum AccelColumns {
    /// The world acceleration `p̈` \[m/s²\] (gravity removed): the project's meaning.
    #[default]
    Acceleration,
    /// The world-frame specific force `f_w = p̈ − g_w` \[m/s²\] (`+9.81` on z at hover):
    /// read as `p̈ = f_w + g_w` with the project's [`GRAVITY_WORLD`].
    WorldSpecificForce,
}

/// One stream's settings that may differ from the global ones.
#[derive(Debug, Clone, Default, PartialEq)]
struct StreamSettings {
    offset: f64,
    columns: BTreeMap<String, Vec<String>>,
    /// Unit key → factor to SI.
    units: BTreeMap<String, f64>,
}

/// A column mapping (the module docs give the file format); [`ColumnMapping::default`] is the
/// identity (project names, SI units, project frames).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ColumnMapping {
    /// Project column (or extra column's new name) → candidate file column names.
    columns: BTreeMap<String, Vec<String>>,
    /// The quaternion columns in file order (`q = [...]`).
    quaternion: Option<[String; 4]>,
    /// File columns never read (`ignore = [...]`).
    ignore: Vec<String>,
    /// Project column, group key or extra column → factor to SI.
    units: BTreeMap<String, f64>,
    /// The log's world frame.
    pub world: WorldFrame,
    /// The log's body frame.
    pub body: BodyFrame,
    /// The order of the `q` list.
    pub quaternion_order: QuaternionOrder,
    /// What the columns `ax, ay, az` hold (`[frames] accel`).
    pub accel: AccelColumns,
    /// Divide the log's quaternions by their norm (`[frames] normalize_quaternion`).
    pub normalize_quaternion: bool,
    /// Stream files named by the mapping (resolved against the mapping file's folder).
    pub files: Vec<PathBuf>,
    /// The primary stream's file name, if set.
    pub primary: Option<String>,
    /// Per-stream settings by file name.
    streams: BTreeMap<String, StreamSettings>,
}

/// The Levenshtein distance between two strings (in characters).
fn edit_distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut diag = row[0];
        row[0] = i + 1;
        for (j, &cb) in b.iter().enumerate() {
            let next = (diag + usize::from(ca != cb))
                .min(row[j] + 1)
                .min(row[j + 1] + 1);
            diag = row[j + 1];
            row[j + 1] = next;
        }
    }
    row[b.len()]
}

/// The candidate nearest `word` by edit distance, if any is within `max` edits.
fn nearest<'a>(
    word: &str,
    candidates: impl IntoIterator<Item = &'a str>,
    max: usize,
) -> Option<&'a str> {
    candidates
        .into_iter()
        .map(|c| (edit_distance(word, c), c))
        .filter(|(d, _)| *d <= max)
        .min_by_key(|(d, _)| *d)
        .map(|(_, c)| c)
}

#[cfg(feature = "toml")]
/// The edits a key may be away from a known key to be taken as a typo of it: one for keys of
/// up to three characters (`wx`, `w1`), two for longer ones (`omgea`).
fn typo_edits(key: &str) -> usize {
    if key.chars().count() <= 3 { 1 } else { 2 }
}

#[cfg(feature = "toml")]
/// `" (did you mean `omega`?)"` for the known key nearest `key`, or empty.
fn did_you_mean<'a>(key: &str, known: impl IntoIterator<Item = &'a str>) -> String {
    nearest(key, known, typo_edits(key).max(2))
        .map(|k| format!("; did you mean `{k}`?"))
        .unwrap_or_default()
}

#[cfg(feature = "toml")]
/// An error for an unknown key of a table whose keys are all known.
fn unknown_key(what: &str, key: &str, known: &[&str]) -> String {
    format!(
        "{what}: unknown key `{key}`{} (known: {})",
        did_you_mean(key, known.iter().copied()),
        known.join(", ")
    )
}

/// Every project column a mapping may name: `t` and the columns of every group.
fn project_columns() -> impl Iterator<Item = &'static str> {
    std::iter::once("t").chain(Group::ALL.iter().flat_map(|g| g.columns().iter().copied()))
}

#[cfg(feature = "toml")]
/// Every key of `[units]` that is not an extra column: `t`, `time`, the project columns and
/// the group keys.
fn unit_keys() -> impl Iterator<Item = &'static str> {
    project_columns()
        .chain(std::iter::once("time"))
        .chain(Group::ALL.iter().map(|g| g.key()))
}

#[cfg(feature = "toml")]
fn str_list(v: &toml::Value, what: &str) -> Result<Vec<String>, String> {
    match v {
        toml::Value::String(s) => Ok(vec![s.clone()]),
        toml::Value::Array(a) => a
            .iter()
            .map(|x| {
                x.as_str()
                    .map(str::to_string)
                    .ok_or_else(|| format!("{what}: expected strings"))
            })
            .collect(),
        _ => Err(format!("{what}: expected a string or a list of strings")),
    }
}

#[cfg(feature = "toml")]
fn table<'a>(v: &'a toml::Value, what: &str) -> Result<&'a toml::Table, String> {
    v.as_table()
        .ok_or_else(|| format!("`{what}` must be a table"))
}

#[cfg(feature = "toml")]
/// Parses a `[columns]` table (`what` is its key path, `global` for the top-level one, which
/// alone may hold `q` and `ignore`).
fn parse_columns(t: &toml::Table, global: bool, what: &str) -> Result<ColumnsParsed, String> {
    let mut out = ColumnsParsed::default();
    for (k, v) in t {
        let key = format!("{what}.{k}");
        if global && k == "q" {
            let list = str_list(v, &key)?;
            let arr: [String; 4] = list
                .try_into()
                .map_err(|_| format!("{key}: expected the four quaternion columns"))?;
            out.quaternion = Some(arr);
            continue;
        }
        if global && k == "ignore" {
            out.ignore = str_list(v, &key)?;
            continue;
        }
        if let Some(g) = Group::ALL.iter().find(|g| g.key() == k) {
            return Err(format!(
                "{key}: columns are mapped one by one ({}{})",
                g.columns().join(", "),
                if *g == Group::Attitude {
                    ", or `q = [...]` in file order"
                } else {
                    ""
                }
            ));
        }
        let project = project_columns().any(|c| c == k);
        if !project {
            // A key that is not a project column renames an extra column, unless it is a
            // typo of a project column or group.
            let known = project_columns()
                .chain(Group::ALL.iter().map(|g| g.key()))
                .chain(if global { vec!["q", "ignore"] } else { vec![] });
            if let Some(near) = nearest(k, known, typo_edits(k)) {
                return Err(format!(
                    "{key}: unknown project column `{k}`; did you mean `{near}`? (a key that is \
                     not a project column renames an extra column, and must not be one typo \
                     away from one)"
                ));
            }
        }
        let list = str_list(v, &key)?;
        if list.is_empty() || list.iter().any(|c| c.trim().is_empty()) {
            return Err(format!(
                "{key}: an empty column name (to leave a file column out, list it in \
                 `[columns] ignore = [...]`)"
            ));
        }
        out.columns.insert(k.clone(), list);
    }
    Ok(out)
}

#[cfg(feature = "toml")]
#[derive(Default)]
struct ColumnsParsed {
    columns: BTreeMap<String, Vec<String>>,
    quaternion: Option<[String; 4]>,
    ignore: Vec<String>,
}

#[cfg(feature = "toml")]
/// The factor to SI of one `[units]` value: a unit name, a number ("multiply by this to get
/// SI"), or `{ unit = "erpm", pole_pairs = N }`; with the quantity of a named unit.
fn parse_unit_value(v: &toml::Value, key: &str) -> Result<(f64, Option<Quantity>), String> {
    let erpm = |pole_pairs: &toml::Value| -> Result<(f64, Option<Quantity>), String> {
        let n = pole_pairs
            .as_integer()
            .filter(|n| *n > 0)
            .ok_or_else(|| format!("{key}.pole_pairs: expected a positive whole number"))?;
        Ok((
            std::f64::consts::PI / 30.0 / n as f64,
            Some(Quantity::AngularRate),
        ))
    };
    match v {
        toml::Value::String(u) => {
            if u.trim() == "erpm" {
                return Err(format!(
                    "{key}: `erpm` (electrical rpm = rpm × pole pairs) needs the motors' pole \
                     pairs: write `{{ unit = \"erpm\", pole_pairs = 7 }}`"
                ));
            }
            let (_, f, q) = unit_entry(u).ok_or_else(|| {
                let known: Vec<&str> = UNITS.iter().map(|x| x.0).collect();
                format!(
                    "{key}: unknown unit `{u}` (known: {}; `{{ unit = \"erpm\", pole_pairs = N }}`; \
                     or a number, the factor to SI)",
                    known.join(", ")
                )
            })?;
            Ok((f, Some(q)))
        }
        toml::Value::Integer(_) | toml::Value::Float(_) => {
            let x = v
                .as_float()
                .unwrap_or_else(|| v.as_integer().unwrap_or(0) as f64);
            if x.is_finite() && x > 0.0 {
                Ok((x, None))
            } else {
                Err(format!(
                    "{key}: a scale factor must be a positive finite number (what to multiply \
                     the column by to get SI)"
                ))
            }
        }
        toml::Value::Table(t) => {
            for k in t.keys() {
                if k != "unit" && k != "pole_pairs" {
                    return Err(unknown_key(key, k, &["unit", "pole_pairs"]));
                }
            }
            match (t.get("unit").and_then(|u| u.as_str()), t.get("pole_pairs")) {
                (Some("erpm"), Some(p)) => erpm(p),
                (Some("erpm"), None) => Err(format!("{key}: `erpm` needs `pole_pairs`")),
                (Some(u), None) => parse_unit_value(&toml::Value::String(u.to_string()), key),
                (Some(u), Some(_)) => Err(format!(
                    "{key}: `pole_pairs` goes with `unit = \"erpm\"`, not `{u}`"
                )),
                (None, _) => Err(format!("{key}: expected `unit = \"...\"`")),
            }
        }
        _ => Err(format!(
            "{key}: expected a unit name, a number (the factor to SI) or \
             `{{ unit = \"erpm\", pole_pairs = N }}`"
        )),
    }
}

#[cfg(feature = "toml")]
fn parse_units(t: &toml::Table, what: &str) -> Result<BTreeMap<String, f64>, String> {
    let mut out = BTreeMap::new();
    for (k, v) in t {
        let key = format!("{what}.{k}");
        let (factor, q) = parse_unit_value(v, &key)?;
        match key_quantity(k) {
            Some(expected) => {
                if let Some(q) = q
                    && expected != q
                {
                    let u = v
                        .as_str()
                        .or_else(|| v.get("unit").and_then(|u| u.as_str()));
                    return Err(format!(
                        "{key}: unit `{}` does not fit (a {expected:?} unit is expected)",
                        u.unwrap_or_default()
                    ));
                }
            }
            None => {
                // An extra column's unit, unless a typo of a project key.
                if let Some(near) = nearest(k, unit_keys(), typo_edits(k)) {
                    return Err(format!(
                        "{key}: unknown key `{k}`; did you mean `{near}`? (keys: t, the project \
                         columns, the groups time position velocity attitude omega force torque \
                         accel omega_dot rotor_speeds specific_force, or an extra column's name)"
                    ));
                }
            }
        }
        out.insert(k.clone(), factor);
    }
    Ok(out)
}

/// The quantity a unit key (project column or group) measures; `None` for extra columns.
fn key_quantity(key: &str) -> Option<Quantity> {
    if key == "t" || key == "time" {
        return Some(Quantity::Time);
    }
    Group::ALL
        .iter()
        .find(|g| g.key() == key || g.columns().contains(&key))
        .map(|g| g.quantity())
}

#[cfg(feature = "toml")]
/// Checks that a stream file named in `[streams] files` stays inside the mapping file's
/// folder: relative, and no `..` that leaves it.
fn confined(file: &str) -> Result<PathBuf, String> {
    let p = PathBuf::from(file);
    let outside = || {
        format!(
            "streams.files: `{file}` is outside the mapping file's folder (stream files are \
             named relative to it; absolute paths and `..` that leave it are refused: give such \
             a file with `--stream FILE`)"
        )
    };
    if p.has_root() || p.is_absolute() {
        return Err(outside());
    }
    let mut depth: i64 = 0;
    for c in p.components() {
        match c {
            std::path::Component::ParentDir => depth -= 1,
            std::path::Component::Normal(_) => depth += 1,
            std::path::Component::CurDir => {}
            std::path::Component::RootDir | std::path::Component::Prefix(_) => {
                return Err(outside());
            }
        }
        if depth < 0 {
            return Err(outside());
        }
    }
    Ok(p)
}

impl ColumnMapping {
    #[cfg(feature = "toml")]
    /// Reads a mapping file (TOML, the module docs); `files` are resolved against its folder.
    ///
    /// # Errors
    /// [`InputError::Mapping`] naming the file (and the line for syntax errors).
    pub fn from_path(path: impl AsRef<Path>) -> Result<Self, InputError> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path).map_err(|e| InputError::Mapping {
            path: path.display().to_string(),
            message: e.to_string(),
        })?;
        let mut m = Self::from_toml_str(&text).map_err(|message| InputError::Mapping {
            path: path.display().to_string(),
            message,
        })?;
        let dir = path.parent().unwrap_or(Path::new(""));
        for f in &mut m.files {
            *f = dir.join(&*f);
        }
        Ok(m)
    }

    #[cfg(feature = "toml")]
    /// Parses a mapping from TOML text.
    ///
    /// # Errors
    /// A message naming the offending key (with the nearest known key for a typo) or the TOML
    /// syntax error with its line.
    pub fn from_toml_str(text: &str) -> Result<Self, String> {
        let doc: toml::Table = text.parse().map_err(|e: toml::de::Error| e.to_string())?;
        let mut m = ColumnMapping::default();
        for (key, value) in &doc {
            match key.as_str() {
                "columns" => {
                    let c = parse_columns(table(value, "columns")?, true, "columns")?;
                    m.columns = c.columns;
                    m.quaternion = c.quaternion;
                    m.ignore = c.ignore;
                }
                "units" => m.units = parse_units(table(value, "units")?, "units")?,
                "frames" => m.parse_frames(table(value, "frames")?)?,
                "streams" => m.parse_streams(table(value, "streams")?)?,
                other => {
                    return Err(format!(
                        "unknown table `{other}`{} (known: columns, units, frames, streams)",
                        did_you_mean(other, ["columns", "units", "frames", "streams"])
                    ));
                }
            }
        }
        Ok(m)
    }

    #[cfg(feature = "toml")]
    fn parse_frames(&mut self, t: &toml::Table) -> Result<(), String> {
        const KNOWN: [&str; 5] = [
            "world",
            "body",
            "quaternion",
            "accel",
            "normalize_quaternion",
        ];
        for (k, v) in t {
            if k == "normalize_quaternion" {
                self.normalize_quaternion = v
                    .as_bool()
                    .ok_or("frames.normalize_quaternion: expected true or false")?;
                continue;
            }
            let s = v.as_str().unwrap_or("").to_ascii_lowercase();
            match (k.as_str(), s.as_str()) {
                ("world", "enu") => self.world = WorldFrame::Enu,
                ("world", "ned") => self.world = WorldFrame::Ned,
                ("body", "flu") => self.body = BodyFrame::Flu,
                ("body", "frd") => self.body = BodyFrame::Frd,
                ("quaternion", "wxyz") => self.quaternion_order = QuaternionOrder::Wxyz,
                ("quaternion", "xyzw") => self.quaternion_order = QuaternionOrder::Xyzw,
                ("accel", "acceleration") => self.accel = AccelColumns::Acceleration,
                ("accel", "specific-force" | "specific_force") => {
                    self.accel = AccelColumns::WorldSpecificForce;
                }
                ("world" | "body" | "quaternion" | "accel", _) => {
                    return Err(format!(
                        "frames.{k}: unknown value {v} (world: enu, ned; body: flu, frd; \
                         quaternion: wxyz, xyzw; accel: acceleration, specific-force)"
                    ));
                }
                _ => return Err(unknown_key("frames", k, &KNOWN)),
            }
        }
        Ok(())
    }

    #[cfg(feature = "toml")]
    fn parse_streams(&mut self, t: &toml::Table) -> Result<(), String> {
        for (k, v) in t {
            match k.as_str() {
                "files" => {
                    self.files = str_list(v, "streams.files")?
                        .iter()
                        .map(|f| confined(f))
                        .collect::<Result<_, _>>()?;
                }
                "primary" => {
                    self.primary = Some(
                        v.as_str()
                            .ok_or("streams.primary: expected a file name")?
                            .to_string(),
                    );
                }
                name => {
                    let what = format!("streams.\"{name}\"");
                    let Some(t) = v.as_table() else {
                        return Err(format!(
                            "{what}: expected a table of one stream's settings (offset, \
                             columns, units){}",
                            did_you_mean(name, ["files", "primary"])
                        ));
                    };
                    let mut s = StreamSettings::default();
                    for (sk, sv) in t {
                        match sk.as_str() {
                            "offset" => {
                                s.offset = sv
                                    .as_float()
                                    .or_else(|| sv.as_integer().map(|i| i as f64))
                                    .filter(|x| x.is_finite())
                                    .ok_or_else(|| format!("{what}.offset: expected seconds"))?;
                            }
                            "columns" => {
                                let what = format!("{what}.columns");
                                s.columns = parse_columns(table(sv, &what)?, false, &what)?.columns;
                            }
                            "units" => {
                                let what = format!("{what}.units");
                                s.units = parse_units(table(sv, &what)?, &what)?;
                            }
                            other => {
                                return Err(unknown_key(
                                    &what,
                                    other,
                                    &["offset", "columns", "units"],
                                ));
                            }
                        }
                    }
                    self.streams.insert(name.to_string(), s);
                }
            }
        }
        Ok(())
    }

    /// Renames a project column (`t` → `timestamp`); a later call for the same column adds a
    /// further candidate.
    pub fn rename(&mut self, project: &str, file_column: &str) -> &mut Self {
        self.columns
            .entry(project.to_string())
            .or_default()
            .push(file_column.to_string());
        self
    }

    #[cfg(feature = "toml")]
    /// Sets the unit of a project column or group (`"t"`, `"rotor_speeds"`).
    ///
    /// # Errors
    /// An unknown unit or one that does not fit the quantity.
    pub fn set_unit(&mut self, key: &str, unit: &str) -> Result<&mut Self, String> {
        let mut t = toml::Table::new();
        t.insert(key.to_string(), toml::Value::String(unit.to_string()));
        self.units.extend(parse_units(&t, "units")?);
        Ok(self)
    }

    /// Adds a time offset \[s\] to the stream whose file name is `file_name`.
    pub fn set_offset(&mut self, file_name: &str, offset: f64) -> &mut Self {
        self.streams
            .entry(file_name.to_string())
            .or_default()
            .offset = offset;
        self
    }
}

/// A gap in one stream: a step longer than [`GAP_FACTOR`] × its median step.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Gap {
    /// The stream's file.
    pub stream: String,
    /// Time of the last sample before the gap \[s\] (project time base).
    pub start: f64,
    /// Length of the gap \[s\].
    pub duration: f64,
}

/// One stream as the merge saw it: rate, span, overlap with the time base, samples dropped.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct StreamSummary {
    /// The stream's file.
    pub stream: String,
    /// Its samples.
    pub samples: usize,
    /// Its rate, one over its median step \[Hz\].
    pub rate: f64,
    /// Its first time stamp, offset included \[s\].
    pub start: f64,
    /// Its last time stamp, offset included \[s\].
    pub end: f64,
    /// The offset the mapping added to its time stamps \[s\].
    pub offset: f64,
    /// Its overlap with the time base \[s\].
    pub overlap: f64,
    /// The overlap as a fraction of the time base's span (1 for the primary stream).
    pub overlap_fraction: f64,
    /// Time-base samples dropped because of this stream (outside its range or in its gaps).
    pub dropped: usize,
    /// The quantities taken from it (group keys: `attitude`, `rotor_speeds`, …).
    pub provides: Vec<String>,
}

/// A column that is not mapped and was not offered as an extra signal, because a cell of it is
/// not a finite number (text, a boolean, an empty cell).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct UnreadColumn {
    /// The stream's file.
    pub stream: String,
    /// The column's name.
    pub column: String,
    /// The first cell that is not a finite number: its CSV line (1-based; the header is 1).
    pub line: usize,
    /// That cell's text.
    pub value: String,
}

/// What the merge did: streams, gaps found, samples dropped, warnings.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct MergeReport {
    /// The primary stream (its time stamps are the time base).
    pub primary: String,
    /// Which stream each quantity came from (`("attitude", "mocap.csv")`, …).
    pub sources: Vec<(String, String)>,
    /// Derived quantities (`"velocity (from position, mocap.csv)"`).
    pub derived: Vec<String>,
    /// Gaps of every stream.
    pub gaps: Vec<Gap>,
    /// Primary samples dropped because they fall in a gap of a stream they interpolate.
    pub dropped_in_gaps: usize,
    /// Primary samples dropped because they are outside the time range of a stream.
    pub dropped_outside: usize,
    /// Every stream: rate, span, overlap, dropped samples, offset.
    pub streams: Vec<StreamSummary>,
    /// The largest `|‖q‖ − 1|` divided out of the attitude (`normalize_quaternion`), if the
    /// quaternions were renormalised.
    pub quaternion_renormalised: Option<f64>,
    /// Unmapped columns not offered as extra signals (a cell is not a number).
    pub unread_columns: Vec<UnreadColumn>,
    /// Warnings in plain words (many samples dropped, renormalised quaternions, a mapped
    /// optional quantity that no stream has, a stream that provides nothing).
    pub warnings: Vec<String>,
    /// The primary stream's CSV line (1-based; the header is line 1) of each sample of the
    /// merged log. Quantities of another stream are interpolated onto these samples: their
    /// own lines are not these. Not serialised (one number per sample).
    #[serde(skip)]
    pub lines: Vec<usize>,
}

impl MergeReport {
    /// The report in a few lines, as the terminal shows it: primary stream, sources, derived
    /// quantities, each stream, gaps, dropped samples, unread columns, then the warnings (each
    /// line `warning: …`). No trailing newline.
    pub fn text(&self) -> String {
        let mut text = format!("time base: {}", self.primary);
        let sources: Vec<String> = self
            .sources
            .iter()
            .map(|(q, s)| format!("{q} <- {s}"))
            .collect();
        if !sources.is_empty() {
            text.push_str(&format!("\nquantities: {}", sources.join(", ")));
        }
        if !self.derived.is_empty() {
            text.push_str(&format!("\nderived: {}", self.derived.join(", ")));
        }
        for s in &self.streams {
            text.push_str(&format!("\n{}", s.text()));
        }
        for g in &self.gaps {
            text.push_str(&format!(
                "\ngap in {}: {:.3} s long at t = {:.3} s",
                g.stream, g.duration, g.start
            ));
        }
        if self.dropped_in_gaps + self.dropped_outside > 0 {
            text.push_str(&format!(
                "\ndropped: {} samples inside gaps, {} outside another stream's time range",
                self.dropped_in_gaps, self.dropped_outside
            ));
        }
        if !self.unread_columns.is_empty() {
            let cols: Vec<String> = self
                .unread_columns
                .iter()
                .map(|c| {
                    format!(
                        "{} ({}, line {}: `{}`)",
                        c.column, c.stream, c.line, c.value
                    )
                })
                .collect();
            text.push_str(&format!(
                "\nnot read (unmapped, not numeric): {}",
                cols.join(", ")
            ));
        }
        for w in &self.warnings {
            text.push_str(&format!("\nwarning: {w}"));
        }
        text
    }
}

impl StreamSummary {
    /// One line: `stream imu.csv: 50.0 Hz, 1250 samples, t = 0.010 to 24.990 s, offset 0 s,
    /// overlap 100 % of the time base, 0 samples dropped`.
    pub fn text(&self) -> String {
        format!(
            "stream {}: {:.1} Hz, {} samples, t = {:.3} to {:.3} s, offset {} s, overlap {:.0} % \
             of the time base, {} samples dropped",
            self.stream,
            self.rate,
            self.samples,
            self.start,
            self.end,
            self.offset,
            self.overlap_fraction * 100.0,
            self.dropped
        )
    }
}

/// Options of [`read_streams`] beyond the mapping.
#[derive(Debug, Clone, Copy, Default)]
pub struct ReadOptions<'a> {
    /// The vehicle that computes the body wrench from the rotor speeds
    /// ([`FlightLog::compute_wrench_from_rotor_speeds`]) when the streams have rotor speeds but
    /// no wrench.
    pub vehicle: Option<&'a Vehicle>,
}

/// One stream read, in project units and frames.
struct Stream {
    name: String,
    header: Vec<String>,
    t: Vec<f64>,
    offset: f64,
    groups: BTreeMap<Group, Vec<Vec<f64>>>,
    extra: Vec<(String, Vec<f64>)>,
    /// The global mapping keys (`columns.*`, `q`) one of whose columns this stream has.
    found: BTreeSet<String>,
    /// Unmapped columns not offered as extras.
    unread: Vec<UnreadColumn>,
    /// The largest `|‖q‖ − 1|` divided out of its attitude (0 without).
    renormalised: f64,
    /// The CSV line of each sample (1-based; the header is line 1).
    lines: Vec<usize>,
}

fn file_name(path: &Path) -> String {
    path.file_name().map_or_else(
        || path.display().to_string(),
        |s| s.to_string_lossy().into_owned(),
    )
}

/// The factor to SI of a project column under a unit table.
fn factor_of(units: &BTreeMap<String, f64>, column: &str, group: Option<Group>) -> f64 {
    units
        .get(column)
        .or_else(|| group.and_then(|g| units.get(g.key())))
        .or_else(|| (column == "t").then(|| units.get("time")).flatten())
        .copied()
        .unwrap_or(1.0)
}

impl ColumnMapping {
    /// Reads one stream file with this mapping. Only the columns it uses are parsed strictly
    /// (a bad cell names file, line and column). The others are read leniently and offered as
    /// extra signals only when every cell is a finite number.
    fn read_stream(&self, path: &Path) -> Result<Stream, InputError> {
        let name = file_name(path);
        let in_file =
            |e: LogError| InputError::Log(LogError::in_file(path.display().to_string(), e));
        let file = crate::log::open_log_file(path)?;
        let mut reader = NumericRows::new(std::io::BufReader::new(file)).map_err(in_file)?;
        let header = reader.header.clone();
        let per = self.streams.get(&name).cloned().unwrap_or_default();
        let mut columns = self.columns.clone();
        columns.extend(per.columns.clone());
        let mut units = self.units.clone();
        units.extend(per.units.clone());
        let position = |c: &str| header.iter().position(|h| h == c);
        // A column the stream's own override maps must be in this stream.
        for (k, cands) in &per.columns {
            if !cands.iter().any(|c| position(c).is_some()) {
                return Err(InputError::UnmappedColumn {
                    path: path.display().to_string(),
                    column: cands.join(" or "),
                    target: format!("streams.\"{name}\".columns.{k}"),
                    header: header.join(", "),
                });
            }
        }
        let mut found = BTreeSet::new();
        // Project column -> index in the header.
        let mut quaternion_cols: BTreeMap<&str, &str> = BTreeMap::new();
        if let Some(q) = &self.quaternion {
            let order = match self.quaternion_order {
                QuaternionOrder::Wxyz => ["qw", "qx", "qy", "qz"],
                QuaternionOrder::Xyzw => ["qx", "qy", "qz", "qw"],
            };
            for (o, c) in order.iter().zip(q) {
                quaternion_cols.insert(o, c.as_str());
            }
            if q.iter().all(|c| position(c).is_some()) {
                found.insert("q".to_string());
            }
        }
        let ignored = |j: usize| self.ignore.contains(&header[j]);
        let find = |project: &str| -> Option<usize> {
            if let Some(c) = quaternion_cols.get(project) {
                return position(c);
            }
            match columns.get(project) {
                // A mapped column is that column: never the file's column of the project name.
                Some(cands) => cands.iter().find_map(|c| position(c)),
                None => position(project).filter(|&j| !ignored(j)),
            }
        };
        for (k, cands) in &self.columns {
            if cands.iter().any(|c| position(c).is_some()) {
                found.insert(k.clone());
            }
        }
        let Some(jt) = find("t") else {
            let close: Vec<&str> = header
                .iter()
                .map(String::as_str)
                .filter(|h| {
                    let l = h.to_ascii_lowercase();
                    l.contains("time") || l.contains("stamp") || l == "ts" || l.starts_with("t_")
                })
                .collect();
            return Err(InputError::MissingQuantity {
                quantity: "time".into(),
                columns: match columns.get("t") {
                    Some(c) => format!("t (mapped to {})", c.join(" or ")),
                    None => "t".into(),
                },
                streams: path.display().to_string(),
                candidates: if close.is_empty() {
                    String::new()
                } else {
                    format!("; columns that could provide it: {}", close.join(", "))
                },
            });
        };
        let mut used = vec![jt];
        let mut group_idx: Vec<(Group, Vec<usize>)> = Vec::new();
        for g in Group::ALL {
            let idx: Vec<Option<usize>> = g.columns().iter().map(|c| find(c)).collect();
            if idx.iter().all(Option::is_some) {
                let idx: Vec<usize> = idx.into_iter().flatten().collect();
                used.extend(&idx);
                group_idx.push((g, idx));
            }
        }
        // Extra columns: renamed ones (`vbat = "Vbat"`) by their new name, then every other
        // column neither used nor ignored by its own name.
        let mut extra_idx: Vec<(String, usize)> = Vec::new();
        for (k, cands) in &columns {
            if project_columns().any(|c| c == k) {
                continue;
            }
            if let Some(j) = cands.iter().find_map(|c| position(c))
                && !used.contains(&j)
            {
                extra_idx.push((k.clone(), j));
            }
        }
        for (j, h) in header.iter().enumerate() {
            if !used.contains(&j) && !ignored(j) && !extra_idx.iter().any(|(_, e)| *e == j) {
                extra_idx.push((h.clone(), j));
            }
        }
        reader.set_lenient((0..header.len()).map(|j| !used.contains(&j)).collect());
        let mut cols = vec![Vec::new(); header.len()];
        let mut lines = Vec::new();
        let mut values = vec![0.0; header.len()];
        while let Some(line) = reader.next_into(&mut values).map_err(in_file)? {
            for (col, &x) in cols.iter_mut().zip(&values) {
                col.push(x);
            }
            lines.push(line);
        }
        let kt = factor_of(&units, "t", None);
        let t: Vec<f64> = cols[jt].iter().map(|x| x * kt + per.offset).collect();
        for i in 1..t.len() {
            if t[i] <= t[i - 1] {
                return Err(in_file(LogError::NonIncreasingTime {
                    line: lines[i],
                    t: t[i],
                    previous: t[i - 1],
                }));
            }
        }
        let mut groups = BTreeMap::new();
        let mut renormalised: f64 = 0.0;
        for (g, idx) in &group_idx {
            let mut rows: Vec<Vec<f64>> = (0..t.len())
                .map(|i| {
                    g.columns()
                        .iter()
                        .zip(idx)
                        .map(|(c, &j)| cols[j][i] * factor_of(&units, c, Some(*g)))
                        .collect()
                })
                .collect();
            if *g == Group::Attitude && self.normalize_quaternion {
                for (i, q) in rows.iter_mut().enumerate() {
                    let norm = q.iter().map(|x| x * x).sum::<f64>().sqrt();
                    if norm.is_nan() || (norm - 1.0).abs() > QUATERNION_RENORMALISE_LIMIT {
                        return Err(InputError::QuaternionFarFromUnit {
                            path: path.display().to_string(),
                            line: lines[i],
                            norm,
                        });
                    }
                    renormalised = renormalised.max((norm - 1.0).abs());
                    q.iter_mut().for_each(|x| *x /= norm);
                }
            }
            groups.insert(*g, rows);
        }
        let mut extra = Vec::new();
        let mut unread = Vec::new();
        for (k, j) in extra_idx {
            if let Some((line, value)) = reader.first_bad[j].clone() {
                unread.push(UnreadColumn {
                    stream: name.clone(),
                    column: header[j].clone(),
                    line,
                    value,
                });
                continue;
            }
            let f = units
                .get(&k)
                .or_else(|| units.get(&header[j]))
                .copied()
                .unwrap_or(1.0);
            extra.push((k, cols[j].iter().map(|x| x * f).collect()));
        }
        let mut s = Stream {
            name,
            header,
            t,
            offset: per.offset,
            groups,
            extra,
            found,
            unread,
            renormalised,
            lines,
        };
        self.convert_frames(&mut s);
        if self.accel == AccelColumns::WorldSpecificForce
            && let Some(rows) = s.groups.get_mut(&Group::Accel)
        {
            // p̈ = f_w + g_w, in the project's world frame.
            for v in rows.iter_mut() {
                for (x, g) in v.iter_mut().zip(GRAVITY_WORLD.iter()) {
                    *x += g;
                }
            }
        }
        Ok(s)
    }

    /// Rotates the stream's vectors and attitude into the project's frames (module docs).
    fn convert_frames(&self, s: &mut Stream) {
        let cw = self.world.to_project();
        let cb = self.body.to_project();
        for (g, rows) in &mut s.groups {
            let c = match g {
                Group::Position | Group::Velocity | Group::Accel => cw,
                Group::Omega
                | Group::OmegaDot
                | Group::Force
                | Group::Torque
                | Group::SpecificForce => cb,
                Group::Attitude => {
                    for q in rows.iter_mut() {
                        let out = convert_attitude([q[0], q[1], q[2], q[3]], self.world, self.body);
                        q.copy_from_slice(&out);
                    }
                    continue;
                }
                Group::RotorSpeeds => continue,
            };
            for v in rows.iter_mut() {
                let r = c * Vector3::new(v[0], v[1], v[2]);
                v.copy_from_slice(r.as_slice());
            }
        }
    }

    /// Checks the mapping against the streams read:
    ///
    /// - every `[streams."NAME"]` and `primary` names a stream;
    /// - every `[columns]` key has a column in some stream (a whole optional quantity that no
    ///   stream has is a warning);
    /// - every extra column's unit names a column.
    fn check_against(
        &self,
        streams: &[Stream],
        report: &mut MergeReport,
    ) -> Result<(), InputError> {
        let names: Vec<&str> = streams.iter().map(|s| s.name.as_str()).collect();
        let unknown = |key: String, name: &str| InputError::UnknownStream {
            key,
            name: name.to_string(),
            files: names.join(", "),
            nearest: nearest(name, names.iter().copied(), usize::MAX)
                .map(|n| format!("; did you mean `{n}`?"))
                .unwrap_or_default(),
        };
        for name in self.streams.keys() {
            if !names.contains(&name.as_str()) {
                return Err(unknown(format!("streams.\"{name}\""), name));
            }
        }
        if let Some(p) = &self.primary
            && !names.contains(&p.as_str())
        {
            return Err(unknown("streams.primary".into(), p));
        }
        let listing = || {
            streams
                .iter()
                .map(|s| format!("{}: {}", s.name, s.header.join(", ")))
                .collect::<Vec<_>>()
                .join("; ")
        };
        let nearest_header = |cands: &[String]| {
            let mut best: Option<(usize, String)> = None;
            for s in streams {
                for h in &s.header {
                    for c in cands {
                        let d = edit_distance(c, h);
                        if best.as_ref().is_none_or(|(b, _)| d < *b) {
                            best = Some((d, format!("; nearest header name: `{h}` ({})", s.name)));
                        }
                    }
                }
            }
            best.map(|b| b.1).unwrap_or_default()
        };
        let has_header = |c: &str| streams.iter().any(|s| s.header.iter().any(|h| h == c));
        // The nearest header name to the columns asked for, or the file's column of the key's
        // own name (which a mapping never falls back on) when it has one.
        let absent = |key: String, cands: &[String]| InputError::AbsentColumn {
            nearest: {
                let own = key.rsplit('.').next().unwrap_or_default().to_string();
                if cands.contains(&own) || !has_header(&own) {
                    nearest_header(cands)
                } else {
                    nearest_header(&[own])
                }
            },
            key,
            columns: cands
                .iter()
                .map(|c| format!("\"{c}\""))
                .collect::<Vec<_>>()
                .join(" or "),
            streams: listing(),
        };
        if let Some(q) = &self.quaternion
            && !streams.iter().any(|s| s.found.contains("q"))
        {
            let missing: Vec<String> = q.iter().filter(|c| !has_header(c)).cloned().collect();
            return Err(absent("columns.q".into(), &missing));
        }
        let mut quiet_groups: BTreeSet<Group> = BTreeSet::new();
        for (k, cands) in &self.columns {
            if streams.iter().any(|s| s.found.contains(k)) {
                continue;
            }
            let group = Group::ALL
                .iter()
                .copied()
                .find(|g| g.columns().contains(&k.as_str()));
            // A whole optional quantity mapped and in no stream (a mapping shared by logs with
            // and without, say, an accelerometer) is a warning; anything else is an error.
            let optional_and_wholly_absent = group.is_some_and(|g| {
                matches!(
                    g,
                    Group::Accel | Group::SpecificForce | Group::OmegaDot | Group::Velocity
                ) && g
                    .columns()
                    .iter()
                    .all(|c| !has_header(c) && !streams.iter().any(|s| s.found.contains(*c)))
            });
            if !optional_and_wholly_absent || has_header(k) {
                return Err(absent(format!("columns.{k}"), cands));
            }
            if let Some(g) = group
                && quiet_groups.insert(g)
            {
                let mapped: Vec<String> = g
                    .columns()
                    .iter()
                    .filter_map(|c| {
                        self.columns
                            .get(*c)
                            .map(|v| format!("{c} = {}", v.join(" or ")))
                    })
                    .collect();
                report.warnings.push(format!(
                    "the mapping's {} ({}) is in no stream: {} not read",
                    g.key(),
                    mapped.join(", "),
                    g.key()
                ));
            }
        }
        for k in self.units.keys() {
            if key_quantity(k).is_none()
                && !has_header(k)
                && !streams.iter().any(|s| s.extra.iter().any(|(n, _)| n == k))
                && !streams
                    .iter()
                    .any(|s| s.unread.iter().any(|u| &u.column == k))
            {
                return Err(absent(format!("units.{k}"), std::slice::from_ref(k)));
            }
        }
        Ok(())
    }
}

/// The attitude `(w, x, y, z)` of a log in frames `world`/`body` expressed in the project's
/// frames: `R' = C_w R C_bᵀ` (module docs). The norm is kept (the reader checks it later).
pub fn convert_attitude(q: [f64; 4], world: WorldFrame, body: BodyFrame) -> [f64; 4] {
    if world == WorldFrame::Enu && body == BodyFrame::Flu {
        return q;
    }
    let norm = q.iter().map(|x| x * x).sum::<f64>().sqrt();
    let r = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(q[0], q[1], q[2], q[3]));
    let cw =
        UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(world.to_project()));
    let cb =
        UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(body.to_project()));
    let out = cw * r * cb.inverse();
    let mut o = [out.w, out.i, out.j, out.k];
    // Keep the scalar part's sign of the input where possible (continuity) and the norm.
    if o[0] * q[0] < 0.0 {
        o.iter_mut().for_each(|x| *x = -*x);
    }
    o.map(|x| x * norm)
}

/// The world acceleration `p̈ = R f + g_w` \[m/s²\] (project frames) of each sample. It is
/// computed from the attitude `(w, x, y, z)` (body → world) and the accelerometer's specific
/// force `f` (body frame) \[m/s²\]. The attitude is normalised here, so a norm within the log's
/// tolerance does not scale the result. This is the inverse of [`crate::proper_acceleration`],
/// with the same [`GRAVITY_WORLD`], so the regressor's `Rᵀ (p̈ − g_w)` gives back `f`.
pub fn world_acceleration(attitude: &[[f64; 4]], specific_force: &[[f64; 3]]) -> Vec<[f64; 3]> {
    attitude
        .iter()
        .zip(specific_force)
        .map(|(q, f)| {
            let q = nalgebra::Quaternion::new(q[0], q[1], q[2], q[3]);
            // A zero quaternion is rejected by the log's validation; rotate by nothing here.
            let r = if q.norm() > 0.0 {
                UnitQuaternion::from_quaternion(q)
            } else {
                UnitQuaternion::identity()
            };
            (r * Vector3::from(*f) + GRAVITY_WORLD).into()
        })
        .collect()
}

fn gaps_of(s: &Stream) -> Vec<Gap> {
    Sampling::of(&s.t)
        .gaps
        .into_iter()
        .map(|g| Gap {
            stream: s.name.clone(),
            start: g.start,
            duration: g.duration,
        })
        .collect()
}

/// Where `tq` falls in `t`: `Ok((k, f))` with `t[k] ≤ tq ≤ t[k+1]`, `f` the fraction;
/// `Err(true)` inside a gap, `Err(false)` outside the range.
fn bracket(t: &[f64], tq: f64, max_step: f64, k: &mut usize) -> Result<(usize, f64), bool> {
    let n = t.len();
    if n == 0 || tq < t[0] || tq > t[n - 1] {
        return Err(false);
    }
    if n == 1 {
        return Ok((0, 0.0));
    }
    while *k + 2 < n && t[*k + 1] <= tq {
        *k += 1;
    }
    let (a, b) = (t[*k], t[*k + 1]);
    if tq == a {
        return Ok((*k, 0.0));
    }
    if tq == b {
        return Ok((*k + 1, 0.0));
    }
    if b - a > max_step {
        return Err(true);
    }
    Ok((*k, (tq - a) / (b - a)))
}

fn interp(rows: &[Vec<f64>], k: usize, f: f64, quaternion: bool) -> Vec<f64> {
    if f == 0.0 || k + 1 >= rows.len() {
        return rows[k].clone();
    }
    let (a, b) = (&rows[k], &rows[k + 1]);
    let sign = if quaternion && a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>() < 0.0 {
        -1.0
    } else {
        1.0
    };
    let mut v: Vec<f64> = a
        .iter()
        .zip(b)
        .map(|(x, y)| x * (1.0 - f) + sign * y * f)
        .collect();
    if quaternion {
        let n = v.iter().map(|x| x * x).sum::<f64>().sqrt();
        let n0 = a.iter().map(|x| x * x).sum::<f64>().sqrt();
        v.iter_mut().for_each(|x| *x *= n0 / n);
    }
    v
}

fn close_names(streams: &[Stream], g: Group) -> String {
    let mut out: Vec<String> = Vec::new();
    for s in streams {
        for h in &s.header {
            let l = h.to_ascii_lowercase();
            let hit = g.hints().iter().any(|k| {
                if k.len() <= 2 {
                    l == *k
                        || l.starts_with(&format!("{k}_"))
                        || l.starts_with(&format!("{k}."))
                        || l.starts_with(&format!("{k}["))
                        || l.ends_with(&format!("_{k}"))
                        || l.ends_with(&format!(".{k}"))
                } else {
                    l.contains(k)
                }
            });
            if hit && !out.contains(h) {
                out.push(format!("{h} ({})", s.name));
            }
        }
    }
    if out.is_empty() {
        String::new()
    } else {
        format!("; columns that could provide it: {}", out.join(", "))
    }
}

/// Reads several streams of one flight with a mapping and merges them onto the primary
/// stream's time base (module docs), then validates the result.
///
/// # Errors
/// - [`InputError::NoStream`] for no file.
/// - File, line and column of a bad cell (in a column the mapping uses) or time stamp.
/// - [`InputError::AbsentColumn`] for a mapped column no stream has.
/// - [`InputError::UnknownStream`] for a `[streams."NAME"]` or `primary` naming no stream.
/// - [`InputError::MissingQuantity`] for a quantity no stream provides (with close header
///   names).
/// - [`InputError::StreamTooSparse`] and [`InputError::StreamOverlap`] for a stream that cannot
///   support the fit.
/// - [`InputError::AccelLooksLikeSpecificForce`] for `ax..az` that average near `g`.
/// - [`InputError::QuaternionFarFromUnit`], and the [`FlightLog::validate`] errors of the
///   merged log.
pub fn read_streams(
    paths: &[PathBuf],
    mapping: &ColumnMapping,
    options: &ReadOptions<'_>,
) -> Result<(FlightLog, MergeReport), InputError> {
    if paths.is_empty() {
        return Err(InputError::NoStream);
    }
    let mut streams = paths
        .iter()
        .map(|p| mapping.read_stream(p))
        .collect::<Result<Vec<_>, _>>()?;
    let mut report = MergeReport::default();
    mapping.check_against(&streams, &mut report)?;
    let primary = mapping
        .primary
        .as_ref()
        .and_then(|p| streams.iter().position(|s| &s.name == p))
        .unwrap_or(0);
    streams.swap(0, primary);
    report.primary = streams[0].name.clone();
    // Derived: velocity from position, on the stream's own time base.
    for s in &mut streams {
        if !s.groups.contains_key(&Group::Velocity)
            && let Some(p) = s.groups.get(&Group::Position)
        {
            let p3: Vec<[f64; 3]> = p.iter().map(|v| [v[0], v[1], v[2]]).collect();
            let v = savitzky_golay_derivative3(&s.t, &p3, DEFAULT_HALF_WIDTH);
            s.groups
                .insert(Group::Velocity, v.iter().map(|x| x.to_vec()).collect());
            report
                .derived
                .push(format!("velocity (from position, {})", s.name));
        }
    }
    for s in &streams {
        report.gaps.extend(gaps_of(s));
        report.unread_columns.extend(s.unread.iter().cloned());
    }
    // Source stream of each group.
    let source = |g: Group| streams.iter().position(|s| s.groups.contains_key(&g));
    let names = || {
        streams
            .iter()
            .map(|s| s.name.as_str())
            .collect::<Vec<_>>()
            .join(", ")
    };
    let missing = |g: Group, columns: String| InputError::MissingQuantity {
        quantity: g.key().to_string(),
        columns,
        streams: names(),
        candidates: close_names(&streams, g),
    };
    for g in [Group::Position, Group::Attitude, Group::Omega] {
        if source(g).is_none() {
            return Err(missing(g, g.columns().join(",")));
        }
    }
    let has_wrench = source(Group::Force).is_some() && source(Group::Torque).is_some();
    if !has_wrench {
        let rotor = source(Group::RotorSpeeds);
        if rotor.is_none() || options.vehicle.is_none() {
            let mut e = missing(Group::Force, "fx,fy,fz,tx,ty,tz".into());
            if let InputError::MissingQuantity {
                quantity,
                candidates,
                ..
            } = &mut e
            {
                *quantity = "wrench".into();
                if rotor.is_some() {
                    candidates.push_str(
                        "; the streams have rotor speeds w1..w4: give a vehicle file to compute \
                         the wrench from them",
                    );
                } else {
                    candidates.push_str(
                        "; or give rotor speeds w1..w4 with a vehicle file to compute it",
                    );
                }
            }
            return Err(e);
        }
    }
    // The accelerometer is read only when no stream has the world acceleration itself (which
    // then wins, as the wrench wins over the rotor speeds).
    let has_world_accel = source(Group::Accel).is_some();
    let used: Vec<(Group, usize)> = Group::ALL
        .iter()
        .filter(|&&g| !(g == Group::SpecificForce && has_world_accel))
        .filter_map(|&g| source(g).map(|s| (g, s)))
        .collect();
    for (g, s) in &used {
        report
            .sources
            .push((g.key().to_string(), streams[*s].name.clone()));
    }
    // Each stream's rate, span and overlap with the time base; a stream that provides a
    // quantity must be dense enough and overlap the base.
    let base = &streams[0].t;
    let (Some(&base_start), Some(&base_end)) = (base.first(), base.last()) else {
        // A time base without a sample: the log would be empty.
        return Err(InputError::Log(LogError::in_file(
            streams[0].name.clone(),
            LogError::TooShort {
                rows: 0,
                needed: crate::log::MIN_ROWS,
            },
        )));
    };
    let base_span = base_end - base_start;
    for (k, s) in streams.iter().enumerate() {
        let provides: Vec<Group> = used
            .iter()
            .filter(|(_, u)| *u == k)
            .map(|(g, _)| *g)
            .collect();
        let step = median_step(&s.t);
        let (Some(&start), Some(&end)) = (s.t.first(), s.t.last()) else {
            // A stream without a sample provides nothing (a quantity it maps is too sparse).
            if provides.is_empty() {
                continue;
            }
            return Err(InputError::StreamTooSparse {
                stream: s.name.clone(),
                samples: 0,
                step,
                rate: 1.0 / step,
                quantities: provides
                    .iter()
                    .map(|g| g.key())
                    .collect::<Vec<_>>()
                    .join(", "),
            });
        };
        let overlap = (end.min(base_end) - start.max(base_start)).max(0.0);
        let overlap_fraction = if k == 0 || base_span <= 0.0 {
            1.0
        } else {
            overlap / base_span
        };
        let keys = || {
            provides
                .iter()
                .map(|g| g.key())
                .collect::<Vec<_>>()
                .join(", ")
        };
        let fast_needed = provides
            .iter()
            .any(|g| !matches!(g, Group::Position | Group::Velocity));
        if !provides.is_empty()
            && (s.t.len() < MIN_STREAM_SAMPLES
                || (fast_needed && (step.is_nan() || step > MAX_STREAM_STEP)))
        {
            return Err(InputError::StreamTooSparse {
                stream: s.name.clone(),
                samples: s.t.len(),
                step,
                rate: 1.0 / step,
                quantities: keys(),
            });
        }
        if !provides.is_empty() && overlap_fraction < MIN_STREAM_OVERLAP {
            return Err(InputError::StreamOverlap {
                stream: s.name.clone(),
                start,
                end,
                offset: s.offset,
                primary: streams[0].name.clone(),
                base_start,
                base_end,
                overlap,
                percent: overlap_fraction * 100.0,
            });
        }
        if provides.is_empty() && k > 0 {
            report.warnings.push(format!(
                "{} provides no quantity (each came from an earlier stream): it was not used",
                s.name
            ));
        }
        report.streams.push(StreamSummary {
            stream: s.name.clone(),
            samples: s.t.len(),
            rate: 1.0 / step,
            start,
            end,
            offset: s.offset,
            overlap,
            overlap_fraction,
            dropped: 0,
            provides: provides.iter().map(|g| g.key().to_string()).collect(),
        });
    }
    // Merge onto the primary's time base.
    let max_steps: Vec<f64> = streams
        .iter()
        .map(|s| GAP_FACTOR * median_step(&s.t))
        .collect();
    let mut cursors = vec![0usize; streams.len()];
    let mut log = FlightLog::new();
    let mut rows: BTreeMap<Group, Vec<Vec<f64>>> = BTreeMap::new();
    let mut kept = Vec::new();
    'sample: for (i, &ti) in base.iter().enumerate() {
        let mut at: Vec<Option<(usize, f64)>> = vec![None; streams.len()];
        at[0] = Some((i, 0.0));
        for (_, s) in &used {
            if at[*s].is_some() {
                continue;
            }
            match bracket(&streams[*s].t, ti, max_steps[*s], &mut cursors[*s]) {
                Ok(b) => at[*s] = Some(b),
                Err(in_gap) => {
                    if in_gap {
                        report.dropped_in_gaps += 1;
                    } else {
                        report.dropped_outside += 1;
                    }
                    report.streams[*s].dropped += 1;
                    continue 'sample;
                }
            }
        }
        kept.push(i);
        log.t.push(ti);
        for (g, s) in &used {
            let (k, f) = at[*s].unwrap_or((i, 0.0));
            rows.entry(*g).or_default().push(interp(
                &streams[*s].groups[g],
                k,
                f,
                *g == Group::Attitude,
            ));
        }
    }
    for s in &report.streams {
        let fraction = s.dropped as f64 / base.len() as f64;
        if fraction > DROPPED_WARNING_FRACTION {
            report.warnings.push(format!(
                "{} of the time base's {} samples ({:.0} %) dropped because of {} (outside its \
                 time range t = {:.3} to {:.3} s, offset {} s, or in its gaps): check its clock \
                 and offset",
                s.dropped,
                base.len(),
                fraction * 100.0,
                s.stream,
                s.start,
                s.end,
                s.offset
            ));
        }
    }
    let from = |g: Group| {
        used.iter()
            .find(|(u, _)| *u == g)
            .map_or("", |(_, s)| streams[*s].name.as_str())
    };
    if mapping.normalize_quaternion
        && let Some((_, s)) = used.iter().find(|(g, _)| *g == Group::Attitude)
    {
        let dev = streams[*s].renormalised;
        report.quaternion_renormalised = Some(dev);
        report.warnings.push(format!(
            "the quaternions of {} were divided by their norm (normalize_quaternion): the \
             largest |‖q‖ − 1| was {dev:.4}",
            streams[*s].name
        ));
    }
    let v3 = |g: Group| -> Option<Vec<[f64; 3]>> {
        rows.get(&g)
            .map(|r| r.iter().map(|v| [v[0], v[1], v[2]]).collect())
    };
    log.position = v3(Group::Position).unwrap_or_default();
    log.velocity = v3(Group::Velocity).unwrap_or_default();
    log.omega = v3(Group::Omega).unwrap_or_default();
    log.attitude = rows
        .get(&Group::Attitude)
        .map(|r| r.iter().map(|v| [v[0], v[1], v[2], v[3]]).collect())
        .unwrap_or_default();
    log.accel = v3(Group::Accel);
    if let Some(a) = &log.accel {
        if mapping.accel == AccelColumns::WorldSpecificForce {
            report.derived.push(format!(
                "accel (world, from the world-frame specific force ax..az of {}: p̈ = f_w + g_w)",
                from(Group::Accel)
            ));
        } else {
            check_accel_is_acceleration(a, &log.t, &log.velocity, from(Group::Accel))?;
        }
    }
    if log.accel.is_none()
        && let Some(f) = v3(Group::SpecificForce)
    {
        log.accel = Some(world_acceleration(&log.attitude, &f));
        report.derived.push(format!(
            "accel (world, from the accelerometer's specific force of {} and the attitude of {})",
            from(Group::SpecificForce),
            from(Group::Attitude)
        ));
    }
    log.omega_dot = v3(Group::OmegaDot);
    log.rotor_speeds = rows
        .get(&Group::RotorSpeeds)
        .map(|r| r.iter().map(|v| [v[0], v[1], v[2], v[3]]).collect());
    if let (Some(f), Some(t)) = (v3(Group::Force), v3(Group::Torque)) {
        log.wrench = f
            .iter()
            .zip(&t)
            .map(|(f, t)| [f[0], f[1], f[2], t[0], t[1], t[2]])
            .collect();
    } else if let Some(vehicle) = options.vehicle {
        let named = |e: LogError| {
            LogError::in_file(format!("{} (merged onto its time base)", report.primary), e)
        };
        log.compute_wrench_from_rotor_speeds(vehicle)
            .map_err(named)?;
        report.derived.push(format!(
            "wrench (from rotor speeds, vehicle `{}`)",
            vehicle.name
        ));
    }
    // Extra columns: the primary stream's (others are not interpolated).
    for (name, v) in &streams[0].extra {
        log.add_extra(name, kept.iter().map(|&i| v[i]).collect());
    }
    report.lines = kept.iter().map(|&i| streams[0].lines[i]).collect();
    log.validate().map_err(|e| match e {
        LogError::TooShort { .. } => e,
        other => LogError::in_file(
            format!("{} (merged onto its time base)", report.primary),
            other,
        ),
    })?;
    Ok((log, report))
}

/// Refuses `ax..az` read as the world acceleration `p̈` whose mean on z is more than `g/2`
/// away from what the velocity's change over the log implies (`Δv_z / T`). A flight's `p̈`
/// averages `Δv / T`, so such columns are most likely the world-frame specific force.
fn check_accel_is_acceleration(
    accel: &[[f64; 3]],
    t: &[f64],
    velocity: &[[f64; 3]],
    stream: &str,
) -> Result<(), InputError> {
    match crate::log::accel_looks_like_specific_force(accel, t, velocity) {
        Some((mean_z, from_velocity)) => Err(InputError::AccelLooksLikeSpecificForce {
            stream: stream.to_string(),
            mean_z,
            from_velocity,
        }),
        None => Ok(()),
    }
}
