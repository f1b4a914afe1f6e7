//! JSON round trips of the plain data types (feature `serde`).
#![cfg(feature = "serde")]

use tagk_dynamics::{InertialParams, QuadrotorModel, SafetyGate, UrdfOptions, Wrench};

#[test]
fn json_round_trips() {
    let q = QuadrotorModel::crazyflie_2_1();
    let back: QuadrotorModel = serde_json::from_str(&serde_json::to_string(&q).unwrap()).unwrap();
    assert_eq!(back, q);
    let g = SafetyGate::crazyflie();
    let back: SafetyGate = serde_json::from_str(&serde_json::to_string(&g).unwrap()).unwrap();
    assert_eq!(back, g);
    let t = InertialParams::from_array([1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0, 10.0]);
    let json = serde_json::to_string(&t).unwrap();
    assert_eq!(json, "[1.0,2.0,3.0,4.0,5.0,6.0,7.0,8.0,9.0,10.0]");
    assert_eq!(serde_json::from_str::<InertialParams>(&json).unwrap(), t);
    let w = Wrench::from_array([1.0, -2.0, 3.0, 0.1, 0.2, -0.3]);
    assert_eq!(
        serde_json::from_str::<Wrench>(&serde_json::to_string(&w).unwrap()).unwrap(),
        w
    );
    let o = UrdfOptions {
        locked_joints: vec!["a".into()],
    };
    assert_eq!(
        serde_json::from_str::<UrdfOptions>(&serde_json::to_string(&o).unwrap()).unwrap(),
        o
    );
}
