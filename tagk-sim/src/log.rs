//! Flight logs in the CONVENTIONS §6 CSV format (v1).

use std::io::Write;
use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::SimError;

/// One log row: what the vehicle measured and commanded over one control interval.
///
/// Every quantity refers to the interval's midpoint `t` (see the crate docs on the
/// measurement model): position and attitude are the true (motion-capture) values, velocity
/// carries the velocity noise, the body rate the gyro noise, `accel_world` is the (noisy)
/// accelerometer reading rotated into the world frame with gravity added back
/// (`p̈ = R a_meas + g_w`), `omega_dot` the difference of gyro rates across the interval, and
/// the wrench and rotor speeds are the commanded ones (nominal `k_f`, `k_m`, through the mixer).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LogSample {
    /// Time [s].
    pub t: f64,
    /// World position [m].
    pub position: [f64; 3],
    /// World velocity [m/s].
    pub velocity: [f64; 3],
    /// Attitude quaternion `(w, x, y, z)`, body → world.
    pub attitude: [f64; 4],
    /// Body angular velocity [rad/s].
    pub body_rate: [f64; 3],
    /// Actuator wrench `[fx, fy, fz, tx, ty, tz]`, body frame, about the origin [N, N m].
    pub wrench: [f64; 6],
    /// World linear acceleration `p̈` [m/s²].
    pub accel_world: [f64; 3],
    /// Body angular acceleration [rad/s²].
    pub omega_dot: [f64; 3],
    /// Commanded rotor speeds M1..M4 [rad/s].
    pub rotor_speeds: [f64; 4],
}

/// The CSV header of [`write_log_csv`].
pub const LOG_HEADER: [&str; 30] = [
    "t", "px", "py", "pz", "vx", "vy", "vz", "qw", "qx", "qy", "qz", "wx", "wy", "wz", "fx", "fy",
    "fz", "tx", "ty", "tz", "ax", "ay", "az", "dwx", "dwy", "dwz", "w1", "w2", "w3", "w4",
];

/// Writes a flight log (CONVENTIONS §6: header row, one row per sample, SI units, columns
/// `t, px..pz, vx..vz, qw..qz, wx..wz, fx..fz, tx..tz, ax..az, dwx..dwz, w1..w4`).
///
/// # Errors
/// [`SimError::InvalidParameter`] if the times are not strictly increasing; I/O and CSV
/// errors.
pub fn write_log_csv<W: Write>(samples: &[LogSample], writer: W) -> Result<(), SimError> {
    if let Some(w) = samples
        .windows(2)
        .find(|w| w[1].t.partial_cmp(&w[0].t) != Some(std::cmp::Ordering::Greater))
    {
        return Err(SimError::InvalidParameter {
            name: "log time",
            value: w[1].t,
            reason: "times must be strictly increasing",
        });
    }
    let mut out = csv::Writer::from_writer(writer);
    out.write_record(LOG_HEADER)?;
    let mut row: Vec<String> = Vec::with_capacity(30);
    for s in samples {
        row.clear();
        row.push(format!("{}", s.t));
        for v in s
            .position
            .iter()
            .chain(&s.velocity)
            .chain(&s.attitude)
            .chain(&s.body_rate)
            .chain(&s.wrench)
            .chain(&s.accel_world)
            .chain(&s.omega_dot)
            .chain(&s.rotor_speeds)
        {
            row.push(format!("{v:e}"));
        }
        out.write_record(&row)?;
    }
    out.flush()?;
    Ok(())
}

/// [`write_log_csv`] to a file (parent directories are created).
///
/// # Errors
/// As [`write_log_csv`].
pub fn write_log_csv_file(samples: &[LogSample], path: &Path) -> Result<(), SimError> {
    if let Some(dir) = path.parent()
        && !dir.as_os_str().is_empty()
    {
        std::fs::create_dir_all(dir)?;
    }
    let file = std::io::BufWriter::new(std::fs::File::create(path)?);
    write_log_csv(samples, file)
}
