//! Smoothing differentiator for logs without accelerations: the one Savitzky–Golay
//! implementation lives in [`tagk_dynamics::deriv`] (the log input pipeline derives velocity
//! from position with it); re-exported here under the name the diagnosis uses.

pub use tagk_dynamics::deriv::*;
