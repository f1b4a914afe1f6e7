use nalgebra::Vector3;
use tagk_control::*;
use tagk_dynamics::{InertialParams, QuadrotorModel};

fn scaled(p: &InertialParams, s: f64) -> InertialParams {
    let mut t = p.to_array();
    for v in t.iter_mut() {
        *v *= s;
    }
    InertialParams::from_array(t)
}

#[test]
fn explore() {
    let model = QuadrotorModel::crazyflie_2_1();
    let nominal = model.params;
    let w = LqrWeights::crazyflie();
    for tol in [1e-6, 1e-9, 1e-11] {
        let opts = DareOptions {
            tolerance: tol,
            max_iterations: 100000,
        };
        for s in [1.01, 1.05, 1.4] {
            let mut l = Lqr::with_solver(
                &model,
                &nominal,
                w,
                DEFAULT_DT,
                RiccatiSolver::Iteration,
                opts,
            )
            .unwrap();
            let p_prev = *l.riccati_solution();
            let cold_new = Lqr::with_solver(
                &model,
                &scaled(&nominal, s),
                w,
                DEFAULT_DT,
                RiccatiSolver::Iteration,
                opts,
            )
            .unwrap();
            let warm = l.redesign(&scaled(&nominal, s)).unwrap();
            let x = l.riccati_solution();
            println!(
                "tol {tol:e} scale {s}: delta {:.3e}, cold {} warm {} (res {:.1e})",
                (p_prev - x).norm() / x.norm(),
                cold_new.last_solve().iterations,
                warm.iterations,
                warm.residual
            );
        }
    }
    let _ = Lqr::with_solver(
        &model,
        &nominal,
        w,
        DEFAULT_DT,
        RiccatiSolver::Doubling,
        DareOptions::default(),
    )
    .unwrap();
    // payload
    let payload = nominal.with_point_mass(0.5 * 0.035, Vector3::new(0.3 * 0.046, 0.0, 0.0));
    let mut l = Lqr::with_solver(
        &model,
        &nominal,
        w,
        DEFAULT_DT,
        RiccatiSolver::Iteration,
        DareOptions::default(),
    )
    .unwrap();
    println!("payload warm {:?}", l.redesign(&payload).unwrap());
}
