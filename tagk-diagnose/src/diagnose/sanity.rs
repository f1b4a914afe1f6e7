//! Physical sanity of a candidate's refit, judged against the current model's fit: a
//! candidate that "explains" the data by destroying the rigid body is not physics.
//!
//! The rules (each names itself in the report):
//!
//! | rule | fires when |
//! |---|---|
//! | `mass-positive` | the refit mass is not positive |
//! | `mass-change` | the refit mass differs from the current fit's by more than [`MAX_MASS_CHANGE`] |
//! | `com-outside` | the refit centre of mass lies outside the airframe radius and farther out than the current fit's |
//! | `consistency-lost` | the current fit is physically consistent (pseudo-inertia positive definite) and the refit is not |
//! | `force-of-thrust-order` | a fitted constant force (unit `N`, not a start-of-log nuisance) exceeds [`MAX_CONSTANT_FORCE_OF_THRUST`] of the mean thrust |
//!
//! Consistency is judged relative to the current fit because some real vehicles' published
//! inertias violate the triangle inequality: a refit is only blamed for what it breaks.
//! The effects' own rules (negative drag, a lag or delay at the end of its physical scan
//! range, a lag or delay gain far from 1) come from [`crate::Effect::plausibility`].

use tagk_dynamics::InertialParams;

use crate::fit::{Coefficient, Fit};

/// Largest relative change of the mass a candidate's refit may make (25 %): a payload is
/// picked up or dropped between flights, not explained away by an aerodynamic term.
pub const MAX_MASS_CHANGE: f64 = 0.25;

/// Largest constant force a candidate may fit, as a fraction of the mean thrust (25 %): a
/// constant force of the order of the thrust is a collapsed rigid body, not a bias.
pub const MAX_CONSTANT_FORCE_OF_THRUST: f64 = 0.25;

/// `true` when a refit's mass `m1` \[kg\] keeps the rigid body: positive, and within
/// [`MAX_MASS_CHANGE`] of the current fit's `m0` (any `m1 > 0` when `m0` is not positive).
pub(crate) fn mass_kept(m0: f64, m1: f64) -> bool {
    m1 > 0.0 && (m0 <= 0.0 || ((m1 - m0) / m0).abs() <= MAX_MASS_CHANGE)
}

/// What the refit rules need besides the candidate.
pub(crate) struct SanityContext<'a> {
    /// The current model's fit.
    pub fit: &'a Fit,
    /// Mean collective thrust of the log \[N\] (mean of the measured `fz`).
    pub mean_thrust: f64,
    /// Airframe radius \[m\].
    pub airframe_radius: f64,
    /// `true` when the model's mass is known (fixed): the refit then has nine rigid columns.
    pub known_mass: bool,
}

/// A fired rule: its name and the sentence the report prints.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Violation {
    /// Rule name (table above).
    pub rule: &'static str,
    /// What happened, with the numbers.
    pub note: String,
}

/// The rigid-body parameters after a candidate's refit: the current fit's plus the deltas
/// `delta` (the refit's first 10 — 9 with a known mass — coefficients).
pub(crate) fn refit_theta(ctx: &SanityContext<'_>, delta: &[f64]) -> InertialParams {
    let mut theta = ctx.fit.theta.to_array();
    let offset = usize::from(ctx.known_mass);
    for (k, d) in delta.iter().enumerate().take(10 - offset) {
        theta[k + offset] += d;
    }
    InertialParams::from_array(theta)
}

/// The first rule a refit breaks, if any (`coefficients`: the candidate's own fitted
/// coefficients).
pub(crate) fn check_refit(
    ctx: &SanityContext<'_>,
    delta: &[f64],
    coefficients: &[Coefficient],
) -> Option<Violation> {
    let base = ctx.fit.theta;
    let refit = refit_theta(ctx, delta);
    let (m0, m1) = (base.mass(), refit.mass());
    if m1 <= 0.0 {
        return Some(Violation {
            rule: "mass-positive",
            note: format!("the refit mass {m1:.4} kg is not positive (current fit {m0:.4} kg)"),
        });
    }
    if m0 > 0.0 && ((m1 - m0) / m0).abs() > MAX_MASS_CHANGE {
        return Some(Violation {
            rule: "mass-change",
            note: format!(
                "the refit mass {m1:.4} kg is {:+.0} % off the current fit's {m0:.4} kg (limit ±{:.0} %)",
                100.0 * (m1 - m0) / m0,
                100.0 * MAX_MASS_CHANGE
            ),
        });
    }
    let com1 = refit.first_moment() / m1;
    let com0 = if m0 > 0.0 {
        base.first_moment() / m0
    } else {
        nalgebra::Vector3::zeros()
    };
    if com1.norm() > ctx.airframe_radius && com1.norm() > com0.norm() {
        return Some(Violation {
            rule: "com-outside",
            note: format!(
                "the refit centre of mass is {:.1} cm from the origin, outside the airframe radius {:.1} cm (current fit {:.1} cm)",
                100.0 * com1.norm(),
                100.0 * ctx.airframe_radius,
                100.0 * com0.norm()
            ),
        });
    }
    if base.is_physically_consistent() && !refit.is_physically_consistent() {
        return Some(Violation {
            rule: "consistency-lost",
            note: "the refit's pseudo-inertia is not positive definite, the current fit's is"
                .into(),
        });
    }
    let limit = MAX_CONSTANT_FORCE_OF_THRUST * ctx.mean_thrust.abs();
    if let Some(c) = coefficients
        .iter()
        .find(|c| c.unit == "N" && !c.name.starts_with("start_") && c.value.abs() > limit)
    {
        return Some(Violation {
            rule: "force-of-thrust-order",
            note: format!(
                "the constant force {} = {:.3e} N is of the order of the thrust ({:.3e} N mean; limit {:.0} %)",
                c.name,
                c.value,
                ctx.mean_thrust,
                100.0 * MAX_CONSTANT_FORCE_OF_THRUST
            ),
        });
    }
    None
}
