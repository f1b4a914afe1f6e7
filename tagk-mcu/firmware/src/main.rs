//! Table III on a Cortex-M7: RLS, KF and TAG-K per-update cost for `n ∈ {40, …, 120}`,
//! `m = 30`, `f32` and `f64`, with every case's estimates checked against the host's. Then the
//! arm cases (`tagk_mcu::ARM_CASES`): the same estimators at `n ∈ {10, 70}`, `m = 70`.
//!
//! Runs on QEMU's `mps2-an500` with semihosting (see `run.sh`) or, with its own memory map
//! and clock, on any ARMv7E-M board with a DWT cycle counter.
//!
//! - Without a selection file: runs every case with `TABLE_REPS` timed updates, prints one row
//!   per case, `firmware: N passed, M failed` for Table III and `firmware arm cases: N passed,
//!   M failed` for the arm, and exits with status 1 on any failure.
//! - With a file `tagk-mcu-case.txt` (`INDEX REPS`) in QEMU's working directory: runs that one
//!   case of `tagk_mcu::case_at` (Table III's 0–29, then the arm's) with `REPS` timed updates,
//!   so that two runs with different `REPS` give the executed instructions per update under the
//!   instruction-counting plugin.

#![no_std]
#![no_main]

use cortex_m_rt::entry;
use cortex_m_semihosting::{debug, hprintln, syscall};
use panic_semihosting as _;
use tagk_mcu::{
    ARENA_LEN, ARM_ARENA_LEN, ARM_CASES, CASE_COUNT, CASES, Case, CaseReport, CycleCounter,
    DwtCycleCounter, HarnessError, Precision, case_at, run_case,
};

include!(concat!(env!("OUT_DIR"), "/expected.rs"));

/// Timed updates per case in the full-table run.
const TABLE_REPS: usize = 2;
/// The core clock the cycle counter reports against (mps2-an500: 25 MHz; QEMU does not run
/// `CYCCNT` anyway). A Teensy 4.1 runs at 600 MHz.
const CORE_HZ: u32 = 25_000_000;
/// The semihosting file that selects a single case.
const SELECTION: &[u8] = b"tagk-mcu-case.txt\0";

/// `f64`s in the arena: enough for every Table III case and every arm case.
const FIRMWARE_ARENA_LEN: usize = if ARM_ARENA_LEN > ARENA_LEN {
    ARM_ARENA_LEN
} else {
    ARENA_LEN
};

/// One arena for every case: `f64` cases use it as is, `f32` cases as twice as many `f32`s.
static mut ARENA: [f64; FIRMWARE_ARENA_LEN] = [0.0; FIRMWARE_ARENA_LEN];

#[entry]
fn main() -> ! {
    let mut cp = cortex_m::Peripherals::take().expect("peripherals are taken once");
    let mut counter = DwtCycleCounter::new(&mut cp.DCB, &mut cp.DWT, CORE_HZ);
    // SAFETY: `main` runs once and is the only code that touches ARENA.
    let arena: &'static mut [f64] = unsafe { &mut *(&raw mut ARENA) };

    let ok = match read_selection() {
        Some((index, reps)) => run_selected(index, reps, arena, &mut counter),
        None => run_table(arena, &mut counter),
    };
    debug::exit(if ok {
        debug::EXIT_SUCCESS
    } else {
        debug::EXIT_FAILURE
    });
    #[allow(clippy::empty_loop)]
    loop {}
}

/// Runs one case in `arena`, viewed as `f32`s for single-precision cases.
fn run(
    case: Case,
    reps: usize,
    arena: &mut [f64],
    counter: &mut DwtCycleCounter,
) -> Result<CaseReport, HarnessError> {
    match case.precision {
        Precision::F64 => run_case(case, reps, arena, counter),
        Precision::F32 => {
            // SAFETY: `f32` has a smaller alignment than `f64` and no invalid bit patterns;
            // the view covers exactly the arena's bytes, and `arena` is not used while it lives.
            let view = unsafe {
                core::slice::from_raw_parts_mut(arena.as_mut_ptr().cast::<f32>(), arena.len() * 2)
            };
            run_case(case, reps, view, counter)
        }
    }
}

/// Runs a case and checks its checksum against the host's; prints one row.
fn run_checked(
    index: usize,
    reps: usize,
    arena: &mut [f64],
    counter: &mut DwtCycleCounter,
) -> bool {
    let Some(case) = case_at(index) else {
        hprintln!("{:>2} FAILED: no case {}", index, index);
        return false;
    };
    match run(case, reps, arena, counter).and_then(|r| r.verify(EXPECTED[index]).map(|()| r)) {
        Ok(report) => {
            hprintln!("{:>2} {} ok", index, report);
            true
        }
        Err(e) => {
            hprintln!("{:>2} FAILED: {}", index, e);
            false
        }
    }
}

fn run_table(arena: &mut [f64], counter: &mut DwtCycleCounter) -> bool {
    hprintln!(
        "tagk-mcu Table III on a Cortex-M7: m = 30, {} timed updates per case",
        TABLE_REPS
    );
    if counter.ticks_per_second() > 0 {
        let t0 = counter.now();
        let t1 = counter.now();
        if counter.elapsed(t0, t1) == 0 {
            hprintln!("(the DWT cycle counter does not run here, as under QEMU: ticks read 0)");
        }
    }
    hprintln!("   {}", CaseReport::HEADER);
    let mut passed = 0;
    for index in 0..CASES.len() {
        if run_checked(index, TABLE_REPS, arena, counter) {
            passed += 1;
        }
    }
    hprintln!(
        "firmware: {} passed, {} failed",
        passed,
        CASES.len() - passed
    );
    hprintln!(
        "arm cases: m = {}, n = {:?}, same estimators and checks",
        ARM_CASES[0].m,
        tagk_mcu::harness::ARM_N
    );
    let mut arm_passed = 0;
    for index in CASES.len()..CASE_COUNT {
        if run_checked(index, TABLE_REPS, arena, counter) {
            arm_passed += 1;
        }
    }
    hprintln!(
        "firmware arm cases: {} passed, {} failed",
        arm_passed,
        ARM_CASES.len() - arm_passed
    );
    passed == CASES.len() && arm_passed == ARM_CASES.len()
}

fn run_selected(
    index: usize,
    reps: usize,
    arena: &mut [f64],
    counter: &mut DwtCycleCounter,
) -> bool {
    if index >= CASE_COUNT || reps == 0 {
        hprintln!("bad selection: case {} with {} repetitions", index, reps);
        return false;
    }
    run_checked(index, reps, arena, counter)
}

/// Reads `INDEX REPS` from the semihosting file [`SELECTION`], if it exists.
fn read_selection() -> Option<(usize, usize)> {
    // SAFETY: semihosting calls with a NUL-terminated path and a buffer we own.
    let fd = unsafe { syscall!(OPEN, SELECTION.as_ptr(), 0, SELECTION.len() - 1) };
    if fd == usize::MAX {
        return None;
    }
    let mut buf = [0u8; 32];
    let not_read = unsafe { syscall!(READ, fd, buf.as_mut_ptr(), buf.len()) };
    unsafe { syscall!(CLOSE, fd) };
    let text = core::str::from_utf8(&buf[..buf.len().saturating_sub(not_read)]).ok()?;
    let mut fields = text
        .split_ascii_whitespace()
        .map(|f| f.parse::<usize>().ok());
    Some((fields.next()??, fields.next()??))
}
