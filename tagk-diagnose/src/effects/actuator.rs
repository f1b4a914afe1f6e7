//! The actuator stream: first-order motor lag, a time delay between the actuator and motion
//! streams, and a thrust-gain error.

use tagk_dynamics::EffectKind;
use tagk_dynamics::front_end::is_actuated;

use crate::effects::{Effect, EffectColumn, Plausibility, ScanSpec};
use crate::signals::{CHANNEL_NAMES, Channel, Signals};

/// First-order actuator dynamics: the delivered thrust and torques follow the logged command
/// through `τ ẏ = u − y`. Column: `y − b` on `fz, tx, ty, tz` (its gain fixed at 1). Here `y`
/// is the exact response to the piecewise-constant command held over each sample interval
/// (see [`first_order_lag`]). With rotor speeds the lag acts on each rotor speed, and the
/// wrench follows through the squares ([`lagged_rotors`]). The thrust is taken at the
/// interval's middle, the torques as its mean. Eight nuisance columns absorb the motors'
/// unknown speeds at the start of the log exactly: per rotor `ω_r e^{−(t − t₀)/τ}` through the
/// mixer, per channel `e^{−2(t − t₀)/τ}`. Without rotor speeds the lag acts on the wrench.
/// Four nuisance columns `e^{−(t − t₀)/τ}` (one per channel) then absorb its unknown state at
/// the start.
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
/// rather than its value at the interval's middle. With rotor speeds and a rotor mixer, the
/// torques are the interval means of the lagged rotors (what a differenced gyro sees). The
/// thrust is then its value at the middle. Without, every channel is lagged at the middle
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
/// the previous step are then reused. The time stamps of a uniformly sampled log differ in
/// their last bits, and the exponentials dominate a scan's cost. The error this makes, below
/// 1e-9 relative, is far below any log's resolution.
fn same_step(dt: f64, previous: f64) -> bool {
    (dt - previous).abs() <= 1e-9 * dt.abs()
}

/// The samples `0, stride, 2 stride, …` of a series of `n`, as they pass by in a loop over
/// every sample: `take(k)` is `Some(slot)` when sample `k` is one of them (without a division
/// per sample).
#[derive(Clone)]
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

/// The samples a column computation keeps, as they pass by in a loop over every sample of a
/// log: every `stride`-th from the first (a scan's subsample, [`Effect::sampled_columns`]) or
/// a contiguous window (a filter's scan window, [`Effect::window_columns`]).
#[derive(Clone)]
enum Keep {
    /// The samples `0, stride, 2 stride, …`.
    Every(Sampled),
    /// The samples of a range (clipped to the log).
    Window(std::ops::Range<usize>),
}

impl Keep {
    /// Every `stride`-th sample (a `stride` of 0 is read as 1).
    fn every(stride: usize) -> Self {
        Keep::Every(Sampled::new(stride))
    }

    /// The slot of sample 0, if it is kept.
    fn first(&self) -> Option<usize> {
        match self {
            Keep::Every(_) => Some(0),
            Keep::Window(r) => (r.start == 0 && r.end > 0).then_some(0),
        }
    }

    /// The slot of sample `k` if it is kept; called for `k = 1, 2, …` in order.
    fn next(&mut self, k: usize) -> Option<usize> {
        match self {
            Keep::Every(sampled) => sampled.next(),
            Keep::Window(r) => r.contains(&k).then(|| k - r.start),
        }
    }

    /// The samples of a log of `n` a loop must visit: `0..end` (none after the last kept).
    fn end(&self, n: usize) -> usize {
        match self {
            Keep::Every(_) => n,
            Keep::Window(r) => r.end.min(n),
        }
    }

    /// How many samples of a log of `n` are kept.
    fn count(&self, n: usize) -> usize {
        match self {
            Keep::Every(sampled) => n.div_ceil(sampled.stride),
            Keep::Window(r) => r.end.min(n).saturating_sub(r.start),
        }
    }
}

/// `e^{−(t − t₀)/τ}` at the samples `keep` (0 once below 1e-12; all 0 for `τ ≤ 0`), by the
/// recursion `x_k = x_{k−1} e^{−Δt_k/τ}` over every sample (one exponential per distinct
/// step).
fn start_decay(t: &[f64], tau: f64, mut keep: Keep) -> Vec<f64> {
    let mut out = vec![0.0; keep.count(t.len())];
    if t.is_empty() || tau <= 0.0 {
        return out;
    }
    let (mut x, mut last_dt, mut factor) = (1.0, f64::NAN, 0.0);
    if let Some(slot) = keep.first() {
        out[slot] = 1.0;
    }
    for k in 1..keep.end(t.len()) {
        let dt = t[k] - t[k - 1];
        if !same_step(dt, last_dt) {
            last_dt = dt;
            factor = (-dt / tau).exp();
        }
        x *= factor;
        if x < 1e-12 {
            break;
        }
        if let Some(slot) = keep.next(k) {
            out[slot] = x;
        }
    }
    out
}

/// Response of the first-order lag `τ ẏ = u − y` (time constant `tau` \[s\]) to a command
/// `u` held constant over each sample interval `[t_k − Δt/2, t_k + Δt/2)`. It is sampled at
/// its middle `t_k` (the convention of logs whose rows describe one control interval).
/// With `Y_k` the state at the end of interval `k`,
/// `y_k = u_k + e^{−Δt/2τ} (Y_{k−1} − u_k)`, `Y_k = u_k + e^{−Δt/τ} (Y_{k−1} − u_k)`,
/// starting at rest on the first command (`Y_0 = u_0`).
#[cfg(test)]
pub(crate) fn first_order_lag(t: &[f64], u: &[f64], tau: f64) -> Vec<f64> {
    sampled_first_order_lag(t, |k| u[k], tau, Keep::every(1))
}

/// [`first_order_lag`] of the command `u(k)` (`k < t.len()`) at the samples `keep` only (the
/// recursion runs over every sample up to the last kept).
fn sampled_first_order_lag(
    t: &[f64],
    u: impl Fn(usize) -> f64,
    tau: f64,
    mut keep: Keep,
) -> Vec<f64> {
    let mut y = Vec::with_capacity(keep.count(t.len()));
    if t.is_empty() {
        return y;
    }
    let mut end = u(0);
    if keep.first().is_some() {
        y.push(end);
    }
    let (mut last_dt, mut a_half, mut a_full) = (f64::NAN, 0.0, 0.0);
    for k in 1..keep.end(t.len()) {
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
        if keep.next(k).is_some() {
            y.push(uk + a_half * (end - uk));
        }
        end = uk + a_full * (end - uk);
    }
    y
}

/// A rotor-speed lag on a log with rotor speeds ([`lagged_rotors`]), at the kept samples
/// ([`Keep`]): the delivered `[fz, tx, ty, tz]` and the start-of-log transient's columns.
struct RotorLag {
    /// The delivered wrench `M lag_τ(ω)²` from rest on the first command: `fz` at the
    /// interval's middle, the torques as interval means \[N, N m\].
    wrench: Vec<[f64; 4]>,
    /// Per rotor `r`, the mixer's column `r` times `y_r(t) e^{−(t − t₀)/τ}` (`y_r` the lagged
    /// speed from rest): the cross term of a start offset `d_r` of rotor `r`, whose
    /// coefficient is `2 d_r` \[N, N m per rad/s\]. Only while the transient lasts (above
    /// 1e-12 of its start): 0 after.
    start_rotor: Vec<[[f64; 4]; 4]>,
    /// `e^{−2(t − t₀)/τ}` sampled as the channels are (`fz` at the middle, the torques as
    /// interval means): the square of the start offsets, one coefficient per channel
    /// (`Σ_r M_cr d_r²`). As long as [`RotorLag::start_rotor`].
    start_square: Vec<[f64; 2]>,
}

impl RotorLag {
    /// Column `pick(sample)` of the start transient at the `m` samples: its values while it
    /// lasts, then 0 (zeroed memory: a long log's tail costs nothing to build).
    fn start_column<T>(&self, of: &[T], m: usize, pick: impl Fn(&T) -> f64) -> Vec<f64> {
        let mut v = vec![0.0; m];
        for (x, y) in v.iter_mut().zip(of) {
            *x = pick(y);
        }
        v
    }
}

/// With rotor speeds in the log, the lag acts on each rotor speed and the wrench follows
/// through the squares. The mixer is identified from the log ([`Signals::rotor_mixer`]).
/// Without one this is `None`, and the lag is applied to the wrench directly. The delivered
/// wrench is `M lag_τ(ω)²`. The lagged speeds start at rest on the first command. The motors'
/// unknown speeds when the log starts add `d_r e^{−(t − t₀)/τ}` to rotor `r`. Hence they add
/// `2 d_r y_r e^{−(t − t₀)/τ} + d_r² e^{−2(t − t₀)/τ}` to its square. Both are kept as columns
/// ([`RotorLag`]), so the start is exact for any offsets. Each sample is the exact response
/// to the command held over its interval `[t_k − Δt/2, t_k + Δt/2)`. The thrust is taken at
/// the middle (what an accelerometer sample sees). The torques are the interval mean (what a
/// differenced gyro, the logged angular acceleration, sees). At the samples `keep` (the lag
/// runs over every sample up to the last kept).
fn lagged_rotors(s: &Signals, tau: f64, mut keep: Keep) -> Option<RotorLag> {
    let w = s.rotor_speeds()?;
    let mixer = s.rotor_mixer()?;
    let n = s.len();
    let mut out = RotorLag {
        wrench: Vec::with_capacity(keep.count(n)),
        start_rotor: Vec::new(),
        start_square: Vec::new(),
    };
    if n == 0 {
        return Some(out);
    }
    // Per step x = Δt/τ: e^{−x/2}, e^{−x}, and the interval means of e^{−σ/τ} and e^{−2σ/τ}.
    let factors = |dt: f64| -> [f64; 4] {
        if tau > 0.0 {
            let x = dt / tau;
            let a = (-x).exp();
            [
                (-0.5 * x).exp(),
                a,
                (1.0 - a) / x,
                (1.0 - a * a) / (2.0 * x),
            ]
        } else {
            [0.0; 4]
        }
    };
    // Rotor r's column through the mixer: fz from the middle value, torques from the mean.
    let through = |r: usize, mid: f64, mean: f64| -> [f64; 4] {
        std::array::from_fn(|c| mixer.matrix[c][r] * if c == 0 { mid } else { mean })
    };
    let mut end = w[0];
    // The transient e^{−(t − t₀)/τ} at the start of the current interval: 1 at the middle of
    // the first (its length that of the first step).
    let first = factors(if n > 1 { s.t[1] - s.t[0] } else { 0.0 });
    let mut z = if first[0] > 0.0 { 1.0 / first[0] } else { 0.0 };
    if keep.first().is_some() {
        out.wrench.push({
            let sq = end.map(|x| x * x);
            mixer.apply(&sq)
        });
        out.start_rotor.push(std::array::from_fn(|r| {
            through(r, end[r], end[r] * z * first[2])
        }));
        out.start_square.push([1.0, z * z * first[3]]);
    }
    z *= first[1];
    let mut step = (f64::NAN, [0.0; 4]);
    for i in 1..keep.end(n) {
        let dt = s.t[i] - s.t[i - 1];
        // Uniform sampling reuses the factors (the exponentials dominate a scan's cost).
        if !same_step(dt, step.0) {
            step = (dt, factors(dt));
        }
        let [a_half, a_full, m1, m2] = step.1;
        let u = w[i];
        let e: [f64; 4] = std::array::from_fn(|r| end[r] - u[r]);
        if let Some(slot) = keep.next(i) {
            let mut mid = [0.0; 4];
            let mut mean = [0.0; 4];
            for r in 0..4 {
                let ym = u[r] + a_half * e[r];
                mid[r] = ym * ym;
                mean[r] = u[r] * u[r] + 2.0 * u[r] * e[r] * m1 + e[r] * e[r] * m2;
            }
            let ym = mixer.apply(&mid);
            let ya = mixer.apply(&mean);
            out.wrench.push([ym[0], ya[1], ya[2], ya[3]]);
            // Once the transient is below 1e-12 of its start, its columns stay 0: the kept
            // entries are the first slots'.
            if z >= 1e-12 && out.start_rotor.len() == slot {
                out.start_rotor.push(std::array::from_fn(|r| {
                    let at_mid = (u[r] + a_half * e[r]) * z * a_half;
                    let mean = z * (u[r] * m1 + e[r] * m2);
                    through(r, at_mid, mean)
                }));
                out.start_square.push([(z * a_half).powi(2), z * z * m2]);
            }
        }
        end = std::array::from_fn(|r| u[r] + a_full * e[r]);
        z *= a_full;
    }
    Some(out)
}

/// The inverse of the first-order lag of [`first_order_lag`], applied in place to `y` sampled
/// at `t`: the command `u` whose lagged response is `y`. With `interval_mean`, it inverts the
/// interval mean of the lag's state instead of its value at the interval's middle. Let `Y` be
/// the state at the end of interval `k` and `g` the factor of the sampled output
/// (`y_k = u_k + g (Y_{k−1} − u_k)`: `g = e^{−Δt/2τ}` at the middle, `(1 − e^{−Δt/τ}) τ/Δt`
/// for the interval mean). Then `u_k = (y_k − g Y_{k−1}) / (1 − g)` and
/// `Y_k = u_k + e^{−Δt/τ} (Y_{k−1} − u_k)`, from `u_0 = y_0`. It is stable: its pole
/// `(e^{−Δt/τ} − g)/(1 − g)` lies in `(−1, 0]`.
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

impl MotorLag {
    /// The columns at the samples `keep` ([`Keep`]); `kept`: the measured wrench there.
    fn kept_columns<'a>(
        &self,
        s: &Signals,
        p: Option<f64>,
        keep: Keep,
        kept: impl Iterator<Item = &'a [f64; 6]> + Clone,
    ) -> Vec<EffectColumn> {
        let tau = self.tau(p);
        let b = s.wrench();
        let mut data: [Option<Vec<f64>>; 6] = Default::default();
        let rotors = lagged_rotors(s, tau, keep.clone());
        if let Some(lagged) = &rotors {
            for (c, d) in data.iter_mut().enumerate().skip(2) {
                *d = Some(
                    lagged
                        .wrench
                        .iter()
                        .zip(kept.clone())
                        .map(|(y, b)| y[c - 2] - b[c])
                        .collect(),
                );
            }
        } else {
            for (c, d) in data.iter_mut().enumerate().skip(2) {
                let y = sampled_first_order_lag(&s.t, |k| b[k][c], tau, keep.clone());
                *d = Some(y.iter().zip(kept.clone()).map(|(y, b)| y - b[c]).collect());
            }
        }
        let mut cols = vec![EffectColumn {
            name: "g_lag".into(),
            unit: "1".into(),
            data,
            fixed: Some(1.0),
        }];
        // The actuators' state when the log starts is unknown: nuisance columns of its decay.
        let unit = |c: usize| if c == 2 { "N" } else { "N m" };
        match &rotors {
            // Per rotor the cross term (coefficient 2 d_r), per channel the squares.
            Some(lagged) => {
                let m = lagged.wrench.len();
                for r in 0..4 {
                    let mut data: [Option<Vec<f64>>; 6] = Default::default();
                    for (c, d) in data.iter_mut().enumerate().skip(2) {
                        *d = Some(lagged.start_column(&lagged.start_rotor, m, |v| v[r][c - 2]));
                    }
                    cols.push(EffectColumn::new(
                        &format!("start_w{}", r + 1),
                        "rad/s",
                        data,
                    ));
                }
                for c in 2..6 {
                    let which = usize::from(interval_mean(s, c));
                    cols.push(EffectColumn::on(
                        &format!("start_sq_{}", CHANNEL_NAMES[c]),
                        unit(c),
                        c,
                        lagged.start_column(&lagged.start_square, m, |v| v[which]),
                    ));
                }
            }
            // A lag of the wrench itself: its decay e^{−(t − t₀)/τ}, one column per channel.
            None => {
                let decay = start_decay(&s.t, tau, keep);
                for c in 2..6 {
                    cols.push(EffectColumn::on(
                        &format!("start_{}", CHANNEL_NAMES[c]),
                        unit(c),
                        c,
                        decay.clone(),
                    ));
                }
            }
        }
        cols
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
        let kept = s.wrench().iter().step_by(stride);
        self.kept_columns(s, p, Keep::every(stride), kept)
    }
    fn window_columns(
        &self,
        s: &Signals,
        p: Option<f64>,
        window: std::ops::Range<usize>,
    ) -> Vec<EffectColumn> {
        let b = s.wrench();
        let end = window.end.min(b.len());
        let window = window.start.min(end)..end;
        self.kept_columns(s, p, Keep::Window(window.clone()), b[window].iter())
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
pub(crate) fn whole_samples(s: &Signals, d: f64) -> i64 {
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

/// Rotor-speed telemetry filtering (`telemetry-lag`): each rotor's *reported* speed is a
/// first-order filter of its true speed, `y_k = α y_{k−1} + (1 − α) x_k` with
/// `α = e^{−Δt/τ_tel}` (the filter of the simulator's `TelemetryLag`). It lags the measurement,
/// not the thrust: the wrench acting is that of the true speeds, which the inverse filter
/// recovers exactly from the reported ones, `x_k = (y_k − α y_{k−1}) / (1 − α)` from
/// `x_0 = y_0` ([`inverse_telemetry_filter`]). Column `M x² − b` on `fz, tx, ty, tz` (`M` the
/// mixer identified from the log, `b` the logged wrench), its gain fixed at 1: the regression's
/// target becomes the wrench of the recovered speeds. Without rotor speeds the inverse filter
/// acts on the wrench itself. It needs no start-of-log column: the inverse is a two-tap
/// filter. The telemetry's pure delay is `time-delay` at a negative delay (a late actuator
/// stream, whole samples).
#[derive(Debug, Clone)]
pub(crate) struct TelemetryLag {
    /// Time constants scanned \[s\].
    pub grid: Vec<f64>,
}

impl Default for TelemetryLag {
    fn default() -> Self {
        Self {
            grid: MotorLag::default().grid,
        }
    }
}

impl TelemetryLag {
    /// The time constant \[s\]: `p`, else the middle of the grid.
    fn tau(&self, p: Option<f64>) -> f64 {
        p.unwrap_or(self.grid[self.grid.len() / 2])
    }
}

/// The telemetry filter's factor `α = e^{−Δt/τ}` over a step `dt` \[s\] (0 for `τ ≤ 0`).
fn telemetry_alpha(dt: f64, tau: f64) -> f64 {
    if tau > 0.0 { (-dt / tau).exp() } else { 0.0 }
}

/// The telemetry filter `y_k = α y_{k−1} + (1 − α) x_k` (`α = e^{−Δt_k/τ}`, `Δt_k` the
/// step before sample `k`), from `y_0 = x_0`, in place on `x` sampled at `t`.
pub(crate) fn telemetry_filter(t: &[f64], x: &mut [f64], tau: f64) {
    let mut y = match x.first() {
        Some(v) => *v,
        None => return,
    };
    let (mut last_dt, mut alpha) = (f64::NAN, 0.0);
    for k in 1..x.len().min(t.len()) {
        let dt = t[k] - t[k - 1];
        if !same_step(dt, last_dt) {
            last_dt = dt;
            alpha = telemetry_alpha(dt, tau);
        }
        y = alpha * y + (1.0 - alpha) * x[k];
        x[k] = y;
    }
}

/// The inverse of [`telemetry_filter`] in place on `y` sampled at `t`:
/// `x_k = (y_k − α y_{k−1}) / (1 − α)`, `x_0 = y_0`. Two taps, no state.
pub(crate) fn inverse_telemetry_filter(t: &[f64], y: &mut [f64], tau: f64) {
    if y.is_empty() || tau <= 0.0 {
        return;
    }
    let mut previous = y[0];
    let (mut last_dt, mut alpha) = (f64::NAN, 0.0);
    for k in 1..y.len().min(t.len()) {
        let dt = t[k] - t[k - 1];
        if !same_step(dt, last_dt) {
            last_dt = dt;
            alpha = telemetry_alpha(dt, tau);
        }
        let reported = y[k];
        y[k] = (reported - alpha * previous) / (1.0 - alpha);
        previous = reported;
    }
}

impl Effect for TelemetryLag {
    fn name(&self) -> &str {
        EffectKind::TelemetryLag.name()
    }
    fn description(&self) -> &str {
        "rotor-speed telemetry filtered: the logged speeds lag the rotors by a time constant"
    }
    fn channels(&self) -> Vec<Channel> {
        vec![2, 3, 4, 5]
    }
    fn scan(&self) -> Option<ScanSpec> {
        Some(ScanSpec {
            name: "tau_tel".into(),
            unit: "s".into(),
            grid: self.grid.clone(),
            start: self.grid.iter().copied().reduce(f64::min),
        })
    }
    fn columns(&self, s: &Signals, p: Option<f64>) -> Vec<EffectColumn> {
        let tau = self.tau(p);
        let b = s.wrench();
        let mut data: [Option<Vec<f64>>; 6] = Default::default();
        match (s.rotor_speeds(), s.rotor_mixer()) {
            (Some(w), Some(mixer)) => {
                let recovered: Vec<Vec<f64>> = (0..4)
                    .map(|r| {
                        let mut x: Vec<f64> = w.iter().map(|v| v[r]).collect();
                        inverse_telemetry_filter(&s.t, &mut x, tau);
                        x
                    })
                    .collect();
                for (c, d) in data.iter_mut().enumerate().skip(2) {
                    let m = &mixer.matrix[c - 2];
                    *d = Some(
                        (0..b.len())
                            .map(|i| {
                                (0..4).map(|j| m[j] * recovered[j][i].powi(2)).sum::<f64>()
                                    - b[i][c]
                            })
                            .collect(),
                    );
                }
            }
            _ => {
                for (c, d) in data.iter_mut().enumerate().skip(2) {
                    let mut x: Vec<f64> = b.iter().map(|v| v[c]).collect();
                    inverse_telemetry_filter(&s.t, &mut x, tau);
                    *d = Some(x.iter().zip(b).map(|(x, b)| x - b[c]).collect());
                }
            }
        }
        vec![EffectColumn {
            name: "g_tel".into(),
            unit: "1".into(),
            data,
            fixed: Some(1.0),
        }]
    }
    fn unfilter(&self, s: &Signals, p: Option<f64>, channel: Channel, series: &mut [f64]) -> bool {
        if !is_actuated(channel) {
            return false;
        }
        telemetry_filter(&s.t, series, self.tau(p));
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
        let (tau, dt) = (self.tau(p), s.mean_dt());
        if !(tau > 0.0 && dt > 0.0) {
            return None;
        }
        // The inverse filter: F(z) = (1 − α z⁻¹) / (1 − α), no pole.
        let alpha = telemetry_alpha(dt, tau);
        Some(crate::fit::TargetFilter {
            g0: 1.0 / (1.0 - alpha),
            g1: -alpha / (1.0 - alpha),
            a: 0.0,
        })
    }
    fn plausibility(&self, _coef: &[f64], _se: &[f64], p: Option<f64>) -> Plausibility {
        MotorLag {
            grid: self.grid.clone(),
        }
        .plausibility(&[], &[], p)
    }
    fn driver(&self, s: &Signals) -> (String, Vec<f64>) {
        MotorLag::default().driver(s)
    }
}

/// Thrust-gain error: the delivered collective thrust is `(1 + κ)` times the logged one
/// (a wrong thrust coefficient, battery sag). Column `[0, 0, f_z, 0, 0, 0]`: identifiable only
/// with a known mass, which anchors `f_z`. The rotor torques scale alike, but there a common
/// factor is the inertia's scale. The measured torques may be mostly rotor-speed noise (a
/// small quadrotor: 20 rad/s of noise against torques of 1e-4 N m). Then a `κ` on them
/// regresses that noise onto itself and drifts towards −1 with a vanishing inertia (measured:
/// κ = −0.70 on a log without any thrust error). So `κ` acts on the thrust alone. In a joint
/// fit of several logs each log gets its own `κ` (a battery's charge differs from flight to
/// flight).
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
        vec![EffectColumn::new("kappa", "1", data)]
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

    /// The telemetry filter against its closed forms (`α = e^{−Δt/τ}`, uniform steps): a unit
    /// step at sample 1 gives `1 − α^k`; a ramp `x_k = k` gives `k − c (1 − α^k)` with the
    /// steady lag `c = α/(1 − α)` samples. Its inverse gives the input back.
    #[test]
    fn the_telemetry_filter_is_the_closed_form_and_its_inverse_undoes_it() {
        let (dt, tau): (f64, f64) = (0.02, 0.03);
        let alpha = (-dt / tau).exp();
        let t: Vec<f64> = (0..40).map(|k| k as f64 * dt).collect();
        let mut step: Vec<f64> = (0..40).map(|k| if k == 0 { 0.0 } else { 1.0 }).collect();
        telemetry_filter(&t, &mut step, tau);
        let mut ramp: Vec<f64> = (0..40).map(|k| k as f64).collect();
        telemetry_filter(&t, &mut ramp, tau);
        let c = alpha / (1.0 - alpha);
        for k in 0..40 {
            let kf = k as f64;
            assert!(
                (step[k] - (1.0 - alpha.powi(k as i32))).abs() < 1e-12,
                "{k}"
            );
            assert!(
                (ramp[k] - (kf - c * (1.0 - alpha.powi(k as i32)))).abs() < 1e-11,
                "{k}"
            );
        }
        inverse_telemetry_filter(&t, &mut ramp, tau);
        for (k, x) in ramp.iter().enumerate() {
            assert!((x - k as f64).abs() < 1e-9, "{k}: {x}");
        }
        // The target filter is the inverse's transfer function: its taps on a unit impulse.
        let mut impulse = vec![0.0; 5];
        impulse[1] = 1.0;
        inverse_telemetry_filter(&t[..5], &mut impulse, tau);
        assert!((impulse[1] - 1.0 / (1.0 - alpha)).abs() < 1e-12);
        assert!((impulse[2] + alpha / (1.0 - alpha)).abs() < 1e-12);
        assert_eq!(impulse[3], 0.0);
    }

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

    /// A Crazyflie-like rotor mixer `[fz, tx, ty, tz] = M ω²`.
    /// A 300-sample log whose rotor speeds are sines with steps every `block` samples (phase
    /// per rotor), and whose wrench is the nominal mixer's of those speeds.
    fn rotor_speed_log(block: usize, frequency: f64) -> (tagk_dynamics::FlightLog, Vec<[f64; 4]>) {
        let m = mixer();
        let mut log =
            crate::testdata::synthetic_log(&crate::testdata::crazyflie(), 300, 0.0, 1, &|_, _| {
                [0.0; 6]
            });
        let speeds: Vec<[f64; 4]> = (0..log.len())
            .map(|k| {
                std::array::from_fn(|r| {
                    let x = k as f64;
                    let step = if (k / block + r).is_multiple_of(3) {
                        150.0
                    } else {
                        0.0
                    };
                    2000.0 + 300.0 * (frequency * x + r as f64).sin() + step
                })
            })
            .collect();
        for (b, w) in log.wrench.iter_mut().zip(&speeds) {
            let sq = w.map(|x| x * x);
            for c in 0..4 {
                b[c + 2] = (0..4).map(|r| m[c][r] * sq[r]).sum();
            }
        }
        log.rotor_speeds = Some(speeds.clone());
        (log, speeds)
    }

    fn mixer() -> [[f64; 4]; 4] {
        let (kf, km, l) = (2.88e-8, 7.24e-10, 0.0325 / std::f64::consts::SQRT_2);
        [
            [kf, kf, kf, kf],
            [-kf * l, -kf * l, kf * l, kf * l],
            [-kf * l, kf * l, kf * l, -kf * l],
            [-km, km, -km, km],
        ]
    }

    /// The rotor-speed lag integrated independently: `τ ω̇ = u − ω` by RK4 at 400 steps per
    /// sample interval (`[t_k − Δt/2, t_k + Δt/2)`, the command `u_k` held), starting from
    /// `u_0 + d` at the first interval's start. Returns per sample `[fz, tx, ty, tz]`: `M ω²`
    /// at the interval's middle for `fz`, the interval mean of `M ω²` (Simpson) for the
    /// torques.
    fn integrated_rotor_lag(
        t: &[f64],
        u: &[[f64; 4]],
        d: [f64; 4],
        tau: f64,
        m: &[[f64; 4]; 4],
    ) -> Vec<[f64; 4]> {
        const STEPS: usize = 400;
        let apply = |w: &[f64; 4]| -> [f64; 4] {
            std::array::from_fn(|c| (0..4).map(|r| m[c][r] * w[r] * w[r]).sum())
        };
        let mut w: [f64; 4] = std::array::from_fn(|r| u[0][r] + d[r]);
        let mut out = Vec::with_capacity(t.len());
        for k in 0..t.len() {
            let dt = if k == 0 { t[1] - t[0] } else { t[k] - t[k - 1] };
            let h = dt / STEPS as f64;
            let mut mean = [0.0; 4];
            let mut mid = [0.0; 4];
            for j in 0..=STEPS {
                let v = apply(&w);
                let weight = if j == 0 || j == STEPS {
                    1.0
                } else if j % 2 == 1 {
                    4.0
                } else {
                    2.0
                };
                for c in 0..4 {
                    mean[c] += weight * v[c] / (3.0 * STEPS as f64);
                }
                if j == STEPS / 2 {
                    mid = v;
                }
                if j == STEPS {
                    break;
                }
                let f = |x: f64, r: usize| (u[k][r] - x) / tau;
                w = std::array::from_fn(|r| {
                    let k1 = f(w[r], r);
                    let k2 = f(w[r] + 0.5 * h * k1, r);
                    let k3 = f(w[r] + 0.5 * h * k2, r);
                    let k4 = f(w[r] + h * k3, r);
                    w[r] + h / 6.0 * (k1 + 2.0 * (k2 + k3) + k4)
                });
            }
            out.push([mid[0], mean[1], mean[2], mean[3]]);
        }
        out
    }

    /// The lag of each rotor speed seen through the squares, against an independent
    /// integration. On a log with rotor speeds, the delivered `[fz, tx, ty, tz]` minus the
    /// logged one is the lag's column plus a least-squares combination of its start columns.
    /// This holds to 1e-7 of the lag's largest wrench, for motors that start 5–10 % off their
    /// first command, at time constants from under a step to several steps. The start columns
    /// are needed: without them the first samples miss by far more.
    #[test]
    fn the_rotor_lag_with_its_start_columns_is_the_integrated_lag() {
        use nalgebra::{DMatrix, DVector};
        let m = mixer();
        let (log, speeds) = rotor_speed_log(37, 0.05);
        let s = Signals::from_log(&log).unwrap();
        assert!(s.rotor_mixer().is_some());
        let d = [-180.0, 120.0, 200.0, -100.0];
        for tau in [0.004, 0.02, 0.06] {
            let truth = integrated_rotor_lag(&s.t, &speeds, d, tau, &m);
            let cols = MotorLag::default().columns(&s, Some(tau));
            let b = s.wrench();
            let n = s.len();
            // Target: delivered − logged − the lag's fixed column, channels fz..tz stacked.
            let target = DVector::from_fn(4 * n, |i, _| {
                let (c, k) = (i / n, i % n);
                truth[k][c] - b[k][c + 2] - cols[0].data[c + 2].as_ref().unwrap()[k]
            });
            let start: Vec<&EffectColumn> = cols[1..].iter().collect();
            assert!(start.iter().all(|c| crate::fit::is_start_nuisance(&c.name)));
            let x = DMatrix::from_fn(4 * n, start.len(), |i, j| {
                let (c, k) = (i / n, i % n);
                start[j].data[c + 2].as_ref().map_or(0.0, |v| v[k])
            });
            // Columns scaled to unit norm for the solve.
            let norms: Vec<f64> = x.column_iter().map(|c| c.norm().max(1e-300)).collect();
            let xs = DMatrix::from_fn(x.nrows(), x.ncols(), |i, j| x[(i, j)] / norms[j]);
            let beta = xs.clone().svd(true, true).solve(&target, 1e-14).unwrap();
            let residual = &target - &xs * &beta;
            let scale = (0..4 * n)
                .map(|i| (truth[i % n][i / n] - b[i % n][i / n + 2]).abs())
                .fold(0.0, f64::max);
            let worst = residual.amax();
            assert!(worst < 1e-7 * scale, "tau {tau}: {worst:e} of {scale:e}");
            assert!(target.amax() > 1e-3 * scale, "tau {tau}: the start matters");
        }
    }

    /// A delay before a rotor-speed lag, against an independent integration. The plant lags
    /// the delayed command: `[fz, tx, ty, tz] = M (L ω(t − d))²`, integrated by RK4. The
    /// logged wrench plus the lag's column, the delay's column and their interaction
    /// ([`crate::fit::actuator_interaction`]) is that wrench to 1e-7 of the lag's size. The
    /// two columns alone (their sum, without the interaction) miss it by far more.
    #[test]
    fn a_delay_before_the_lag_composes_with_it() {
        let m = mixer();
        let (log, speeds) = rotor_speed_log(23, 0.07);
        let s = Signals::from_log(&log).unwrap();
        let dt = s.mean_dt();
        let b = s.wrench();
        let n = s.len();
        for (tau, k) in [(0.006, 1usize), (0.02, 3), (0.05, 6)] {
            // The command the motors see: the logged speeds `k` samples late.
            let late: Vec<[f64; 4]> = (0..n).map(|i| speeds[i.saturating_sub(k)]).collect();
            let truth = integrated_rotor_lag(&s.t, &late, [0.0; 4], tau, &m);
            let lag = MotorLag::default().columns(&s, Some(tau))[0].data.clone();
            let delay = TimeDelay::default().columns(&s, Some(k as f64 * dt))[0]
                .data
                .clone();
            let cross = crate::fit::actuator_interaction(&s, &lag, k as f64 * dt).unwrap();
            let (mut worst, mut additive, mut scale) = (0.0f64, 0.0f64, 0.0f64);
            for c in 2..6 {
                let (l, d, x) = (
                    lag[c].as_ref().unwrap(),
                    delay[c].as_ref().unwrap(),
                    cross[c].as_ref().unwrap(),
                );
                for i in 0..n {
                    let sum = b[i][c] + l[i] + d[i];
                    let t = truth[i][c - 2];
                    worst = worst.max((sum + x[i] - t).abs());
                    additive = additive.max((sum - t).abs());
                    scale = scale.max((t - b[i][c]).abs());
                }
            }
            assert!(
                worst < 1e-7 * scale,
                "tau {tau}, k {k}: {worst:e} of {scale:e}"
            );
            assert!(
                additive > 1e-3 * scale,
                "tau {tau}, k {k}: the interaction matters ({additive:e} of {scale:e})"
            );
        }
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
