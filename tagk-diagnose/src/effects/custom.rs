//! A user-defined effect from log columns (the CLI's `--custom NAME=EXPR@CH[,CH...]`).

use crate::effects::expression::{BODY_VELOCITY, Dimension, Expression, ExpressionError};
use crate::effects::{Effect, EffectColumn, Plausibility};
use crate::error::DiagnoseError;
use crate::log::FlightLog;
use crate::signals::{CHANNEL_NAMES, Channel, Signals};

/// A user-defined effect from log signals: an expression of log columns as a regressor on
/// chosen wrench channels (one coefficient per channel). CLI syntax (`--custom`):
/// `NAME=EXPR@CH[,CH…]`, e.g. `vbat=vbat*fz@fz` or `drag_x='vbx*abs(vbx)'@fx`. The
/// expression's syntax, functions and units: [`Expression`]. A product of columns
/// (`COL*COL…`, the older syntax) is an expression too.
///
/// For an effect that is not an expression of logged columns, implement [`Effect`] yourself
/// (`examples/custom_effect.rs`).
#[derive(Debug, Clone, PartialEq)]
pub struct CustomEffect {
    name: String,
    expression: Expression,
    factors: Vec<String>,
    on: Vec<Channel>,
    description: String,
    /// The coefficient's unit on each channel of `on`: the channel's over the expression's.
    units: Vec<String>,
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
        if factors.is_empty() {
            return Err(DiagnoseError::BadCustomSpec {
                spec,
                reason: "no factor".into(),
            });
        }
        let factors: Vec<String> = factors.iter().map(|f| f.trim().to_string()).collect();
        if factors.iter().any(String::is_empty) {
            return Err(DiagnoseError::BadCustomSpec {
                spec,
                reason: "empty factor".into(),
            });
        }
        Self::with_expression(name, &factors.join("*"), on)
    }

    /// A custom effect named `name`: the expression `expression` ([`Expression`]) of log
    /// columns acting on the wrench channels `on` (`0..6` = `fx, fy, fz, tx, ty, tz`; repeats
    /// are ignored).
    ///
    /// # Errors
    /// [`DiagnoseError::BadCustomSpec`] for an empty name, no channel, a channel outside
    /// `0..6` or an expression that does not parse; [`DiagnoseError::CustomUnits`] for a
    /// unit mistake in the expression.
    pub fn with_expression(
        name: &str,
        expression: &str,
        on: Vec<Channel>,
    ) -> Result<Self, DiagnoseError> {
        let spec = format!("{name}={expression}@{on:?}");
        let bad = |reason: String| DiagnoseError::BadCustomSpec {
            spec: spec.clone(),
            reason,
        };
        let name = name.trim();
        if name.is_empty() {
            return Err(bad("empty name".into()));
        }
        if expression.trim().is_empty() {
            return Err(bad("empty expression".into()));
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
        let expression = Expression::parse(expression).map_err(|e| match e {
            ExpressionError::Units(reason) => DiagnoseError::CustomUnits {
                effect: name.to_string(),
                expression: expression.trim().to_string(),
                reason,
            },
            ExpressionError::Syntax(reason) => bad(reason),
        })?;
        let mut factors: Vec<String> = Vec::new();
        for i in expression.inputs() {
            if !factors.iter().any(|f| f == i.column()) {
                factors.push(i.column().to_string());
            }
        }
        let units = channels
            .iter()
            .map(|&c| coefficient_unit(c, expression.unit()))
            .collect();
        let description = format!(
            "custom: {} on {}",
            expression.text(),
            channels
                .iter()
                .map(|c| CHANNEL_NAMES[*c])
                .collect::<Vec<_>>()
                .join(",")
        );
        Ok(Self {
            name: name.to_string(),
            expression,
            factors,
            on: channels,
            description,
            units,
        })
    }

    /// The log columns the expression reads, each once.
    pub fn factors(&self) -> &[String] {
        &self.factors
    }

    /// The expression.
    pub fn expression(&self) -> &Expression {
        &self.expression
    }

    /// The unit of the coefficient on each channel of [`Effect::channels`] (the channel's
    /// unit over the expression's, in SI base units; `?` when the expression reads an extra
    /// column).
    pub fn coefficient_units(&self) -> &[String] {
        &self.units
    }

    /// Checks that the log has every column the expression reads.
    ///
    /// # Errors
    /// [`DiagnoseError::UnknownColumn`] naming the first missing column and the log's
    /// columns.
    pub fn require_columns(&self, log: &FlightLog) -> Result<(), DiagnoseError> {
        match self.expression.missing_columns(log).into_iter().next() {
            Some(column) => Err(DiagnoseError::UnknownColumn {
                effect: self.name.clone(),
                column,
                available: available_columns(log),
            }),
            None => Ok(()),
        }
    }

    /// Parses `NAME=EXPR@CH[,CH…]` (the expression may be quoted with `'` or `"`).
    ///
    /// # Errors
    /// [`DiagnoseError::BadCustomSpec`] on a syntax error or unknown channel;
    /// [`DiagnoseError::CustomUnits`] on a unit mistake in the expression.
    pub fn parse(spec: &str) -> Result<Self, DiagnoseError> {
        let bad = |reason: &str| DiagnoseError::BadCustomSpec {
            spec: spec.to_string(),
            reason: reason.to_string(),
        };
        let (name, rest) = spec
            .split_once('=')
            .ok_or_else(|| bad("expected NAME=EXPR@CH[,CH...]"))?;
        let (expr, chans) = rest
            .rsplit_once('@')
            .ok_or_else(|| bad("missing @channels"))?;
        let name = name.trim();
        if name.is_empty() {
            return Err(bad("empty name"));
        }
        let expr = expr.trim();
        let expr = ['\'', '"']
            .iter()
            .find_map(|q| expr.strip_prefix(*q).and_then(|e| e.strip_suffix(*q)))
            .unwrap_or(expr);
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
        Self::with_expression(name, expr, on).map_err(|e| match e {
            DiagnoseError::BadCustomSpec { reason, .. } => bad(&reason),
            other => other,
        })
    }

    /// The canonical specification `NAME=EXPR@CH[,CH…]`.
    pub fn spec(&self) -> String {
        let channels: Vec<&str> = self.on.iter().map(|c| CHANNEL_NAMES[*c]).collect();
        format!(
            "{}={}@{}",
            self.name,
            self.expression.text(),
            channels.join(",")
        )
    }

    fn product(&self, s: &Signals) -> Result<Vec<f64>, String> {
        self.expression.evaluate(s)
    }
}

/// The unit of a coefficient on channel `c` of a column in `unit` (`?` if unknown).
fn coefficient_unit(c: Channel, unit: Option<Dimension>) -> String {
    let channel = if c < 3 {
        Dimension::NEWTON
    } else {
        Dimension::NEWTON_METRE
    };
    unit.map_or_else(|| "?".to_string(), |u| channel.div(&u).to_string())
}

/// The signals an expression can read on `log`: its columns, the body-frame velocity and its
/// extra columns, comma separated.
fn available_columns(log: &FlightLog) -> String {
    let standard = [
        "t", "px", "py", "pz", "vx", "vy", "vz", "qw", "qx", "qy", "qz", "wx", "wy", "wz", "fx",
        "fy", "fz", "tx", "ty", "tz", "ax", "ay", "az", "dwx", "dwy", "dwz", "w1", "w2", "w3",
        "w4",
    ];
    let mut names: Vec<String> = standard
        .iter()
        .filter(|c| log.signal(c).is_some())
        .map(|c| c.to_string())
        .collect();
    names.extend(BODY_VELOCITY.iter().map(|c| c.to_string()));
    for (name, _) in &log.extra {
        if !names.contains(name) {
            names.push(name.clone());
        }
    }
    names.join(", ")
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
            .zip(&self.units)
            .map(|(&c, unit)| {
                EffectColumn::on(
                    &format!("{}_{}", self.name, CHANNEL_NAMES[c]),
                    unit,
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
        (
            self.expression.text().to_string(),
            self.product(s).unwrap_or_default(),
        )
    }
}
