//! Joint-space reference trajectories: Fourier-series excitation and pick-and-place.

use rand::{Rng, RngExt};

use super::ArmModel;
use crate::SimError;

/// A reference sample: position \[rad\], velocity \[rad/s\] and acceleration \[rad/s²\].
#[derive(Debug, Clone, PartialEq)]
pub struct JointReference {
    /// `q_d` \[rad\].
    pub q: Vec<f64>,
    /// `q̇_d` \[rad/s\].
    pub qd: Vec<f64>,
    /// `q̈_d` \[rad/s²\].
    pub qdd: Vec<f64>,
}

/// A finite Fourier series per joint (Swevers et al. 1997), periodic with period `2π/ω_f`.
///
/// `q_j(t) = q0_j + Σ_l (a_jl sin(l ω_f t) − b_jl cos(l ω_f t)) / (l ω_f)`, `l = 1..=L`.
#[derive(Debug, Clone, PartialEq)]
pub struct FourierTrajectory {
    /// Centre `q0` per joint \[rad\].
    pub q0: Vec<f64>,
    /// Fundamental angular frequency `ω_f` \[rad/s\].
    pub omega: f64,
    /// Sine coefficients `a_jl` \[rad/s\], one row per joint.
    pub a: Vec<Vec<f64>>,
    /// Cosine coefficients `b_jl` \[rad/s\], one row per joint.
    pub b: Vec<Vec<f64>>,
}

/// Samples per period used to scale a random series into the limits.
const SCALE_SAMPLES: usize = 400;

impl FourierTrajectory {
    /// A random excitation for `model`: `harmonics` terms, period `period` \[s\].
    ///
    /// Coefficients are uniform in `[−1, 1]`. Each joint's series is then scaled so that it
    /// stays within `amplitude` rad of the home posture, within 80 % of the distance to its
    /// position limits, and under half its velocity limit.
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] for no harmonics, or a non-positive period or amplitude.
    #[allow(clippy::needless_range_loop)] // j indexes q0, a, b and the limits alike.
    pub fn random<R: Rng + ?Sized>(
        model: &ArmModel,
        harmonics: usize,
        period: f64,
        amplitude: f64,
        rng: &mut R,
    ) -> Result<Self, SimError> {
        if harmonics == 0 {
            return Err(SimError::InvalidParameter {
                name: "harmonics",
                value: 0.0,
                reason: "at least one",
            });
        }
        for (name, v) in [("period", period), ("amplitude", amplitude)] {
            if !(v.is_finite() && v > 0.0) {
                return Err(SimError::InvalidParameter {
                    name,
                    value: v,
                    reason: "positive and finite",
                });
            }
        }
        let n = model.dof();
        let q0 = model.home();
        let omega = std::f64::consts::TAU / period;
        let mut traj = Self {
            q0: q0.clone(),
            omega,
            a: vec![vec![0.0; harmonics]; n],
            b: vec![vec![0.0; harmonics]; n],
        };
        for j in 0..n {
            for l in 0..harmonics {
                traj.a[j][l] = rng.random_range(-1.0..1.0);
                traj.b[j][l] = rng.random_range(-1.0..1.0);
            }
            let (mut dq, mut vmax) = (0.0f64, 0.0f64);
            for k in 0..SCALE_SAMPLES {
                let t = period * k as f64 / SCALE_SAMPLES as f64;
                let (p, v, _) = traj.joint(j, t);
                dq = dq.max((p - q0[j]).abs());
                vmax = vmax.max(v.abs());
            }
            let room = 0.8 * (model.limits.upper[j] - q0[j]).min(q0[j] - model.limits.lower[j]);
            let allowed = amplitude.min(room.max(0.0));
            let scale =
                (allowed / dq.max(1e-12)).min(0.5 * model.limits.velocity[j] / vmax.max(1e-12));
            for l in 0..harmonics {
                traj.a[j][l] *= scale;
                traj.b[j][l] *= scale;
            }
        }
        Ok(traj)
    }

    /// A random excitation of `dof` joints, without a model: `harmonics` harmonics of
    /// `base_hz` \[Hz\], drawn from `seed`.
    ///
    /// Each coefficient is uniform in `±speed / harmonics` \[rad/s\], so no joint's speed
    /// exceeds `2 speed`. The centres are uniform in ±0.5 rad. The joint-torque diagnosis's
    /// logs use it ([`prescribed_log`](super::prescribed_log)).
    pub fn random_with_speed(
        dof: usize,
        harmonics: usize,
        base_hz: f64,
        speed: f64,
        seed: u64,
    ) -> Self {
        let mut rng = <rand_chacha::ChaCha8Rng as rand::SeedableRng>::seed_from_u64(seed);
        let bound = speed / harmonics.max(1) as f64;
        let mut draw = |n: usize| -> Vec<f64> {
            (0..n)
                .map(|_| bound * (2.0 * rng.random::<f64>() - 1.0))
                .collect()
        };
        let a = (0..dof).map(|_| draw(harmonics)).collect();
        let b = (0..dof).map(|_| draw(harmonics)).collect();
        let q0 = draw(dof).into_iter().map(|x| 0.5 * x / bound).collect();
        Self {
            omega: std::f64::consts::TAU * base_hz,
            q0,
            a,
            b,
        }
    }

    fn joint(&self, j: usize, t: f64) -> (f64, f64, f64) {
        let (mut p, mut v, mut a) = (self.q0[j], 0.0, 0.0);
        for (l, (&al, &bl)) in self.a[j].iter().zip(&self.b[j]).enumerate() {
            let w = self.omega * (l + 1) as f64;
            let (s, c) = (w * t).sin_cos();
            p += (al * s - bl * c) / w;
            v += al * c + bl * s;
            a += w * (-al * s + bl * c);
        }
        (p, v, a)
    }

    /// The reference at time `t` \[s\].
    pub fn sample(&self, t: f64) -> JointReference {
        let n = self.q0.len();
        let mut r = JointReference {
            q: vec![0.0; n],
            qd: vec![0.0; n],
            qdd: vec![0.0; n],
        };
        for j in 0..n {
            (r.q[j], r.qd[j], r.qdd[j]) = self.joint(j, t);
        }
        r
    }
}

/// Pick-and-place: home → pick → place → home in quintic moves, with a dwell at each stop.
///
/// The cycle repeats. Each move takes `move_time` \[s\] and starts and ends at rest; the arm
/// then dwells `dwell` \[s\]. [`grasp_times`](Self::grasp_times) gives the mid-dwell instants.
#[derive(Debug, Clone, PartialEq)]
pub struct PickAndPlace {
    /// Waypoints `[home, pick, place]` \[rad\].
    pub waypoints: [Vec<f64>; 3],
    /// Duration of one move \[s\].
    pub move_time: f64,
    /// Dwell at each waypoint \[s\].
    pub dwell: f64,
}

impl PickAndPlace {
    /// A pick-and-place cycle for `model`: pick and place are the home posture moved by
    /// `±reach` rad on every joint (alternating sign by joint), inside 80 % of the limits.
    pub fn around_home(model: &ArmModel, reach: f64, move_time: f64, dwell: f64) -> Self {
        let home = model.home();
        let shift = |sign: f64| -> Vec<f64> {
            (0..model.dof())
                .map(|j| {
                    let s = if j % 2 == 0 { sign } else { -sign };
                    let (lo, hi) = (model.limits.lower[j], model.limits.upper[j]);
                    let (lo, hi) = (
                        home[j] - 0.8 * (home[j] - lo),
                        home[j] + 0.8 * (hi - home[j]),
                    );
                    (home[j] + s * reach).clamp(lo, hi)
                })
                .collect()
        };
        Self {
            waypoints: [home.clone(), shift(1.0), shift(-1.0)],
            move_time,
            dwell,
        }
    }

    /// Length of one cycle \[s\].
    pub fn cycle(&self) -> f64 {
        3.0 * (self.move_time + self.dwell)
    }

    /// The instants of the first cycle's grasp (mid-dwell at pick) and release (mid-dwell at
    /// place) \[s\].
    pub fn grasp_times(&self) -> (f64, f64) {
        let seg = self.move_time + self.dwell;
        (
            self.move_time + 0.5 * self.dwell,
            seg + self.move_time + 0.5 * self.dwell,
        )
    }

    /// The reference at time `t` \[s\].
    pub fn sample(&self, t: f64) -> JointReference {
        let seg = self.move_time + self.dwell;
        let tc = t.rem_euclid(self.cycle());
        let k = ((tc / seg).floor() as usize).min(2);
        let from = &self.waypoints[k];
        let to = &self.waypoints[(k + 1) % 3];
        let tau = ((tc - k as f64 * seg) / self.move_time).clamp(0.0, 1.0);
        let moving = tc - (k as f64) * seg < self.move_time;
        // Quintic s(τ) = 10τ³ − 15τ⁴ + 6τ⁵: zero velocity and acceleration at both ends.
        let s = tau * tau * tau * (10.0 - 15.0 * tau + 6.0 * tau * tau);
        let (ds, dds) = if moving {
            (
                30.0 * tau * tau * (1.0 - tau) * (1.0 - tau) / self.move_time,
                60.0 * tau * (1.0 - tau) * (1.0 - 2.0 * tau) / (self.move_time * self.move_time),
            )
        } else {
            (0.0, 0.0)
        };
        let n = from.len();
        let mut r = JointReference {
            q: vec![0.0; n],
            qd: vec![0.0; n],
            qdd: vec![0.0; n],
        };
        for j in 0..n {
            let d = to[j] - from[j];
            r.q[j] = from[j] + s * d;
            r.qd[j] = ds * d;
            r.qdd[j] = dds * d;
        }
        r
    }
}

/// A reference trajectory for the arm.
#[derive(Debug, Clone, PartialEq)]
pub enum ArmTrajectory {
    /// Fourier-series excitation.
    Fourier(FourierTrajectory),
    /// Pick-and-place cycles.
    PickAndPlace(PickAndPlace),
}

impl ArmTrajectory {
    /// The reference at time `t` \[s\].
    pub fn sample(&self, t: f64) -> JointReference {
        match self {
            ArmTrajectory::Fourier(f) => f.sample(t),
            ArmTrajectory::PickAndPlace(p) => p.sample(t),
        }
    }
}
