//! Helpers shared by the integration tests: seeded windows and independent reference
//! computations written with nalgebra (explicit factorisations, no code from this crate).
#![allow(dead_code)]

use nalgebra::{DMatrix, DVector};
use rand::RngExt;
use rand_chacha::ChaCha8Rng;
use rand_chacha::rand_core::SeedableRng;
use tagk_baselines::Backend;

pub mod filters;

/// One window: `a` (`m × n`, row-major) and `b` (`m`).
#[derive(Clone, Debug)]
pub struct Window {
    pub a: Vec<f64>,
    pub b: Vec<f64>,
}

impl Window {
    pub fn rows(&self) -> usize {
        self.b.len()
    }
}

pub fn rng(seed: u64) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(seed)
}

/// A random vector with entries in `[-scale, scale)`.
pub fn random_vec(rng: &mut ChaCha8Rng, len: usize, scale: f64) -> Vec<f64> {
    (0..len).map(|_| rng.random_range(-scale..scale)).collect()
}

/// `count` windows of `n` columns with a random number of rows in `1..=m_max` (or exactly
/// `m_max` when `fixed_rows`), `b = A θ + noise`.
pub fn windows(
    rng: &mut ChaCha8Rng,
    n: usize,
    m_max: usize,
    count: usize,
    theta: &[f64],
    noise: f64,
    fixed_rows: bool,
) -> Vec<Window> {
    (0..count)
        .map(|_| {
            let m = if fixed_rows {
                m_max
            } else {
                rng.random_range(1..=m_max)
            };
            let a = random_vec(rng, m * n, 1.0);
            let b = a
                .chunks(n)
                .map(|row| {
                    row.iter().zip(theta).map(|(x, t)| x * t).sum::<f64>()
                        + noise * rng.random_range(-1.0..1.0)
                })
                .collect();
            Window { a, b }
        })
        .collect()
}

/// The exponentially weighted, regularised least-squares problem RLS solves, assembled and
/// solved from scratch: `H θ = g` with
/// `H = λ^N P₀⁻¹ + Σ_k λ^(N−k) A_kᵀ A_k`, `g = λ^N P₀⁻¹ θ₀ + Σ_k λ^(N−k) A_kᵀ b_k`.
/// Returns `(θ, H⁻¹)`; `H⁻¹` is the covariance RLS should hold.
pub fn weighted_batch_ls(
    n: usize,
    windows: &[Window],
    lambda: f64,
    p0: f64,
    theta0: &[f64],
) -> (Vec<f64>, DMatrix<f64>) {
    let big_n = windows.len() as i32;
    let prior_w = lambda.powi(big_n) / p0;
    let mut h = DMatrix::<f64>::identity(n, n) * prior_w;
    let mut g = DVector::from_column_slice(theta0) * prior_w;
    for (k, w) in windows.iter().enumerate() {
        let weight = lambda.powi(big_n - (k as i32 + 1));
        let a = DMatrix::from_row_slice(w.rows(), n, &w.a);
        let b = DVector::from_column_slice(&w.b);
        h += a.transpose() * &a * weight;
        g += a.transpose() * b * weight;
    }
    let chol = h
        .clone()
        .cholesky()
        .expect("the normal matrix is positive definite");
    let theta = chol.solve(&g);
    (theta.as_slice().to_vec(), chol.inverse())
}

/// A textbook random-walk Kalman filter with explicit inverses and the Joseph-form
/// covariance update, written independently of the crate.
pub struct TextbookKf {
    pub theta: DVector<f64>,
    pub p: DMatrix<f64>,
    q: f64,
    r: f64,
}

impl TextbookKf {
    pub fn new(n: usize, sigma_q: f64, sigma_r: f64, p0: f64) -> Self {
        Self {
            theta: DVector::zeros(n),
            p: DMatrix::identity(n, n) * p0,
            q: sigma_q * sigma_q,
            r: sigma_r * sigma_r,
        }
    }

    pub fn step(&mut self, w: &Window) {
        let n = self.theta.len();
        let m = w.rows();
        let h = DMatrix::from_row_slice(m, n, &w.a);
        let z = DVector::from_column_slice(&w.b);
        let p_pred = &self.p + DMatrix::identity(n, n) * self.q;
        let r = DMatrix::identity(m, m) * self.r;
        let s = &h * &p_pred * h.transpose() + &r;
        let s_inv = s.try_inverse().expect("innovation covariance invertible");
        let k = &p_pred * h.transpose() * s_inv;
        self.theta = &self.theta + &k * (z - &h * &self.theta);
        let i_kh = DMatrix::identity(n, n) - &k * &h;
        self.p = &i_kh * p_pred * i_kh.transpose() + &k * r * k.transpose();
    }
}

/// One step of [`TextbookKf`] and of [`InformationKf`] from the state `(theta, p)`; returns
/// the result of the formulation whose system matrix (`S` or the information matrix) is
/// better conditioned, as `(θ, P)` with `P` row-major.
pub fn best_conditioned_step(
    theta: &[f64],
    p: &[f64],
    sigma_q: f64,
    sigma_r: f64,
    w: &Window,
) -> (Vec<f64>, Vec<f64>) {
    let n = theta.len();
    let h = DMatrix::from_row_slice(w.rows(), n, &w.a);
    let p_pred = DMatrix::from_row_slice(n, n, p) + DMatrix::identity(n, n) * sigma_q * sigma_q;
    let r = sigma_r * sigma_r;
    let s = &h * &p_pred * h.transpose() + DMatrix::identity(w.rows(), w.rows()) * r;
    let info = p_pred.clone().cholesky().unwrap().inverse() + h.transpose() * &h / r;
    let cond = |m: DMatrix<f64>| {
        let ev = m.symmetric_eigen().eigenvalues;
        ev.max() / ev.min()
    };
    let (theta, p) = if cond(s) <= cond(info) {
        let mut kf = TextbookKf::new(n, sigma_q, sigma_r, 1.0);
        kf.theta = DVector::from_column_slice(theta);
        kf.p = DMatrix::from_row_slice(n, n, p);
        kf.step(w);
        (kf.theta, kf.p)
    } else {
        let mut kf = InformationKf::from_state(theta, p, sigma_q, sigma_r);
        kf.step(w);
        (kf.theta, kf.p)
    };
    (theta.as_slice().to_vec(), p.transpose().as_slice().to_vec())
}

/// `max |x − y|`.
pub fn max_abs_diff(x: &[f64], y: &[f64]) -> f64 {
    assert_eq!(x.len(), y.len());
    x.iter()
        .zip(y)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max)
}

/// `max |x − y| / max(1, max |y|)`.
pub fn rel_err(x: &[f64], y: &[f64]) -> f64 {
    assert_eq!(x.len(), y.len());
    let scale = y.iter().fold(1.0f64, |s, v| s.max(v.abs()));
    x.iter()
        .zip(y)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max)
        / scale
}

/// The two concrete backends.
pub const BACKENDS: [Backend; 2] = [Backend::Loops, Backend::Faer];

/// The same random-walk filter in information form: the update solves the `n × n` system
/// `(P⁻⁻¹ + Aᵀ A / σ_R²) Δθ = Aᵀ (b − A θ) / σ_R²` and sets `P = (P⁻⁻¹ + Aᵀ A / σ_R²)⁻¹`.
/// Mathematically identical to [`TextbookKf`], but well conditioned when `σ_R` is tiny and
/// `m > n` (where `S = A P Aᵀ + R` is nearly singular).
pub struct InformationKf {
    pub theta: DVector<f64>,
    pub p: DMatrix<f64>,
    q: f64,
    r: f64,
}

impl InformationKf {
    pub fn new(n: usize, sigma_q: f64, sigma_r: f64, p0: f64) -> Self {
        Self {
            theta: DVector::zeros(n),
            p: DMatrix::identity(n, n) * p0,
            q: sigma_q * sigma_q,
            r: sigma_r * sigma_r,
        }
    }

    /// Starts from a given state (`p` row-major `n × n`).
    pub fn from_state(theta: &[f64], p: &[f64], sigma_q: f64, sigma_r: f64) -> Self {
        let n = theta.len();
        Self {
            theta: DVector::from_column_slice(theta),
            p: DMatrix::from_row_slice(n, n, p),
            q: sigma_q * sigma_q,
            r: sigma_r * sigma_r,
        }
    }

    pub fn step(&mut self, w: &Window) {
        let n = self.theta.len();
        let h = DMatrix::from_row_slice(w.rows(), n, &w.a);
        let z = DVector::from_column_slice(&w.b);
        let p_pred = &self.p + DMatrix::identity(n, n) * self.q;
        let info = p_pred.cholesky().expect("P⁻ positive definite").inverse()
            + h.transpose() * &h / self.r;
        let chol = info
            .cholesky()
            .expect("information matrix positive definite");
        let innovation = z - &h * &self.theta;
        self.theta = &self.theta + chol.solve(&(h.transpose() * innovation / self.r));
        self.p = chol.inverse();
    }
}
