//! Making a case's tests: the lumped generator (state equations in cascade, RK4 with the
//! input held between samples, the truth by exact zero-order-hold discretisation of the same
//! equations through a matrix exponential), the physics generator (the crate's
//! Bergh-Tijdeman time-domain simulation), and the channels (offset, drift, coloured and
//! white noise, 16-bit ADC) shared by both.

use std::f64::consts::PI;

use super::case::{Case, Effect, Generator, Test, REFERENCE_K};
use super::draw::Rng;
use unlag::physics::{gas::Gas, simulate, Acquisition, Diaphragm, Element, Probe, Volume};

/// One stage of a lumped probe, in cascade order.
#[derive(Debug, Clone, Copy)]
pub enum Stage {
    /// `w^2 / (s^2 + 2 zeta w s + w^2)`, with quadratic damping `quad |v| v` on its rate.
    Mode { f_hz: f64, zeta: f64, quad: f64 },
    /// `(s + g p)/(s + p)`, `p = 2 pi corner`.
    Leak { corner_hz: f64, dc_gain: f64 },
}

/// `x' = A x + B u` (plus the quadratic damping), `y = C x`.
#[derive(Debug, Clone)]
pub struct StateSpace {
    a: Vec<Vec<f64>>,
    b: Vec<f64>,
    c: Vec<f64>,
    /// Equilibrium state for a unit input.
    x_unit: Vec<f64>,
    /// `(rate state, k)` of each quadratic damping term.
    quad: Vec<(usize, f64)>,
    /// The stages it was built from.
    stages: Vec<Stage>,
}

impl StateSpace {
    /// The cascade of `stages` (the first must be a mode: strictly proper).
    pub fn cascade(stages: &[Stage]) -> Self {
        let n: usize = stages
            .iter()
            .map(|s| match s {
                Stage::Mode { .. } => 2,
                Stage::Leak { .. } => 1,
            })
            .sum();
        let mut a = vec![vec![0.0; n]; n];
        let mut b = vec![0.0; n];
        let mut x_unit = vec![0.0; n];
        let mut quad = Vec::new();
        // The current stage's input as a linear form of the state and the input.
        let (mut row, mut du) = (vec![0.0; n], 1.0);
        let mut dc = 1.0;
        let mut i = 0;
        for s in stages {
            match *s {
                Stage::Mode {
                    f_hz,
                    zeta,
                    quad: k,
                } => {
                    let w = 2.0 * PI * f_hz;
                    a[i][i + 1] = 1.0;
                    for (j, r) in row.iter().enumerate() {
                        a[i + 1][j] += w * w * r;
                    }
                    b[i + 1] += w * w * du;
                    a[i + 1][i] -= w * w;
                    a[i + 1][i + 1] -= 2.0 * zeta * w;
                    if k != 0.0 {
                        quad.push((i + 1, k));
                    }
                    x_unit[i] = dc;
                    row = vec![0.0; n];
                    row[i] = 1.0;
                    du = 0.0;
                    i += 2;
                }
                Stage::Leak { corner_hz, dc_gain } => {
                    let p = 2.0 * PI * corner_hz;
                    let z = dc_gain * p;
                    for (j, r) in row.iter().enumerate() {
                        a[i][j] += (z - p) * r;
                    }
                    b[i] += (z - p) * du;
                    a[i][i] -= p;
                    x_unit[i] = (dc_gain - 1.0) * dc;
                    dc *= dc_gain;
                    row[i] += 1.0;
                    i += 1;
                }
            }
        }
        Self {
            a,
            b,
            c: row,
            x_unit,
            quad,
            stages: stages.to_vec(),
        }
    }

    fn deriv(&self, x: &[f64], u: f64, out: &mut [f64]) {
        for (o, (ar, br)) in out.iter_mut().zip(self.a.iter().zip(&self.b)) {
            *o = ar.iter().zip(x).map(|(p, q)| p * q).sum::<f64>() + br * u;
        }
        for &(i, k) in &self.quad {
            out[i] -= k * x[i].abs() * x[i];
        }
    }

    /// Output to `u` held between samples and delayed by `delay` samples, from equilibrium
    /// at `u[0]`, by RK4 with 32 steps per sample.
    pub fn simulate(&self, u: &[f64], delay: usize, fs: f64) -> Vec<f64> {
        const SUB: usize = 32;
        let n = self.b.len();
        let h = 1.0 / (fs * SUB as f64);
        let u0 = u.first().copied().unwrap_or(0.0);
        let mut x: Vec<f64> = self.x_unit.iter().map(|v| v * u0).collect();
        let (mut k1, mut k2, mut k3, mut k4, mut tmp) = (
            vec![0.0; n],
            vec![0.0; n],
            vec![0.0; n],
            vec![0.0; n],
            vec![0.0; n],
        );
        let mut y = Vec::with_capacity(u.len());
        for k in 0..u.len() {
            y.push(self.c.iter().zip(&x).map(|(p, q)| p * q).sum());
            let uk = k.checked_sub(delay).map_or(u0, |j| u[j]);
            for _ in 0..SUB {
                self.deriv(&x, uk, &mut k1);
                for j in 0..n {
                    tmp[j] = x[j] + 0.5 * h * k1[j];
                }
                self.deriv(&tmp, uk, &mut k2);
                for j in 0..n {
                    tmp[j] = x[j] + 0.5 * h * k2[j];
                }
                self.deriv(&tmp, uk, &mut k3);
                for j in 0..n {
                    tmp[j] = x[j] + h * k3[j];
                }
                self.deriv(&tmp, uk, &mut k4);
                for j in 0..n {
                    x[j] += h / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j]);
                }
            }
        }
        y
    }

    /// The exact zero-order-hold discretisation of the linear part at `fs` with an input
    /// delay of `delay` samples, in the model file's convention: `(delay, a, b)`.
    pub fn zoh(&self, fs: f64, delay: usize) -> (usize, Vec<f64>, Vec<f64>) {
        let n = self.b.len();
        let t = 1.0 / fs;
        // exp([[A T, B T], [0, 0]]) = [[Ad, Bd], [0, 1]].
        let mut m = vec![vec![0.0; n + 1]; n + 1];
        for ((row, ar), br) in m.iter_mut().zip(&self.a).zip(&self.b) {
            for (v, a) in row.iter_mut().zip(ar) {
                *v = a * t;
            }
            row[n] = br * t;
        }
        let e = expm(&m);
        let ad: Vec<Vec<f64>> = e.iter().take(n).map(|r| r[..n].to_vec()).collect();
        let bd: Vec<f64> = e.iter().take(n).map(|r| r[n]).collect();
        // Denominator from the continuous poles, mapped by z = exp(s T).
        let mut den = vec![1.0];
        for s in &self.stages {
            let factor = match *s {
                Stage::Mode { f_hz, zeta, .. } => {
                    let w = 2.0 * PI * f_hz;
                    if zeta < 1.0 {
                        let r = (-zeta * w * t).exp();
                        let wd = w * (1.0 - zeta * zeta).sqrt();
                        vec![1.0, -2.0 * r * (wd * t).cos(), r * r]
                    } else {
                        let q = (zeta * zeta - 1.0).sqrt();
                        let (z1, z2) = ((w * (-zeta + q) * t).exp(), (w * (-zeta - q) * t).exp());
                        vec![1.0, -(z1 + z2), z1 * z2]
                    }
                }
                Stage::Leak { corner_hz, .. } => vec![1.0, -(-2.0 * PI * corner_hz * t).exp()],
            };
            den = poly_mul(&den, &factor);
        }
        // Markov parameters h[k] = C Ad^(k-1) Bd, then B(z) = A(z) H(z) truncated.
        let mut h = vec![0.0; n + 1];
        let mut v = bd;
        for hk in h.iter_mut().skip(1) {
            *hk = self.c.iter().zip(&v).map(|(p, q)| p * q).sum();
            v = ad
                .iter()
                .map(|r| r.iter().zip(&v).map(|(p, q)| p * q).sum())
                .collect();
        }
        let b: Vec<f64> = (1..=n)
            .map(|k| (0..k).map(|j| den[j] * h[k - j]).sum())
            .collect();
        (delay + 1, den[1..].to_vec(), b)
    }
}

fn poly_mul(p: &[f64], q: &[f64]) -> Vec<f64> {
    let mut r = vec![0.0; p.len() + q.len() - 1];
    for (i, a) in p.iter().enumerate() {
        for (j, b) in q.iter().enumerate() {
            r[i + j] += a * b;
        }
    }
    r
}

fn mat_mul(a: &[Vec<f64>], b: &[Vec<f64>]) -> Vec<Vec<f64>> {
    let n = a.len();
    (0..n)
        .map(|i| {
            (0..n)
                .map(|j| (0..n).map(|k| a[i][k] * b[k][j]).sum())
                .collect()
        })
        .collect()
}

/// Matrix exponential by scaling, a 20-term Taylor series and squaring.
fn expm(m: &[Vec<f64>]) -> Vec<Vec<f64>> {
    let n = m.len();
    let norm = m
        .iter()
        .map(|r| r.iter().map(|v| v.abs()).sum::<f64>())
        .fold(0.0, f64::max);
    let squarings = if norm > 0.25 {
        (norm / 0.25).log2().ceil() as i32
    } else {
        0
    };
    let scale = 0.5f64.powi(squarings);
    let x: Vec<Vec<f64>> = m
        .iter()
        .map(|r| r.iter().map(|v| v * scale).collect())
        .collect();
    let identity: Vec<Vec<f64>> = (0..n)
        .map(|i| (0..n).map(|j| f64::from(u8::from(i == j))).collect())
        .collect();
    let mut sum = identity.clone();
    let mut term = identity;
    for k in 1..=20 {
        term = mat_mul(&term, &x);
        term.iter_mut()
            .for_each(|r| r.iter_mut().for_each(|v| *v /= f64::from(k)));
        for (s, t) in sum.iter_mut().zip(&term) {
            for (a, b) in s.iter_mut().zip(t) {
                *a += b;
            }
        }
    }
    for _ in 0..squarings {
        sum = mat_mul(&sum, &sum);
    }
    sum
}

/// The true pressure of `test` at `fs`, each sample the mean over its interval.
pub fn pressure(test: &Test, fs: f64) -> Vec<f64> {
    (0..test.n)
        .map(|k| {
            test.base_pa
                + test
                    .excitation
                    .cell_average(k as f64 / fs - test.event_s, 1.0 / fs)
        })
        .collect()
}

/// Speed-of-sound ratio of air at `kelvin` to the reference temperature.
fn sound_ratio(kelvin: f64) -> f64 {
    let a = |t| Gas::air(t, 101_325.0).speed_of_sound();
    a(kelvin) / a(REFERENCE_K)
}

/// A lumped case's probe stages at gas temperature `kelvin` (with the diaphragm when
/// `with_sensor`) and its delay.
pub fn lumped_stages(case: &Case, kelvin: f64, with_sensor: bool) -> (Vec<Stage>, usize) {
    let Generator::Lumped { f_hz, zeta, delay } = case.generator else {
        return (Vec::new(), 0);
    };
    let k = sound_ratio(kelvin);
    let quad = match case.effect {
        Effect::NonlinearDamping { ratio } => ratio * 2.0 * zeta / case.step_pa,
        _ => 0.0,
    };
    let mut stages = vec![Stage::Mode {
        f_hz: f_hz * k,
        zeta,
        quad,
    }];
    match case.effect {
        Effect::Mode { f_hz, zeta, .. } => stages.push(Stage::Mode {
            f_hz: f_hz * k,
            zeta,
            quad: 0.0,
        }),
        Effect::Leak { corner_hz, dc_gain } => stages.push(Stage::Leak { corner_hz, dc_gain }),
        Effect::SensorResonance { f_hz, zeta } if with_sensor => stages.push(Stage::Mode {
            f_hz,
            zeta,
            quad: 0.0,
        }),
        _ => {}
    }
    (stages, (delay as f64 / k).round() as usize)
}

/// Noise-free `(reference, probe)` of `test` at `kelvin`, from the case's generator.
///
/// # Errors
/// The physics module's, as text.
pub fn clean(case: &Case, test: &Test, kelvin: f64) -> Result<(Vec<f64>, Vec<f64>), String> {
    let sensor = match case.effect {
        Effect::SensorResonance { f_hz, zeta } => Some((f_hz, zeta)),
        _ => None,
    };
    let (u, mut y) = match &case.generator {
        Generator::Lumped { .. } => {
            let p = pressure(test, case.fs);
            let (stages, delay) = lumped_stages(case, kelvin, true);
            let y = StateSpace::cascade(&stages).simulate(&p, delay, case.fs);
            let u = match sensor {
                Some((f_hz, zeta)) => StateSpace::cascade(&[Stage::Mode {
                    f_hz,
                    zeta,
                    quad: 0.0,
                }])
                .simulate(&p, 0, case.fs),
                None => p,
            };
            (u, y)
        }
        Generator::Physics { geometry } => {
            let gas = Gas::air(kelvin, 101_325.0);
            let mut line = geometry.line(&gas);
            if let Effect::Mode {
                second_stage: Some((l, r, v)),
                ..
            } = case.effect
            {
                line = line.tube(l, r).with(Element::Volume(Volume::new(v)));
            }
            let dc = line.dc_gain(&gas);
            let mut probe = Probe::new(line, gas);
            let diaphragm = sensor.map(|(natural_frequency_hz, damping)| Diaphragm {
                natural_frequency_hz,
                damping,
            });
            probe.diaphragm = diaphragm;
            let mut acq = Acquisition::new(case.fs, test.n as f64 / case.fs);
            acq.event_time_s = test.event_s;
            acq.oversample = 16;
            acq.reference_sensor = diaphragm;
            let sim = simulate(&probe, &test.excitation, &acq).map_err(|e| e.to_string())?;
            let u = sim.reference.iter().map(|v| v + test.base_pa).collect();
            let y = sim
                .probe_clean
                .iter()
                .map(|v| v + dc * test.base_pa)
                .collect();
            (u, y)
        }
    };
    // A physics probe's leak: the pole-zero pair on its output (exact for a held input).
    if let (Generator::Physics { .. }, Effect::Leak { corner_hz, dc_gain }) =
        (&case.generator, case.effect)
    {
        let p = 2.0 * PI * corner_hz;
        let e = (-p / case.fs).exp();
        let gain = (1.0 - e) * (dc_gain - 1.0);
        let mut x = (dc_gain - 1.0) * y.first().copied().unwrap_or(0.0);
        for v in &mut y {
            let input = *v;
            *v = input + x;
            x = e * x + gain * input;
        }
    }
    Ok((u, y))
}

/// The `(reference, probe)` before the ADC: the clean channels with the case's additive
/// effects and white noise on both.
pub fn measured(case: &Case, u: &[f64], y: &[f64], rng: &mut Rng) -> (Vec<f64>, Vec<f64>) {
    let su = case.noise_u * case.step_pa;
    let sy = case.noise_y * case.step_pa;
    let u = u.iter().map(|v| v + su * rng.gauss()).collect();
    let mut coloured = 0.0;
    let y = y
        .iter()
        .enumerate()
        .map(|(k, v)| {
            let t = k as f64 / case.fs;
            let extra = match case.effect {
                Effect::Offset { fraction } => fraction * case.step_pa,
                Effect::Drift { per_s } => per_s * case.step_pa * t,
                Effect::ColouredNoise { rho, ratio } => {
                    let innovation = ratio * sy * (1.0 - rho * rho).sqrt() * rng.gauss();
                    coloured = if k == 0 {
                        ratio * sy * rng.gauss()
                    } else {
                        rho * coloured + innovation
                    };
                    coloured
                }
                _ => 0.0,
            };
            v + extra + sy * rng.gauss()
        })
        .collect();
    (u, y)
}

/// The case's 16-bit ADC, its range set from all of `channels`.
pub fn adc_for(case: &Case, channels: &[&Vec<f64>]) -> unlag::physics::simulate::Adc {
    let lo = channels
        .iter()
        .flat_map(|c| c.iter())
        .copied()
        .fold(f64::INFINITY, f64::min);
    let hi = channels
        .iter()
        .flat_map(|c| c.iter())
        .copied()
        .fold(f64::NEG_INFINITY, f64::max);
    case.adc(lo, hi)
}

/// Writes a `t,u,y` CSV.
///
/// # Errors
/// I/O, with the path.
pub fn write_csv(path: &std::path::Path, fs: f64, u: &[f64], y: &[f64]) -> Result<(), String> {
    use std::fmt::Write as _;
    let mut s = String::with_capacity(40 * u.len());
    s.push_str("t,u,y\n");
    for (k, (a, b)) in u.iter().zip(y).enumerate() {
        let _ = writeln!(s, "{:.9},{a:.6},{b:.6}", k as f64 / fs);
    }
    std::fs::write(path, s).map_err(|e| format!("cannot write {}: {e}", path.display()))
}

/// Writes a model file (format version 1) with only the model.
///
/// # Errors
/// I/O, with the path.
pub fn write_model(
    path: &std::path::Path,
    fs: f64,
    (delay, a, b): &(usize, Vec<f64>, Vec<f64>),
) -> Result<(), String> {
    let list = |v: &[f64]| {
        v.iter()
            .map(|c| format!("{c:e}"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let text = format!(
        "# The true probe of a bench_bank case: exact ZOH discretisation of its lumped model.\n\
         # y[k] = sum_{{i=0..m}} b[i] u[k-i-delay] - sum_{{i=1..m}} a[i] y[k-i]\n\
         format_version = 1\nfs = {fs:?}\ndelay = {delay}\na = [{}]\nb = [{}]\n",
        list(a),
        list(b)
    );
    std::fs::write(path, text).map_err(|e| format!("cannot write {}: {e}", path.display()))
}

/// Largest `|x - y|` relative to `scale`.
pub fn max_difference(x: &[f64], y: &[f64], scale: f64) -> f64 {
    x.iter()
        .zip(y)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max)
        / scale
}

/// `y = q^-d B/A u` from equilibrium at `u[0]`.
pub fn filter_model((delay, a, b): &(usize, Vec<f64>, Vec<f64>), u: &[f64]) -> Vec<f64> {
    let u0 = u.first().copied().unwrap_or(0.0);
    let dc = b.iter().sum::<f64>() / (1.0 + a.iter().sum::<f64>());
    let mut y = vec![0.0; u.len()];
    for k in 0..u.len() {
        let mut acc = 0.0;
        for (i, bi) in b.iter().enumerate() {
            if let Some(j) = k.checked_sub(i + delay) {
                acc += bi * (u[j] - u0);
            }
        }
        for (i, ai) in a.iter().enumerate() {
            if let Some(j) = k.checked_sub(i + 1) {
                acc -= ai * y[j];
            }
        }
        y[k] = acc;
    }
    y.iter().map(|v| v + dc * u0).collect()
}
