//! The five reference trajectories of the protocol (figure-8, circle, spiral, helix,
//! ellipse), with randomised size, centre and phase within the peak-speed limits
//! (0.5 m/s and 0.5 rad/s of the path's angular rate, docs/CONVENTIONS.md §5).
//!
//! Every path is `p(t) = c + shape(s(t), λ(t))` with the phase `s(t) = φ + Ω g(t)` and the
//! progress `λ(t) = g(t) / g(T*)` (used by the spiral's growing radius and the helix's climb).
//! `g` starts the motion smoothly from rest: `g'(t)` is the smoothstep `3u² − 2u³`,
//! `u = t / T_r`, over the first `T_r = 1.5 s`, then 1. Hence `|ṗ| ≤ Ω |∂shape/∂s| +
//! |∂shape/∂λ| / g(T*)`, and `Ω` is chosen so that this bound is at most 0.5 m/s (and (`T* = max(T, 10 s)`)
//! `Ω ≤ 0.5 rad/s`). The reference heading is yaw 0.

use std::f64::consts::TAU;

use nalgebra::Vector3;
use rand::RngExt;
use serde::{Deserialize, Serialize};

use crate::SimError;

/// Peak reference speed [m/s] (docs/CONVENTIONS.md §5).
pub const PEAK_SPEED: f64 = 0.5;
/// Peak angular rate of the path parameter [rad/s] (docs/CONVENTIONS.md §5).
pub const PEAK_RATE: f64 = 0.5;
/// Duration of the smooth start from rest \[s\].
pub const RAMP_TIME: f64 = 1.5;

/// The shape of a reference path.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum TrajectoryKind {
    /// Lemniscate of Gerono: `(a sin s, (b/2) sin 2s, 0)`.
    Figure8,
    /// `(R cos s, R sin s, 0)`.
    Circle,
    /// Planar spiral with radius growing from `0.3 R` to `R`.
    Spiral,
    /// Circle of radius `R` climbing `H` over the trial.
    Helix,
    /// `(a cos s, b sin s, 0)`.
    Ellipse,
}

impl TrajectoryKind {
    /// All five, in the order the Monte Carlo driver cycles through them.
    pub const ALL: [TrajectoryKind; 5] = [
        TrajectoryKind::Figure8,
        TrajectoryKind::Circle,
        TrajectoryKind::Spiral,
        TrajectoryKind::Helix,
        TrajectoryKind::Ellipse,
    ];

    /// Command-line name (`figure8`, `circle`, `spiral`, `helix`, `ellipse`), parsed back by
    /// `FromStr`.
    pub fn cli_name(self) -> &'static str {
        match self {
            TrajectoryKind::Figure8 => "figure8",
            other => other.name(),
        }
    }

    /// Display name.
    pub fn name(self) -> &'static str {
        match self {
            TrajectoryKind::Figure8 => "figure-8",
            TrajectoryKind::Circle => "circle",
            TrajectoryKind::Spiral => "spiral",
            TrajectoryKind::Helix => "helix",
            TrajectoryKind::Ellipse => "ellipse",
        }
    }
}

impl std::str::FromStr for TrajectoryKind {
    type Err = SimError;

    /// Parses [`TrajectoryKind::cli_name`].
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        TrajectoryKind::ALL
            .into_iter()
            .find(|k| k.cli_name() == s)
            .ok_or_else(|| SimError::Unknown {
                what: "trajectory",
                value: s.to_string(),
                expected: "figure8, circle, spiral, helix, ellipse",
            })
    }
}

/// Reference position, velocity and acceleration at one time (world frame), and the
/// reference heading.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReferenceSample {
    /// Position \[m\].
    pub position: Vector3<f64>,
    /// Velocity [m/s].
    pub velocity: Vector3<f64>,
    /// Acceleration [m/s²].
    pub acceleration: Vector3<f64>,
    /// Heading `ψ`: the reference attitude's yaw about world `+z` \[rad\] (0: body `x`
    /// along world `x`).
    pub yaw: f64,
    /// Rate of the heading `ψ̇` \[rad/s\].
    pub yaw_rate: f64,
}

impl ReferenceSample {
    /// This sample with heading `yaw` \[rad\] turning at `yaw_rate` \[rad/s\].
    pub fn with_heading(self, yaw: f64, yaw_rate: f64) -> Self {
        Self {
            yaw,
            yaw_rate,
            ..self
        }
    }
}

/// One reference path (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Trajectory {
    /// Shape.
    pub kind: TrajectoryKind,
    /// Centre `c`, world frame \[m\].
    pub centre: [f64; 3],
    /// Size along the path's first axis (`a` or `R`) \[m\].
    pub size_a: f64,
    /// Size along the second axis (`b`; equal to `size_a` for circle, spiral, helix) \[m\].
    pub size_b: f64,
    /// Climb of the helix over the trial \[m\] (0 for the others).
    pub climb: f64,
    /// Initial phase `φ` \[rad\].
    pub phase: f64,
    /// Angular rate `Ω` of the phase [rad/s].
    pub rate: f64,
    /// Trial duration `T` \[s\] (sets the spiral's growth and the helix's climb rate, spread
    /// over `max(T, MIN_GROWTH_TIME)`).
    pub duration: f64,
}

/// Shortest time over which the spiral grows and the helix climbs \[s\], so that short flights
/// keep the speed limit.
pub const MIN_GROWTH_TIME: f64 = 10.0;

fn ramp(t: f64) -> f64 {
    let t = t.max(0.0);
    if t >= RAMP_TIME {
        t - 0.5 * RAMP_TIME
    } else {
        let u = t / RAMP_TIME;
        RAMP_TIME * (u * u * u - 0.5 * u * u * u * u)
    }
}

impl Trajectory {
    /// A random path of `kind` for a trial of `duration` \[s\]: sizes `a ∈ U[0.4, 1.0] m`,
    /// `b ∈ U[0.5, 1]·a` (ellipse, figure-8), helix climb `U[0.3, 0.6] m`, centre
    /// `x, y ∈ U[−0.5, 0.5] m`, `z = altitude` if given (else `U[0.8, 1.5] m`), phase
    /// `U[0, 2π)`, and the largest `Ω ≤ 0.5 rad/s` keeping the speed ≤ 0.5 m/s.
    ///
    /// # Errors
    /// [`SimError::InvalidDuration`] unless `duration > 0` and finite;
    /// [`SimError::InvalidParameter`] for a non-finite altitude.
    pub fn random<R: rand::Rng + ?Sized>(
        kind: TrajectoryKind,
        duration: f64,
        altitude: Option<f64>,
        rng: &mut R,
    ) -> Result<Self, SimError> {
        if !(duration > 0.0 && duration.is_finite()) {
            return Err(SimError::InvalidDuration {
                what: "trial duration",
                value: duration,
            });
        }
        if let Some(z) = altitude
            && !z.is_finite()
        {
            return Err(SimError::InvalidParameter {
                name: "altitude",
                value: z,
                reason: "must be finite",
            });
        }
        let a = rng.random_range(0.4..1.0);
        let b = match kind {
            TrajectoryKind::Ellipse | TrajectoryKind::Figure8 => a * rng.random_range(0.5..1.0),
            _ => a,
        };
        let climb = if kind == TrajectoryKind::Helix {
            rng.random_range(0.3..0.6)
        } else {
            0.0
        };
        let cx = rng.random_range(-0.5..0.5);
        let cy = rng.random_range(-0.5..0.5);
        let cz_random: f64 = rng.random_range(0.8..1.5);
        let cz = altitude.unwrap_or(cz_random);
        let phase = rng.random_range(0.0..TAU);
        let mut t = Self {
            kind,
            centre: [cx, cy, cz],
            size_a: a,
            size_b: b,
            climb,
            phase,
            rate: 0.0,
            duration,
        };
        t.rate = t.max_rate();
        Ok(t)
    }

    /// The largest `Ω ≤ PEAK_RATE` whose speed bound (module docs) is `≤ 0.98 PEAK_SPEED`.
    fn max_rate(&self) -> f64 {
        let (a, b) = (self.size_a, self.size_b);
        let (ds, dl) = match self.kind {
            TrajectoryKind::Circle => (a, 0.0),
            TrajectoryKind::Ellipse => (a.max(b), 0.0),
            TrajectoryKind::Figure8 => (a.hypot(b), 0.0),
            TrajectoryKind::Spiral => (a, 0.7 * a),
            TrajectoryKind::Helix => (a, self.climb),
        };
        let budget = 0.98 * PEAK_SPEED - dl / self.growth_scale();
        (budget / ds).clamp(0.0, PEAK_RATE)
    }

    fn growth_scale(&self) -> f64 {
        ramp(self.duration.max(MIN_GROWTH_TIME))
    }

    fn shape(&self, s: f64, lambda: f64) -> Vector3<f64> {
        let (a, b) = (self.size_a, self.size_b);
        let (sn, cs) = s.sin_cos();
        match self.kind {
            TrajectoryKind::Circle => Vector3::new(a * cs, a * sn, 0.0),
            TrajectoryKind::Ellipse => Vector3::new(a * cs, b * sn, 0.0),
            TrajectoryKind::Figure8 => Vector3::new(a * sn, b * sn * cs, 0.0),
            TrajectoryKind::Spiral => {
                let r = a * (0.3 + 0.7 * lambda);
                Vector3::new(r * cs, r * sn, 0.0)
            }
            TrajectoryKind::Helix => Vector3::new(a * cs, a * sn, self.climb * (lambda - 0.5)),
        }
    }

    /// Reference position at time `t` \[s\] (world frame, m).
    pub fn position(&self, t: f64) -> Vector3<f64> {
        let g = ramp(t);
        let lambda = g / self.growth_scale();
        Vector3::from(self.centre) + self.shape(self.phase + self.rate * g, lambda)
    }

    /// Position, velocity and acceleration at `t` \[s\]; the derivatives are central
    /// differences of [`position`](Self::position) (steps 1e-4 s and 1e-3 s; errors below
    /// 1e-7 m/s and 1e-5 m/s² for these smooth, slow paths).
    pub fn sample(&self, t: f64) -> ReferenceSample {
        let p = self.position(t);
        let h1 = 1e-4;
        let v = (self.position(t + h1) - self.position(t - h1)) / (2.0 * h1);
        let h2 = 1e-3;
        let acc = (self.position(t + h2) - p * 2.0 + self.position(t - h2)) / (h2 * h2);
        ReferenceSample {
            position: p,
            velocity: v,
            acceleration: acc,
            yaw: 0.0,
            yaw_rate: 0.0,
        }
    }
}
