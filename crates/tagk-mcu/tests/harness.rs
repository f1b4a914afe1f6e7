//! The Table III harness on the host: every case runs, and reproduces the reference checksums
//! the firmware checks against.

use tagk_mcu::{ARENA_LEN, CASES, CaseReport, StdClock, run_case_in};

#[test]
fn every_case_runs_and_matches_the_reference_checksum() {
    let mut a32 = vec![0.0f32; ARENA_LEN];
    let mut a64 = vec![0.0f64; ARENA_LEN];
    let mut clock = StdClock::new();
    println!("{}", CaseReport::HEADER);
    let mut mismatches = Vec::new();
    for (i, case) in CASES.iter().enumerate() {
        let report = run_case_in(*case, 2, &mut a32, &mut a64, &mut clock).unwrap();
        println!("{report}");
        if report.verify().is_err() {
            mismatches.push(format!(
                "    Checksum {{ hash: 0x{:016x}, sum: {:e} }}, // {i}: {} n={} {}",
                report.checksum.hash,
                report.checksum.sum,
                case.kind.label(),
                case.n,
                case.precision.label()
            ));
        }
    }
    assert!(mismatches.is_empty(), "GOLDEN differs:\n{}", mismatches.join("\n"));
}
