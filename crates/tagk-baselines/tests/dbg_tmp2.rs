use std::time::Instant;
use tagk_baselines::{Backend, KalmanConfig, KalmanFilter, OnlineEstimator, Rls, RlsConfig};
use rand::RngExt;
use rand_chacha::ChaCha8Rng;
use rand_chacha::rand_core::SeedableRng;

#[test]
#[ignore]
fn interleaved() {
    let sizes: Vec<usize> = std::env::var("SIZES").ok().map(|s| s.split(',').map(|v| v.parse().unwrap()).collect()).unwrap_or(vec![10, 20, 30, 40, 80, 120]);
    let m = 30;
    for n in sizes {
        let mut rng = ChaCha8Rng::seed_from_u64(2024 + n as u64);
        let theta: Vec<f64> = (0..n).map(|_| rng.random_range(-1.0..1.0)).collect();
        let stream: Vec<(Vec<f64>, Vec<f64>)> = (0..64).map(|_| {
            let a: Vec<f64> = (0..m * n).map(|_| rng.random_range(-1.0..1.0)).collect();
            let b = a.chunks(n).map(|r| r.iter().zip(&theta).map(|(x, t)| x * t).sum::<f64>() + 1e-3 * rng.random_range(-1.0..1.0)).collect();
            (a, b)
        }).collect();
        let mut ests: Vec<(String, Box<dyn OnlineEstimator>)> = vec![];
        let mut bs = vec![Backend::Loops, Backend::Faer];
        
        for b in bs {
            ests.push((format!("RLS/{b:?}"), Box::new(Rls::new(n, m, RlsConfig::LOW.with_backend(b)).unwrap())));
            ests.push((format!("KF/{b:?}"), Box::new(KalmanFilter::new(n, m, KalmanConfig::LOW.with_backend(b)).unwrap())));
        }
        let reps = (20000 / (n * n / 10 + 30)).max(20);
        let mut times = vec![vec![]; ests.len()];
        for round in 0..31 {
            for (e, (_, est)) in ests.iter_mut().enumerate() {
                let mut per = vec![];
                for chunk in 0..5 {
                    let t = Instant::now();
                    for k in 0..reps {
                        let (a, b) = &stream[(k + chunk + round) % 64];
                        std::hint::black_box(est.update(std::hint::black_box(a), std::hint::black_box(b)).unwrap());
                    }
                    per.push(t.elapsed().as_secs_f64() * 1e6 / reps as f64);
                }
                per.sort_by(|a, b| a.partial_cmp(b).unwrap());
                times[e].push(per[2]);
            }
        }
        for (e, (name, _)) in ests.iter().enumerate() {
            let mut t = times[e].clone();
            t.sort_by(|a, b| a.partial_cmp(b).unwrap());
            eprintln!("n={n:>3} {name:<20} median {:>8.2} us  min {:>8.2} us", t[t.len() / 2], t[0]);
        }
    }
}
