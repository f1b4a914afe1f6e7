//! `battery-voltage`: its column against a closed form and the simulator's truth, a missing
//! voltage column, and the effect hidden in simulated flights with realistic sensing (the fit
//! recovers `β` within its interval with the mass free, the staircase adds it).
mod common;

use tagk_diagnose::{DiagnoseOptions, Model, Signals, builtin, discover, fit_model};
use tagk_dynamics::{BATTERY_COLUMN, EffectKind};
use tagk_sim::plant_effects::BatteryVoltage;
use tagk_sim::{Sensing, TrajectoryKind};

/// A 60-s figure-8 flight with the battery effect `battery` hidden, `sensing`.
fn flight(seed: u64, battery: BatteryVoltage, sensing: Sensing) -> tagk_sim::SimOutput {
    let mut cfg = common::config(None, seed);
    cfg.trajectory = TrajectoryKind::Figure8;
    cfg.duration = 60.0;
    cfg.sensing = sensing;
    cfg.record_truth = true;
    cfg.effects.battery_voltage = Some(battery);
    let out = tagk_sim::simulate(&cfg).unwrap();
    assert!(!out.metrics.aborted);
    out
}

/// A battery draining 0.3 V over the minute (late in a flight), `β = 1`.
fn draining() -> BatteryVoltage {
    BatteryVoltage {
        discharge_rate: 5e-3,
        ..BatteryVoltage::crazyflie()
    }
}

/// With ideal sensing: the column is the logged `f_z (V − 3.8)/3.8` (closed form, from the
/// log's own columns), and `β` times it is the simulator's truth of the effect on `f_z`
/// (`β (V − V_ref)/V_ref k_f Σ ω²`), to 1e-9 of its RMS. The logged voltage is the model's
/// `V₀ − r t − s Σ ω²` at the sample's time and rotor speeds.
#[test]
fn the_column_is_the_closed_form_and_the_simulators_truth() {
    let battery = draining();
    let out = flight(7, battery, Sensing::ideal());
    let truth = out.truth.as_ref().unwrap();
    let k = truth
        .effects
        .iter()
        .position(|e| *e == EffectKind::BatteryVoltage)
        .unwrap();
    let vbat = out
        .log
        .signal(BATTERY_COLUMN)
        .expect("the simulator logs vbat");
    let s = Signals::from_log(&out.log).unwrap();
    assert_eq!(s.len(), vbat.len());
    let columns = builtin(EffectKind::BatteryVoltage)
        .unwrap()
        .columns(&s, None);
    assert_eq!(columns.len(), 1);
    let column = columns[0].data[2].as_ref().unwrap();
    assert!(
        columns[0]
            .data
            .iter()
            .enumerate()
            .all(|(c, d)| c == 2 || d.is_none())
    );
    let (mut miss, mut size) = (0.0, 0.0);
    for i in 0..s.len() {
        let w = out.log.rotor_speeds.as_ref().unwrap()[i];
        let sq: f64 = w.iter().map(|x| x * x).sum();
        let v = 4.1 - 5e-3 * out.log.t[i] - 2.8e-8 * sq;
        assert!((vbat[i] - v).abs() < 1e-12, "sample {i}: {} {v}", vbat[i]);
        let closed = out.log.wrench[i][2] * (vbat[i] - 3.8) / 3.8;
        assert!((column[i] - closed).abs() < 1e-15, "sample {i}");
        let expected = truth.samples[i].effect_wrenches[k][2];
        miss += (battery.beta * column[i] - expected).powi(2);
        size += expected * expected;
    }
    assert!(size > 0.0);
    assert!(
        miss.sqrt() < 1e-9 * size.sqrt(),
        "RMS miss {:.3e} of {:.3e}",
        miss.sqrt(),
        size.sqrt()
    );
}

/// A log without the voltage column: the candidate says why, and the fit refuses it.
#[test]
fn without_a_voltage_column_the_candidate_is_unavailable() {
    let out = tagk_sim::simulate(&common::config(None, 3)).unwrap();
    let s = Signals::from_log(&out.log).unwrap();
    let effect = builtin(EffectKind::BatteryVoltage).unwrap();
    let reason = effect.check(&s).unwrap_err();
    assert!(reason.contains("vbat"), "{reason}");
    let model = Model::rigid_body().with_ref(effect);
    assert!(fit_model(&model, &s, None).is_err());
}

/// Realistic sensing, the battery draining over a minute, the mass free: the fitted `β` is
/// within 6 % of the truth (1) and the staircase adds `battery-voltage`.
///
/// Not within its interval: measured `β` = 1.027 ± 0.015 and 1.041 ± 0.014 (seeds 7, 8). Ideal
/// sensing recovers 1.0000 ± 0.0003; rotor-speed noise alone gives 1.002 and 1.015, IMU noise
/// alone 1.008 (errors in the variables of a mass fitted with `β`). With the default slow
/// drain (0.09 V/min) the sag, which follows the thrust, carries most of the voltage's
/// variation, and the bias grows to +23..28 %.
#[test]
fn a_hidden_battery_effect_is_recovered_and_found() {
    let battery = draining();
    for seed in [7, 8] {
        let out = flight(seed, battery, Sensing::realistic());
        let s = Signals::from_log(&out.log).unwrap();
        let model = Model::rigid_body()
            .with_ref(builtin(EffectKind::BatteryVoltage).unwrap())
            .with_ref(tagk_diagnose::builtin_by_name(tagk_diagnose::ACCEL_BIAS).unwrap());
        let fit = fit_model(&model, &s, None).unwrap();
        let beta = &fit
            .effects
            .iter()
            .find(|e| e.effect == EffectKind::BatteryVoltage.name())
            .unwrap()
            .coefficients[0];
        let [lo, hi] = beta.confidence_interval.expect("identified");
        assert!(
            (beta.value - battery.beta).abs() < 0.06 && hi - lo < 0.1,
            "seed {seed}: beta {:.4} [{lo:.4}, {hi:.4}]",
            beta.value
        );
        let mut options = DiagnoseOptions::default();
        if tagk_diagnose::NOT_PROPOSED.contains(&EffectKind::BatteryVoltage) {
            options
                .candidates
                .push(builtin(EffectKind::BatteryVoltage).unwrap());
        }
        let found = discover(&Model::rigid_body(), &s, &options).unwrap();
        assert!(
            found
                .added
                .iter()
                .any(|a| a == EffectKind::BatteryVoltage.name()),
            "seed {seed}: staircase {:?}: {}",
            found.added,
            found.stopped
        );
    }
}

/// The accelerometer calibrated, the mass known: the fitted `β` covers the truth (measured
/// 1.0017 ± 0.0046 and 1.0031 ± 0.0045, seeds 7, 9). With an uncalibrated accelerometer its
/// vertical offset trades against the mean of the column and `β` misses by up to 35 %.
#[test]
fn with_a_known_mass_and_a_calibrated_accelerometer_beta_is_within_its_interval() {
    let battery = draining();
    for seed in [7, 9] {
        let out = flight(seed, battery, Sensing::realistic_calibrated());
        let s = Signals::from_log(&out.log).unwrap();
        let model = Model::rigid_body()
            .with_known_mass(tagk_dynamics::quadrotor::CRAZYFLIE_MASS)
            .with_ref(builtin(EffectKind::BatteryVoltage).unwrap());
        let fit = fit_model(&model, &s, None).unwrap();
        let beta = &fit
            .effects
            .iter()
            .find(|e| e.effect == EffectKind::BatteryVoltage.name())
            .unwrap()
            .coefficients[0];
        let [lo, hi] = beta.confidence_interval.expect("identified");
        assert!(
            lo <= battery.beta && battery.beta <= hi,
            "seed {seed}: beta {:.4} [{lo:.4}, {hi:.4}]",
            beta.value
        );
    }
}

/// A logged voltage without its effect (`β = 0`: speeds measured, or the firmware's battery
/// compensation), realistic sensing, with and without a hidden rotor drag: the staircase,
/// given the candidate, never adds `battery-voltage` (seeds 7..=10).
#[test]
fn a_voltage_without_its_effect_is_not_found() {
    let battery = BatteryVoltage {
        beta: 0.0,
        ..draining()
    };
    let mut false_finds = Vec::new();
    for seed in 7..=10 {
        for drag in [false, true] {
            let mut cfg = common::config(drag.then_some(EffectKind::RotorDrag), seed);
            cfg.duration = 60.0;
            cfg.sensing = Sensing::realistic();
            cfg.effects.battery_voltage = Some(battery);
            let out = tagk_sim::simulate(&cfg).unwrap();
            let s = Signals::from_log(&out.log).unwrap();
            let mut options = DiagnoseOptions::default();
            if tagk_diagnose::NOT_PROPOSED.contains(&EffectKind::BatteryVoltage) {
                options
                    .candidates
                    .push(builtin(EffectKind::BatteryVoltage).unwrap());
            }
            let found = discover(&Model::rigid_body(), &s, &options).unwrap();
            eprintln!("seed {seed} drag {drag}: {:?}", found.added);
            if found
                .added
                .iter()
                .any(|a| a == EffectKind::BatteryVoltage.name())
            {
                false_finds.push((seed, drag));
            }
        }
    }
    assert!(false_finds.is_empty(), "{false_finds:?}");
}

/// The model file carries `β` with its standard error and 95 % interval, as every other
/// coefficient, and reads them back bit for bit. The interval is `β ± 1.96 s.e.` (computed
/// here from the standard error) and covers the truth on an ideal log.
#[test]
fn the_model_file_gives_beta_its_interval() {
    let out = flight(7, draining(), Sensing::ideal());
    let s = Signals::from_log(&out.log).unwrap();
    let model = Model::rigid_body().with_ref(builtin(EffectKind::BatteryVoltage).unwrap());
    let fit = fit_model(&model, &s, None).unwrap();
    let file = tagk_diagnose::ModelFile::from_fit(
        &fit,
        &fit.effects,
        &tagk_diagnose::ModelContext::default(),
    );
    let back = tagk_diagnose::ModelFile::from_toml_str(&file.to_toml_string().unwrap()).unwrap();
    let effect = back
        .effects
        .iter()
        .find(|e| e.name == EffectKind::BatteryVoltage.name())
        .unwrap();
    let beta = &effect.coefficients[0];
    assert_eq!(beta.name, "beta");
    let se = beta.std_error.expect("a standard error");
    let [lo, hi] = beta.interval.expect("an interval");
    let half = 0.5 * (hi - lo);
    assert!(
        (half / (1.96 * se) - 1.0).abs() < 0.05 && (0.5 * (lo + hi) - beta.value).abs() < 1e-9,
        "beta {} ± {se}: [{lo}, {hi}]",
        beta.value
    );
    assert!(lo <= 1.0 && 1.0 <= hi, "beta {} [{lo}, {hi}]", beta.value);
}
