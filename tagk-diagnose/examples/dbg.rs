use tagk_diagnose::*;
fn main() {
    let path = std::env::args().nth(1).unwrap();
    let log = FlightLog::from_csv_path(&path).unwrap();
    let s = Signals::from_log(&log).unwrap();
    check(&s);
    let opts = DiagnoseOptions::default();
    for with in [vec![], vec!["motor-lag"]] {
        let mut m = Model::rigid_body();
        for w in &with { m = m.with_ref(builtin_by_name(w).unwrap()); }
        let d = diagnose(&m, &s, &opts).unwrap();
        println!("{}: held-out {:?}", d.model, d.held_out_rms);
        println!("  in-sample {:?}", d.channels.iter().map(|c| c.rms).collect::<Vec<_>>());
        println!("  noise {:?}", d.noise_floor.rms);
        for e in &d.effects { println!("  {:?} {:?}", e.scanned, e.scanned_interval); }
    }
}
#[allow(dead_code)]
fn check(s: &Signals) {
    let e = builtin_by_name("motor-lag").unwrap();
    let cols = effect_columns(e.as_ref(), s, Some(0.02));
    for c in 2..6 {
        let b: Vec<f64> = s.wrench().iter().map(|w| w[c]).collect();
        let mut y: Vec<f64> = cols[0].data[c].as_ref().unwrap().iter().zip(&b).map(|(d, b)| d + b).collect();
        e.unfilter(s, Some(0.02), c, &mut y);
        let err: f64 = y.iter().zip(&b).map(|(a, b)| (a - b).powi(2)).sum::<f64>().sqrt() / (b.len() as f64).sqrt();
        let rmsb: f64 = (b.iter().map(|x| x * x).sum::<f64>() / b.len() as f64).sqrt();
        println!("channel {c}: unfiltered lag target vs b rms err {err:.3e} (b rms {rmsb:.3e}); first {:?} vs {:?}", &y[..4], &b[..4]);
    }
}
