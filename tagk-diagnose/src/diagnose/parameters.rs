//! The fitted rigid-body parameters and their plausibility: centre of mass against the
//! airframe, physical consistency, the safety gate, implausible effect coefficients.

use tagk_dynamics::SafetyGate;

use crate::diagnose::DiagnoseOptions;
use crate::diagnose::sanity::{
    Limits, MAX_MASS_FROM_VEHICLE, com_excess, consistency_margin, consistent_within_tolerance,
};
use crate::fit::{Coefficient, Fit, THETA_NAMES, THETA_UNITS};

/// A rigid-body parameter estimate.
pub type Parameter = Coefficient;

/// The outcome of [`parameter_report`].
pub(crate) struct ParameterReport {
    /// The ten parameters with standard errors.
    pub parameters: Vec<Parameter>,
    /// Centre of mass \[m\] (zeros when the fitted mass is not positive).
    pub com: [f64; 3],
    /// Pseudo-inertia positive definite within the tolerance
    /// ([`crate::CONSISTENCY_TOLERANCE`]).
    pub physically_consistent: bool,
    /// Safety gate verdict.
    pub safety_gate: String,
    /// Implausible estimates and what they suggest.
    pub warnings: Vec<String>,
}

/// The parameters of `fit` and their plausibility (step 4 of [`crate::diagnose()`]): a
/// non-positive mass, a mass far from the vehicle file's, a centre of mass significantly
/// outside the airframe (horizontally beyond its radius, vertically too far from the rotor
/// plane: evidence of an unmodelled force; the message names `recommended` when there is
/// one), physical inconsistency beyond the tolerance, and effects fitted implausibly.
pub(crate) fn parameter_report(
    fit: &Fit,
    s: &crate::signals::Signals,
    opts: &DiagnoseOptions,
    recommended: Option<&str>,
) -> ParameterReport {
    let airframe_radius = opts.airframe_radius;
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
    let physically_consistent = consistent_within_tolerance(&theta);
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
        let limits = Limits {
            airframe_radius,
            com_vertical: opts.com_vertical_limit,
            rotor_plane: opts.rotor_plane_height,
            known_mass: false,
        };
        let se: [f64; 10] = std::array::from_fn(|j| fit.theta_se[j].unwrap_or(f64::INFINITY));
        let (horizontal, vertical) = com_excess(&limits, &theta, &se);
        let mut outside = Vec::new();
        if horizontal > 0.0 {
            outside.push(format!(
                "{:.1} cm from the body's z axis (airframe radius {:.1} cm)",
                100.0 * (com[0].powi(2) + com[1].powi(2)).sqrt(),
                100.0 * airframe_radius
            ));
        }
        if vertical > 0.0 {
            outside.push(format!(
                "{:.1} cm {} the rotor plane (at most {:.1} cm)",
                100.0 * (com[2] - opts.rotor_plane_height).abs(),
                if com[2] < opts.rotor_plane_height {
                    "below"
                } else {
                    "above"
                },
                100.0 * opts.com_vertical_limit
            ));
        }
        if !outside.is_empty() {
            warnings.push(format!(
                "fitted centre of mass outside the airframe ({}): this is evidence of an unmodelled force or torque{}, not a real centre of mass",
                outside.join("; "),
                recommended
                    .map(|r| format!(" (the ranking points at `{r}`)"))
                    .unwrap_or_default()
            ));
        }
        if let Some(mv) = opts.vehicle_mass
            && ((m - mv) / mv).abs() > MAX_MASS_FROM_VEHICLE
        {
            warnings.push(format!(
                "fitted mass {m:.4} kg is {:+.0} % off the vehicle file's {mv:.4} kg: a payload, a wrong thrust coefficient, or a wrong vehicle file",
                100.0 * (m - mv) / mv
            ));
        }
    }
    if !physically_consistent && m > 0.0 {
        warnings.push(format!(
            "the fitted parameters are not physically consistent: the pseudo-inertia's consistency margin is {:.3}, beyond the tolerance −{}",
            consistency_margin(&theta),
            crate::diagnose::CONSISTENCY_TOLERANCE
        ));
    }
    warnings.extend(attenuation_warnings(s));
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

/// An inertia whose axis' angular acceleration hardly rises above the noise of the
/// differentiated gyro is biased towards zero (errors in variables: the noise of a regressor
/// column attenuates its coefficient by `signal / (signal + noise)` in variance): a warning
/// per such axis, with the attenuation, when it exceeds [`ATTENUATION_WARNING`].
fn attenuation_warnings(s: &crate::signals::Signals) -> Vec<String> {
    let n = s.len();
    if n < 8 {
        return Vec::new();
    }
    let series: Vec<[f64; 6]> = (0..n)
        .map(|i| {
            let w = s.omega_dot(i);
            [w.x, w.y, w.z, 0.0, 0.0, 0.0]
        })
        .collect();
    let noise = crate::fit::high_frequency_noise(s, &series);
    let mut out = Vec::new();
    for (k, axis) in ["xx", "yy", "zz"].iter().enumerate() {
        let mean = series.iter().map(|x| x[k]).sum::<f64>() / n as f64;
        let var = series.iter().map(|x| (x[k] - mean).powi(2)).sum::<f64>() / n as f64;
        let noise2 = noise[k] * noise[k];
        if var <= 0.0 {
            continue;
        }
        let attenuation = (noise2 / var).min(1.0);
        if attenuation > ATTENUATION_WARNING {
            out.push(format!(
                "I_{axis} is biased towards zero by about {:.0} %: the flight's angular acceleration about {} is only {:.1}× the noise of the differentiated gyro (errors in variables; fly sharper {} rotations)",
                100.0 * attenuation,
                &axis[..1],
                ((var - noise2).max(0.0) / noise2.max(f64::MIN_POSITIVE)).sqrt(),
                match k {
                    0 => "roll",
                    1 => "pitch",
                    _ => "yaw",
                }
            ));
        }
    }
    out
}

/// Attenuation of an inertia by the noise of its angular acceleration beyond which the report
/// warns (10 %).
pub(crate) const ATTENUATION_WARNING: f64 = 0.10;
