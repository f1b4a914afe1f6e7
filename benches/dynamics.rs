//! Regressor timings of `tagk-dynamics`: the 6×10 rigid-body regressor of the quadrotor
//! (target ≤ 50 ns), a 5-frame window, and the joint-torque regressor of each shipped arm
//! (7-DoF target ≤ 5 µs), plus RNEA for comparison. Inputs come from a fixed seed.

use std::hint::black_box;

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use rand::RngExt;
use rand_chacha::ChaCha8Rng;
use rand_chacha::rand_core::SeedableRng;
use tagk::dynamics::nalgebra::Vector3;
use tagk::dynamics::{
    KinematicTree, QuadrotorModel, UrdfOptions, WindowBuilder, newton_euler, rigid_body_regressor,
    write_rigid_body_regressor,
};

fn robot(name: &str, locked: &[&str]) -> KinematicTree {
    let path = format!("{}/tagk-dynamics/robots/{name}", env!("CARGO_MANIFEST_DIR"));
    let opts = UrdfOptions {
        locked_joints: locked.iter().map(|s| s.to_string()).collect(),
    };
    KinematicTree::from_urdf_file_with(path, &opts).expect("shipped URDF loads")
}

fn rigid_body(c: &mut Criterion) {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let mut v = || {
        Vector3::new(
            rng.random_range(-5.0..5.0),
            rng.random_range(-5.0..5.0),
            rng.random_range(-5.0..5.0),
        )
    };
    let (a, w, wd) = (v(), v(), v());
    let theta = QuadrotorModel::crazyflie_2_1().params;
    c.bench_function("rigid_body_regressor (6x10, quadrotor)", |b| {
        b.iter(|| rigid_body_regressor(black_box(&a), black_box(&w), black_box(&wd)))
    });
    let mut buf = [0.0; 60];
    c.bench_function("write_rigid_body_regressor (row-major 60)", |b| {
        b.iter(|| {
            write_rigid_body_regressor(
                black_box(&a),
                black_box(&w),
                black_box(&wd),
                black_box(&mut buf),
            )
        })
    });
    c.bench_function("newton_euler (quadrotor)", |b| {
        b.iter(|| {
            newton_euler(
                black_box(&theta),
                black_box(&a),
                black_box(&w),
                black_box(&wd),
            )
        })
    });
    let mut win = WindowBuilder::new(5).expect("k > 0");
    let wrench = newton_euler(&theta, &a, &w, &wd);
    c.bench_function("window push + stacked (k = 5, A 30x10)", |b| {
        b.iter(|| {
            win.push(
                black_box(&a),
                black_box(&w),
                black_box(&wd),
                black_box(&wrench),
            )
            .expect("finite");
            let (a_s, b_s) = win.stacked();
            black_box((a_s.len(), b_s.len()))
        })
    });
}

fn chains(c: &mut Criterion) {
    let robots = [
        ("planar_2link (2 dof)", robot("planar_2link.urdf", &[])),
        ("ur5 (6 dof)", robot("ur5.urdf", &[])),
        (
            "panda arm (7 dof)",
            robot(
                "panda.urdf",
                &["panda_finger_joint1", "panda_finger_joint2"],
            ),
        ),
        ("panda + fingers (9 dof)", robot("panda.urdf", &[])),
    ];
    let mut group = c.benchmark_group("joint_torque_regressor");
    for (name, chain) in &robots {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let n = chain.dof();
        let mut state = || {
            (0..n)
                .map(|_| rng.random_range(-2.0..2.0))
                .collect::<Vec<f64>>()
        };
        let (q, qd, qdd) = (state(), state(), state());
        let mut ws = chain.workspace();
        let mut out = vec![0.0; n * chain.n_params()];
        group.bench_with_input(BenchmarkId::from_parameter(name), &(), |b, _| {
            b.iter(|| {
                chain
                    .joint_torque_regressor_into(
                        black_box(&q),
                        black_box(&qd),
                        black_box(&qdd),
                        &mut ws,
                        &mut out,
                    )
                    .expect("valid state");
                black_box(out[0])
            })
        });
    }
    group.finish();
    let mut group = c.benchmark_group("rnea");
    for (name, chain) in &robots {
        let n = chain.dof();
        let q = vec![0.3; n];
        let params = chain.params();
        let mut ws = chain.workspace();
        let mut tau = vec![0.0; n];
        group.bench_with_input(BenchmarkId::from_parameter(name), &(), |b, _| {
            b.iter(|| {
                chain
                    .rnea_into(
                        black_box(&q),
                        black_box(&q),
                        black_box(&q),
                        &params,
                        &mut ws,
                        &mut tau,
                    )
                    .expect("valid state");
                black_box(tau[0])
            })
        });
    }
    group.finish();
}

criterion_group!(benches, rigid_body, chains);
criterion_main!(benches);
