//! What one flight produced: payload events, estimator updates, the per-step trace, the
//! metrics and the flight log.

use serde::{Deserialize, Serialize};
use tagk_dynamics::log::FlightLog;

use crate::metrics::GroupErrors;
use crate::trajectory::Trajectory;

/// A payload change as it happened.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct EventRecord {
    /// Time \[s\] (quantised to the control step).
    pub time: f64,
    /// Control step index.
    pub step: usize,
    /// `true` for an attach, `false` for a removal.
    pub attach: bool,
    /// True parameters after the event.
    pub params: [f64; 10],
}

/// One estimator update.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct UpdateRecord {
    /// Time \[s\].
    pub time: f64,
    /// The estimator's output `θ̂`.
    pub estimate: [f64; 10],
    /// True parameters at that time.
    pub truth: [f64; 10],
    /// Whether the safety gate (and the controller redesign) accepted it.
    pub accepted: bool,
    /// Wall-clock time of the estimator update alone \[µs\].
    pub micros: f64,
    /// The drag the controller compensates after this update, `diag(d_x, d_y, d_z)`
    /// \[N s/m\] (body frame). Zero without drag columns
    /// ([`EstimatorSpec::drag`](crate::EstimatorSpec::drag)); then left out of serialised
    /// records.
    #[serde(default, skip_serializing_if = "is_zero3")]
    pub drag: [f64; 3],
}

/// Whether every entry is zero (skips [`UpdateRecord::drag`] when off).
fn is_zero3(v: &[f64; 3]) -> bool {
    *v == [0.0; 3]
}

/// Per-control-step trace for figures.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TraceSample {
    /// Time \[s\].
    pub t: f64,
    /// True position \[m\].
    pub position: [f64; 3],
    /// Reference position \[m\].
    pub reference: [f64; 3],
    /// `‖θ̂ − θ‖₂` of the latest estimator output (of the controller's parameters without
    /// an estimator).
    pub parameter_error: f64,
}

/// Metrics of one flight (definitions in [`crate::metrics`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TrialMetrics {
    /// Position error \[cm\].
    pub position_error_cm: f64,
    /// Largest tracking error \[cm\].
    pub max_tracking_error_cm: f64,
    /// Mean parameter error `‖θ̂ − θ‖₂` over the estimator's updates (NaN without updates).
    pub parameter_error: f64,
    /// Mean per-group relative errors over the updates.
    pub group_errors: GroupErrors,
    /// (t+1) error (NaN without an event followed by an update).
    pub t1_error: f64,
    /// (t+1) error over the events whose first window held only post-event frames (NaN
    /// without one).
    pub t1_error_clean: f64,
    /// (t+1) error over the events whose first window mixed frames from before and after
    /// the event (NaN without one).
    pub t1_error_mixed: f64,
    /// Position error over the planned flight, an aborted flight's missing steps at the abort
    /// threshold (`metrics::position_error_all_cm`) \[cm\].
    pub position_error_all_cm: f64,
    /// Table II's success: settled after each payload event (`metrics::is_settled`).
    pub settled: bool,
    /// The paper's success rule (docs/CONVENTIONS.md §5: 5 cm, judged 10 control steps after
    /// each payload event).
    pub success: bool,
    /// Success judged instead 10 control steps after the first estimator update following
    /// each payload event (the window in which an estimator can act; equals the controller's
    /// redesign for the oracle, judged at the event).
    pub success_after_update: bool,
    /// The largest tracking error [`SETTLED_DELAY_STEPS`](crate::metrics::SETTLED_DELAY_STEPS)
    /// control steps after each payload event \[cm\]: the trial succeeds at any threshold
    /// above it (issue #27's success curve). +∞ when aborted; 0 when no event was judged.
    #[serde(default)]
    pub settle_error_cm: f64,
    /// Aborted.
    pub aborted: bool,
    /// Control steps flown.
    pub steps: usize,
}

/// Everything one flight produced.
#[derive(Debug, Clone, PartialEq)]
pub struct SimOutput {
    /// The reference path flown.
    pub trajectory: Trajectory,
    /// Metrics.
    pub metrics: TrialMetrics,
    /// Payload events.
    pub events: Vec<EventRecord>,
    /// Control steps at which the change detector alarmed (empty without
    /// [`EstimatorSpec::change_detector`](crate::EstimatorSpec::change_detector)).
    pub alarms: Vec<usize>,
    /// Estimator updates.
    pub updates: Vec<UpdateRecord>,
    /// Flight log (empty unless [`SimConfig::record_log`](crate::SimConfig::record_log)).
    ///
    /// Every sample refers to its control interval's midpoint `t`: position and attitude are
    /// the true (motion-capture) values, velocity carries the velocity noise, the body rate
    /// the gyro noise, the acceleration is the (noisy) accelerometer reading rotated into
    /// the world frame with gravity added back (`p̈ = R a_meas + g_w`), `omega_dot` the
    /// difference of gyro rates across the interval, and the wrench and rotor speeds are the
    /// commanded ones (nominal `k_f`, `k_m`, through the mixer). Every optional signal is
    /// present.
    pub log: FlightLog,
    /// Trace (empty unless [`SimConfig::record_trace`](crate::SimConfig::record_trace)).
    pub trace: Vec<TraceSample>,
    /// Tracking error per control step \[m\].
    pub tracking_errors: Vec<f64>,
    /// The noise-free truth behind the log, one [`TruthSample`](crate::sim::TruthSample) per
    /// log sample: true motion, true inertial parameters, each plant effect's wrench, the
    /// sensor biases (`Some` with [`SimConfig::record_truth`](crate::SimConfig::record_truth)
    /// and [`SimConfig::record_log`](crate::SimConfig::record_log), else `None`).
    pub truth: Option<crate::sim::FlightTruth>,
}
