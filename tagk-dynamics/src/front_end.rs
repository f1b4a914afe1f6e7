//! The tuned estimator front end of a rigid body's wrench windows: which rows it feeds, the
//! column scales, the noise-aware stop and the window length.
//!
//! One home for the settings that tagk-core's `FrontEnd` applies on a rigid body (column
//! scaling, row selection, noise-aware stop): the simulator's tuned TAG-K
//! (`tagk_sim::tagk_tuned`) and the diagnosis' online pass (`tagk_diagnose::online_pass`) both
//! read them here. The wrench channels are numbered as in docs/CONVENTIONS.md §3:
//! `0..6` = `f_x, f_y, f_z, τ_x, τ_y, τ_z` (body frame, torques about the body origin).

use crate::InertialParams;

/// Frames (samples) per window: the TAG-K paper's 5. With all six rows a window is 30 × 10;
/// with the [`ACTUATED_CHANNELS`] only it is 20 × 10.
pub const WINDOW_FRAMES: usize = 5;

/// The wrench channels the tuned front end feeds: `f_z, τ_x, τ_y, τ_z`, the ones a
/// quadrotor's rotors command.
///
/// The lateral force rows `f_x`, `f_y` are left out. Their measurement is identically zero for
/// a quadrotor, so every unmodelled horizontal force (drag, wind, a bias) lands in their
/// residual. Their regressor is nearly zero in smooth flight, and a Kaczmarz method projects
/// onto each chosen row exactly: they turn that force and the accelerometer noise into mass
/// and first-moment errors. Without them `h_z` is only weakly observable (through
/// `−(ω_x² + ω_y²) h_z` on `f_z` and the horizontal proper acceleration on the torques).
pub const ACTUATED_CHANNELS: [usize; 4] = [2, 3, 4, 5];

/// `true` if wrench channel `channel` (`0..6`) is one of the [`ACTUATED_CHANNELS`].
pub const fn is_actuated(channel: usize) -> bool {
    let mut k = 0;
    while k < ACTUATED_CHANNELS.len() {
        if ACTUATED_CHANNELS[k] == channel {
            return true;
        }
        k += 1;
    }
    false
}

/// `κ_stop`: an iterative estimator stops a window's iterations once the window's residual
/// norm is at most this many times its noise floor. The floor is the expected norm of the
/// residual at the true parameters: `σ √rows` for rows of noise `σ`. 3 is about the 99.9 %
/// point of the noise's norm on large windows; projecting further would fit the noise.
pub const STOP_MULTIPLE: f64 = 3.0;

/// The column scales `d` of a prior guess `prior` of θ (docs/CONVENTIONS.md §1).
///
/// `arm` \[m\] is the body's characteristic length: the arm offset `L_arm`, the largest
/// admissible centre-of-mass offset. The scales are `[m, m L, m L, m L, ī, ī, ī, ī, ī, ī]`,
/// with `m = |m_prior|` \[kg\], `L = arm` and `ī = (|I_xx| + |I_yy| + |I_zz|) / 3` \[kg m²\].
///
/// These are the typical magnitudes of the parameters. An estimator that sees the columns of
/// `A D` (and estimates `D⁻¹ θ`) then has columns with the units and the order of the
/// measurement: the mass (kg) and the inertia (kg m², five orders smaller) converge alike. The
/// first moment's scale is the largest the safety gate admits (`m L`), since its prior is
/// usually zero.
///
/// A scale is zero (and unusable: tagk-core's `FrontEnd` refuses it) when the prior's mass or
/// its inertia diagonal is zero, or when `arm` is zero; callers check.
pub fn column_scales(prior: &InertialParams, arm: f64) -> [f64; 10] {
    let p = prior.as_slice();
    let m = p[0].abs();
    let i = (p[4].abs() + p[6].abs() + p[9].abs()) / 3.0;
    [m, m * arm, m * arm, m * arm, i, i, i, i, i, i]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn actuated_channels_are_fz_and_the_torques() {
        let actuated: Vec<usize> = (0..6).filter(|c| is_actuated(*c)).collect();
        assert_eq!(actuated, ACTUATED_CHANNELS);
        assert!(!is_actuated(6));
    }

    #[test]
    fn scales_are_the_magnitudes_of_the_parameters() {
        let theta = InertialParams::from_array([
            0.035, 0.0, 0.0, 0.0, 1.6e-5, 1e-6, 1.8e-5, 0.0, 0.0, 2.9e-5,
        ]);
        let d = column_scales(&theta, 0.0325);
        assert_eq!(d[0], 0.035);
        assert!((d[1] - 0.035 * 0.0325).abs() < 1e-18);
        assert!((d[9] - 2.1e-5).abs() < 1e-12);
        // Signs do not matter: a scale is a magnitude.
        let negative = InertialParams::from_array(theta.to_array().map(|x| -x));
        assert_eq!(column_scales(&negative, 0.0325), d);
    }
}
