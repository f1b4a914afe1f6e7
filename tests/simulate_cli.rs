//! `tagk simulate`: flags to configuration to flight log, and the names of the shared effect
//! vocabulary.

use clap::Parser;
use tagk::cli::simulate::{SimulateArgs, SimulateError, run_simulate};
use tagk::dynamics::EffectKind;
use tagk::sim::SimError;

#[derive(Parser)]
struct Cli {
    #[command(flatten)]
    args: SimulateArgs,
}

#[test]
fn simulate_command_writes_a_log_from_flags() {
    let path = std::env::temp_dir().join(format!("tagk-sim-cli-{}.csv", std::process::id()));
    let cli = Cli::try_parse_from([
        "tagk",
        "--trajectory",
        "helix",
        "--duration",
        "2",
        "--noise",
        "low",
        "--effect",
        "rotor-drag",
        "--effect",
        "motor-lag",
        "--payload",
        "fixed",
        "--payload-mass",
        "0.01",
        "--payload-offset",
        "0.005,0,0",
        "--attach",
        "1",
        "--output",
        path.to_str().unwrap(),
    ])
    .unwrap();
    let cfg = cli.args.config().unwrap();
    assert!(cfg.effects.rotor_drag.is_some() && cfg.effects.motor_lag.is_some());
    assert!(cfg.effects.wind.is_none() && cfg.effects.linear_drag.is_none());
    let summary = run_simulate(&cli.args).unwrap();
    assert_eq!(summary.samples, 100);
    assert!(summary.to_string().starts_with("wrote 100 samples to "));
    let text = std::fs::read_to_string(&path).unwrap();
    assert_eq!(text.lines().count(), 101);
    std::fs::remove_file(&path).ok();
    let bad = Cli::try_parse_from(["tagk", "--duration", "0"]).unwrap();
    assert!(matches!(
        run_simulate(&bad.args),
        Err(SimulateError::Sim(SimError::InvalidDuration { .. }))
    ));
}

#[test]
fn effect_flag_takes_the_vocabulary_and_its_aliases() {
    let parse = |name: &str| {
        Cli::try_parse_from(["tagk", "--effect", name])
            .map(|c| c.args.effects)
            .map_err(|e| e.to_string())
    };
    for kind in EffectKind::ALL {
        assert_eq!(parse(kind.name()).unwrap(), vec![kind]);
        for alias in kind.aliases() {
            assert_eq!(parse(alias).unwrap(), vec![kind], "{alias}");
        }
    }
    let cfg = Cli::try_parse_from(["tagk", "--effect", "linear-drag", "--effect", "bias"])
        .unwrap()
        .args
        .config()
        .unwrap();
    assert!(cfg.effects.linear_drag.is_some() && cfg.effects.body_bias.is_some());
    assert!(cfg.effects.rotor_drag.is_none());
    let unknown = parse("drag").unwrap_err();
    assert!(unknown.contains("rotor-drag"), "{unknown}");
}

#[test]
fn every_effect_of_the_vocabulary_can_be_simulated() {
    for kind in EffectKind::ALL {
        let cli = Cli::try_parse_from(["tagk", "--effect", kind.name()]).unwrap();
        let cfg = cli.args.config().unwrap();
        assert!(!cfg.effects.is_ideal(), "{kind}");
    }
    let cfg = Cli::try_parse_from(["tagk", "--effect", "delay"])
        .unwrap()
        .args
        .config()
        .unwrap();
    assert!(cfg.effects.time_delay.is_some());
}

#[test]
fn names_of_trajectories_noise_and_estimators_are_unchanged() {
    let cli = Cli::try_parse_from([
        "tagk",
        "--trajectory",
        "figure8",
        "--noise",
        "high",
        "--estimator",
        "kf-high",
    ])
    .unwrap();
    assert_eq!(cli.args.trajectory, tagk::sim::TrajectoryKind::Figure8);
    assert_eq!(cli.args.noise, tagk::sim::NoiseLevel::High);
    assert_eq!(cli.args.estimator, Some(tagk::sim::EstimatorKind::KfHigh));
    assert!(Cli::try_parse_from(["tagk", "--estimator", "tagk"]).is_ok());
    assert!(Cli::try_parse_from(["tagk", "--noise", "loud"]).is_err());
}

#[test]
fn sensing_flag_selects_a_profile_and_gyro_noise_replaces_its_sigma() {
    use tagk::sim::{Sensing, SensingProfile};
    let config = |flags: &[&str]| {
        let mut argv = vec!["tagk"];
        argv.extend_from_slice(flags);
        Cli::try_parse_from(argv).unwrap().args.config().unwrap()
    };
    assert_eq!(config(&[]).sensing, Sensing::ideal());
    for p in SensingProfile::ALL {
        let c = config(&["--sensing", p.name()]);
        assert_eq!(c.sensing, p.sensing());
        assert_eq!(c.flight_stack.rotor_sensing, p.rotor_sensing(), "{p}");
    }
    // The brushless vehicle reads eRPM (no Gaussian rotor-speed noise); the others do not.
    let brushless = config(&["--sensing", "cf21-brushless"]);
    assert!(matches!(
        brushless.flight_stack.rotor_sensing,
        tagk::sim::sim::rotor_sensing::RotorSensing::Erpm(_)
    ));
    assert_eq!(brushless.sensing.rotor_speed_noise, 0.0);
    assert_eq!(
        config(&["--sensing", "realistic"]).flight_stack,
        config(&[]).flight_stack
    );
    let gyro = config(&["--sensing", "realistic", "--gyro-noise", "0.02"]).sensing;
    assert_eq!(gyro, Sensing::realistic().with_gyro_noise(0.02));
    assert_eq!(
        config(&["--gyro-noise", "0.01"]).sensing,
        Sensing::ideal().with_gyro_noise(0.01)
    );
    let unknown = Cli::try_parse_from(["tagk", "--sensing", "perfect"])
        .map(|_| ())
        .unwrap_err()
        .to_string();
    assert!(unknown.contains("realistic-calibrated"), "{unknown}");
}

#[test]
fn yaw_rate_flag_sets_the_reference_heading_rate() {
    let yaw = |flags: &[&str]| {
        let mut argv = vec!["tagk"];
        argv.extend_from_slice(flags);
        Cli::try_parse_from(argv)
            .unwrap()
            .args
            .config()
            .unwrap()
            .yaw_rate
    };
    assert_eq!(yaw(&[]), 0.0);
    assert_eq!(yaw(&["--yaw-rate", "0.5"]), 0.5);
    assert_eq!(yaw(&["--yaw-rate", "-0.5"]), -0.5);
}

#[test]
fn log_rate_flag_records_every_physics_step() {
    use tagk::sim::LogRate;
    let path = std::env::temp_dir().join(format!("tagk-sim-rate-{}.csv", std::process::id()));
    let cli = Cli::try_parse_from([
        "tagk",
        "--duration",
        "2",
        "--log-rate",
        "physics",
        "--output",
        path.to_str().unwrap(),
    ])
    .unwrap();
    assert_eq!(cli.args.config().unwrap().log_rate, LogRate::Physics);
    let summary = run_simulate(&cli.args).unwrap();
    assert_eq!(summary.samples, 1000);
    let header = std::fs::read_to_string(&path).unwrap();
    let header = header.lines().next().unwrap().to_string();
    std::fs::remove_file(&path).ok();
    assert!(header.contains("ax") && !header.contains("dwx"), "{header}");
    let default = Cli::try_parse_from(["tagk"])
        .unwrap()
        .args
        .config()
        .unwrap();
    assert_eq!(default.log_rate, LogRate::Control);
}
