//! Stepwise discovery: rigid body → + effect A → + effect B → …, each step the set of
//! effects the search chose ([`crate::diagnose::select`]: candidates and sets of them scored
//! jointly on held-out data in units of each channel's noise), until no set is admissible.
//!
//! Each effect of a chosen set is shown as a step of its own (rigid → + A → + A + B), but the
//! decision is made on the whole set. When the search stops, every added effect is checked
//! once more within the final model (the same rules as in the search); one that no longer
//! earns its place is dropped and the staircase rebuilt. The noise is measured again on the
//! final model's residual: if it is clearly lower on some channel (a missing effect's
//! high-frequency part had inflated it), the search runs again against it (at most twice).
//!
//! Last, each added effect is swapped for every other candidate within the final model. A
//! candidate that passes the same rules and explains the data as well is reported beside it
//! ([`Discovery::equivalents`]): its held-out gain is within chance of the effect's, and the
//! data cannot tell the two apart.

use std::sync::Arc;

use serde::Serialize;

use crate::diagnose::select::{
    Judge, Member, Score, SetEval, chance_margin, mean_thrust, usable_candidates,
};
use crate::diagnose::{
    Context, DiagnoseOptions, Diagnosis, FloorSource, NoiseFloor, diagnose_with_fit, limits_of,
    noise_floor,
};
use crate::error::DiagnoseError;
use crate::fit::GramEngine;
use crate::fit::{Coefficient, Model, fit_model};
use crate::signals::{CHANNEL_NAMES, CHANNEL_UNITS, Signals};

/// One channel of one step.
#[derive(Debug, Clone, Serialize)]
pub struct StepChannel {
    /// Channel (`fx` … `tz`).
    pub name: String,
    /// Unit.
    pub unit: String,
    /// Held-out residual RMS of the step's model.
    pub held_out_rms: f64,
    /// The channel's noise.
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
    /// Per channel: held-out RMS, noise, change.
    pub channels: Vec<StepChannel>,
    /// The step's held-out gain per sample in units of the noise variance
    /// (`Σ_c (rms_before² − rms²) / σ_c²`; 0 for the first step).
    pub gain: f64,
    /// The added effect's fitted coefficients in this step's model, with 95 % intervals.
    pub coefficients: Vec<Coefficient>,
    /// Quantities derived from the added effect's coefficients (e.g. the wind velocity).
    pub derived: Vec<Coefficient>,
    /// The added effect's scanned parameter `(name, value, unit)`, if any.
    pub scanned: Option<(String, f64, String)>,
    /// Its 95 % interval, when the data bound it.
    pub scanned_interval: Option<[f64; 2]>,
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
    /// The noise of the log.
    pub noise_floor: NoiseFloor,
    /// Why the search stopped.
    pub stopped: String,
    /// `true` when the final model is adequate ([`Diagnosis::adequate`]).
    pub adequate: bool,
    /// Effects of the final model that another candidate replaces as well: the data cannot
    /// tell them apart (empty when every added effect is the only one that fits its place).
    pub equivalents: Vec<Equivalent>,
    /// The diagnosis of every step's model (the first is the starting model's, the last the
    /// final model's).
    #[serde(skip)]
    pub diagnoses: Vec<Diagnosis>,
}

/// An added effect of the final model and another candidate that explains the data as well
/// in its place.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Equivalent {
    /// The final model's effect.
    pub effect: String,
    /// The candidate that replaces it as well.
    pub alternative: String,
    /// Held-out gain of the effect within the final model, in noise units (the sum over the
    /// channels of the held-out squared residual it removes over the noise variance, whole
    /// log; dimensionless).
    pub gain: f64,
    /// Held-out gain of the alternative in its place (noise units).
    pub alternative_gain: f64,
}

impl Equivalent {
    /// What the report says of it, in a sentence (without the names' markup).
    pub fn sentence(&self) -> String {
        format!(
            "{} in place of {} explains the data as well (held-out gain {} against {} noise units): the data cannot tell them apart",
            self.alternative,
            self.effect,
            crate::format::significant(self.alternative_gain, 4),
            crate::format::significant(self.gain, 4)
        )
    }
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
///
/// # Examples
///
/// A log of a body whose actuators fight a hidden linear drag (hidden: `flight`, as in
/// [`Signals`]' example). The search adds the drag and stops at the noise, and the drag
/// removes more than 99 % of the held-out force residual.
///
/// ```
/// # use tagk_diagnose::{FlightLog, LogSample};
/// # use tagk_dynamics::nalgebra::{UnitQuaternion, Vector3};
/// # use tagk_dynamics::{GRAVITY_WORLD, InertialParams, newton_euler};
/// # // Closed-form motion of a 35 g body at 100 Hz; the actuators also fight a linear drag
/// # // of 0.01 N s/m. `with_accel`: log the accelerations, or leave them to be derived.
/// # fn motion(t: f64) -> (Vector3<f64>, Vector3<f64>, UnitQuaternion<f64>, Vector3<f64>, Vector3<f64>) {
/// #     let v = Vector3::new(0.5 * (0.8 * t).cos(), 0.4 * (1.1 * t).cos(), 0.1 * (0.5 * t).cos());
/// #     let acc = Vector3::new(-0.4 * (0.8 * t).sin(), -0.44 * (1.1 * t).sin(), -0.05 * (0.5 * t).sin());
/// #     let q = UnitQuaternion::from_euler_angles(0.2 * (1.3 * t).sin(), 0.15 * (0.9 * t).sin(), 0.3 * t);
/// #     let w = Vector3::new(0.26 * (1.3 * t).cos(), 0.135 * (0.9 * t).cos(), 0.3);
/// #     let wd = Vector3::new(-0.338 * (1.3 * t).sin(), -0.1215 * (0.9 * t).sin(), 0.0);
/// #     (v, acc, q, w, wd)
/// # }
/// # fn flight(samples: usize, with_accel: bool) -> FlightLog {
/// #     let theta = InertialParams::from_array([0.035, 0.0, 0.0, 0.0, 1.7e-5, 0.0, 1.7e-5, 0.0, 0.0, 2.9e-5]);
/// #     let mut log = FlightLog::new();
/// #     for k in 0..samples {
/// #         let t = k as f64 * 0.01;
/// #         let (v, acc, q, w, wd) = motion(t);
/// #         let a_body = q.inverse_transform_vector(&(acc - GRAVITY_WORLD));
/// #         let mut wrench = newton_euler(&theta, &a_body, &w, &wd).to_array();
/// #         let v_body = q.inverse_transform_vector(&v);
/// #         for c in 0..3 {
/// #             wrench[c] += 0.01 * v_body[c];
/// #         }
/// #         let p = Vector3::new(0.625 * (0.8 * t).sin(), 0.4 / 1.1 * (1.1 * t).sin(), 1.0 + 0.2 * (0.5 * t).sin());
/// #         log.push(&LogSample {
/// #             t,
/// #             position: p.into(),
/// #             velocity: v.into(),
/// #             attitude: [q.w, q.i, q.j, q.k],
/// #             omega: w.into(),
/// #             wrench,
/// #             accel: with_accel.then(|| acc.into()),
/// #             omega_dot: with_accel.then(|| wd.into()),
/// #             rotor_speeds: None,
/// #         });
/// #     }
/// #     log
/// # }
/// use tagk_diagnose::{DiagnoseOptions, EffectKind, Model, Signals, discover};
///
/// let s = Signals::from_log(&flight(1500, true))?;
/// let found = discover(&Model::rigid_body(), &s, &DiagnoseOptions::default())?;
/// assert_eq!(found.added, [EffectKind::LinearDrag.name()]);
/// assert!(found.adequate);
/// let (first, last) = (&found.steps[0], &found.steps[found.steps.len() - 1]);
/// for c in 0..3 {
///     assert!(last.held_out_rms[c] < 0.01 * first.held_out_rms[c]);
/// }
/// assert_eq!(found.last().model, found.final_model);
/// # Ok::<(), tagk_diagnose::DiagnoseError>(())
/// ```
pub fn discover(
    start: &Model,
    s: &Signals,
    opts: &DiagnoseOptions,
) -> Result<Discovery, DiagnoseError> {
    let first = crate::diagnose::diagnose(start, s, opts)?;
    discover_from(start, first, s, opts)
}

/// [`discover`] from an existing diagnosis of `start` (its noise is the starting one).
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
    let mut fits = Fits::default();
    fits.keep(start, first.fit.clone());
    let mut run = Run {
        steps: vec![step_of(None, &first, None, &floor)],
        diagnoses: vec![first],
        added: Vec::new(),
        model: start.clone(),
        stopped: String::new(),
    };
    let mut round = 0;
    loop {
        // Climb, prune, and climb again from what the pruning left (a dropped effect may
        // leave room for another: a drag law where an implausible wind was), at most twice.
        for _ in 0..2 {
            climb(&mut run, s, opts, &floor, &mut fits)?;
            let climbed = run.added.clone();
            prune(start, &mut run, s, opts, &floor, &mut fits)?;
            if run.added == climbed {
                break;
            }
        }
        round += 1;
        if floor.source == FloorSource::Given || round >= 3 {
            let same = equivalents(&run, s, opts, &floor);
            return Ok(finish(run, floor, same));
        }
        let last = run
            .diagnoses
            .last()
            .expect("a staircase has its first step");
        let again = noise_floor(s, &last.fit, &run.model, None, opts.airframe_radius);
        if !(0..6).any(|c| again.rms[c] < 0.85 * floor.rms[c]) {
            let same = equivalents(&run, s, opts, &floor);
            return Ok(finish(run, floor, same));
        }
        for c in 0..6 {
            if again.rms[c] < floor.rms[c] {
                floor.rms[c] = again.rms[c];
                floor.noise_estimate[c] = again.noise_estimate[c];
                floor.from_wrench[c] = again.from_wrench[c];
                floor.from_motion[c] = again.from_motion[c];
            }
        }
        floor.model = again.model;
        // The search goes on from the model reached, against the lower noise (the fits do
        // not depend on the noise); the effects added stay unless the pruning drops them.
        let d = diagnose_with_fit(
            &run.model,
            s,
            opts,
            &floor,
            fits.get(&run.model, s)?,
            true,
            run.reference(),
        )?;
        let k = run.diagnoses.len() - 1;
        let previous = (k > 0).then(|| &run.diagnoses[k - 1]);
        let effect = run.steps[k].effect.clone();
        run.steps[k] = step_of(effect.as_deref(), &d, previous, &floor);
        run.diagnoses[k] = d;
    }
}

/// Fits of the models a discovery meets, by label: they do not depend on the noise, and the
/// rounds and the pruning meet the same models again.
#[derive(Default)]
struct Fits(std::collections::HashMap<String, Arc<crate::fit::Fit>>);

impl Fits {
    /// Keeps a model's fit.
    fn keep(&mut self, model: &Model, fit: Arc<crate::fit::Fit>) {
        self.0.insert(model.label(), fit);
    }

    /// A model's fit, fitted once.
    fn get(&mut self, model: &Model, s: &Signals) -> Result<Arc<crate::fit::Fit>, DiagnoseError> {
        if let Some(f) = self.0.get(&model.label()) {
            return Ok(f.clone());
        }
        let f = Arc::new(fit_model(model, s, None)?);
        self.keep(model, f.clone());
        Ok(f)
    }
}

/// A staircase before its steps are set against the final noise.
struct Run {
    steps: Vec<Step>,
    diagnoses: Vec<Diagnosis>,
    added: Vec<String>,
    model: Model,
    stopped: String,
}

impl Run {
    /// The rigid body the physical rules judge every refit against: the starting model's.
    fn reference(&self) -> Option<tagk_dynamics::InertialParams> {
        Some(self.diagnoses[0].fit.theta)
    }

    /// Adds the candidate `name` of `opts` to the model as a step of its own, diagnosed
    /// against `floor` (with the search for the next step when `search`). A name that is
    /// not a candidate adds nothing.
    fn add(
        &mut self,
        name: &str,
        search: bool,
        s: &Signals,
        opts: &DiagnoseOptions,
        floor: &NoiseFloor,
        fits: &mut Fits,
    ) -> Result<(), DiagnoseError> {
        let Some(effect) = opts.candidates.iter().find(|c| c.name() == name) else {
            return Ok(());
        };
        self.model = self.model.clone().with_ref(effect.clone());
        let fit = fits.get(&self.model, s)?;
        let next = diagnose_with_fit(&self.model, s, opts, floor, fit, search, self.reference())?;
        self.steps
            .push(step_of(Some(name), &next, self.diagnoses.last(), floor));
        self.diagnoses.push(next);
        self.added.push(name.to_string());
        Ok(())
    }
}

/// Judges each added effect of `run`'s final model within it, by the search's rules against the
/// starting model's rigid body. `f` gets the effect's name, the context of the final model
/// without it (with its engines and its score) and the effect's own verdict there.
fn judge_each_added(
    run: &Run,
    s: &Signals,
    opts: &DiagnoseOptions,
    floor: &NoiseFloor,
    mut f: impl FnMut(&str, &JudgedWithout<'_, '_>),
) {
    let Some(last) = run.diagnoses.last() else {
        return;
    };
    let fit = &last.fit;
    let limits = limits_of(&run.model, opts);
    let judge = Judge {
        limits: &limits,
        current: run.diagnoses[0].fit.theta,
        mean_thrust: mean_thrust(s),
        tests: opts.candidates.len().max(1) as f64,
        alpha: opts.alpha,
    };
    for name in &run.added {
        let Some(k) = run.model.effects().iter().position(|e| e.name() == name) else {
            continue;
        };
        let ctx = Context::without_effect(s, &run.model, fit, k, floor, opts.folds);
        let engine = ctx.engine();
        let fit_engine = ctx.fit_engine();
        let base = ctx.score(&engine, &[]);
        let member = Member {
            effect: run.model.effects()[k].clone(),
            param: fit.params[k],
        };
        let own = ctx.judge_set(&engine, &fit_engine, vec![member], &base, &judge, false);
        f(
            name,
            &JudgedWithout {
                ctx: &ctx,
                engine: &engine,
                fit_engine: &fit_engine,
                base: &base,
                judge: &judge,
                own,
            },
        );
    }
}

/// The final model without one of its added effects, and that effect's verdict within it
/// ([`judge_each_added`]).
struct JudgedWithout<'c, 's> {
    ctx: &'c Context<'s>,
    engine: &'c GramEngine<'c>,
    fit_engine: &'c GramEngine<'c>,
    base: &'c Score,
    judge: &'c Judge<'c>,
    /// The effect's own verdict.
    own: SetEval,
}

/// The added effects of the final model that another candidate replaces as well
/// ([`Equivalent`]): each added effect is taken out, and every usable candidate judged in its
/// place by the search's rules. One that is admissible and whose held-out gain is within
/// chance of the effect's own ([`chance_margin`]: twice the square root of the gain) is an
/// equivalent.
fn equivalents(
    run: &Run,
    s: &Signals,
    opts: &DiagnoseOptions,
    floor: &NoiseFloor,
) -> Vec<Equivalent> {
    let mut found = Vec::new();
    judge_each_added(run, s, opts, floor, |name, w| {
        let (candidates, _) = usable_candidates(&w.ctx.model, s, opts);
        for c in candidates.iter().filter(|c| c.name() != name) {
            let Ok(set) = w
                .ctx
                .judge_single(w.engine, w.fit_engine, c, w.base, w.judge)
            else {
                continue;
            };
            if set.admissible()
                && (set.gain - w.own.gain).abs() <= chance_margin(set.gain.max(w.own.gain))
            {
                found.push(Equivalent {
                    effect: name.to_string(),
                    alternative: c.name().to_string(),
                    gain: w.own.gain,
                    alternative_gain: set.gain,
                });
            }
        }
    });
    found
}

/// Every step against the final noise; the discovery.
fn finish(mut run: Run, floor: NoiseFloor, equivalents: Vec<Equivalent>) -> Discovery {
    for step in &mut run.steps {
        for (c, ch) in step.channels.iter_mut().enumerate() {
            ch.floor = floor.rms[c];
            ch.ratio_to_floor = if floor.rms[c] > 0.0 {
                ch.held_out_rms / floor.rms[c]
            } else {
                f64::INFINITY
            };
        }
    }
    for d in &mut run.diagnoses {
        d.noise_floor = floor.clone();
    }
    let adequate = run.diagnoses.last().is_some_and(|d| d.adequate);
    Discovery {
        steps: run.steps,
        added: run.added,
        final_model: run.model.label(),
        noise_floor: floor,
        stopped: run.stopped,
        adequate,
        equivalents,
        diagnoses: run.diagnoses,
    }
}

/// Climbs the staircase from its last step against the noise `floor`: each step the set the
/// search of the last model chose, until none is admissible or the step limit.
fn climb(
    run: &mut Run,
    s: &Signals,
    opts: &DiagnoseOptions,
    floor: &NoiseFloor,
    fits: &mut Fits,
) -> Result<(), DiagnoseError> {
    run.stopped = loop {
        let current = &run.diagnoses[run.diagnoses.len() - 1];
        if current.recommended_set.is_empty() {
            break stop_reason(current);
        }
        let set = current.recommended_set.clone();
        if run.added.len() + set.len() > opts.max_steps {
            break format!(
                "step limit: {} effects added (`max_steps` {}); {} would be next",
                run.added.len(),
                opts.max_steps,
                set.iter()
                    .map(|n| format!("`{n}`"))
                    .collect::<Vec<_>>()
                    .join(" + ")
            );
        }
        for (i, name) in set.iter().enumerate() {
            run.add(name, i + 1 == set.len(), s, opts, floor, fits)?;
        }
    };
    Ok(())
}

/// Checks every added effect within the final model and drops, one at a time, the one that
/// no longer earns its place (module docs). Then the whole set decides between two ways on:
/// the others kept in their order and refitted, or the search climbed again from `start`
/// without the dropped effects. The lower held-out error in units of the noise wins. The
/// others' refit alone may land far from what the search chose (a lag and a delay refitted
/// along the ridge on which they trade, once a third effect is gone); judged there, one drop
/// cascaded into the next until nothing was left.
fn prune(
    start: &Model,
    run: &mut Run,
    s: &Signals,
    opts: &DiagnoseOptions,
    floor: &NoiseFloor,
    fits: &mut Fits,
) -> Result<(), DiagnoseError> {
    let mut dropped = Vec::new();
    let mut vetoed: Vec<String> = Vec::new();
    // Each drop takes a candidate out for good: at most as many drops as candidates.
    for _ in 0..opts.candidates.len() {
        let fit = run.diagnoses[run.diagnoses.len() - 1].fit.clone();
        let mut weakest: Option<(f64, String, String)> = None;
        judge_each_added(run, s, opts, floor, |name, w| {
            // The final fit's own verdict on the effect's coefficients counts too — but for a
            // wind whose force is within its noise: its drag is still needed (the report
            // carries the verdict).
            let own = fit
                .effects
                .iter()
                .find(|f| f.effect == name)
                .filter(|f| !f.plausible && !f.plausibility_note.contains("a drag without wind"))
                .map(|f| format!("implausible in the final fit: {}", f.plausibility_note));
            let why = w.own.verdicts[0]
                .refusal
                .as_ref()
                .map(|r| r.describe())
                .or(own);
            if let Some(why) = why
                && weakest.as_ref().is_none_or(|(g, _, _)| w.own.gain < *g)
            {
                weakest = Some((w.own.gain, name.to_string(), why));
            }
        });
        let Some((_, name, why)) = weakest else {
            break;
        };
        dropped.push(format!("`{name}` ({why})"));
        // Two ways on: the other effects kept in their order and refitted, or the search
        // again from the starting model without the dropped effects. The whole set decides:
        // the one of the lower held-out error in units of the noise.
        let kept: Vec<String> = run.added.iter().filter(|n| **n != name).cloned().collect();
        let first = run.diagnoses[0].clone();
        let mut kept_run = Run {
            steps: vec![step_of(None, &first, None, floor)],
            diagnoses: vec![first],
            added: Vec::new(),
            model: start.clone(),
            stopped: std::mem::take(&mut run.stopped),
        };
        for (i, n) in kept.iter().enumerate() {
            kept_run.add(n, i + 1 == kept.len(), s, opts, floor, fits)?;
        }
        if kept.is_empty() {
            // The starting model again, with its search.
            let d = diagnose_with_fit(start, s, opts, floor, fits.get(start, s)?, true, None)?;
            kept_run.steps = vec![step_of(None, &d, None, floor)];
            kept_run.diagnoses = vec![d];
        }
        vetoed.push(name);
        let mut without = opts.clone();
        without
            .candidates
            .retain(|c| !vetoed.iter().any(|v| v == c.name()));
        let first = diagnose_with_fit(start, s, &without, floor, fits.get(start, s)?, true, None)?;
        let mut searched = Run {
            steps: vec![step_of(None, &first, None, floor)],
            diagnoses: vec![first],
            added: Vec::new(),
            model: start.clone(),
            stopped: String::new(),
        };
        climb(&mut searched, s, &without, floor, fits)?;
        *run = if held_out_score(&searched, floor) < held_out_score(&kept_run, floor) {
            searched
        } else {
            kept_run
        };
    }
    if !vetoed.is_empty() {
        // The last model's search with every candidate again: a dropped effect may earn its
        // place beside other effects than those it was dropped from (the next climb).
        let k = run.diagnoses.len() - 1;
        let d = diagnose_with_fit(
            &run.model,
            s,
            opts,
            floor,
            fits.get(&run.model, s)?,
            true,
            run.reference(),
        )?;
        let previous = (k > 0).then(|| &run.diagnoses[k - 1]);
        let effect = run.steps[k].effect.clone();
        run.steps[k] = step_of(effect.as_deref(), &d, previous, floor);
        run.diagnoses[k] = d;
    }
    if !dropped.is_empty() {
        // The verdict of the model that is left: the one before the drop may have been
        // adequate where this one is not.
        let last = &run.diagnoses[run.diagnoses.len() - 1];
        run.stopped = format!(
            "{}; dropped once the others were in: {}",
            stop_reason(last),
            dropped.join(", ")
        );
    }
    Ok(())
}

/// The held-out error of a staircase's last model in units of the noise: `Σ_c rms_c² / σ_c²`
/// over the channels with a noise (per sample; dimensionless).
fn held_out_score(run: &Run, floor: &NoiseFloor) -> f64 {
    let last = &run.diagnoses[run.diagnoses.len() - 1];
    (0..6)
        .filter(|&c| floor.rms[c] > 0.0)
        .map(|c| (last.held_out_rms[c] / floor.rms[c]).powi(2))
        .sum()
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
    let gain = previous.map_or(0.0, |p| {
        (0..6)
            .filter(|&c| floor.rms[c] > 0.0)
            .map(|c| (p.held_out_rms[c].powi(2) - d.held_out_rms[c].powi(2)) / floor.rms[c].powi(2))
            .sum()
    });
    let fitted = effect.and_then(|e| d.effects.iter().find(|f| f.effect == e));
    Step {
        effect: effect.map(str::to_string),
        model: d.model.clone(),
        held_out_rms: d.held_out_rms,
        channels,
        gain,
        coefficients: fitted.map_or_else(Vec::new, |f| f.coefficients.clone()),
        derived: fitted.map_or_else(Vec::new, |f| f.derived.clone()),
        scanned: fitted.and_then(|f| f.scanned.clone()),
        scanned_interval: fitted.and_then(|f| f.scanned_interval),
    }
}

/// Why the search stops at `d` (which recommends nothing).
fn stop_reason(d: &Diagnosis) -> String {
    if d.adequate {
        return format!(
            "adequate: every channel's held-out error is within {}× its noise and white",
            crate::diagnose::ADEQUACY_FACTOR
        );
    }
    match d.ranking.first() {
        Some(best) => format!(
            "no set of candidates is admissible; the best remaining, {}",
            best.explanation
        ),
        None => "no candidate left to try".into(),
    }
}
