//! The `rotor-inertia` candidate: its columns against closed forms on a synthetic signal, and
//! a simulated flight with the effect hidden, where the fit recovers `J_r` and the diagnosis
//! finds it.

use tagk_diagnose::{DiagnoseOptions, FlightLog, Model, Signals, builtin, diagnose, fit_model};
use tagk_dynamics::{EffectKind, QuadrotorModel};
use tagk_sim::plant_effects::{MotorLag, RotorInertia};
use tagk_sim::{Adaptation, NoiseLevel, PayloadSchedule, PlantEffects, SimConfig, TrajectoryKind};

/// A simulated log (ideal sensors unless `noise`) with the rotor inertia `j_r` \[kg m²\] and a
/// 20 ms motor lag hidden, the motors' own speeds logged (so `ω̇` is smooth), the heading
/// turning at `yaw_rate` \[rad/s\], controlled and logged every `control_dt` \[s\].
fn flight(j_r: f64, seed: u64, noise: NoiseLevel, yaw_rate: f64, control_dt: f64) -> FlightLog {
    let mut c = SimConfig {
        trajectory: TrajectoryKind::Figure8,
        duration: 25.0,
        seed,
        noise,
        payload: PayloadSchedule::None,
        effects: PlantEffects {
            motor_lag: Some(MotorLag {
                time_constant: 0.02,
            }),
            rotor_inertia: Some(RotorInertia { inertia: j_r }),
            ..PlantEffects::none()
        },
        adaptation: Adaptation::Nominal,
        record_log: true,
        stop_on_abort: false,
        yaw_rate,
        ..SimConfig::default()
    };
    c.flight_stack.motor_telemetry = true;
    c.control_dt = control_dt;
    c.physics_dt = (control_dt / 4.0).min(0.002);
    let out = tagk_sim::simulate(&c).expect("simulation runs");
    assert!(!out.metrics.aborted, "flight aborted");
    out.log
}

/// The log's rotor speeds and body rates replaced by analytic signals, the wrench by the
/// Crazyflie mixer of those speeds (so the diagnosis identifies the mixer).
fn synthetic() -> (FlightLog, [f64; 4]) {
    let mut log = flight(0.0, 3, NoiseLevel::None, 0.0, 0.02);
    let model = QuadrotorModel::crazyflie_2_1();
    let speeds: Vec<[f64; 4]> = log
        .t
        .iter()
        .map(|&t| {
            [
                1900.0 + 150.0 * (3.0 * t).sin(),
                1950.0 + 120.0 * (2.0 * t + 0.5).cos(),
                1880.0 - 90.0 * (5.0 * t).sin(),
                1920.0 + 60.0 * (1.5 * t).cos(),
            ]
        })
        .collect();
    for (i, &t) in log.t.clone().iter().enumerate() {
        log.omega[i] = [0.6 * (1.3 * t).sin(), -0.4 * (0.7 * t).cos(), 0.2];
        log.wrench[i] = model.wrench_from_rotor_speeds(&speeds[i]).to_array();
    }
    log.rotor_speeds = Some(speeds);
    (log, model.spin_directions)
}

/// `H(t) = Σ sᵢ ωᵢ(t)`, its derivative and that of the yaw torque `k_m Σ sᵢ ωᵢ²`, in closed
/// form, for [`synthetic`].
fn spin_sum_closed_form(t: f64, spins: &[f64; 4]) -> (f64, f64, f64) {
    let w = [
        1900.0 + 150.0 * (3.0 * t).sin(),
        1950.0 + 120.0 * (2.0 * t + 0.5).cos(),
        1880.0 - 90.0 * (5.0 * t).sin(),
        1920.0 + 60.0 * (1.5 * t).cos(),
    ];
    let dw = [
        450.0 * (3.0 * t).cos(),
        -240.0 * (2.0 * t + 0.5).sin(),
        -450.0 * (5.0 * t).cos(),
        -90.0 * (1.5 * t).sin(),
    ];
    let h = (0..4).map(|i| spins[i] * w[i]).sum();
    let dh = (0..4).map(|i| spins[i] * dw[i]).sum();
    let k_m = QuadrotorModel::crazyflie_2_1().k_m;
    let dtz = (0..4).map(|i| 2.0 * k_m * spins[i] * w[i] * dw[i]).sum();
    (h, dh, dtz)
}

#[test]
fn columns_are_the_closed_form_of_the_spin_sum() {
    let (log, spins) = synthetic();
    let s = Signals::from_log(&log).unwrap();
    let effect = builtin(EffectKind::RotorInertia).unwrap();
    effect.check(&s).unwrap();
    let cols = effect.columns(&s, None);
    assert_eq!(cols.len(), 1);
    let c = &cols[0];
    let (tx, ty, tz) = (
        c.data[3].as_ref().unwrap(),
        c.data[4].as_ref().unwrap(),
        c.data[5].as_ref().unwrap(),
    );
    assert!(c.data[..3].iter().all(Option::is_none));
    let n = s.len();
    // The yaw column is `Ḣ` less its least-squares multiple of the yaw torque's rate.
    let rates: Vec<(f64, f64)> = log
        .t
        .iter()
        .map(|&t| {
            let (_, dh, dtz) = spin_sum_closed_form(t, &spins);
            (dh, dtz)
        })
        .collect();
    let k = rates.iter().map(|(a, b)| a * b).sum::<f64>()
        / rates.iter().map(|(_, b)| b * b).sum::<f64>();
    let mut worst_rate = 0.0f64;
    for i in 0..n {
        let (h, _, _) = spin_sum_closed_form(log.t[i], &spins);
        let dh = rates[i].0 - k * rates[i].1;
        let [p, q, _] = log.omega[i];
        assert!((tx[i] - h * q).abs() <= 1e-9 * h.abs(), "tx at {i}");
        assert!((ty[i] + h * p).abs() <= 1e-9 * h.abs(), "ty at {i}");
        if (1..n - 1).contains(&i) {
            worst_rate = worst_rate.max((tz[i] - dh).abs());
        }
        // The k-step prediction's columns at the logged state are the same.
        let state = tagk_diagnose::BodyState::logged(&log, i);
        let at = effect.columns_at(&s, i, &state, None).unwrap();
        assert_eq!(at.len(), 1);
        for (ch, predicted) in at[0].iter().enumerate().skip(3) {
            let col = c.data[ch].as_ref().unwrap()[i];
            assert!(
                (predicted - col).abs() <= 1e-12 * (1.0 + col.abs()),
                "ch {ch} at {i}"
            );
        }
    }
    // A central difference over 2Δt = 40 ms errs by (ω Δt)²/6 of a sinusoid's rate: at most
    // 0.17 % at 5 rad/s, below 3 rad/s² of the 1 300 rad/s² peak (the projection included).
    assert!(
        worst_rate < 3.0,
        "largest error of the yaw column {worst_rate} rad/s²"
    );
    // The projection removes a large share: the column is not `Ḣ` itself.
    assert!(k.abs() > 1e5, "projection factor {k}");
}

#[test]
fn the_candidate_needs_rotor_speeds() {
    let (mut log, _) = synthetic();
    log.rotor_speeds = None;
    let s = Signals::from_log(&log).unwrap();
    assert!(
        builtin(EffectKind::RotorInertia)
            .unwrap()
            .check(&s)
            .is_err()
    );
}

/// With the effect hidden at four times the Crazyflie's `J_r`, the fit's 95 % interval holds
/// it, on a 50 Hz log with the paper's medium noise and with ideal sensors.
///
/// Measured (`J_r` true 1e-7): medium noise 1.06e-7 in [7.2e-8, 1.39e-7]; ideal sensors
/// 2.9e-6 in ±2.5e-4 (not identified: the yaw column is `Ḣ` less what a timing error makes,
/// and without noise the fit's scale is the model error). On a 200 Hz log with medium noise
/// the interval [−3.0e-8, 4.7e-8] misses it (a known limitation, not asserted).
#[test]
fn a_hidden_rotor_inertia_is_within_the_fit_s_interval() {
    let j_true = 1e-7;
    for (noise, seed) in [(NoiseLevel::Medium, 8), (NoiseLevel::None, 7)] {
        let log = flight(j_true, seed, noise, 1.0, 0.02);
        let s = Signals::from_log(&log).unwrap();
        let model = Model::rigid_body().with_ref(builtin(EffectKind::RotorInertia).unwrap());
        let fit = fit_model(&model, &s, None).unwrap();
        let j = &fit.effects[0].coefficients[0];
        let [lo, hi] = j.confidence_interval.unwrap();
        assert!(
            lo <= j_true && j_true <= hi,
            "{noise:?}: J_r = {:e} [{lo:e}, {hi:e}], true {j_true:e}",
            j.value
        );
        if noise == NoiseLevel::Medium {
            assert!(lo > 0.0, "J_r not significant: [{lo:e}, {hi:e}]");
            assert!(
                (j.value - j_true).abs() < 0.2 * j_true,
                "J_r = {:e}",
                j.value
            );
        }
        assert!(fit.effects[0].plausible, "{noise:?}");
    }
}

/// The diagnosis of a 50 Hz flight with the effect hidden recommends it.
#[test]
fn diagnose_finds_a_hidden_rotor_inertia() {
    let log = flight(1e-7, 7, NoiseLevel::Medium, 1.0, 0.02);
    let s = Signals::from_log(&log).unwrap();
    let d = diagnose(&Model::rigid_body(), &s, &DiagnoseOptions::default()).unwrap();
    assert_eq!(
        d.recommended.as_deref(),
        Some(EffectKind::RotorInertia.name()),
        "ranking {:?}",
        d.ranking
            .iter()
            .map(|r| r.effect.as_str())
            .collect::<Vec<_>>()
    );
}
