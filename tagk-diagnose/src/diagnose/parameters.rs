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
/// `limits` are the airframe's ([`crate::diagnose::limits_of`] of `opts`).
pub(crate) fn parameter_report(
    fit: &Fit,
    s: &crate::signals::Signals,
    opts: &DiagnoseOptions,
    limits: &Limits,
    recommended: Option<&str>,
) -> ParameterReport {
    let airframe_radius = limits.airframe_radius;
    // The reported parameters are physically consistent ([`Fit::consistent_theta`]).
    let theta = fit.consistent_theta();
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
    let physically_consistent = consistent_within_tolerance(&fit.theta);
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
        let se: [f64; 10] = std::array::from_fn(|j| fit.theta_se[j].unwrap_or(f64::INFINITY));
        let (horizontal, vertical) = com_excess(limits, &theta, &se);
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
                100.0 * (com[2] - limits.rotor_plane).abs(),
                if com[2] < limits.rotor_plane {
                    "below"
                } else {
                    "above"
                },
                100.0 * limits.com_vertical
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
            consistency_margin(&fit.theta),
            crate::diagnose::CONSISTENCY_TOLERANCE
        ));
    }
    if let Some(note) = repair_note(fit, &theta) {
        warnings.push(note);
    }
    warnings.extend(attenuation_warnings(s, fit));
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

/// What the consistency repair ([`Fit::consistent_theta`]) changed, when it moved a
/// parameter by at least a tenth of its standard error: the largest move, in standard errors.
fn repair_note(fit: &Fit, repaired: &tagk_dynamics::InertialParams) -> Option<String> {
    let (k, moved) = (0..10)
        .filter_map(|k| {
            let se = fit.theta_se[k]?;
            let d = repaired.as_slice()[k] - fit.theta.as_slice()[k];
            (se > 0.0).then_some((k, d / se))
        })
        .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))?;
    (moved.abs() >= 0.1).then(|| {
        format!(
            "the least-squares parameters are no body's (a pseudo-inertia eigenvalue of {:.2e}); the reported ones are the nearest physically consistent parameters in the fit's covariance: {} moved by {:+.1} standard errors",
            fit.theta.min_pseudo_inertia_eigenvalue().unwrap_or(f64::NAN),
            THETA_NAMES[k],
            moved
        )
    })
}

/// An inertia whose axis' angular acceleration hardly rises above the noise of the
/// differentiated gyro is biased towards zero (errors in variables: the noise of a regressor
/// column attenuates its coefficient by `signal / (signal + noise)` in variance): a warning
/// per such axis, with the attenuation, when it exceeds [`ATTENUATION_WARNING`]. The figure is
/// the open-loop one. In closed loop the commanded torque reacts to the gyro's noise, so the
/// torque and the noise of the angular acceleration are correlated. That correlation offsets
/// part of the attenuation: the README's realistic example warns of 95 % on I_zz and is 36 %
/// low. The warning gives the open-loop figure as such, and says the bias may be smaller.
///
/// The noise of the angular acceleration comes from the gyro's: its high-frequency part
/// (second differences, robust) `σ_g`. A derived angular acceleration carries it through the
/// differentiator's noise gain ([`tagk_dynamics::deriv::derivative_noise_gain`]). A logged one
/// is taken at its own high-frequency part, but at most `√2 σ_g / Δt`, the noise of the
/// gyro's first difference (the noisiest way to differentiate it): a sharp flight's own
/// high-frequency motion is not noise. Last, noise `n` in the angular acceleration would leave
/// about `Î n` in the fitted model's torque residual (`Î` the fitted inertia of the axis), so
/// the noise is at most that residual's RMS over `Î`: a log whose torques were computed from
/// the same angular accelerations (a consistent simulation) shows no bias.
fn attenuation_warnings(s: &crate::signals::Signals, fit: &Fit) -> Vec<String> {
    let mut out = Vec::new();
    for (k, a) in inertia_attenuation(s, fit).iter().enumerate() {
        let Some((attenuation, ratio)) = *a else {
            continue;
        };
        if attenuation > ATTENUATION_WARNING {
            let (axis, rotation) = [("x", "roll"), ("y", "pitch"), ("z", "yaw")][k];
            out.push(format!(
                "I_{axis}{axis} may be biased towards zero: the flight's angular acceleration about {axis} is only {ratio:.1}× the noise of the differentiated gyro (errors in variables). Open loop, that noise would bias it by about {:.0} %. A controller that reacts to the gyro's noise makes the bias smaller. Fly sharper {rotation} rotations",
                100.0 * attenuation,
            ));
        }
    }
    out
}

/// Per body axis, the attenuation of the fitted inertia by the noise of the angular
/// acceleration (its share of the measured variance) and the signal's deviation over that
/// noise ([`attenuation_warnings`]); `None` for an axis without any angular acceleration.
fn inertia_attenuation(s: &crate::signals::Signals, fit: &Fit) -> [Option<(f64, f64)>; 3] {
    let n = s.len();
    if n < 8 {
        return [None; 3];
    }
    let series = |f: &dyn Fn(usize) -> nalgebra::Vector3<f64>| -> Vec<[f64; 6]> {
        (0..n)
            .map(|i| {
                let w = f(i);
                [w.x, w.y, w.z, 0.0, 0.0, 0.0]
            })
            .collect()
    };
    let gyro_noise = crate::fit::high_frequency_noise(s, &series(&|i| s.omega(i)));
    let dt = s.mean_dt().max(f64::MIN_POSITIVE);
    let noise: [f64; 3] = if s.derived_omega_dot {
        let gain = crate::deriv::derivative_noise_gain(crate::deriv::DEFAULT_HALF_WIDTH) / dt;
        std::array::from_fn(|k| gyro_noise[k] * gain)
    } else {
        let own = crate::fit::high_frequency_noise(s, &series(&|i| s.omega_dot(i)));
        std::array::from_fn(|k| own[k].min(std::f64::consts::SQRT_2 * gyro_noise[k] / dt))
    };
    let theta = fit.theta.as_slice();
    let inertia = [theta[4], theta[6], theta[9]];
    // The covariance of the angular acceleration's three axes, and its inverse.
    let mean = (0..n).fold(nalgebra::Vector3::zeros(), |acc, i| acc + s.omega_dot(i)) / n as f64;
    let covariance = (0..n).fold(nalgebra::Matrix3::zeros(), |acc, i| {
        let d = s.omega_dot(i) - mean;
        acc + d * d.transpose()
    }) / n as f64;
    let precision = covariance
        .try_inverse()
        .filter(|p| p.iter().all(|x| x.is_finite()));
    std::array::from_fn(|k| {
        // The torque residual's bound on the noise.
        let rms = (fit
            .residual
            .iter()
            .map(|r| r[3 + k] * r[3 + k])
            .sum::<f64>()
            / fit.residual.len().max(1) as f64)
            .sqrt();
        let noise = if inertia[k] > 0.0 {
            noise[k].min(rms / inertia[k])
        } else {
            noise[k]
        };
        let var = covariance[(k, k)];
        if var <= 0.0 {
            return None;
        }
        let noise2 = noise * noise;
        // The noise's share of the axis' variance given the other axes: the diagonal of the
        // inverse covariance (an axis whose motion the others explain keeps less signal).
        let share = precision.map_or(noise2 / var, |p| p[(k, k)] * noise2);
        let attenuation = share.clamp(0.0, 1.0);
        let ratio = ((var - noise2).max(0.0) / noise2.max(f64::MIN_POSITIVE)).sqrt();
        Some((attenuation, ratio))
    })
}

/// Attenuation of an inertia by the noise of its angular acceleration beyond which the report
/// warns (10 %).
pub(crate) const ATTENUATION_WARNING: f64 = 0.10;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fit::{Model, fit_model};
    use crate::signals::Signals;
    use crate::testdata::{crazyflie, gauss, synthetic_log};
    use nalgebra::Vector3;
    use rand_chacha::ChaCha8Rng;
    use rand_core::SeedableRng;

    /// A log whose gyro has white noise `sigma_g` and whose angular acceleration is the noisy
    /// gyro's first difference (as a flight controller logs it; the signal part is the exact
    /// derivative). The torques are the true ones or, with `consistent`, computed from the
    /// noisy gyro and angular acceleration. Returns the signals, the rigid-body fit and the
    /// angular acceleration's noise per axis, `√2 σ_g / Δt`.
    fn differenced_gyro_log(sigma_g: f64, consistent: bool) -> (Signals, Fit, f64) {
        let theta = crazyflie();
        let mut log = synthetic_log(&theta, 6000, 5e-4, 3, &|_, _| [0.0; 6]);
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        let n = log.len();
        let noise: Vec<[f64; 3]> = (0..n)
            .map(|_| std::array::from_fn(|_| sigma_g * gauss(&mut rng)))
            .collect();
        let dt = log.t[1] - log.t[0];
        let true_omega = log.omega.clone();
        let true_dot = log.omega_dot.clone().unwrap();
        let dot = log.omega_dot.as_mut().unwrap();
        for i in 0..n {
            for k in 0..3 {
                log.omega[i][k] += noise[i][k];
                let before = if i > 0 { noise[i - 1][k] } else { 0.0 };
                dot[i][k] += (noise[i][k] - before) / dt;
            }
        }
        if consistent {
            let zero = Vector3::zeros();
            for i in 0..n {
                let noisy = tagk_dynamics::newton_euler(
                    &theta,
                    &zero,
                    &Vector3::from(log.omega[i]),
                    &Vector3::from(log.omega_dot.as_ref().unwrap()[i]),
                )
                .to_array();
                let clean = tagk_dynamics::newton_euler(
                    &theta,
                    &zero,
                    &Vector3::from(true_omega[i]),
                    &Vector3::from(true_dot[i]),
                )
                .to_array();
                for c in 3..6 {
                    log.wrench[i][c] += noisy[c] - clean[c];
                }
            }
        }
        let s = Signals::from_log(&log).unwrap();
        let fit = fit_model(&Model::rigid_body(), &s, None).unwrap();
        (s, fit, std::f64::consts::SQRT_2 * sigma_g / dt)
    }

    /// The variance of one axis of the signals' angular acceleration.
    fn variance(s: &Signals, k: usize) -> f64 {
        let n = s.len() as f64;
        let mean = (0..s.len()).map(|i| s.omega_dot(i)[k]).sum::<f64>() / n;
        (0..s.len())
            .map(|i| (s.omega_dot(i)[k] - mean).powi(2))
            .sum::<f64>()
            / n
    }

    /// Against the closed form `σ_n² / var` of the known noise, and against the bias the
    /// least squares fit actually shows on the best-excited axis.
    #[test]
    fn the_attenuation_of_a_differenced_gyro_is_its_noise_share() {
        let (s, fit, sigma_n) = differenced_gyro_log(1.5e-3, false);
        let got = inertia_attenuation(&s, &fit);
        for (k, g) in got.iter().enumerate() {
            let expected = (sigma_n * sigma_n / variance(&s, k)).min(1.0);
            let (a, _) = g.expect("an attenuation");
            assert!(
                (a - expected).abs() <= 0.1 * expected + 0.02,
                "axis {k}: {a} against {expected}"
            );
        }
        // Roll: the fitted I_xx is low by at least about the attenuation (the noise of the
        // barely excited pitch and yaw axes biases it further through the shared parameters).
        let (a, _) = got[0].unwrap();
        let bias = 1.0 - fit.theta.as_slice()[4] / crazyflie().as_slice()[4];
        assert!(a > 0.1 && bias >= 0.8 * a, "bias {bias}, attenuation {a}");
        // The one-regressor least squares slope of the roll torque on the roll acceleration:
        // low by the attenuation itself.
        let (mut sxy, mut sxx) = (0.0, 0.0);
        for i in 0..s.len() {
            let x = s.omega_dot(i)[0];
            sxy += x * s.log().wrench[i][3];
            sxx += x * x;
        }
        let slope_bias = 1.0 - sxy / sxx / crazyflie().as_slice()[4];
        assert!(
            (slope_bias - a).abs() <= 0.15 * a,
            "slope bias {slope_bias}, attenuation {a}"
        );
        let warnings = attenuation_warnings(&s, &fit);
        assert!(
            warnings.iter().any(|w| w.starts_with("I_xx may be biased")),
            "{warnings:?}"
        );
    }

    /// Torques computed from the same noisy angular acceleration: no bias, no warning.
    #[test]
    fn a_consistent_log_has_no_attenuation_warning() {
        let (s, fit, _) = differenced_gyro_log(1.5e-3, true);
        let bias = 1.0 - fit.theta.as_slice()[4] / crazyflie().as_slice()[4];
        assert!(bias.abs() < 0.01, "bias {bias}");
        assert_eq!(attenuation_warnings(&s, &fit), Vec::<String>::new());
    }

    /// A fit whose yaw inertia breaks the triangle inequality (as a flight that hardly yaws
    /// can give): the report gives the nearest consistent parameters, lowers I_zz and says
    /// by how much; the well-determined mass stays. A consistent fit is reported as it is.
    #[test]
    fn an_inconsistent_fit_is_reported_as_the_nearest_consistent_body() {
        let (s, fit, _) = differenced_gyro_log(0.0, false);
        let opts = DiagnoseOptions::default();
        let limits = crate::diagnose::limits_of(&Model::rigid_body(), &opts);
        let report = parameter_report(&fit, &s, &opts, &limits, None);
        let values: Vec<f64> = report.parameters.iter().map(|p| p.value).collect();
        assert_eq!(values, fit.theta.as_slice());
        assert!(!report.warnings.iter().any(|w| w.contains("no body's")));
        let mut broken = fit.clone();
        let mut t = fit.theta.to_array();
        let i = fit.theta.inertia_origin();
        t[9] = 1.3 * (i[(0, 0)] + i[(1, 1)]);
        broken.theta = tagk_dynamics::InertialParams::from_array(t);
        // A flight that hardly yaws: I_zz a hundred times less determined.
        for k in 0..10 {
            broken.theta_cov[9][k] *= 100.0;
            broken.theta_cov[k][9] *= 100.0;
        }
        broken.theta_se[9] = fit.theta_se[9].map(|se| 100.0 * se);
        assert!(broken.theta.min_pseudo_inertia_eigenvalue().unwrap() < 0.0);
        let report = parameter_report(&broken, &s, &opts, &limits, None);
        let moved = |k: usize| report.parameters[k].value - fit.theta.as_slice()[k];
        assert!(
            moved(4).abs() < 0.1 * fit.theta_se[4].unwrap(),
            "I_xx moved {}",
            moved(4)
        );
        let got: [f64; 10] = std::array::from_fn(|k| report.parameters[k].value);
        let got = tagk_dynamics::InertialParams::from_array(got);
        let scale = got.pseudo_inertia().norm();
        assert!(got.min_pseudo_inertia_eigenvalue().unwrap() >= -1e-12 * scale);
        assert!(got.as_slice()[9] < t[9]);
        let mass_se = fit.theta_se[0].unwrap();
        assert!((got.mass() - fit.theta.mass()).abs() < 0.1 * mass_se);
        let note = report.warnings.iter().find(|w| w.contains("no body's"));
        assert!(
            note.is_some_and(|w| w.contains("I_zz")),
            "{:?}",
            report.warnings
        );
    }
}
