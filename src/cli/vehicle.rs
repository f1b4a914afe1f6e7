//! `tagk vehicle`: list the built-in vehicle presets and print one as a vehicle-file template
//! (`tagk vehicle show crazyflie-2.1 > my-quad.toml`, then edit it; the format is in
//! `docs/VEHICLE.md`).

use crate::dynamics::vehicle::{PRESETS, ThrustCurve, Vehicle, VehicleError};

/// Arguments of tagk vehicle.
#[derive(Debug, Clone, clap::Args)]
pub struct VehicleArgs {
    /// What to do.
    #[command(subcommand)]
    pub command: VehicleCommand,
}

/// The subcommands of tagk vehicle.
#[derive(Debug, Clone, clap::Subcommand)]
pub enum VehicleCommand {
    /// List the built-in vehicle presets (usable as --vehicle NAME).
    List,
    /// Print a preset (or check a vehicle file) as a commented TOML vehicle file, a template
    /// to edit for your own vehicle.
    Show {
        /// A preset name (tagk vehicle list) or a vehicle file.
        #[arg(value_name = "NAME|FILE")]
        name: String,
    },
}

/// One line per preset: name, thrust model, largest rotor speed, mass prior.
pub fn preset_list() -> String {
    let mut text = String::new();
    for name in PRESETS {
        if let Ok(v) = Vehicle::preset(name) {
            let thrust = match &v.thrust {
                ThrustCurve::Quadratic { k_f } => format!("k_f {k_f:e} N/(rad/s)^2"),
                ThrustCurve::Polynomial { coefficients } => {
                    format!("thrust curve of degree {}", coefficients.len() - 1)
                }
            };
            let mass = v
                .mass
                .map_or_else(|| "no mass prior".to_string(), |m| format!("mass {m} kg"));
            text.push_str(&format!(
                "{name:<16} 4 rotors, {thrust}, max {} rad/s, {mass}\n",
                v.max_rotor_speed
            ));
        }
    }
    text
}

/// Runs `tagk vehicle`: the text to print (the preset list, or the vehicle as TOML).
///
/// # Errors
/// `show` with a name that is neither a preset nor a valid vehicle file.
pub fn run_vehicle(args: &VehicleArgs) -> Result<String, VehicleError> {
    match &args.command {
        VehicleCommand::List => Ok(preset_list()),
        VehicleCommand::Show { name } => Ok(Vehicle::from_name_or_path(name)?.to_toml_string()),
    }
}
