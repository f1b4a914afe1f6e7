//! A user-defined effect from log columns (the CLI's `--custom NAME=COL[*COL...]@CH[,CH...]`).

use crate::effects::{Effect, EffectColumn, Plausibility};
use crate::error::DiagnoseError;
use crate::log::FlightLog;
use crate::signals::{CHANNEL_NAMES, Channel, Signals};

/// A user-defined effect from log signals: the product of named log columns as a regressor on
/// chosen wrench channels (one coefficient per channel). CLI syntax (`--custom`):
/// `NAME=COL[*COL…]@CH[,CH…]`, e.g. `vbat=vbat*fz@fz`.
///
/// For an effect that is not a product of logged columns, implement [`Effect`] yourself
/// (`examples/custom_effect.rs`).
#[derive(Debug, Clone, PartialEq)]
pub struct CustomEffect {
    name: String,
    factors: Vec<String>,
    on: Vec<Channel>,
    description: String,
}

impl CustomEffect {
    /// A custom effect named `name`: the product of the log columns `factors` (names as in
    /// the CSV header, e.g. an extra column `vbat`, or a standard one such as `fz`) acting on
    /// the wrench channels `on` (`0..6` = `fx, fy, fz, tx, ty, tz`; repeats are ignored).
    ///
    /// # Errors
    /// [`DiagnoseError::BadCustomSpec`] for an empty name, no factor, an empty factor name,
    /// no channel or a channel outside `0..6`.
    pub fn new(name: &str, factors: Vec<String>, on: Vec<Channel>) -> Result<Self, DiagnoseError> {
        let spec = format!("{name}={}@{:?}", factors.join("*"), on);
        let bad = |reason: String| DiagnoseError::BadCustomSpec {
            spec: spec.clone(),
            reason,
        };
        let name = name.trim();
        if name.is_empty() {
            return Err(bad("empty name".into()));
        }
        if factors.is_empty() {
            return Err(bad("no factor".into()));
        }
        let factors: Vec<String> = factors.iter().map(|f| f.trim().to_string()).collect();
        if factors.iter().any(String::is_empty) {
            return Err(bad("empty factor".into()));
        }
        if on.is_empty() {
            return Err(bad("no channel".into()));
        }
        let mut channels = Vec::new();
        for c in on {
            if c >= CHANNEL_NAMES.len() {
                return Err(bad(format!("channel {c} outside 0..6 (fx,fy,fz,tx,ty,tz)")));
            }
            if !channels.contains(&c) {
                channels.push(c);
            }
        }
        let description = format!(
            "custom: {} on {}",
            factors.join("·"),
            channels
                .iter()
                .map(|c| CHANNEL_NAMES[*c])
                .collect::<Vec<_>>()
                .join(",")
        );
        Ok(Self {
            name: name.to_string(),
            factors,
            on: channels,
            description,
        })
    }

    /// The log columns multiplied together.
    pub fn factors(&self) -> &[String] {
        &self.factors
    }

    /// Checks that the log has every column the effect multiplies.
    ///
    /// # Errors
    /// [`DiagnoseError::UnknownColumn`] naming the first missing column.
    pub fn require_columns(&self, log: &FlightLog) -> Result<(), DiagnoseError> {
        match self.factors.iter().find(|f| log.signal(f).is_none()) {
            Some(column) => Err(DiagnoseError::UnknownColumn {
                effect: self.name.clone(),
                column: column.clone(),
            }),
            None => Ok(()),
        }
    }

    /// Parses `NAME=COL[*COL…]@CH[,CH…]`.
    ///
    /// # Errors
    /// [`DiagnoseError::BadCustomSpec`] on a syntax error or unknown channel.
    pub fn parse(spec: &str) -> Result<Self, DiagnoseError> {
        let bad = |reason: &str| DiagnoseError::BadCustomSpec {
            spec: spec.to_string(),
            reason: reason.to_string(),
        };
        let (name, rest) = spec
            .split_once('=')
            .ok_or_else(|| bad("expected NAME=COL[*COL...]@CH[,CH...]"))?;
        let (expr, chans) = rest
            .split_once('@')
            .ok_or_else(|| bad("missing @channels"))?;
        let name = name.trim();
        if name.is_empty() {
            return Err(bad("empty name"));
        }
        let factors: Vec<String> = expr.split('*').map(|s| s.trim().to_string()).collect();
        if factors.iter().any(String::is_empty) {
            return Err(bad("empty factor"));
        }
        let mut on = Vec::new();
        for c in chans.split(',') {
            let c = c.trim();
            let k = CHANNEL_NAMES
                .iter()
                .position(|n| *n == c)
                .ok_or_else(|| bad(&format!("unknown channel `{c}` (fx,fy,fz,tx,ty,tz)")))?;
            if !on.contains(&k) {
                on.push(k);
            }
        }
        Self::new(name, factors, on).map_err(|e| match e {
            DiagnoseError::BadCustomSpec { reason, .. } => bad(&reason),
            other => other,
        })
    }

    fn product(&self, s: &Signals) -> Result<Vec<f64>, String> {
        let mut out = vec![1.0; s.len()];
        for f in &self.factors {
            let v = s
                .log()
                .signal(f)
                .ok_or_else(|| format!("log has no column `{f}`"))?;
            for (o, x) in out.iter_mut().zip(v) {
                *o *= x;
            }
        }
        Ok(out)
    }
}

impl Effect for CustomEffect {
    fn name(&self) -> &str {
        &self.name
    }
    fn description(&self) -> &str {
        &self.description
    }
    fn channels(&self) -> Vec<Channel> {
        self.on.clone()
    }
    fn check(&self, s: &Signals) -> Result<(), String> {
        self.product(s).map(|_| ())
    }
    fn columns(&self, s: &Signals, _p: Option<f64>) -> Vec<EffectColumn> {
        let Ok(v) = self.product(s) else {
            return Vec::new();
        };
        self.on
            .iter()
            .map(|&c| {
                EffectColumn::on(
                    &format!("{}_{}", self.name, CHANNEL_NAMES[c]),
                    "?",
                    c,
                    v.clone(),
                )
            })
            .collect()
    }
    fn plausibility(&self, _coef: &[f64], _se: &[f64], _p: Option<f64>) -> Plausibility {
        Plausibility::ok()
    }
    fn driver(&self, s: &Signals) -> (String, Vec<f64>) {
        (self.factors.join("*"), self.product(s).unwrap_or_default())
    }
}
