//! The arm's Table II: online payload estimation on a UR5, a Panda or your own URDF.
//!
//! Every estimator (behind `OnlineEstimator`), `nominal` (never adapts) and `oracle` (true
//! parameters at once) feed a computed-torque controller on the same random runs. Two scopes:
//! the flange body's 10 parameters (the payload; the other links known), and every link's
//! (`10·n`, reduced to the numerical base parameters; the URDF's links off by ±15 %).
//! `cargo run --release --example arm_payload -- --help` lists the options. The simulation
//! lives in `tagk::sim::arm`; this example parses flags, shows progress and prints.

use std::path::PathBuf;
use std::time::Instant;

use clap::Parser;
use rayon::prelude::*;
use tagk::cli::progress::Progress;
use tagk::dynamics::UrdfOptions;
use tagk::sim::arm::{
    ARM_JUDGE_TIME, ARM_SETTLE_TIME, ARM_SUCCESS_THRESHOLD, ArmAdaptation, ArmExperiment, ArmModel,
    ArmRow, ArmTrajectoryKind, BaseParameters, EstimationScope, JointSensing, arm_table,
    arm_table_rows, run_arm_trial, simulate_arm,
};

/// Online payload estimation on a robot arm: every estimator, nominal and oracle.
#[derive(Debug, Clone, Parser)]
struct Args {
    /// Trials per row and scope.
    #[arg(long, default_value_t = 4)]
    trials: usize,
    /// Base seed.
    #[arg(long, default_value_t = 2025)]
    seed: u64,
    /// The arm: `ur5`, `panda` (fingers locked) or the path of a URDF.
    #[arg(long, default_value = "panda")]
    robot: String,
    /// What is estimated: `payload` (n = 10), `all` (10 per link, base parameters) or `both`.
    #[arg(long, default_value = "both")]
    scope: String,
    /// The reference: `fourier` (excitation) or `pick-place`.
    #[arg(long, default_value = "fourier")]
    trajectory: String,
    /// Exact sensing instead of the realistic encoders, velocity and torque noise and offsets.
    #[arg(long)]
    ideal_sensing: bool,
    /// Run length [s].
    #[arg(long, default_value_t = 8.0)]
    duration: f64,
    /// Write the joint-space log of the first trial's oracle run (CSV
    /// `t,q1..qN,dq1..dqN,ddq1..ddqN,tau1..tauN`) here.
    #[arg(long)]
    log: Option<PathBuf>,
    /// Rayon threads [default: all cores].
    #[arg(long)]
    threads: Option<usize>,
    /// Hide the progress bar.
    #[arg(long)]
    quiet: bool,
}

fn robot_path(name: &str) -> (PathBuf, UrdfOptions) {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/tagk-dynamics/robots");
    match name {
        "ur5" => (
            PathBuf::from(format!("{dir}/ur5.urdf")),
            UrdfOptions::default(),
        ),
        "panda" => (
            PathBuf::from(format!("{dir}/panda.urdf")),
            UrdfOptions {
                locked_joints: vec!["panda_finger_joint1".into(), "panda_finger_joint2".into()],
            },
        ),
        path => (PathBuf::from(path), UrdfOptions::default()),
    }
}

fn run() -> Result<(), String> {
    let args = Args::parse();
    let (path, options) = robot_path(&args.robot);
    let model = ArmModel::from_urdf_file(&path, &options).map_err(|e| e.to_string())?;
    let scopes = match args.scope.as_str() {
        "payload" => vec![EstimationScope::Payload],
        "all" => vec![EstimationScope::AllLinks],
        "both" => vec![EstimationScope::Payload, EstimationScope::AllLinks],
        s => return Err(format!("unknown scope `{s}` (payload, all, both)")),
    };
    let trajectory = match args.trajectory.as_str() {
        "fourier" => ArmTrajectoryKind::Fourier,
        "pick-place" => ArmTrajectoryKind::PickAndPlace,
        s => return Err(format!("unknown trajectory `{s}` (fourier, pick-place)")),
    };
    if args.trials == 0 {
        return Err("--trials must be at least 1".into());
    }
    if let Some(t) = args.threads {
        rayon::ThreadPoolBuilder::new()
            .num_threads(t)
            .build_global()
            .map_err(|e| e.to_string())?;
    }
    let rows = arm_table_rows();
    let total = (scopes.len() * rows.len() * args.trials) as u64;
    let progress = Progress::counting(!args.quiet, total, "runs");
    let start = Instant::now();
    println!(
        "{} ({} joints), {} trials per row, seed {}, {} s runs, {:?}, {} sensing",
        model.tree.name(),
        model.dof(),
        args.trials,
        args.seed,
        args.duration,
        trajectory,
        if args.ideal_sensing {
            "ideal"
        } else {
            "realistic"
        }
    );
    for scope in scopes {
        let base = BaseParameters::compute(&model, scope, args.seed).map_err(|e| e.to_string())?;
        let mut experiment = ArmExperiment::new(scope);
        experiment.duration = args.duration;
        experiment.trajectory = trajectory;
        if args.ideal_sensing {
            experiment.sensing = JointSensing::IDEAL;
        }
        progress.message(scope.name());
        let jobs: Vec<(usize, usize)> = (0..rows.len())
            .flat_map(|r| (0..args.trials).map(move |t| (r, t)))
            .collect();
        let results: Vec<_> = jobs
            .par_iter()
            .map(|&(r, t)| {
                let seed = tagk::sim::trial_seed(args.seed, 0, t);
                let m = run_arm_trial(&model, &base, &experiment, seed, rows[r]);
                progress.inc();
                m
            })
            .collect::<Result<_, _>>()
            .map_err(|e| e.to_string())?;
        let table: Vec<ArmRow> = rows
            .iter()
            .enumerate()
            .map(|(r, a)| {
                ArmRow::from_trials(&a.label(), &results[r * args.trials..(r + 1) * args.trials])
            })
            .collect();
        progress.suspend(|| {
            println!(
                "\n{}: n = {} parameters, {} base parameters (estimator dimension)",
                scope.name(),
                base.columns.len(),
                base.rank()
            );
            print!("{}", arm_table(&table));
        });
    }
    progress.finish();
    println!(
        "\nsuccess: no abort, and RMS flange error ≤ {} mm over [{}, {}] s after each grasp and release",
        ARM_SUCCESS_THRESHOLD * 1e3,
        ARM_SETTLE_TIME,
        ARM_SETTLE_TIME + ARM_JUDGE_TIME
    );
    println!(
        "param err: ‖β̂ − β‖/‖β‖ on the base parameters, mean over updates; (t+1): first update after each event"
    );
    println!(
        "{:.1} s on {} threads",
        start.elapsed().as_secs_f64(),
        rayon::current_num_threads()
    );
    if let Some(log_path) = &args.log {
        let base = BaseParameters::compute(&model, EstimationScope::Payload, args.seed)
            .map_err(|e| e.to_string())?;
        let mut experiment = ArmExperiment::new(EstimationScope::Payload);
        experiment.duration = args.duration;
        experiment.trajectory = trajectory;
        let mut config = experiment
            .config(
                &model,
                tagk::sim::trial_seed(args.seed, 0, 0),
                ArmAdaptation::Oracle,
            )
            .map_err(|e| e.to_string())?;
        config.record_log = true;
        let out = simulate_arm(&model, &base, &config).map_err(|e| e.to_string())?;
        if let Some(log) = out.log {
            log.write_csv(log_path).map_err(|e| e.to_string())?;
            println!("log in {}", log_path.display());
        }
    }
    Ok(())
}

fn main() {
    tagk::cli::terminal::end_quietly_on_broken_pipe();
    if let Err(e) = run() {
        eprintln!("arm_payload: {e}");
        std::process::exit(1);
    }
}
