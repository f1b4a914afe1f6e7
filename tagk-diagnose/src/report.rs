//! The before/after report: the whole loop in one value, its terminal table and its JSON.

use serde::Serialize;

use crate::diagnose::FloorSource;
use crate::diagnose::{
    Candidate, CandidateStatus, ChannelAdequacy, DiagnoseOptions, Diagnosis, Discovery, NoiseFloor,
    Step, diagnose, diagnose_against, discover, discover_from,
};
use crate::effects::EffectRef;
use crate::error::DiagnoseError;
use crate::fit::{ChannelFit, Model};
use crate::format::{change_percent, percent_cell, shell_join};
use crate::online::OnlineSummary;
use crate::signals::{CHANNEL_NAMES, Signals};
use tagk_dynamics::EffectKind;

/// The two per-channel fit measures of the tables, defined once for the terminal help, the
/// terminal tables and the HTML report.
pub const FIT_MEASURES: &str = "fit %  MATLAB compare's fit, 100 (1 - |y - y_model| / |y - mean(y)|); \
100 is perfect; n/a for a channel whose measurement is constant (a quadrotor's fx, fy).\n\
err %  residual RMS as a percentage of the RMS magnitude of the measured force (about the \
thrust) for fx, fy, fz, and of the measured torque for tx, ty, tz; defined for every channel; \
0 is perfect.";

/// One entry of the JSON `ranking`.
#[derive(Debug, Clone, Serialize)]
pub struct RankingEntry {
    /// Effect name.
    pub effect: String,
    /// Held-out residual reduction (fraction).
    pub reduction: f64,
    /// p-value of the significance test.
    pub p_value: f64,
    /// Physically plausible coefficients.
    pub plausible: bool,
    /// Where the candidate stands (`recommended`, `worse`, `below-floor`, …).
    pub status: CandidateStatus,
    /// One-line explanation.
    pub explanation: String,
}

impl From<&Candidate> for RankingEntry {
    fn from(c: &Candidate) -> Self {
        Self {
            effect: c.effect.clone(),
            reduction: c.reduction,
            p_value: c.p_value,
            plausible: c.plausible,
            status: c.status,
            explanation: c.explanation.clone(),
        }
    }
}

/// Before/after comparison of one channel.
#[derive(Debug, Clone, Serialize)]
pub struct ChannelChange {
    /// Channel.
    pub name: String,
    /// Residual RMS before.
    pub rms_before: f64,
    /// Residual RMS after.
    pub rms_after: f64,
    /// `1 − after/before`.
    pub rms_reduction: f64,
    /// Fit % before.
    pub fit_percent_before: Option<f64>,
    /// Fit % after.
    pub fit_percent_after: Option<f64>,
    /// Error % before ([`ChannelFit::error_percent`]).
    pub error_percent_before: Option<f64>,
    /// Error % after.
    pub error_percent_after: Option<f64>,
}

/// What to run next, with the reason: the last line of every report.
#[derive(Debug, Clone, Serialize)]
pub struct NextStep {
    /// The command line.
    pub command: String,
    /// Why this is the next step.
    pub why: String,
}

/// The whole loop on one log: diagnose the rigid-body model (`before`); if effects were added
/// with `with`, diagnose the augmented model (`after`); then the stepwise search from that
/// model ([`crate::discover`]): the staircase of further effects down to the noise floor.
///
/// The top-level `recommended`, `ranking` and `channels` describe the model the search
/// started from (`after` when effects were added, otherwise `before`); `recommended` is the
/// first step of the staircase.
///
/// # Examples
///
/// The loop on a log of a body whose actuators fight a hidden linear drag (hidden: `flight`,
/// as in [`Signals`]' example): the report recommends the drag, its staircase adds it, and
/// it names the next command.
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
/// use tagk_diagnose::{DiagnoseOptions, EffectKind, Model, Signals, run_loop};
///
/// let s = Signals::from_log(&flight(1500, true))?;
/// let report = run_loop(&s, &Model::rigid_body(), &[], &DiagnoseOptions::default())?;
/// let drag = EffectKind::LinearDrag.name();
/// assert_eq!(report.recommended.as_deref(), Some(drag));
/// assert_eq!(report.final_model.added, [drag]);
/// assert!(report.adequate && report.after.is_none()); // nothing was added with `--with`
/// assert_eq!(report.next_step().map(|n| n.command), Some(format!("--with {drag}")));
/// // The JSON form carries the same recommendation.
/// let json: serde_json::Value = serde_json::from_str(&report.to_json()?).expect("valid JSON");
/// assert_eq!(json["recommended"], drag);
/// # Ok::<(), tagk_diagnose::DiagnoseError>(())
/// ```
#[derive(Debug, Clone, Serialize)]
pub struct Report {
    /// The first step of the staircase: the effect to add next (`null` when the starting
    /// model is adequate).
    pub recommended: Option<String>,
    /// The staircase: the starting model, then one entry per added effect, each with the
    /// held-out residual RMS per channel.
    pub steps: Vec<Step>,
    /// The final model of the staircase.
    pub final_model: FinalModel,
    /// The log's noise floor.
    pub noise_floor: NoiseFloor,
    /// Why the staircase stopped.
    pub stopped: String,
    /// `true` when the final model is adequate: what remains of the measured wrench is the
    /// sensors' noise on every channel.
    pub adequate: bool,
    /// Effects of the final model that another candidate replaces as well: the data cannot
    /// tell them apart ([`crate::diagnose::Equivalent`]).
    pub equivalents: Vec<crate::diagnose::Equivalent>,
    /// Ranking for the starting model.
    pub ranking: Vec<RankingEntry>,
    /// Channel fit of the starting model.
    pub channels: Vec<ChannelFit>,
    /// Effects added (`--with`).
    pub with: Vec<String>,
    /// Diagnosis of the rigid-body model.
    pub before: Diagnosis,
    /// Diagnosis after adding `with` (absent if nothing was added).
    pub after: Option<Diagnosis>,
    /// Per-channel before/after (absent if nothing was added).
    pub change: Option<Vec<ChannelChange>>,
    /// Diagnosis of the staircase's final model (absent when no step was added): its
    /// "where it fails" is what remains.
    pub final_diagnosis: Option<Diagnosis>,
    /// Online TAG-K pass, if requested.
    pub online: Option<OnlineSummary>,
    /// With several logs ([`run_logs`]): each log's own staircase against the joint one
    /// (empty for one log).
    pub logs: Vec<LogVerdict>,
    /// The next command to run (filled in by the command-line tool, which knows the files
    /// and flags; without it the report suggests the `--with` list, see [`Report::next`]).
    pub next: Option<NextStep>,
    /// The timing of each sensor stream against the pose, and the offsets removed before the
    /// fit ([`crate::streams::align_streams`]; filled in by the caller that aligned the log,
    /// empty otherwise).
    pub streams: Vec<crate::streams::StreamAlignment>,
    /// The accelerometer's offset of each flight, measured against its velocity before the
    /// fit, and the vertical part removed ([`crate::accel_offset`]; filled in by the caller
    /// that conditioned the log, empty otherwise or when it could not be measured).
    pub accelerometer_offsets: Vec<crate::accel_offset::AccelerometerOffset>,
    /// How each log is sampled — median step, gaps (where, how long), irregular steps — and
    /// what was done about it (split at the gaps, resampled); one entry per log, filled in by
    /// the caller that read the log ([`crate::sampling::SamplingFindings`]), empty otherwise.
    pub sampling: Vec<crate::sampling::SamplingFindings>,
    /// How each flight read through a column mapping was merged from its streams: each
    /// stream's rate, span, overlap with the time base and dropped samples, the gaps, the
    /// unread columns and the warnings ([`tagk_dynamics::log_input::MergeReport`], the lines
    /// the terminal prints before the diagnosis); one entry per such flight, empty for logs
    /// read in the project's format.
    pub inputs: Vec<tagk_dynamics::log_input::MergeReport>,
    /// The scale and consistency checks that found something ([`crate::scales`]: errors
    /// accepted, warnings), filled in by the caller that read the log; empty otherwise.
    pub scale_checks: Vec<crate::scales::ScaleFinding>,
    /// The glitches found and excluded from the fit ([`crate::glitches`]), filled in by the
    /// caller that read the log; empty otherwise.
    pub glitches: Vec<crate::glitches::Glitch>,
    /// Samples excluded around the glitches (each glitch and the samples whose derivatives
    /// read it).
    pub glitch_samples_excluded: usize,
    /// The fit of every model on the way to the final one, simplest first: the rigid body,
    /// the model with the `--with` effects (when some were given), then one per staircase
    /// step. What `tagk diagnose --save-steps` writes ([`crate::ModelFile::steps`]).
    #[serde(skip)]
    pub step_fits: Vec<std::sync::Arc<crate::fit::Fit>>,
    /// The time windows the diagnosis kept (`[start, end]` in log time \[s\], each log's
    /// rows within one of them; [`crate::DiagnosisPlan::window`]); not written when empty
    /// (the whole log).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub windows: Vec<[f64; 2]>,
    /// Every model of [`Report::step_fits`] scored on a validation log
    /// ([`crate::DiagnosisPlan::validation_file`]); not written when none was given.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub validation: Option<crate::validation::Validation>,
}

/// One log's own staircase in a joint diagnosis of several logs of one vehicle.
#[derive(Debug, Clone, Serialize)]
pub struct LogVerdict {
    /// The log's name (its file).
    pub log: String,
    /// Samples.
    pub samples: usize,
    /// The effects its own staircase adds.
    pub added: Vec<String>,
    /// `true` when it finds the same effect families as the joint staircase (the drag laws
    /// are one family; a `wind` fit counts as a drag too).
    pub agrees: bool,
    /// Why it disagrees (empty when it agrees).
    pub note: String,
    /// The log's own parameters under the final joint model (its mass when fitted, the
    /// effects' coefficients), each against the other logs'
    /// ([`crate::log_params`]).
    pub parameters: Vec<crate::log_params::LogParameter>,
    /// `true` when its parameters are inconsistent with the other logs' (another vehicle
    /// state): it is left out of the joint fit, and `agrees` is false.
    pub excluded: bool,
}

/// The final model of the staircase.
#[derive(Debug, Clone, Serialize)]
pub struct FinalModel {
    /// Model label (`rigid body + …`).
    pub label: String,
    /// Every effect of the final model (the `--with` list that reproduces it).
    pub effects: Vec<String>,
    /// The effects the staircase added.
    pub added: Vec<String>,
    /// The command that reproduces the final model (filled in by the command-line tool,
    /// which knows the files and flags; `null` from the library).
    pub command: Option<String>,
}

impl Report {
    /// The starting model's diagnosis (after, or before if nothing was added).
    pub fn last(&self) -> &Diagnosis {
        self.after.as_ref().unwrap_or(&self.before)
    }

    /// The next step: [`Report::next`] when the command-line tool set it, otherwise the
    /// effects to add (`--with …`) when the staircase added some, otherwise `None`.
    pub fn next_step(&self) -> Option<NextStep> {
        self.next.clone().or_else(|| {
            (!self.final_model.added.is_empty()).then(|| NextStep {
                command: shell_join(["--with", &self.final_model.effects.join(",")]),
                why: "refit with the effects the stepwise search added".into(),
            })
        })
    }

    /// The final model's diagnosis (the staircase's last step).
    pub fn final_diagnosis(&self) -> &Diagnosis {
        self.final_diagnosis.as_ref().unwrap_or_else(|| self.last())
    }

    /// The report as pretty JSON.
    ///
    /// # Errors
    /// [`DiagnoseError::Output`] if serialisation fails (non-finite numbers become `null`).
    pub fn to_json(&self) -> Result<String, DiagnoseError> {
        serde_json::to_string_pretty(self).map_err(|e| DiagnoseError::Output {
            path: "<json>".into(),
            message: e.to_string(),
        })
    }
}

/// Runs the loop: diagnose `base`, then `base + with` if `with` is not empty, then the
/// staircase from there.
///
/// # Errors
/// As [`diagnose`].
pub fn run_loop(
    s: &Signals,
    base: &Model,
    with: &[EffectRef],
    opts: &DiagnoseOptions,
) -> Result<Report, DiagnoseError> {
    let before = diagnose(base, s, opts)?;
    loop_from(before, s, base, with, opts)
}

/// The loop with the first recommendation applied: diagnose `base`; if an effect is
/// recommended, add it and diagnose again (the staircase then continues from there).
/// `report.after` is `None` when `base` was adequate.
///
/// # Errors
/// As [`diagnose`].
pub fn add_recommended(
    s: &Signals,
    base: &Model,
    opts: &DiagnoseOptions,
) -> Result<Report, DiagnoseError> {
    let before = diagnose(base, s, opts)?;
    // The recommendation is one of the candidates (built-in or the user's own).
    let with: Vec<EffectRef> = before
        .recommended
        .iter()
        .filter_map(|name| opts.candidates.iter().find(|c| c.name() == name))
        .cloned()
        .collect();
    loop_from(before, s, base, &with, opts)
}

/// [`run_loop`] from an existing diagnosis of `base` (its noise floor is reused).
fn loop_from(
    before: Diagnosis,
    s: &Signals,
    base: &Model,
    with: &[EffectRef],
    opts: &DiagnoseOptions,
) -> Result<Report, DiagnoseError> {
    let mut start = base.clone();
    for e in with {
        start = start.with_ref(e.clone());
    }
    let (after, change) = if with.is_empty() {
        (None, None)
    } else {
        let after = diagnose_against(&start, s, opts, &before.noise_floor)?;
        let change = before
            .channels
            .iter()
            .zip(&after.channels)
            .map(|(b, a)| ChannelChange {
                name: b.name.clone(),
                rms_before: b.rms,
                rms_after: a.rms,
                rms_reduction: if b.rms > 0.0 {
                    1.0 - a.rms / b.rms
                } else {
                    0.0
                },
                fit_percent_before: b.fit_percent,
                fit_percent_after: a.fit_percent,
                error_percent_before: b.error_percent,
                error_percent_after: a.error_percent,
            })
            .collect();
        (Some(after), Some(change))
    };
    let first = after.clone().unwrap_or_else(|| before.clone());
    let discovery = discover_from(&start, first, s, opts)?;
    let final_diagnosis = (!discovery.added.is_empty()).then(|| discovery.last().clone());
    let last = after.as_ref().unwrap_or(&before);
    let with_names: Vec<String> = with.iter().map(|e| e.name().to_string()).collect();
    let mut step_fits = vec![before.fit.clone()];
    step_fits.extend(
        discovery
            .diagnoses
            .iter()
            .skip(usize::from(with.is_empty()))
            .map(|d| d.fit.clone()),
    );
    let mut effects = with_names.clone();
    effects.extend(discovery.added.iter().cloned());
    Ok(Report {
        recommended: discovery.added.first().cloned(),
        final_model: FinalModel {
            label: discovery.final_model.clone(),
            effects,
            added: discovery.added.clone(),
            command: None,
        },
        steps: discovery.steps,
        noise_floor: discovery.noise_floor,
        stopped: discovery.stopped,
        equivalents: discovery.equivalents,
        adequate: discovery.adequate,
        ranking: last.ranking.iter().map(RankingEntry::from).collect(),
        channels: last.channels.clone(),
        with: with_names,
        before,
        after,
        change,
        final_diagnosis,
        online: None,
        logs: Vec::new(),
        next: None,
        streams: Vec::new(),
        accelerometer_offsets: Vec::new(),
        sampling: Vec::new(),
        inputs: Vec::new(),
        scale_checks: Vec::new(),
        glitches: Vec::new(),
        glitch_samples_excluded: 0,
        step_fits,
        windows: Vec::new(),
        validation: None,
    })
}

/// The effect families of a list of effect names, each with the effect that stands for it
/// (custom effects are their own family; a `wind` also counts as a drag).
fn families(names: &[String]) -> std::collections::BTreeMap<String, String> {
    let mut out = std::collections::BTreeMap::new();
    for name in names {
        match EffectKind::from_name(name) {
            Some(kind) => {
                out.entry(kind.family().to_string())
                    .or_insert_with(|| name.clone());
                if kind.includes_drag() {
                    out.entry(EffectKind::LinearDrag.family().to_string())
                        .or_insert_with(|| name.clone());
                }
            }
            None => {
                out.entry(name.clone()).or_insert_with(|| name.clone());
            }
        }
    }
    out
}

/// The loop on several logs of one vehicle: one joint data set ([`Signals::concat`]: one θ,
/// one set of effect coefficients, per-log start transients) diagnosed as [`run_loop`] does,
/// then each log's own staircase, compared with the joint one ([`Report::logs`]). A log that
/// disagrees says which effect it misses or adds and where that effect stands on it alone.
///
/// Each log's own parameters under the final joint model (mass, effect coefficients) are
/// compared with the other logs' ([`crate::log_params`]): a log whose parameters are
/// inconsistent (another vehicle state) is named, left out, and the joint loop is run again
/// on the others.
///
/// # Errors
/// As [`run_loop`]; [`DiagnoseError::InvalidOption`] for no log or an empty one, or (field
/// `logs`) when no log's parameters are consistent with the others' (two logs of two vehicle
/// states).
pub fn run_logs(
    logs: Vec<(String, Signals)>,
    base: &Model,
    with: &[EffectRef],
    opts: &DiagnoseOptions,
) -> Result<Report, DiagnoseError> {
    let names: Vec<String> = logs.iter().map(|(n, _)| n.clone()).collect();
    let parts: Vec<Signals> = logs.into_iter().map(|(_, s)| s).collect();
    if parts.len() == 1 {
        return run_loop(&parts[0], base, with, opts);
    }
    let mut start = base.clone();
    for e in with {
        start = start.with_ref(e.clone());
    }
    let mut verdicts = Vec::new();
    let single: Vec<Discovery> = parts
        .iter()
        .map(|p| discover(&start, p, opts))
        .collect::<Result<_, _>>()?;
    let joint = Signals::concat(parts.clone())?;
    let mut report = run_loop(&joint, base, with, opts)?;
    // Each log's own fit of the final joint model, against the others'.
    let mut final_model = start.clone();
    for name in &report.final_model.added {
        if let Some(e) = opts.candidates.iter().find(|c| c.name() == name) {
            final_model = final_model.with_ref(e.clone());
        }
    }
    let estimates: Vec<_> = parts
        .iter()
        .map(|p| crate::log_params::estimates(&final_model, p))
        .collect();
    let (parameters, flagged) = crate::log_params::compare(&estimates);
    if flagged.iter().all(|f| *f) {
        return Err(crate::log_params::refusal(&names, &parameters));
    }
    if flagged.iter().any(|f| *f) {
        // The consistent logs alone, then the others' verdicts beside theirs, in order.
        let keep: Vec<(String, Signals)> = names
            .iter()
            .cloned()
            .zip(parts)
            .zip(&flagged)
            .filter(|(_, f)| !**f)
            .map(|(l, _)| l)
            .collect();
        let mut kept = run_logs(keep, base, with, opts)?;
        let mut own = std::mem::take(&mut kept.logs).into_iter();
        let mut all = Vec::new();
        for (k, ((name, d), params)) in names.into_iter().zip(single).zip(parameters).enumerate() {
            if flagged[k] {
                let mut notes = vec![crate::log_params::excluded_note(&name, &params)];
                notes.extend(family_notes(&families(&kept.final_model.added), &d));
                all.push(LogVerdict {
                    note: notes.join("; "),
                    log: name,
                    samples: d.first().samples,
                    added: d.added.clone(),
                    agrees: false,
                    parameters: params,
                    excluded: true,
                });
            } else if let Some(v) = own.next() {
                all.push(LogVerdict {
                    parameters: params,
                    ..v
                });
            } else {
                // The one log left was diagnosed alone: it is the joint fit.
                all.push(LogVerdict {
                    log: name,
                    samples: d.first().samples,
                    added: d.added.clone(),
                    agrees: true,
                    note: String::new(),
                    parameters: params,
                    excluded: false,
                });
            }
        }
        kept.logs = all;
        return Ok(kept);
    }
    let joint_families = families(&report.final_model.added);
    for ((name, d), params) in names.into_iter().zip(single).zip(parameters) {
        let notes = family_notes(&joint_families, &d);
        verdicts.push(LogVerdict {
            log: name,
            samples: d.first().samples,
            added: d.added.clone(),
            agrees: notes.is_empty(),
            note: notes.join("; "),
            parameters: params,
            excluded: false,
        });
    }
    report.logs = verdicts;
    Ok(report)
}

impl ChannelAdequacy {
    /// `true` when the channel's residual is white: its autocorrelation sum is within its
    /// limit.
    pub fn is_white(&self) -> bool {
        self.autocorrelation_sum <= self.autocorrelation_limit
    }
}

/// How a log's own staircase `d` differs from the joint one (its effect families
/// `joint_families`): the effects it misses (and where each stands on it alone) and the ones
/// it adds. Empty when it agrees.
fn family_notes(
    joint_families: &std::collections::BTreeMap<String, String>,
    d: &Discovery,
) -> Vec<String> {
    let own = families(&d.added);
    let mut notes = Vec::new();
    for (family, effect) in joint_families {
        if !own.contains_key(family) {
            let why = d
                .last()
                .ranking
                .iter()
                .find(|c| &c.effect == effect)
                .map_or_else(
                    || "not available on this log".to_string(),
                    |c| c.explanation.rsplit("; ").next().unwrap_or("").to_string(),
                );
            notes.push(format!("misses `{effect}` (alone: {why})"));
        }
    }
    for (family, effect) in &own {
        if !joint_families.contains_key(family) {
            notes.push(format!(
                "adds `{effect}`, which the joint fit of all logs does not need"
            ));
        }
    }
    notes
}

fn fmt_fit(f: Option<f64>) -> String {
    f.map_or("   n/a".to_string(), |x| format!("{x:6.1}"))
}

/// Terminal summary of one diagnosis.
pub fn diagnosis_table(d: &Diagnosis) -> String {
    let mut s = String::new();
    s.push_str(&format!(
        "model: {}  ({} samples, {:.1} s{})\n",
        d.model,
        d.samples,
        d.duration,
        if d.derived_accelerations {
            ", accelerations derived by Savitzky-Golay"
        } else {
            ""
        }
    ));
    s.push_str("channel   fit %   err %   residual RMS\n");
    for c in &d.channels {
        s.push_str(&format!(
            "{:<8} {} {}   {:>12.4e} {}\n",
            c.name,
            fmt_fit(c.fit_percent),
            percent_cell(c.error_percent, 7),
            c.rms,
            c.unit
        ));
    }
    s.push_str("parameters (± 1 s.e.):\n");
    for p in &d.parameters {
        s.push_str(&format!(
            "  {:<5} = {:>11.4e} ± {:<10} {}\n",
            p.name,
            p.value,
            p.std_error.map_or("n/a".into(), |e| format!("{e:.1e}")),
            p.unit
        ));
    }
    s.push_str(&format!(
        "  centre of mass = ({:.2}, {:.2}, {:.2}) cm; physically consistent: {}; safety gate: {}\n",
        d.com[0] * 100.0,
        d.com[1] * 100.0,
        d.com[2] * 100.0,
        if d.physically_consistent { "yes" } else { "NO" },
        d.safety_gate
    ));
    for e in &d.effects {
        s.push_str(&format!("  effect {}:", e.effect));
        for c in &e.coefficients {
            s.push_str(&format!(" {} = {:.4e} {}", c.name, c.value, c.unit));
        }
        if let Some((n, v, u)) = &e.scanned {
            s.push_str(&format!(", {n} = {v:.3} {u}"));
            if let Some([lo, hi]) = e.scanned_interval {
                s.push_str(&format!(" [{lo:.3}, {hi:.3}]"));
            }
        }
        s.push_str(if e.plausible {
            "\n"
        } else {
            "  (IMPLAUSIBLE)\n"
        });
    }
    for w in &d.warnings {
        s.push_str(&format!("WARNING: {w}\n"));
    }
    if !d.findings.is_empty() {
        s.push_str("where it fails:\n");
        for f in &d.findings {
            s.push_str(&format!("  - {f}\n"));
        }
    }
    s.push_str(
        "what is missing (each candidate alone: held-out error in units of each channel's noise, blocked CV):\n",
    );
    for (k, c) in d.ranking.iter().enumerate() {
        s.push_str(&format!("  {:>2}. {}\n", k + 1, c.explanation));
    }
    for u in &d.unavailable {
        s.push_str(&format!("   -  {}: skipped, {}\n", u.effect, u.reason));
    }
    for c in &d.confounded {
        s.push_str(&format!(
            "cannot be told apart: `{}` and {} (variance inflation {:.0}): {}\n",
            c.effects[0],
            if c.effects[1] == "rigid body" {
                "the rigid body".to_string()
            } else {
                format!("`{}`", c.effects[1])
            },
            c.inflation,
            c.advice
        ));
    }
    for a in &d.alternatives {
        s.push_str(&format!(
            "explains the data as well: {}\n",
            a.iter()
                .map(|n| format!("`{n}`"))
                .collect::<Vec<_>>()
                .join(" + ")
        ));
    }
    s.push_str(&format!("verdict: {}\n", d.verdict));
    s
}

/// The staircase as a terminal table: per step, the held-out RMS per channel and its change,
/// then the floor, why the search stopped and the final model.
pub fn staircase_table(r: &Report) -> String {
    let mut s = format!(
        "=== stepwise: held-out residual RMS per channel (blocked CV), against each channel's noise ===\n{:<26}",
        "step"
    );
    for c in CHANNEL_NAMES {
        s.push_str(&format!(" {c:>17}"));
    }
    s.push('\n');
    for (k, step) in r.steps.iter().enumerate() {
        let label = match &step.effect {
            None => format!("{k}. {}", step.model),
            Some(e) => format!("{k}. + {e}"),
        };
        s.push_str(&format!("{label:<26}"));
        for ch in &step.channels {
            let change = if step.effect.is_some() {
                format!("({})", change_percent(ch.change, 0).replace(' ', ""))
            } else {
                String::new()
            };
            s.push_str(&format!(" {:>9.3e}{change:>8}", ch.held_out_rms));
        }
        s.push('\n');
    }
    let source = match r.noise_floor.source {
        FloorSource::Data => "noise (data)",
        FloorSource::Given => "noise (given)",
    };
    let noise = &r.noise_floor;
    for (label, values) in [
        (source, noise.rms),
        ("  of it: measured wrench", noise.from_wrench),
        ("  of it: motion sensors", noise.from_motion),
    ] {
        s.push_str(&format!("{label:<26}"));
        for f in values {
            s.push_str(&format!(" {f:>9.3e}{:>8}", ""));
        }
        s.push('\n');
    }
    s.push_str(&format!("stopped: {}\n", r.stopped));
    for step in r.steps.iter().skip(1) {
        if let Some(e) = &step.effect {
            let coefs: Vec<String> = step
                .coefficients
                .iter()
                .filter(|c| !crate::fit::is_start_nuisance(&c.name))
                .chain(&step.derived)
                .map(|c| match c.confidence_interval {
                    Some([lo, hi]) => {
                        format!(
                            "{} = {:.3e} [{:.2e}, {:.2e}] {}",
                            c.name, c.value, lo, hi, c.unit
                        )
                    }
                    None => format!("{} = {:.3e} {}", c.name, c.value, c.unit),
                })
                .collect();
            let mut all = coefs;
            if let Some((n, v, u)) = &step.scanned {
                all.push(match step.scanned_interval {
                    Some([lo, hi]) => format!("{n} = {v:.3} [{lo:.3}, {hi:.3}] {u}"),
                    None => format!("{n} = {v:.3} {u}"),
                });
            }
            let limited = r
                .final_diagnosis()
                .effects
                .iter()
                .find(|f| &f.effect == e)
                .filter(|f| !f.limited_by.is_empty())
                .map(|f| format!("; limited by {}", f.limited_by))
                .unwrap_or_default();
            s.push_str(&format!(
                "  {e}: {} (95 % intervals{limited})\n",
                all.join(", ")
            ));
        }
    }
    s.push_str(&format!("final model: {}\n", r.final_model.label));
    for e in &r.equivalents {
        s.push_str(&format!("  {}\n", e.sentence()));
    }
    if let Some(cmd) = &r.final_model.command {
        s.push_str(&format!("reproduce it: {cmd}\n"));
    } else if !r.final_model.effects.is_empty() {
        s.push_str(&format!(
            "reproduce it: {}\n",
            shell_join(["--with", &r.final_model.effects.join(",")])
        ));
    }
    s
}

/// Terminal summary of a whole report: the starting model's diagnosis (with `--with`, a
/// before/after table instead of a second full section), the staircase, and what remains.
pub fn report_table(r: &Report) -> String {
    let mut s = crate::sampling::sampling_text(&r.sampling);
    s.push_str(&crate::glitches::glitches_text(
        &r.glitches,
        r.glitch_samples_excluded,
    ));
    s.push_str(&crate::scales::scales_text(&r.scale_checks));
    if !r.streams.is_empty() {
        s.push_str(&crate::streams::streams_table(&r.streams));
        s.push('\n');
    }
    for offset in &r.accelerometer_offsets {
        s.push_str(&offset.text());
        s.push_str("\n\n");
    }
    if let (Some(a), Some(ch)) = (&r.after, &r.change) {
        s.push_str(&format!("=== model with {} ===\n", r.with.join(", ")));
        s.push_str(&diagnosis_table(a));
        s.push_str("\n=== rigid body / with the added effects (in-sample residual) ===\n");
        s.push_str(
            "channel   fit % before  fit % after  err % before  err % after   RMS before    RMS after    change\n",
        );
        for c in ch {
            s.push_str(&format!(
                "{:<8}  {:>11}  {:>11}  {}  {}  {:>11.4e}  {:>11.4e}  {:>8}\n",
                c.name,
                fmt_fit(c.fit_percent_before),
                fmt_fit(c.fit_percent_after),
                percent_cell(c.error_percent_before, 12),
                percent_cell(c.error_percent_after, 11),
                c.rms_before,
                c.rms_after,
                change_percent(-c.rms_reduction, 1)
            ));
        }
    } else {
        s.push_str("=== model: rigid body ===\n");
        s.push_str(&diagnosis_table(&r.before));
    }
    s.push('\n');
    s.push_str(&staircase_table(r));
    if !r.windows.is_empty() {
        let w: Vec<String> = r
            .windows
            .iter()
            .map(|[a, b]| format!("{a}..{b} s"))
            .collect();
        s.push_str(&format!("\nwindows kept (log time): {}\n", w.join(", ")));
    }
    if let Some(v) = &r.validation {
        s.push('\n');
        s.push_str(&v.text());
    }
    if !r.logs.is_empty() {
        s.push_str(&format!(
            "\n=== each log alone (joint staircase: {}) ===\n",
            if r.final_model.added.is_empty() {
                "nothing added".to_string()
            } else {
                r.final_model.added.join(" → ")
            }
        ));
        for l in &r.logs {
            let found = if l.added.is_empty() {
                "nothing added".to_string()
            } else {
                l.added.join(" → ")
            };
            if l.agrees {
                s.push_str(&format!(
                    "  {} ({} samples): {found}; agrees\n",
                    l.log, l.samples
                ));
            } else {
                s.push_str(&format!(
                    "  {} ({} samples): {found}; DISAGREES: {}\n",
                    l.log, l.samples, l.note
                ));
            }
            if let Some(mass) = l
                .parameters
                .iter()
                .find(|p| p.name == "mass" && p.consistent)
            {
                s.push_str(&format!("    own {}\n", mass.describe()));
            }
        }
    }
    if let Some(f) = &r.final_diagnosis {
        s.push_str(&format!("\n=== what remains ({}) ===\n", f.model));
        s.push_str(&remains(f));
    }
    if let Some(o) = &r.online {
        s.push_str(&format!(
            "\nonline TAG-K pass ({} rows, {} updates): mass {:.4} kg (tail average; last {:.4} kg), batch {:.4} kg ({:+.1} %); parameter distance to batch {:.3e}\n",
            o.rows.join("+"),
            o.updates,
            o.tail_average[0],
            o.final_estimate[0],
            o.batch_estimate[0],
            100.0 * o.mass_error_to_batch,
            o.distance_to_batch
        ));
    }
    if let Some(next) = r.next_step() {
        s.push_str(&format!("\nnext ({}):\n  {}\n", next.why, next.command));
    }
    s
}

/// The final model in a few lines: its channels against their noise (and which sensor limits
/// each), its parameters' warnings, and whether it is adequate or where it still fails.
fn remains(d: &Diagnosis) -> String {
    let mut s =
        String::from("channel   fit %   err %   held-out RMS  / noise  white  limited by\n");
    for (c, ch) in d.channels.iter().enumerate() {
        let a = &d.adequacy[c];
        s.push_str(&format!(
            "{:<8} {} {}   {:>12.4e}   {:>6.2}  {:>5}  {}\n",
            ch.name,
            fmt_fit(ch.fit_percent),
            percent_cell(ch.error_percent, 7),
            d.held_out_rms[c],
            a.ratio,
            if a.is_white() { "yes" } else { "no" },
            a.limited_by
        ));
    }
    for w in &d.warnings {
        s.push_str(&format!("WARNING: {w}\n"));
    }
    if d.adequate {
        s.push_str(&format!(
            "adequate: every channel's held-out error is within {}× its noise (or below its resolution) and white\n",
            crate::ADEQUACY_FACTOR
        ));
    } else if !d.findings.is_empty() {
        s.push_str("where it still fails:\n");
        for f in &d.findings {
            s.push_str(&format!("  - {f}\n"));
        }
    }
    s.push_str(&format!("verdict: {}\n", d.verdict));
    s
}
