//! Puts `memory.x` on the linker path, and runs the verification updates of every case (Table
//! III's, then the arm's) on the host to embed their checksums: the firmware must reproduce
//! them bit for bit.

use std::fmt::Write as _;
use std::path::PathBuf;

use tagk_mcu::{ARENA_LEN, ARM_ARENA_LEN, CASE_COUNT, NullCounter, case_at, run_case_in};

fn main() {
    let out = PathBuf::from(std::env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"));
    std::fs::write(out.join("memory.x"), include_bytes!("memory.x")).expect("write memory.x");
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rerun-if-changed=memory.x");
    println!("cargo:rerun-if-changed=build.rs");

    let len = ARENA_LEN.max(ARM_ARENA_LEN);
    let mut a32 = vec![0.0f32; len];
    let mut a64 = vec![0.0f64; len];
    let mut src = String::from(
        "/// Checksums of the verification updates of every case, computed on the host by build.rs.\n\
         const EXPECTED: [tagk_mcu::Checksum; tagk_mcu::CASE_COUNT] = [\n",
    );
    for (i, case) in (0..CASE_COUNT).filter_map(case_at).enumerate() {
        let report = run_case_in(case, 1, &mut a32, &mut a64, &mut NullCounter)
            .unwrap_or_else(|e| panic!("case {i} failed on the host: {e}"));
        writeln!(
            src,
            "    tagk_mcu::Checksum {{ hash: {:#018x}, sum: f64::from_bits({:#018x}) }}, // {} n={} {}",
            report.checksum.hash,
            report.checksum.sum.to_bits(),
            case.kind.name(),
            case.n,
            case.precision.label()
        )
        .expect("write to a String");
    }
    src.push_str("];\n");
    std::fs::write(out.join("expected.rs"), src).expect("write expected.rs");
}
