mod common;
use common::*;
use rand::RngExt;
use tagk_baselines::*;

fn skew(x: [f64; 3]) -> [[f64; 3]; 3] { [[0.0, -x[2], x[1]], [x[2], 0.0, -x[0]], [-x[1], x[0], 0.0]] }
fn mm(a: [[f64; 3]; 3], b: [[f64; 3]; 3]) -> [[f64; 3]; 3] { let mut c = [[0.0; 3]; 3]; for i in 0..3 { for j in 0..3 { for k in 0..3 { c[i][j] += a[i][k] * b[k][j]; } } } c }
fn lmat(w: [f64; 3]) -> [[f64; 6]; 3] { [[w[0], w[1], 0.0, w[2], 0.0, 0.0], [0.0, w[0], w[1], 0.0, w[2], 0.0], [0.0, 0.0, 0.0, w[0], w[1], w[2]]] }
fn regressor(a: [f64; 3], w: [f64; 3], dw: [f64; 3]) -> Vec<f64> {
    let mut y = vec![0.0; 60];
    let sdw = skew(dw); let sw = skew(w); let sw2 = mm(sw, sw); let sa = skew(a);
    let ldw = lmat(dw); let lw = lmat(w);
    for r in 0..3 {
        y[r * 10] = a[r];
        for c in 0..3 { y[r * 10 + 1 + c] = sdw[r][c] + sw2[r][c]; }
        for c in 0..3 { y[(3 + r) * 10 + 1 + c] = -sa[r][c]; }
        for c in 0..6 { let mut v = ldw[r][c]; for k in 0..3 { v += sw[r][k] * lw[k][c]; } y[(3 + r) * 10 + 4 + c] = v; }
    }
    y
}

#[test]
fn quadrotor_like() {
    let theta = [0.035, 0.0, 0.0, 0.0, 1.66e-5, 0.83e-6, 1.66e-5, 0.72e-6, 1.8e-6, 2.93e-5];
    let mut g = rng(5);
    let mut ests: Vec<Box<dyn OnlineEstimator>> = vec![
        Box::new(Rls::rls_low(10, 30).unwrap()), Box::new(Rls::rls_high(10, 30).unwrap()),
        Box::new(KalmanFilter::kf_low(10, 30).unwrap()), Box::new(KalmanFilter::kf_high(10, 30).unwrap()),
        Box::new(KalmanFilter::new(10, 30, KalmanConfig::LOW.with_backend(Backend::Loops)).unwrap()),
    ];
    let mut fails = vec![0; ests.len()];
    let mut t = 0.0f64;
    for _k in 0..50 {
        let mut a = vec![];
        let mut b = vec![];
        for _f in 0..5 {
            t += 0.02;
            let acc = [0.3 * (t * 1.3).sin() + g.random_range(-0.01..0.01), 0.3 * (t * 0.7).cos(), 9.81 + 0.2 * (t * 2.1).sin()];
            let w = [0.5 * (t * 0.9).sin(), 0.4 * (t * 1.1).cos(), 0.3 * (t * 0.5).sin()];
            let dw = [0.45 * (t * 0.9).cos(), -0.44 * (t * 1.1).sin(), 0.15 * (t * 0.5).cos()];
            let y = regressor(acc, w, dw);
            for row in y.chunks(10) {
                b.push(row.iter().zip(&theta).map(|(x, t)| x * t).sum::<f64>());
                a.extend_from_slice(row);
            }
        }
        for (i, e) in ests.iter_mut().enumerate() {
            if let Err(err) = e.update(&a, &b) { fails[i] += 1; if fails[i] < 3 { eprintln!("{} {err}", e.name()); } }
        }
    }
    for e in &ests { eprintln!("{} err {:e}", e.name(), e.estimate().iter().zip(&theta).map(|(a, b)| (a - b) * (a - b)).sum::<f64>().sqrt()); }
    eprintln!("fails {fails:?}");
}
