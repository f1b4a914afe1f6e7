//! The Table III estimators over borrowed buffers: TAG-K is tagk-core's kernel (bit-identical
//! to building it directly) and converges to the batch least-squares solution; buffer sizes
//! and RAM figures match what the constructors accept.

use nalgebra::{DMatrix, DVector};
use tagk_mcu::harness::{TABLE_M, TABLE_N};
use tagk_mcu::{
    ConfigError, EstimatorKind, McuEstimator, OnlineEstimator, SyntheticWindows, TagK, buffer_len,
    kaczmarz_buffer_len, state_bytes, tagk_paper_config,
};

#[test]
fn tagk_is_tagk_core_bit_for_bit() {
    let (n, m) = (12, 6);
    let mut stream = SyntheticWindows::new(9, n, m);
    let mut buf = vec![0.0; buffer_len(EstimatorKind::TagK, n, m)];
    let mut ours = McuEstimator::build(EstimatorKind::TagK, n, m, &mut buf).unwrap();
    let mut direct = TagK::<f64, Vec<f64>>::with_storage(
        n,
        m,
        tagk_paper_config(),
        vec![0.0; kaczmarz_buffer_len(n, m)],
    )
    .unwrap();
    assert_eq!(ours.name(), "TAG-K");
    for _ in 0..20 {
        let (mut a, mut b) = (vec![0.0; m * n], vec![0.0; m]);
        stream.next_window(&mut a, &mut b);
        let x = ours.update(&a, &b).unwrap();
        let y = direct.update(&a, &b).unwrap();
        assert_eq!(x, y);
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(ours.estimate()), bits(direct.estimate()));
    }
}

#[test]
fn tagk_converges_to_the_batch_least_squares_solution() {
    // A fixed, consistent system seen window after window: TAG-K must reach its solution.
    let (n, m) = (8, 6);
    let mut stream = SyntheticWindows::new(3, n, m);
    let windows: Vec<(Vec<f64>, Vec<f64>)> = (0..3)
        .map(|_| {
            let (mut a, mut b) = (vec![0.0; m * n], vec![0.0; m]);
            stream.next_window(&mut a, &mut b);
            (a, b)
        })
        .collect();
    let stacked_a: Vec<f64> = windows.iter().flat_map(|w| w.0.iter().copied()).collect();
    let stacked_b: Vec<f64> = windows.iter().flat_map(|w| w.1.iter().copied()).collect();
    let a = DMatrix::from_row_slice(3 * m, n, &stacked_a);
    let b = DVector::from_column_slice(&stacked_b);
    let ls = (a.transpose() * &a)
        .lu()
        .solve(&(a.transpose() * &b))
        .unwrap();
    // Make the system consistent with the least-squares solution, then run.
    let consistent: Vec<Vec<f64>> = windows
        .iter()
        .map(|(aw, _)| {
            (DMatrix::from_row_slice(m, n, aw) * &ls)
                .as_slice()
                .to_vec()
        })
        .collect();
    let mut buf = vec![0.0; buffer_len(EstimatorKind::TagK, n, m)];
    let mut est = McuEstimator::build(EstimatorKind::TagK, n, m, &mut buf).unwrap();
    for k in 0..600 {
        est.update(&windows[k % 3].0, &consistent[k % 3]).unwrap();
    }
    let err = est
        .estimate()
        .iter()
        .zip(ls.iter())
        .fold(0.0f64, |e, (x, y)| e.max((x - y).abs()));
    assert!(err < 1e-8, "max error {err:e}");
}

/// The kinds the microcontroller runs.
const MCU_KINDS: [EstimatorKind; 5] = [
    EstimatorKind::RlsLow,
    EstimatorKind::RlsHigh,
    EstimatorKind::KfLow,
    EstimatorKind::KfHigh,
    EstimatorKind::TagK,
];

#[test]
fn the_other_kaczmarz_variants_are_typed_errors() {
    for kind in [EstimatorKind::Grk, EstimatorKind::Tark, EstimatorKind::Rk] {
        let mut buf = vec![0.0f64; buffer_len(kind, 10, 4)];
        assert!(matches!(
            McuEstimator::build(kind, 10, 4, &mut buf).err(),
            Some(ConfigError::InvalidParameter { name: "kind", .. })
        ));
    }
}

#[test]
fn every_kind_builds_in_exactly_its_buffer_length() {
    for kind in MCU_KINDS {
        for n in TABLE_N {
            let len = buffer_len(kind, n, TABLE_M);
            let mut buf = vec![0.0f32; len];
            let est = McuEstimator::build(kind, n, TABLE_M, &mut buf).unwrap();
            assert_eq!(est.name(), kind.name());
            assert_eq!((est.dim(), est.capacity()), (n, TABLE_M));
            assert!(est.estimate().iter().all(|v| *v == 0.0));
            drop(est);
            let mut short = vec![0.0f64; len - 1];
            assert_eq!(
                McuEstimator::build(kind, n, TABLE_M, &mut short).err(),
                Some(ConfigError::BufferTooSmall {
                    needed: len,
                    found: len - 1
                })
            );
            let bytes = state_bytes::<f64>(kind, n, TABLE_M);
            assert!(
                bytes >= len * 8 && bytes < len * 8 + 1024,
                "{kind:?} {n}: {bytes}"
            );
        }
    }
}

#[test]
fn every_estimator_fits_a_teensy_at_n_120() {
    // 512 KB of tightly coupled RAM, with room for the window (m n + m values).
    let window = (120 * 30 + 30) * 8;
    for kind in MCU_KINDS {
        assert!(
            state_bytes::<f64>(kind, 120, 30) + window < 512 * 1024,
            "{kind:?}"
        );
    }
}
