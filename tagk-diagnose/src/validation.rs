//! Scores of fitted models on a second log of the same vehicle (`tagk diagnose --validate`).
//!
//! Each model of the staircase keeps its fitted parameters and coefficients. Its wrench is
//! predicted on the validation log and compared with the measured one. Nothing is refitted
//! except what belongs to one flight: a sensor effect's coefficients (an accelerometer bias)
//! and the start-of-log nuisance columns, least squares on the validation log.

use serde::Serialize;
use tagk_dynamics::write_rigid_body_regressor;

use crate::effects::{EffectRef, effect_columns, is_sensor_effect};
use crate::error::DiagnoseError;
use crate::fit::{ColData, Fit, design_of_columns, is_start_nuisance};
use crate::model_file::ModelEffect;
use crate::signals::{CHANNEL_NAMES, Signals};

/// One model's error on the validation log.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ValidationStep {
    /// The model's label (`rigid body + …`), as in the staircase.
    pub model: String,
    /// Residual RMS per channel on the validation log (N, N m), in the order `fx … tz`.
    pub rms: [f64; 6],
}

/// The staircase's models scored on a validation log.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Validation {
    /// The validation log's name (its file).
    pub log: String,
    /// Samples of the validation log used.
    pub samples: usize,
    /// One entry per model of [`crate::Report::step_fits`]: the rigid body, the `--with`
    /// model when given, then each staircase step; the last is the final model.
    pub steps: Vec<ValidationStep>,
}

impl Validation {
    /// The final model's residual RMS per channel on the validation log.
    pub fn final_rms(&self) -> Option<[f64; 6]> {
        self.steps.last().map(|s| s.rms)
    }

    /// A few lines for the terminal: each model's RMS per channel.
    pub fn text(&self) -> String {
        let mut out = format!(
            "validation on {} ({} samples): residual RMS per channel (N, N m), fitted models not refitted\n",
            self.log, self.samples
        );
        out.push_str(&format!("  {:<40}", "model"));
        for c in CHANNEL_NAMES {
            out.push_str(&format!(" {c:>10}"));
        }
        out.push('\n');
        for s in &self.steps {
            let label: String = s.model.chars().take(40).collect();
            out.push_str(&format!("  {label:<40}"));
            for r in s.rms {
                out.push_str(&format!(" {r:>10.3e}"));
            }
            out.push('\n');
        }
        out
    }
}

/// The residual RMS per channel of `fit` on the signals `s` of another log: the fit's
/// parameters and coefficients, its model's `effects` (found by name), the per-flight
/// columns (sensor effects, start nuisances) fitted again on `s`.
///
/// # Errors
/// [`DiagnoseError::EffectUnavailable`] for an effect of the fit that is not among
/// `effects`, or cannot be used on `s`.
pub fn validation_rms(
    fit: &Fit,
    effects: &[EffectRef],
    s: &Signals,
) -> Result<[f64; 6], DiagnoseError> {
    let n = s.len();
    let theta = fit.theta.to_array();
    let mut predicted = vec![[0.0; 6]; n];
    let mut buf = [0.0; 60];
    for (i, p) in predicted.iter_mut().enumerate() {
        // Infallible: the buffer has 60 entries.
        let _ =
            write_rigid_body_regressor(&s.accel_proper[i], &s.omega(i), &s.omega_dot(i), &mut buf);
        for c in 0..6 {
            p[c] = (0..10).map(|j| buf[10 * c + j] * theta[j]).sum();
        }
    }
    let mut nuisance: Vec<ColData> = Vec::new();
    for (k, fitted) in fit.effects.iter().enumerate() {
        let effect = effects
            .iter()
            .find(|e| e.name() == fitted.effect)
            .ok_or_else(|| DiagnoseError::EffectUnavailable {
                effect: fitted.effect.clone(),
                reason: "not among the plan's effects: cannot be predicted on the validation log"
                    .into(),
            })?;
        let param = fit.params.get(k).copied().flatten();
        let columns = effect_columns(effect.as_ref(), s, param);
        crate::effects::check_columns(&columns, s).map_err(|reason| {
            DiagnoseError::EffectUnavailable {
                effect: fitted.effect.clone(),
                reason: format!("on the validation log: {reason}"),
            }
        })?;
        let design = design_of_columns(columns, s);
        let record = ModelEffect::of(fitted, None);
        let sensor = is_sensor_effect(&fitted.effect);
        for (col, (name, _)) in design.cols.into_iter().zip(&design.names) {
            if sensor || is_start_nuisance(name) {
                nuisance.push(col);
                continue;
            }
            let beta = record.coefficient(name).unwrap_or(0.0);
            add_column(&mut predicted, &col, beta);
        }
        if let Some(offset) = &design.offset {
            add_column(&mut predicted, offset, 1.0);
        }
    }
    let mut residual: Vec<[f64; 6]> = s
        .target()
        .iter()
        .zip(&predicted)
        .map(|(b, p)| std::array::from_fn(|c| b[c] - p[c]))
        .collect();
    if !nuisance.is_empty() {
        refit_nuisance(&mut residual, &nuisance);
    }
    Ok(std::array::from_fn(|c| {
        (residual.iter().map(|r| r[c] * r[c]).sum::<f64>() / n.max(1) as f64).sqrt()
    }))
}

/// `values += beta · col` on the channels `col` touches.
fn add_column(values: &mut [[f64; 6]], col: &ColData, beta: f64) {
    for (c, d) in col.iter().enumerate() {
        if let Some(v) = d {
            for (x, o) in values.iter_mut().zip(v) {
                x[c] += beta * o;
            }
        }
    }
}

/// Removes from `residual` its least-squares fit on the columns `cols` (all channels
/// stacked, unweighted; a singular system keeps the residual as it is).
fn refit_nuisance(residual: &mut [[f64; 6]], cols: &[ColData]) {
    let m = cols.len();
    let mut gram = nalgebra::DMatrix::<f64>::zeros(m, m);
    let mut rhs = nalgebra::DVector::<f64>::zeros(m);
    for c in 0..6 {
        for a in 0..m {
            let Some(va) = &cols[a][c] else { continue };
            rhs[a] += va
                .iter()
                .zip(residual.iter())
                .map(|(x, r)| x * r[c])
                .sum::<f64>();
            for b in 0..m {
                if let Some(vb) = &cols[b][c] {
                    gram[(a, b)] += va.iter().zip(vb).map(|(x, y)| x * y).sum::<f64>();
                }
            }
        }
    }
    let Some(beta) = gram.cholesky().map(|ch| ch.solve(&rhs)) else {
        return;
    };
    for (a, col) in cols.iter().enumerate() {
        add_column(residual, col, -beta[a]);
    }
}
