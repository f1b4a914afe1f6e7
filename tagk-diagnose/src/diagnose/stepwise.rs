//! Stepwise discovery: rigid body → + effect A → + effect B → …, each step the candidate with
//! the largest held-out gain over the noise floor that passes every rule, until the model is at
//! the floor or no candidate qualifies.
//!
//! A candidate qualifies ([`CandidateStatus::qualifies`](crate::CandidateStatus::qualifies))
//! when it lowers the held-out (blocked CV) residual, passes the partial test (Bonferroni over
//! the candidates), keeps the rigid body and its own coefficients physical
//! ([`crate::MAX_MASS_CHANGE`] and the other rules), makes no channel's held-out RMS worse by
//! more than [`crate::MAX_CHANNEL_WORSENING`], and lowers some channel's held-out RMS by at
//! least [`crate::MIN_GAIN_OF_FLOOR`] of that channel's noise floor ([`crate::NoiseFloor`]).
//! The search stops when every channel is within [`crate::FLOOR_MARGIN`] of its floor, when no
//! candidate qualifies, or after [`crate::DiagnoseOptions::max_steps`] steps.

use serde::Serialize;

use crate::diagnose::floor::noise_floor;
use crate::diagnose::{
    DiagnoseOptions, Diagnosis, FLOOR_MARGIN, FloorSource, MAX_CHANNEL_WORSENING, NoiseFloor,
    diagnose_against,
};
use crate::error::DiagnoseError;
use crate::fit::{Coefficient, Model};
use crate::signals::{CHANNEL_NAMES, CHANNEL_UNITS, Signals};
use tagk_dynamics::EffectKind;

/// One channel of one step.
#[derive(Debug, Clone, Serialize)]
pub struct StepChannel {
    /// Channel (`fx` … `tz`).
    pub name: String,
    /// Unit.
    pub unit: String,
    /// Held-out residual RMS of the step's model.
    pub held_out_rms: f64,
    /// The channel's noise floor.
    pub floor: f64,
    /// `held_out_rms / floor`.
    pub ratio_to_floor: f64,
    /// Relative change of the held-out RMS from the previous step (`−0.4`: 40 % lower; 0 for
    /// the first step).
    pub change: f64,
}

/// One step of the staircase: the model after adding `effect` (the starting model for the
/// first step).
#[derive(Debug, Clone, Serialize)]
pub struct Step {
    /// The effect this step adds (`null` for the starting model).
    pub effect: Option<String>,
    /// The step's model label (`rigid body + …`).
    pub model: String,
    /// Held-out residual RMS per channel (N, N m), in the order `fx … tz`.
    pub held_out_rms: [f64; 6],
    /// Per channel: held-out RMS, floor, change.
    pub channels: Vec<StepChannel>,
    /// The added effect's held-out gain in units of the noise floor (0 for the first step).
    pub gain_over_floor: f64,
    /// The added effect's fitted coefficients in this step's model, with 95 % intervals.
    pub coefficients: Vec<Coefficient>,
    /// Quantities derived from the added effect's coefficients (e.g. the wind velocity).
    pub derived: Vec<Coefficient>,
    /// The added effect's scanned parameter `(name, value, unit)`, if any.
    pub scanned: Option<(String, f64, String)>,
}

/// The outcome of [`discover`].
#[derive(Debug, Clone, Serialize)]
pub struct Discovery {
    /// The staircase: the starting model, then one step per added effect.
    pub steps: Vec<Step>,
    /// Effects of the final model beyond the starting model, in the order added.
    pub added: Vec<String>,
    /// Label of the final model.
    pub final_model: String,
    /// The noise floor of the log.
    pub noise_floor: NoiseFloor,
    /// Why the search stopped.
    pub stopped: String,
    /// The diagnosis of every step's model (the first is the starting model's, the last the
    /// final model's).
    #[serde(skip)]
    pub diagnoses: Vec<Diagnosis>,
}

impl Discovery {
    /// The starting model's diagnosis.
    pub fn first(&self) -> &Diagnosis {
        &self.diagnoses[0]
    }

    /// The final model's diagnosis.
    pub fn last(&self) -> &Diagnosis {
        &self.diagnoses[self.diagnoses.len() - 1]
    }
}

/// Runs the stepwise search from `start` (module docs).
///
/// # Errors
/// As [`crate::diagnose()`].
pub fn discover(
    start: &Model,
    s: &Signals,
    opts: &DiagnoseOptions,
) -> Result<Discovery, DiagnoseError> {
    let first = crate::diagnose::diagnose(start, s, opts)?;
    discover_from(start, first, s, opts)
}

/// [`discover`] from an existing diagnosis of `start` (its noise floor is reused).
///
/// # Errors
/// As [`crate::diagnose()`].
pub fn discover_from(
    start: &Model,
    first: Diagnosis,
    s: &Signals,
    opts: &DiagnoseOptions,
) -> Result<Discovery, DiagnoseError> {
    let mut floor = first.noise_floor.clone();
    let mut floor_updates = 0;
    let mut steps = vec![step_of(None, &first, None, &floor)];
    let mut diagnoses = vec![first];
    let mut model = start.clone();
    let mut added = Vec::new();
    let stopped = 'search: loop {
        let current = &diagnoses[diagnoses.len() - 1];
        if current.recommended.is_none() {
            // The floor was measured from the starting model: candidates implausible then
            // (a drag whose vertical coefficient soaked up an unmodelled lag) may be plausible
            // now. Measure it again from here; a lower floor reopens the search.
            if floor.source == FloorSource::Data
                && floor_updates < 2
                && !added.is_empty()
                && new_family_plausible(current, &floor)
            {
                floor_updates += 1;
                let again = noise_floor(
                    &model,
                    s,
                    opts,
                    &current.fit,
                    &current.ranking,
                    Some(floor.noise_estimate),
                )?;
                if (0..6).any(|c| again.rms[c] < (1.0 - FLOOR_MARGIN) * floor.rms[c]) {
                    for c in 0..6 {
                        if again.rms[c] < floor.rms[c] {
                            floor.rms[c] = again.rms[c];
                            floor.reachable[c] = again.reachable[c];
                            floor.noise_estimate[c] = again.noise_estimate[c];
                        }
                    }
                    floor.saturated_model = again.saturated_model;
                    let fit = current.fit.clone();
                    let rejudged =
                        crate::diagnose::diagnose_with_fit(&model, s, opts, &floor, fit)?;
                    let last = diagnoses.len() - 1;
                    diagnoses[last] = rejudged;
                    continue;
                }
            }
            // Second chance by refit: an effect of the saturated model that only helps once
            // the scanned parameters move with it (its ranking held them fixed).
            let current = &diagnoses[diagnoses.len() - 1];
            if !current.at_floor
                && let Some((name, next)) = best_by_refit(&model, current, s, opts, &floor)?
            {
                let gain = 0.0;
                steps.push(step_of(Some(&name), &next, Some(current), &floor));
                if let Some(last) = steps.last_mut() {
                    last.gain_over_floor = gain;
                }
                model = model.clone().with_ref(
                    opts.candidates
                        .iter()
                        .find(|c| c.name() == name)
                        .cloned()
                        .expect("a candidate of the options"),
                );
                added.push(name);
                diagnoses.push(next);
                continue;
            }
            break stop_reason(&diagnoses[diagnoses.len() - 1]);
        }
        // The qualifying candidates, best first: the first whose refit keeps every channel
        // within MAX_CHANNEL_WORSENING of the current held-out RMS is the step (the full refit
        // re-scans every effect, so it can differ from the candidate's own evaluation).
        let qualifying: Vec<(String, f64)> = current
            .ranking
            .iter()
            .filter(|c| c.status.qualifies())
            .map(|c| (c.effect.clone(), c.gain_over_floor))
            .collect();
        let mut refused = Vec::new();
        for (name, gain) in qualifying {
            if added.len() >= opts.max_steps {
                break 'search format!(
                    "step limit: {} effects added (`max_steps`); `{name}` would be next",
                    opts.max_steps
                );
            }
            let Some(effect) = opts.candidates.iter().find(|c| c.name() == name) else {
                continue;
            };
            let trial = model.clone().with_ref(effect.clone());
            let next = diagnose_against(&trial, s, opts, &floor)?;
            let worse: Vec<&str> = (0..6)
                .filter(|&c| {
                    crate::diagnose::ranking::worsens(
                        next.held_out_rms[c],
                        current.held_out_rms[c],
                        floor.rms[c],
                    )
                })
                .map(|c| CHANNEL_NAMES[c])
                .collect();
            if !worse.is_empty() {
                refused.push(format!(
                    "`{name}` (its refit worsens the held-out RMS of {} by more than {:.0} %, above the floor)",
                    worse.join(", "),
                    100.0 * MAX_CHANNEL_WORSENING
                ));
                continue;
            }
            steps.push(step_of(Some(&name), &next, Some(current), &floor));
            if let Some(last) = steps.last_mut() {
                last.gain_over_floor = gain;
            }
            model = trial;
            added.push(name);
            diagnoses.push(next);
            continue 'search;
        }
        break format!(
            "no candidate qualifies after its refit: {}",
            refused.join("; ")
        );
    };
    // Every step against the final floor.
    for (k, step) in steps.iter_mut().enumerate() {
        for (c, ch) in step.channels.iter_mut().enumerate() {
            ch.floor = floor.rms[c];
            ch.ratio_to_floor = if floor.rms[c] > 0.0 {
                ch.held_out_rms / floor.rms[c]
            } else {
                f64::INFINITY
            };
        }
        let _ = k;
    }
    for d in &mut diagnoses {
        d.noise_floor = floor.clone();
    }
    Ok(Discovery {
        steps,
        added,
        final_model: model.label(),
        noise_floor: floor,
        stopped,
        diagnoses,
    })
}

/// `true` when a candidate plausible now belongs to an effect family that the floor's
/// saturated model lacks: only then can measuring the floor again lower it.
fn new_family_plausible(current: &Diagnosis, floor: &NoiseFloor) -> bool {
    let family = |name: &str| {
        EffectKind::from_name(name).map_or_else(|| name.to_string(), |k| k.family().to_string())
    };
    let mut covered: Vec<String> = floor.saturated_model.iter().map(|n| family(n)).collect();
    // A wind carries its drag.
    if floor
        .saturated_model
        .iter()
        .any(|n| EffectKind::from_name(n).is_some_and(EffectKind::includes_drag))
    {
        covered.push(EffectKind::LinearDrag.family().to_string());
    }
    current
        .ranking
        .iter()
        .filter(|c| c.plausible)
        .any(|c| !covered.contains(&family(&c.effect)))
}

/// Among the effects of the floor's saturated model not yet in `model`, the one whose full
/// refit (every scan redone) qualifies and lowers the held-out residual most: plausible in the
/// refit, the rigid body's mass within [`crate::MAX_MASS_CHANGE`], no channel worsened
/// ([`crate::diagnose::ranking::worsens`]), and some channel lowered by at least
/// [`crate::MIN_GAIN_OF_FLOOR`] of its floor.
fn best_by_refit(
    model: &Model,
    current: &Diagnosis,
    s: &Signals,
    opts: &DiagnoseOptions,
    floor: &NoiseFloor,
) -> Result<Option<(String, Diagnosis)>, DiagnoseError> {
    let mut best: Option<(f64, String, Model)> = None;
    for name in &floor.saturated_model {
        if model.has(name) {
            continue;
        }
        let Some(effect) = opts.candidates.iter().find(|c| c.name() == name) else {
            continue;
        };
        let trial = model.clone().with_ref(effect.clone());
        // The fit and its held-out residual first; the whole diagnosis only for a step.
        let fit = crate::fit::fit_model(&trial, s, None)?;
        let ev = crate::diagnose::floor::held_out_evaluation(&trial, s, &fit, opts.folds);
        let held_out = crate::diagnose::floor::held_out_rms(&ev, &fit.weights, s.len());
        let plausible = fit.effects.iter().all(|f| f.plausible);
        let (m0, m1) = (current.parameters[0].value, fit.theta.mass());
        let mass_ok = crate::diagnose::sanity::mass_kept(m0, m1);
        let worse = (0..6).any(|c| {
            crate::diagnose::ranking::worsens(held_out[c], current.held_out_rms[c], floor.rms[c])
        });
        let material = (0..6).any(|c| {
            current.held_out_rms[c] - held_out[c]
                >= crate::diagnose::MIN_GAIN_OF_FLOOR * floor.rms[c]
        });
        if !(plausible && mass_ok && !worse && material) {
            continue;
        }
        let gain: f64 = (0..6)
            .map(|c| (current.held_out_rms[c].powi(2) - held_out[c].powi(2)) / floor.rms[c].powi(2))
            .sum();
        if best.as_ref().is_none_or(|(g, _, _)| gain > *g) {
            best = Some((gain, name.clone(), trial));
        }
    }
    match best {
        None => Ok(None),
        Some((_, name, trial)) => Ok(Some((name, diagnose_against(&trial, s, opts, floor)?))),
    }
}

/// The staircase entry of a step's diagnosis `d` (after adding `effect`; `previous` is the
/// step before).
fn step_of(
    effect: Option<&str>,
    d: &Diagnosis,
    previous: Option<&Diagnosis>,
    floor: &NoiseFloor,
) -> Step {
    let channels = (0..6)
        .map(|c| {
            let rms = d.held_out_rms[c];
            let before = previous.map_or(rms, |p| p.held_out_rms[c]);
            StepChannel {
                name: CHANNEL_NAMES[c].to_string(),
                unit: CHANNEL_UNITS[c].to_string(),
                held_out_rms: rms,
                floor: floor.rms[c],
                ratio_to_floor: if floor.rms[c] > 0.0 {
                    rms / floor.rms[c]
                } else {
                    f64::INFINITY
                },
                change: if before > 0.0 {
                    rms / before - 1.0
                } else {
                    0.0
                },
            }
        })
        .collect();
    let fitted = effect.and_then(|e| d.effects.iter().find(|f| f.effect == e));
    Step {
        effect: effect.map(str::to_string),
        model: d.model.clone(),
        held_out_rms: d.held_out_rms,
        channels,
        gain_over_floor: 0.0,
        coefficients: fitted.map_or_else(Vec::new, |f| f.coefficients.clone()),
        derived: fitted.map_or_else(Vec::new, |f| f.derived.clone()),
        scanned: fitted.and_then(|f| f.scanned.clone()),
    }
}

/// Why the search stops at `d` (which recommends nothing).
fn stop_reason(d: &Diagnosis) -> String {
    if d.at_floor {
        return format!(
            "at the noise floor: every channel's held-out RMS is within {:.0} % of its floor",
            100.0 * FLOOR_MARGIN
        );
    }
    match d.ranking.first() {
        Some(best) => format!(
            "no candidate qualifies; the best remaining, {}",
            best.explanation
        ),
        None => "no candidate left to try".into(),
    }
}
