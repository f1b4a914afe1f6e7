//! Physical sanity of a fit: a candidate that "explains" the data by destroying the rigid
//! body is not physics, and a final model with an unphysical rigid body is not trusted.
//!
//! The rules (each names itself in the report):
//!
//! | rule | fires when |
//! |---|---|
//! | `mass-positive` | the refit mass is not positive |
//! | `mass-change` | the refit mass differs from the current fit's by more than [`MAX_MASS_CHANGE`] |
//! | `com-outside` | the refit centre of mass lies outside the airframe (more than 2 standard errors beyond the arm length horizontally, or beyond [`crate::DiagnoseOptions::com_vertical_limit`] from the rotor plane), farther out than the current fit's |
//! | `consistency-lost` | the refit's pseudo-inertia is not positive definite beyond the tolerance ([`CONSISTENCY_TOLERANCE`]) and significantly ([`INCONSISTENCY_STANDARD_ERRORS`]), and the current fit's is within the tolerance |
//! | `force-of-thrust-order` | a fitted constant force (unit `N`, not a start-of-log nuisance) exceeds [`MAX_CONSTANT_FORCE_OF_THRUST`] of the mean thrust |
//!
//! **Consistency with a tolerance.** The pseudo-inertia `J = [[Σ, h], [hᵀ, m]]` (`Σ` the
//! second moment of the mass, `½ tr(I) 1 − I`) is scaled to unit diagonal scale — `Σ` by its
//! mean eigenvalue, `m` by itself — and its smallest eigenvalue is the **consistency margin**:
//! positive for a realisable body, zero for a body flat as a plate. A near-planar quadrotor
//! sits at the triangle inequality's limit (`I_zz ≈ I_xx + I_yy`), so noise alone can push its
//! margin slightly negative: a margin above `−CONSISTENCY_TOLERANCE` counts as consistent.
//! The effects' own rules (negative drag, a lag or delay gain far from 1) come from
//! [`crate::Effect::plausibility`]; a scanned parameter at the end of its range is refused by
//! the search as out of the range the data support.

use nalgebra::{Matrix4, SymmetricEigen, Vector3};
use tagk_dynamics::InertialParams;

/// Largest relative change of the mass a candidate's refit may make (25 %): a payload is
/// picked up or dropped between flights, not explained away by an aerodynamic term.
pub const MAX_MASS_CHANGE: f64 = 0.25;

/// Largest constant force a candidate may fit, as a fraction of the mean thrust (25 %): a
/// constant force of the order of the thrust is a collapsed rigid body, not a bias.
pub const MAX_CONSTANT_FORCE_OF_THRUST: f64 = 0.25;

/// Tolerance of the consistency margin (module docs): 5 % of the mean second moment.
pub const CONSISTENCY_TOLERANCE: f64 = 0.05;

/// A refit's pseudo-inertia counts as inconsistent only when the smallest eigenvalue of its
/// second moment about the centre of mass ([`second_moment_eigen`]) lies more than this many
/// standard errors below zero (3: as a drag coefficient is significantly negative).
pub const INCONSISTENCY_STANDARD_ERRORS: f64 = 3.0;

/// Largest difference between the fitted mass and the vehicle file's before the report says
/// so (25 %): a payload, or a wrong thrust coefficient.
pub const MAX_MASS_FROM_VEHICLE: f64 = 0.25;

/// The airframe and vehicle limits a fit is judged against.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Limits {
    /// Largest horizontal distance of the centre of mass from the body origin \[m\].
    pub airframe_radius: f64,
    /// Largest vertical distance of the centre of mass from the rotor plane \[m\].
    pub com_vertical: f64,
    /// Height of the rotor plane in the body frame (body z, up) \[m\].
    pub rotor_plane: f64,
    /// `true` when the mass is known (fixed): it cannot change.
    pub known_mass: bool,
}

/// A fired rule: its name and the sentence the report prints.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Violation {
    /// Rule name (table above, or an effect's own).
    pub rule: String,
    /// What happened, with the numbers.
    pub note: String,
}

/// The consistency margin of θ (module docs): the smallest eigenvalue of the scaled
/// pseudo-inertia; `−∞` for a non-finite θ or a non-positive mass or second moment.
pub fn consistency_margin(theta: &InertialParams) -> f64 {
    if !theta.is_finite() || theta.mass() <= 0.0 {
        return f64::NEG_INFINITY;
    }
    let j: Matrix4<f64> = theta.pseudo_inertia();
    let sigma_mean = (j[(0, 0)] + j[(1, 1)] + j[(2, 2)]) / 3.0;
    if sigma_mean <= 0.0 {
        return f64::NEG_INFINITY;
    }
    let d = [
        sigma_mean.sqrt(),
        sigma_mean.sqrt(),
        sigma_mean.sqrt(),
        j[(3, 3)].sqrt(),
    ];
    let scaled = Matrix4::from_fn(|r, c| j[(r, c)] / (d[r] * d[c]));
    scaled.symmetric_eigenvalues().min()
}

/// `true` when θ is consistent within [`CONSISTENCY_TOLERANCE`].
pub fn consistent_within_tolerance(theta: &InertialParams) -> bool {
    consistency_margin(theta) >= -CONSISTENCY_TOLERANCE
}

/// How far the centre of mass of θ lies outside the airframe, in standard errors beyond the
/// limits (`theta_se`: standard errors of θ's entries): `(horizontal, vertical)` excess \[m\]
/// after subtracting 2 standard errors (≤ 0 inside).
pub(crate) fn com_excess(
    limits: &Limits,
    theta: &InertialParams,
    theta_se: &[f64; 10],
) -> (f64, f64) {
    let m = theta.mass();
    if m <= 0.0 {
        return (0.0, 0.0);
    }
    let c: Vector3<f64> = theta.first_moment() / m;
    let se = |k: usize| theta_se[1 + k] / m;
    let horizontal = (c.x * c.x + c.y * c.y).sqrt();
    let h_se = (se(0).powi(2) + se(1).powi(2)).sqrt();
    let vertical = (c.z - limits.rotor_plane).abs();
    (
        horizontal - 2.0 * h_se - limits.airframe_radius,
        vertical - 2.0 * se(2) - limits.com_vertical,
    )
}

/// The smallest eigenvalue `λ` of `Σ_c = ½ tr(I) 1 − I − h hᵀ/m` \[kg m²\] for the parameters
/// `theta` (`m > 0`) and its standard error from the parameters' standard errors `se`
/// (`InertialParams` order, independent; `∂λ/∂θ = vᵀ (∂Σ_c/∂θ) v` at its unit eigenvector `v`).
/// `½ tr(I) 1 − I` is the pseudo-inertia's upper-left block.
pub fn second_moment_eigen(theta: &InertialParams, se: &[f64]) -> Option<(f64, f64)> {
    let m = theta.mass();
    let h = theta.first_moment();
    let sigma = theta.pseudo_inertia().fixed_view::<3, 3>(0, 0) - h * h.transpose() / m;
    let eig = SymmetricEigen::new(sigma);
    let k = eig.eigenvalues.imin();
    let lambda = eig.eigenvalues[k];
    let v = eig.eigenvectors.column(k).into_owned();
    let vh = v.dot(&h);
    let gradient = [
        vh * vh / (m * m),
        -2.0 * vh * v.x / m,
        -2.0 * vh * v.y / m,
        -2.0 * vh * v.z / m,
        0.5 - v.x * v.x,
        -2.0 * v.x * v.y,
        0.5 - v.y * v.y,
        -2.0 * v.x * v.z,
        -2.0 * v.y * v.z,
        0.5 - v.z * v.z,
    ];
    let var: f64 = gradient.iter().zip(se).map(|(g, s)| (g * s).powi(2)).sum();
    lambda.is_finite().then_some((lambda, var.sqrt()))
}

/// The first rule a refit θ (`theta_se` its standard errors) breaks against the current
/// fit's rigid body `current`, if any; `coefficients` are the candidate's own (name, unit,
/// value), `mean_thrust` the mean measured thrust \[N\].
pub(crate) fn rigid_violation(
    limits: &Limits,
    current: &InertialParams,
    theta: &InertialParams,
    theta_se: &[f64; 10],
    coefficients: &[(String, String, f64)],
    mean_thrust: f64,
) -> Option<Violation> {
    let (m0, m1) = (current.mass(), theta.mass());
    if m1 <= 0.0 {
        return Some(Violation {
            rule: "mass-positive".into(),
            note: format!("the refit mass {m1:.4} kg is not positive (current fit {m0:.4} kg)"),
        });
    }
    if !limits.known_mass && m0 > 0.0 && ((m1 - m0) / m0).abs() > MAX_MASS_CHANGE {
        return Some(Violation {
            rule: "mass-change".into(),
            note: format!(
                "the refit mass {m1:.4} kg is {:+.0} % off the current fit's {m0:.4} kg (limit ±{:.0} %)",
                100.0 * (m1 - m0) / m0,
                100.0 * MAX_MASS_CHANGE
            ),
        });
    }
    let (h1, v1) = com_excess(limits, theta, theta_se);
    let (h0, v0) = com_excess(limits, current, &[0.0; 10]);
    if (h1 > 0.0 && h1 > h0) || (v1 > 0.0 && v1 > v0) {
        let c = theta.first_moment() / m1;
        return Some(Violation {
            rule: "com-outside".into(),
            note: format!(
                "the refit centre of mass ({:.1}, {:.1}, {:.1}) cm lies outside the airframe ({:.1} cm from the axis, {:.1} cm from the rotor plane allowed)",
                100.0 * c.x,
                100.0 * c.y,
                100.0 * c.z,
                100.0 * limits.airframe_radius,
                100.0 * limits.com_vertical
            ),
        });
    }
    // Lost only when the data show it: beyond the tolerance and significantly (an inertia the
    // flight barely excites, or one beside a large unexplained torque, is uncertain enough to
    // cross the limit by chance).
    if consistent_within_tolerance(current)
        && !consistent_within_tolerance(theta)
        && second_moment_eigen(theta, theta_se)
            .is_none_or(|(lambda, se)| lambda < -INCONSISTENCY_STANDARD_ERRORS * se)
    {
        return Some(Violation {
            rule: "consistency-lost".into(),
            note: format!(
                "the refit's pseudo-inertia is not positive definite (consistency margin {:.3}, tolerance −{CONSISTENCY_TOLERANCE}); the current fit's is",
                consistency_margin(theta)
            ),
        });
    }
    let limit = MAX_CONSTANT_FORCE_OF_THRUST * mean_thrust.abs();
    if let Some((name, _, value)) = coefficients
        .iter()
        .find(|(n, u, v)| u == "N" && !crate::fit::is_start_nuisance(n) && v.abs() > limit)
    {
        return Some(Violation {
            rule: "force-of-thrust-order".into(),
            note: format!(
                "the constant force {name} = {value:.3e} N is of the order of the thrust ({mean_thrust:.3e} N mean; limit {:.0} %)",
                100.0 * MAX_CONSTANT_FORCE_OF_THRUST
            ),
        });
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The margin is positive for a solid box, about zero for a thin plate, negative beyond.
    #[test]
    fn the_margin_tells_boxes_from_plates() {
        let solid =
            InertialParams::solid_box(0.035, Vector3::zeros(), Vector3::new(0.09, 0.09, 0.03));
        assert!(consistency_margin(&solid) > 0.05);
        let plate =
            InertialParams::solid_box(0.035, Vector3::zeros(), Vector3::new(0.09, 0.09, 1e-6));
        assert!(consistency_margin(&plate).abs() < 1e-3);
        // A plate whose I_zz exceeds I_xx + I_yy by 2 %: barely inconsistent, within the
        // tolerance; by 40 %: beyond it.
        let mut a = plate.to_array();
        a[9] *= 1.02;
        let slight = InertialParams::from_array(a);
        assert!(!slight.is_physically_consistent());
        assert!(consistent_within_tolerance(&slight));
        a[9] = plate.to_array()[9] * 1.4;
        assert!(!consistent_within_tolerance(&InertialParams::from_array(a)));
    }

    /// The eigenvalue's gradient against central finite differences of the eigenvalue
    /// itself: each parameter's standard error alone gives `|∂λ/∂θ_j| se_j`.
    #[test]
    fn the_second_moments_standard_error_matches_finite_differences() {
        let theta: [f64; 10] = [
            0.035, 1e-5, -2e-5, -3e-5, 1.7e-5, 1e-7, 1.8e-5, -2e-7, 3e-7, 2.9e-5,
        ];
        let lambda = |a: [f64; 10]| {
            let p = InertialParams::from_array(a);
            second_moment_eigen(&p, &[0.0; 10]).unwrap().0
        };
        for j in 0..10 {
            let step = 1e-6 * theta[j].abs().max(1e-9);
            let (mut up, mut down) = (theta, theta);
            up[j] += step;
            down[j] -= step;
            let numeric = (lambda(up) - lambda(down)) / (2.0 * step);
            let mut se = [0.0; 10];
            se[j] = 1.0;
            let (_, analytic) =
                second_moment_eigen(&InertialParams::from_array(theta), &se).unwrap();
            assert!(
                (analytic - numeric.abs()).abs() <= 1e-5 * numeric.abs().max(1e-3),
                "parameter {j}: {analytic} against {numeric}"
            );
        }
    }

    /// A centre of mass 4 cm below the rotor plane of a Crazyflie-sized airframe is outside;
    /// 1 cm below is inside.
    #[test]
    fn a_centre_of_mass_far_below_the_rotors_is_outside() {
        let limits = Limits {
            airframe_radius: 0.0325,
            com_vertical: 0.0163,
            rotor_plane: 0.0,
            known_mass: false,
        };
        let low = InertialParams::from_array([
            0.035, 0.0, 0.0, 0.0, 1.7e-5, 0.0, 1.7e-5, 0.0, 0.0, 2.9e-5,
        ]);
        let mut a = low.to_array();
        a[3] = -0.04 * a[0];
        let (_, v) = com_excess(&limits, &InertialParams::from_array(a), &[0.0; 10]);
        assert!(v > 0.0);
        a[3] = -0.01 * a[0];
        let (h, v) = com_excess(&limits, &InertialParams::from_array(a), &[0.0; 10]);
        assert!(h <= 0.0 && v <= 0.0);
    }
}
