//! Small fixed-size helpers shared by the rigid-body and chain code.

use nalgebra::{Matrix3, Rotation3, Vector3};

/// Skew-symmetric matrix `S(x)` with `S(x) y = x × y`.
#[inline]
pub fn skew(x: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -x.z, x.y, x.z, 0.0, -x.x, -x.y, x.x, 0.0)
}

/// `P(x) = xᵀx·1 − x xᵀ = S(x)ᵀ S(x)`: the inertia of a unit point mass at `x` about the origin.
#[inline]
pub fn parallel_axis(x: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::identity() * x.norm_squared() - x * x.transpose()
}

/// The rotation matrix of URDF fixed-axis roll–pitch–yaw angles: `R = Rz(yaw)·Ry(pitch)·Rx(roll)`.
#[inline]
pub fn rotation_from_rpy(roll: f64, pitch: f64, yaw: f64) -> Matrix3<f64> {
    Rotation3::from_euler_angles(roll, pitch, yaw).into_inner()
}

/// The rotation by `angle` \[rad\] about the unit vector `axis`.
#[inline]
pub fn axis_angle(axis: &Vector3<f64>, angle: f64) -> Matrix3<f64> {
    // Rodrigues: R = c·1 + s·S(a) + (1 − c)·a aᵀ.
    let (s, c) = angle.sin_cos();
    let t = 1.0 - c;
    let (x, y, z) = (axis.x, axis.y, axis.z);
    Matrix3::new(
        c + t * x * x,
        t * x * y - s * z,
        t * x * z + s * y,
        t * x * y + s * z,
        c + t * y * y,
        t * y * z - s * x,
        t * x * z - s * y,
        t * y * z + s * x,
        c + t * z * z,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rpy_matches_composition_of_elementary_rotations() {
        let (r, p, y) = (0.3, -0.7, 1.1);
        let rx = axis_angle(&Vector3::x(), r);
        let ry = axis_angle(&Vector3::y(), p);
        let rz = axis_angle(&Vector3::z(), y);
        let expected = rz * ry * rx;
        assert!((rotation_from_rpy(r, p, y) - expected).abs().max() < 1e-14);
    }

    #[test]
    fn axis_angle_is_exponential_of_skew() {
        let a = Vector3::new(0.3, -0.5, 0.8).normalize();
        let angle = 1.234;
        // exp(S(a)·angle) by its power series.
        let k = skew(&a) * angle;
        let mut term = Matrix3::identity();
        let mut sum = Matrix3::identity();
        for n in 1..40 {
            term = term * k / n as f64;
            sum += term;
        }
        assert!((axis_angle(&a, angle) - sum).amax() < 1e-14);
    }

    #[test]
    fn axis_angle_rotates_perpendicular_vector() {
        let r = axis_angle(&Vector3::z(), std::f64::consts::FRAC_PI_2);
        assert!((r * Vector3::x() - Vector3::y()).norm() < 1e-15);
    }

    #[test]
    fn skew_is_cross_product() {
        let a = Vector3::new(0.1, -2.0, 3.5);
        let b = Vector3::new(-1.2, 0.4, 0.9);
        assert!((skew(&a) * b - a.cross(&b)).norm() < 1e-14);
        assert!((parallel_axis(&a) - skew(&a).transpose() * skew(&a)).norm() < 1e-13);
    }
}
