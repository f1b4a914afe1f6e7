//! Writes a UR5 joint-torque log for `tagk diagnose LOG --robot ur5` (docs/ARM_LOG.md).
//!
//! The arm follows a prescribed Fourier excitation (5 harmonics of 0.1 Hz) for one period.
//! Its torques are inverse dynamics of the URDF with a 1.2 kg payload at the flange, plus
//! viscous and Coulomb friction on every joint. The sensing is a UR's: 2¹⁸-count encoders,
//! velocity noise 2·10⁻³ rad/s, torque noise 0.2 N m; the accelerations are not logged.
//!
//! Run: `cargo run --release --example arm_log -- examples/data/arm/ur5.csv`, then
//! `cargo run --release -- diagnose examples/data/arm/ur5.csv --robot ur5`.
//! The shipped `examples/data/arm/ur5.csv` is this example's output with the default seed.

use clap::Parser;
use tagk::dynamics::nalgebra::Vector3;
use tagk::dynamics::robots::shipped_urdf;
use tagk::dynamics::{InertialParams, JointEffects, KinematicTree};
use tagk::sim::arm::{FourierTrajectory, JointSensing, prescribed_log};

/// Writes a simulated UR5 joint-torque log with friction and a payload hidden in it.
#[derive(Debug, Parser)]
struct Args {
    /// Where to write the CSV log.
    #[arg(default_value = "out/arm/ur5.csv")]
    out: std::path::PathBuf,
    /// Seed of the excitation and the sensor noise.
    #[arg(long, default_value_t = 28)]
    seed: u64,
}

/// Viscous [N m s/rad] and Coulomb [N m] friction of the six joints (UR5-like magnitudes).
const VISCOUS: [f64; 6] = [1.8, 1.6, 1.2, 0.5, 0.4, 0.3];
const COULOMB: [f64; 6] = [2.5, 2.2, 1.6, 0.8, 0.7, 0.6];

fn main() -> std::process::ExitCode {
    tagk::cli::terminal::end_quietly_on_broken_pipe();
    tagk::cli::terminal::exit_code("arm_log", run())
}

/// The example; an error is printed once by `main`.
fn run() -> Result<(), Box<dyn std::error::Error>> {
    let args = Args::parse();
    let tree = KinematicTree::from_urdf_str(shipped_urdf("ur5").ok_or("ur5 is shipped")?)?;
    let dof = tree.dof();
    let mut effects = JointEffects::none(dof);
    effects.viscous = VISCOUS.to_vec();
    effects.coulomb = COULOMB.to_vec();
    // 1.2 kg held 8 cm beyond the flange (wrist_3_link's z axis).
    let payload = InertialParams::point_mass(1.2, Vector3::new(0.0, 0.0, 0.08));
    let motion = FourierTrajectory::random_with_speed(dof, 5, 0.1, 1.0, args.seed);
    let sensing = JointSensing {
        torque_noise: 0.2,
        torque_offset: 0.0,
        ..JointSensing::REALISTIC
    };
    let mut log = prescribed_log(
        &tree,
        Some(&payload),
        &effects,
        &motion,
        &sensing,
        false,
        100.0,
        10.0,
        args.seed,
    )?;
    // Round below the sensors' resolution: a smaller file, the same information.
    let round = |v: &mut Vec<Vec<f64>>, scale: f64| {
        v.iter_mut()
            .flatten()
            .for_each(|x| *x = (*x * scale).round() / scale);
    };
    round(&mut log.q, 1e7);
    round(&mut log.qd, 1e6);
    round(&mut log.tau, 1e4);
    log.write_csv_path(&args.out)?;
    println!(
        "wrote {} ({} samples, {} joints): diagnose it with\n  tagk diagnose {} --robot ur5",
        args.out.display(),
        log.len(),
        dof,
        args.out.display()
    );
    Ok(())
}
