//! The Table III harness on the host: every case runs with a small repetition count,
//! results are deterministic, the synthetic windows are what they claim, and single and double
//! precision agree. The firmware checks its checksums against this same computation (its
//! build script runs it on the host).

use nalgebra::{DMatrix, DVector};
use tagk_mcu::harness::NOISE;
use tagk_mcu::{
    ARENA_LEN, CASES, Case, CaseReport, EstimatorKind, HarnessError, NullCounter, Precision,
    StdClock, SyntheticWindows, run_case, run_case_in,
};

#[test]
fn every_case_runs_deterministically_and_prints_the_table() {
    let mut a32 = vec![0.0f32; ARENA_LEN];
    let mut a64 = vec![0.0f64; ARENA_LEN];
    let mut clock = StdClock::new();
    println!(
        "   {} (ticks: ns on this host, unoptimised test build)",
        CaseReport::HEADER
    );
    for (i, case) in CASES.iter().enumerate() {
        assert!(case.arena_len() <= ARENA_LEN);
        let report = run_case_in(*case, 2, &mut a32, &mut a64, &mut clock).unwrap();
        println!("{i:>2} {report}");
        assert_eq!(report.reps, 2);
        assert!(report.min_ticks <= report.max_ticks);
        // Same case again, with another counter and repetition count: same checksum.
        let again = run_case_in(*case, 1, &mut a32, &mut a64, &mut NullCounter).unwrap();
        again.verify(report.checksum).unwrap();
        assert_eq!(again.total_ticks, 0);
    }
}

#[test]
fn single_and_double_precision_agree() {
    let mut a32 = vec![0.0f32; ARENA_LEN];
    let mut a64 = vec![0.0f64; ARENA_LEN];
    for (c64, c32) in CASES[..15].iter().zip(&CASES[15..]) {
        assert_eq!(
            (c64.n, c64.precision, c32.precision),
            (c32.n, Precision::F64, Precision::F32)
        );
        let s64 = run_case_in(*c64, 1, &mut a32, &mut a64, &mut NullCounter)
            .unwrap()
            .checksum
            .sum;
        let s32 = run_case_in(*c32, 1, &mut a32, &mut a64, &mut NullCounter)
            .unwrap()
            .checksum
            .sum;
        // KF-high (f32) and KF-low (f64) weigh the data differently; compare RLS and TAG-K.
        if c64.kind == c32.kind {
            assert!(
                (s64 - s32).abs() < 1e-4 * (1.0 + s64.abs()),
                "{c64:?}: {s64} vs {s32}"
            );
        }
    }
}

#[test]
fn a_different_result_fails_verification() {
    let mut a64 = vec![0.0f64; ARENA_LEN];
    let case = CASES[2];
    let report = run_case(case, 1, &mut a64, &mut NullCounter).unwrap();
    let mut wrong = report.checksum;
    wrong.hash ^= 1;
    assert!(matches!(
        report.verify(wrong),
        Err(HarnessError::ChecksumMismatch { index: 2, .. })
    ));
    let mut wrong = report.checksum;
    wrong.sum = f64::from_bits(wrong.sum.to_bits() ^ 1);
    assert!(report.verify(wrong).is_err());
}

#[test]
fn synthetic_windows_are_a_theta_plus_bounded_noise() {
    let (n, m) = (40, 30);
    let mut stream = SyntheticWindows::for_table(n, m);
    let mut theta = vec![0.0; n];
    stream.theta(&mut theta);
    assert!(theta.iter().all(|t| (-1.0..1.0).contains(t)));
    let mut again = SyntheticWindows::for_table(n, m);
    for _ in 0..3 {
        let (mut a, mut b) = (vec![0.0f64; m * n], vec![0.0f64; m]);
        stream.next_window(&mut a, &mut b);
        let (mut a2, mut b2) = (vec![0.0f64; m * n], vec![0.0f64; m]);
        again.next_window(&mut a2, &mut b2);
        assert_eq!((&a, &b), (&a2, &b2));
        assert!(a.iter().all(|v| (-1.0..1.0).contains(v)));
        let residual = DVector::from_column_slice(&b)
            - DMatrix::from_row_slice(m, n, &a) * DVector::from_column_slice(&theta);
        assert!(
            residual.amax() <= NOISE * (1.0 + 1e-9),
            "{}",
            residual.amax()
        );
        assert!(residual.amax() > NOISE * 0.5, "the noise is really there");
    }
    let mut other = SyntheticWindows::for_table(60, m);
    let mut theta60 = vec![0.0; 60];
    other.theta(&mut theta60);
    assert_ne!(&theta60[..n], &theta[..]);
    let (mut a, mut b) = (vec![0.0f32; m * 60], vec![0.0f32; m]);
    other.next_window(&mut a, &mut b);
}

#[test]
fn bad_arguments_are_typed_errors() {
    let case = Case {
        kind: EstimatorKind::RlsLow,
        n: 40,
        m: 30,
        precision: Precision::F64,
    };
    let mut small = vec![0.0f64; case.arena_len() - 1];
    assert_eq!(
        run_case(case, 1, &mut small, &mut NullCounter).err(),
        Some(HarnessError::ArenaTooSmall {
            needed: case.arena_len(),
            found: case.arena_len() - 1
        })
    );
    let mut arena = vec![0.0f64; case.arena_len()];
    assert_eq!(
        run_case(case, 0, &mut arena, &mut NullCounter).err(),
        Some(HarnessError::NothingToRun)
    );
    assert_eq!(case.index(), Some(0));
    assert_eq!(Case { n: 41, ..case }.index(), None);
}

#[test]
fn arm_cases_run_after_the_table_and_rls_matches_batch_least_squares() {
    use tagk_mcu::harness::{ARM_M, ARM_N};
    use tagk_mcu::{ARM_ARENA_LEN, ARM_CASES, CASE_COUNT, case_at};
    assert_eq!(CASE_COUNT, 40);
    assert_eq!(case_at(29), Some(CASES[29]));
    assert_eq!(case_at(30), Some(ARM_CASES[0]));
    assert_eq!(case_at(CASE_COUNT), None);
    let mut a32 = vec![0.0f32; ARM_ARENA_LEN];
    let mut a64 = vec![0.0f64; ARM_ARENA_LEN];
    for (i, case) in ARM_CASES.iter().enumerate() {
        assert_eq!(case.index(), Some(30 + i));
        assert_eq!(case.m, ARM_M);
        assert!(ARM_N.contains(&case.n));
        assert!(case.arena_len() <= ARM_ARENA_LEN);
        let report = run_case_in(*case, 2, &mut a32, &mut a64, &mut NullCounter)
            .unwrap_or_else(|e| panic!("{case:?}: {e}"));
        let again = run_case_in(*case, 1, &mut a32, &mut a64, &mut NullCounter).unwrap();
        again.verify(report.checksum).unwrap();
    }
    // Independent check of what the arm cases compute: RLS-low (λ = 0.99, P₀ = 10³ I) on the
    // four pool windows, in f64, against batch least squares on the same rows. With
    // m = 70 ≥ n every window alone determines θ, so both sit within the noise of θ*.
    for (n, case) in [(10, ARM_CASES[0]), (70, ARM_CASES[3])] {
        assert_eq!(
            (case.kind, case.precision),
            (EstimatorKind::RlsLow, Precision::F64)
        );
        let m = ARM_M;
        let mut stream = SyntheticWindows::for_table(n, m);
        let mut theta = vec![0.0; n];
        stream.theta(&mut theta);
        let (mut rows, mut rhs) = (Vec::new(), Vec::new());
        for _ in 0..Case::POOL {
            let (mut a, mut b) = (vec![0.0f64; m * n], vec![0.0f64; m]);
            stream.next_window(&mut a, &mut b);
            rows.extend(a);
            rhs.extend(b);
        }
        let a = DMatrix::from_row_slice(Case::POOL * m, n, &rows);
        let b = DVector::from_column_slice(&rhs);
        let batch = a.clone().svd(true, true).solve(&b, 1e-12).unwrap();
        let batch_sum: f64 = batch.iter().sum();
        let report = run_case_in(case, 1, &mut a32, &mut a64, &mut NullCounter).unwrap();
        let truth: f64 = theta.iter().sum();
        // The sum of the final estimate: RLS weights old windows by λ^k, so it differs from
        // the batch solution by the noise's share only (NOISE per row, 280 rows).
        assert!(
            (report.checksum.sum - batch_sum).abs() < 1e-3 * n as f64,
            "n = {n}: RLS {} vs batch {batch_sum}",
            report.checksum.sum
        );
        assert!((batch_sum - truth).abs() < 1e-3 * n as f64, "n = {n}");
    }
}
