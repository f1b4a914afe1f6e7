//! The actuator stream: first-order motor lag, a time delay between the actuator and motion
//! streams, and a thrust-gain error.

use tagk_dynamics::EffectKind;
use tagk_dynamics::front_end::is_actuated;

use crate::effects::{Effect, EffectColumn, Plausibility, ScanSpec};
use crate::signals::{CHANNEL_NAMES, Channel, Signals};

/// First-order actuator dynamics: the delivered thrust and torques follow the logged command
/// through `τ ẏ = u − y`. Column: `y − b` on `fz, tx, ty, tz`, with `y` the exact response
/// to the piecewise-constant command sampled in the middle of each sample interval (see
/// [`first_order_lag`]); the coefficient is ≈ 1 for that sampling, between `e^{−Δt/2τ}` and
/// `e^{Δt/2τ}` for others, so gains in `[0.4, 2.5]` are accepted as plausible. Four nuisance
/// columns `e^{−(t − t₀)/τ}` (one per channel) absorb the unknown actuator state at the start
/// of the log.
#[derive(Debug, Clone)]
pub(crate) struct MotorLag {
    /// Time constants scanned \[s\].
    pub grid: Vec<f64>,
}

impl MotorLag {
    /// The time constant \[s\]: `p`, else the middle of the grid.
    fn tau(&self, p: Option<f64>) -> f64 {
        p.unwrap_or(self.grid[self.grid.len() / 2])
    }
}

/// `true` when channel `channel`'s lagged response is the interval mean of the lag's state
/// rather than its value at the interval's middle: with rotor speeds and a rotor mixer the
/// torques are the interval means of the lagged rotors (what a differenced gyro sees), the
/// thrust its value at the middle; without, every channel is lagged at the middle
/// ([`MotorLag::sampled_columns`]).
fn interval_mean(s: &Signals, channel: Channel) -> bool {
    // No rotor speeds, no mixer.
    s.rotor_mixer().is_some() && channel > 2
}

/// The factors of the first-order lag over one step `x = Δt/τ`: `a = e^{−x}` (the state's
/// decay over the step) and `g`, that of the sampled output
/// (`y_k = u_k + g (Y_{k−1} − u_k)`): `(1 − a)/x` for the interval mean,
/// `e^{−x/2}` at the middle.
fn lag_factors(x: f64, interval_mean: bool) -> (f64, f64) {
    let a = (-x).exp();
    let g = if interval_mean {
        (1.0 - a) / x
    } else {
        (-0.5 * x).exp()
    };
    (a, g)
}

impl Default for MotorLag {
    fn default() -> Self {
        // 5 ms .. 200 ms, log-spaced.
        let grid = (0..16)
            .map(|k| 0.005 * (40.0f64).powf(k as f64 / 15.0))
            .collect();
        Self { grid }
    }
}

/// `true` when two sampling steps \[s\] agree to 1e-9 relative: the exponential factors of
/// the previous step are reused (the time stamps of a uniformly sampled log differ in their
/// last bits, and the exponentials dominate a scan's cost; the error this makes, below 1e-9
/// relative, is far below any log's resolution).
fn same_step(dt: f64, previous: f64) -> bool {
    (dt - previous).abs() <= 1e-9 * dt.abs()
}

/// The samples `0, stride, 2 stride, …` of a series of `n`, as they pass by in a loop over
/// every sample: `take(k)` is `Some(slot)` when sample `k` is one of them (without a division
/// per sample).
struct Sampled {
    stride: usize,
    phase: usize,
    slot: usize,
}

impl Sampled {
    /// Positioned at sample 0 (which is taken by the caller); a `stride` of 0 is read as 1.
    fn new(stride: usize) -> Self {
        Self {
            stride: stride.max(1),
            phase: 0,
            slot: 0,
        }
    }

    /// Advances to the next sample: its slot in the sampled series if it is sampled.
    fn next(&mut self) -> Option<usize> {
        self.phase += 1;
        if self.phase == self.stride {
            self.phase = 0;
            self.slot += 1;
            Some(self.slot)
        } else {
            None
        }
    }
}

/// `e^{−(t − t₀)/τ}` at the samples `0, stride, 2 stride, …` (0 once below 1e-12; all 0 for
/// `τ ≤ 0`), by the recursion `x_k = x_{k−1} e^{−Δt_k/τ}` over every sample (one exponential
/// per distinct step).
fn start_decay(t: &[f64], tau: f64, stride: usize) -> Vec<f64> {
    let mut out = vec![0.0; t.len().div_ceil(stride.max(1))];
    if t.is_empty() || tau <= 0.0 {
        return out;
    }
    let (mut x, mut last_dt, mut factor) = (1.0, f64::NAN, 0.0);
    out[0] = 1.0;
    let mut sampled = Sampled::new(stride);
    for k in 1..t.len() {
        let dt = t[k] - t[k - 1];
        if !same_step(dt, last_dt) {
            last_dt = dt;
            factor = (-dt / tau).exp();
        }
        x *= factor;
        if x < 1e-12 {
            break;
        }
        if let Some(slot) = sampled.next() {
            out[slot] = x;
        }
    }
    out
}

/// Response of the first-order lag `τ ẏ = u − y` (time constant `tau` \[s\]) to a command
/// `u` held constant over each sample interval `[t_k − Δt/2, t_k + Δt/2)` and sampled at
/// its middle `t_k` (the convention of logs whose rows describe one control interval):
/// with `Y_k` the state at the end of interval `k`,
/// `y_k = u_k + e^{−Δt/2τ} (Y_{k−1} − u_k)`, `Y_k = u_k + e^{−Δt/τ} (Y_{k−1} − u_k)`,
/// starting at rest on the first command (`Y_0 = u_0`).
#[cfg(test)]
pub(crate) fn first_order_lag(t: &[f64], u: &[f64], tau: f64) -> Vec<f64> {
    sampled_first_order_lag(t, |k| u[k], tau, 1)
}

/// [`first_order_lag`] of the command `u(k)` (`k < t.len()`) at the samples
/// `0, stride, 2 stride, …` only (the recursion runs over every sample).
fn sampled_first_order_lag(
    t: &[f64],
    u: impl Fn(usize) -> f64,
    tau: f64,
    stride: usize,
) -> Vec<f64> {
    let mut y = Vec::with_capacity(t.len().div_ceil(stride.max(1)));
    if t.is_empty() {
        return y;
    }
    let mut end = u(0);
    y.push(end);
    let (mut last_dt, mut a_half, mut a_full) = (f64::NAN, 0.0, 0.0);
    let mut sampled = Sampled::new(stride);
    for k in 1..t.len() {
        let dt = t[k] - t[k - 1];
        // Uniformly sampled logs reuse the factors (exp is the cost of a 1-D scan).
        if !same_step(dt, last_dt) {
            last_dt = dt;
            (a_half, a_full) = if tau > 0.0 {
                ((-0.5 * dt / tau).exp(), (-dt / tau).exp())
            } else {
                (0.0, 0.0)
            };
        }
        let uk = u(k);
        if sampled.next().is_some() {
            y.push(uk + a_half * (end - uk));
        }
        end = uk + a_full * (end - uk);
    }
    y
}

/// With rotor speeds in the log, the lag acts on each rotor speed and the wrench follows
/// through the squares: with the mixer identified from the log ([`Signals::rotor_mixer`];
/// without one the lag is applied to the wrench directly, `None`), the delivered wrench is
/// `M lag_τ(ω)²`. Returns `[fz, tx, ty, tz]` at the samples `0, stride, 2 stride, …` (the
/// lag runs over every sample).
fn lagged_wrench_from_rotors(s: &Signals, tau: f64, stride: usize) -> Option<Vec<[f64; 4]>> {
    let w = s.rotor_speeds()?;
    let mixer = s.rotor_mixer()?;
    // Per rotor: ω² at the interval midpoint (what an accelerometer sample sees) and the
    // interval mean of ω² (what a differenced gyro — the logged angular acceleration — sees).
    let n = s.len();
    let m = n.div_ceil(stride.max(1));
    let mut mid = vec![[0.0; 4]; m];
    let mut mean = vec![[0.0; 4]; m];
    let mut factors = (f64::NAN, (0.0, 0.0, 0.0, 0.0));
    let mut end = w[0];
    mid[0] = end.map(|x| x * x);
    mean[0] = mid[0];
    let mut sampled = Sampled::new(stride);
    for i in 1..n {
        let dt = s.t[i] - s.t[i - 1];
        // Uniform sampling reuses the factors (the exponentials dominate a scan's cost).
        if !same_step(dt, factors.0) {
            factors = (
                dt,
                if tau > 0.0 {
                    let x = dt / tau;
                    (
                        (-0.5 * x).exp(),
                        (-x).exp(),
                        (1.0 - (-x).exp()) / x,
                        (1.0 - (-2.0 * x).exp()) / (2.0 * x),
                    )
                } else {
                    (0.0, 0.0, 0.0, 0.0)
                },
            );
        }
        let (a_half, a_full, m1, m2) = factors.1;
        let u = w[i];
        let e: [f64; 4] = std::array::from_fn(|r| end[r] - u[r]);
        if let Some(slot) = sampled.next() {
            for r in 0..4 {
                let ym = u[r] + a_half * e[r];
                mid[slot][r] = ym * ym;
                mean[slot][r] = u[r] * u[r] + 2.0 * u[r] * e[r] * m1 + e[r] * e[r] * m2;
            }
        }
        end = std::array::from_fn(|r| u[r] + a_full * e[r]);
    }
    Some(
        mid.iter()
            .zip(&mean)
            .map(|(mid, mean)| {
                let ym = mixer.apply(mid);
                let ya = mixer.apply(mean);
                [ym[0], ya[1], ya[2], ya[3]]
            })
            .collect(),
    )
}

/// The inverse of the first-order lag of [`first_order_lag`] (with `interval_mean`, of the
/// interval mean of the lag's state instead of its value at the interval's middle), applied in
/// place to `y` sampled at `t`: the command `u` whose lagged response is `y`. With `Y` the
/// state at the end of interval `k` and `g` the factor of the sampled output
/// (`y_k = u_k + g (Y_{k−1} − u_k)`: `g = e^{−Δt/2τ}` at the middle, `(1 − e^{−Δt/τ}) τ/Δt`
/// for the interval mean), `u_k = (y_k − g Y_{k−1}) / (1 − g)` and
/// `Y_k = u_k + e^{−Δt/τ} (Y_{k−1} − u_k)`, from `u_0 = y_0`; stable (its pole
/// `(e^{−Δt/τ} − g)/(1 − g)` lies in `(−1, 0]`).
pub(crate) fn inverse_first_order_lag(t: &[f64], y: &mut [f64], tau: f64, interval_mean: bool) {
    if y.is_empty() || tau <= 0.0 {
        return;
    }
    let mut end = y[0];
    let (mut last_dt, mut g, mut a) = (f64::NAN, 0.0, 0.0);
    for k in 1..y.len().min(t.len()) {
        let dt = t[k] - t[k - 1];
        if !same_step(dt, last_dt) {
            last_dt = dt;
            (a, g) = lag_factors(dt / tau, interval_mean);
        }
        let u = (y[k] - g * end) / (1.0 - g);
        end = u + a * (end - u);
        y[k] = u;
    }
}

impl Effect for MotorLag {
    fn name(&self) -> &str {
        EffectKind::MotorLag.name()
    }
    fn description(&self) -> &str {
        "first-order motor dynamics: delivered thrust/torque lags the logged command by a time constant"
    }
    fn channels(&self) -> Vec<Channel> {
        vec![2, 3, 4, 5]
    }
    fn scan(&self) -> Option<ScanSpec> {
        Some(ScanSpec {
            name: "tau".into(),
            unit: "s".into(),
            grid: self.grid.clone(),
            // The shortest lag: the closest to no lag at all.
            start: self.grid.iter().copied().reduce(f64::min),
        })
    }
    fn columns(&self, s: &Signals, p: Option<f64>) -> Vec<EffectColumn> {
        self.sampled_columns(s, p, 1)
    }
    fn sampled_columns(&self, s: &Signals, p: Option<f64>, stride: usize) -> Vec<EffectColumn> {
        let stride = stride.max(1);
        let tau = self.tau(p);
        let b = s.wrench();
        let mut data: [Option<Vec<f64>>; 6] = Default::default();
        if let Some(lagged) = lagged_wrench_from_rotors(s, tau, stride) {
            for (c, d) in data.iter_mut().enumerate().skip(2) {
                *d = Some(
                    lagged
                        .iter()
                        .zip(b.iter().step_by(stride))
                        .map(|(y, b)| y[c - 2] - b[c])
                        .collect(),
                );
            }
        } else {
            for (c, d) in data.iter_mut().enumerate().skip(2) {
                let y = sampled_first_order_lag(&s.t, |k| b[k][c], tau, stride);
                *d = Some(
                    y.iter()
                        .zip(b.iter().step_by(stride))
                        .map(|(y, b)| y - b[c])
                        .collect(),
                );
            }
        }
        let mut cols = vec![EffectColumn {
            name: "g_lag".into(),
            unit: "1".into(),
            data,
            fixed: Some(1.0),
        }];
        // The actuators' state when the log starts is unknown: its effect decays like
        // e^{−(t − t₀)/τ}, a nuisance column per channel.
        let decay = start_decay(&s.t, tau, stride);
        for c in 2..6 {
            cols.push(EffectColumn::on(
                &format!("start_{}", CHANNEL_NAMES[c]),
                if c == 2 { "N" } else { "N m" },
                c,
                decay.clone(),
            ));
        }
        cols
    }
    fn unfilter(&self, s: &Signals, p: Option<f64>, channel: Channel, series: &mut [f64]) -> bool {
        if !is_actuated(channel) {
            return false;
        }
        inverse_first_order_lag(&s.t, series, self.tau(p), interval_mean(s, channel));
        true
    }
    fn target_filter(
        &self,
        s: &Signals,
        p: Option<f64>,
        channel: Channel,
    ) -> Option<crate::fit::TargetFilter> {
        if !is_actuated(channel) {
            return None;
        }
        let tau = self.tau(p);
        let dt = s.mean_dt();
        if !(tau > 0.0 && dt > 0.0) {
            return None;
        }
        // y_k = u_k + g (Y_{k−1} − u_k): L(z) = ((1 − g) + (g − a) z⁻¹) / (1 − a z⁻¹).
        let (a, g) = lag_factors(dt / tau, interval_mean(s, channel));
        Some(crate::fit::TargetFilter {
            g0: 1.0 - g,
            g1: g - a,
            a,
        })
    }
    fn plausibility(&self, _coef: &[f64], _se: &[f64], p: Option<f64>) -> Plausibility {
        // The lag's gain is fixed at 1 (the delivered wrench IS the lagged command); only the
        // time constant can be unphysical.
        if let Some(tau) = p
            && tau >= *self.grid.last().unwrap_or(&f64::INFINITY)
        {
            return Plausibility::broken(
                "lag-range",
                format!(
                    "time constant {tau:.3} s at the end of the physical range {:.3}–{:.3} s",
                    self.grid.iter().copied().fold(f64::INFINITY, f64::min),
                    self.grid.iter().copied().fold(0.0, f64::max)
                ),
            );
        }
        Plausibility::ok()
    }
    fn driver(&self, s: &Signals) -> (String, Vec<f64>) {
        let fz = s.channel(2);
        (
            "thrust rate |dfz/dt| [N/s]".into(),
            crate::deriv::savitzky_golay_derivative(&s.t, &fz, 2)
                .iter()
                .map(|x| x.abs())
                .collect(),
        )
    }
}

/// Delay `d` \[s\] in whole samples of the log (`round(d / Δt)`, `Δt` the mean period).
fn whole_samples(s: &Signals, d: f64) -> i64 {
    let dt = s.mean_dt();
    if dt > 0.0 { (d / dt).round() as i64 } else { 0 }
}

/// A constant time offset `d` between the actuator stream and the motion stream: the wrench
/// acting at `t` is the logged `b(t − d)`. Column `b(t − d) − b(t)` on all six channels with
/// its coefficient fixed at 1 (a pure shift); `d` scanned, applied in whole samples of the
/// log: a shift between samples would interpolate, i.e. average the measurement noise of
/// neighbouring samples, which lowers the residual without any delay in the data.
#[derive(Debug, Clone)]
pub(crate) struct TimeDelay {
    /// Delays scanned \[s\] (positive: the actuator log is early).
    pub grid: Vec<f64>,
}

impl Default for TimeDelay {
    fn default() -> Self {
        let mut grid: Vec<f64> = (1..=12).map(|k| 0.01 * k as f64).collect();
        grid.extend((1..=12).map(|k| -0.01 * k as f64));
        Self { grid }
    }
}

/// `x(t − d)` at every sample by linear interpolation (clamped at the ends), in one
/// monotone sweep: the reference of the whole-sample shift in the unit tests.
#[cfg(test)]
pub(crate) fn shifted(t: &[f64], x: &[f64], d: f64) -> Vec<f64> {
    let n = t.len();
    let mut out = Vec::with_capacity(n);
    let mut k = 0usize;
    for &ti in t {
        let tq = ti - d;
        if tq <= t[0] {
            out.push(x[0]);
            continue;
        }
        if tq >= t[n - 1] {
            out.push(x[n - 1]);
            continue;
        }
        while k + 1 < n && t[k + 1] <= tq {
            k += 1;
        }
        let f = (tq - t[k]) / (t[k + 1] - t[k]);
        out.push(x[k] * (1.0 - f) + x[k + 1] * f);
    }
    out
}

impl Effect for TimeDelay {
    fn name(&self) -> &str {
        EffectKind::TimeDelay.name()
    }
    fn description(&self) -> &str {
        "constant time offset between the actuator stream and the motion stream"
    }
    fn channels(&self) -> Vec<Channel> {
        (0..6).collect()
    }
    fn scan(&self) -> Option<ScanSpec> {
        Some(ScanSpec {
            name: "delay".into(),
            unit: "s".into(),
            grid: self.grid.clone(),
            // No shift.
            start: Some(0.0),
        })
    }
    fn applied(&self, s: &Signals, d: f64) -> f64 {
        whole_samples(s, d) as f64 * s.mean_dt()
    }
    fn columns(&self, s: &Signals, p: Option<f64>) -> Vec<EffectColumn> {
        self.sampled_columns(s, p, 1)
    }
    fn sampled_columns(&self, s: &Signals, p: Option<f64>, stride: usize) -> Vec<EffectColumn> {
        let k = whole_samples(s, p.unwrap_or(0.02));
        let b = s.wrench();
        let n = b.len() as i64;
        let mut data: [Option<Vec<f64>>; 6] = Default::default();
        for (c, dd) in data.iter_mut().enumerate() {
            if b.iter().all(|x| x[c] == 0.0) {
                continue;
            }
            *dd = Some(
                (0..n)
                    .step_by(stride.max(1))
                    .map(|i| b[(i - k).clamp(0, n - 1) as usize][c] - b[i as usize][c])
                    .collect(),
            );
        }
        vec![EffectColumn {
            name: "g_delay".into(),
            unit: "1".into(),
            data,
            fixed: Some(1.0),
        }]
    }
    fn plausibility(&self, _coef: &[f64], _se: &[f64], p: Option<f64>) -> Plausibility {
        // A pure time shift: the gain is fixed at 1; only the delay can be unphysical.
        if let Some(d) = p {
            let max = self.grid.iter().fold(0.0f64, |m, x| m.max(x.abs()));
            if d.abs() >= max {
                return Plausibility::broken(
                    "delay-range",
                    format!("delay {d:.3} s at the end of the physical range ±{max:.3} s"),
                );
            }
        }
        Plausibility::ok()
    }
    fn driver(&self, s: &Signals) -> (String, Vec<f64>) {
        MotorLag::default().driver(s)
    }
}

/// Thrust-gain error: the delivered collective thrust is `(1 + κ)` times the logged one
/// (a wrong thrust coefficient, battery sag). Column `[0, 0, f_z, 0, 0, 0]`: identifiable only
/// with a known mass, which anchors `f_z`. The rotor torques scale alike, but there a common
/// factor is the inertia's scale, and where the measured torques are mostly rotor-speed noise
/// (a small quadrotor: 20 rad/s of noise against torques of 1e-4 N m) a `κ` on them regresses
/// that noise onto itself and drifts towards −1 with a vanishing inertia (measured: κ = −0.70
/// on a log without any thrust error); so `κ` acts on the thrust alone. In a joint fit of
/// several logs each log gets its own `κ` (a battery's charge differs from flight to flight).
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct ThrustGain;

impl Effect for ThrustGain {
    fn name(&self) -> &str {
        EffectKind::ThrustGain.name()
    }
    fn description(&self) -> &str {
        "delivered thrust is a constant factor (1 + kappa) times the logged thrust"
    }
    fn channels(&self) -> Vec<Channel> {
        vec![2]
    }
    fn needs_known_mass(&self) -> bool {
        true
    }
    fn per_log(&self) -> bool {
        true
    }
    fn columns(&self, s: &Signals, _p: Option<f64>) -> Vec<EffectColumn> {
        let mut data: [Option<Vec<f64>>; 6] = Default::default();
        data[2] = Some(s.channel(2));
        vec![EffectColumn {
            name: "kappa".into(),
            unit: "1".into(),
            data,
            fixed: None,
        }]
    }
    fn plausibility(&self, coef: &[f64], _se: &[f64], _p: Option<f64>) -> Plausibility {
        // One coefficient, or one per log in a joint fit.
        if let Some(k) = coef.iter().find(|k| k.abs() > 0.5) {
            Plausibility::broken(
                "thrust-gain-range",
                format!("thrust gain error {k:.2} beyond ±50 %"),
            )
        } else {
            Plausibility::ok()
        }
    }
    fn driver(&self, s: &Signals) -> (String, Vec<f64>) {
        ("thrust fz [N]".into(), s.channel(2))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The interval mean of the lag's state, written out independently: the exact mean of
    /// `u + (Y − u) e^{−s/τ}` over `s ∈ [0, Δt]`.
    fn interval_mean_lag(t: &[f64], u: &[f64], tau: f64) -> Vec<f64> {
        let mut y = vec![u[0]];
        let mut end = u[0];
        for k in 1..u.len() {
            let dt = t[k] - t[k - 1];
            let x = dt / tau;
            y.push(u[k] + (end - u[k]) * (1.0 - (-x).exp()) / x);
            end = u[k] + (end - u[k]) * (-x).exp();
        }
        y
    }

    /// The inverse lag undoes the forward lag (at the middle and as an interval mean) to
    /// rounding, on a jittery command and uneven steps, for time constants from a tenth of a
    /// step to ten steps.
    #[test]
    fn the_inverse_lag_undoes_the_lag() {
        let n = 400;
        let mut t = vec![0.0];
        for k in 1..n {
            t.push(t[k - 1] + 0.02 * (1.0 + 0.3 * ((k * 7919) % 13) as f64 / 13.0));
        }
        let u: Vec<f64> = (0..n)
            .map(|k| (0.3 * k as f64).sin() + 0.2 * (((k * 104_729) % 17) as f64 / 17.0 - 0.5))
            .collect();
        for tau in [0.002, 0.01, 0.02, 0.06, 0.2] {
            let mut mid = first_order_lag(&t, &u, tau);
            inverse_first_order_lag(&t, &mut mid, tau, false);
            let mut mean = interval_mean_lag(&t, &u, tau);
            inverse_first_order_lag(&t, &mut mean, tau, true);
            for k in 0..n {
                assert!((mid[k] - u[k]).abs() < 1e-9, "mid, tau {tau}, k {k}");
                assert!((mean[k] - u[k]).abs() < 1e-9, "mean, tau {tau}, k {k}");
            }
        }
    }
}
