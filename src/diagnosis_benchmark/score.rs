//! The score of one diagnosis against its flight's ground truth.

use serde::{Deserialize, Serialize};
use tagk_diagnose::{BuiltinOptions, Coefficient, EffectKind, FittedEffect, Report};
use tagk_dynamics::InertialParams;
use tagk_sim::SensingProfile;

use super::ground_truth::{ACCEL_BIAS, CoefficientKind, ExpectedCoefficient, GroundTruth};

/// The final-model effects that stand for a true effect other than by its own name: `(truth,
/// final-model effect)`. Edit here when the diagnosis gains a candidate for a sensor error.
///
/// - An uncalibrated accelerometer's bias is a constant body force (and the torque of the
///   first moment): today's `body-bias` fits it; the sensor candidate `accel-bias` will; with
///   the mass known, its vertical part scales the thrust and `thrust-gain` fits that.
pub const STAND_INS: &[(&str, &str)] = &[
    (ACCEL_BIAS, ACCEL_BIAS),
    (ACCEL_BIAS, BODY_BIAS),
    (ACCEL_BIAS, EffectKind::ThrustGain.name()),
    // The plant's body bias is a constant force and torque: its force is the accelerometer
    // offset's signature, which the diagnosis names (its torque about x and y trades with the
    // centre of mass in level flight).
    (BODY_BIAS, ACCEL_BIAS),
];

/// Stand-ins that hold only at a constant heading (a flight without a yaw rate). A force fixed
/// in the world and one fixed in the body are then the same in the data. So a wind (a drag and
/// a world force) and a constant body force with a drag explain a log alike. Each entry is
/// `(truth, stands for it)`; a wind's stand-in also needs a drag law in the final model.
pub const CONSTANT_HEADING_STAND_INS: &[(&str, &str)] =
    &[(WIND, ACCEL_BIAS), (ACCEL_BIAS, WIND), (BODY_BIAS, WIND)];

/// The vocabulary's `body-bias`.
const BODY_BIAS: &str = EffectKind::BodyBias.name();
/// The vocabulary's `wind`.
const WIND: &str = EffectKind::Wind.name();
/// The drag laws' family (`drag`).
const DRAG_FAMILY: &str = EffectKind::LinearDrag.family();

/// Whether `name` names a drag law (an effect of [`DRAG_FAMILY`]).
fn is_drag_law(name: &str) -> bool {
    EffectKind::from_name(name).is_some_and(|k| k.family() == DRAG_FAMILY)
}

/// The strength of a missing effect (RMS over the noise) that raises a channel's residual to
/// the diagnosis' adequacy factor: `√(F² − 1)` for `F = tagk_diagnose::ADEQUACY_FACTOR`
/// (0.66 for 1.2). A missing effect between it and the detectability threshold may make the
/// final model "not adequate" rightly.
pub fn adequacy_gray_zone() -> f64 {
    let f = crate::diagnose::ADEQUACY_FACTOR;
    (f * f - 1.0).sqrt()
}

/// Largest relative mass error counted as "within" (the 2 %).
pub const MASS_TOLERANCE: f64 = 0.02;

/// A fitted pseudo-inertia is "clearly" not positive definite when the smallest eigenvalue
/// `λ` of the second moment of the mass about the fitted centre of mass lies more than
/// `IMPLAUSIBLE_PSEUDO_INERTIA` standard errors below zero. That second moment is
/// `Σ_c = ½ tr(I) 1 − I − h hᵀ/m` \[kg m²\] (positive definite together with `m > 0` iff the
/// pseudo-inertia is). The standard error comes from the fitted parameters' own (first-order
/// propagation through `λ`, the parameters taken as independent). This is the rule a drag
/// coefficient meets, on the body's mass distribution. A thin body's smallest second moment is
/// small (the Crazyflie's is about 11 % of its largest). So an inertia barely excited by the
/// flight can come out slightly negative within its noise; that is not counted.
pub const IMPLAUSIBLE_PSEUDO_INERTIA: f64 = 3.0;

/// What the scorer reads of a diagnosis report: the final model, its fitted coefficients and
/// rigid-body parameters, and the adequacy verdict.
#[derive(Debug, Clone)]
pub struct DiagnosisOutcome {
    /// The final model's effects (`Report::final_model.effects`).
    pub final_effects: Vec<String>,
    /// The final model's fitted effects (`Report::final_diagnosis().effects`).
    pub fitted: Vec<FittedEffect>,
    /// The final model's rigid-body parameters in `InertialParams` order, with standard
    /// errors and intervals (`Report::final_diagnosis().parameters`).
    pub parameters: Vec<Coefficient>,
    /// `Report::adequate`.
    pub adequate: bool,
    /// The final model's held-out residual RMS per channel `fx..tz` \[N, N m\]
    /// (`Report::final_diagnosis().held_out_rms`): a measurement, which the scorer sets
    /// against the true noise.
    pub held_out_rms: [f64; 6],
    /// `Report::stopped`: why the staircase stopped.
    pub stopped: String,
    /// `Report::equivalents`: `(final-model effect, candidate that explains the data as
    /// well in its place)`.
    pub equivalents: Vec<(String, String)>,
}

impl DiagnosisOutcome {
    /// The outcome of a report.
    pub fn from_report(report: &Report) -> Self {
        let last = report.final_diagnosis();
        Self {
            final_effects: report.final_model.effects.clone(),
            fitted: last.effects.clone(),
            parameters: last.parameters.clone(),
            adequate: report.adequate,
            held_out_rms: last.held_out_rms,
            stopped: report.stopped.clone(),
            equivalents: report
                .equivalents
                .iter()
                .map(|e| (e.effect.clone(), e.alternative.clone()))
                .collect(),
        }
    }
}

/// How one true effect fared.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EffectScore {
    /// Its name (the vocabulary's, or a sensor truth such as [`ACCEL_BIAS`]).
    pub name: String,
    /// Its family.
    pub family: String,
    /// Its largest channel strength over the noise ([`super::TrueEffect::max_strength`]).
    pub strength: f64,
    /// Its strength per channel `fx..tz` ([`super::TrueEffect::strength`]).
    pub channel_strength: [f64; 6],
    /// Detectable (strength ≥ `D`).
    pub detectable: bool,
    /// The `Σ ρ_k²` it alone adds to a white residual when missing
    /// ([`super::TrueEffect::whiteness`]).
    pub whiteness: f64,
    /// Found: its own name, or a stand-in ([`STAND_INS`]), is in the final model.
    pub found: bool,
    /// Found in its family: an effect of the same `EffectKind::family()` is in the final model
    /// (a drag law also by a `wind`, which includes a drag; a sensor truth by a stand-in).
    pub found_in_family: bool,
    /// The final-model effect that stands for it (its own name first), if any.
    pub reported_as: Option<String>,
    /// Found, or named by the report as explaining the data as well as an effect of the final
    /// model in its place (`Report::equivalents`: its own name or a stand-in). The report
    /// then says the data cannot tell the two apart.
    pub found_or_equivalent: bool,
}

/// One reported coefficient against its true value.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CoefficientScore {
    /// The diagnosis effect.
    pub effect: String,
    /// The coefficient's name.
    pub name: String,
    /// Coefficient, scanned parameter or derived quantity.
    pub kind: CoefficientKind,
    /// True value (SI).
    pub truth: f64,
    /// Reported value (`None`: the effect does not report it).
    pub estimate: Option<f64>,
    /// `|estimate − truth| / scale`, the scale being the norm of the true values of its group
    /// ([`ExpectedCoefficient::scale`]).
    pub relative_error: Option<f64>,
    /// The reported 95 % interval (`None`: no interval reported).
    pub interval: Option<[f64; 2]>,
    /// Whether the truth lies in the interval (`None` without an interval).
    pub covered: Option<bool>,
}

/// The score of one flight.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FlightScore {
    /// The flight's sensing profile.
    pub sensing: SensingProfile,
    /// `true`: diagnosed with the known mass.
    pub known_mass: bool,
    /// Noise σ per channel `fx..tz` \[N, N m\] ([`GroundTruth::noise`]).
    pub noise: [f64; 6],
    /// Whiteness `Σ ρ_k²` of the true model's residual per channel
    /// ([`GroundTruth::noise_whiteness`]), against the diagnosis' limit
    /// [`Self::whiteness_limit`] (dimensionless).
    pub noise_whiteness: [f64; 6],
    /// The diagnosis' whiteness limit for this log ([`GroundTruth::whiteness_limit`]).
    pub whiteness_limit: f64,
    /// Every true effect (plant effects, then sensor truths).
    pub effects: Vec<EffectScore>,
    /// The final model's effects.
    pub final_effects: Vec<String>,
    /// Final-model effects that are neither a true effect nor a stand-in for one.
    pub false_effects: Vec<String>,
    /// Final-model effects whose family is not a true effect's family (a drag law counts as
    /// covered by a true `wind`).
    pub false_families: Vec<String>,
    /// Every coefficient compared (the final model's effects that have a truth and whose
    /// comparison is not ambiguous).
    pub coefficients: Vec<CoefficientScore>,
    /// Coefficient comparisons skipped as ambiguous (a drag law and a wind in one final model).
    pub ambiguous_coefficients: usize,
    /// True mass of the flying body \[kg\].
    pub mass_true: f64,
    /// The mass the data identify \[kg\] ([`GroundTruth::identifiable_mass`]).
    pub mass_identifiable: f64,
    /// The final model's mass \[kg\] (the known mass when it was given).
    pub mass_estimate: f64,
    /// `|m̂ − m| / m` against the true mass.
    pub mass_error: f64,
    /// `|m̂ − m'| / m'` against the identifiable mass.
    pub mass_error_identifiable: f64,
    /// `|Î_ii − I_ii| / I_ii` for `xx, yy, zz` (about the body origin).
    pub inertia_error: [f64; 3],
    /// `Report::adequate`.
    pub adequate_reported: bool,
    /// What `adequate` should say: every detectable true effect is in the final model *and* the
    /// final model is at the true noise ([`Self::at_true_noise`]). An effect counts by name or
    /// stand-in, or when the report names it as an equivalent of a final-model effect
    /// ([`EffectScore::found_or_equivalent`]). A drag law also counts by another drag law (the
    /// laws cannot always be told apart in a log).
    pub adequate_expected: bool,
    /// The final model's held-out residual RMS is within the diagnosis' adequacy factor
    /// (`tagk_diagnose::ADEQUACY_FACTOR`) of the true noise on every channel (the true
    /// model's residual on the logged signals, at least the resolution:
    /// [`super::GroundTruth::noise`]). A model of the right effects whose form differs from
    /// the plant's (a stand-in, another drag law) can leave more than that, most of all on
    /// a noise-free log: "adequate" is then a false claim.
    pub at_true_noise: bool,
    /// The expectation before the final model's residual was set against the true noise
    /// (every detectable effect accounted for alone), kept for comparison.
    pub adequate_expected_by_effects: bool,
    /// `adequate` right under [`Self::adequate_expected_by_effects`], as scored before: "not
    /// adequate" also right when a missing effect's strength alone lies in the gray zone.
    pub adequate_right_by_effects: bool,
    /// With every detectable effect accounted for, either verdict is right. Here an effect below
    /// the detectability threshold is missing that either criterion of adequacy can see:
    ///
    /// - a strength above [`adequacy_gray_zone`] raises the residual beyond the adequacy factor
    ///   (the gray zone of the two thresholds);
    /// - or its autocorrelation makes the residual's `Σ ρ_k²` exceed the whiteness limit
    ///   ([`EffectScore::whiteness`]). A slow effect such as a ground effect does at a fifth of
    ///   the noise on a long log.
    pub adequate_gray: bool,
    /// The same by name ([`EffectScore::found`]).
    pub adequate_expected_by_name: bool,
    /// `adequate_reported == adequate_expected`, or any verdict in the gray zone
    /// ([`Self::adequate_gray`]).
    pub adequate_right: bool,
    /// This benchmark's own implausibility findings on the final model (empty: plausible).
    pub implausible: Vec<String>,
    /// Effects of the final model the diagnosis itself marks implausible
    /// (`FittedEffect::plausible == false`).
    pub diagnosis_implausible: Vec<String>,
    /// Why the staircase stopped (`Report::stopped`).
    pub stopped: String,
    /// The report's equivalents: `(final-model effect, candidate that explains the data as
    /// well in its place)`.
    pub equivalents: Vec<(String, String)>,
}

impl FlightScore {
    /// `true` when the flight has no true effect at all (neither a plant effect nor a sensor
    /// truth).
    pub fn is_clean(&self) -> bool {
        self.effects.is_empty()
    }
}

/// Whether `reported` in the final model `finals` stands for the true effect `name` at a
/// constant heading ([`CONSTANT_HEADING_STAND_INS`]).
fn constant_heading_stand_in(
    truth: &GroundTruth,
    finals: &[String],
    name: &str,
    reported: &str,
) -> bool {
    if !truth.constant_heading || !CONSTANT_HEADING_STAND_INS.contains(&(name, reported)) {
        return false;
    }
    name != WIND || finals.iter().any(|f| is_drag_law(f))
}

/// Whether a final-model effect `reported` is in the family of the true effect `truth`.
fn in_family(truth: &str, reported: &str) -> bool {
    if truth == reported || STAND_INS.contains(&(truth, reported)) {
        return true;
    }
    match (
        EffectKind::from_name(truth),
        EffectKind::from_name(reported),
    ) {
        (Some(t), Some(r)) => {
            t.family() == r.family() || (t.family() == DRAG_FAMILY && r.includes_drag())
        }
        _ => false,
    }
}

/// The coefficient `name` of `kind` in a fitted effect, with its interval.
fn reported(
    fitted: &FittedEffect,
    kind: CoefficientKind,
    name: &str,
) -> Option<(f64, Option<[f64; 2]>)> {
    match kind {
        CoefficientKind::Coefficient => fitted
            .coefficients
            .iter()
            .find(|c| c.name == name)
            .map(|c| (c.value, c.confidence_interval)),
        CoefficientKind::Derived => fitted
            .derived
            .iter()
            .find(|c| c.name == name)
            .map(|c| (c.value, c.confidence_interval)),
        CoefficientKind::Scanned => fitted
            .scanned
            .as_ref()
            .filter(|(n, _, _)| n == name)
            .map(|(_, v, _)| (*v, fitted.scanned_interval)),
    }
}

/// This benchmark's implausibility checks of a final model (independent of the diagnosis'
/// own):
///
/// - a drag coefficient (of a drag law, of a wind's drag, the ground-effect gain)
///   significantly negative (below −3 standard errors; below 0 without one);
/// - a motor lag at the upper end of its scan range or a delay at either end (the default
///   grids of `tagk_diagnose::BuiltinOptions`);
/// - a mass that is not positive;
/// - a pseudo-inertia clearly not positive definite ([`IMPLAUSIBLE_PSEUDO_INERTIA`]).
fn implausibilities(outcome: &DiagnosisOutcome) -> Vec<String> {
    let mut out = Vec::new();
    let grids = BuiltinOptions::default();
    let lag_max = grids
        .motor_lag_time_constants
        .iter()
        .copied()
        .fold(0.0, f64::max);
    let delay_max = grids.time_delays.iter().fold(0.0f64, |m, d| m.max(d.abs()));
    for fe in &outcome.fitted {
        let kind = EffectKind::from_name(&fe.effect);
        let signed: &[Coefficient] = match kind {
            Some(k) if k.family() == DRAG_FAMILY => &fe.coefficients,
            // The wind's drag coefficients only (its wind force, `kv_w*` or `F_w*`, is signed).
            Some(EffectKind::Wind) => {
                let drags = fe
                    .coefficients
                    .iter()
                    .take_while(|c| !(c.name.starts_with("kv_") || c.name.starts_with("F_")))
                    .count();
                &fe.coefficients[..drags]
            }
            Some(EffectKind::GroundEffect) => &fe.coefficients,
            _ => &[],
        };
        for c in signed {
            let negative = match c.std_error {
                Some(se) => c.value < -3.0 * se,
                None => c.value < 0.0,
            };
            if negative {
                out.push(format!(
                    "{}: {} = {:.3e} significantly negative",
                    fe.effect, c.name, c.value
                ));
            }
        }
        if let Some((name, value, _)) = &fe.scanned {
            let at_end = match kind {
                Some(EffectKind::MotorLag) => *value >= lag_max * (1.0 - 1e-9),
                Some(EffectKind::TimeDelay) => value.abs() >= delay_max * (1.0 - 1e-9),
                _ => false,
            };
            if at_end {
                out.push(format!(
                    "{}: {name} = {value:.3} at the end of its scan range",
                    fe.effect
                ));
            }
        }
    }
    let theta: Vec<f64> = outcome.parameters.iter().map(|p| p.value).collect();
    let se: Vec<f64> = outcome
        .parameters
        .iter()
        .map(|p| p.std_error.unwrap_or(0.0))
        .collect();
    match InertialParams::from_slice(&theta) {
        Ok(params) => {
            let m = params.mass();
            if m.is_nan() || m <= 0.0 {
                out.push(format!("mass {m:.4e} kg not positive"));
            } else if let Some((lambda, lambda_se)) =
                tagk_diagnose::second_moment_eigen(&params, &se)
                && lambda < -IMPLAUSIBLE_PSEUDO_INERTIA * lambda_se
            {
                out.push(format!(
                    "pseudo-inertia not positive definite: the second moment about the centre of mass has the eigenvalue {lambda:.2e} ± {lambda_se:.1e} kg m²"
                ));
            }
        }
        Err(_) => out.push(format!(
            "{} rigid-body parameters, 10 expected",
            theta.len()
        )),
    }
    out
}

/// The score of a diagnosis `outcome` against its flight's `truth` (see [`FlightScore`]'s
/// fields for every rule).
pub fn score_flight(truth: &GroundTruth, outcome: &DiagnosisOutcome) -> FlightScore {
    let finals = &outcome.final_effects;
    let windy = truth.effects.iter().any(|u| u.name == WIND);
    let effects: Vec<EffectScore> = truth
        .effects
        .iter()
        .map(|t| {
            let exact = finals
                .iter()
                .find(|f| **f == t.name)
                .or_else(|| {
                    finals
                        .iter()
                        .find(|f| STAND_INS.contains(&(t.name.as_str(), f.as_str())))
                })
                .or_else(|| {
                    finals
                        .iter()
                        .find(|f| constant_heading_stand_in(truth, finals, &t.name, f))
                })
                .or_else(|| {
                    // A true wind acts through the flight's drag law: the diagnosis' `wind`
                    // is a drag and a wind fitted together, so it stands for that law too.
                    (windy && is_drag_law(&t.name))
                        .then(|| finals.iter().find(|f| f.as_str() == WIND))
                        .flatten()
                })
                .cloned();
            let family = finals.iter().find(|f| in_family(&t.name, f)).cloned();
            let equivalent = outcome.equivalents.iter().any(|(_, alternative)| {
                *alternative == t.name
                    || STAND_INS.contains(&(t.name.as_str(), alternative.as_str()))
            });
            EffectScore {
                name: t.name.clone(),
                family: t.family.clone(),
                strength: t.max_strength,
                channel_strength: t.strength,
                detectable: t.detectable,
                whiteness: t.whiteness,
                found: exact.is_some(),
                found_or_equivalent: exact.is_some() || equivalent,
                found_in_family: family.is_some() || exact.is_some(),
                reported_as: exact.or(family),
            }
        })
        .collect();
    let false_effects: Vec<String> = finals
        .iter()
        .filter(|f| {
            !truth.effects.iter().any(|t| {
                t.name == **f
                    || STAND_INS.contains(&(t.name.as_str(), f.as_str()))
                    || constant_heading_stand_in(truth, finals, &t.name, f)
                    // A wind's drag law at a constant heading.
                    || (t.name == WIND
                        && truth.constant_heading
                        && finals.iter().any(|g| g == ACCEL_BIAS)
                        && is_drag_law(f))
            })
        })
        .cloned()
        .collect();
    let false_families: Vec<String> = finals
        .iter()
        .filter(|f| !truth.effects.iter().any(|t| in_family(&t.name, f)))
        .cloned()
        .collect();
    let mut coefficients = Vec::new();
    let mut ambiguous = 0;
    for fe in &outcome.fitted {
        for exp in truth.expected.iter().filter(|e| e.effect == fe.effect) {
            if exp.unless_with.iter().any(|u| finals.contains(u)) {
                ambiguous += 1;
                continue;
            }
            coefficients.push(coefficient_score(exp, fe));
        }
    }
    let estimate = |j: usize| outcome.parameters.get(j).map_or(f64::NAN, |p| p.value);
    let mass_estimate = estimate(0);
    let inertia_error = [(4, 4), (6, 6), (9, 9)].map(|(j, t)| {
        let truth_ii = truth.params[t];
        (estimate(j) - truth_ii).abs() / truth_ii.abs()
    });
    // Found by name or stand-in, named as an equivalent of a final-model effect (the report
    // says the data cannot tell them apart), or a drag law found in its family.
    let accounted =
        |e: &EffectScore| e.found_or_equivalent || (e.family == DRAG_FAMILY && e.found_in_family);
    let adequate_expected_by_effects = effects.iter().all(|e| !e.detectable || accounted(e));
    let factor = crate::diagnose::ADEQUACY_FACTOR;
    let at_true_noise = (0..6).all(|c| outcome.held_out_rms[c] <= factor * truth.noise[c]);
    let adequate_expected = adequate_expected_by_effects && at_true_noise;
    // The gray zone of the rule before the true noise was used: the strength alone.
    let strength_gray = effects
        .iter()
        .any(|e| !accounted(e) && e.strength >= adequacy_gray_zone());
    // The gray zone: an effect not accounted for that either criterion of adequacy can see.
    let adequate_gray = effects.iter().any(|e| {
        !accounted(e) && (e.strength >= adequacy_gray_zone() || e.whiteness > truth.whiteness_limit)
    });
    let adequate_expected_by_name = effects.iter().all(|e| !e.detectable || e.found);
    FlightScore {
        sensing: truth.sensing,
        known_mass: truth.known_mass,
        noise: truth.noise,
        noise_whiteness: truth.noise_whiteness,
        whiteness_limit: truth.whiteness_limit,
        effects,
        final_effects: finals.clone(),
        false_effects,
        false_families,
        coefficients,
        ambiguous_coefficients: ambiguous,
        mass_true: truth.mass,
        mass_identifiable: truth.identifiable_mass,
        mass_estimate,
        mass_error: (mass_estimate - truth.mass).abs() / truth.mass,
        mass_error_identifiable: (mass_estimate - truth.identifiable_mass).abs()
            / truth.identifiable_mass,
        inertia_error,
        adequate_reported: outcome.adequate,
        adequate_expected,
        adequate_expected_by_name,
        // In the gray zone either verdict is right (every detectable effect accounted for).
        adequate_right: outcome.adequate == adequate_expected
            || (adequate_expected_by_effects && adequate_gray),
        at_true_noise,
        adequate_expected_by_effects,
        adequate_right_by_effects: outcome.adequate == adequate_expected_by_effects
            || (adequate_expected_by_effects && !outcome.adequate && strength_gray),
        adequate_gray,
        implausible: implausibilities(outcome),
        diagnosis_implausible: outcome
            .fitted
            .iter()
            .filter(|f| !f.plausible)
            .map(|f| format!("{}: {}", f.effect, f.plausibility_note))
            .collect(),
        stopped: outcome.stopped.clone(),
        equivalents: outcome.equivalents.clone(),
    }
}

/// One expected coefficient against the fitted effect that reports it.
fn coefficient_score(exp: &ExpectedCoefficient, fitted: &FittedEffect) -> CoefficientScore {
    let got = reported(fitted, exp.kind, &exp.name);
    let estimate = got.map(|(v, _)| v);
    let interval = got.and_then(|(_, i)| i);
    CoefficientScore {
        effect: exp.effect.clone(),
        name: exp.name.clone(),
        kind: exp.kind,
        truth: exp.value,
        estimate,
        relative_error: estimate.map(|v| (v - exp.value).abs() / exp.scale.max(f64::MIN_POSITIVE)),
        interval,
        covered: interval.map(|[lo, hi]| lo <= exp.value && exp.value <= hi),
    }
}
