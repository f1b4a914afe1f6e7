//! A user-defined physical effect end to end, flown and diagnosed: an elastic tether.
//!
//! The vehicle flies tied to its take-off point by an elastic tether (a safety line, a power
//! cable): a force `f = −k (p − p₀)` in the world frame pulls it back towards the anchor `p₀`.
//! No built-in candidate knows this force, and it is not a product of logged columns (the
//! `--custom` syntax). So one type, [`Tether`], implements both sides:
//! tagk-diagnose's [`Effect`] (the candidate the diagnosis fits) and tagk-sim's
//! [`PlantEffect`] (the force the simulator flies).
//!
//! 1. Fly the simulated Crazyflie (tagk-sim) for 25 s with the tether acting on the plant
//!    ([`SimConfig::with_plant_effect`]). The controller feels it and fights it in closed loop.
//!    The logged actuator wrench is the rotors' own, so the tether is in the log only through
//!    the motion: `b = Y θ − f_ext` (force channels; the tether is tied at the body origin, so
//!    it exerts no torque).
//! 2. Diagnose the rigid-body model with the built-in candidates only: the tether is not
//!    among them, so the tool can at best point at a look-alike.
//! 3. Register the tether as a candidate: it is ranked first and recommended.
//! 4. Add it: the force channels' residual falls and the stiffness comes out near the truth
//!    (0.05 N/m flown; the default run prints `fitted stiffness 0.0500 N/m (true 0.05)`).
//!
//! Run: `cargo run --release --example custom_effect [-- --seed 42 --duration 25]`. `tests/custom_effect.rs` runs the
//! same functions on a shorter flight.

use std::sync::Arc;

use tagk::diagnose::{
    Channel, DiagnoseError, DiagnoseOptions, Diagnosis, Effect, EffectColumn, FlightLog, Model,
    Plausibility, Report, Signals, diagnose, diagnosis_table, report_table, run_loop,
};
use tagk::dynamics::Wrench;
use tagk::dynamics::nalgebra::Vector3;
use tagk::sim::plant_effects::EffectState;
use tagk::sim::{
    Adaptation, NoiseLevel, PayloadSchedule, PlantEffect, PlantEffects, SimConfig, simulate,
};

/// An elastic tether from the anchor `p₀` (world frame \[m\]) to the body origin:
/// `f_world = −k (p − p₀)` \[N\].
/// - Flown ([`PlantEffect`]): stiffness `k` = [`Tether::stiffness`].
/// - Diagnosed ([`Effect`]): one coefficient `k` \[N/m\] to fit, on the body-frame force
///   columns `Rᵀ (−(p − p₀))` of `fx, fy, fz`; the diagnosis ignores `stiffness`.
#[derive(Debug, Clone)]
pub struct Tether {
    /// Anchor point, world frame \[m\].
    pub anchor: [f64; 3],
    /// Stiffness `k` the simulator flies \[N/m\].
    pub stiffness: f64,
}

impl PlantEffect for Tether {
    fn name(&self) -> &str {
        "tether"
    }
    /// `Rᵀ (−k (p − p₀))`, body frame \[N\]; no torque (tied at the body origin).
    fn wrench(&self, s: &EffectState<'_>) -> Wrench {
        let pull = -self.stiffness * (s.position - Vector3::from(self.anchor));
        Wrench {
            force: s.attitude.inverse_transform_vector(&pull),
            torque: Vector3::zeros(),
        }
    }
}

impl Tether {
    /// The body-frame force per unit stiffness at every sample \[N per N/m\].
    fn unit_force(&self, s: &Signals) -> Vec<Vector3<f64>> {
        let anchor = Vector3::from(self.anchor);
        s.rotations()
            .zip(s.positions())
            .map(|(r, p)| r.transpose() * (anchor - p))
            .collect()
    }
}

impl Effect for Tether {
    fn name(&self) -> &str {
        "tether"
    }
    fn description(&self) -> &str {
        "elastic tether to the anchor point, f = -k (p - p0) in the world frame"
    }
    fn channels(&self) -> Vec<Channel> {
        vec![0, 1, 2]
    }
    fn columns(&self, s: &Signals, _param: Option<f64>) -> Vec<EffectColumn> {
        let f = self.unit_force(s);
        let mut data: [Option<Vec<f64>>; 6] = Default::default();
        for (c, d) in data.iter_mut().enumerate().take(3) {
            *d = Some(f.iter().map(|v| v[c]).collect());
        }
        vec![EffectColumn {
            name: "k_tether".into(),
            unit: "N/m".into(),
            data,
            // A stiffness to estimate, not a known coefficient.
            fixed: None,
        }]
    }
    fn plausibility(&self, coef: &[f64], se: &[f64], _param: Option<f64>) -> Plausibility {
        // A tether pulls; it never pushes.
        if coef[0] < -3.0 * se[0] {
            Plausibility::bad(format!(
                "stiffness {:.3e} N/m is significantly negative",
                coef[0]
            ))
        } else {
            Plausibility::ok()
        }
    }
    fn driver(&self, s: &Signals) -> (String, Vec<f64>) {
        let anchor = Vector3::from(self.anchor);
        (
            "distance to the anchor [m]".into(),
            s.positions().map(|p| (p - anchor).norm()).collect(),
        )
    }
}

/// Its stiffness \[N/m\]: about 0.05 N at 1 m altitude, 15 % of the vehicle's weight. The
/// rotors carry the vertical pull, so the rigid-body fit reads it as extra mass. Twice this
/// stiffness moves that mass by more than the diagnosis's ±25 % `mass-change` plausibility
/// limit, and the tether would be ranked first but not recommended.
pub const STIFFNESS: f64 = 0.05;

/// The tether of the example: tied to the ground at the world origin.
pub const TETHER: Tether = Tether {
    anchor: [0.0, 0.0, 0.0],
    stiffness: STIFFNESS,
};

/// A simulated flight of `duration` \[s\] (seed `seed`, medium sensor noise, no built-in
/// plant effect) with `tether` acting on the plant in closed loop.
///
/// # Errors
/// Simulation errors.
pub fn tethered_log(
    tether: &Tether,
    duration: f64,
    seed: u64,
) -> Result<FlightLog, Box<dyn std::error::Error>> {
    let config = SimConfig {
        duration,
        seed,
        noise: NoiseLevel::Medium,
        payload: PayloadSchedule::None,
        effects: PlantEffects::none(),
        adaptation: Adaptation::Nominal,
        record_log: true,
        stop_on_abort: false,
        ..SimConfig::default()
    }
    .with_plant_effect(Box::new(tether.clone()));
    Ok(simulate(&config)?.log)
}

/// What the example finds.
#[derive(Debug, Clone)]
pub struct Outcome {
    /// The diagnosis with the built-in candidates only.
    pub builtins_only: Diagnosis,
    /// The whole loop with the tether registered as a candidate and added.
    pub report: Report,
}

/// Diagnoses the log with the built-in candidates, then with `tether` registered, and adds it.
///
/// # Errors
/// Log validation or fit failures.
pub fn diagnose_tether(log: &FlightLog, tether: &Tether) -> Result<Outcome, DiagnoseError> {
    let signals = Signals::from_log(log)?;
    let builtins_only = diagnose(&Model::rigid_body(), &signals, &DiagnoseOptions::default())?;
    let tether: Arc<dyn Effect> = Arc::new(tether.clone());
    let mut options = DiagnoseOptions::default();
    options.candidates.push(tether.clone());
    let report = run_loop(&signals, &Model::rigid_body(), &[tether], &options)?;
    Ok(Outcome {
        builtins_only,
        report,
    })
}

/// A user-defined physical effect end to end: a simulated flight with an elastic tether
/// acting on the vehicle, diagnosed with the built-in candidates, then with the tether
/// registered.
#[derive(Debug, clap::Parser)]
struct Args {
    /// Seed of the simulated flight.
    #[arg(long, default_value_t = 42)]
    seed: u64,
    /// Flight duration in seconds.
    #[arg(long, default_value_t = 25.0)]
    duration: f64,
}

fn main() -> std::process::ExitCode {
    tagk::cli::terminal::end_quietly_on_broken_pipe();
    tagk::cli::terminal::exit_code("custom_effect", run())
}

/// The example; an error is printed once by `main`.
fn run() -> Result<(), Box<dyn std::error::Error>> {
    let args = <Args as clap::Parser>::parse();
    let log = tethered_log(&TETHER, args.duration, args.seed)?;
    println!(
        "simulated {} samples with a tether of {STIFFNESS} N/m acting on the vehicle (the \
         controller fights it; the logged wrench is the rotors')\n",
        log.len()
    );
    let outcome = diagnose_tether(&log, &TETHER)?;
    println!("--- built-in candidates only ---");
    println!("{}", diagnosis_table(&outcome.builtins_only));
    println!("--- with the tether registered and added ---");
    println!("{}", report_table(&outcome.report));
    let found = &outcome.report.before;
    let k = outcome
        .report
        .after
        .as_ref()
        .and_then(|a| a.effects.first())
        .map(|e| e.coefficients[0].value);
    println!(
        "tether ranked #{} of {}, recommended: {}; fitted stiffness {} N/m (true {STIFFNESS})",
        found
            .ranking
            .iter()
            .position(|c| c.effect == "tether")
            .map_or(0, |k| k + 1),
        found.ranking.len(),
        found.recommended.as_deref().unwrap_or("nothing"),
        k.map_or("n/a".into(), |k| format!("{k:.4}")),
    );
    Ok(())
}
