use nalgebra::Vector3;
use std::hint::black_box;
use tagk_control::*;
use tagk_dynamics::QuadrotorModel;

#[test]
fn cpu() {
    let model = QuadrotorModel::crazyflie_2_1();
    let w = LqrWeights::crazyflie();
    let payload = model
        .params
        .with_point_mass(0.5 * 0.035, Vector3::new(0.3 * 0.046, 0.0, 0.0));
    let op = hover_trim(&model, &payload, Vector3::zeros(), 0.0).unwrap();
    let d = discretize(&linearize(&model, &payload, &op).unwrap(), DEFAULT_DT).unwrap();
    let opts = DareOptions::default();
    let which = std::env::var("WHICH").unwrap();
    let n: usize = 5000;
    let opn = hover_trim(&model, &model.params, Vector3::zeros(), 0.0).unwrap();
    let dn = discretize(&linearize(&model, &model.params, &opn).unwrap(), DEFAULT_DT).unwrap();
    let p0 = solve_dare_sda(&dn.a, &dn.b, &w.q, &w.r, &opts).unwrap().p;
    for _ in 0..n {
        match which.as_str() {
            "sda" => {
                black_box(solve_dare_sda(black_box(&d.a), &d.b, &w.q, &w.r, &opts).unwrap());
            }
            "warm" => {
                black_box(solve_dare(black_box(&d.a), &d.b, &w.q, &w.r, &p0, &opts).unwrap());
            }
            "none" => {}
            _ => panic!(),
        }
    }
}
