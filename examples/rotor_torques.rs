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
use tagk::sim::sim::rotor_sensing::RotorSensing;
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
    /// Sensing profile of every flight (ideal, realistic, realistic-calibrated,
    /// cf21-brushless: the Crazyflie 2.1 Brushless's eRPM rotor speeds).
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
    /// Folder for the flights' logs (`flight-K-identify.csv`, `flight-K-held-out.csv`); none:
    /// not written.
    #[arg(long)]
    logs: Option<PathBuf>,
    /// Hide the progress bar.
    #[arg(long)]
    quiet: bool,
}

/// The true model of a flight: its true inertial parameters and the hidden effects at their
/// true coefficients, as a model file. `None` when an effect is hidden that it does not
/// write (only `motor-lag`, `rotor-inertia`, `rotor-inflow`, `rotor-imbalance`,
/// `thrust-gain`).
///
/// With `motors_read` (eRPM telemetry: the logged speeds are the motors' own, read near the
/// middle of the interval) the motor lag is already in the log: the true model has none.
///
/// A rotor's relative error `ε_i` splits into the common part `ε̄` and the contrasts
/// `(1 + ε_i)/(1 + ε̄) − 1` (`rotor-imbalance`'s `d_eps1..3`). The common part (times a thrust
/// gain's) scales the whole wrench, torques too: the parameters are divided by it.
fn truth_model(theta: [f64; 10], effects: &PlantEffects, motors_read: bool) -> Option<ModelFile> {
    use tagk::diagnose::model_file::{ModelCoefficient, ModelEffect, ScannedParameter};
    let coefficient = |name: &str, unit: &str, value: f64| ModelCoefficient {
        name: name.into(),
        unit: unit.into(),
        value,
        std_error: None,
        interval: None,
    };
    let effect = |name: &str, coefficients: Vec<ModelCoefficient>| ModelEffect {
        name: name.into(),
        spec: None,
        scanned: None,
        coefficients,
    };
    let others = PlantEffects {
        motor_lag: None,
        rotor_inertia: None,
        rotor_inflow: None,
        rotor_imbalance: None,
        thrust_gain: None,
        ..*effects
    };
    if others != PlantEffects::none() {
        return None;
    }
    let mut file = ModelFile::rigid_body(theta);
    file.label = "truth".into();
    if let Some(lag) = effects.motor_lag.filter(|_| !motors_read) {
        let mut e = effect(
            "motor-lag",
            ["start_w1", "start_w2", "start_w3", "start_w4"]
                .iter()
                .map(|n| coefficient(n, "rad/s", 0.0))
                .chain(
                    ["start_sq_fz", "start_sq_tx", "start_sq_ty", "start_sq_tz"]
                        .iter()
                        .map(|n| coefficient(n, "N", 0.0)),
                )
                .collect(),
        );
        e.scanned = Some(ScannedParameter {
            name: "tau".into(),
            unit: "s".into(),
            value: lag.time_constant,
            interval: None,
        });
        file.effects.push(e);
    }
    if let Some(r) = effects.rotor_inertia {
        file.effects.push(effect(
            "rotor-inertia",
            vec![coefficient("J_r", "kg m²", r.inertia)],
        ));
    }
    if let Some(r) = effects.rotor_inflow {
        file.effects.push(effect(
            "rotor-inflow",
            vec![coefficient("k_in", "N s²/(m rad)", r.coefficient)],
        ));
    }
    let gain = 1.0 + effects.thrust_gain.map_or(0.0, |g| g.relative_error);
    let eps = effects
        .rotor_imbalance
        .map_or([0.0; 4], |r| r.relative_errors);
    let mean = eps.iter().sum::<f64>() / 4.0;
    if effects.rotor_imbalance.is_some() {
        file.effects.push(effect(
            "rotor-imbalance",
            (0..3)
                .map(|i| {
                    coefficient(
                        &format!("d_eps{}", i + 1),
                        "1",
                        (1.0 + eps[i]) / (1.0 + mean) - 1.0,
                    )
                })
                .collect(),
        ));
    }
    // The common factor scales the whole wrench: the same as the parameters over it (the
    // wrench is linear in θ). The file's rotor map is the log's, identified from its wrench.
    let scale = gain * (1.0 + mean);
    for v in &mut file.inertial.values {
        *v /= scale;
    }
    Some(file)
}

/// Per hidden effect, the RMS of its true wrench's variation about its mean as the log samples
/// it (after the first second) over the RMS of the logged wrench's noise (the logged `fx..tz` less their noise-free values: the rotor-speed
/// noise), per channel `[fx, fy, fz, tx, ty, tz]` (inf or NaN where a channel has no noise).
/// Also that noise's RMS per channel \[N, N m\].
type Snr = (Vec<(EffectKind, [f64; 6])>, [f64; 6]);
fn signal_to_noise(log: &tagk::dynamics::FlightLog, truth: &tagk::sim::FlightTruth) -> Snr {
    // After the first second: the start-of-log transient (motors spinning up to the first
    // command) is the diagnosis's start columns', not the effect's steady signature.
    let start = truth.samples.iter().take_while(|s| s.t < 1.0).count();
    let n = truth.samples.len().saturating_sub(start).max(1) as f64;
    let mut noise = [0.0; 6];
    for (s, b) in truth.samples.iter().zip(&log.wrench).skip(start) {
        for c in 0..6 {
            noise[c] += (b[c] - s.logged_actuator_wrench[c]).powi(2) / n;
        }
    }
    let ratios = truth
        .effects
        .iter()
        .enumerate()
        .map(|(k, kind)| {
            let mut ratio = [0.0; 6];
            for (c, r) in ratio.iter_mut().enumerate() {
                // Its variation: a constant part is the mass's or a bias's as much as the
                // effect's.
                let values = || {
                    truth
                        .samples
                        .iter()
                        .skip(start)
                        .map(|s| s.logged_effect_wrenches[k][c])
                };
                let mean = values().sum::<f64>() / n;
                let signal = values().map(|v| (v - mean).powi(2)).sum::<f64>() / n;
                *r = (signal / noise[c]).sqrt();
            }
            (*kind, ratio)
        })
        .collect();
    (ratios, noise.map(f64::sqrt))
}

/// The body-rate error at `horizon` steps of `dt` \[s\] of an open loop driven by white torque
/// noise of RMS `torque_noise` \[N m\] per body axis, with the principal moments
/// `I_xx, I_yy, I_zz` of `theta` \[kg m²\]: the RMS norm of a random walk,
/// `sqrt(Σ_c (σ_c / I_c)²) dt sqrt(horizon)` \[rad/s\]. What even the true model misses when
/// the logged wrench carries that noise.
fn noise_floor(torque_noise: [f64; 3], theta: [f64; 10], dt: f64, horizon: usize) -> f64 {
    let moments = [theta[4], theta[6], theta[9]];
    let per_step = torque_noise
        .iter()
        .zip(moments)
        .map(|(s, i)| (s / i).powi(2))
        .sum::<f64>()
        .sqrt();
    per_step * dt * (horizon as f64).sqrt()
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
    /// The true model (`None`: not written for these hidden effects).
    truth: Option<Errors>,
    /// Per hidden effect, its true wrench's RMS over the logged wrench's noise RMS, per
    /// channel (identification flight).
    snr: Vec<(EffectKind, [f64; 6])>,
    /// The logged torques' noise RMS per body axis (identification flight) \[N m\].
    torque_noise: [f64; 3],
    /// The true inertial parameters (docs/CONVENTIONS.md §1).
    theta: [f64; 10],
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
    if let Some(dir) = &args.logs {
        std::fs::create_dir_all(dir)?;
    }
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
        "{:>3} {:>9} {:>28} {:>31} {:>31} {:>31}  diagnosed model",
        "#",
        "T [rad/s]",
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
            let fly = |spec: &FlightSpec, name: &str| -> Result<_, Box<dyn std::error::Error>> {
                let out = simulate(&spec.sim_config())?;
                if out.metrics.aborted {
                    return Err(format!("the {:?} flight aborted", spec.trajectory).into());
                }
                if let Some(dir) = &args.logs {
                    out.log
                        .write_csv_path(dir.join(format!("flight-{index}-{name}.csv")))?;
                }
                let truth = out.truth.ok_or("the simulator recorded no truth")?;
                Ok((out.log, truth))
            };
            let (id_log, id_truth) = fly(&identify, "identify")?;
            let (snr, noise) = signal_to_noise(&id_log, &id_truth);
            // The payload is attached once the flight runs (not at its first sample).
            let theta = id_truth
                .samples
                .last()
                .ok_or("an empty flight")?
                .params
                .to_array();
            let report = run_diagnosis(id_log, None)?;
            let context = ModelContext::default();
            let diagnosed = ModelFile::from_diagnosis(&report, &context);
            diagnosed.write(&args.out.join(format!("flight-{index}.toml")))?;
            let rigid = ModelFile::steps(&report, &context)
                .into_iter()
                .next()
                .ok_or("the diagnosis has no rigid-body step")?;
            let (log, _) = fly(&held_out, "held-out")?;
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
            let motors_read = matches!(args.sensing.rotor_sensing(), RotorSensing::Erpm(_));
            let truth = match truth_model(theta, &effects, motors_read) {
                Some(model) => Some(at(&read_as(&model, &log)?, Predictor::Model(&model))?),
                None => None,
            };
            Ok((
                Scored {
                    truth,
                    snr,
                    torque_noise: [noise[3], noise[4], noise[5]],
                    theta,
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
                    "{index:>3} {:>9.2e} {:>9.2e} {:>9.2e} {:>9.2e} {:>10.2e} {:>9.2e} {:>9.2e} {:>10.2e} {:>9.2e} {:>9.2e} {:>15.2} {:>15.2}  {label}",
                    s.truth.map_or(f64::NAN, |t| t.body_rate),
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
        "the true model (T: true parameters and hidden effects, from the same noisy log): median body rate T/C {}, T/D {}; T <= C/2: {}/{n}",
        ratio(&|s| s
            .truth
            .map_or(f64::NAN, |t| t.body_rate / s.constant_rate.body_rate)),
        ratio(&|s| s
            .truth
            .map_or(f64::NAN, |t| t.body_rate / s.diagnosed.body_rate)),
        scored
            .iter()
            .filter(|s| s
                .truth
                .is_some_and(|t| t.body_rate <= 0.5 * s.constant_rate.body_rate))
            .count(),
    );
    let dt = *step.borrow();
    println!(
        "the logged torques' noise alone, integrated open loop (random walk, RMS norm): median {:.3e} rad/s at {} steps (median body-rate error T {:.3e}, C {:.3e}); median torque noise RMS [tx ty tz] {:.2e} {:.2e} {:.2e} N m",
        median(
            scored
                .iter()
                .map(|s| noise_floor(s.torque_noise, s.theta, dt, args.horizon))
                .collect()
        ),
        args.horizon,
        median(
            scored
                .iter()
                .map(|s| s.truth.map_or(f64::NAN, |t| t.body_rate))
                .collect()
        ),
        median(scored.iter().map(|s| s.constant_rate.body_rate).collect()),
        median(scored.iter().map(|s| s.torque_noise[0]).collect()),
        median(scored.iter().map(|s| s.torque_noise[1]).collect()),
        median(scored.iter().map(|s| s.torque_noise[2]).collect()),
    );
    println!(
        "each hidden effect's true wrench, RMS about its mean after the first second, over the logged wrench's noise RMS (identification flights, median) [fx fy fz tx ty tz]; a candidate's held-out gain is about its square, against 0.05 to be admitted:"
    );
    if let Some(first) = scored.first() {
        for (k, (kind, _)) in first.snr.iter().enumerate() {
            let per_channel: Vec<String> = (0..6)
                .map(|c| {
                    let m = median(
                        scored
                            .iter()
                            .filter_map(|s| s.snr.get(k).map(|e| e.1[c]))
                            .collect(),
                    );
                    format!("{m:9.3}")
                })
                .collect();
            println!("  {:<16} {}", kind.name(), per_channel.join(" "));
        }
    }
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
