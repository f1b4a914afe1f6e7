//! Residual analysis on the actual inputs (issue 30, item 3), on simulator logs.
//!
//! (a) A hidden signed linear drag: the rigid model's fx residual correlates with the signed
//! body velocity vx far outside the 99 % band, and no longer once linear-drag is in the model.
//! The correlation and its band are computed here by the plain formulas, not by the library.
//! (b) "Where it fails" is silent on logs at their noise: noise-free, the paper's medium noise,
//! the Crazyflie's realistic (calibrated) sensing; it still speaks on the drag log.
//! (c) The residual panels of the HTML report are scaled to the residual itself.
mod common;

use tagk_diagnose::{
    DiagnoseOptions, Diagnosis, FlightLog, Model, Signals, builtin_by_name, diagnose, html,
    run_loop,
};
use tagk_dynamics::EffectKind;
use tagk_sim::{NoiseLevel, Sensing, SimConfig};

const SEEDS: [u64; 2] = [7, 11];

fn log_of(c: &SimConfig) -> FlightLog {
    let out = tagk_sim::simulate(c).expect("simulation runs");
    assert!(!out.metrics.aborted, "flight aborted");
    out.log
}

/// Plain normalised cross-correlation at lag 0 of two series (means removed).
fn corr0(u: &[f64], e: &[f64]) -> f64 {
    let n = u.len() as f64;
    let mu = u.iter().sum::<f64>() / n;
    let me = e.iter().sum::<f64>() / n;
    let mut suu = 0.0;
    let mut see = 0.0;
    let mut sue = 0.0;
    for (a, b) in u.iter().zip(e) {
        suu += (a - mu) * (a - mu);
        see += (b - me) * (b - me);
        sue += (a - mu) * (b - me);
    }
    sue / (suu * see).sqrt()
}

/// Plain autocorrelation at lag `k` (means removed, normalised by lag 0).
fn acf(x: &[f64], k: usize) -> f64 {
    let n = x.len();
    let m = x.iter().sum::<f64>() / n as f64;
    let c0: f64 = x.iter().map(|v| (v - m) * (v - m)).sum();
    let ck: f64 = (0..n - k).map(|i| (x[i] - m) * (x[i + k] - m)).sum();
    ck / c0
}

/// The 99 % band of the cross-correlation of two independent series (Bartlett over 25 lags).
fn band(u: &[f64], e: &[f64]) -> f64 {
    let l = 25;
    let mut p = 1.0;
    for j in 1..=l {
        p += 2.0 * (1.0 - j as f64 / (l + 1) as f64) * acf(u, j) * acf(e, j);
    }
    2.575_829 * (p / u.len() as f64).sqrt()
}

/// The fx residual and the signed body vx of a diagnosis, and the library's lag-0 entry.
fn fx_vx(d: &Diagnosis, s: &Signals) -> (f64, f64, f64, f64) {
    let e: Vec<f64> = d.fit.residual.iter().map(|r| r[0]).collect();
    let u: Vec<f64> = s.velocity_body.iter().map(|v| v.x).collect();
    let entry = d
        .input_correlation
        .iter()
        .find(|x| x.channel == "fx" && x.input == "vx")
        .expect("fx against vx");
    (corr0(&u, &e), band(&u, &e), entry.lag0, entry.band)
}

#[test]
fn a_signed_drag_shows_in_the_fx_vx_correlation_until_it_is_modelled() {
    let opts = DiagnoseOptions::default();
    for seed in SEEDS {
        // 60 s: a smooth residual against a smooth input has few independent samples (the
        // band is Bartlett's, P ≈ 26 here), and the band narrows as 1/√N.
        let mut c = common::config(Some(EffectKind::LinearDrag), seed);
        c.duration = 60.0;
        let s = Signals::from_log(&log_of(&c)).unwrap();
        let rigid = diagnose(&Model::rigid_body(), &s, &opts).unwrap();
        let (rho, b, lib_rho, lib_b) = fx_vx(&rigid, &s);
        eprintln!(
            "seed {seed}: rigid ρ(fx, vx) = {rho:+.3}, band ±{b:.3} (library {lib_rho:+.3}, ±{lib_b:.3})"
        );
        // The library correlates the selection engine's residual (the same fit, solved
        // apart): equal to a small fraction of the band.
        assert!((rho - lib_rho).abs() < 1e-3, "{rho} vs library {lib_rho}");
        assert!((b - lib_b).abs() < 1e-2 * b, "{b} vs library {lib_b}");
        // Three 99 % bands: 7.7 standard deviations.
        assert!(rho.abs() > 3.0 * b, "rigid: ρ {rho} within 3 bands {b}");
        let drag = Model::rigid_body().with_ref(builtin_by_name("linear-drag").unwrap());
        let with = diagnose(&drag, &s, &opts).unwrap();
        let (rho, b, lib_rho, _) = fx_vx(&with, &s);
        eprintln!("seed {seed}: + linear-drag ρ(fx, vx) = {rho:+.3}, band ±{b:.3}");
        assert!((rho - lib_rho).abs() < 1e-3, "{rho} vs library {lib_rho}");
        assert!(lib_rho.abs() < b, "with drag: ρ {rho} outside the band {b}");
    }
}

#[test]
fn where_it_fails_is_silent_on_logs_at_their_noise() {
    let opts = DiagnoseOptions::default();
    for seed in SEEDS {
        let mut ideal = common::config(None, seed);
        ideal.noise = NoiseLevel::None;
        let medium = common::config(None, seed);
        let mut realistic = common::config(None, seed);
        realistic.noise = NoiseLevel::None;
        realistic.sensing = Sensing::realistic_calibrated();
        for (name, c) in [
            ("noise-free", ideal),
            ("medium", medium),
            ("realistic", realistic),
        ] {
            let s = Signals::from_log(&log_of(&c)).unwrap();
            let d = diagnose(&Model::rigid_body(), &s, &opts).unwrap();
            eprintln!(
                "seed {seed} {name}: {} findings, {} windows, held-out/noise {:?}",
                d.findings.len(),
                d.failure_windows.len(),
                d.adequacy
                    .iter()
                    .map(|a| (a.ratio * 100.0).round() / 100.0)
                    .collect::<Vec<_>>()
            );
            assert!(
                d.findings.is_empty(),
                "{name} seed {seed}: {:?}",
                d.findings
            );
            assert!(d.failure_windows.is_empty(), "{name} seed {seed}");
        }
        // The realistic profile's accelerometer bias is a real sensor error: its findings end
        // once the staircase has modelled it.
        let mut biased = common::config(None, seed);
        biased.noise = NoiseLevel::None;
        biased.sensing = Sensing::realistic();
        let s = Signals::from_log(&log_of(&biased)).unwrap();
        let report = run_loop(&s, &Model::rigid_body(), &[], &opts).unwrap();
        let last = report.final_diagnosis();
        eprintln!(
            "seed {seed} realistic+bias: final {} with {} findings",
            last.model,
            last.findings.len()
        );
        assert!(
            last.findings.is_empty(),
            "{}: {:?}",
            last.model,
            last.findings
        );
        // And it speaks where physics is missing.
        let s = Signals::from_log(&common::sim_log(Some(EffectKind::LinearDrag), seed)).unwrap();
        let d = diagnose(&Model::rigid_body(), &s, &opts).unwrap();
        assert!(!d.findings.is_empty(), "drag log seed {seed}: no findings");
    }
}

/// The residual panels (`residual fx [N], held-out RMS …`) of a rendered report: per panel
/// the channel index and its y-range.
fn residual_panels(page: &str) -> Vec<(usize, f64, f64)> {
    let names = ["fx", "fy", "fz", "tx", "ty", "tz"];
    let mut out = Vec::new();
    for svg in page.split("<svg").skip(1) {
        let attr = |key: &str| -> Option<f64> {
            let start = svg.find(&format!("{key}=\""))? + key.len() + 2;
            let end = start + svg[start..].find('"')?;
            svg[start..end].parse().ok()
        };
        let Some(title_start) = svg.find("font-family=\"sans-serif\">") else {
            continue;
        };
        let title = &svg[title_start + 25..];
        let Some(c) = names
            .iter()
            .position(|n| title.starts_with(&format!("residual {n} [")))
        else {
            continue;
        };
        if !title[..title.find("</text>").unwrap_or(0)].contains("held-out RMS") {
            continue;
        }
        out.push((c, attr("data-ylo").unwrap(), attr("data-yhi").unwrap()));
    }
    out
}

#[test]
fn residual_panels_are_scaled_to_the_residual() {
    let opts = DiagnoseOptions::default();
    for (name, noise, effect) in [
        ("noise-free", NoiseLevel::None, None),
        ("medium", NoiseLevel::Medium, None),
        ("drag", NoiseLevel::Medium, Some(EffectKind::LinearDrag)),
    ] {
        let mut c = common::config(effect, 7);
        c.noise = noise;
        let s = Signals::from_log(&log_of(&c)).unwrap();
        let report = run_loop(&s, &Model::rigid_body(), &[], &opts).unwrap();
        let page = html::render(&report);
        let panels = residual_panels(&page);
        // The first diagnosis rendered is the starting model's.
        assert!(
            panels.len() >= 6,
            "{name}: {} residual panels",
            panels.len()
        );
        for &(ch, lo, hi) in &panels[..6] {
            let r = report.before.fit.residual_channel(ch);
            let dlo = r.iter().copied().fold(f64::INFINITY, f64::min);
            let dhi = r.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            let ratio = (hi - lo) / (dhi - dlo);
            eprintln!(
                "{name} channel {ch}: data [{dlo:.3e}, {dhi:.3e}], axis [{lo:.3e}, {hi:.3e}], ×{ratio:.2}"
            );
            assert!(
                lo <= dlo && hi >= dhi,
                "{name} channel {ch}: data outside the axis"
            );
            assert!(
                ratio <= 4.0,
                "{name} channel {ch}: axis ×{ratio} the data range"
            );
        }
        if name == "noise-free" {
            assert!(
                !page.contains("class=\"failure\""),
                "shading on a noise-free log"
            );
            // The noise line, far above a residual at the rounding level, is named, not drawn.
            assert!(page.contains("off scale"), "noise line not named off scale");
        }
    }
}
