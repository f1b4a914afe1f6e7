//! LQR design costs for the 12-state Crazyflie model (tagk-control).
//!
//! - `dare/*`: Riccati solves of the 50 Hz hover model with a 50 % payload at 30 % of the arm
//!   (docs/CONVENTIONS.md §5 worst case): cold plain iteration (P₀ = Q), warm plain iteration
//!   (P₀ = the nominal vehicle's solution — what `Lqr::redesign` does after a payload
//!   event), the doubling algorithm (SDA), and the same solvers on `DMatrix` to compare the
//!   statically sized fast path with the general one.
//! - `linearize/*`: hover trim + analytic Jacobians; the zero-order hold as used (Taylor
//!   scaling-and-squaring on the 12×12 blocks) and, for comparison, nalgebra's Padé
//!   exponential of the 16×16 augmented matrix.
//! - `lqr/redesign`: the whole re-design the simulator runs after an accepted estimate.

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use tagk::control::nalgebra::{DMatrix, SMatrix, Vector3};
use tagk::control::{
    DEFAULT_DT, DareOptions, Lqr, LqrWeights, RiccatiSolver, discretize, hover_trim, linearize,
    solve_dare, solve_dare_cold, solve_dare_sda,
};
use tagk::dynamics::{InertialParams, QuadrotorModel};

fn payload_params(model: &QuadrotorModel) -> InertialParams {
    model.params.with_point_mass(
        0.5 * model.params.mass(),
        Vector3::new(0.3 * model.arm, 0.0, 0.0),
    )
}

fn bench_control(c: &mut Criterion) {
    let model = QuadrotorModel::crazyflie_2_1();
    let weights = LqrWeights::crazyflie();
    let opts = DareOptions::default();
    let nominal = model.params;
    let payload = payload_params(&model);

    let design = |p: &InertialParams| {
        let op = hover_trim(&model, p, Vector3::zeros(), 0.0).unwrap();
        discretize(&linearize(&model, p, &op).unwrap(), DEFAULT_DT).unwrap()
    };
    let d_nom = design(&nominal);
    let d_pay = design(&payload);
    let (q, r) = (weights.q, weights.r);
    let p_nom = solve_dare_sda(&d_nom.a, &d_nom.b, &q, &r, &opts).unwrap().p;

    // Iteration counts, printed once so the medians can be read per iteration.
    let cold = solve_dare_cold(&d_pay.a, &d_pay.b, &q, &r, &opts).unwrap();
    let warm = solve_dare(&d_pay.a, &d_pay.b, &q, &r, &p_nom, &opts).unwrap();
    let sda = solve_dare_sda(&d_pay.a, &d_pay.b, &q, &r, &opts).unwrap();
    eprintln!(
        "iterations: cold {} (residual {:.1e}), warm {} ({:.1e}), sda {} doublings ({:.1e})",
        cold.iterations,
        cold.residual,
        warm.iterations,
        warm.residual,
        sda.iterations,
        sda.residual
    );

    let mut g = c.benchmark_group("dare");
    g.bench_function("iteration_cold_static", |b| {
        b.iter(|| solve_dare_cold(black_box(&d_pay.a), &d_pay.b, &q, &r, &opts).unwrap())
    });
    g.bench_function("iteration_warm_static", |b| {
        b.iter(|| solve_dare(black_box(&d_pay.a), &d_pay.b, &q, &r, &p_nom, &opts).unwrap())
    });
    g.bench_function("sda_static", |b| {
        b.iter(|| solve_dare_sda(black_box(&d_pay.a), &d_pay.b, &q, &r, &opts).unwrap())
    });
    let to_d = |m: &[f64], rows: usize, cols: usize| DMatrix::from_column_slice(rows, cols, m);
    let (ad, bd) = (
        to_d(d_pay.a.as_slice(), 12, 12),
        to_d(d_pay.b.as_slice(), 12, 4),
    );
    let (qd, rd, pd) = (
        to_d(q.as_slice(), 12, 12),
        to_d(r.as_slice(), 4, 4),
        to_d(p_nom.as_slice(), 12, 12),
    );
    g.bench_function("iteration_warm_dynamic", |b| {
        b.iter(|| solve_dare(black_box(&ad), &bd, &qd, &rd, &pd, &opts).unwrap())
    });
    g.bench_function("sda_dynamic", |b| {
        b.iter(|| solve_dare_sda(black_box(&ad), &bd, &qd, &rd, &opts).unwrap())
    });
    g.finish();

    let mut g = c.benchmark_group("linearize");
    let op = hover_trim(&model, &payload, Vector3::zeros(), 0.0).unwrap();
    let cont = linearize(&model, &payload, &op).unwrap();
    g.bench_function("trim_and_jacobians", |b| {
        b.iter(|| {
            let op = hover_trim(&model, black_box(&payload), Vector3::zeros(), 0.0).unwrap();
            linearize(&model, &payload, &op).unwrap()
        })
    });
    g.bench_function("zoh_taylor_12x12", |b| {
        b.iter(|| discretize(black_box(&cont), DEFAULT_DT).unwrap())
    });
    let mut aug = SMatrix::<f64, 16, 16>::zeros();
    aug.fixed_view_mut::<12, 12>(0, 0)
        .copy_from(&(cont.a * DEFAULT_DT));
    aug.fixed_view_mut::<12, 4>(0, 12)
        .copy_from(&(cont.b * DEFAULT_DT));
    g.bench_function("zoh_pade_augmented_16x16", |b| {
        b.iter(|| black_box(&aug).exp())
    });
    g.finish();

    let mut g = c.benchmark_group("lqr");
    for (name, solver) in [
        ("redesign_sda", RiccatiSolver::Doubling),
        ("redesign_warm_iteration", RiccatiSolver::Iteration),
    ] {
        let base = Lqr::with_solver(&model, &nominal, weights, DEFAULT_DT, solver, opts).unwrap();
        g.bench_function(name, |b| {
            b.iter_batched_ref(
                || base.clone(),
                |lqr| lqr.redesign(black_box(&payload)).unwrap(),
                criterion::BatchSize::SmallInput,
            )
        });
    }
    g.finish();
}

criterion_group!(benches, bench_control);
criterion_main!(benches);
