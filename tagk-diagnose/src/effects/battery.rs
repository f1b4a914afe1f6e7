//! Battery voltage: the rotor map falls with the battery's voltage.

use tagk_dynamics::{BATTERY_COLUMN, BATTERY_REFERENCE_VOLTAGE, EffectKind};

use crate::effects::{Effect, EffectColumn, Plausibility};
use crate::signals::{Channel, Signals};

/// Battery-voltage dependence of the rotor map (`battery-voltage`): with the logged battery
/// voltage `V` \[V\] (column `vbat`), the rotors make `(1 + β (V − V_ref)/V_ref)` times their
/// nominal thrust and torque. `V_ref` is [`BATTERY_REFERENCE_VOLTAGE`] (3.8 V), a stated
/// reference: a fitted `β` then flies in the simulator as it is.
///
/// One column, `β`: the logged thrust `f_z` times `(V − V_ref)/V_ref`. On the thrust alone,
/// for the reason of `thrust-gain`: a factor on the logged torques regresses their rotor-speed
/// noise onto itself.
///
/// Identifiability: the column's mean over the log trades against the mass, like
/// `thrust-gain`. Its variation over the flight (the battery drains, the voltage sags with the
/// thrust) does not: the mass is constant. So it needs no known mass on a log whose voltage
/// varies; a test measures `β` recovered with the mass free. Needs the `vbat` column.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct BatteryVoltage;

/// The column `(V − V_ref)/V_ref` of `signals`, if it has a battery-voltage column.
fn relative_voltage(s: &Signals) -> Option<Vec<f64>> {
    let v = s.log().signal(BATTERY_COLUMN)?;
    Some(
        v.iter()
            .map(|v| (v - BATTERY_REFERENCE_VOLTAGE) / BATTERY_REFERENCE_VOLTAGE)
            .collect(),
    )
}

impl Effect for BatteryVoltage {
    fn name(&self) -> &str {
        EffectKind::BatteryVoltage.name()
    }
    fn description(&self) -> &str {
        "rotor map falling with the battery voltage, (1 + beta (V - V_ref)/V_ref) k_f w^2"
    }
    fn channels(&self) -> Vec<Channel> {
        vec![2]
    }
    fn check(&self, s: &Signals) -> Result<(), String> {
        let Some(v) = s.log().signal(BATTERY_COLUMN) else {
            return Err(format!(
                "needs the battery voltage (column {BATTERY_COLUMN} [V])"
            ));
        };
        if v.len() != s.len() {
            return Err(format!(
                "the battery voltage column has {} values for {} samples",
                v.len(),
                s.len()
            ));
        }
        if let Some(x) = v.iter().find(|x| !(x.is_finite() && **x > 0.0)) {
            return Err(format!("battery voltage {x} V is not a positive number"));
        }
        Ok(())
    }
    fn columns(&self, s: &Signals, _p: Option<f64>) -> Vec<EffectColumn> {
        let Some(x) = relative_voltage(s) else {
            return Vec::new();
        };
        let mut data: [Option<Vec<f64>>; 6] = Default::default();
        data[2] = Some(s.channel(2).iter().zip(&x).map(|(f, x)| f * x).collect());
        vec![EffectColumn::new("beta", "1", data)]
    }
    fn plausibility(&self, coef: &[f64], _se: &[f64], _p: Option<f64>) -> Plausibility {
        // A motor's thrust grows about with its voltage squared: β ≤ 2, and never negative.
        match coef.iter().find(|b| !(-0.5..=4.0).contains(*b)) {
            Some(b) => Plausibility::broken(
                "battery-voltage-range",
                format!("battery exponent beta {b:.2} outside [-0.5, 4]"),
            ),
            None => Plausibility::ok(),
        }
    }
    fn driver(&self, s: &Signals) -> (String, Vec<f64>) {
        let v = s.log().signal(BATTERY_COLUMN).unwrap_or_default();
        ("battery voltage [V]".into(), v)
    }
}
