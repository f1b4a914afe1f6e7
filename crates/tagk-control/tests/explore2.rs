use nalgebra::SMatrix;
use std::hint::black_box;
use std::time::Instant;
type M12 = SMatrix<f64, 12, 12>;

#[test]
fn micro() {
    let a = M12::from_fn(|i, j| ((i * 7 + j * 3) % 11) as f64 * 0.1 + if i == j { 3.0 } else { 0.0 });
    let b = M12::from_fn(|i, j| ((i * 5 + j * 2) % 13) as f64 * 0.1);
    let mut c = M12::zeros();
    let n = 200_000;
    let t = Instant::now();
    for _ in 0..n { black_box(&a).mul_to(black_box(&b), &mut c); black_box(&c); }
    println!("mul_to {:.1} ns", t.elapsed().as_nanos() as f64 / n as f64);
    let t = Instant::now();
    for _ in 0..n { black_box(&a).tr_mul_to(black_box(&b), &mut c); black_box(&c); }
    println!("tr_mul_to {:.1} ns", t.elapsed().as_nanos() as f64 / n as f64);
    let t = Instant::now();
    for _ in 0..n { c = black_box(&a) * black_box(&b); black_box(&c); }
    println!("op* {:.1} ns", t.elapsed().as_nanos() as f64 / n as f64);
    let t = Instant::now();
    for _ in 0..n { let lu = black_box(a).lu(); c = lu.solve(black_box(&b)).unwrap(); black_box(&c); }
    println!("nalgebra lu+solve12 {:.1} ns", t.elapsed().as_nanos() as f64 / n as f64);
}
