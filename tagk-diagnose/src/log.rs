//! Flight logs: the one log type of tagk and its CSV reader and writer live in
//! [`tagk_dynamics::log`] (shared with the simulator); this module re-exports them under the
//! names the diagnosis uses.

pub use tagk_dynamics::log::{
    FlightLog, LogError, LogSample, MIN_ROWS, OPTIONAL_COLUMNS, QUATERNION_NORM_TOLERANCE,
    REQUIRED_COLUMNS,
};
