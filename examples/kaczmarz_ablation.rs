//! Fig. 4b of the TAG-K paper: RK, TARK, GRK, TAG-K across payload events, and a burn-in sweep.
//!
//! `cargo run --release --example kaczmarz_ablation -- --help` lists the options; results go to
//! `out/kaczmarz_ablation/` unless `--out` says otherwise. The logic lives in `tagk_sim::experiments`.

use tagk::sim::clap::Parser;
use tagk::sim::experiments::{KaczmarzAblationArgs, run_kaczmarz_ablation};

fn main() {
    let args = KaczmarzAblationArgs::parse();
    if let Err(e) = run_kaczmarz_ablation(&args) {
        eprintln!("kaczmarz_ablation: {e}");
        std::process::exit(1);
    }
}
