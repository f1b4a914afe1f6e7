//! The regression design: the rigid-body columns, the effects' columns, the known-mass
//! target and the channel weights.

use std::borrow::Cow;

use tagk_dynamics::write_rigid_body_regressor;

use crate::effects::{
    Effect, EffectColumn, check_columns, check_lengths, cut_to_window, subsample,
};
use crate::fit::Model;
use crate::fit::columns::{Column, rigid_channels};
use crate::signals::Signals;
use crate::stats;

/// A regressor column: one value per sample on each channel it touches.
pub(crate) type ColData = [Option<Vec<f64>>; 6];

/// The ten rigid-body columns on a log, stored (`39 n` values: the fit itself reads them
/// block by block instead, [`Column::Rigid`], and the online pass per window; this is the
/// reference of the unit tests).
#[cfg(test)]
pub(crate) fn rigid_columns(s: &Signals) -> Vec<ColData> {
    let n = s.len();
    let mut cols: Vec<ColData> = (0..10)
        .map(|j| {
            let mut d: ColData = Default::default();
            for &c in rigid_channels(j) {
                d[c] = Some(vec![0.0; n]);
            }
            d
        })
        .collect();
    let mut buf = [0.0; 60];
    for i in 0..n {
        // Infallible: the buffer has 60 entries.
        let _ =
            write_rigid_body_regressor(&s.accel_proper[i], &s.omega(i), &s.omega_dot(i), &mut buf);
        for (j, col) in cols.iter_mut().enumerate() {
            for (c, d) in col.iter_mut().enumerate() {
                if let Some(v) = d {
                    v[i] = buf[10 * c + j];
                }
            }
        }
    }
    cols
}

/// The rigid-body design of a model and its regression target: with a known mass the mass
/// column moves to the target (`b − m·Y₀`) and only nine columns remain. The columns are
/// computed block by block where they are read ([`Column::Rigid`]); the target is the
/// signals' own ([`Signals::target`]) without a known mass.
pub(crate) fn rigid_design<'s>(
    model: &Model,
    s: &'s Signals,
) -> (Vec<Column<'static>>, Cow<'s, [[f64; 6]]>) {
    match model.known_mass() {
        None => (
            (0..10).map(Column::Rigid).collect(),
            Cow::Borrowed(s.target()),
        ),
        Some(m) => {
            let mut target = s.target().to_vec();
            let mut y = [0.0; 60];
            for (i, t) in target.iter_mut().enumerate() {
                // Infallible: the buffer has 60 entries.
                let _ = write_rigid_body_regressor(
                    &s.accel_proper[i],
                    &s.omega(i),
                    &s.omega_dot(i),
                    &mut y,
                );
                for &c in rigid_channels(0) {
                    t[c] -= m * y[10 * c];
                }
            }
            ((1..10).map(Column::Rigid).collect(), Cow::Owned(target))
        }
    }
}

/// Adds the known mass times the mass column back to a prediction made without it.
pub(crate) fn add_known_mass(model: &Model, s: &Signals, pred: &mut [[f64; 6]]) {
    if let Some(m) = model.known_mass() {
        for (p, a) in pred.iter_mut().zip(&s.accel_proper) {
            for c in 0..3 {
                p[c] += m * a[c];
            }
        }
    }
}

/// `true` for the name of a start-of-log nuisance column (`start_fz`, `start_fz@2` for the
/// second of joined logs): the unknown initial state of a filter, decaying. It is per log,
/// not the effect's physics.
pub(crate) fn is_start_nuisance(name: &str) -> bool {
    name.starts_with("start_")
}

/// An effect's part of the regression: the fitted columns and the known part (the fixed
/// columns times their values), both sign-flipped (`b = Yθ − Φβ`).
#[derive(Debug, Clone, Default)]
pub(crate) struct EffectDesign {
    /// Fitted columns.
    pub cols: Vec<ColData>,
    /// The fixed columns' sum, to move to the target (`None`: none).
    pub offset: Option<ColData>,
    /// Name and unit of each fitted column's coefficient ([`crate::effects::EffectColumn`]),
    /// in the order of `cols`.
    pub names: Vec<(String, String)>,
}

/// Turns effect columns into regression columns (`b = Yθ − Φβ`: sign flipped), smoothed like
/// the target ([`Signals::smooth_channels`]); fixed columns go into the offset. The effect
/// must be usable on the log ([`crate::effects::usable`]).
pub(crate) fn effect_design(effect: &dyn Effect, s: &Signals, p: Option<f64>) -> EffectDesign {
    design_of_columns(crate::effects::effect_columns(effect, s, p), s)
}

/// [`effect_design`] of columns already computed ([`crate::effects::effect_columns`] of the
/// effect on `s`): for a caller that checks them first.
pub(crate) fn design_of_columns(columns: Vec<EffectColumn>, s: &Signals) -> EffectDesign {
    design_of(smoothed(columns, s))
}

/// [`effect_design`] for an effect not yet known to be usable at `p`: `Err(reason)` when its
/// columns there fail [`check_columns`] (the columns are computed once, for the check and the
/// design).
pub(crate) fn checked_effect_design(
    effect: &dyn Effect,
    s: &Signals,
    p: Option<f64>,
) -> Result<EffectDesign, String> {
    let columns = crate::effects::effect_columns(effect, s, p);
    check_columns(&columns, s)?;
    Ok(design_of_columns(columns, s))
}

/// The columns smoothed like the target ([`Signals::smooth_channels`]).
fn smoothed(mut columns: Vec<EffectColumn>, s: &Signals) -> Vec<EffectColumn> {
    for c in &mut columns {
        s.smooth_channels(&mut c.data);
    }
    columns
}

/// [`effect_design`] at the samples `0, stride, 2 stride, …` only (each vector
/// `s.len().div_ceil(stride)` long, bit for bit the full design's values there): the columns
/// a scan reads ([`crate::fit::GramEngine::evaluate_sampled`]). From the effect's own
/// [`Effect::sampled_columns`] on a single log without smoothed channels; else (joined logs,
/// a smoothing filter, or sampled columns of the wrong length) the full design, subsampled.
/// `None` when the full columns have the wrong length too (a faulty user effect: the scan
/// skips the value).
pub(crate) fn sampled_effect_design(
    effect: &dyn Effect,
    s: &Signals,
    p: Option<f64>,
    stride: usize,
) -> Option<EffectDesign> {
    let stride = stride.max(1);
    let sampled_len = s.len().div_ceil(stride);
    if stride > 1 && s.parts().is_empty() && !s.smoothed.iter().any(|x| *x) {
        let columns = effect.sampled_columns(s, p, stride);
        if !columns.is_empty() && check_lengths(&columns, sampled_len).is_ok() {
            return Some(design_of(columns));
        }
    }
    let columns = crate::effects::effect_columns(effect, s, p);
    check_lengths(&columns, s.len()).ok()?;
    Some(design_of(subsample(smoothed(columns, s), stride)))
}

/// [`effect_design`] at the samples `window` only (each vector `window.len()` long, bit for
/// bit the full design's values there): the columns a scan of a filtering effect reads on a
/// long log ([`crate::fit::GramEngine::evaluate_window`]). From the effect's own
/// [`Effect::window_columns`] on a single log without smoothed channels; else (joined logs,
/// a smoothing filter, or window columns of the wrong length) the full design, cut.
/// `None` when the full columns have the wrong length too (a faulty user effect: the scan
/// skips the value).
pub(crate) fn window_effect_design(
    effect: &dyn Effect,
    s: &Signals,
    p: Option<f64>,
    window: std::ops::Range<usize>,
) -> Option<EffectDesign> {
    let window = window.start.min(s.len())..window.end.min(s.len());
    if s.parts().is_empty() && !s.smoothed.iter().any(|x| *x) {
        let columns = effect.window_columns(s, p, window.clone());
        if !columns.is_empty() && check_lengths(&columns, window.len()).is_ok() {
            return Some(design_of(columns));
        }
    }
    let columns = crate::effects::effect_columns(effect, s, p);
    check_lengths(&columns, s.len()).ok()?;
    Some(design_of(cut_to_window(smoothed(columns, s), window)))
}

/// The regression's side of effect columns: sign flipped (`b = Yθ − Φβ`), fitted columns kept,
/// fixed ones summed (times their values) into the offset. Pointwise: the same bits for any
/// subset of the samples.
fn design_of(columns: Vec<EffectColumn>) -> EffectDesign {
    let mut out = EffectDesign::default();
    for c in columns {
        let data: ColData = c
            .data
            .map(|d| d.map(|v| v.into_iter().map(|x| -x).collect()));
        match c.fixed {
            None => {
                out.cols.push(data);
                out.names.push((c.name, c.unit));
            }
            Some(value) => {
                let offset = out.offset.get_or_insert_with(Default::default);
                for (o, d) in offset.iter_mut().zip(data) {
                    let Some(d) = d else { continue };
                    match o {
                        Some(v) => v.iter_mut().zip(&d).for_each(|(a, b)| *a += value * b),
                        None => *o = Some(d.iter().map(|b| value * b).collect()),
                    }
                }
            }
        }
    }
    out
}

/// Adds `offset` (a sum of fixed columns) to per-sample values.
pub(crate) fn add_offset(values: &mut [[f64; 6]], offset: &ColData) {
    for (c, d) in offset.iter().enumerate() {
        if let Some(v) = d {
            for (x, o) in values.iter_mut().zip(v) {
                x[c] += o;
            }
        }
    }
}

/// The role of an effect in the actuator chain: a motor lag or a time delay (by name).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Actuator {
    /// The first-order motor lag (`motor-lag`).
    Lag,
    /// The time delay of the actuator stream (`time-delay`).
    Delay,
}

/// The role of `effect` in the actuator chain (`None`: neither a lag nor a delay).
pub(crate) fn actuator_role(effect: &dyn Effect) -> Option<Actuator> {
    use tagk_dynamics::EffectKind;
    match EffectKind::from_name(effect.name()) {
        Some(EffectKind::MotorLag) => Some(Actuator::Lag),
        Some(EffectKind::TimeDelay) => Some(Actuator::Delay),
        _ => None,
    }
}

/// The known part that composes a motor lag with a time delay in one model.
///
/// The plant delays the command, then lags it: the delivered wrench is `L b(t − d)`.
/// The two effects' own known parts sum to `L b − b` and `b(t − d) − b`. That sum misses
/// `(L − 1)(b(t − d) − b)`, as large as the lag itself when the delay is several samples.
/// This term adds it: the lag's known part `lag` (a design's offset, sign-flipped like it),
/// shifted by the delay `delay` \[s\] in whole samples, minus itself. `None` for a shift of
/// zero samples.
pub(crate) fn actuator_interaction(s: &Signals, lag: &ColData, delay: f64) -> Option<ColData> {
    let k = crate::effects::whole_samples(s, delay);
    if k == 0 {
        return None;
    }
    let out: ColData = std::array::from_fn(|c| {
        lag[c].as_ref().map(|v| {
            let n = v.len() as i64;
            (0..n)
                .map(|i| v[(i - k).clamp(0, n - 1) as usize] - v[i as usize])
                .collect()
        })
    });
    Some(out)
}

/// Initial channel weights from the measurement scale per unit group (forces, torques).
pub(crate) fn initial_weights(s: &Signals) -> [f64; 6] {
    let mut w = [1.0; 6];
    for group in [[0usize, 1, 2], [3, 4, 5]] {
        let scale = group
            .iter()
            .map(|&c| stats::rms(&s.channel(c)))
            .fold(0.0f64, f64::max);
        let scale = if scale > 0.0 { scale } else { 1.0 };
        for c in group {
            w[c] = 1.0 / scale;
        }
    }
    w
}

/// Weights `1 / rms` from a residual, floored at `1e-6` of each unit group's largest RMS.
pub(crate) fn weights_from_residual(res: &[[f64; 6]]) -> [f64; 6] {
    let mut r = [0.0; 6];
    for (c, rc) in r.iter_mut().enumerate() {
        *rc = stats::rms(&res.iter().map(|x| x[c]).collect::<Vec<_>>());
    }
    let mut w = [1.0; 6];
    for group in [[0usize, 1, 2], [3, 4, 5]] {
        let top = group.iter().map(|&c| r[c]).fold(0.0f64, f64::max);
        let floor = if top > 0.0 { top * 1e-6 } else { 1.0 };
        for c in group {
            w[c] = 1.0 / r[c].max(floor);
        }
    }
    w
}
