#![doc = include_str!("../README.md")]

pub mod cli;
pub mod diagnosis_benchmark;
pub mod model_plant;

pub use tagk_baselines as baselines;
pub use tagk_control as control;
pub use tagk_core as core;
pub use tagk_diagnose as diagnose;
pub use tagk_dynamics as dynamics;
pub use tagk_mcu as mcu;
pub use tagk_sim as sim;
