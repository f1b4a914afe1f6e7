//! The estimators compared in the experiments, built by name.

use serde::{Deserialize, Serialize};
use tagk_baselines::{KalmanFilter, Rls};
use tagk_core::{
    BurnIn, GreedyKaczmarz, KaczmarzConfig, OnlineEstimator, RandomizedKaczmarz, TagK,
    TailAveragedKaczmarz,
};

use crate::SimError;

/// Parameter dimension of one rigid body.
pub(crate) const N_PARAMS: usize = 10;

/// The estimator algorithms with the TAG-K paper's settings: one list for the whole
/// workspace, defined with the presets in `tagk-baselines`.
pub use tagk_baselines::EstimatorKind;

/// An estimator with its experiment options.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct EstimatorSpec {
    /// Algorithm.
    pub kind: EstimatorKind,
    /// Burn-in fraction `t_b / T` of the tail-averaged Kaczmarz variants (ignored otherwise).
    pub burn_in: f64,
    /// Fig. 4a's "early adaptation": TAG-K runs alongside, and the first update after each
    /// payload event takes TAG-K's estimate instead (the estimator is
    /// [`reset`](OnlineEstimator::reset) to it, covariance back to `P₀`).
    pub early_tagk: bool,
    /// Column equilibration: the estimator sees the window `A D` and estimates `D⁻¹θ`, with
    /// `D = diag(m₀, m₀L, m₀L, m₀L, ī, …, ī)` from the nominal mass `m₀`, `L = L_arm` and
    /// `ī = tr(I₀)/3` (see `column_scales`). The paper's estimators work in SI units
    /// (`false`).
    pub scaled: bool,
    /// Noise-aware stopping of the Kaczmarz variants, as a multiple `κ` of the expected
    /// noise floor of the window's residual: iterations stop once
    /// `‖b − A x‖₂ ≤ κ · m₀ σ_a √(3k)` (the force rows' share of accelerometer noise,
    /// `k` frames; see `noise_floor`). `0` (the default) never stops early.
    pub noise_tolerance: f64,
    /// Feed only the actuated rows (`f_z`, `τ`) of each frame: the lateral force rows, whose
    /// measurement is identically zero for a quadrotor (`b_x = b_y = 0`) and whose regressor
    /// `[a_x, (S(ω̇) + S(ω)²)_x, 0]` is nearly zero in smooth flight, are zeroed (estimators
    /// skip zero rows). Kaczmarz projects onto each chosen row exactly, so these weak rows turn
    /// accelerometer noise into first-moment errors with gain `m / ‖ω̇‖`; see the README.
    pub actuated_rows_only: bool,
}

/// Expected norm of the residual `b − A θ` at the true `θ` caused by accelerometer noise of
/// standard deviation `sigma_accel` [m/s²] on a window of `frames` frames of a body of mass
/// `mass` \[kg\]: each of the `3·frames` force rows carries `m·n` with `n ~ N(0, σ_a²)` \[N\].
pub(crate) fn noise_floor(mass: f64, sigma_accel: f64, frames: usize) -> f64 {
    mass * sigma_accel * ((3 * frames) as f64).sqrt()
}

/// The column scales `D` of [`EstimatorSpec::scaled`] for nominal parameters `nominal` (the order
/// of θ, docs/CONVENTIONS.md §1) and arm length `arm` \[m\]: typical magnitudes of each parameter,
/// so that every column of `A D` has the units of the measurement.
pub(crate) fn column_scales(nominal: &[f64; 10], arm: f64) -> [f64; 10] {
    let m = nominal[0];
    let i = (nominal[4] + nominal[6] + nominal[9]) / 3.0;
    [m, m * arm, m * arm, m * arm, i, i, i, i, i, i]
}

/// The default TAG-K burn-in fraction (see the crate README's burn-in study).
pub const DEFAULT_BURN_IN: f64 = 0.5;

impl EstimatorSpec {
    /// `kind` with the default burn-in and no early adaptation.
    pub fn new(kind: EstimatorKind) -> Self {
        Self {
            kind,
            burn_in: DEFAULT_BURN_IN,
            early_tagk: false,
            scaled: false,
            noise_tolerance: 0.0,
            actuated_rows_only: false,
        }
    }

    /// Feeds only the actuated rows ([`EstimatorSpec::actuated_rows_only`]).
    pub fn with_actuated_rows_only(mut self) -> Self {
        self.actuated_rows_only = true;
        self
    }

    /// Sets the noise-aware stopping multiple ([`EstimatorSpec::noise_tolerance`]).
    pub fn with_noise_tolerance(mut self, kappa: f64) -> Self {
        self.noise_tolerance = kappa;
        self
    }

    /// Turns on column equilibration ([`EstimatorSpec::scaled`]).
    pub fn with_scaling(mut self) -> Self {
        self.scaled = true;
        self
    }

    /// Sets the burn-in fraction.
    pub fn with_burn_in(mut self, burn_in: f64) -> Self {
        self.burn_in = burn_in;
        self
    }

    /// Turns on early adaptation.
    pub fn with_early_tagk(mut self) -> Self {
        self.early_tagk = true;
        self
    }

    /// Label for tables: the name, with the burn-in for non-default TAG-K/TARK and a `+TAG-K`
    /// suffix for early adaptation.
    pub fn label(&self) -> String {
        let mut s = self.kind.name().to_string();
        if matches!(self.kind, EstimatorKind::TagK | EstimatorKind::Tark)
            && (self.burn_in - DEFAULT_BURN_IN).abs() > 1e-12
        {
            s.push_str(&format!(" (t_b={:.2}T)", self.burn_in));
        }
        let mut options = Vec::new();
        if self.scaled {
            options.push("scaled".to_string());
        }
        if self.noise_tolerance > 0.0 && self.kind.is_kaczmarz() {
            options.push(format!("tol {}σ", self.noise_tolerance));
        }
        if self.actuated_rows_only {
            options.push("fz+τ rows".to_string());
        }
        if !options.is_empty() {
            s.push_str(&format!(" ({})", options.join(", ")));
        }
        if self.early_tagk {
            s.push_str(" +TAG-K");
        }
        s
    }

    /// Builds the estimator for windows of at most `m_max` rows, seeded with `seed`
    /// (Kaczmarz variants), with residual tolerance `tolerance` (Kaczmarz variants,
    /// measurement units), initial estimate zero (callers reset it to the prior).
    ///
    /// # Errors
    /// [`SimError::EstimatorConfig`] for a burn-in outside `[0, 1)`, `m_max = 0` or a bad
    /// tolerance.
    pub fn build(
        &self,
        m_max: usize,
        seed: u64,
        tolerance: f64,
    ) -> Result<Box<dyn OnlineEstimator<f64> + Send>, SimError> {
        build_kind(self.kind, N_PARAMS, self.burn_in, m_max, seed, tolerance)
    }
}

/// Builds one estimator of dimension `n` (see [`EstimatorSpec::build`]).
///
/// # Errors
/// As [`EstimatorSpec::build`].
pub(crate) fn build_kind(
    kind: EstimatorKind,
    n: usize,
    burn_in: f64,
    m_max: usize,
    seed: u64,
    tolerance: f64,
) -> Result<Box<dyn OnlineEstimator<f64> + Send>, SimError> {
    let cfg = KaczmarzConfig::default()
        .with_seed(seed)
        .with_tolerance(tolerance)
        .with_burn_in(BurnIn::Fraction(burn_in));
    Ok(match kind {
        EstimatorKind::RlsLow => Box::new(Rls::rls_low(n, m_max)?),
        EstimatorKind::RlsHigh => Box::new(Rls::rls_high(n, m_max)?),
        EstimatorKind::KfLow => Box::new(KalmanFilter::kf_low(n, m_max)?),
        EstimatorKind::KfHigh => Box::new(KalmanFilter::kf_high(n, m_max)?),
        EstimatorKind::TagK => Box::new(TagK::<f64, Vec<f64>>::new(n, m_max, cfg)?),
        EstimatorKind::Grk => Box::new(GreedyKaczmarz::<f64, Vec<f64>>::new(n, m_max, cfg)?),
        EstimatorKind::Tark => Box::new(TailAveragedKaczmarz::<f64, Vec<f64>>::new(n, m_max, cfg)?),
        EstimatorKind::Rk => Box::new(RandomizedKaczmarz::<f64, Vec<f64>>::new(n, m_max, cfg)?),
    })
}

/// The TAG-K variant this crate recommends: column-equilibrated windows, noise-aware
/// stopping at 3σ and only the actuated rows (see the README's study).
pub fn tagk_tuned() -> EstimatorSpec {
    tuned(EstimatorKind::TagK)
}

/// [`tagk_tuned`]'s options applied to any estimator kind.
pub fn tuned(kind: EstimatorKind) -> EstimatorSpec {
    EstimatorSpec::new(kind)
        .with_scaling()
        .with_noise_tolerance(3.0)
        .with_actuated_rows_only()
}

/// Table II's estimators: the paper's five, plus [`tagk_tuned`].
pub fn table_ii_estimators() -> Vec<EstimatorSpec> {
    let mut v: Vec<EstimatorSpec> = EstimatorKind::TABLE_II
        .iter()
        .map(|k| EstimatorSpec::new(*k))
        .collect();
    v.push(tagk_tuned());
    v
}
