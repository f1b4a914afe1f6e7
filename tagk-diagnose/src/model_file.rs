//! The model file: the identified model of a diagnosis as a versioned TOML artefact
//! (`tagk diagnose --save-model m.toml`; format in docs/MODEL_FILE.md).
//!
//! It holds the vehicle (the vehicle file's keys, docs/VEHICLE.md), the inertial parameters
//! with their covariance, the effects with their coefficients and intervals, the sensing
//! assumptions and the logs it came from. Every number reads back bit for bit.
//!
//! ```
//! use tagk_diagnose::ModelFile;
//! let file = ModelFile::rigid_body([0.035, 0.0, 0.0, 0.0, 1.7e-5, 0.0, 1.7e-5, 0.0, 0.0, 2.9e-5]);
//! let text = file.to_toml_string()?;
//! let back = ModelFile::from_toml_str(&text)?;
//! assert_eq!(back.inertial.values, file.inertial.values);
//! // No standard errors: `nan` in the file (NaN is not equal to itself).
//! assert!(back.inertial.std_error.iter().all(|e| e.is_nan()));
//! # Ok::<(), tagk_diagnose::ModelFileError>(())
//! ```

use std::path::Path;
use std::sync::Arc;

pub mod format {
    // The link definition comes before the document's own, so docs.rs links the crate's page.
    #![doc = "[vehicle-file]: tagk_dynamics::conventions::vehicle_file"]
    #![doc = include_str!("../docs/MODEL_FILE.md")]
}

use serde::{Deserialize, Serialize};
use tagk_dynamics::InertialParams;
use tagk_dynamics::alignment::Sensor;
use tagk_dynamics::vehicle::Vehicle;

use crate::effects::{CustomEffect, EffectRef, builtin_by_name};
use crate::fit::{Coefficient, Fit, FittedEffect, Model, THETA_NAMES, THETA_UNITS};
use crate::report::Report;

/// The value of the file's `format` key.
pub const MODEL_FORMAT: &str = "tagk-model";

/// The format version this build writes and reads.
pub const MODEL_FILE_VERSION: u32 = 1;

/// What can be wrong with a model file.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ModelFileError {
    /// The file cannot be read or written.
    #[error("{path}: {message}")]
    Io {
        /// The file.
        path: String,
        /// The operating system's message.
        message: String,
    },
    /// An error of the model file `path` (its other variants, naming the file).
    #[error("{path}: {source}")]
    InFile {
        /// The file.
        path: String,
        /// What is wrong with it.
        source: Box<ModelFileError>,
    },
    /// The text is not a model file: bad TOML, a missing or mistyped key, an unknown key.
    /// The message names the key and, for a syntax error, the line.
    #[error("malformed model file: {message}")]
    Malformed {
        /// What is wrong, with the key.
        message: String,
    },
    /// A key holds a value of the right type but the wrong shape (e.g. a covariance that
    /// is not 10 × 10).
    #[error("malformed model file: `{key}` {reason}")]
    BadValue {
        /// The key, dotted (e.g. `inertial.covariance`).
        key: String,
        /// What is wrong with it.
        reason: String,
    },
    /// The `format` key is not [`MODEL_FORMAT`].
    #[error("not a tagk model file: `format` is `{found}`, expected `{MODEL_FORMAT}`")]
    WrongFormat {
        /// The value found.
        found: String,
    },
    /// The file's `version` is not one this build reads.
    #[error(
        "model file version {found} is not supported (this build reads version {MODEL_FILE_VERSION})"
    )]
    UnsupportedVersion {
        /// The version found.
        found: u32,
    },
    /// An effect name that is neither built in nor a custom effect with a specification.
    #[error("model file: unknown effect `{name}` in `effects` (not built in, and no `spec`)")]
    UnknownEffect {
        /// The name.
        name: String,
    },
    /// A custom effect's specification does not parse.
    #[error("model file: effect `{name}`: bad `spec`: {reason}")]
    BadSpec {
        /// The effect.
        name: String,
        /// Why.
        reason: String,
    },
    /// The `vehicle` table is not a valid vehicle (docs/VEHICLE.md).
    #[error("model file: `vehicle`: {0}")]
    Vehicle(#[from] tagk_dynamics::vehicle::VehicleError),
}

/// One log a model came from: its path as given, its size and a hash of its bytes.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LogSource {
    /// The path as given on the command line.
    pub path: String,
    /// Its size \[bytes\].
    pub bytes: u64,
    /// FNV-1a (64 bit) of its bytes, 16 hexadecimal digits: tells a changed file, not a
    /// security check.
    pub fnv1a64: String,
}

impl LogSource {
    /// The source record of a file's bytes.
    pub fn of_bytes(path: &str, bytes: &[u8]) -> Self {
        Self {
            path: path.to_string(),
            bytes: bytes.len() as u64,
            fnv1a64: format!("{:016x}", fnv1a64(bytes)),
        }
    }

    /// Reads a file and records it.
    ///
    /// # Errors
    /// [`ModelFileError::Io`] if the file cannot be read.
    pub fn of_file(path: &Path) -> Result<Self, ModelFileError> {
        let bytes = std::fs::read(path).map_err(|e| ModelFileError::Io {
            path: path.display().to_string(),
            message: e.to_string(),
        })?;
        Ok(Self::of_bytes(&path.display().to_string(), &bytes))
    }
}

/// FNV-1a, 64 bit, of `bytes`.
pub fn fnv1a64(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, b| {
        (h ^ u64::from(*b)).wrapping_mul(0x0000_0100_0000_01b3)
    })
}

/// A stream offset removed before the fit.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StreamShift {
    /// The log (its file) for several logs; empty for one.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub log: String,
    /// The stream.
    pub sensor: Sensor,
    /// The offset removed \[s\] (positive: the stream was late).
    pub seconds: f64,
    /// `measured` (found significant and removed) or `given` (`--shift`).
    pub action: String,
}

/// An accelerometer offset found before the fit.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AccelOffsetRecord {
    /// The log (its file) for several logs; empty for one.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub log: String,
    /// The offset measured, body frame \[m/s²\].
    pub offset: [f64; 3],
    /// The vertical part removed from the logged acceleration \[m/s²\].
    pub removed_z: f64,
}

/// What the model assumes of the sensing: what was done to the logs before the fit.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Sensing {
    /// `true` if the accelerations were derived from the velocity (not logged).
    pub derived_accelerations: bool,
    /// `true` if stream offsets were measured and removed automatically (not `--no-align`).
    pub align: bool,
    /// The uniform step the logs were resampled to \[s\] (`--resample`), if any.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub resample: Option<f64>,
    /// The stream offsets removed (none: every stream as logged).
    #[serde(default)]
    pub shifts: Vec<StreamShift>,
    /// The accelerometer offsets found.
    #[serde(default)]
    pub accelerometer_offsets: Vec<AccelOffsetRecord>,
}

impl Sensing {
    /// The shifts to apply to a log before predicting with the model: one per stream (the
    /// first logged for it).
    pub fn shifts_to_apply(&self) -> Vec<(Sensor, f64)> {
        let mut out: Vec<(Sensor, f64)> = Vec::new();
        for s in &self.shifts {
            if !out.iter().any(|(k, _)| *k == s.sensor) {
                out.push((s.sensor, s.seconds));
            }
        }
        out
    }
}

/// The rigid-body part: the ten inertial parameters in the project's order
/// (docs/CONVENTIONS.md §3) with their standard errors and covariance.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InertialSection {
    /// The names, `m, h_x, h_y, h_z, I_xx, I_xy, I_yy, I_xz, I_yz, I_zz`.
    pub names: Vec<String>,
    /// Their units (`kg`, `kg m`, `kg m²`).
    pub units: Vec<String>,
    /// The values.
    pub values: Vec<f64>,
    /// Their standard errors (`nan`: none, unidentifiable or fixed).
    pub std_error: Vec<f64>,
    /// Their covariance, 10 rows of 10 (`nan` in the rows and columns without a standard
    /// error).
    pub covariance: Vec<Vec<f64>>,
    /// The mass fixed instead of fitted \[kg\], if any.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub known_mass: Option<f64>,
}

impl InertialSection {
    /// The parameters.
    pub fn theta(&self) -> InertialParams {
        let mut t = [0.0; 10];
        for (x, v) in t.iter_mut().zip(&self.values) {
            *x = *v;
        }
        InertialParams::from_array(t)
    }
}

/// A scanned nonlinear parameter (a time constant, a delay).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScannedParameter {
    /// Its name.
    pub name: String,
    /// Its unit.
    pub unit: String,
    /// The value applied.
    pub value: f64,
    /// Its 95 % interval, when the data bound it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub interval: Option<[f64; 2]>,
}

/// One fitted coefficient (a column of the effect).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModelCoefficient {
    /// The column's name (e.g. `d_x`).
    pub name: String,
    /// Its unit.
    pub unit: String,
    /// The value.
    pub value: f64,
    /// Its standard error, if identifiable.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub std_error: Option<f64>,
    /// Its 95 % interval, if identifiable.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub interval: Option<[f64; 2]>,
}

impl From<&Coefficient> for ModelCoefficient {
    fn from(c: &Coefficient) -> Self {
        Self {
            name: c.name.clone(),
            unit: c.unit.clone(),
            value: c.value,
            std_error: c.std_error,
            interval: c.confidence_interval,
        }
    }
}

/// One effect of the model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModelEffect {
    /// The effect's name: built in (docs/CONVENTIONS.md §7) or custom.
    pub name: String,
    /// A custom effect's specification `NAME=EXPR@CH[,CH…]` ([`crate::CustomEffect`]) (none for a built-in).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub spec: Option<String>,
    /// The scanned parameter, if the effect has one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scanned: Option<ScannedParameter>,
    /// The fitted coefficients, in the order of the effect's columns.
    pub coefficients: Vec<ModelCoefficient>,
}

impl ModelEffect {
    /// The record of a fitted effect (`spec`: a custom effect's specification).
    pub fn of(effect: &FittedEffect, spec: Option<String>) -> Self {
        Self {
            name: effect.effect.clone(),
            spec,
            scanned: effect
                .scanned
                .as_ref()
                .map(|(name, value, unit)| ScannedParameter {
                    name: name.clone(),
                    unit: unit.clone(),
                    value: *value,
                    interval: effect.scanned_interval,
                }),
            coefficients: effect
                .coefficients
                .iter()
                .map(ModelCoefficient::from)
                .collect(),
        }
    }

    /// The coefficient of column `name`: the value of that name, else (a per-log coefficient
    /// of a joint fit, `name@k`) the mean over the logs; `None` if there is none.
    pub fn coefficient(&self, name: &str) -> Option<f64> {
        if let Some(c) = self.coefficients.iter().find(|c| c.name == name) {
            return Some(c.value);
        }
        let prefix = format!("{name}@");
        let per_log: Vec<f64> = self
            .coefficients
            .iter()
            .filter(|c| c.name.starts_with(&prefix))
            .map(|c| c.value)
            .collect();
        (!per_log.is_empty()).then(|| per_log.iter().sum::<f64>() / per_log.len() as f64)
    }

    /// The effect, instantiated: a built-in by its name, a custom one from its `spec`.
    ///
    /// # Errors
    /// [`ModelFileError::UnknownEffect`], [`ModelFileError::BadSpec`].
    pub fn instantiate(&self) -> Result<EffectRef, ModelFileError> {
        match &self.spec {
            Some(spec) => CustomEffect::parse(spec)
                .map(|e| Arc::new(e) as EffectRef)
                .map_err(|e| ModelFileError::BadSpec {
                    name: self.name.clone(),
                    reason: e.to_string(),
                }),
            None => builtin_by_name(&self.name).map_err(|_| ModelFileError::UnknownEffect {
                name: self.name.clone(),
            }),
        }
    }
}

/// What a model file records besides the fit: only the caller (the command line) knows it.
#[derive(Debug, Clone, Default)]
pub struct ModelContext {
    /// The vehicle given (or the default one used), if any.
    pub vehicle: Option<Vehicle>,
    /// The logs the model came from.
    pub logs: Vec<LogSource>,
    /// The custom effects' specifications (`--custom`), matched to effects by name.
    pub custom: Vec<String>,
    /// The mass fixed instead of fitted \[kg\], if any.
    pub known_mass: Option<f64>,
    /// `true` unless stream offsets were only reported (`--no-align`).
    pub align: bool,
    /// The resampling step \[s\] (`--resample`), if any.
    pub resample: Option<f64>,
}

/// The identified model as a file: see the module documentation and docs/MODEL_FILE.md.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModelFile {
    /// Always [`MODEL_FORMAT`].
    pub format: String,
    /// The format version, [`MODEL_FILE_VERSION`].
    pub version: u32,
    /// The model's label (`rigid body + …`).
    pub label: String,
    /// The logs it was identified on.
    #[serde(default)]
    pub logs: Vec<LogSource>,
    /// The sensing assumptions.
    #[serde(default)]
    pub sensing: Sensing,
    /// The inertial parameters.
    pub inertial: InertialSection,
    /// The effects, in the order of the model.
    #[serde(default)]
    pub effects: Vec<ModelEffect>,
    /// The vehicle (the keys of a vehicle file, docs/VEHICLE.md), if one was given.
    #[serde(
        default,
        skip_serializing_if = "Option::is_none",
        with = "vehicle_table"
    )]
    pub vehicle: Option<Vehicle>,
}

/// The `vehicle` table: the vehicle file's own keys ([`Vehicle::to_toml_string`],
/// [`Vehicle::from_toml_str`]).
mod vehicle_table {
    use serde::{Deserialize, Deserializer, Serialize, Serializer, de::Error as _};
    use tagk_dynamics::vehicle::Vehicle;

    pub fn serialize<S: Serializer>(v: &Option<Vehicle>, s: S) -> Result<S::Ok, S::Error> {
        match v {
            Some(v) => {
                let table: toml::Table =
                    toml::from_str(&v.to_toml_string()).map_err(serde::ser::Error::custom)?;
                table.serialize(s)
            }
            None => s.serialize_none(),
        }
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Option<Vehicle>, D::Error> {
        let table = toml::Table::deserialize(d)?;
        let text = toml::to_string(&table).map_err(D::Error::custom)?;
        Vehicle::from_toml_str(&text)
            .map(Some)
            .map_err(D::Error::custom)
    }
}

/// The header read first: a wrong format or version is told before any other key.
#[derive(Deserialize)]
struct Header {
    format: Option<String>,
    version: Option<u32>,
}

impl ModelFile {
    /// A rigid-body model of parameters `theta` (the order of [`InertialParams`]), without
    /// covariance, effects, vehicle or sources.
    pub fn rigid_body(theta: [f64; 10]) -> Self {
        Self {
            format: MODEL_FORMAT.into(),
            version: MODEL_FILE_VERSION,
            label: "rigid body".into(),
            logs: Vec::new(),
            sensing: Sensing::default(),
            inertial: InertialSection {
                names: THETA_NAMES.iter().map(|s| s.to_string()).collect(),
                units: THETA_UNITS.iter().map(|s| s.to_string()).collect(),
                values: theta.to_vec(),
                std_error: vec![f64::NAN; 10],
                covariance: vec![vec![f64::NAN; 10]; 10],
                known_mass: None,
            },
            effects: Vec::new(),
            vehicle: None,
        }
    }

    /// The model of a fit (`effects`: its fitted effects, those of a diagnosis carry the
    /// scanned parameters' intervals), with what `context` records. Its inertial parameters
    /// are the fit's physically consistent ones ([`Fit::consistent_theta`]): a model file
    /// is flown and predicted with.
    pub fn from_fit(fit: &Fit, effects: &[FittedEffect], context: &ModelContext) -> Self {
        let mut file = Self::rigid_body(fit.consistent_theta().to_array());
        file.label = fit.label.clone();
        file.inertial.std_error = fit.theta_se.map(|e| e.unwrap_or(f64::NAN)).to_vec();
        file.inertial.covariance = fit.theta_cov.iter().map(|r| r.to_vec()).collect();
        file.inertial.known_mass = context.known_mass;
        file.effects = effects
            .iter()
            .map(|e| ModelEffect::of(e, custom_spec(&context.custom, &e.effect)))
            .collect();
        file.vehicle = context.vehicle.clone();
        file.logs = context.logs.clone();
        file.sensing = Sensing {
            align: context.align,
            resample: context.resample,
            ..Sensing::default()
        };
        file
    }

    /// The final model of a diagnosis (the staircase's last step), with the sensing the
    /// report records (stream offsets, accelerometer offsets).
    pub fn from_diagnosis(report: &Report, context: &ModelContext) -> Self {
        let d = report.final_diagnosis();
        let mut file = Self::from_fit(&d.fit, &d.effects, context);
        file.sensing = sensing_of(report, context, d.derived_accelerations);
        file
    }

    /// One model per step on the way to the final one ([`Report::step_fits`]): the rigid
    /// body, the `--with` model, then each staircase step. The last is the final model,
    /// without the scanned parameters' intervals of [`ModelFile::from_diagnosis`].
    pub fn steps(report: &Report, context: &ModelContext) -> Vec<Self> {
        let derived = report.final_diagnosis().derived_accelerations;
        report
            .step_fits
            .iter()
            .map(|fit| {
                let mut file = Self::from_fit(fit, &fit.effects, context);
                file.sensing = sensing_of(report, context, derived);
                file
            })
            .collect()
    }

    /// The file's text (TOML).
    ///
    /// # Errors
    /// [`ModelFileError::Malformed`] if serialisation fails.
    pub fn to_toml_string(&self) -> Result<String, ModelFileError> {
        let body = toml::to_string(self).map_err(|e| ModelFileError::Malformed {
            message: e.to_string(),
        })?;
        Ok(format!(
            "# tagk model file (docs/MODEL_FILE.md). SI units; body frame x forward, y left, z up.\n{body}"
        ))
    }

    /// Reads a model file's text, checking its format, version and shapes.
    ///
    /// # Errors
    /// [`ModelFileError::WrongFormat`], [`ModelFileError::UnsupportedVersion`],
    /// [`ModelFileError::Malformed`] (naming the key), [`ModelFileError::BadValue`],
    /// [`ModelFileError::UnknownEffect`], [`ModelFileError::BadSpec`].
    pub fn from_toml_str(text: &str) -> Result<Self, ModelFileError> {
        let malformed = |e: toml::de::Error| ModelFileError::Malformed {
            message: e.to_string().trim_end().to_string(),
        };
        let header: Header = toml::from_str(text).map_err(malformed)?;
        match header.format {
            Some(f) if f == MODEL_FORMAT => {}
            Some(found) => return Err(ModelFileError::WrongFormat { found }),
            None => {
                return Err(ModelFileError::Malformed {
                    message: "missing key `format`".into(),
                });
            }
        }
        match header.version {
            Some(MODEL_FILE_VERSION) => {}
            Some(found) => return Err(ModelFileError::UnsupportedVersion { found }),
            None => {
                return Err(ModelFileError::Malformed {
                    message: "missing key `version`".into(),
                });
            }
        }
        let file: ModelFile = toml::from_str(text).map_err(malformed)?;
        file.validate()?;
        Ok(file)
    }

    /// Reads a model file.
    ///
    /// # Errors
    /// [`ModelFileError::Io`]; the errors of [`ModelFile::from_toml_str`] in
    /// [`ModelFileError::InFile`], naming the file.
    pub fn from_path(path: &Path) -> Result<Self, ModelFileError> {
        let text = std::fs::read_to_string(path).map_err(|e| ModelFileError::Io {
            path: path.display().to_string(),
            message: e.to_string(),
        })?;
        Self::from_toml_str(&text).map_err(|e| ModelFileError::InFile {
            path: path.display().to_string(),
            source: Box::new(e),
        })
    }

    /// Writes the file.
    ///
    /// # Errors
    /// [`ModelFileError::Io`] naming the file.
    pub fn write(&self, path: &Path) -> Result<(), ModelFileError> {
        std::fs::write(path, self.to_toml_string()?).map_err(|e| ModelFileError::Io {
            path: path.display().to_string(),
            message: e.to_string(),
        })
    }

    /// Checks the shapes: ten parameters in the project's order, a 10 × 10 covariance, and
    /// every effect instantiable.
    ///
    /// # Errors
    /// [`ModelFileError::BadValue`] naming the key; the errors of [`ModelFile::effects`].
    pub fn validate(&self) -> Result<(), ModelFileError> {
        let bad = |key: &str, reason: String| {
            Err(ModelFileError::BadValue {
                key: key.into(),
                reason,
            })
        };
        let i = &self.inertial;
        if i.names.iter().map(String::as_str).ne(THETA_NAMES) {
            return bad(
                "inertial.names",
                format!("must be {THETA_NAMES:?} (docs/CONVENTIONS.md §3)"),
            );
        }
        if i.units.len() != 10 {
            return bad(
                "inertial.units",
                format!("has {} entries, not 10", i.units.len()),
            );
        }
        for (key, v) in [
            ("inertial.values", &i.values),
            ("inertial.std_error", &i.std_error),
        ] {
            if v.len() != 10 {
                return bad(key, format!("has {} entries, not 10", v.len()));
            }
        }
        if i.values.iter().any(|x| !x.is_finite()) {
            return bad("inertial.values", "holds a value that is not finite".into());
        }
        if i.covariance.len() != 10 || i.covariance.iter().any(|r| r.len() != 10) {
            return bad("inertial.covariance", "is not 10 rows of 10".into());
        }
        if let Some(m) = i.known_mass
            && !(m.is_finite() && m > 0.0)
        {
            return bad("inertial.known_mass", format!("{m} kg is not positive"));
        }
        for (k, e) in self.effects.iter().enumerate() {
            if self.effects[..k].iter().any(|f| f.name == e.name) {
                return bad("effects", format!("holds `{}` twice", e.name));
            }
        }
        self.effects().map(|_| ())
    }

    /// The effects, instantiated: the built-ins by name (the registry,
    /// [`crate::builtin_by_name`]), the custom ones from their `spec`.
    ///
    /// # Errors
    /// [`ModelFileError::UnknownEffect`], [`ModelFileError::BadSpec`].
    pub fn effects(&self) -> Result<Vec<EffectRef>, ModelFileError> {
        self.effects.iter().map(ModelEffect::instantiate).collect()
    }

    /// The model to fit again ([`Model`]): its effects and the known mass.
    ///
    /// # Errors
    /// As [`ModelFile::effects`].
    pub fn model(&self) -> Result<Model, ModelFileError> {
        let mut model = Model::rigid_body();
        for e in self.effects()? {
            model = model.with_ref(e);
        }
        if let Some(m) = self.inertial.known_mass {
            model = model.with_known_mass(m);
        }
        Ok(model)
    }
}

/// The specification of the custom effect named `name` among `specs`, if any.
fn custom_spec(specs: &[String], name: &str) -> Option<String> {
    specs
        .iter()
        .find(|s| s.split_once('=').is_some_and(|(n, _)| n.trim() == name))
        .cloned()
}

/// The sensing a report records, with the context's options.
fn sensing_of(report: &Report, context: &ModelContext, derived: bool) -> Sensing {
    Sensing {
        derived_accelerations: derived,
        align: context.align,
        resample: context.resample,
        shifts: report
            .streams
            .iter()
            .filter(|s| s.action != "none")
            .map(|s| StreamShift {
                log: s.log.clone(),
                sensor: s.sensor,
                seconds: s.applied,
                action: s.action.to_string(),
            })
            .collect(),
        accelerometer_offsets: report
            .accelerometer_offsets
            .iter()
            .map(|a| AccelOffsetRecord {
                log: a.log.clone(),
                offset: a.offset,
                removed_z: a.removed_z,
            })
            .collect(),
    }
}
