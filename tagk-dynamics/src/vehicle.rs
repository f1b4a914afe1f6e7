//! Vehicle descriptions: what turns a log's rotor speeds into the body wrench.
//!
//! A [`Vehicle`] holds the rotor layout (hub positions in the body frame, spin directions),
//! the thrust curve and reaction torque of the rotors, and the largest rotor speed. It may also
//! hold priors (motor time constant, mass, inertia) and the airframe radius the diagnosis uses
//! to flag an implausible centre of mass. It is read from a small TOML file
//! ([`Vehicle::from_path`], [`Vehicle::from_toml_str`]), or taken from the built-in presets
//! ([`Vehicle::preset`], [`PRESETS`]). [`Vehicle::to_toml_string`] writes one back as a
//! commented template. The repository's `docs/VEHICLE.md` describes the format key by key.
//!
//! With a vehicle, a flight log that holds the rotor speeds `w1..w4` but not the wrench
//! `fx..tz` gets its wrench from [`FlightLog::compute_wrench_from_rotor_speeds`].
//! The force is `(0, 0, Σ T(ωᵢ))`, the torque `Σ rᵢ × (0, 0, T(ωᵢ)) + (0, 0, Σ sᵢ Q(ωᵢ))`
//! (the formula of [`rotor_wrench`]).
//!
//! ```
//! use tagk_dynamics::vehicle::Vehicle;
//! use tagk_dynamics::QuadrotorModel;
//!
//! let cf = Vehicle::preset("crazyflie-2.1")?;
//! #[cfg(feature = "toml")]
//! {
//!     let text = cf.to_toml_string();
//!     assert_eq!(Vehicle::from_toml_str(&text)?, cf);
//! }
//! let w = [2000.0, 2100.0, 1900.0, 2050.0];
//! assert_eq!(
//!     cf.wrench_from_rotor_speeds(&w),
//!     QuadrotorModel::crazyflie_2_1().wrench_from_rotor_speeds(&w)
//! );
//! # Ok::<(), tagk_dynamics::vehicle::VehicleError>(())
//! ```

#[cfg(feature = "toml")]
use std::fmt::Write as _;
#[cfg(feature = "toml")]
use std::path::Path;

use nalgebra::Vector3;
use serde::Deserialize;
use thiserror::Error;

use crate::log::{FlightLog, LogError, ROTOR_SPEED_COLUMNS};
use crate::quadrotor::{QuadrotorModel, rotor_wrench};
use crate::{InertialParams, SafetyGate, Wrench};

/// Number of rotors a vehicle has (the log's rotor-speed columns `w1..w4`).
pub const ROTOR_COUNT: usize = 4;

/// The built-in presets, by name (`--vehicle NAME`).
pub const PRESETS: [&str; 1] = ["crazyflie-2.1"];

/// A rotor speed this many times the vehicle's `max_rotor_speed` is refused as a unit error
/// (rpm logged as rad/s is ≈ 9.5 times too large).
pub const ROTOR_SPEED_MARGIN: f64 = 1.5;

/// Direction a rotor spins, seen from above (from body `+z`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
pub enum Spin {
    /// Clockwise seen from above: the reaction torque turns the body counter-clockwise
    /// (`+z`). Written `"cw"`.
    #[serde(rename = "cw")]
    Clockwise,
    /// Counter-clockwise seen from above: reaction torque about `−z`. Written `"ccw"`.
    #[serde(rename = "ccw")]
    CounterClockwise,
}

impl Spin {
    /// Sign of the rotor's reaction torque about body `+z` (`+1` clockwise, `−1`
    /// counter-clockwise; the `spin_directions` of [`QuadrotorModel`]).
    pub fn sign(self) -> f64 {
        match self {
            Spin::Clockwise => 1.0,
            Spin::CounterClockwise => -1.0,
        }
    }

    /// The spin whose reaction-torque sign is that of `sign` (`> 0`: clockwise).
    pub fn from_sign(sign: f64) -> Self {
        if sign > 0.0 {
            Spin::Clockwise
        } else {
            Spin::CounterClockwise
        }
    }

    /// The name in a vehicle file: `"cw"` or `"ccw"`.
    pub fn name(self) -> &'static str {
        match self {
            Spin::Clockwise => "cw",
            Spin::CounterClockwise => "ccw",
        }
    }
}

/// One rotor: where its hub is and which way it spins.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rotor {
    /// Hub position in the body frame (x forward, y left, z up) \[m\].
    pub position: Vector3<f64>,
    /// Spin direction seen from above.
    pub spin: Spin,
}

/// Thrust `T(ω)` \[N\] of one rotor at speed `ω` \[rad/s\].
#[derive(Debug, Clone, PartialEq)]
pub enum ThrustCurve {
    /// `T = k_f ω²` (key `k_f`, \[N/(rad/s)²\]).
    Quadratic {
        /// Thrust coefficient \[N/(rad/s)²\].
        k_f: f64,
    },
    /// `T = c₀ + c₁ ω + c₂ ω² + …` (key `thrust_curve = [c₀, c₁, …]`, `c_k` in
    /// \[N/(rad/s)^k\]).
    Polynomial {
        /// Coefficients, constant term first.
        coefficients: Vec<f64>,
    },
}

impl ThrustCurve {
    /// The thrust at rotor speed `omega` \[rad/s\] \[N\].
    pub fn thrust(&self, omega: f64) -> f64 {
        match self {
            ThrustCurve::Quadratic { k_f } => k_f * omega * omega,
            ThrustCurve::Polynomial { coefficients } => coefficients
                .iter()
                .rev()
                .fold(0.0, |acc, c| acc * omega + c),
        }
    }
}

/// Magnitude `Q` \[N m\] of one rotor's reaction (drag) torque.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ReactionTorque {
    /// `Q = k_m ω²` (key `k_m`, \[N m/(rad/s)²\]).
    Coefficient {
        /// Reaction-torque coefficient \[N m/(rad/s)²\].
        k_m: f64,
    },
    /// `Q = ratio · T(ω)` (key `torque_ratio`, \[m\]; PX4's `CA_ROTORn_KM`).
    Ratio {
        /// Torque-to-thrust ratio \[m\].
        ratio: f64,
    },
}

/// A multirotor vehicle description (see the [module](self) documentation).
#[derive(Debug, Clone, PartialEq)]
pub struct Vehicle {
    /// Name (a preset's name, or the file's `name` key).
    pub name: String,
    /// The four rotors, in the order of the log's columns `w1..w4`.
    pub rotors: [Rotor; ROTOR_COUNT],
    /// Thrust of one rotor as a function of its speed.
    pub thrust: ThrustCurve,
    /// Reaction torque of one rotor.
    pub reaction_torque: ReactionTorque,
    /// Largest rotor speed \[rad/s\] (speeds beyond [`ROTOR_SPEED_MARGIN`] times it are
    /// refused as a unit error).
    pub max_rotor_speed: f64,
    /// First-order motor time constant \[s\], if known (informative: the diagnosis's
    /// `motor-lag` candidate fits its own).
    pub motor_time_constant: Option<f64>,
    /// Mass prior \[kg\] (`tagk diagnose --mass vehicle` fixes the mass to it).
    pub mass: Option<f64>,
    /// Inertia prior about the body origin, `[I_xx, I_xy, I_yy, I_xz, I_yz, I_zz]` \[kg m²\]
    /// (the last six entries of the parameter order).
    pub inertia: Option<[f64; 6]>,
    /// Radius \[m\] beyond which a fitted centre of mass is implausible (the diagnosis's
    /// default `--airframe-radius`).
    pub airframe_radius: f64,
}

/// A problem with a vehicle description: TOML errors name the line and column, invalid values
/// name the key.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum VehicleError {
    /// TOML syntax error, unknown key, missing key or a value of the wrong type.
    #[error("line {line}, column {column}: {message}")]
    Toml {
        /// 1-based line.
        line: usize,
        /// 1-based column (in characters).
        column: usize,
        /// What the TOML reader reported.
        message: String,
    },
    /// A value that is out of range or inconsistent with another key.
    #[error("key `{key}`: {message}")]
    InvalidKey {
        /// The key (e.g. `k_f`, `rotor[2].position`).
        key: String,
        /// What is wrong.
        message: String,
    },
    /// Neither a preset nor an existing file.
    #[error("`{name}` is neither a vehicle preset ({available}) nor a vehicle file")]
    UnknownVehicle {
        /// What was asked for.
        name: String,
        /// The presets, comma separated.
        available: String,
    },
    /// A problem in a vehicle file: the file and the problem.
    #[error("{path}: {source}")]
    InFile {
        /// The file.
        path: String,
        /// The problem.
        #[source]
        source: Box<VehicleError>,
    },
    /// The file could not be read.
    #[error("{path}: {message}")]
    Io {
        /// The file.
        path: String,
        /// The OS error.
        message: String,
    },
}

#[cfg(feature = "toml")]
/// The file's keys, as written (validated into a [`Vehicle`]).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct VehicleFile {
    name: Option<String>,
    airframe_radius: Option<f64>,
    max_rotor_speed: f64,
    motor_time_constant: Option<f64>,
    k_f: Option<f64>,
    thrust_curve: Option<Vec<f64>>,
    k_m: Option<f64>,
    torque_ratio: Option<f64>,
    mass: Option<f64>,
    inertia: Option<[f64; 6]>,
    rotor: Vec<RotorFile>,
}

#[cfg(feature = "toml")]
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RotorFile {
    position: [f64; 3],
    spin: Spin,
}

fn invalid(key: impl Into<String>, message: impl Into<String>) -> VehicleError {
    VehicleError::InvalidKey {
        key: key.into(),
        message: message.into(),
    }
}

fn positive(key: &str, x: f64, unit: &str) -> Result<f64, VehicleError> {
    if x.is_finite() && x > 0.0 {
        Ok(x)
    } else {
        Err(invalid(
            key,
            format!("{x} {unit} is not positive and finite"),
        ))
    }
}

#[cfg(feature = "toml")]
/// 1-based line and column (in characters) of byte offset `at` in `text`.
fn line_column(text: &str, at: usize) -> (usize, usize) {
    let at = at.min(text.len());
    let before = text.get(..at).unwrap_or(text);
    let line = before.matches('\n').count() + 1;
    let start = before.rfind('\n').map_or(0, |i| i + 1);
    (line, before[start..].chars().count() + 1)
}

impl Vehicle {
    /// The Crazyflie 2.1 of the paper: [`QuadrotorModel::crazyflie_2_1`]'s rotors,
    /// coefficients, largest speed, mass and inertia (one source of truth), the airframe
    /// radius of [`SafetyGate::crazyflie`] (0.0325 m), no motor time constant.
    pub fn crazyflie_2_1() -> Self {
        Self::from_quadrotor(
            "crazyflie-2.1",
            &QuadrotorModel::crazyflie_2_1(),
            SafetyGate::crazyflie().max_com_offset,
        )
    }

    /// The vehicle of a [`QuadrotorModel`]: its rotors, `k_f`, `k_m`, largest speed, and its
    /// mass and inertia about the origin as priors.
    pub fn from_quadrotor(name: &str, model: &QuadrotorModel, airframe_radius: f64) -> Self {
        let theta = model.params.to_array();
        let rotors = std::array::from_fn(|i| Rotor {
            position: model.rotor_positions[i],
            spin: Spin::from_sign(model.spin_directions[i]),
        });
        Self {
            name: name.to_string(),
            rotors,
            thrust: ThrustCurve::Quadratic { k_f: model.k_f },
            reaction_torque: ReactionTorque::Coefficient { k_m: model.k_m },
            max_rotor_speed: model.max_rotor_speed,
            motor_time_constant: None,
            mass: Some(theta[0]),
            inertia: Some([theta[4], theta[5], theta[6], theta[7], theta[8], theta[9]]),
            airframe_radius,
        }
    }

    /// A built-in preset by name (see [`PRESETS`]).
    ///
    /// # Errors
    /// [`VehicleError::UnknownVehicle`] for another name.
    pub fn preset(name: &str) -> Result<Self, VehicleError> {
        match name {
            "crazyflie-2.1" => Ok(Self::crazyflie_2_1()),
            _ => Err(VehicleError::UnknownVehicle {
                name: name.to_string(),
                available: PRESETS.join(", "),
            }),
        }
    }

    #[cfg(feature = "toml")]
    /// A preset by name, or else a vehicle file at that path (what `--vehicle NAME|FILE`
    /// accepts).
    ///
    /// # Errors
    /// [`VehicleError::UnknownVehicle`] if it is neither a preset nor an existing file;
    /// otherwise the errors of [`Vehicle::from_path`].
    pub fn from_name_or_path(name_or_path: &str) -> Result<Self, VehicleError> {
        match Self::preset(name_or_path) {
            Ok(v) => Ok(v),
            Err(e) if !Path::new(name_or_path).exists() => Err(e),
            Err(_) => Self::from_path(name_or_path),
        }
    }

    #[cfg(feature = "toml")]
    /// Reads and validates a vehicle file. Without a `name` key, the vehicle is named after
    /// the file (its name without extension).
    ///
    /// # Errors
    /// [`VehicleError::Io`] if the file cannot be read, otherwise the error of
    /// [`Vehicle::from_toml_str`] wrapped in [`VehicleError::InFile`].
    pub fn from_path(path: impl AsRef<Path>) -> Result<Self, VehicleError> {
        let path = path.as_ref();
        let name = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|e| VehicleError::Io {
            path: name.clone(),
            message: e.to_string(),
        })?;
        let stem = path.file_stem().map_or_else(
            || "vehicle".to_string(),
            |s| s.to_string_lossy().into_owned(),
        );
        Self::parse(&text, &stem).map_err(|e| VehicleError::InFile {
            path: name,
            source: Box::new(e),
        })
    }

    #[cfg(feature = "toml")]
    /// Parses and validates a vehicle description (the TOML format of `docs/VEHICLE.md`).
    /// Without a `name` key the vehicle is named `vehicle`.
    ///
    /// # Errors
    /// [`VehicleError::Toml`] (line and column) for a syntax error, an unknown or missing key
    /// or a value of the wrong type; [`VehicleError::InvalidKey`] for a value out of range.
    pub fn from_toml_str(text: &str) -> Result<Self, VehicleError> {
        Self::parse(text, "vehicle")
    }

    #[cfg(feature = "toml")]
    fn parse(text: &str, default_name: &str) -> Result<Self, VehicleError> {
        let file: VehicleFile = toml::from_str(text).map_err(|e| {
            let (line, column) = e
                .span()
                .map_or((1, 1), |span| line_column(text, span.start));
            VehicleError::Toml {
                line,
                column,
                message: e.message().trim().to_string(),
            }
        })?;
        let v = Self::from_file(file, default_name)?;
        v.validate()?;
        Ok(v)
    }

    #[cfg(feature = "toml")]
    fn from_file(f: VehicleFile, default_name: &str) -> Result<Self, VehicleError> {
        let rotors: [Rotor; ROTOR_COUNT] = f
            .rotor
            .iter()
            .map(|r| Rotor {
                position: Vector3::from(r.position),
                spin: r.spin,
            })
            .collect::<Vec<_>>()
            .try_into()
            .map_err(|v: Vec<Rotor>| {
                invalid(
                    "rotor",
                    format!(
                        "{} [[rotor]] tables, {ROTOR_COUNT} needed (one per log column {})",
                        v.len(),
                        ROTOR_SPEED_COLUMNS.join(", ")
                    ),
                )
            })?;
        let thrust = match (f.k_f, f.thrust_curve) {
            (Some(k_f), None) => ThrustCurve::Quadratic { k_f },
            (None, Some(coefficients)) => ThrustCurve::Polynomial { coefficients },
            (Some(_), Some(_)) => {
                return Err(invalid(
                    "thrust_curve",
                    "give either `k_f` or `thrust_curve`, not both",
                ));
            }
            (None, None) => {
                return Err(invalid(
                    "k_f",
                    "missing: give the thrust coefficient `k_f` or a `thrust_curve`",
                ));
            }
        };
        let reaction_torque = match (f.k_m, f.torque_ratio) {
            (Some(k_m), None) => ReactionTorque::Coefficient { k_m },
            (None, Some(ratio)) => ReactionTorque::Ratio { ratio },
            (Some(_), Some(_)) => {
                return Err(invalid(
                    "torque_ratio",
                    "give either `k_m` or `torque_ratio`, not both",
                ));
            }
            (None, None) => {
                return Err(invalid(
                    "k_m",
                    "missing: give the reaction-torque coefficient `k_m` or a `torque_ratio`",
                ));
            }
        };
        let airframe_radius = match f.airframe_radius {
            Some(r) => r,
            None => rotors
                .iter()
                .map(|r| r.position.xy().norm())
                .fold(0.0, f64::max),
        };
        Ok(Self {
            name: f.name.unwrap_or_else(|| default_name.to_string()),
            rotors,
            thrust,
            reaction_torque,
            max_rotor_speed: f.max_rotor_speed,
            motor_time_constant: f.motor_time_constant,
            mass: f.mass,
            inertia: f.inertia,
            airframe_radius,
        })
    }

    /// Checks every value: finite rotor positions, positive `k_f`, `k_m` / `torque_ratio` not
    /// negative, a thrust curve with finite coefficients that is positive at
    /// `max_rotor_speed`, positive `max_rotor_speed`, `airframe_radius`, motor time constant
    /// and mass, a finite inertia with positive diagonal.
    ///
    /// # Errors
    /// [`VehicleError::InvalidKey`] naming the first key at fault.
    pub fn validate(&self) -> Result<(), VehicleError> {
        if self.name.trim().is_empty() {
            return Err(invalid("name", "empty"));
        }
        for (i, r) in self.rotors.iter().enumerate() {
            if !r.position.iter().all(|x| x.is_finite()) {
                return Err(invalid(
                    format!("rotor[{}].position", i + 1),
                    format!("{:?} is not finite", r.position.as_slice()),
                ));
            }
        }
        positive("max_rotor_speed", self.max_rotor_speed, "rad/s")?;
        match &self.thrust {
            ThrustCurve::Quadratic { k_f } => {
                positive("k_f", *k_f, "N/(rad/s)^2")?;
            }
            ThrustCurve::Polynomial { coefficients } => {
                if coefficients.is_empty() {
                    return Err(invalid("thrust_curve", "no coefficient"));
                }
                if let Some(c) = coefficients.iter().find(|c| !c.is_finite()) {
                    return Err(invalid(
                        "thrust_curve",
                        format!("coefficient {c} is not finite"),
                    ));
                }
                let top = self.thrust.thrust(self.max_rotor_speed);
                if !(top.is_finite() && top > 0.0) {
                    return Err(invalid(
                        "thrust_curve",
                        format!(
                            "thrust {top} N at max_rotor_speed {} rad/s is not positive",
                            self.max_rotor_speed
                        ),
                    ));
                }
            }
        }
        match self.reaction_torque {
            ReactionTorque::Coefficient { k_m } if !(k_m.is_finite() && k_m >= 0.0) => {
                return Err(invalid(
                    "k_m",
                    format!("{k_m} N m/(rad/s)^2 is negative or not finite"),
                ));
            }
            ReactionTorque::Ratio { ratio } if !(ratio.is_finite() && ratio >= 0.0) => {
                return Err(invalid(
                    "torque_ratio",
                    format!("{ratio} m is negative or not finite"),
                ));
            }
            _ => {}
        }
        positive("airframe_radius", self.airframe_radius, "m")?;
        if let Some(tau) = self.motor_time_constant {
            positive("motor_time_constant", tau, "s")?;
        }
        if let Some(m) = self.mass {
            positive("mass", m, "kg")?;
        }
        if let Some(inertia) = self.inertia {
            if let Some(x) = inertia.iter().find(|x| !x.is_finite()) {
                return Err(invalid("inertia", format!("{x} kg m^2 is not finite")));
            }
            for (k, name) in [(0, "I_xx"), (2, "I_yy"), (5, "I_zz")] {
                if inertia[k] <= 0.0 {
                    return Err(invalid(
                        "inertia",
                        format!("{name} = {} kg m^2 is not positive", inertia[k]),
                    ));
                }
            }
        }
        Ok(())
    }

    /// Thrust of each rotor \[N\] at the given speeds \[rad/s\].
    pub fn thrusts(&self, rotor_speeds: &[f64; ROTOR_COUNT]) -> [f64; ROTOR_COUNT] {
        rotor_speeds.map(|w| self.thrust.thrust(w))
    }

    /// The body wrench (body frame, about the origin) \[N, N m\] of the rotors turning at
    /// `rotor_speeds` \[rad/s\]: thrusts `T(ωᵢ)` along body `+z`, reaction torques `sᵢ Q(ωᵢ)`
    /// about `+z` ([`rotor_wrench`]). For `T = k_f ω²` and `Q = k_m ω²` it is bit for bit
    /// [`QuadrotorModel::wrench_from_rotor_speeds`] of the same numbers.
    pub fn wrench_from_rotor_speeds(&self, rotor_speeds: &[f64; ROTOR_COUNT]) -> Wrench {
        let thrusts = self.thrusts(rotor_speeds);
        let reaction: [f64; ROTOR_COUNT] = match (&self.thrust, self.reaction_torque) {
            // As QuadrotorModel: Q = (k_m / k_f) T, the same bits as k_m ω² up to rounding.
            (ThrustCurve::Quadratic { k_f }, ReactionTorque::Coefficient { k_m }) => {
                let kappa = k_m / k_f;
                thrusts.map(|t| kappa * t)
            }
            (_, ReactionTorque::Coefficient { k_m }) => rotor_speeds.map(|w| k_m * w * w),
            (_, ReactionTorque::Ratio { ratio }) => thrusts.map(|t| ratio * t),
        };
        let positions = self.rotors.map(|r| r.position);
        let spins = self.rotors.map(|r| r.spin.sign());
        rotor_wrench(&positions, &spins, &thrusts, &reaction)
    }

    /// The mass and inertia priors as inertial parameters (centre of mass at the origin), if
    /// both are given.
    pub fn inertial_prior(&self) -> Option<InertialParams> {
        let (m, i) = (self.mass?, self.inertia?);
        Some(InertialParams::from_array([
            m, 0.0, 0.0, 0.0, i[0], i[1], i[2], i[3], i[4], i[5],
        ]))
    }

    #[cfg(feature = "toml")]
    /// The vehicle as a commented TOML template that [`Vehicle::from_toml_str`] reads back to
    /// the same vehicle (numbers in Rust's shortest round-trip notation).
    pub fn to_toml_string(&self) -> String {
        let f = |x: f64| format!("{x:?}");
        let list = |xs: &[f64]| {
            let items: Vec<String> = xs.iter().map(|x| f(*x)).collect();
            format!("[{}]", items.join(", "))
        };
        let mut s = String::new();
        let _ = writeln!(
            s,
            "# tagk vehicle file (docs/VEHICLE.md). Units: SI; body frame x forward, y left, z up."
        );
        let _ = writeln!(s, "name = {}", toml::Value::from(self.name.as_str()));
        let _ = writeln!(
            s,
            "# Radius beyond which a fitted centre of mass is flagged [m]."
        );
        let _ = writeln!(s, "airframe_radius = {}", f(self.airframe_radius));
        let _ = writeln!(s, "# Largest rotor speed [rad/s].");
        let _ = writeln!(s, "max_rotor_speed = {}", f(self.max_rotor_speed));
        match &self.thrust {
            ThrustCurve::Quadratic { k_f } => {
                let _ = writeln!(
                    s,
                    "# Thrust T = k_f w^2 [N/(rad/s)^2] (or thrust_curve = [c0, c1, c2, ...]: T = c0 + c1 w + c2 w^2 + ...)."
                );
                let _ = writeln!(s, "k_f = {}", f(*k_f));
            }
            ThrustCurve::Polynomial { coefficients } => {
                let _ = writeln!(
                    s,
                    "# Thrust T = c0 + c1 w + c2 w^2 + ... [N] (or k_f: T = k_f w^2)."
                );
                let _ = writeln!(s, "thrust_curve = {}", list(coefficients));
            }
        }
        match self.reaction_torque {
            ReactionTorque::Coefficient { k_m } => {
                let _ = writeln!(
                    s,
                    "# Reaction torque Q = k_m w^2 [N m/(rad/s)^2] (or torque_ratio: Q = torque_ratio T [m])."
                );
                let _ = writeln!(s, "k_m = {}", f(k_m));
            }
            ReactionTorque::Ratio { ratio } => {
                let _ = writeln!(
                    s,
                    "# Reaction torque Q = torque_ratio T [m] (or k_m: Q = k_m w^2)."
                );
                let _ = writeln!(s, "torque_ratio = {}", f(ratio));
            }
        }
        let _ = writeln!(s, "# Optional: first-order motor time constant [s].");
        match self.motor_time_constant {
            Some(tau) => {
                let _ = writeln!(s, "motor_time_constant = {}", f(tau));
            }
            None => {
                let _ = writeln!(s, "# motor_time_constant = 0.02");
            }
        }
        let _ = writeln!(
            s,
            "# Optional priors: mass [kg] (used by `tagk diagnose --mass vehicle`) and inertia"
        );
        let _ = writeln!(
            s,
            "# about the body origin [I_xx, I_xy, I_yy, I_xz, I_yz, I_zz] [kg m^2]."
        );
        match self.mass {
            Some(m) => {
                let _ = writeln!(s, "mass = {}", f(m));
            }
            None => {
                let _ = writeln!(s, "# mass = 0.035");
            }
        }
        match self.inertia {
            Some(i) => {
                let _ = writeln!(s, "inertia = {}", list(&i));
            }
            None => {
                let _ = writeln!(s, "# inertia = [1.66e-5, 0.0, 1.66e-5, 0.0, 0.0, 2.93e-5]");
            }
        }
        let _ = writeln!(
            s,
            "\n# One [[rotor]] per log column w1..w4, in that order: hub position [m] and spin\n# seen from above (\"cw\": reaction torque about +z, \"ccw\": about -z)."
        );
        for r in &self.rotors {
            let _ = writeln!(s, "\n[[rotor]]");
            let _ = writeln!(s, "position = {}", list(r.position.as_slice()));
            let _ = writeln!(s, "spin = {:?}", r.spin.name());
        }
        s
    }
}

impl FlightLog {
    /// `true` if the log holds the body wrench (one `fx..tz` row per sample). A log read
    /// without the wrench columns has an empty [`FlightLog::wrench`] until
    /// [`FlightLog::compute_wrench_from_rotor_speeds`] fills it.
    pub fn has_wrench(&self) -> bool {
        self.wrench.len() == self.t.len() && !self.t.is_empty()
    }

    /// Computes the body wrench of every sample from the rotor speeds `w1..w4` with
    /// `vehicle` ([`Vehicle::wrench_from_rotor_speeds`]), replacing any wrench the log had.
    ///
    /// # Errors
    /// [`LogError::MissingWrench`] if the log has no rotor speeds;
    /// [`LogError::RotorSpeedOutOfRange`] (line and column) for a negative speed or one
    /// above [`ROTOR_SPEED_MARGIN`] times the vehicle's `max_rotor_speed` (rpm logged as
    /// rad/s); [`LogError::LengthMismatch`] if the rotor speeds do not have one row per
    /// sample.
    pub fn compute_wrench_from_rotor_speeds(&mut self, vehicle: &Vehicle) -> Result<(), LogError> {
        let Some(speeds) = &self.rotor_speeds else {
            return Err(LogError::MissingWrench {
                has_rotor_speeds: false,
            });
        };
        if speeds.len() != self.t.len() {
            return Err(LogError::LengthMismatch {
                column: "rotor_speeds".to_string(),
                got: speeds.len(),
                expected: self.t.len(),
            });
        }
        let max = ROTOR_SPEED_MARGIN * vehicle.max_rotor_speed;
        let mut wrench = Vec::with_capacity(speeds.len());
        for (i, w) in speeds.iter().enumerate() {
            if let Some(k) = w
                .iter()
                .position(|x| !(x.is_finite() && (0.0..=max).contains(x)))
            {
                return Err(LogError::RotorSpeedOutOfRange {
                    line: i + 2,
                    column: ROTOR_SPEED_COLUMNS[k].to_string(),
                    value: w[k],
                    max,
                });
            }
            let b = vehicle.wrench_from_rotor_speeds(w);
            wrench.push([
                b.force.x, b.force.y, b.force.z, b.torque.x, b.torque.y, b.torque.z,
            ]);
        }
        self.wrench = wrench;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::quadrotor::{CRAZYFLIE_INERTIA, CRAZYFLIE_K_F, CRAZYFLIE_K_M, CRAZYFLIE_MASS};

    #[test]
    fn preset_is_the_quadrotor_model() {
        let v = Vehicle::crazyflie_2_1();
        let q = QuadrotorModel::crazyflie_2_1();
        assert_eq!(v.thrust, ThrustCurve::Quadratic { k_f: CRAZYFLIE_K_F });
        assert_eq!(
            v.reaction_torque,
            ReactionTorque::Coefficient { k_m: CRAZYFLIE_K_M }
        );
        assert_eq!(v.max_rotor_speed, q.max_rotor_speed);
        assert_eq!(v.mass, Some(CRAZYFLIE_MASS));
        assert_eq!(v.inertia, Some(CRAZYFLIE_INERTIA));
        assert_eq!(v.inertial_prior(), Some(q.params));
        for i in 0..4 {
            assert_eq!(v.rotors[i].position, q.rotor_positions[i]);
            assert_eq!(v.rotors[i].spin.sign(), q.spin_directions[i]);
        }
        for w in [
            [0.0; 4],
            [2500.0; 4],
            [1234.5, 2100.25, 1900.0, 17.0],
            [2400.0, 800.0, 1500.0, 2499.0],
        ] {
            assert_eq!(
                v.wrench_from_rotor_speeds(&w),
                q.wrench_from_rotor_speeds(&w)
            );
        }
        assert_eq!(Vehicle::preset("crazyflie-2.1").unwrap(), v);
    }

    #[cfg(feature = "toml")]
    #[test]
    fn template_round_trips() {
        let v = Vehicle::crazyflie_2_1();
        assert_eq!(Vehicle::from_toml_str(&v.to_toml_string()).unwrap(), v);
        let mut other = v.clone();
        other.name = "curve \"v2\" \\ \u{1b}".into();
        other.thrust = ThrustCurve::Polynomial {
            coefficients: vec![0.001, 1.0e-7, 2.2e-8],
        };
        other.reaction_torque = ReactionTorque::Ratio { ratio: 0.006 };
        other.motor_time_constant = Some(0.03);
        other.mass = None;
        other.inertia = None;
        assert_eq!(
            Vehicle::from_toml_str(&other.to_toml_string()).unwrap(),
            other
        );
    }

    #[test]
    fn polynomial_and_ratio_wrench() {
        let mut v = Vehicle::crazyflie_2_1();
        v.thrust = ThrustCurve::Polynomial {
            coefficients: vec![0.01, 0.0, 2.0e-8],
        };
        v.reaction_torque = ReactionTorque::Ratio { ratio: 0.005 };
        let w = [1000.0, 1100.0, 1200.0, 1300.0];
        let b = v.wrench_from_rotor_speeds(&w);
        let t: Vec<f64> = w.iter().map(|w| 0.01 + 2.0e-8 * w * w).collect();
        let fz: f64 = t.iter().sum();
        assert!((b.force.z - fz).abs() < 1e-15);
        // Independent: τ_x = Σ y_i T_i, τ_y = −Σ x_i T_i, τ_z = Σ s_i 0.005 T_i.
        let (mut tx, mut ty, mut tz) = (0.0, 0.0, 0.0);
        for (r, ti) in v.rotors.iter().zip(&t) {
            tx += r.position.y * ti;
            ty -= r.position.x * ti;
            tz += r.spin.sign() * 0.005 * ti;
        }
        assert!((b.torque - Vector3::new(tx, ty, tz)).norm() < 1e-15);
    }

    #[cfg(feature = "toml")]
    fn key_of(text: &str) -> String {
        match Vehicle::from_toml_str(text) {
            Err(VehicleError::InvalidKey { key, .. }) => key,
            other => panic!("expected an invalid key, got {other:?}"),
        }
    }

    #[cfg(feature = "toml")]
    #[test]
    fn errors_name_key_line_and_column() {
        let good = Vehicle::crazyflie_2_1().to_toml_string();
        let bad = good.replace("k_f = 2.3e-8", "k_f = -2.3e-8");
        assert_eq!(key_of(&bad), "k_f");
        let bad = good.replace("k_f = 2.3e-8", "");
        assert_eq!(key_of(&bad), "k_f");
        let bad = good.replace("k_m = 7.8e-10", "k_m = 7.8e-10\ntorque_ratio = 0.03");
        assert_eq!(key_of(&bad), "torque_ratio");
        let bad = good.replace("mass = 0.035", "mass = 0.0");
        assert_eq!(key_of(&bad), "mass");
        let bad = good.replace("airframe_radius = 0.0325", "airframe_radius = -1.0");
        assert_eq!(key_of(&bad), "airframe_radius");
        let bad = good.replacen(
            "position = [0.0325, -0.0325, 0.0]",
            "position = [nan, 0.0, 0.0]",
            1,
        );
        assert_eq!(key_of(&bad), "rotor[1].position");
        let three = good.rsplit_once("[[rotor]]").unwrap().0.to_string();
        assert_eq!(key_of(&three), "rotor");
        // Syntax error: line and column of the bad token.
        let text = "name = \"x\"\nmax_rotor_speed = = 3\n";
        match Vehicle::from_toml_str(text) {
            Err(VehicleError::Toml { line, column, .. }) => assert_eq!((line, column), (2, 19)),
            other => panic!("{other:?}"),
        }
        // Unknown key and wrong spin: located too.
        let bad = good.replace("k_f = 2.3e-8", "k_f = 2.3e-8\nkf = 1.0");
        assert!(matches!(
            Vehicle::from_toml_str(&bad),
            Err(VehicleError::Toml { message, .. }) if message.contains("kf")
        ));
        let bad = good.replacen("spin = \"cw\"", "spin = \"left\"", 1);
        assert!(matches!(
            Vehicle::from_toml_str(&bad),
            Err(VehicleError::Toml { line, .. }) if line > 1
        ));
        assert!(matches!(
            Vehicle::from_name_or_path("no-such-vehicle"),
            Err(VehicleError::UnknownVehicle { .. })
        ));
    }

    #[test]
    fn csv_without_wrench_needs_rotor_speeds() {
        let mut log = FlightLog::new();
        for i in 0..crate::log::MIN_ROWS {
            log.push(&crate::log::LogSample {
                t: 0.01 * i as f64,
                attitude: [1.0, 0.0, 0.0, 0.0],
                rotor_speeds: Some([1900.0, 2000.0, 2100.0, 2000.0 + i as f64]),
                ..Default::default()
            });
        }
        log.wrench.clear();
        let mut csv = Vec::new();
        log.write_csv(&mut csv).unwrap();
        let text = String::from_utf8(csv).unwrap();
        let header = text.lines().next().unwrap();
        assert!(
            !header.contains("fx") && header.ends_with("w1,w2,w3,w4"),
            "{header}"
        );
        let mut back = FlightLog::from_csv_reader(text.as_bytes()).unwrap();
        assert_eq!(back, log);
        assert_eq!(back.signal("fz"), None);
        assert_eq!(
            back.validate(),
            Err(LogError::MissingWrench {
                has_rotor_speeds: true
            })
        );
        back.compute_wrench_from_rotor_speeds(&Vehicle::crazyflie_2_1())
            .unwrap();
        back.validate().unwrap();
        assert_eq!(back.sample(7).unwrap().wrench, back.wrench[7]);
        // Neither the wrench nor the rotor speeds: the error names both ways.
        let no_rotors: String = text
            .lines()
            .map(|l| l.rsplitn(5, ',').last().unwrap().to_string() + "\n")
            .collect();
        let e = FlightLog::from_csv_reader(no_rotors.as_bytes()).unwrap_err();
        assert_eq!(
            e,
            LogError::MissingWrench {
                has_rotor_speeds: false
            }
        );
        let msg = e.to_string();
        assert!(
            msg.contains("fx,fy,fz,tx,ty,tz") && msg.contains("w1,w2,w3,w4"),
            "{msg}"
        );
        assert_eq!(e.line(), Some(1));
    }

    #[test]
    fn log_wrench_from_rotor_speeds() {
        let v = Vehicle::crazyflie_2_1();
        let mut log = FlightLog::new();
        for i in 0..3 {
            log.push(&crate::log::LogSample {
                t: f64::from(i),
                attitude: [1.0, 0.0, 0.0, 0.0],
                rotor_speeds: Some([2000.0 + f64::from(i), 2000.0, 2000.0, 2000.0]),
                ..Default::default()
            });
        }
        log.wrench.clear();
        assert!(!log.has_wrench());
        log.compute_wrench_from_rotor_speeds(&v).unwrap();
        assert!(log.has_wrench());
        let b = v.wrench_from_rotor_speeds(&[2002.0, 2000.0, 2000.0, 2000.0]);
        assert_eq!(log.wrench[2][2], b.force.z);
        log.rotor_speeds.as_mut().unwrap()[1][3] = 2000.0 * 9.55;
        assert_eq!(
            log.compute_wrench_from_rotor_speeds(&v),
            Err(LogError::RotorSpeedOutOfRange {
                line: 3,
                column: "w4".into(),
                value: 2000.0 * 9.55,
                max: 3750.0
            })
        );
        log.rotor_speeds = None;
        assert!(matches!(
            log.compute_wrench_from_rotor_speeds(&v),
            Err(LogError::MissingWrench {
                has_rotor_speeds: false
            })
        ));
    }
}
