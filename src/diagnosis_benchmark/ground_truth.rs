//! What a diagnosis of a benchmark flight should find, from the simulator's truth and the log
//! alone: the noise per channel, each true effect's strength over it, the coefficients.

use serde::{Deserialize, Serialize};
use tagk_diagnose::{
    DiagnoseOptions, EffectKind, residual_autocorrelation, resolution_of, whiteness_limit,
};
use tagk_dynamics::nalgebra::{DMatrix, DVector, Quaternion, UnitQuaternion, Vector3};
use tagk_dynamics::{
    InertialParams, newton_euler, proper_acceleration, write_rigid_body_regressor,
};
use tagk_sim::{SensingProfile, SimOutput};

use super::{DRAG_LAWS, FlightSpec};

/// Name of the sensor truth of an uncalibrated accelerometer, the diagnosis' own name for that
/// candidate: its constant bias `b_a` (body frame) makes the logged proper acceleration
/// `a + b_a`, so that the data carry the constant body-frame wrench `[m b_a; h × b_a]`
/// (`Y(b_a, 0, 0) θ`) that no plant effect made. The diagnosis may stand for it with the
/// effects listed in [`super::STAND_INS`].
pub use tagk_diagnose::ACCEL_BIAS;

/// One true effect of a flight (a hidden plant effect, or the [`ACCEL_BIAS`] sensor truth)
/// and how strongly the log shows it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TrueEffect {
    /// The vocabulary's name (`tagk_dynamics::EffectKind::name`), or [`ACCEL_BIAS`].
    pub name: String,
    /// Its family (`EffectKind::family`; the name itself for a sensor truth).
    pub family: String,
    /// Per channel `fx..tz`: the RMS of its wrench after removing its least-squares projection
    /// on the rigid-body regressor's columns (what a rigid body of other parameters absorbs:
    /// the mass too unless the mass is known), over the channel's noise σ (dimensionless).
    pub strength: [f64; 6],
    /// The largest of [`TrueEffect::strength`].
    pub max_strength: f64,
    /// `max_strength ≥ D` ([`super::BenchmarkOptions::detectable`]).
    pub detectable: bool,
    /// The largest over the channels of the `Σ ρ_k²` this effect alone, missing from a model,
    /// adds to a white residual of unit noise (dimensionless): at lag `k` the residual's
    /// autocorrelation is `s² ρ_k / (1 + s²)`, `s` the channel's strength and `ρ_k` the
    /// autocorrelation of the effect's projected wrench at the whiteness test's lags
    /// (`tagk_diagnose::residual_autocorrelation`). Set against
    /// [`GroundTruth::whiteness_limit`].
    pub whiteness: f64,
}

/// What kind of reported number an [`ExpectedCoefficient`] is compared with.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum CoefficientKind {
    /// One of `FittedEffect::coefficients` (interval: `Coefficient::confidence_interval`).
    Coefficient,
    /// The scanned parameter `FittedEffect::scanned` (interval: `FittedEffect::scanned_interval`).
    Scanned,
    /// One of `FittedEffect::derived` (interval: its `confidence_interval`).
    Derived,
}

/// A coefficient the diagnosis should report, with its true value.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ExpectedCoefficient {
    /// The diagnosis effect that reports it (a name of the vocabulary).
    pub effect: String,
    /// The coefficient's name as the diagnosis names it (e.g. `d_x`, `tau`, `v_wx`).
    pub name: String,
    /// Where the diagnosis reports it.
    pub kind: CoefficientKind,
    /// Its true value, in the diagnosis' unit (SI).
    pub value: f64,
    /// The scale of the relative error: the norm of the true values of its group (e.g. the
    /// three drag coefficients, the bias force), so that a small component of a vector is
    /// judged against the vector (same unit as `value`).
    pub scale: f64,
    /// The comparison is ambiguous, and skipped, when the final model also holds any of these
    /// effects (e.g. a drag law next to a `wind`: their drag columns are the same).
    pub unless_with: Vec<String>,
}

/// Everything the score of one flight is judged against, computed from the simulator's truth
/// ([`tagk_sim::FlightTruth`]) and the log, independently of the diagnosis.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GroundTruth {
    /// The flight's sensing profile.
    pub sensing: SensingProfile,
    /// `true`: the diagnosis is given the true mass.
    pub known_mass: bool,
    /// Noise σ per channel `fx..tz` \[N, N m\]: `max(residual_rms, resolution)`.
    pub noise: [f64; 6],
    /// RMS per channel of the true model's residual on the logged signals,
    /// `b_logged − Y(logged a, ω, ω̇) θ_true + Σ w_e` \[N, N m\], with `w_e` the external
    /// wrench each true effect exerts (the diagnosis' sign: `b = Y θ − Σ w_e`; for the
    /// accelerometer bias `w = Y(b_a, 0, 0) θ`): the noise realisation as the diagnosis sees it
    /// (rotor-speed noise, IMU noise through θ, the discretisation of the logged `ω̇`).
    pub residual_rms: [f64; 6],
    /// The resolution floor per channel \[N, N m\]: the diagnosis' own
    /// ([`tagk_diagnose::resolution_of`]) of the logged wrench, with the default airframe
    /// radius (`DiagnoseOptions::airframe_radius`).
    pub resolution: [f64; 6],
    /// The true effects: the hidden plant effects (vocabulary order), then the sensor truths.
    pub effects: Vec<TrueEffect>,
    /// The coefficients the diagnosis should report for each effect it may fit.
    pub expected: Vec<ExpectedCoefficient>,
    /// True mass of the flying body \[kg\].
    pub mass: f64,
    /// The mass the data identify \[kg\]: with the accelerometer's vertical offset left in the
    /// fit, `b_z` ([`identifiable_offset`]), the least-squares scale of `m a_z = m' (a_z + b_z)`
    /// over the flight, `m Σ a_z (a_z + b_z) / Σ (a_z + b_z)²` (≈ `m (1 − b_z/g)` near hover).
    /// The diagnosis measures the vertical offset against the velocity and removes it
    /// (`tagk_diagnose::accel_offset`), so this is the true mass.
    pub identifiable_mass: f64,
    /// True inertial parameters (docs/CONVENTIONS.md §1).
    pub params: [f64; 10],
    /// The detectability threshold `D` used.
    pub detectable_threshold: f64,
    /// `true` for a flight at a constant heading (no yaw rate): a force fixed in the world and
    /// one fixed in the body are then the same in the data.
    pub constant_heading: bool,
    /// The diagnosis' whiteness limit for this log's length (`tagk_diagnose::whiteness_limit`):
    /// the largest `Σ ρ_k²` of an adequate channel's residual.
    pub whiteness_limit: f64,
    /// Whiteness of the true model's residual per channel, `Σ ρ_k²` at the diagnosis' lags
    /// (`tagk_diagnose::residual_autocorrelation`; dimensionless): how coloured the noise
    /// itself is, to set against [`Self::whiteness_limit`].
    pub noise_whiteness: [f64; 6],
}

/// The least-squares projection onto the rigid-body regressor's columns of stacked,
/// noise-weighted wrench series: `strength` gives what an effect's wrench keeps after a rigid
/// body of free parameters absorbed what it can.
#[derive(Debug, Clone)]
pub struct RigidProjection {
    /// Orthonormal basis of the weighted columns' span (`6 n` rows, sample-major).
    basis: DMatrix<f64>,
    /// Channel weights `1/σ_c`.
    weights: [f64; 6],
}

impl RigidProjection {
    /// The projection for the rigid-body regressors `regressors` (one 6×10 block per sample,
    /// row-major as `write_rigid_body_regressor` writes it) with channels weighted by
    /// `1/noise[c]` (`noise` \[N, N m\], positive), on all ten columns or, with `known_mass`,
    /// without the mass column (a known mass absorbs nothing).
    pub fn new(regressors: &[[f64; 60]], known_mass: bool, noise: [f64; 6]) -> Self {
        let n = regressors.len();
        let first = usize::from(known_mass);
        let p = 10 - first;
        let weights = noise.map(|s| 1.0 / s.max(f64::MIN_POSITIVE));
        let mut a = DMatrix::<f64>::zeros(6 * n, p);
        for (i, y) in regressors.iter().enumerate() {
            for c in 0..6 {
                for j in 0..p {
                    a[(6 * i + c, j)] = y[10 * c + j + first] * weights[c];
                }
            }
        }
        // Unit columns: the span is unchanged and the rank test below is scale-free.
        for j in 0..p {
            let norm = a.column(j).norm();
            if norm > 0.0 {
                a.column_mut(j).scale_mut(1.0 / norm);
            }
        }
        let svd = a.svd(true, false);
        let u = svd.u.unwrap_or_else(|| DMatrix::zeros(6 * n, 0));
        let largest = svd.singular_values.iter().copied().fold(0.0, f64::max);
        let keep: Vec<usize> = (0..svd.singular_values.len())
            .filter(|&k| svd.singular_values[k] > 1e-10 * largest)
            .collect();
        let basis = DMatrix::from_fn(6 * n, keep.len(), |r, k| u[(r, keep[k])]);
        Self { basis, weights }
    }

    /// Per channel: the RMS of `wrench` (one `[fx..tz]` per sample of the regressors \[N, N m\])
    /// after removing its weighted least-squares projection on the rigid-body columns, over
    /// the channel's σ (dimensionless).
    ///
    /// # Panics
    /// When `wrench` has not one row per sample of the regressors.
    pub fn strength(&self, wrench: &[[f64; 6]]) -> [f64; 6] {
        let e = self.residual(wrench);
        let n = e.len();
        std::array::from_fn(|c| {
            let sum: f64 = e.iter().map(|x| x[c].powi(2)).sum();
            (sum / n.max(1) as f64).sqrt()
        })
    }

    /// Per sample and channel: what `wrench` (one `[fx..tz]` per sample of the regressors
    /// \[N, N m\]) keeps after removing its weighted least-squares projection on the
    /// rigid-body columns, over the channel's σ (dimensionless).
    ///
    /// # Panics
    /// When `wrench` has not one row per sample of the regressors.
    pub fn residual(&self, wrench: &[[f64; 6]]) -> Vec<[f64; 6]> {
        let n = self.basis.nrows() / 6;
        assert_eq!(wrench.len(), n, "one wrench per regressor sample");
        let v = DVector::from_fn(6 * n, |r, _| wrench[r / 6][r % 6] * self.weights[r % 6]);
        let e = &v - &self.basis * (self.basis.transpose() * &v);
        (0..n)
            .map(|i| std::array::from_fn(|c| e[6 * i + c]))
            .collect()
    }

    /// The largest over the channels of the `Σ ρ_k²` that `wrench`, missing from a model,
    /// adds to a white residual of the channels' noise ([`TrueEffect::whiteness`]).
    ///
    /// # Panics
    /// When `wrench` has not one row per sample of the regressors.
    pub fn whiteness(&self, wrench: &[[f64; 6]]) -> f64 {
        let e = self.residual(wrench);
        let n = e.len().max(1) as f64;
        (0..6)
            .map(|c| {
                let x: Vec<f64> = e.iter().map(|v| v[c]).collect();
                let s2 = x.iter().map(|v| v * v).sum::<f64>() / n;
                let share = s2 / (1.0 + s2);
                residual_autocorrelation(&x)
                    .iter()
                    .map(|rho| (share * rho).powi(2))
                    .sum::<f64>()
            })
            .fold(0.0, f64::max)
    }
}

/// `Y(a, ω, ω̇)`, 6×10 row-major.
fn regressor(a: &Vector3<f64>, w: &Vector3<f64>, wd: &Vector3<f64>) -> [f64; 60] {
    let mut y = [0.0; 60];
    // The buffer holds 60 values: the write cannot fail.
    let _ = write_rigid_body_regressor(a, w, wd, &mut y);
    y
}

impl GroundTruth {
    /// The ground truth of a flown benchmark flight: `spec` as drawn, `output` its simulation
    /// (flown with the truth recorded), `detectable` the threshold `D`.
    ///
    /// # Errors
    /// A description when the output has no truth, or a log without the accelerations the
    /// noise estimate reads.
    pub fn of_flight(
        spec: &FlightSpec,
        output: &SimOutput,
        detectable: f64,
    ) -> Result<Self, String> {
        let truth = output
            .truth
            .as_ref()
            .ok_or("the flight was flown without its truth")?;
        let log = &output.log;
        let n = log.len();
        if truth.samples.len() != n || n == 0 {
            return Err(format!(
                "{} truth samples for {n} log samples",
                truth.samples.len()
            ));
        }
        let (Some(accel), Some(omega_dot)) = (&log.accel, &log.omega_dot) else {
            return Err("the log has no accelerations".into());
        };
        let theta0 = truth.samples[0].params;
        // The bias as logged, and the part of it the fit sees.
        let logged_bias = Vector3::from(truth.accel_bias);
        let b_a = identifiable_offset(&logged_bias);
        let removed = logged_bias - b_a;
        let has_accel_bias = logged_bias.norm() > 0.0;
        // The true effects' wrench series on the log's terms (forces at the sample, torques
        // over the interval the logged ω̇ spans): the plant's, then the accelerometer bias's.
        let mut names: Vec<(String, String)> = truth
            .effects
            .iter()
            .map(|k| (k.name().to_string(), k.family().to_string()))
            .collect();
        let mut series: Vec<Vec<[f64; 6]>> = (0..truth.effects.len())
            .map(|e| {
                truth
                    .samples
                    .iter()
                    .map(|s| s.logged_effect_wrenches[e])
                    .collect()
            })
            .collect();
        if has_accel_bias {
            names.push((ACCEL_BIAS.into(), ACCEL_BIAS.into()));
            series.push(
                truth
                    .samples
                    .iter()
                    .map(|s| accel_bias_wrench(&s.params, &b_a))
                    .collect(),
            );
        }
        // The noise: the true model's residual on the logged signals.
        let mut sum_sq = [0.0; 6];
        let mut residual_series: [Vec<f64>; 6] = std::array::from_fn(|_| Vec::with_capacity(n));
        for i in 0..n {
            let [w, x, y, z] = log.attitude[i];
            let q = UnitQuaternion::from_quaternion(Quaternion::new(w, x, y, z));
            let a = proper_acceleration(&q, &Vector3::from(accel[i]));
            let yt = newton_euler(
                &truth.samples[i].params,
                &a,
                &Vector3::from(log.omega[i]),
                &Vector3::from(omega_dot[i]),
            )
            .to_array();
            // The offset the diagnosis removes before the fit is in the logged signals.
            let before_fit = accel_bias_wrench(&truth.samples[i].params, &removed);
            for c in 0..6 {
                let effects: f64 = series.iter().map(|s| s[i][c]).sum::<f64>() + before_fit[c];
                // The effects' wrenches act beside the actuators: b = Y θ − Σ w_e.
                let r = log.wrench[i][c] - yt[c] + effects;
                sum_sq[c] += r * r;
                residual_series[c].push(r);
            }
        }
        let residual_rms = sum_sq.map(|s| (s / n as f64).sqrt());
        let resolution = resolution_of(&log.wrench, DiagnoseOptions::default().airframe_radius);
        let noise: [f64; 6] = std::array::from_fn(|c| residual_rms[c].max(resolution[c]));
        // Strengths over the noise, after the rigid body absorbed what it can (its regressor on
        // the true motion, with the log's interval-mean ω̇).
        let regressors: Vec<[f64; 60]> = truth
            .samples
            .iter()
            .map(|s| {
                regressor(
                    &Vector3::from(s.proper_acceleration),
                    &Vector3::from(s.body_rate),
                    &Vector3::from(s.logged_angular_acceleration),
                )
            })
            .collect();
        let projection = RigidProjection::new(&regressors, spec.known_mass, noise);
        let effects = names
            .into_iter()
            .zip(&series)
            .map(|((name, family), w)| {
                let strength = projection.strength(w);
                let max_strength = strength.iter().copied().fold(0.0, f64::max);
                TrueEffect {
                    name,
                    family,
                    strength,
                    max_strength,
                    detectable: max_strength >= detectable,
                    whiteness: projection.whiteness(w),
                }
            })
            .collect();
        let mass = theta0.mass();
        let identifiable_mass = if has_accel_bias && !spec.known_mass {
            let (mut num, mut den) = (0.0, 0.0);
            for s in &truth.samples {
                let az = s.proper_acceleration[2];
                num += az * (az + b_a.z);
                den += (az + b_a.z).powi(2);
            }
            mass * num / den
        } else {
            mass
        };
        let expected = expected_coefficients(spec, truth, has_accel_bias.then_some(b_a));
        Ok(Self {
            sensing: spec.sensing,
            known_mass: spec.known_mass,
            noise,
            residual_rms,
            resolution,
            effects,
            expected,
            mass,
            identifiable_mass,
            params: theta0.to_array(),
            detectable_threshold: detectable,
            constant_heading: spec.yaw_rate == 0.0,
            whiteness_limit: whiteness_limit(n),
            noise_whiteness: residual_series
                .each_ref()
                .map(|r| residual_autocorrelation(r).iter().map(|x| x * x).sum()),
        })
    }
}

/// The part of an accelerometer bias `b_a` (body frame \[m/s²\]) left in the signals the
/// diagnosis fits: the horizontal offsets. The vertical one is measured against the velocity
/// and removed before the fit (`tagk_diagnose::accel_offset`); what that measurement leaves
/// (a few mm/s², a few hundredths of a per cent of the mass) is below the benchmark's
/// tolerances.
pub fn identifiable_offset(b_a: &Vector3<f64>) -> Vector3<f64> {
    Vector3::new(b_a.x, b_a.y, 0.0)
}

/// The wrench an accelerometer bias `b_a` \[m/s²\] adds to `Y(logged a) θ`:
/// `Y(b_a, 0, 0) θ = [m b_a; h × b_a]` \[N, N m\].
fn accel_bias_wrench(theta: &InertialParams, b_a: &Vector3<f64>) -> [f64; 6] {
    let zero = Vector3::zeros();
    newton_euler(theta, b_a, &zero, &zero).to_array()
}

/// The coefficients each diagnosis effect should report on this flight (the table of the
/// module docs, "Coefficients").
/// `offset`: the accelerometer bias the fit sees ([`identifiable_offset`]), `None` for a
/// calibrated accelerometer.
fn expected_coefficients(
    spec: &FlightSpec,
    truth: &tagk_sim::FlightTruth,
    offset: Option<Vector3<f64>>,
) -> Vec<ExpectedCoefficient> {
    let e = &spec.effects;
    let theta = truth.samples[0].params;
    let accel_bias = offset.is_some();
    let b_a = offset.unwrap_or_else(Vector3::zeros);
    let drag_laws: Vec<String> = DRAG_LAWS.iter().map(|k| k.name().to_string()).collect();
    let wind = vec![EffectKind::Wind.name().to_string()];
    let mut out = Vec::new();
    let mut group =
        |effect: &str, kind: CoefficientKind, values: &[(&str, f64)], unless: &[String]| {
            let scale = values.iter().map(|(_, v)| v * v).sum::<f64>().sqrt();
            for (name, value) in values {
                out.push(ExpectedCoefficient {
                    effect: effect.to_string(),
                    name: (*name).to_string(),
                    kind,
                    value: *value,
                    scale,
                    unless_with: unless.to_vec(),
                });
            }
        };
    use CoefficientKind::{Coefficient, Derived, Scanned};
    if let Some(d) = e.linear_drag {
        let [x, y, z] = d.coefficients;
        group(
            EffectKind::LinearDrag.name(),
            Coefficient,
            &[("d_x", x), ("d_y", y), ("d_z", z)],
            &wind,
        );
    }
    if let Some(d) = e.quadratic_drag {
        let c = d.cd_area.map(|a| 0.5 * d.air_density * a);
        group(
            EffectKind::QuadraticDrag.name(),
            Coefficient,
            &[("c_x", c[0]), ("c_y", c[1]), ("c_z", c[2])],
            &wind,
        );
    }
    if let Some(d) = e.rotor_drag {
        let k = d.coefficients;
        group(
            EffectKind::RotorDrag.name(),
            Coefficient,
            &[("k_h", k[0]), ("k_z", k[2])],
            &wind,
        );
    }
    if let Some(l) = e.motor_lag {
        group(
            EffectKind::MotorLag.name(),
            Scanned,
            &[("tau", l.time_constant)],
            &[],
        );
    }
    if let Some(d) = e.time_delay {
        group(
            EffectKind::TimeDelay.name(),
            Scanned,
            &[("delay", -d.delay)],
            &[],
        );
    }
    let epsilon = e.thrust_gain.map_or(0.0, |g| g.relative_error);
    if e.ground_effect.is_some() {
        group(
            EffectKind::GroundEffect.name(),
            Coefficient,
            &[("c_ge", 1.0 + epsilon)],
            &[],
        );
    }
    if e.body_bias.is_some() || accel_bias {
        let (f, t) = e
            .body_bias
            .map_or(([0.0; 3], [0.0; 3]), |b| (b.force, b.torque));
        let w = accel_bias_wrench(&theta, &b_a);
        // The constant body force (the plant's and the accelerometer offset's `m b_a`) is
        // the accelerometer offset's columns in the diagnosis. At a constant heading a wind's
        // world-fixed force is body-fixed too, and the body force carries an unknown share of
        // it: ambiguous whenever `accel-bias` is fitted (skipped, counted as ambiguous).
        let world_force_in_body = spec.yaw_rate == 0.0 && e.wind.is_some();
        let unless = if world_force_in_body {
            vec![ACCEL_BIAS.to_string()]
        } else {
            Vec::new()
        };
        group(
            ACCEL_BIAS,
            Coefficient,
            &[("f_x", f[0] + w[0]), ("f_y", f[1] + w[1])],
            &unless,
        );
        group(
            EffectKind::BodyBias.name(),
            Coefficient,
            &[
                ("bias_tx", t[0] + w[3]),
                ("bias_ty", t[1] + w[4]),
                ("bias_tz", t[2] + w[5]),
            ],
            &[],
        );
    }
    if let Some(w) = e.wind {
        let [vx, vy, _] = w.velocity;
        group(
            EffectKind::Wind.name(),
            Derived,
            &[("v_wx", vx), ("v_wy", vy)],
            &drag_laws,
        );
        if let Some(d) = e.rotor_drag {
            let k = d.coefficients;
            // The diagnosis' wind through the rotors' hub drag: one horizontal coefficient
            // `k_h` (the simulator's are equal in x and y), `k_z`, and `k_h v_w`.
            group(
                EffectKind::Wind.name(),
                Coefficient,
                &[("k_h", k[0]), ("k_z", k[2])],
                &drag_laws,
            );
            group(
                EffectKind::Wind.name(),
                Coefficient,
                &[("kv_wx", k[0] * vx), ("kv_wy", k[1] * vy)],
                &drag_laws,
            );
        }
    }
    if e.thrust_gain.is_some() || (accel_bias && spec.known_mass) {
        let (mut num, mut den) = (0.0, 0.0);
        for s in &truth.samples {
            let az = s.proper_acceleration[2];
            num += az * (az + b_a.z);
            den += az * az;
        }
        group(
            EffectKind::ThrustGain.name(),
            Coefficient,
            &[("kappa", (1.0 + epsilon) * num / den - 1.0)],
            &[],
        );
    }
    out
}
