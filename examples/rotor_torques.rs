//! Does the diagnosed model predict a held-out flight better than the rigid body and than
//! holding the body rate? The nano-quadrotor rotor effects hidden by default.
//!
//! For each of `--flights` vehicles (a Crazyflie with its own payload):
//!
//! 1. fly it twice in the simulator, with realistic sensing and the plant effects of
//!    `--hidden` at their Crazyflie magnitudes (`tagk::sim::PlantEffects::with`): an
//!    identification flight and a held-out flight (another seed, path and yaw rate);
//! 2. diagnose the identification flight as `tagk diagnose LOG` does
//!    (`tagk::diagnosis_benchmark::run_diagnosis`), and save its final model
//!    (`--out DIR/flight-K.toml`);
//! 3. on the held-out flight, measure the mean `--horizon`-step (default 50 steps: 1 s at
//!    the simulator's 50 Hz log; `--horizon 25` for 0.5 s) body-rate, position and velocity
//!    errors of the diagnosed model, of the rigid body (the staircase's first step) and of the
//!    constant-rate reference (`tagk::diagnose::Predictor::ConstantRate`).
//!
//! A model whose spatial inertia is not positive definite, or whose open-loop state diverges
//! within the horizon, cannot be integrated. Its errors are infinite: it meets no target.
//!
//! It prints one line per flight, then the medians of the error ratios and the fractions of
//! flights where the diagnosed model's body-rate error is at most half the constant-rate's
//! and half the rigid body's, and where its position and velocity errors are no worse than the
//! rigid body's. The flights are drawn from `--seed` alone (ChaCha8, one stream per flight).
//!
//! Run: `cargo run --release --example rotor_torques -- --help`.

use std::path::PathBuf;

use rand_chacha::ChaCha8Rng;
use rand_chacha::rand_core::SeedableRng;
use tagk::diagnose::{
    AlignOptions, CONSTANT_RATE, DiagnoseError, DiagnosisPlan, HorizonError, ModelContext,
    ModelFile, Predictor, Signals, predict_logs,
};
use tagk::diagnosis_benchmark::{FlightSpec, draw_path, draw_payload, mix, run_diagnosis};
use tagk::dynamics::EffectKind;
use tagk::sim::{Payload, PlantEffects, SensingProfile, simulate};

/// Flights with hidden effects, diagnosed, scored on held-out flights against the rigid body
/// and the constant-rate reference.
#[derive(Debug, clap::Parser)]
struct Args {
    /// Number of vehicles (each flown twice).
    #[arg(long, default_value_t = 12)]
    flights: usize,
    /// Seed of every random choice.
    #[arg(long, default_value_t = 7)]
    seed: u64,
    /// Hidden plant effects (comma-separated names of docs/CONVENTIONS.md §7; `none`: the
    /// ideal plant).
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "motor-lag,rotor-inertia,rotor-inflow,rotor-imbalance"
    )]
    hidden: Vec<String>,
    /// Sensing profile of every flight (ideal, realistic, realistic-calibrated).
    #[arg(long, default_value = "realistic")]
    sensing: SensingProfile,
    /// Prediction horizon [steps of the log].
    #[arg(long, default_value_t = 50)]
    horizon: usize,
    /// Duration of each flight [s].
    #[arg(long, default_value_t = 20.0)]
    duration: f64,
    /// Folder for the diagnosed final models.
    #[arg(long, default_value = "out/rotor_torques")]
    out: PathBuf,
    /// Hide the progress bar.
    #[arg(long)]
    quiet: bool,
}

/// One flight of the vehicle: its path, yaw rate and simulator seed drawn from `rng`.
fn flight(
    rng: &mut ChaCha8Rng,
    sensing: SensingProfile,
    index: usize,
    duration: f64,
    payload: Payload,
    effects: PlantEffects,
    hidden: &[String],
) -> FlightSpec {
    let (sim_seed, trajectory, yaw_rate) = draw_path(rng);
    FlightSpec {
        index,
        sim_seed,
        trajectory,
        yaw_rate,
        duration,
        sensing,
        payload,
        known_mass: false,
        altitude: None,
        effects,
        hidden: hidden.to_vec(),
    }
}

/// The held-out log as `model` reads it (as `tagk compare` does: its stream shifts applied,
/// its resampling, nothing measured again).
fn read_as(
    model: &ModelFile,
    log: &tagk::diagnose::FlightLog,
) -> Result<Vec<Signals>, Box<dyn std::error::Error>> {
    let mut plan = DiagnosisPlan::new().align(AlignOptions {
        auto: false,
        shifts: model.sensing.shifts_to_apply(),
        ..AlignOptions::default()
    });
    if let Some(dt) = model.sensing.resample {
        plan = plan.resample(dt);
    }
    Ok(plan
        .log(log.clone())
        .accept_scales(true)
        .conditioned_flights()?
        .into_iter()
        .map(|(_, log)| Signals::from_owned_log_split(log).map(|s| s.0))
        .collect::<Result<_, _>>()?)
}

/// The mean errors at the horizon of one flight: body rate, position, velocity.
#[derive(Debug, Clone, Copy)]
struct Errors {
    body_rate: f64,
    position: f64,
    velocity: f64,
}

impl Errors {
    /// A model that cannot be integrated.
    const UNPREDICTABLE: Self = Self {
        body_rate: f64::INFINITY,
        position: f64::INFINITY,
        velocity: f64::INFINITY,
    };
}

impl From<&HorizonError> for Errors {
    fn from(e: &HorizonError) -> Self {
        Self {
            body_rate: e.body_rate,
            position: e.position,
            velocity: e.velocity,
        }
    }
}

/// One scored flight.
struct Scored {
    diagnosed: Errors,
    rigid: Errors,
    constant_rate: Errors,
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n == 0 {
        f64::NAN
    } else if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

fn main() -> std::process::ExitCode {
    tagk::cli::terminal::end_quietly_on_broken_pipe();
    tagk::cli::terminal::exit_code("rotor_torques", run())
}

/// The example; an error is printed once by `main`.
fn run() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = <Args as clap::Parser>::parse();
    let mut effects = PlantEffects::none();
    args.hidden.retain(|n| !n.is_empty() && n != "none");
    for name in &args.hidden {
        let kind = EffectKind::from_name(name)
            .ok_or_else(|| format!("--hidden: unknown effect `{name}` (docs/CONVENTIONS.md §7)"))?;
        effects = effects.with(kind)?;
    }
    std::fs::create_dir_all(&args.out)?;
    let horizons = [args.horizon];
    println!(
        "{} vehicles, hidden {}, {} s flights, {} sensing, seed {}; mean {}-step errors on a held-out flight",
        args.flights,
        args.hidden.join(" + "),
        args.duration,
        args.sensing,
        args.seed,
        args.horizon
    );
    println!(
        "{:>3} {:>28} {:>31} {:>31} {:>31}  diagnosed model",
        "#",
        "body rate D / R / C [rad/s]",
        "position D / R / C [m]",
        "velocity D / R / C [m/s]",
        "ratios D/C D/R (rate)"
    );
    let step = std::cell::RefCell::new(f64::NAN);
    let mut scored = Vec::new();
    let mut failed = Vec::new();
    let bar = tagk::cli::progress::Progress::counting(!args.quiet, args.flights as u64, "vehicles");
    for index in 0..args.flights {
        let mut rng = ChaCha8Rng::seed_from_u64(mix(mix(args.seed) ^ index as u64));
        let payload = draw_payload(&mut rng, &effects);
        let identify = flight(
            &mut rng,
            args.sensing,
            index,
            args.duration,
            payload,
            effects,
            &args.hidden,
        );
        let held_out = flight(
            &mut rng,
            args.sensing,
            index,
            args.duration,
            payload,
            effects,
            &args.hidden,
        );
        let outcome = (|| -> Result<(Scored, String), Box<dyn std::error::Error>> {
            let fly = |spec: &FlightSpec| -> Result<_, Box<dyn std::error::Error>> {
                let out = simulate(&spec.sim_config())?;
                if out.metrics.aborted {
                    return Err(format!("the {:?} flight aborted", spec.trajectory).into());
                }
                Ok(out.log)
            };
            let report = run_diagnosis(fly(&identify)?, None)?;
            let context = ModelContext::default();
            let diagnosed = ModelFile::from_diagnosis(&report, &context);
            diagnosed.write(&args.out.join(format!("flight-{index}.toml")))?;
            let rigid = ModelFile::steps(&report, &context)
                .into_iter()
                .next()
                .ok_or("the diagnosis has no rigid-body step")?;
            let log = fly(&held_out)?;
            let d_logs = read_as(&diagnosed, &log)?;
            let r_logs = read_as(&rigid, &log)?;
            // A model without a positive-definite spatial inertia, or whose open-loop state
            // leaves the finite numbers within the horizon, cannot be integrated: it
            // predicts nothing (its errors infinite).
            let at = |logs: &[Signals],
                      p: Predictor<'_>|
             -> Result<Errors, Box<dyn std::error::Error>> {
                match predict_logs(logs, p, &horizons, &[]) {
                    Ok(p) => {
                        *step.borrow_mut() = p.horizons[0].dt;
                        Ok(Errors::from(&p.horizons[0]))
                    }
                    Err(DiagnoseError::InvalidModel(_)) => Ok(Errors::UNPREDICTABLE),
                    Err(e) => Err(e.into()),
                }
            };
            Ok((
                Scored {
                    diagnosed: at(&d_logs, Predictor::Model(&diagnosed))?,
                    rigid: at(&r_logs, Predictor::Model(&rigid))?,
                    constant_rate: at(&r_logs, Predictor::ConstantRate)?,
                },
                diagnosed.label,
            ))
        })();
        bar.inc();
        match outcome {
            Ok((s, label)) => {
                let (d, r, c) = (s.diagnosed, s.rigid, s.constant_rate);
                bar.suspend(|| println!(
                    "{index:>3} {:>9.2e} {:>9.2e} {:>9.2e} {:>10.2e} {:>9.2e} {:>9.2e} {:>10.2e} {:>9.2e} {:>9.2e} {:>15.2} {:>15.2}  {label}",
                    d.body_rate,
                    r.body_rate,
                    c.body_rate,
                    d.position,
                    r.position,
                    c.position,
                    d.velocity,
                    r.velocity,
                    c.velocity,
                    d.body_rate / c.body_rate,
                    d.body_rate / r.body_rate,
                ));
                scored.push(s);
            }
            Err(e) => {
                bar.suspend(|| println!("{index:>3} failed: {e}"));
                failed.push(index);
            }
        }
    }
    bar.finish();
    let n = scored.len();
    // Medians over the flights whose ratio is defined (not both models unpredictable); a
    // target is met only by a diagnosed model that predicts (finite errors).
    let ratio = |f: &dyn Fn(&Scored) -> f64| {
        let v: Vec<f64> = scored.iter().map(f).filter(|r| !r.is_nan()).collect();
        format!("{:.3} (of {})", median(v.clone()), v.len())
    };
    let share = |f: &dyn Fn(&Scored) -> bool| {
        scored
            .iter()
            .filter(|s| s.diagnosed.body_rate.is_finite() && f(s))
            .count()
    };
    let unpredictable = |f: &dyn Fn(&Scored) -> &Errors| {
        scored
            .iter()
            .filter(|s| !f(s).body_rate.is_finite())
            .count()
    };
    println!(
        "\n{n} flights scored ({} failed{}); D diagnosed, R rigid body, C {CONSTANT_RATE}",
        failed.len(),
        if failed.is_empty() {
            String::new()
        } else {
            format!(": {failed:?}")
        }
    );
    println!(
        "models that cannot be integrated (spatial inertia not positive definite, or the open-loop state diverges): diagnosed {}/{n}, rigid {}/{n}",
        unpredictable(&|s| &s.diagnosed),
        unpredictable(&|s| &s.rigid),
    );
    println!(
        "median ratio body rate D/C {}, D/R {}; position D/R {}; velocity D/R {}",
        ratio(&|s| s.diagnosed.body_rate / s.constant_rate.body_rate),
        ratio(&|s| s.diagnosed.body_rate / s.rigid.body_rate),
        ratio(&|s| s.diagnosed.position / s.rigid.position),
        ratio(&|s| s.diagnosed.velocity / s.rigid.velocity),
    );
    println!(
        "body rate D <= C/2: {}/{n}; D <= R/2: {}/{n}; position D <= R: {}/{n}; velocity D <= R: {}/{n}",
        share(&|s| s.diagnosed.body_rate <= 0.5 * s.constant_rate.body_rate),
        share(&|s| s.diagnosed.body_rate <= 0.5 * s.rigid.body_rate),
        share(&|s| s.diagnosed.position <= s.rigid.position),
        share(&|s| s.diagnosed.velocity <= s.rigid.velocity),
    );
    println!(
        "horizon {} steps = {:.3} s (the log's step {:.3} s); a model that cannot be integrated predicts nothing (inf)",
        args.horizon,
        args.horizon as f64 * *step.borrow(),
        *step.borrow()
    );
    println!("final models in {}", args.out.display());
    Ok(())
}
