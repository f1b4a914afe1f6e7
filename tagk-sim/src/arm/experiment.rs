//! The arm's Table II: every estimator, nominal and oracle on the same random runs.

use nalgebra::Vector3;
use rand::RngExt;
use serde::{Deserialize, Serialize};
use tagk_dynamics::InertialParams;

use super::{
    ArmAdaptation, ArmModel, ArmOutput, ArmSimConfig, ArmTrajectory, BaseParameters,
    EstimationScope, FourierTrajectory, JointSensing, PayloadEvent, PickAndPlace, box_payload,
};
use crate::{EstimatorKind, SimError};

/// RMS flange error \[m\] over the judged second after each event that a successful run stays
/// under (see [`ArmTrialMetrics::success`]).
pub const ARM_SUCCESS_THRESHOLD: f64 = 2e-3;
/// Time after a payload event before success is judged \[s\]: ten estimator windows.
pub const ARM_SETTLE_TIME: f64 = 1.0;
/// Length of the judged stretch after the settle time \[s\].
pub const ARM_JUDGE_TIME: f64 = 1.0;

/// The reference of the experiment.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum ArmTrajectoryKind {
    /// A random 5-harmonic Fourier excitation, period 4 s, within 0.6 rad of home.
    Fourier,
    /// Pick-and-place moves of 0.5 rad per joint, 1.5 s each, 1 s dwell.
    PickAndPlace,
}

/// The random runs of the arm's Table II.
#[derive(Debug, Clone, PartialEq)]
pub struct ArmExperiment {
    /// What the estimators learn.
    pub scope: EstimationScope,
    /// Run length \[s\].
    pub duration: f64,
    /// The reference.
    pub trajectory: ArmTrajectoryKind,
    /// Joint sensing.
    pub sensing: JointSensing,
    /// Payload mass range \[kg\] (uniform).
    pub payload_mass: (f64, f64),
    /// Relative error of the URDF's link parameters: each true link is its URDF θ times
    /// `U[1 − e, 1 + e]` (0 for the payload scope, where the links are known).
    pub link_error: f64,
}

impl ArmExperiment {
    /// The default experiment of a scope: 8 s Fourier runs, realistic sensing, payloads of
    /// 1–2 kg; for all links, URDF errors of ±15 %.
    pub fn new(scope: EstimationScope) -> Self {
        Self {
            scope,
            duration: 8.0,
            trajectory: ArmTrajectoryKind::Fourier,
            sensing: JointSensing::REALISTIC,
            payload_mass: (1.0, 2.0),
            link_error: match scope {
                EstimationScope::Payload => 0.0,
                EstimationScope::AllLinks => 0.15,
            },
        }
    }

    /// The run of trial `seed` with `adaptation`; every row of a trial shares the draws.
    ///
    /// The payload (a 6 cm box, centre 10–20 cm along the flange joint's axis and within 2 cm
    /// across it) is grasped at U[2, 3] s and released at U[5, 6] s (Fourier), or mid-dwell at
    /// pick and place.
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] / [`SimError::NonPositiveMass`] for a bad experiment.
    pub fn config(
        &self,
        model: &ArmModel,
        seed: u64,
        adaptation: ArmAdaptation,
    ) -> Result<ArmSimConfig, SimError> {
        let mut rng = crate::sim::sub_rng(seed, 0xA3);
        let (trajectory, grasp, release) = match self.trajectory {
            ArmTrajectoryKind::Fourier => {
                let f = FourierTrajectory::random(model, 5, 4.0, 0.6, &mut rng)?;
                let g = rng.random_range(2.0..3.0);
                let r = rng.random_range(5.0..6.0);
                (ArmTrajectory::Fourier(f), g, r)
            }
            ArmTrajectoryKind::PickAndPlace => {
                let p = PickAndPlace::around_home(model, 0.5, 1.5, 1.0);
                let (g, r) = p.grasp_times();
                (ArmTrajectory::PickAndPlace(p), g, r)
            }
        };
        let (lo, hi) = self.payload_mass;
        if !(lo > 0.0 && lo <= hi && hi.is_finite()) {
            return Err(SimError::NonPositiveMass {
                what: "payload",
                mass: lo,
            });
        }
        let mass = if hi > lo {
            rng.random_range(lo..hi)
        } else {
            lo
        };
        let axis = *model.tree.bodies()[model.flange()].axis();
        // Two directions across the axis.
        let helper = if axis.x.abs() < 0.9 {
            Vector3::x()
        } else {
            Vector3::y()
        };
        let u = axis.cross(&helper).normalize();
        let w = axis.cross(&u);
        let centre = axis * rng.random_range(0.10..0.20)
            + u * rng.random_range(-0.02..0.02)
            + w * rng.random_range(-0.02..0.02);
        let payload = box_payload(mass, centre, 0.06)?;
        let true_links = if self.link_error > 0.0 {
            let e = self.link_error;
            Some(
                model
                    .tree
                    .params()
                    .iter()
                    .map(|p| {
                        let s = rng.random_range(1.0 - e..1.0 + e);
                        InertialParams::from_array(p.to_array().map(|x| s * x))
                    })
                    .collect(),
            )
        } else {
            None
        };
        let mut c = ArmSimConfig::new(model, trajectory, self.duration);
        c.seed = seed;
        c.sensing = self.sensing;
        c.events = vec![
            PayloadEvent {
                time: grasp,
                payload: Some(payload),
            },
            PayloadEvent {
                time: release,
                payload: None,
            },
        ];
        c.true_links = true_links;
        c.adaptation = adaptation;
        Ok(c)
    }
}

/// The metrics of one run.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ArmTrialMetrics {
    /// RMS flange position error over the run \[mm\].
    pub tracking_mm: f64,
    /// Mean over updates of the relative base-parameter error `‖β̂ − β‖ / ‖β‖`.
    pub parameter_error: f64,
    /// Mean over events of that error at the first update after the event.
    pub t1_error: f64,
    /// Success: not aborted, and after every event the RMS flange error over
    /// `[t_e + ARM_SETTLE_TIME, t_e + ARM_SETTLE_TIME + ARM_JUDGE_TIME]` is under
    /// [`ARM_SUCCESS_THRESHOLD`].
    pub success: bool,
    /// The run stopped early.
    pub aborted: bool,
    /// Mean wall time of one estimator update \[s\] (0 for nominal and oracle).
    pub update_s: f64,
}

impl ArmTrialMetrics {
    /// The metrics of `output` for payload events at `event_times` \[s\].
    pub fn from_output(output: &ArmOutput, event_times: &[f64]) -> Self {
        let rms = |v: &[f64]| -> f64 {
            if v.is_empty() {
                f64::NAN
            } else {
                (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt()
            }
        };
        let tracking_mm = 1e3 * rms(&output.flange_error);
        let mean = |v: &[f64]| -> f64 {
            if v.is_empty() {
                f64::NAN
            } else {
                v.iter().sum::<f64>() / v.len() as f64
            }
        };
        let errs: Vec<f64> = output.updates.iter().map(|u| u.parameter_error).collect();
        let t1: Vec<f64> = event_times
            .iter()
            .filter_map(|&te| output.updates.iter().find(|u| u.time > te))
            .map(|u| u.parameter_error)
            .collect();
        let mut success = !output.aborted;
        for &te in event_times {
            let (a, b) = (te + ARM_SETTLE_TIME, te + ARM_SETTLE_TIME + ARM_JUDGE_TIME);
            let judged: Vec<f64> = output
                .times
                .iter()
                .zip(&output.flange_error)
                .filter(|(t, _)| **t >= a && **t < b)
                .map(|(_, e)| *e)
                .collect();
            if judged.is_empty() || rms(&judged) > ARM_SUCCESS_THRESHOLD {
                success = false;
            }
        }
        let times: Vec<f64> = output
            .updates
            .iter()
            .map(|u| u.update_s)
            .filter(|s| *s > 0.0)
            .collect();
        Self {
            tracking_mm,
            parameter_error: mean(&errs),
            t1_error: mean(&t1),
            success,
            aborted: output.aborted,
            update_s: if times.is_empty() { 0.0 } else { mean(&times) },
        }
    }
}

/// Runs one trial of `experiment` with `adaptation` and scores it.
///
/// # Errors
/// As [`ArmExperiment::config`] and [`simulate_arm`](super::simulate_arm).
pub fn run_arm_trial(
    model: &ArmModel,
    base: &BaseParameters,
    experiment: &ArmExperiment,
    seed: u64,
    adaptation: ArmAdaptation,
) -> Result<ArmTrialMetrics, SimError> {
    let config = experiment.config(model, seed, adaptation)?;
    let out = super::simulate_arm(model, base, &config)?;
    let times: Vec<f64> = config.events.iter().map(|e| e.time).collect();
    Ok(ArmTrialMetrics::from_output(&out, &times))
}

/// The rows of the arm's Table II: every estimator kind, then RLS-high, KF-high and TAG-K on
/// scaled columns, then `nominal` and `oracle`.
pub fn arm_table_rows() -> Vec<ArmAdaptation> {
    let mut v: Vec<ArmAdaptation> = EstimatorKind::ALL
        .iter()
        .map(|k| ArmAdaptation::Estimator(*k))
        .collect();
    v.extend(
        [
            EstimatorKind::RlsHigh,
            EstimatorKind::KfHigh,
            EstimatorKind::TagK,
        ]
        .map(ArmAdaptation::Scaled),
    );
    v.push(ArmAdaptation::Nominal);
    v.push(ArmAdaptation::Oracle);
    v
}

/// One row of the table: means over trials (non-aborted trials for the errors).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ArmRow {
    /// The row's label.
    pub label: String,
    /// Trials run.
    pub trials: usize,
    /// Mean RMS flange error \[mm\].
    pub tracking_mm: f64,
    /// Mean parameter error (relative).
    pub parameter_error: f64,
    /// Mean (t+1) error (relative).
    pub t1_error: f64,
    /// Share of successful trials, 0–1.
    pub success: f64,
    /// Share of aborted trials, 0–1.
    pub aborted: f64,
    /// Mean update time \[µs\].
    pub update_us: f64,
}

impl ArmRow {
    /// Aggregates the trials of one row.
    pub fn from_trials(label: &str, trials: &[ArmTrialMetrics]) -> Self {
        let ok: Vec<&ArmTrialMetrics> = trials.iter().filter(|m| !m.aborted).collect();
        let mean = |f: &dyn Fn(&ArmTrialMetrics) -> f64| -> f64 {
            let v: Vec<f64> = ok.iter().map(|m| f(m)).filter(|x| x.is_finite()).collect();
            if v.is_empty() {
                f64::NAN
            } else {
                v.iter().sum::<f64>() / v.len() as f64
            }
        };
        let share = |f: &dyn Fn(&ArmTrialMetrics) -> bool| -> f64 {
            trials.iter().filter(|m| f(m)).count() as f64 / trials.len().max(1) as f64
        };
        Self {
            label: label.to_string(),
            trials: trials.len(),
            tracking_mm: mean(&|m| m.tracking_mm),
            parameter_error: mean(&|m| m.parameter_error),
            t1_error: mean(&|m| m.t1_error),
            success: share(&|m| m.success),
            aborted: share(&|m| m.aborted),
            update_us: 1e6 * mean(&|m| m.update_s),
        }
    }
}

/// The table as aligned text.
pub fn arm_table(rows: &[ArmRow]) -> String {
    let mut s = format!(
        "{:<19} {:>10} {:>10} {:>10} {:>8} {:>7} {:>12}\n",
        "estimator", "track [mm]", "param err", "(t+1) err", "success", "aborts", "update [µs]"
    );
    for r in rows {
        s.push_str(&format!(
            "{:<19} {:>10.3} {:>10.4} {:>10.4} {:>7.0}% {:>6.0}% {:>12.2}\n",
            r.label,
            r.tracking_mm,
            r.parameter_error,
            r.t1_error,
            100.0 * r.success,
            100.0 * r.aborted,
            r.update_us
        ));
    }
    s
}
