//! Foreign flight logs in: a **column mapping** (renames, units, quaternion order, frames) and
//! **several streams** (one CSV file per topic, each with its own time column and rate) merged
//! onto one time base, giving a [`FlightLog`] in the project's format (see [`crate::log`]).
//!
//! # The mapping file (TOML)
//!
//! ```toml
//! [columns]                 # project column = column name in the file (or a list of names:
//! t = ["timestamp", "time"] # the first one a stream has is used)
//! px = "pos.x"
//! q = ["q0", "q1", "q2", "q3"]   # the four quaternion columns, in file order
//!
//! [units]                   # by project column or group; SI if absent
//! t = "ms"                  # s, ms, us (µs), ns
//! position = "mm"           # m, cm, mm   (groups: position velocity accel specific_force
//! omega = "deg/s"           #   omega omega_dot force torque rotor_speeds time)
//! rotor_speeds = "rpm"      # rad/s, deg/s, rpm
//! specific_force = "g"      # the accelerometer (sfx, sfy, sfz): m/s2, mm/s2, g
//!
//! [frames]
//! world = "ned"             # enu (default: z up) or ned
//! body = "frd"              # flu (default: x forward, y left, z up) or frd
//! quaternion = "xyzw"       # order of the `q` list: wxyz (default) or xyzw
//!
//! [streams]                 # optional
//! files = ["imu.csv", "mocap.csv"]   # relative to the mapping file
//! primary = "imu.csv"       # whose time stamps are the time base (default: the first file)
//! [streams."mocap.csv"]     # per-stream settings, by file name
//! offset = 0.02             # [s], added to this stream's time stamps
//! units = { t = "us" }      # overrides of [units] (and `columns = {...}` of [columns])
//! ```
//!
//! Units (factor to SI): time `s` 1, `ms` 1e-3, `us`/`µs` 1e-6, `ns` 1e-9; length `m` 1, `cm`
//! 1e-2, `mm` 1e-3; speed `m/s`, `cm/s`, `mm/s`; acceleration `m/s2`, `mm/s2`, `g` (9.80665);
//! angular rate `rad/s` 1, `deg/s` π/180, `rpm` 2π/60; angular acceleration `rad/s2`,
//! `deg/s2`; force `N`, `mN`; torque `Nm`, `mNm`, `Nmm`; extra columns also take `rad`, `deg`.
//! A unit that does not fit the column's quantity (`t = "rpm"`) is an error.
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
//! `specific_force`) are what an accelerometer at the body origin measures: the **specific
//! force** `f = Rᵀ (p̈ − g_w)`, body frame (a vehicle at rest, level, reads `+1 g` along body
//! up: `(0, 0, 9.81)` m/s² in FLU, `(0, 0, −9.81)` in FRD). They are not the wrench `fx..fz`
//! (a force in N) nor the world acceleration `ax..az` (`p̈`, gravity removed). After the merge
//! they become the log's world acceleration `p̈ = R f + g_w` ([`world_acceleration`]) with the
//! merged attitude `R` and the project's `g_w = (0, 0, −9.81)` m/s² (the one the regressor
//! subtracts again, so it sees `f` exactly, whatever the local gravity). A stream with
//! `ax..az` wins over the accelerometer. The accelerometer is taken to sit at the body origin
//! (a lever arm `r` adds `ω̇ × r + ω × (ω × r)`, not removed here); its bias and scale errors
//! are not corrected.
//!
//! # Several streams
//!
//! The time base is the primary stream's time stamps (after its unit and offset). Each quantity
//! (position, velocity, attitude, angular velocity, wrench, rotor speeds, …) is taken from the
//! primary stream if it has it, else from the first other stream that has it, and linearly
//! interpolated onto the time base (quaternions: normalised linear interpolation, after
//! flipping the later sample onto the earlier one's hemisphere). A **gap** of a stream is a
//! step longer than [`GAP_FACTOR`] times its median step; a primary sample that falls inside a
//! gap of a stream it interpolates, or outside that stream's time range, is **dropped** (never
//! interpolated over) and counted in the [`MergeReport`]. Gaps of the primary stream itself
//! are reported too (the diagnosis splits the log at every gap, [`FlightLog::sampling`]).
//!
//! Derived columns: a stream with position but no velocity gets its velocity by the
//! Savitzky–Golay derivative ([`crate::deriv`], half-width [`crate::deriv::DEFAULT_HALF_WIDTH`])
//! on its own time base before the merge. The world acceleration comes from the accelerometer
//! when a stream has one (above). Acceleration (without an accelerometer) and angular
//! acceleration, when absent, are derived by the diagnosis (see [`FlightLog::accel`]). A log
//! without the wrench `fx..tz` but with rotor speeds `w1..w4` needs a
//! [vehicle](crate::vehicle): pass it as [`ReadOptions::vehicle`] (the wrench is then computed
//! after the merge, on the time base).

use std::collections::BTreeMap;
use std::io::Read;
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
    /// No stream was given.
    #[error("no stream file: give a log, `--stream FILE`, or `files` in the mapping's [streams]")]
    NoStream,
}

/// One stream's settings that may differ from the global ones.
#[derive(Debug, Clone, Default, PartialEq)]
struct StreamSettings {
    offset: f64,
    columns: BTreeMap<String, Vec<String>>,
    units: BTreeMap<String, String>,
}

/// A column mapping (the module docs give the file format); [`ColumnMapping::default`] is the
/// identity (project names, SI units, project frames).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ColumnMapping {
    /// Project column → candidate file column names.
    columns: BTreeMap<String, Vec<String>>,
    /// The quaternion columns in file order (`q = [...]`).
    quaternion: Option<[String; 4]>,
    /// Project column or group key → unit.
    units: BTreeMap<String, String>,
    /// The log's world frame.
    pub world: WorldFrame,
    /// The log's body frame.
    pub body: BodyFrame,
    /// The order of the `q` list.
    pub quaternion_order: QuaternionOrder,
    /// Stream files named by the mapping (resolved against the mapping file's folder).
    pub files: Vec<PathBuf>,
    /// The primary stream's file name, if set.
    pub primary: Option<String>,
    /// Per-stream settings by file name.
    streams: BTreeMap<String, StreamSettings>,
}

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

fn table<'a>(v: &'a toml::Value, what: &str) -> Result<&'a toml::Table, String> {
    v.as_table()
        .ok_or_else(|| format!("`{what}` must be a table"))
}

fn parse_columns(t: &toml::Table, allow_q: bool) -> Result<ColumnsParsed, String> {
    let mut out = ColumnsParsed::default();
    for (k, v) in t {
        if k == "q" && allow_q {
            let list = str_list(v, "columns.q")?;
            let arr: [String; 4] = list
                .try_into()
                .map_err(|_| "columns.q: expected the four quaternion columns".to_string())?;
            out.quaternion = Some(arr);
        } else {
            out.columns
                .insert(k.clone(), str_list(v, &format!("columns.{k}"))?);
        }
    }
    Ok(out)
}

#[derive(Default)]
struct ColumnsParsed {
    columns: BTreeMap<String, Vec<String>>,
    quaternion: Option<[String; 4]>,
}

fn parse_units(t: &toml::Table, what: &str) -> Result<BTreeMap<String, String>, String> {
    let mut out = BTreeMap::new();
    for (k, v) in t {
        let u = v
            .as_str()
            .ok_or_else(|| format!("{what}.{k}: expected a unit name"))?;
        let (_, _, q) = unit_entry(u).ok_or_else(|| {
            let known: Vec<&str> = UNITS.iter().map(|x| x.0).collect();
            format!(
                "{what}.{k}: unknown unit `{u}` (known: {})",
                known.join(", ")
            )
        })?;
        if let Some(expected) = key_quantity(k)
            && expected != q
        {
            return Err(format!(
                "{what}.{k}: unit `{u}` does not fit (a {expected:?} unit is expected)"
            ));
        }
        out.insert(k.clone(), u.to_string());
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

impl ColumnMapping {
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
            if f.is_relative() {
                *f = dir.join(&*f);
            }
        }
        Ok(m)
    }

    /// Parses a mapping from TOML text.
    ///
    /// # Errors
    /// A message naming the offending key or the TOML syntax error with its line.
    pub fn from_toml_str(text: &str) -> Result<Self, String> {
        let doc: toml::Table = text.parse().map_err(|e: toml::de::Error| e.to_string())?;
        let mut m = ColumnMapping::default();
        for (key, value) in &doc {
            match key.as_str() {
                "columns" => {
                    let c = parse_columns(table(value, "columns")?, true)?;
                    m.columns = c.columns;
                    m.quaternion = c.quaternion;
                }
                "units" => m.units = parse_units(table(value, "units")?, "units")?,
                "frames" => {
                    for (k, v) in table(value, "frames")? {
                        let s = v.as_str().unwrap_or("").to_ascii_lowercase();
                        match (k.as_str(), s.as_str()) {
                            ("world", "enu") => m.world = WorldFrame::Enu,
                            ("world", "ned") => m.world = WorldFrame::Ned,
                            ("body", "flu") => m.body = BodyFrame::Flu,
                            ("body", "frd") => m.body = BodyFrame::Frd,
                            ("quaternion", "wxyz") => m.quaternion_order = QuaternionOrder::Wxyz,
                            ("quaternion", "xyzw") => m.quaternion_order = QuaternionOrder::Xyzw,
                            ("world" | "body" | "quaternion", _) => {
                                return Err(format!(
                                    "frames.{k}: unknown value {v:?} (world: enu, ned; body: flu, \
                                     frd; quaternion: wxyz, xyzw)"
                                ));
                            }
                            _ => {
                                return Err(format!(
                                    "frames: unknown key `{k}` (known: world, body, quaternion)"
                                ));
                            }
                        }
                    }
                }
                "streams" => {
                    for (k, v) in table(value, "streams")? {
                        match k.as_str() {
                            "files" => {
                                m.files = str_list(v, "streams.files")?
                                    .into_iter()
                                    .map(PathBuf::from)
                                    .collect();
                            }
                            "primary" => {
                                m.primary = Some(
                                    v.as_str()
                                        .ok_or("streams.primary: expected a file name")?
                                        .to_string(),
                                );
                            }
                            name => {
                                let mut s = StreamSettings::default();
                                for (sk, sv) in table(v, &format!("streams.{name}"))? {
                                    match sk.as_str() {
                                        "offset" => {
                                            s.offset = sv
                                                .as_float()
                                                .or_else(|| sv.as_integer().map(|i| i as f64))
                                                .filter(|x| x.is_finite())
                                                .ok_or_else(|| {
                                                    format!(
                                                        "streams.\"{name}\".offset: expected \
                                                         seconds"
                                                    )
                                                })?;
                                        }
                                        "columns" => {
                                            s.columns =
                                                parse_columns(table(sv, "columns")?, false)?
                                                    .columns;
                                        }
                                        "units" => {
                                            s.units = parse_units(
                                                table(sv, "units")?,
                                                &format!("streams.\"{name}\".units"),
                                            )?;
                                        }
                                        other => {
                                            return Err(format!(
                                                "streams.\"{name}\": unknown key `{other}` \
                                                 (known: offset, columns, units)"
                                            ));
                                        }
                                    }
                                }
                                m.streams.insert(name.to_string(), s);
                            }
                        }
                    }
                }
                other => {
                    return Err(format!(
                        "unknown table `{other}` (known: columns, units, frames, streams)"
                    ));
                }
            }
        }
        Ok(m)
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
#[derive(Debug, Clone, PartialEq)]
pub struct Gap {
    /// The stream's file.
    pub stream: String,
    /// Time of the last sample before the gap \[s\] (project time base).
    pub start: f64,
    /// Length of the gap \[s\].
    pub duration: f64,
}

/// What the merge did: gaps found, samples dropped.
#[derive(Debug, Clone, Default, PartialEq)]
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
}

/// A stream's cells: header, one vector per column, the CSV line of each row.
type Table = (Vec<String>, Vec<Vec<f64>>, Vec<usize>);

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
    groups: BTreeMap<Group, Vec<Vec<f64>>>,
    extra: Vec<(String, Vec<f64>)>,
}

fn file_name(path: &Path) -> String {
    path.file_name().map_or_else(
        || path.display().to_string(),
        |s| s.to_string_lossy().into_owned(),
    )
}

/// Reads the header and every cell (as numbers) of a CSV stream.
fn read_table<R: Read>(reader: R) -> Result<Table, LogError> {
    let mut rows = NumericRows::new(reader)?;
    let header = rows.header.clone();
    let mut cols = vec![Vec::new(); header.len()];
    let mut lines = Vec::new();
    let mut values = vec![0.0; header.len()];
    while let Some(line) = rows.next_into(&mut values)? {
        for (col, &x) in cols.iter_mut().zip(&values) {
            col.push(x);
        }
        lines.push(line);
    }
    Ok((header, cols, lines))
}

/// The factor to SI of a project column under a unit table.
fn factor_of(units: &BTreeMap<String, String>, column: &str, group: Option<Group>) -> f64 {
    let unit = units
        .get(column)
        .or_else(|| group.and_then(|g| units.get(g.key())))
        .or_else(|| (column == "t").then(|| units.get("time")).flatten());
    unit.and_then(|u| unit_factor(u)).unwrap_or(1.0)
}

impl ColumnMapping {
    /// Reads one stream file with this mapping.
    fn read_stream(&self, path: &Path) -> Result<Stream, InputError> {
        let name = file_name(path);
        let in_file =
            |e: LogError| InputError::Log(LogError::in_file(path.display().to_string(), e));
        let file = crate::log::open_log_file(path)?;
        let (header, cols, lines) = read_table(std::io::BufReader::new(file)).map_err(in_file)?;
        let per = self.streams.get(&name).cloned().unwrap_or_default();
        let mut columns = self.columns.clone();
        columns.extend(per.columns.clone());
        let mut units = self.units.clone();
        units.extend(per.units.clone());
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
        }
        let find = |project: &str| -> Option<usize> {
            if let Some(c) = quaternion_cols.get(project) {
                return header.iter().position(|h| h == c);
            }
            if let Some(cands) = columns.get(project) {
                for c in cands {
                    if let Some(j) = header.iter().position(|h| h == c) {
                        return Some(j);
                    }
                }
                // A mapped name that is absent: fall back on the project name itself.
            }
            header.iter().position(|h| h == project)
        };
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
        let mut used = vec![jt];
        let mut groups = BTreeMap::new();
        for g in Group::ALL {
            let idx: Vec<Option<usize>> = g.columns().iter().map(|c| find(c)).collect();
            if idx.iter().all(Option::is_some) {
                let idx: Vec<usize> = idx.into_iter().flatten().collect();
                used.extend(&idx);
                let rows: Vec<Vec<f64>> = (0..t.len())
                    .map(|i| {
                        g.columns()
                            .iter()
                            .zip(&idx)
                            .map(|(c, &j)| cols[j][i] * factor_of(&units, c, Some(g)))
                            .collect()
                    })
                    .collect();
                groups.insert(g, rows);
            }
        }
        let extra = (0..header.len())
            .filter(|j| !used.contains(j))
            .map(|j| {
                let k = factor_of(&units, &header[j], None);
                (header[j].clone(), cols[j].iter().map(|x| x * k).collect())
            })
            .collect();
        let mut s = Stream {
            name,
            header,
            t,
            groups,
            extra,
        };
        self.convert_frames(&mut s);
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

/// The world acceleration `p̈ = R f + g_w` \[m/s²\] (project frames) of each sample from the
/// attitude `(w, x, y, z)` (body → world; normalised here, so a norm within the log's tolerance
/// does not scale the result) and the accelerometer's specific force `f` (body frame)
/// \[m/s²\]: the inverse of [`crate::proper_acceleration`], with the same [`GRAVITY_WORLD`],
/// so the regressor's `Rᵀ (p̈ − g_w)` gives back `f`.
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
/// [`InputError::NoStream`] for no file; file, line and column of a bad cell or time stamp;
/// [`InputError::MissingQuantity`] for a quantity no stream provides (with close header names);
/// the [`FlightLog::validate`] errors of the merged log.
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
    let primary = mapping
        .primary
        .as_ref()
        .and_then(|p| streams.iter().position(|s| &s.name == p))
        .unwrap_or(0);
    streams.swap(0, primary);
    let mut report = MergeReport {
        primary: streams[0].name.clone(),
        ..MergeReport::default()
    };
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
    // Merge onto the primary's time base.
    let base = &streams[0].t;
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
                Err(true) => {
                    report.dropped_in_gaps += 1;
                    continue 'sample;
                }
                Err(false) => {
                    report.dropped_outside += 1;
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
    if log.accel.is_none()
        && let Some(f) = v3(Group::SpecificForce)
    {
        log.accel = Some(world_acceleration(&log.attitude, &f));
        let from = |g: Group| {
            used.iter()
                .find(|(u, _)| *u == g)
                .map_or("", |(_, s)| streams[*s].name.as_str())
        };
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
    log.validate().map_err(|e| match e {
        LogError::TooShort { .. } => e,
        other => LogError::in_file(
            format!("{} (merged onto its time base)", report.primary),
            other,
        ),
    })?;
    Ok((log, report))
}
