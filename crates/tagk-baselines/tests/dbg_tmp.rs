use faer::linalg::matmul::triangular::{self as tri, BlockStructure};
use faer::prelude::{Reborrow, ReborrowMut};
use faer::{Accum, MatMut, MatRef, Par};
use std::time::Instant;

fn med(mut f: impl FnMut()) -> f64 {
    let mut v = vec![];
    for _ in 0..300 {
        let t = Instant::now();
        for _ in 0..10 { f(); }
        v.push(t.elapsed().as_secs_f64() * 1e5);
    }
    v.sort_by(|a, b| a.partial_cmp(b).unwrap());
    v[v.len() / 2]
}

#[test]
#[ignore]
fn steps() {
    for n in [10usize, 40, 120] {
        let m = 30;
        let n1 = n + 1;
        let a: Vec<f64> = (0..m * n).map(|i| (i as f64 * 0.37).sin()).collect();
        let mut p: Vec<f64> = vec![0.0; n * n];
        for k in 0..n { p[k * n + k] = 1.0; }
        let mut ur = vec![0.0; m * n1];
        let mut s = vec![0.0; m * m];
        let mut pc = vec![0.0; n * n];
        let t1 = med(|| {
            let av = MatRef::from_row_major_slice(&a, m, n);
            let pv = MatRef::from_row_major_slice(&p, n, n);
            let mut urv = MatMut::from_column_major_slice_with_stride_mut(&mut ur, n1, m, n1).transpose_mut();
            faer::linalg::matmul::matmul(urv.rb_mut().subcols_mut(0, n), Accum::Replace, av, pv, 1.0, Par::Seq);
        });
        let t1b = med(|| {
            let av = MatRef::from_row_major_slice(&a, m, n);
            let pv = MatRef::from_row_major_slice(&p, n, n);
            // U^T = P A^T  column-major target = row-major U
            let mut urv = MatMut::from_column_major_slice_with_stride_mut(&mut ur, n, m, n1);
            faer::linalg::matmul::matmul(urv.rb_mut(), Accum::Replace, pv, av.transpose(), 1.0, Par::Seq);
        });
        let t2 = med(|| {
            let av = MatRef::from_row_major_slice(&a, m, n);
            let urv = MatRef::from_column_major_slice_with_stride(&ur, n1, m, n1).transpose();
            let sv = MatMut::from_row_major_slice_mut(&mut s, m, m);
            tri::matmul(sv, BlockStructure::TriangularLower, Accum::Replace, urv.subcols(0, n), BlockStructure::Rectangular, av.transpose(), BlockStructure::Rectangular, 1.0, Par::Seq);
        });
        let t6 = med(|| {
            let g = MatRef::from_column_major_slice_with_stride(&ur, n1, m, n1).transpose().subcols(0, n);
            let pv = MatMut::from_row_major_slice_mut(&mut pc, n, n);
            tri::matmul(pv, BlockStructure::TriangularUpper, Accum::Add, g.transpose(), BlockStructure::Rectangular, g, BlockStructure::Rectangular, -1.0, Par::Seq);
        });
        let t6b = med(|| {
            let g = MatRef::from_column_major_slice_with_stride(&ur, n1, m, n1).transpose().subcols(0, n);
            let pv = MatMut::from_row_major_slice_mut(&mut pc, n, n);
            faer::linalg::matmul::matmul(pv, Accum::Add, g.transpose(), g, -1.0, Par::Seq);
        });
        let tc = med(|| { pc.copy_from_slice(&p); });
        eprintln!("n={n}: U=AP {t1:.2}us (alt {t1b:.2}) S {t2:.2} P-tri {t6:.2} P-full {t6b:.2} copy {tc:.2}");
    }
}
