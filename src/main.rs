//! The `tagk` command: simulate flights and diagnose models against flight logs.
//!
//! ```text
//! tagk simulate --help     write a realistic flight log (CSV) from the simulator
//! tagk diagnose LOG.csv    compare the rigid-body model with a log, find what is missing
//! tagk compare LOG.csv --model m.toml   k-step prediction error of identified models
//! tagk vehicle show NAME   print a vehicle preset as a vehicle-file template
//! ```

use std::process::ExitCode;

use clap::{Parser, Subcommand};

/// Online inertial-parameter estimation for robots: simulate flights and diagnose models.
#[derive(Parser)]
#[command(name = "tagk", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

// Parsed once per run: the size of the largest variant (diagnose's arguments) does not matter.
#[allow(clippy::large_enum_variant)]
#[derive(Subcommand)]
enum Command {
    /// Simulate a flight of the Crazyflie, a --vehicle file's quadrotor or a --model file's
    /// identified model (trajectory, payloads, plant effects, sensor noise) and write it as a
    /// flight log.
    Simulate(tagk::cli::simulate::SimulateArgs),
    /// Fit the rigid-body model to a flight log, show where it fails, rank the physical effects
    /// that are missing, and refit with the ones you add (--with); with --robot, a robot arm's
    /// joint-torque log against its URDF.
    Diagnose(tagk::cli::diagnose::DiagnoseArgs),
    /// Predict each log k steps ahead with identified models (model files of diagnose
    /// --save-model) from every sample, and report the error against the horizon (MATLAB's
    /// compare(data, sys, k)).
    Compare(tagk::cli::compare::CompareArgs),
    /// List the vehicle presets or print one as a vehicle file (TOML) to edit
    /// (--vehicle of diagnose).
    Vehicle(tagk::cli::vehicle::VehicleArgs),
}

fn main() -> ExitCode {
    tagk::cli::terminal::end_quietly_on_broken_pipe();
    let cli = Cli::parse();
    let result: Result<(), Box<dyn std::error::Error>> = match &cli.command {
        Command::Simulate(args) => tagk::cli::simulate::run_simulate(args)
            .map(|summary| {
                if !args.quiet {
                    println!("{summary}");
                }
            })
            .map_err(Into::into),
        Command::Diagnose(args) => tagk::cli::diagnose::run_diagnose(args).map_err(Into::into),
        Command::Compare(args) => tagk::cli::compare::run_compare(args).map_err(Into::into),
        Command::Vehicle(args) => tagk::cli::vehicle::run_vehicle(args)
            .map(|text| print!("{text}"))
            .map_err(Into::into),
    };
    // Each message once: a cause the message already quotes is not printed again.
    tagk::cli::terminal::exit_code("tagk", result)
}
