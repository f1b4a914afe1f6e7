//! The fitted rigid-body parameters and their plausibility: centre of mass against the
//! airframe, physical consistency, the safety gate, implausible effect coefficients.

use tagk_dynamics::SafetyGate;

use crate::fit::{Coefficient, Fit, THETA_NAMES, THETA_UNITS};

/// A rigid-body parameter estimate.
pub type Parameter = Coefficient;

/// The outcome of [`parameter_report`].
pub(crate) struct ParameterReport {
    /// The ten parameters with standard errors.
    pub parameters: Vec<Parameter>,
    /// Centre of mass \[m\] (zeros when the fitted mass is not positive).
    pub com: [f64; 3],
    /// Pseudo-inertia positive definite.
    pub physically_consistent: bool,
    /// Safety gate verdict.
    pub safety_gate: String,
    /// Implausible estimates and what they suggest.
    pub warnings: Vec<String>,
}

/// The parameters of `fit` and their plausibility (step 4 of [`crate::diagnose()`]): a
/// non-positive mass, a centre of mass significantly outside `airframe_radius` \[m\] (evidence
/// of an unmodelled force; the message names `recommended` when there is one), physical
/// inconsistency, and effects fitted implausibly.
pub(crate) fn parameter_report(
    fit: &Fit,
    airframe_radius: f64,
    recommended: Option<&str>,
) -> ParameterReport {
    let theta = fit.theta;
    let parameters: Vec<Parameter> = (0..10)
        .map(|j| {
            Coefficient::new(
                THETA_NAMES[j],
                THETA_UNITS[j],
                theta.as_slice()[j],
                fit.theta_se[j],
            )
        })
        .collect();
    let m = theta.mass();
    let h = theta.first_moment();
    let com = if m > 0.0 {
        [h.x / m, h.y / m, h.z / m]
    } else {
        [f64::NAN; 3]
    };
    let mut warnings = Vec::new();
    let physically_consistent = theta.is_physically_consistent();
    let safety_gate = match theta.safety_gate(&SafetyGate {
        max_com_offset: airframe_radius,
        ..SafetyGate::crazyflie()
    }) {
        Ok(()) => "pass".to_string(),
        Err(v) => format!("{v}"),
    };
    let com_json = if m > 0.0 { com } else { [0.0; 3] };
    if m <= 0.0 {
        warnings.push(format!(
            "fitted mass {m:.4} kg is not positive: the model is missing a force, do not trust these parameters"
        ));
    } else {
        let mut outside = Vec::new();
        for (k, axis) in ["x", "y", "z"].iter().enumerate() {
            let se = fit.theta_se[1 + k].map_or(f64::INFINITY, |s| s / m);
            if com[k].abs() - 2.0 * se > airframe_radius {
                outside.push(format!(
                    "c_{axis} = {:.1} cm (± {:.1})",
                    com[k] * 100.0,
                    se * 100.0
                ));
            }
        }
        if !outside.is_empty() {
            warnings.push(format!(
                "fitted centre of mass outside the airframe ({} vs radius {:.1} cm): this is evidence of an unmodelled force or torque{}, not a real centre of mass",
                outside.join(", "),
                airframe_radius * 100.0,
                recommended
                    .map(|r| format!(" (the ranking points at `{r}`)"))
                    .unwrap_or_default()
            ));
        }
    }
    if !physically_consistent && m > 0.0 {
        warnings.push(
            "the fitted parameters are not physically consistent (pseudo-inertia not positive definite)".into(),
        );
    }
    for fe in &fit.effects {
        if !fe.plausible {
            warnings.push(format!(
                "effect `{}` fitted implausibly: {}",
                fe.effect, fe.plausibility_note
            ));
        }
    }
    ParameterReport {
        parameters,
        com: com_json,
        physically_consistent,
        safety_gate,
        warnings,
    }
}
