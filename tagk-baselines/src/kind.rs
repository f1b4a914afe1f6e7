//! The estimators of the TAG-K paper, by name: one list for the firmware harness, the
//! experiments and the benchmarks.

use core::fmt;
use core::str::FromStr;

use crate::{KalmanConfig, RlsConfig};

/// An estimator of the TAG-K paper with the paper's settings.
///
/// The baselines' settings are [`RlsConfig::LOW`]/[`HIGH`](RlsConfig::HIGH) and
/// [`KalmanConfig::LOW`]/[`HIGH`](KalmanConfig::HIGH) (see [`EstimatorKind::rls_config`] and
/// [`EstimatorKind::kalman_config`]); the Kaczmarz family runs
/// [`tagk_paper_config`](tagk_core::tagk_paper_config) (`T = m`, tail average over the last
/// half). Names parse back ([`FromStr`]) from either the display name (`"RLS-low"`, `"TAG-K"`)
/// or the command-line spelling (`"rls-low"`, `"tagk"`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum EstimatorKind {
    /// RLS, `λ = 0.99`, `P₀ = 10³·I` ([`RlsConfig::LOW`]).
    RlsLow,
    /// RLS, `λ = 0.96`, `P₀ = 10³·I` ([`RlsConfig::HIGH`]).
    RlsHigh,
    /// Random-walk Kalman filter, `σ_Q = 10⁻³`, `σ_R = 10⁻⁵`, `P₀ = 10³·I`
    /// ([`KalmanConfig::LOW`]).
    KfLow,
    /// Random-walk Kalman filter, `σ_Q = 10⁻¹`, `σ_R = 10⁻³`, `P₀ = 10³·I`
    /// ([`KalmanConfig::HIGH`]).
    KfHigh,
    /// Tail-averaged greedy Kaczmarz (tagk-core's `TagK`), `T = m`.
    TagK,
    /// Greedy Kaczmarz, no averaging (`GreedyKaczmarz`).
    Grk,
    /// Tail-averaged randomised Kaczmarz (`TailAveragedKaczmarz`).
    Tark,
    /// Randomised Kaczmarz (`RandomizedKaczmarz`).
    Rk,
}

impl EstimatorKind {
    /// Every kind, baselines first.
    pub const ALL: [Self; 8] = [
        Self::RlsLow,
        Self::RlsHigh,
        Self::KfLow,
        Self::KfHigh,
        Self::TagK,
        Self::Grk,
        Self::Tark,
        Self::Rk,
    ];
    /// The five estimators of the paper's Table II, in its order.
    pub const TABLE_II: [Self; 5] = [
        Self::RlsLow,
        Self::RlsHigh,
        Self::KfLow,
        Self::KfHigh,
        Self::TagK,
    ];
    /// The Kaczmarz family of the ablation (Fig. 4b).
    pub const KACZMARZ: [Self; 4] = [Self::Rk, Self::Tark, Self::Grk, Self::TagK];

    /// Display name, as in the paper (and the built estimator's `name()`).
    pub const fn name(self) -> &'static str {
        match self {
            Self::RlsLow => "RLS-low",
            Self::RlsHigh => "RLS-high",
            Self::KfLow => "KF-low",
            Self::KfHigh => "KF-high",
            Self::TagK => "TAG-K",
            Self::Grk => "GRK",
            Self::Tark => "TARK",
            Self::Rk => "RK",
        }
    }

    /// Command-line spelling: lower-case, `-` separated (`"rls-low"`, `"tagk"`).
    pub const fn cli_name(self) -> &'static str {
        match self {
            Self::RlsLow => "rls-low",
            Self::RlsHigh => "rls-high",
            Self::KfLow => "kf-low",
            Self::KfHigh => "kf-high",
            Self::TagK => "tagk",
            Self::Grk => "grk",
            Self::Tark => "tark",
            Self::Rk => "rk",
        }
    }

    /// `true` for the Kaczmarz family (seeded, with a burn-in), `false` for RLS and the KF.
    pub const fn is_kaczmarz(self) -> bool {
        matches!(self, Self::TagK | Self::Grk | Self::Tark | Self::Rk)
    }

    /// The RLS preset of an RLS kind.
    pub const fn rls_config(self) -> Option<RlsConfig> {
        match self {
            Self::RlsLow => Some(RlsConfig::LOW),
            Self::RlsHigh => Some(RlsConfig::HIGH),
            _ => None,
        }
    }

    /// The Kalman filter preset of a KF kind.
    pub const fn kalman_config(self) -> Option<KalmanConfig> {
        match self {
            Self::KfLow => Some(KalmanConfig::LOW),
            Self::KfHigh => Some(KalmanConfig::HIGH),
            _ => None,
        }
    }
}

impl fmt::Display for EstimatorKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A name that is no [`EstimatorKind`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error(
    "unknown estimator name (expected one of rls-low, rls-high, kf-low, kf-high, tagk, grk, tark, rk)"
)]
#[non_exhaustive]
pub struct UnknownEstimator;

impl FromStr for EstimatorKind {
    type Err = UnknownEstimator;

    /// Parses [`EstimatorKind::name`] or [`EstimatorKind::cli_name`], ignoring ASCII case.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Self::ALL
            .into_iter()
            .find(|k| s.eq_ignore_ascii_case(k.name()) || s.eq_ignore_ascii_case(k.cli_name()))
            .ok_or(UnknownEstimator)
    }
}
