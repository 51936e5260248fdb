//! Regenerates the shipped example step tests (`examples/data/`) and the recorded traces of
//! the integration tests (`host-tests/data/`).
//!
//! The probe is a pneumatic line with two acoustic modes (112 Hz, damping 0.32; 362 Hz, 0.16),
//! a transport delay of 1.7 ms, sampled at 10 kHz; the reference opens like a fast valve
//! (0.3 ms rise); both channels carry white noise. The simulation is the independent RK4
//! integrator of the test fixtures, not the crate's own code.
//!
//! ```sh
//! cargo run --example make_example_data
//! ```

#[path = "../host-tests/common/mod.rs"]
mod common;

use common::{add_noise, continuous_line, write_csv, Rng};

const FS: f64 = 10_000.0;

fn valve(n: usize, at: usize, lo: f64, hi: f64) -> Vec<f64> {
    (0..n)
        .map(|k| {
            let x = (k as f64 - at as f64) / 3.0;
            lo + (hi - lo) * x.clamp(0.0, 1.0)
        })
        .collect()
}

fn main() {
    let modes = [(112.0, 0.32), (362.0, 0.16)];
    let tests = [
        ("examples/data/step_test_1.csv", 4000, 600, 0.0, 1000.0, 1),
        ("examples/data/step_test_2.csv", 4000, 900, 800.0, 100.0, 2),
        ("host-tests/data/line_est.csv", 3000, 400, 0.0, 500.0, 3),
        ("host-tests/data/line_val.csv", 3000, 700, 500.0, 50.0, 4),
    ];
    for (path, n, at, lo, hi, seed) in tests {
        let u = valve(n, at, lo, hi);
        let y = continuous_line(&u, FS, &modes, 17);
        let mut rng = Rng::new(seed);
        let sigma = 0.001 * f64::abs(hi - lo);
        let y = add_noise(&y, sigma, &mut rng);
        let u = add_noise(&u, 0.3 * sigma, &mut rng);
        let round =
            |v: Vec<f64>| -> Vec<f64> { v.iter().map(|x| (x * 1e4).round() / 1e4).collect() };
        write_csv(std::path::Path::new(path), FS, &round(u), &round(y));
        println!("wrote {path}");
    }
}
