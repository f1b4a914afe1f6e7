//! Several logs of one vehicle: each log's own parameters under the joint model, against the
//! other logs'. This names a log of another vehicle state (a payload, another battery, a
//! velocity logged in mm/s) and leaves it out instead of blending it into one mass.
//!
//! The final joint model is fitted on each log alone ([`crate::fit_model`]). Its mass (when
//! fitted) and every effect coefficient with a standard error are compared across the logs.
//! Only the effects that describe the vehicle count. The wind, the thrust gain (a battery's
//! charge) and a sensor error change from flight to flight and are left out.
//!
//! A log's value is **inconsistent** when it lies further from the reference than
//! [`LOG_CONSISTENCY_Z`] combined standard errors *and* by more than a margin:
//!
//! - [`LOG_CONSISTENCY_RELATIVE`] of the reference's magnitude for the mass;
//! - a factor [`LOG_CONSISTENCY_EFFECT_FACTOR`] for an effect coefficient.
//!
//! The margin holds on the linear scale or — where both values are significant and of one
//! sign — as a ratio on the log scale. There a unit error shows: a drag coefficient 1000× off
//! with ±40 % on each log. The reference is the median of every log's value, with the median
//! log's standard error. With three logs or more, one odd log cannot move it. With two logs
//! it is the other log's value, so both are flagged and neither can be preferred.
//!
//! A flagged log is **left out of the joint fit** (its verdict says so and `agrees` is
//! false); the joint diagnosis is run again on the others. When no log is left (two logs that
//! disagree, or every log disagreeing with the median), the joint fit is refused
//! ([`DiagnoseError::InvalidOption`], field `logs`): diagnose them separately.

use serde::Serialize;

use tagk_dynamics::EffectKind;

use crate::effects::is_sensor_effect;
use crate::error::DiagnoseError;
use crate::fit::{Model, Z_95, fit_model};
use crate::signals::Signals;

/// How many combined standard errors (`√(se_log² + se_ref²)`) a log's parameter may lie from
/// the reference before it is inconsistent: 3.29, the two-sided 99.9 % quantile. Several
/// parameters of several logs are compared, so the 95 % quantile would flag a log of a
/// consistent set every few diagnoses.
pub const LOG_CONSISTENCY_Z: f64 = 3.290_526_731_491_926;

/// The smallest relative difference from the reference (a fraction of its magnitude) that
/// can make a log inconsistent: 10 %. Below it, a statistically significant difference
/// between long logs is a change of flight (battery, regime), not another vehicle.
pub const LOG_CONSISTENCY_RELATIVE: f64 = 0.1;

/// The smallest ratio between a log's effect coefficient and the reference that can make the
/// log inconsistent: 2. An effect coefficient varies with the flight (a rotor drag's `k_z` by
/// 11 % between two figure-8s of one simulated vehicle, beyond its intervals), since its
/// interval assumes the model is exact. A unit mistake is a larger factor: 3.6 (km/h), 100
/// (cm/s), 1000 (mm/s).
pub const LOG_CONSISTENCY_EFFECT_FACTOR: f64 = 2.0;

/// One parameter of one log's own fit of the joint model, against the other logs.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct LogParameter {
    /// The parameter: `mass`, or the effect and its coefficient (`linear-drag d_x`).
    pub name: String,
    /// Its unit.
    pub unit: String,
    /// The log's own value.
    pub value: f64,
    /// Its 95 % interval (`value ± 1.96 se`).
    pub interval: [f64; 2],
    /// The other consistent logs' value (inverse-variance weighted mean), if any.
    pub others: Option<f64>,
    /// Its 95 % interval.
    pub others_interval: Option<[f64; 2]>,
    /// `false` when this log's value is inconsistent with the others'
    /// ([`LOG_CONSISTENCY_Z`], [`LOG_CONSISTENCY_RELATIVE`]).
    pub consistent: bool,
}

impl LogParameter {
    /// The parameter in plain words: `mass 0.052 kg [0.051, 0.053]`, then against the others.
    pub fn describe(&self) -> String {
        let mut s = format!(
            "{} {} {} [{}, {}]",
            self.name,
            sig4(self.value),
            self.unit,
            sig4(self.interval[0]),
            sig4(self.interval[1])
        );
        if let (Some(o), Some([lo, hi])) = (self.others, self.others_interval) {
            let verb = if self.consistent {
                "others"
            } else {
                "differs from the others'"
            };
            s.push_str(&format!(
                " ({verb} {} [{}, {}])",
                sig4(o),
                sig4(lo),
                sig4(hi)
            ));
        }
        s
    }
}

/// `x` with four significant digits, plain between 1e-3 and 1e4, else in exponent notation.
fn sig4(x: f64) -> String {
    if x == 0.0 || !x.is_finite() {
        return format!("{x}");
    }
    let mag = x.abs().log10().floor() as i32;
    if (-3..4).contains(&mag) {
        let decimals = (3 - mag).max(0) as usize;
        format!("{x:.decimals$}")
    } else {
        format!("{x:.3e}")
    }
}

/// One estimate of one log: key, unit, value, standard error.
#[derive(Debug, Clone)]
pub(crate) struct Estimate {
    name: String,
    unit: String,
    value: f64,
    se: f64,
}

/// The parameters of `model` fitted on one log alone. These are the mass (when fitted) and
/// every coefficient with a standard error of the effects that describe the vehicle. Left out
/// are the per-segment start transients, per-log nuisances, the wind, the thrust gain and a
/// sensor error. Empty when the model cannot be fitted on this log alone.
pub(crate) fn estimates(model: &Model, s: &Signals) -> Vec<Estimate> {
    let Ok(fit) = fit_model(model, s, None) else {
        return Vec::new();
    };
    let mut out = Vec::new();
    if let Some(se) = fit.theta_se[0].filter(|se| se.is_finite()) {
        out.push(Estimate {
            name: "mass".into(),
            unit: "kg".into(),
            value: fit.theta.as_slice()[0],
            se,
        });
    }
    for e in fit
        .effects
        .iter()
        .filter(|e| is_vehicle_property(&e.effect))
    {
        for c in &e.coefficients {
            if crate::fit::is_start_nuisance(&c.name) || c.name.contains('@') {
                continue;
            }
            if let Some(se) = c.std_error.filter(|se| se.is_finite() && *se > 0.0) {
                out.push(Estimate {
                    name: format!("{} {}", e.effect, c.name),
                    unit: c.unit.clone(),
                    value: c.value,
                    se,
                });
            }
        }
    }
    out
}

/// `true` for an effect whose coefficients describe the vehicle, so that another value on
/// another log means another vehicle state; `false` for what changes from flight to flight
/// on one vehicle: the wind (the weather), the thrust gain (the battery's charge, already one
/// coefficient per log) and the sensor errors (an accelerometer offset after each power-up).
fn is_vehicle_property(effect: &str) -> bool {
    !is_sensor_effect(effect)
        && !matches!(
            EffectKind::from_name(effect),
            Some(EffectKind::Wind | EffectKind::ThrustGain)
        )
}

/// Whether `value ± se` is inconsistent with `reference ± se_ref`: further than
/// [`LOG_CONSISTENCY_Z`] combined standard errors and by more than `relative` of the
/// reference. This holds either on the linear scale, or — where both 95 % intervals exclude
/// zero on the same side — as a ratio on the log scale. That is the scale on which a unit
/// error (1000× for mm/s) shows: relative standard errors add there.
fn inconsistent_with(value: f64, se: f64, reference: f64, se_ref: f64, relative: f64) -> bool {
    let gap = (value - reference).abs();
    let linear = gap > LOG_CONSISTENCY_Z * se.hypot(se_ref) && gap > relative * reference.abs();
    let significant = |v: f64, s: f64| v.abs() > Z_95 * s;
    let ratio = value / reference;
    let scale = significant(value, se)
        && significant(reference, se_ref)
        && ratio > 0.0
        && ratio.ln().abs() > LOG_CONSISTENCY_Z * (se / value).hypot(se_ref / reference)
        && ratio.ln().abs() > relative.ln_1p();
    linear || scale
}

/// Each log's parameters against the others', and which logs are inconsistent.
///
/// `per_log[i]` are log `i`'s [`estimates`]. A parameter is compared only where every log has
/// it.
pub(crate) fn compare(per_log: &[Vec<Estimate>]) -> (Vec<Vec<LogParameter>>, Vec<bool>) {
    let n = per_log.len();
    let mut flagged = vec![false; n];
    let mut inconsistent: Vec<Vec<bool>> = per_log.iter().map(|e| vec![false; e.len()]).collect();
    let names: Vec<String> = per_log
        .first()
        .map(|e| e.iter().map(|x| x.name.clone()).collect())
        .unwrap_or_default();
    // Indices of each common parameter in each log.
    let common: Vec<Vec<usize>> = names
        .iter()
        .filter_map(|name| {
            per_log
                .iter()
                .map(|e| e.iter().position(|x| &x.name == name))
                .collect::<Option<Vec<usize>>>()
        })
        .collect();
    for idx in &common {
        // The mass by 10 %, an effect coefficient by a factor of 2.
        let relative = if per_log[0][idx[0]].name == "mass" {
            LOG_CONSISTENCY_RELATIVE
        } else {
            LOG_CONSISTENCY_EFFECT_FACTOR - 1.0
        };
        let values: Vec<f64> = (0..n).map(|i| per_log[i][idx[i]].value).collect();
        let ses: Vec<f64> = (0..n).map(|i| per_log[i][idx[i]].se).collect();
        // The median log(s): the reference value and its standard error.
        let mut order: Vec<usize> = (0..n).collect();
        order.sort_by(|&a, &b| values[a].total_cmp(&values[b]));
        let middle: &[usize] = if n % 2 == 1 {
            &order[n / 2..=n / 2]
        } else {
            &order[n / 2 - 1..=n / 2]
        };
        let median_value = middle.iter().map(|&j| values[j]).sum::<f64>() / middle.len() as f64;
        let median_se = middle.iter().map(|&j| ses[j]).sum::<f64>() / middle.len() as f64;
        for i in 0..n {
            let (reference, se_ref) = if n == 2 {
                (values[1 - i], ses[1 - i])
            } else {
                (median_value, median_se)
            };
            if inconsistent_with(values[i], ses[i], reference, se_ref, relative) {
                inconsistent[i][idx[i]] = true;
                flagged[i] = true;
            }
        }
    }
    // What each log is shown against: the pool of the other logs left in the joint fit.
    let params = (0..n)
        .map(|i| {
            per_log[i]
                .iter()
                .enumerate()
                .map(|(k, e)| {
                    let mut w_sum = 0.0;
                    let mut wv_sum = 0.0;
                    if let Some(idx) = common.iter().find(|idx| idx[i] == k) {
                        for j in (0..n).filter(|&j| j != i && !flagged[j]) {
                            let o = &per_log[j][idx[j]];
                            let w = o.se.powi(-2);
                            w_sum += w;
                            wv_sum += w * o.value;
                        }
                    }
                    let (others, others_interval) = if w_sum > 0.0 {
                        let v = wv_sum / w_sum;
                        let se = w_sum.sqrt().recip();
                        (Some(v), Some([v - Z_95 * se, v + Z_95 * se]))
                    } else {
                        (None, None)
                    };
                    LogParameter {
                        name: e.name.clone(),
                        unit: e.unit.clone(),
                        value: e.value,
                        interval: [e.value - Z_95 * e.se, e.value + Z_95 * e.se],
                        others,
                        others_interval,
                        consistent: !inconsistent[i][k],
                    }
                })
                .collect()
        })
        .collect();
    (params, flagged)
}

/// The note of a log left out of the joint fit: its inconsistent parameters in plain words.
pub(crate) fn excluded_note(log: &str, params: &[LogParameter]) -> String {
    let what: Vec<String> = params
        .iter()
        .filter(|p| !p.consistent)
        .map(LogParameter::describe)
        .collect();
    format!(
        "log {log}: {}: another vehicle state (payload, battery, a unit)? not blended: left out of the joint fit",
        what.join("; ")
    )
}

/// The refusal when no log is consistent with the others.
pub(crate) fn refusal(names: &[String], params: &[Vec<LogParameter>]) -> DiagnoseError {
    let what: Vec<String> = names
        .iter()
        .zip(params)
        .map(|(name, p)| {
            let bad: Vec<String> = p
                .iter()
                .filter(|p| !p.consistent)
                .map(LogParameter::describe)
                .collect();
            format!("{name}: {}", bad.join(", "))
        })
        .collect();
    DiagnoseError::InvalidOption {
        field: "logs",
        reason: format!(
            "the logs' own parameters differ beyond their intervals ({}): another vehicle state \
             in each? They are not blended into one fit: diagnose them separately (with a third \
             log of the same state, the odd one is left out)",
            what.join("; ")
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn est(name: &str, value: f64, se: f64) -> Estimate {
        Estimate {
            name: name.into(),
            unit: "kg".into(),
            value,
            se,
        }
    }

    /// Three logs of one vehicle within their intervals: none flagged; each is shown against
    /// the pool of the two others.
    #[test]
    fn consistent_logs_are_not_flagged() {
        let logs = vec![
            vec![est("mass", 0.0350, 2e-4)],
            vec![est("mass", 0.0352, 2e-4)],
            vec![est("mass", 0.0349, 3e-4)],
        ];
        let (params, flagged) = compare(&logs);
        assert_eq!(flagged, [false; 3]);
        let p = &params[0][0];
        assert!(p.consistent);
        let others = p.others.unwrap();
        assert!((others - 0.03508).abs() < 1e-4, "{others}");
    }

    /// A heavier vehicle among three: only it is flagged, named against the others' pool.
    #[test]
    fn the_odd_log_among_three_is_flagged() {
        let logs = vec![
            vec![est("mass", 0.0350, 2e-4), est("drag d_x", 7e-3, 2e-3)],
            vec![est("mass", 0.0520, 5e-4), est("drag d_x", 7e-3, 2e-3)],
            vec![est("mass", 0.0351, 2e-4), est("drag d_x", 7.5e-3, 2e-3)],
        ];
        let (params, flagged) = compare(&logs);
        assert_eq!(flagged, [false, true, false]);
        let note = excluded_note("b.csv", &params[1]);
        assert!(
            note.starts_with(
                "log b.csv: mass 0.05200 kg [0.05102, 0.05298] (differs from the others' 0.03505"
            ),
            "{note}"
        );
        assert!(note.contains("not blended"), "{note}");
    }

    /// A drag coefficient 1000× off (velocity in mm/s) is flagged on the log scale even where
    /// each log's interval is ±40 % and the linear test, dominated by the wide intervals,
    /// would not see it.
    #[test]
    fn a_unit_error_is_flagged_on_the_log_scale() {
        let logs = vec![
            vec![est("drag d_x", 7.1e-3, 2.5e-3)],
            vec![est("drag d_x", 7.0e-3, 2.6e-3)],
            vec![est("drag d_x", 7.1e-6, 2.8e-6)],
        ];
        assert!(7.1e-3 - 7.1e-6 <= LOG_CONSISTENCY_Z * 2.5e-3f64.hypot(2.8e-6));
        let (_, flagged) = compare(&logs);
        assert_eq!(flagged, [false, false, true]);
        // Insignificant values are not compared as ratios.
        let logs = vec![
            vec![est("drag d_x", 1e-3, 2e-3)],
            vec![est("drag d_x", 1e-6, 2e-3)],
            vec![est("drag d_x", -1e-4, 2e-3)],
        ];
        assert_eq!(compare(&logs).1, [false; 3]);
    }

    /// Two flights of one vehicle whose rotor drag `k_z` differs by 11 %, beyond the intervals
    /// (as two simulated figure-8s do): not flagged. Their masses 11 % apart would be.
    #[test]
    fn an_effect_coefficient_must_differ_by_a_factor_of_two() {
        let logs = vec![
            vec![est("rotor-drag k_z", 9.946e-7, 1.8e-8)],
            vec![est("rotor-drag k_z", 8.886e-7, 2.5e-8)],
        ];
        assert_eq!(compare(&logs).1, [false, false]);
        let logs = vec![
            vec![est("mass", 9.946e-7, 1.8e-8)],
            vec![est("mass", 8.886e-7, 2.5e-8)],
        ];
        assert_eq!(compare(&logs).1, [true, true]);
    }

    /// Two logs that disagree: both are flagged (neither can be preferred): the joint fit is
    /// refused, naming both.
    #[test]
    fn two_logs_that_disagree_are_both_flagged() {
        let logs = vec![
            vec![est("mass", 0.035, 2e-4)],
            vec![est("mass", 0.052, 2e-4)],
        ];
        let (params, flagged) = compare(&logs);
        assert_eq!(flagged, [true, true]);
        let err = refusal(&["a.csv".into(), "b.csv".into()], &params);
        let text = err.to_string();
        assert!(matches!(
            err,
            DiagnoseError::InvalidOption { field: "logs", .. }
        ));
        assert!(
            text.contains("a.csv: mass 0.03500 kg") && text.contains("b.csv: mass 0.05200 kg"),
            "{text}"
        );
    }
}
