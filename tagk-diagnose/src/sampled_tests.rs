//! The scans' sampled columns ([`Effect::sampled_columns`], [`sampled_effect_design`],
//! [`GramEngine::evaluate_sampled`]) against the full columns subsampled. Their window columns
//! ([`Effect::window_columns`], [`window_effect_design`], [`GramEngine::evaluate_window`])
//! against the full columns cut. Both give the same bits for every built-in effect. The logs
//! have rotor speeds or not, smoothed channels or not, and some are joined. A user effect
//! with malformed sampled columns falls back to the full ones.

use nalgebra::{Matrix4, Vector4};

use crate::effects::{
    Effect, EffectColumn, Plausibility, builtin_effects, cut_to_window, subsample,
};
use crate::fit::{
    ColData, Column, GramEngine, effect_design, sampled_effect_design, window_effect_design,
};
use crate::log::FlightLog;
use crate::signals::{Channel, Signals};
use crate::testdata::{crazyflie, synthetic_log};

fn bits(v: &[f64]) -> Vec<u64> {
    v.iter().map(|x| x.to_bits()).collect()
}

/// A synthetic log whose wrench comes from four rotors: the rotor speeds that produce its
/// `[fz, tx, ty, tz]` through a Crazyflie-like mixer (the mixer the signals identify).
fn log_with_rotors(n: usize, seed: u64) -> FlightLog {
    let mut log = synthetic_log(&crazyflie(), n, 5e-3, seed, &|_, vb| {
        [-0.02 * vb.x, -0.01 * vb.y, -0.03 * vb.z, 0.0, 0.0, 0.0]
    });
    let (kf, km, l) = (2.88e-8, 7.24e-10, 0.0325 / std::f64::consts::SQRT_2);
    let mixer = Matrix4::new(
        kf,
        kf,
        kf,
        kf,
        -kf * l,
        -kf * l,
        kf * l,
        kf * l,
        -kf * l,
        kf * l,
        kf * l,
        -kf * l,
        -km,
        km,
        -km,
        km,
    );
    let inverse = mixer.try_inverse().unwrap();
    let speeds = log
        .wrench
        .iter()
        .map(|b| {
            let sq = inverse * Vector4::new(b[2], b[3], b[4], b[5]);
            std::array::from_fn(|r| sq[r].max(0.0).sqrt())
        })
        .collect();
    log.rotor_speeds = Some(speeds);
    log
}

/// Every column of `a` equals the same column of `b`: names, units, fixed values, bits.
fn assert_same_columns(a: &[EffectColumn], b: &[EffectColumn], what: &str) {
    assert_eq!(a.len(), b.len(), "{what}: column count");
    for (x, y) in a.iter().zip(b) {
        assert_eq!(
            (&x.name, &x.unit, x.fixed),
            (&y.name, &y.unit, y.fixed),
            "{what}"
        );
        for c in 0..6 {
            assert_eq!(
                x.data[c].as_deref().map(bits),
                y.data[c].as_deref().map(bits),
                "{what}: column {} channel {c}",
                x.name
            );
        }
    }
}

/// Each built-in effect's sampled columns are its full columns at the sampled samples, bit
/// for bit. The strides divide the log's length or not. A scanned parameter takes several
/// values. The lag runs on each rotor (with the rotor mixer) or on the wrench.
#[test]
fn sampled_columns_are_the_full_columns_subsampled() {
    let with_rotors = Signals::from_log(&log_with_rotors(1_003, 3)).unwrap();
    assert!(with_rotors.rotor_mixer().is_some());
    let without = Signals::from_log(&synthetic_log(&crazyflie(), 1_003, 5e-3, 4, &|_, _| {
        [0.0; 6]
    }))
    .unwrap();
    for s in [&with_rotors, &without] {
        for e in builtin_effects() {
            if e.check(s).is_err() {
                continue;
            }
            let params: Vec<Option<f64>> = match e.scan() {
                None => vec![None],
                Some(spec) => spec
                    .grid
                    .iter()
                    .step_by(5)
                    .map(|g| Some(*g))
                    .chain([None])
                    .collect(),
            };
            for p in params {
                let full = e.columns(s, p);
                for stride in [1, 2, 7, 100, 1_003, 5_000] {
                    assert_same_columns(
                        &e.sampled_columns(s, p, stride),
                        &subsample(full.clone(), stride),
                        &format!("{} at {p:?}, stride {stride}", e.name()),
                    );
                }
            }
        }
    }
}

/// Each built-in effect's window columns are its full columns in the window, bit for bit.
/// The windows lie at the log's start (where a lag's start transient lives), in its middle,
/// at its end and past it; one is empty. The log has the rotor mixer or not.
#[test]
fn window_columns_are_the_full_columns_cut() {
    let with_rotors = Signals::from_log(&log_with_rotors(1_003, 3)).unwrap();
    let without = Signals::from_log(&synthetic_log(&crazyflie(), 1_003, 5e-3, 4, &|_, _| {
        [0.0; 6]
    }))
    .unwrap();
    for s in [&with_rotors, &without] {
        for e in builtin_effects() {
            if e.check(s).is_err() {
                continue;
            }
            let params: Vec<Option<f64>> = match e.scan() {
                None => vec![None],
                Some(spec) => spec.grid.iter().step_by(5).map(|g| Some(*g)).collect(),
            };
            for p in params {
                let full = e.columns(s, p);
                for window in [
                    0..1_003,
                    0..17,
                    1..40,
                    500..700,
                    990..1_003,
                    990..2_000,
                    5..5,
                ] {
                    assert_same_columns(
                        &e.window_columns(s, p, window.clone()),
                        &cut_to_window(full.clone(), window.clone()),
                        &format!("{} at {p:?}, window {window:?}", e.name()),
                    );
                }
            }
        }
    }
}

/// A window engine's evaluation and residual of the window design equal those of the full
/// design, bit for bit, for the scanned built-ins. The logs: a plain one, one without rotor
/// speeds, a smoothed one (the full design, cut). One window starts at the log's start.
#[test]
fn window_engines_on_window_designs_equal_them_on_full_designs() {
    let plain = Signals::from_log(&log_with_rotors(6_011, 5)).unwrap();
    let mut no_rotors = log_with_rotors(6_011, 6);
    no_rotors.rotor_speeds = None;
    let no_rotors = Signals::from_log(&no_rotors).unwrap();
    let mut derived = log_with_rotors(6_011, 7);
    derived.accel = None;
    derived.omega_dot = None;
    let derived = Signals::from_log(&derived).unwrap();
    let rigid: Vec<Column<'_>> = (0..10).map(Column::Rigid).collect();
    let w = [100.0, 100.0, 50.0, 1e5, 1e5, 1e5];
    for s in [&plain, &no_rotors, &derived] {
        for range in [2_000..4_500, 0..3_000] {
            let engine = GramEngine::new_window(s, &w, &rigid, None, range.clone());
            for e in builtin_effects().iter().filter(|e| e.scan().is_some()) {
                let grid = e.scan().unwrap().grid;
                for g in [grid[0], grid[grid.len() / 2], grid[grid.len() - 1]] {
                    let what = format!("{} at {g}, window {range:?}", e.name());
                    let full = effect_design(e.as_ref(), s, Some(g));
                    let window = window_effect_design(e.as_ref(), s, Some(g), range.clone())
                        .expect("a built-in's window design");
                    let a = engine.evaluate_with(&full.cols, full.offset.as_ref());
                    let b = engine.evaluate_window(&window.cols, window.offset.as_ref());
                    assert_eq!(a.sse_full.to_bits(), b.sse_full.to_bits(), "{what}");
                    assert_eq!(bits(&a.beta), bits(&b.beta), "{what}");
                    let ra = engine.residual_unweighted(&full.cols, full.offset.as_ref(), &a.beta);
                    let rb = engine.residual_window_unweighted(
                        &window.cols,
                        window.offset.as_ref(),
                        &b.beta,
                    );
                    assert_eq!(ra.len(), range.len(), "{what}");
                    let flat = |r: &[[f64; 6]]| bits(&r.concat());
                    assert_eq!(flat(&ra), flat(&rb), "{what}");
                    assert_eq!(full.names, window.names);
                }
            }
        }
    }
}

/// A scan engine's evaluation of the sampled design equals its evaluation of the full design
/// (which reads the same samples), bit for bit. The two scanned built-ins take several
/// values. The logs: a plain one, one with rotor speeds, one whose accelerations are derived
/// (smoothed channels: the full design, subsampled), and two joined logs (per-log columns:
/// likewise).
#[test]
fn scans_on_sampled_designs_equal_scans_on_full_designs() {
    let plain = Signals::from_log(&log_with_rotors(20_011, 5)).unwrap();
    let mut no_rotors = log_with_rotors(20_011, 6);
    no_rotors.rotor_speeds = None;
    let no_rotors = Signals::from_log(&no_rotors).unwrap();
    let mut derived = log_with_rotors(20_011, 7);
    derived.accel = None;
    derived.omega_dot = None;
    let derived = Signals::from_log(&derived).unwrap();
    assert!(derived.smoothed.iter().any(|x| *x));
    let joined = Signals::concat(vec![
        Signals::from_log(&log_with_rotors(10_007, 8)).unwrap(),
        Signals::from_log(&log_with_rotors(10_009, 9)).unwrap(),
    ])
    .unwrap();
    let rigid: Vec<Column<'_>> = (0..10).map(Column::Rigid).collect();
    let w = [100.0, 100.0, 50.0, 1e5, 1e5, 1e5];
    for s in [&plain, &no_rotors, &derived, &joined] {
        let engine = GramEngine::new(s, &w, &rigid, None, 5);
        let scan = engine.for_scan();
        assert_eq!(scan.stride(), 2);
        for e in builtin_effects().iter().filter(|e| e.scan().is_some()) {
            let grid = e.scan().unwrap().grid;
            for g in [grid[0], grid[grid.len() / 2], grid[grid.len() - 1]] {
                let full = effect_design(e.as_ref(), s, Some(g));
                let sampled = sampled_effect_design(e.as_ref(), s, Some(g), scan.stride()).unwrap();
                let a = scan.evaluate_with(&full.cols, full.offset.as_ref());
                let b = scan.evaluate_sampled(&sampled.cols, sampled.offset.as_ref());
                assert_eq!(
                    a.sse_full.to_bits(),
                    b.sse_full.to_bits(),
                    "{} at {g}",
                    e.name()
                );
                assert_eq!(bits(&a.beta), bits(&b.beta), "{} at {g}", e.name());
                assert_eq!(full.names, sampled.names);
            }
        }
    }
}

/// A user effect whose sampled columns have the wrong length: the scan falls back to its full
/// columns, subsampled.
#[derive(Debug)]
struct WrongSampledLength;

impl Effect for WrongSampledLength {
    fn name(&self) -> &str {
        "wrong-sampled-length"
    }
    fn description(&self) -> &str {
        "a force along x proportional to the thrust, with sampled columns of the full length"
    }
    fn channels(&self) -> Vec<Channel> {
        vec![0]
    }
    fn columns(&self, s: &Signals, _param: Option<f64>) -> Vec<EffectColumn> {
        vec![EffectColumn::on("k", "1", 0, s.channel(2))]
    }
    fn sampled_columns(&self, s: &Signals, p: Option<f64>, _stride: usize) -> Vec<EffectColumn> {
        self.columns(s, p)
    }
    fn plausibility(&self, _coef: &[f64], _se: &[f64], _p: Option<f64>) -> Plausibility {
        Plausibility::ok()
    }
    fn driver(&self, s: &Signals) -> (String, Vec<f64>) {
        ("thrust fz [N]".into(), s.channel(2))
    }
}

#[test]
fn malformed_sampled_columns_fall_back_to_the_full_columns() {
    let s = Signals::from_log(&log_with_rotors(1_000, 10)).unwrap();
    let full = effect_design(&WrongSampledLength, &s, None);
    let sampled = sampled_effect_design(&WrongSampledLength, &s, None, 9).unwrap();
    let want: Vec<ColData> = full
        .cols
        .iter()
        .map(|col| {
            col.clone()
                .map(|d| d.map(|v| v.into_iter().step_by(9).collect()))
        })
        .collect();
    assert_eq!(sampled.cols.len(), want.len());
    for (a, b) in sampled.cols.iter().zip(&want) {
        for c in 0..6 {
            assert_eq!(a[c].as_deref().map(bits), b[c].as_deref().map(bits));
        }
    }
}

/// A scanned user effect, a lateral drag `sign(v) |v|^p` along body x. At `p = 1` (the drag
/// hidden in the test log) its column is not finite at sample 1, which a scan of a long log
/// does not read. At `p = 3` its columns are one value short.
#[derive(Debug)]
struct FaultyScanned;

impl Effect for FaultyScanned {
    fn name(&self) -> &str {
        "faulty-scanned"
    }
    fn description(&self) -> &str {
        "a drag sign(v)|v|^p along body x, with faults at p = 1 and p = 3"
    }
    fn channels(&self) -> Vec<Channel> {
        vec![0]
    }
    fn scan(&self) -> Option<crate::ScanSpec> {
        Some(crate::ScanSpec {
            name: "p".into(),
            unit: "1".into(),
            grid: vec![1.0, 2.0, 3.0],
            start: None,
        })
    }
    fn columns(&self, s: &Signals, p: Option<f64>) -> Vec<EffectColumn> {
        let p = p.unwrap_or(2.0);
        let mut v: Vec<f64> = s
            .velocity_body
            .iter()
            .map(|v| v.x.signum() * v.x.abs().powf(p))
            .collect();
        if p == 1.0 {
            v[1] = f64::NAN;
        }
        if p == 3.0 {
            v.pop();
        }
        vec![EffectColumn::on("k", "N s^p/m^p", 0, v)]
    }
    fn plausibility(&self, _coef: &[f64], _se: &[f64], _p: Option<f64>) -> Plausibility {
        Plausibility::ok()
    }
    fn driver(&self, s: &Signals) -> (String, Vec<f64>) {
        (
            "speed [m/s]".into(),
            s.velocity_body.iter().map(|v| v.x).collect(),
        )
    }
}

/// The scan of a faulty user effect neither panics on the value whose columns are short nor
/// lets a non-finite value it did not read into the ranking: the candidate is listed as
/// unavailable, naming the sample.
#[test]
fn a_faulty_scanned_effect_is_unavailable_not_a_panic() {
    let s = Signals::from_log(&synthetic_log(&crazyflie(), 20_011, 5e-3, 12, &|_, vb| {
        [-0.02 * vb.x, 0.0, 0.0, 0.0, 0.0, 0.0]
    }))
    .unwrap();
    assert!(crate::effects::usable(&FaultyScanned, &s).is_ok());
    let opts = crate::DiagnoseOptions {
        candidates: vec![std::sync::Arc::new(FaultyScanned) as crate::EffectRef],
        ..Default::default()
    };
    let d = crate::diagnose(&crate::Model::rigid_body(), &s, &opts).unwrap();
    assert!(d.ranking.is_empty(), "{:?}", d.ranking);
    assert_eq!(d.unavailable.len(), 1);
    assert!(
        d.unavailable[0].reason.contains("not finite at sample 1 "),
        "{}",
        d.unavailable[0].reason
    );
}
