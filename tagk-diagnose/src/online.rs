//! Optional online pass (`tagk diagnose LOG --online`): TAG-K run over the log as it would run
//! in flight, on the estimator's tuned front end, and compared with the batch fit of the same
//! model.
//!
//! # What TAG-K is fed
//! The settings are tagk-dynamics' [`front_end`](tagk_dynamics::front_end), the ones the
//! simulator's tuned TAG-K (`tagk_sim::tagk_tuned`) flies with, applied by tagk-core's
//! [`FrontEnd`]:
//!
//! - **Rows**: `f_z`, `τ_x`, `τ_y`, `τ_z` of each sample
//!   ([`ACTUATED_CHANNELS`]), windows of
//!   [`WINDOW_FRAMES`] samples (20 rows × 10 columns). A quadrotor measures no `f_x`, `f_y`: those
//!   rows are zero in the measured wrench and carry every unmodelled horizontal force (drag,
//!   wind), which would pull the mass down.
//! - **Known effects removed**: the batch fit's effects (drag, lag, …, with the fitted
//!   coefficients) are subtracted from the measured wrench before the rows are formed. Their
//!   part is the fit's prediction minus its rigid-body part, `ŷ − Y θ̂`. TAG-K then estimates
//!   the same θ as the batch fit of that model.
//! - **Rows whitened**: each row is divided by its channel's noise `σ_c`, the batch fit's
//!   residual RMS (floored as the batch fit's own channel weights are). Every row then has unit
//!   noise, like the batch fit's weighted rows.
//! - **Scaled columns**: TAG-K estimates `D⁻¹ θ` with
//!   [`column_scales`] of a prior. The prior is the
//!   batch estimate the pass is compared with (the natural one here: it is the magnitude of
//!   every parameter on this log, and the command line uses it), or a vehicle prior
//!   ([`OnlineOptions::prior`]).
//! - **Noise-aware stop**: a window's iterations stop once its residual is within
//!   [`STOP_MULTIPLE`] times its noise floor `√20`
//!   (20 rows of unit noise).
//! - **No event windows**: the batch fit assumes one θ for the whole log, so the pass does too.
//!
//! # Where it starts
//! TAG-K starts from the prior ([`OnlineStart::Prior`], the default), as in flight, where the
//! estimator starts from the vehicle's nominal parameters. From the batch estimate the pass
//! checks that the batch fit is where the online front end stays: a window moves the estimate
//! only when the fit leaves more than its noise unexplained on that window's `f_z` and torque
//! rows. From a vehicle prior it checks that TAG-K gets from there to the fit.
//!
//! [`OnlineStart::Zero`] starts from θ = 0 instead. The mass then converges: its rows carry
//! `m g` per sample, far above the noise. A parameter whose part of a window is below the
//! window's noise never leaves zero: the stop ends the window first. On gentle flights with
//! realistic sensors that is the inertia (`I ω̇` below the torque noise). Even without noise
//! `I_xx` and `I_yy` hardly move in gentle flight: on the torque rows their scaled columns
//! (`ī ω̇`) are hundreds of times smaller than the first moments' (`m L g`), and 20
//! projections per window go to the large columns. The stop also leaves
//! a dead zone on the mass of about `6 σ_fz / (m g)` around the batch mass (relative; 6–12 %
//! at the simulator's `realistic` sensing). From zero, on 80 simulated flights of 20 s with
//! realistic sensors (120 fits), the online mass ended a median 1.3 % and at worst 7.9 % from
//! the batch mass; with ideal sensors within 0.01 %.
//!
//! # What it reports
//! The online result is the **tail average**: the mean of the front end's estimates over the
//! windows that end in the second half of the log. A running mean is what an online estimator
//! can report at the end of a flight: it is causal and keeps no past windows. It averages the
//! window-to-window wander that the noise-aware stop leaves (a window stops anywhere within
//! its noise), which the last window's estimate carries in full. The last estimate is
//! reported beside it ([`OnlineSummary::final_estimate`]).
//!
//! A fit with a known mass ([`Model::with_known_mass`](crate::Model::with_known_mass)): the
//! online pass still estimates all ten parameters, the mass included. The batch mass it is
//! compared with is then the known mass.

use serde::Serialize;
use tagk_core::{FrontEnd, FrontEndConfig, KaczmarzConfig, OnlineEstimator, TagK};
use tagk_dynamics::front_end::{ACTUATED_CHANNELS, STOP_MULTIPLE, WINDOW_FRAMES, column_scales};
use tagk_dynamics::{InertialParams, SafetyGate, write_rigid_body_regressor};

use crate::error::DiagnoseError;
use crate::fit::{Fit, weights_from_residual};
use crate::signals::{CHANNEL_NAMES, Signals};

/// Rows per sample fed to TAG-K (the actuated channels).
const ROWS_PER_FRAME: usize = ACTUATED_CHANNELS.len();

/// Settings of the online pass ([`online_pass_with`]).
#[derive(Debug, Clone, PartialEq)]
pub struct OnlineOptions {
    /// Samples between the last samples of two consecutive windows (at least 1;
    /// [`WINDOW_FRAMES`], the default, gives windows that touch without overlapping).
    pub stride: usize,
    /// Prior of θ (docs/CONVENTIONS.md §1, SI units) for the column scales and, with
    /// [`OnlineStart::Prior`], the start: e.g. a vehicle's mass and inertia priors
    /// ([`Vehicle::inertial_prior`](tagk_dynamics::vehicle::Vehicle::inertial_prior)). `None`
    /// (the default): the batch estimate of the fit the pass is compared with.
    pub prior: Option<InertialParams>,
    /// Characteristic length \[m\] of the first moments' column scale `m L`: the arm offset,
    /// the largest admissible centre-of-mass offset (default: the Crazyflie's 0.0325 m, the
    /// default [`DiagnoseOptions::airframe_radius`](crate::DiagnoseOptions::airframe_radius)).
    pub arm_length: f64,
    /// Where TAG-K starts (default: from the prior).
    pub start: OnlineStart,
}

/// The online pass' initial estimate ([`OnlineOptions::start`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum OnlineStart {
    /// From the prior of the column scales ([`OnlineOptions::prior`], else the batch
    /// estimate), as in flight.
    #[default]
    Prior,
    /// From θ = 0: every parameter has to come from the data (see the [module docs](self)).
    Zero,
}

impl Default for OnlineOptions {
    fn default() -> Self {
        Self {
            stride: WINDOW_FRAMES,
            prior: None,
            arm_length: SafetyGate::crazyflie().max_com_offset,
            start: OnlineStart::default(),
        }
    }
}

/// Summary of the online pass. Parameters are in the order of
/// [`InertialParams`] (docs/CONVENTIONS.md §1: `m` \[kg\], `h` \[kg m\], `I` about the body
/// origin \[kg m²\]).
#[derive(Debug, Clone, Serialize)]
pub struct OnlineSummary {
    /// Windows processed (TAG-K updates).
    pub updates: usize,
    /// Samples per window.
    pub window_frames: usize,
    /// Samples between the last samples of two consecutive windows.
    pub stride: usize,
    /// The wrench channels fed, by name (`fz`, `tx`, `ty`, `tz`).
    pub rows: Vec<String>,
    /// Noise `σ_c` of each channel in [`OnlineSummary::rows`] (same order), in the channel's
    /// unit (N, N m): the batch fit's residual RMS. Each row is divided by it.
    pub row_noise: Vec<f64>,
    /// Column scales `d_j` (units of θ): the estimator estimates `θ_j / d_j`.
    pub column_scales: [f64; 10],
    /// Where the prior (the column scales' and, from the prior, the start) comes from:
    /// `"batch estimate"` or `"given prior"` ([`OnlineOptions::prior`]).
    pub prior_from: String,
    /// Where TAG-K started: `"prior"` or `"zero"` ([`OnlineStart`]).
    pub start: String,
    /// The initial estimate.
    pub initial_estimate: [f64; 10],
    /// The effects whose fitted part was removed from the measured wrench before the rows were
    /// formed (the model's effects; empty for the rigid body).
    pub effects_removed: Vec<String>,
    /// Estimate after the last window.
    pub final_estimate: [f64; 10],
    /// The online result: the mean of the estimates after each window that ends in the second
    /// half of the log (the tail average; the last estimate when no window does).
    pub tail_average: [f64; 10],
    /// The batch least-squares estimate it is compared with (with a known mass, its mass is
    /// the known mass).
    pub batch_estimate: [f64; 10],
    /// `‖tail_average − batch‖ / ‖batch‖` over the ten parameters (relative, dimensionless;
    /// the mass dominates the norm).
    pub distance_to_batch: f64,
    /// `(m_tail − m_batch) / m_batch` (relative, signed: negative when the online mass is
    /// lower).
    pub mass_error_to_batch: f64,
    /// `(m_final − m_batch) / m_batch` for the last window's estimate (relative, signed).
    pub final_mass_error_to_batch: f64,
    /// Mass estimate after each update \[kg\] (for plots).
    pub mass_history: Vec<f64>,
}

/// [`online_pass_with`] with the default options and windows every `stride` samples.
///
/// # Errors
/// As [`online_pass_with`].
pub fn online_pass(s: &Signals, fit: &Fit, stride: usize) -> Result<OnlineSummary, DiagnoseError> {
    online_pass_with(
        s,
        fit,
        &OnlineOptions {
            stride,
            ..OnlineOptions::default()
        },
    )
}

/// Runs TAG-K behind the tuned front end over the log (see the [module docs](self)): windows
/// of [`WINDOW_FRAMES`] samples every `options.stride` samples, the `f_z` and torque rows, the
/// effects of `fit` removed from the measured wrench, rows divided by the channel noise of
/// `fit`'s residual, columns scaled by a prior, the noise-aware stop. `fit` must be a fit of
/// the model on these signals ([`Model::fit`](crate::Model::fit),
/// [`fit_model`](crate::fit_model)).
///
/// An update the estimator rejects leaves its estimate as it was (tagk-core's
/// [`FrontEnd::update_weighted`]); the pass then stops with the error.
///
/// # Errors
/// [`DiagnoseError::InvalidOption`] for a zero `stride` (field `stride`), signals whose series
/// differ in length (`signals`), an arm length that
/// is not positive and finite (`arm_length`), a prior whose mass or inertia diagonal is zero
/// or not finite (`prior`), or a fit made on other signals (`fit`: its prediction or
/// residual does not have one row per sample); [`DiagnoseError::OnlineTooShort`] for a log
/// shorter than one window; [`DiagnoseError::Online`] if the estimator cannot be built or
/// rejects a window.
pub fn online_pass_with(
    s: &Signals,
    fit: &Fit,
    options: &OnlineOptions,
) -> Result<OnlineSummary, DiagnoseError> {
    let stride = options.stride;
    if stride == 0 {
        return Err(DiagnoseError::InvalidOption {
            field: "stride",
            reason: "0 samples between windows: the stride must be at least 1".into(),
        });
    }
    if !(options.arm_length > 0.0 && options.arm_length.is_finite()) {
        return Err(DiagnoseError::InvalidOption {
            field: "arm_length",
            reason: format!(
                "{} m: the arm length must be positive and finite",
                options.arm_length
            ),
        });
    }
    let n = s.len();
    if n < WINDOW_FRAMES {
        return Err(DiagnoseError::OnlineTooShort {
            samples: n,
            needed: WINDOW_FRAMES,
        });
    }
    if s.accel_proper.len() != n || s.log().len() != n {
        return Err(DiagnoseError::InvalidOption {
            field: "signals",
            reason: format!(
                "{n} time stamps, {} accelerations and {} log samples: the signals were \
                 changed after they were derived",
                s.accel_proper.len(),
                s.log().len()
            ),
        });
    }
    if fit.predicted.len() != n || fit.residual.len() != n {
        return Err(DiagnoseError::InvalidOption {
            field: "fit",
            reason: format!(
                "the fit has {} predicted and {} residual rows for a log of {n} samples: \
                 it was not made on these signals",
                fit.predicted.len(),
                fit.residual.len()
            ),
        });
    }
    let batch = fit.theta.to_array();
    let (prior, prior_from) = match &options.prior {
        Some(p) => (*p, "given prior"),
        None => (fit.theta, "batch estimate"),
    };
    let scales = column_scales(&prior, options.arm_length);
    if scales.iter().any(|d| !(*d > 0.0 && d.is_finite())) {
        return Err(DiagnoseError::InvalidOption {
            field: "prior",
            reason: format!(
                "the {prior_from} (mass {} kg, inertia diagonal {:?} kg m²) gives column \
                 scales {scales:?}: the mass must be finite and not zero, the inertia diagonal \
                 finite and not all zero",
                prior.mass(),
                [
                    prior.as_slice()[4],
                    prior.as_slice()[6],
                    prior.as_slice()[9]
                ],
            ),
        });
    }
    // The channel noise: the batch fit's residual RMS, floored as its channel weights are.
    let weights = weights_from_residual(&fit.residual);
    let row_noise: Vec<f64> = ACTUATED_CHANNELS
        .iter()
        .map(|&c| 1.0 / weights[c])
        .collect();

    let m_max = ROWS_PER_FRAME * WINDOW_FRAMES;
    let config = FrontEndConfig {
        // Rows divided by their channel's noise: unit noise per row.
        row_noise: 1.0,
        stop_multiple: STOP_MULTIPLE,
        event_multiple: 0.0,
        block_rows: ROWS_PER_FRAME,
        average_horizon: 0,
    };
    let tagk = TagK::<f64, Vec<f64>>::new(10, m_max, KaczmarzConfig::default())
        .map_err(|e| DiagnoseError::Online(e.to_string()))?;
    let mut est =
        FrontEnd::new(tagk, &scales, config).map_err(|e| DiagnoseError::Online(e.to_string()))?;
    let initial_estimate = match options.start {
        OnlineStart::Prior => prior.to_array(),
        OnlineStart::Zero => [0.0; 10],
    };
    est.reset(&initial_estimate)
        .map_err(|e| DiagnoseError::Online(e.to_string()))?;

    let target = s.target();
    // The rigid regressor's entries from the signals' cache when the fit filled it (the same
    // values; the entries it leaves empty are the regressor's zeros).
    let cache = s.rigid_cache_if_computed();
    let mut a = vec![0.0; m_max * 10];
    let mut b = vec![0.0; m_max];
    let mut y = [0.0; 60];
    let mut updates = 0;
    let mut tail = [0.0; 10];
    let mut tail_n = 0usize;
    let mut mass_history = Vec::with_capacity((n - WINDOW_FRAMES) / stride + 1);
    let mut end = WINDOW_FRAMES;
    while end <= n {
        for (f, i) in (end - WINDOW_FRAMES..end).enumerate() {
            match cache {
                Some(rows) => {
                    for &c in &ACTUATED_CHANNELS {
                        for q in 10 * c..10 * c + 10 {
                            y[q] = rows[q].get(i).copied().unwrap_or(0.0);
                        }
                    }
                }
                None => {
                    // Infallible: the buffer has 60 entries.
                    let _ = write_rigid_body_regressor(
                        &s.accel_proper[i],
                        &s.omega(i),
                        &s.omega_dot(i),
                        &mut y,
                    );
                }
            }
            for (k, &c) in ACTUATED_CHANNELS.iter().enumerate() {
                let r = ROWS_PER_FRAME * f + k;
                let yc = &y[10 * c..10 * c + 10];
                // The fitted effects' part of this channel: ŷ − Y θ̂.
                let rigid: f64 = yc.iter().zip(&batch).map(|(y, t)| y * t).sum();
                let effects = fit.predicted[i][c] - rigid;
                let w = weights[c];
                for (dst, v) in a[r * 10..r * 10 + 10].iter_mut().zip(yc) {
                    *dst = v * w;
                }
                b[r] = (target[i][c] - effects) * w;
            }
        }
        est.update(&a, &b).map_err(|e| {
            DiagnoseError::Online(format!(
                "window {} (samples {}..{end}): {e}",
                updates + 1,
                end - WINDOW_FRAMES
            ))
        })?;
        updates += 1;
        let th = est.estimate();
        mass_history.push(th[0]);
        if 2 * end > n {
            for (t, x) in tail.iter_mut().zip(th) {
                *t += x;
            }
            tail_n += 1;
        }
        end += stride;
    }
    let final_estimate: [f64; 10] = std::array::from_fn(|j| est.estimate()[j]);
    // No window ends in the second half only when the stride skips it: the last estimate.
    let tail_average: [f64; 10] = if tail_n > 0 {
        tail.map(|t| t / tail_n as f64)
    } else {
        final_estimate
    };
    let nb = batch.iter().map(|x| x * x).sum::<f64>().sqrt();
    let d = tail_average
        .iter()
        .zip(&batch)
        .map(|(a, b)| (a - b).powi(2))
        .sum::<f64>()
        .sqrt();
    let relative = |x: f64, reference: f64| {
        if reference != 0.0 {
            (x - reference) / reference.abs()
        } else {
            x - reference
        }
    };
    Ok(OnlineSummary {
        updates,
        window_frames: WINDOW_FRAMES,
        stride,
        rows: ACTUATED_CHANNELS
            .iter()
            .map(|&c| CHANNEL_NAMES[c].to_string())
            .collect(),
        row_noise,
        column_scales: scales,
        prior_from: prior_from.to_string(),
        start: match options.start {
            OnlineStart::Prior => "prior",
            OnlineStart::Zero => "zero",
        }
        .to_string(),
        initial_estimate,
        effects_removed: fit.effects.iter().map(|e| e.effect.clone()).collect(),
        final_estimate,
        tail_average,
        batch_estimate: batch,
        distance_to_batch: if nb > 0.0 { d / nb } else { d },
        mass_error_to_batch: relative(tail_average[0], batch[0]),
        final_mass_error_to_batch: relative(final_estimate[0], batch[0]),
        mass_history,
    })
}
