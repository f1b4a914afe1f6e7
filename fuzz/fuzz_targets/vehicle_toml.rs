//! The vehicle description (TOML, docs/VEHICLE.md) on arbitrary input. Every outcome must be a
//! typed vehicle error or a valid vehicle; a valid vehicle must survive its own checks, write
//! itself back as TOML that reads back to the same vehicle, and map any finite rotor speeds
//! within its range to a finite wrench: never a panic.
#![no_main]

use libfuzzer_sys::fuzz_target;
use tagk_dynamics::vehicle::Vehicle;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let Ok(vehicle) = Vehicle::from_toml_str(text) else {
        return;
    };
    vehicle.validate().expect("a vehicle read is valid");
    let back = Vehicle::from_toml_str(&vehicle.to_toml_string()).expect("its TOML reads back");
    assert_eq!(back, vehicle, "the TOML round trip keeps every value");
    // Rotor speeds from 0 to the vehicle's largest, in four steps.
    let top = vehicle.max_rotor_speed;
    for k in 0..=4 {
        let w = top * f64::from(k) / 4.0;
        let wrench = vehicle.wrench_from_rotor_speeds(&[w, 0.5 * w, w, 0.25 * w]);
        assert!(
            wrench.to_array().iter().all(|x| x.is_finite()),
            "a finite wrench at rotor speeds up to {top} rad/s"
        );
    }
});
