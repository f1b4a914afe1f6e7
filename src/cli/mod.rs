//! The command-line front ends of the `tagk` binary (clap argument types and the functions
//! that run them; the libraries below do not print).

pub mod diagnose;
