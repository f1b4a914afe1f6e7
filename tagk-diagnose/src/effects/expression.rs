//! Expressions of log columns for custom effects (`--custom NAME='EXPR'@CH`).
//!
//! The text is parsed by the `exmex` crate with this module's own operators. One evaluation
//! computes every sample and the expression's SI unit together. A unit mistake (adding a
//! speed to a rate, `sin` of a speed) is found before any fit.
//!
//! Syntax:
//!
//! - log columns by their CSV names (`vx`, `wz`, `fz`, `w1`, an extra column `vbat`), `t`;
//! - `vbx`, `vby`, `vbz`: the body-frame velocity `Rᵀ v` \[m/s\], smoothed as the built-in drag
//!   effects read it;
//! - `d(col)` or `der(col)`: the time derivative of a column, by the Savitzky–Golay
//!   differentiator that derives accelerations from logs
//!   ([`tagk_dynamics::deriv::savitzky_golay_derivative`]);
//! - numbers (`2`, `0.5`, `1e-3`) and `PI`;
//! - `+ - * / ^`, and `pow(a, b)`, `min(a, b)`, `max(a, b)`;
//! - `abs`, `sign`, `sqrt`, `sin`, `cos`, `tan`, `atan`, `exp`, `ln`, `tanh`.
//!
//! A unary operator binds tighter than any binary one: `-vx^2` is `(-vx)^2`.

use std::str::FromStr;

use exmex::prelude::*;
use exmex::{BinOp, MakeOperators, MatchLiteral, Operator};

use crate::deriv::{DEFAULT_HALF_WIDTH, savitzky_golay_derivative};
use crate::log::FlightLog;
use crate::signals::Signals;

/// The exponents of kilogram, metre and second of an SI unit (the radian is 1).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Dimension(pub [f64; 3]);

impl Dimension {
    /// A pure number.
    pub const ONE: Dimension = Dimension([0.0; 3]);
    /// Newton, `kg m s⁻²` (the force channels).
    pub const NEWTON: Dimension = Dimension([1.0, 1.0, -2.0]);
    /// Newton metre, `kg m² s⁻²` (the torque channels).
    pub const NEWTON_METRE: Dimension = Dimension([1.0, 2.0, -2.0]);

    /// Whether it is a pure number.
    pub fn is_one(&self) -> bool {
        self.same(&Self::ONE)
    }

    /// Whether two dimensions are equal (exponents within 1e-9).
    pub fn same(&self, other: &Dimension) -> bool {
        self.0
            .iter()
            .zip(other.0)
            .all(|(a, b)| (a - b).abs() < 1e-9)
    }

    /// The product's dimension.
    pub fn mul(&self, other: &Dimension) -> Dimension {
        Dimension(std::array::from_fn(|k| self.0[k] + other.0[k]))
    }

    /// The quotient's dimension.
    pub fn div(&self, other: &Dimension) -> Dimension {
        Dimension(std::array::from_fn(|k| self.0[k] - other.0[k]))
    }

    /// The dimension raised to `p`.
    pub fn powf(&self, p: f64) -> Dimension {
        Dimension(self.0.map(|e| e * p))
    }
}

impl std::fmt::Display for Dimension {
    /// SI base units, e.g. `kg/m`, `m/s`, `kg m s^-2`; `1` for a pure number.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let names = ["kg", "m", "s"];
        let power = |name: &str, e: f64| {
            let e = (e * 1e6).round() / 1e6;
            if (e - 1.0).abs() < 1e-9 {
                name.to_string()
            } else {
                format!("{name}^{e}")
            }
        };
        let up: Vec<String> = (0..3)
            .filter(|&k| self.0[k] > 1e-9)
            .map(|k| power(names[k], self.0[k]))
            .collect();
        let down: Vec<String> = (0..3)
            .filter(|&k| self.0[k] < -1e-9)
            .map(|k| power(names[k], -self.0[k]))
            .collect();
        match (up.is_empty(), down.len()) {
            (true, 0) => f.write_str("1"),
            (false, 0) => f.write_str(&up.join(" ")),
            (true, _) => write!(f, "1/{}", wrap(&down)),
            (false, _) => write!(f, "{}/{}", up.join(" "), wrap(&down)),
        }
    }
}

/// Units after a `/`: one as it is, several in parentheses.
fn wrap(units: &[String]) -> String {
    if units.len() == 1 {
        units[0].clone()
    } else {
        format!("({})", units.join(" "))
    }
}

/// The SI unit of a log column or signal of an expression; `None` for an extra column (its
/// unit is the log's, not known to tagk).
pub fn column_unit(name: &str) -> Option<Dimension> {
    let d = |kg: f64, m: f64, s: f64| Some(Dimension([kg, m, s]));
    match name {
        "t" => d(0.0, 0.0, 1.0),
        "px" | "py" | "pz" => d(0.0, 1.0, 0.0),
        "vx" | "vy" | "vz" | "vbx" | "vby" | "vbz" => d(0.0, 1.0, -1.0),
        "ax" | "ay" | "az" => d(0.0, 1.0, -2.0),
        "qw" | "qx" | "qy" | "qz" => d(0.0, 0.0, 0.0),
        "wx" | "wy" | "wz" | "w1" | "w2" | "w3" | "w4" => d(0.0, 0.0, -1.0),
        "dwx" | "dwy" | "dwz" => d(0.0, 0.0, -2.0),
        "fx" | "fy" | "fz" => Some(Dimension::NEWTON),
        "tx" | "ty" | "tz" => Some(Dimension::NEWTON_METRE),
        _ => None,
    }
}

/// Signals of an expression that are not log columns: the body-frame velocity.
pub const BODY_VELOCITY: [&str; 3] = ["vbx", "vby", "vbz"];

/// A series of samples with its unit, or the first error met while computing it: the value
/// type the expression is evaluated on.
#[derive(Debug, Clone, Default)]
struct Series {
    /// One value per sample, or one value for a number.
    values: Vec<f64>,
    /// The unit (`None`: unknown).
    unit: Option<Dimension>,
    /// A number written in the expression: in a sum it takes the other term's unit.
    literal: bool,
    /// The first error.
    error: Option<String>,
}

impl FromStr for Series {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        let x: f64 = s.parse().map_err(|_| format!("`{s}` is not a number"))?;
        Ok(Series {
            values: vec![x],
            unit: Some(Dimension::ONE),
            literal: true,
            error: None,
        })
    }
}

impl Series {
    fn failed(reason: String) -> Series {
        Series {
            error: Some(reason),
            ..Series::default()
        }
    }

    fn map(self, f: impl Fn(f64) -> f64, unit: Option<Dimension>) -> Series {
        if self.error.is_some() {
            return self;
        }
        Series {
            values: self.values.iter().map(|&x| f(x)).collect(),
            unit,
            literal: self.literal,
            error: None,
        }
    }

    fn zip(self, other: Series, f: impl Fn(f64, f64) -> f64, unit: Option<Dimension>) -> Series {
        if self.error.is_some() {
            return self;
        }
        if other.error.is_some() {
            return other;
        }
        let n = self.values.len().max(other.values.len());
        let at = |v: &Vec<f64>, i: usize| if v.len() == 1 { v[0] } else { v[i] };
        Series {
            values: (0..n)
                .map(|i| f(at(&self.values, i), at(&other.values, i)))
                .collect(),
            unit,
            literal: self.literal && other.literal,
            error: None,
        }
    }

    /// The unit of a sum, a difference, a `min` or a `max`: both alike (a number takes the
    /// other's unit; an unknown unit is not checked).
    fn common_unit(&self, other: &Series, what: &str) -> Result<Option<Dimension>, String> {
        match (self.unit, other.unit) {
            (Some(a), Some(b)) if a.same(&b) => Ok(Some(a)),
            (Some(_), Some(b)) if self.literal => Ok(Some(b)),
            (Some(a), Some(_)) if other.literal => Ok(Some(a)),
            (Some(a), Some(b)) => Err(format!("{what} of different units: {a} and {b}")),
            _ => Ok(None),
        }
    }

    fn same_unit_op(self, other: Series, f: fn(f64, f64) -> f64, what: &str) -> Series {
        match self.common_unit(&other, what) {
            Ok(unit) => self.zip(other, f, unit),
            Err(e) if self.error.is_none() && other.error.is_none() => Series::failed(e),
            Err(_) => self.zip(other, f, None),
        }
    }

    fn power(self, exponent: Series) -> Series {
        let unit = match (self.unit, exponent.unit) {
            (_, Some(e)) if !e.is_one() => {
                return Series::failed(format!("an exponent must be a pure number, not {e}"));
            }
            (Some(u), _) if u.is_one() => Some(u),
            (Some(u), _) if exponent.literal && exponent.values.len() == 1 => {
                Some(u.powf(exponent.values[0]))
            }
            (Some(u), _) => {
                return Series::failed(format!(
                    "a quantity in {u} raised to a non-constant power has no unit"
                ));
            }
            (None, _) => None,
        };
        self.zip(exponent, f64::powf, unit)
    }

    /// A function that needs a pure number (`sin`, `exp`, …).
    fn transcendental(self, name: &str, f: fn(f64) -> f64) -> Series {
        match self.unit {
            Some(u) if !u.is_one() && self.error.is_none() => Series::failed(format!(
                "{name}() needs a pure number, not a quantity in {u}"
            )),
            unit => self.map(f, unit),
        }
    }
}

/// The operators of custom expressions on [`Series`] (priorities as exmex's float operators).
#[derive(Debug, Clone)]
struct SeriesOps;

fn bin(prio: i64, is_commutative: bool, apply: fn(Series, Series) -> Series) -> BinOp<Series> {
    BinOp {
        apply,
        prio,
        is_commutative,
    }
}

impl MakeOperators<Series> for SeriesOps {
    fn make<'a>() -> Vec<Operator<'a, Series>> {
        vec![
            Operator::make_bin("^", bin(4, false, Series::power)),
            Operator::make_bin("pow", bin(0, false, Series::power)),
            Operator::make_bin(
                "*",
                bin(2, true, |a, b| {
                    let unit = match (a.unit, b.unit) {
                        (Some(x), Some(y)) => Some(x.mul(&y)),
                        _ => None,
                    };
                    a.zip(b, |x, y| x * y, unit)
                }),
            ),
            Operator::make_bin(
                "/",
                bin(3, false, |a, b| {
                    let unit = match (a.unit, b.unit) {
                        (Some(x), Some(y)) => Some(x.div(&y)),
                        _ => None,
                    };
                    a.zip(b, |x, y| x / y, unit)
                }),
            ),
            Operator::make_bin_unary(
                "+",
                bin(0, true, |a, b| a.same_unit_op(b, |x, y| x + y, "a sum")),
                |a| a,
            ),
            Operator::make_bin_unary(
                "-",
                bin(1, false, |a, b| {
                    a.same_unit_op(b, |x, y| x - y, "a difference")
                }),
                |a| {
                    let unit = a.unit;
                    a.map(|x| -x, unit)
                },
            ),
            Operator::make_bin(
                "min",
                bin(0, false, |a, b| a.same_unit_op(b, f64::min, "min()")),
            ),
            Operator::make_bin(
                "max",
                bin(0, false, |a, b| a.same_unit_op(b, f64::max, "max()")),
            ),
            Operator::make_unary("abs", |a| {
                let unit = a.unit;
                a.map(f64::abs, unit)
            }),
            Operator::make_unary("sign", |a| {
                a.map(
                    |x| if x == 0.0 { 0.0 } else { x.signum() },
                    Some(Dimension::ONE),
                )
            }),
            Operator::make_unary("sqrt", |a| {
                let unit = a.unit.map(|u| u.powf(0.5));
                a.map(f64::sqrt, unit)
            }),
            Operator::make_unary("sin", |a| a.transcendental("sin", f64::sin)),
            Operator::make_unary("cos", |a| a.transcendental("cos", f64::cos)),
            Operator::make_unary("tan", |a| a.transcendental("tan", f64::tan)),
            Operator::make_unary("atan", |a| a.transcendental("atan", f64::atan)),
            Operator::make_unary("tanh", |a| a.transcendental("tanh", f64::tanh)),
            Operator::make_unary("exp", |a| a.transcendental("exp", f64::exp)),
            Operator::make_unary("ln", |a| a.transcendental("ln", f64::ln)),
            Operator::make_constant(
                "PI",
                Series {
                    values: vec![std::f64::consts::PI],
                    unit: Some(Dimension::ONE),
                    literal: true,
                    error: None,
                },
            ),
        ]
    }
}

/// Numbers of custom expressions: `2`, `0.5`, `.5`, `1e-3`, `2.5E+2`.
#[derive(Debug, Clone)]
struct NumberLiteral;

impl MatchLiteral for NumberLiteral {
    fn is_literal(text: &str) -> Option<&str> {
        let b = text.as_bytes();
        let digits = |mut i: usize| {
            while i < b.len() && b[i].is_ascii_digit() {
                i += 1;
            }
            i
        };
        let mut i = digits(0);
        let mut mantissa = i > 0;
        if i < b.len() && b[i] == b'.' {
            let j = digits(i + 1);
            mantissa |= j > i + 1;
            i = j;
        }
        if !mantissa {
            return None;
        }
        if i < b.len() && (b[i] == b'e' || b[i] == b'E') {
            let mut j = i + 1;
            if j < b.len() && (b[j] == b'+' || b[j] == b'-') {
                j += 1;
            }
            let k = digits(j);
            if k > j {
                i = k;
            }
        }
        Some(&text[..i])
    }
}

type Parsed = FlatEx<Series, SeriesOps, NumberLiteral>;

/// One input of an expression: a log column (or `vbx..vbz`), or a column's time derivative.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Input {
    /// A log column or a body-frame velocity component, by name.
    Column(String),
    /// The time derivative of a log column (`d(col)`), by the column's name.
    Derivative(String),
}

impl Input {
    /// The column it reads.
    pub fn column(&self) -> &str {
        match self {
            Input::Column(c) | Input::Derivative(c) => c,
        }
    }

    /// Its unit (`None`: an extra column).
    pub fn unit(&self) -> Option<Dimension> {
        match self {
            Input::Column(c) => column_unit(c),
            Input::Derivative(c) => column_unit(c).map(|u| u.div(&Dimension([0.0, 0.0, 1.0]))),
        }
    }
}

impl std::fmt::Display for Input {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Input::Column(c) => f.write_str(c),
            Input::Derivative(c) => write!(f, "d({c})"),
        }
    }
}

/// The prefix of the variables that stand for `d(col)` in the text given to the parser.
const DERIVATIVE_PREFIX: &str = "__d__";

/// Why an expression is refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ExpressionError {
    /// It does not parse: a syntax error, an unknown function, `d()` of anything but one
    /// column.
    #[error("{0}")]
    Syntax(String),
    /// A unit mistake: a sum, difference, `min` or `max` of different units, a function that
    /// needs a pure number given a quantity, an exponent with a unit.
    #[error("{0}")]
    Units(String),
}

/// A parsed custom expression: its text, its inputs and its unit.
#[derive(Debug, Clone)]
pub struct Expression {
    text: String,
    /// Boxed: the parser keeps its nodes inline (22 kB).
    parsed: std::sync::Arc<Parsed>,
    /// The inputs, in the parser's variable order.
    inputs: Vec<Input>,
    unit: Option<Dimension>,
}

impl PartialEq for Expression {
    fn eq(&self, other: &Self) -> bool {
        self.text == other.text
    }
}

impl Expression {
    /// Parses `text` and infers its unit from the columns' units ([`column_unit`]).
    ///
    /// # Errors
    /// [`ExpressionError::Syntax`]: a syntax error, an unknown function, `d()` of anything
    /// but one column; [`ExpressionError::Units`]: a unit mistake (a sum of different units, a
    /// function of a quantity that needs a pure number).
    pub fn parse(text: &str) -> Result<Self, ExpressionError> {
        let syntax = ExpressionError::Syntax;
        let rewritten = rewrite_derivatives(text).map_err(syntax)?;
        let parsed = Parsed::parse(&rewritten)
            .map_err(|e| syntax(format!("cannot parse `{}`: {e}", text.trim())))?;
        let inputs: Vec<Input> = parsed
            .var_names()
            .iter()
            .map(|v| match v.strip_prefix(DERIVATIVE_PREFIX) {
                Some(c) => Input::Derivative(c.to_string()),
                None => Input::Column(v.clone()),
            })
            .collect();
        if let Some(bad) = inputs.iter().find(|i| {
            let c = i.column();
            c.chars()
                .any(|ch| !(ch.is_ascii_alphanumeric() || ch == '_'))
        }) {
            return Err(syntax(format!("`{bad}` is not a column name")));
        }
        let probe: Vec<Series> = inputs
            .iter()
            .map(|i| Series {
                values: vec![1.0],
                unit: i.unit(),
                literal: false,
                error: None,
            })
            .collect();
        let out = parsed
            .eval(&probe)
            .map_err(|e| syntax(format!("cannot evaluate `{}`: {e}", text.trim())))?;
        if let Some(e) = out.error {
            return Err(ExpressionError::Units(e));
        }
        Ok(Self {
            text: text.trim().to_string(),
            parsed: std::sync::Arc::new(parsed),
            inputs,
            unit: out.unit,
        })
    }

    /// The text as given (trimmed).
    pub fn text(&self) -> &str {
        &self.text
    }

    /// The inputs it reads, each once, in alphabetical order of their names.
    pub fn inputs(&self) -> &[Input] {
        &self.inputs
    }

    /// Its SI unit, `None` when it reads an extra column (unit unknown).
    pub fn unit(&self) -> Option<Dimension> {
        self.unit
    }

    /// The inputs a log lacks (by column name; `vbx..vbz` are always there).
    pub fn missing_columns(&self, log: &FlightLog) -> Vec<String> {
        let mut missing: Vec<String> = Vec::new();
        for i in &self.inputs {
            let c = i.column();
            let derived = BODY_VELOCITY.contains(&c) && !matches!(i, Input::Derivative(_));
            if !derived && log.signal(c).is_none() && !missing.iter().any(|m| m == c) {
                missing.push(c.to_string());
            }
        }
        missing
    }

    /// Evaluates the expression at every sample of `s`. A derivative is taken on each
    /// joined log on its own, never across a join.
    ///
    /// # Errors
    /// `Err(reason)`: a column the log lacks, or a value that is not finite (naming the
    /// time of the first one).
    pub fn evaluate(&self, s: &Signals) -> Result<Vec<f64>, String> {
        let mut vars = Vec::with_capacity(self.inputs.len());
        for input in &self.inputs {
            let values = input_values(input, s)?;
            vars.push(Series {
                values,
                unit: input.unit(),
                literal: false,
                error: None,
            });
        }
        let out = self
            .parsed
            .eval(&vars)
            .map_err(|e| format!("cannot evaluate `{}`: {e}", self.text))?;
        if let Some(e) = out.error {
            return Err(e);
        }
        let values = if out.values.len() == 1 {
            vec![out.values[0]; s.len()]
        } else {
            out.values
        };
        if let Some(i) = values.iter().position(|x| !x.is_finite()) {
            return Err(format!(
                "`{}` is {} at t = {} s (not a finite number)",
                self.text, values[i], s.t[i]
            ));
        }
        Ok(values)
    }
}

/// One input's values on `s`.
fn input_values(input: &Input, s: &Signals) -> Result<Vec<f64>, String> {
    let column = |s: &Signals, c: &str| -> Result<Vec<f64>, String> {
        if let Some(k) = BODY_VELOCITY.iter().position(|n| *n == c)
            && s.log().signal(c).is_none()
        {
            return Ok(s.velocity_body.iter().map(|v| v[k]).collect());
        }
        s.log()
            .signal(c)
            .ok_or_else(|| format!("log has no column `{c}`"))
    };
    match input {
        Input::Column(c) => column(s, c),
        Input::Derivative(c) => {
            let one = |p: &Signals| -> Result<Vec<f64>, String> {
                Ok(savitzky_golay_derivative(
                    &p.t,
                    &column(p, c)?,
                    DEFAULT_HALF_WIDTH,
                ))
            };
            if s.parts().is_empty() {
                one(s)
            } else {
                let mut all = Vec::with_capacity(s.len());
                for p in s.parts() {
                    all.extend(one(p)?);
                }
                Ok(all)
            }
        }
    }
}

/// Replaces each `d(col)` / `der(col)` by a variable the parser reads as one name.
fn rewrite_derivatives(text: &str) -> Result<String, String> {
    let chars: Vec<char> = text.chars().collect();
    let mut out = String::with_capacity(text.len());
    let mut i = 0;
    let ident = |c: char| c.is_ascii_alphanumeric() || c == '_';
    while i < chars.len() {
        if ident(chars[i]) && (i == 0 || !ident(chars[i - 1])) {
            let start = i;
            while i < chars.len() && ident(chars[i]) {
                i += 1;
            }
            let word: String = chars[start..i].iter().collect();
            let mut j = i;
            while j < chars.len() && chars[j] == ' ' {
                j += 1;
            }
            if (word == "d" || word == "der") && j < chars.len() && chars[j] == '(' {
                let close = chars[j..]
                    .iter()
                    .position(|&c| c == ')')
                    .map(|k| j + k)
                    .ok_or_else(|| format!("`{word}(` without `)` in `{text}`"))?;
                let arg: String = chars[j + 1..close].iter().collect();
                let arg = arg.trim();
                if arg.is_empty() || !arg.chars().all(ident) {
                    return Err(format!(
                        "{word}() takes one log column, e.g. {word}(vx), not `{arg}`"
                    ));
                }
                out.push_str(DERIVATIVE_PREFIX);
                out.push_str(arg);
                i = close + 1;
            } else {
                out.push_str(&word);
            }
        } else {
            out.push(chars[i]);
            i += 1;
        }
    }
    Ok(out)
}
