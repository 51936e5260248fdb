//! The filters a design is built from: zeros, poles and gain ([`Zpk`]), the low-pass
//! prototypes, second-order sections and their responses, noise gain and phase unwrapping.

use super::LowpassKind;
use crate::error::{Error, Result};
use crate::fit::model::Model;
use crate::poly::{self, Complex};
use std::f64::consts::PI;

/// Zeros, poles and gain of a rational function in `z^-1`:
/// `k * prod(1 - z_i z^-1) / prod(1 - p_i z^-1)`.
#[derive(Debug, Clone, PartialEq)]
pub struct Zpk {
    /// Zeros.
    pub zeros: Vec<Complex>,
    /// Poles.
    pub poles: Vec<Complex>,
    /// Gain.
    pub gain: f64,
}

pub(crate) fn c(re: f64) -> Complex {
    Complex::new(re, 0.0)
}

impl Zpk {
    /// Value at `z`.
    #[must_use]
    pub fn eval(&self, z: Complex) -> Complex {
        let zi = c(1.0) / z;
        let num = self
            .zeros
            .iter()
            .fold(c(self.gain), |acc, q| acc * (c(1.0) - *q * zi));
        self.poles
            .iter()
            .fold(num, |acc, p| acc / (c(1.0) - *p * zi))
    }
}

/// Analog prototype poles with the -3 dB corner at 1 rad/s.
fn analog_prototype(kind: LowpassKind, n: usize) -> Result<Vec<Complex>> {
    match kind {
        LowpassKind::Butterworth => Ok((0..n)
            .map(|k| {
                let th = PI * (2 * k + n + 1) as f64 / (2 * n) as f64;
                Complex::new(th.cos(), th.sin())
            })
            .collect()),
        LowpassKind::Bessel => {
            // Reverse Bessel polynomial theta_n(s) = sum a_k s^k,
            // a_k = (2n-k)! / (2^(n-k) k! (n-k)!); its roots have unit group delay at DC.
            let fact = |x: usize| (1..=x).fold(1.0f64, |a, b| a * b as f64);
            let a: Vec<f64> = (0..=n)
                .map(|k| fact(2 * n - k) / (2f64.powi((n - k) as i32) * fact(k) * fact(n - k)))
                .collect();
            // poly::roots takes the highest power first.
            let hi_first: Vec<f64> = a.iter().rev().copied().collect();
            let roots = poly::roots(&hi_first)?;
            // Scale so that |H(j w)| = 1/sqrt(2) at w = 1.
            let mag2 = |w: f64, r: &[Complex]| {
                r.iter().fold(1.0, |acc, p| {
                    acc * (p.norm_sqr() / (Complex::new(0.0, w) - *p).norm_sqr())
                })
            };
            let (mut lo, mut hi): (f64, f64) = (1e-3, 1e3);
            for _ in 0..200 {
                let mid = (lo * hi).sqrt();
                if mag2(mid, &roots) > 0.5 {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            let w3 = (lo * hi).sqrt();
            Ok(roots.into_iter().map(|p| p / w3).collect())
        }
    }
}

/// Digital low-pass by the bilinear transform, corner prewarped to `fc`, unit DC gain.
///
/// # Errors
/// [`Error::InvalidParameter`] for an order outside 1..=8 or a corner outside (0, fs/2).
pub fn lowpass(kind: LowpassKind, order: usize, fc: f64, fs: f64) -> Result<Zpk> {
    if !(1..=8).contains(&order) {
        return Err(Error::InvalidParameter {
            parameter: crate::error::Parameter::LowpassOrder,
            message: format!("must be 1..=8, not {order}"),
        });
    }
    if !(fc.is_finite() && fc > 0.0 && fc < 0.5 * fs) {
        return Err(Error::InvalidParameter {
            parameter: crate::error::Parameter::Bandwidth,
            message: format!(
                "the low-pass corner must be between 0 and half the sample rate ({} Hz), not {fc}",
                0.5 * fs
            ),
        });
    }
    let wc = 2.0 * fs * (PI * fc / fs).tan();
    let poles: Vec<Complex> = analog_prototype(kind, order)?
        .into_iter()
        .map(|p| {
            let s = p * wc / (2.0 * fs);
            (c(1.0) + s) / (c(1.0) - s)
        })
        .collect();
    let zeros = vec![c(-1.0); order];
    let mut z = Zpk {
        zeros,
        poles,
        gain: 1.0,
    };
    z.gain = 1.0 / z.eval(c(1.0)).re;
    Ok(z)
}

/// The model `H(z) = z^-d B/A` at `z`.
#[must_use]
pub fn model_response(model: &Model, z: Complex) -> Complex {
    let num = poly::eval(&model.b, z);
    let den = poly::eval(&model.denominator(), z);
    let delay = (c(1.0) / z).powi(i32::try_from(model.delay).unwrap_or(i32::MAX));
    num / den * delay
}

pub(crate) fn unit(f: f64, fs: f64) -> Complex {
    let w = 2.0 * PI * f / fs;
    Complex::new(w.cos(), w.sin())
}

/// Pairs poles and zeros into second-order sections `[b0, b1, b2, a1, a2]` (leading
/// coefficients one; the gain is returned apart). Poles nearest the unit circle come first,
/// each with the zeros nearest to it.
///
/// Real roots are paired slowest with fastest. Rounding a section's coefficients by `d`
/// moves a root `r` by about `d / |r - r'|`, `r'` the section's other root: two slow real
/// roots side by side (a thermal creep's poles, with its zeros beside them) in one section
/// lose `1 - r`, and with it the gain below their corners, to `f32` rounding, where each
/// paired with a fast root (often a pole at the origin) keeps it.
#[must_use]
pub fn to_sections(zpk: &Zpk) -> (f64, Vec<[f64; 5]>) {
    // Quadratic factors [1, c1, c2] from roots: conjugate pairs together, reals the slowest
    // with the fastest.
    fn quads(roots: &[Complex]) -> Vec<(Vec<Complex>, [f64; 2])> {
        let mut cpx: Vec<Complex> = roots.iter().copied().filter(|r| r.im > 1e-12).collect();
        let mut real: Vec<f64> = roots
            .iter()
            .filter(|r| r.im.abs() <= 1e-12)
            .map(|r| r.re)
            .collect();
        cpx.sort_by(|a, b| b.norm().total_cmp(&a.norm()));
        real.sort_by(|a, b| b.abs().total_cmp(&a.abs()));
        let mut out: Vec<(Vec<Complex>, [f64; 2])> = cpx
            .into_iter()
            .map(|r| (vec![r, r.conj()], [-2.0 * r.re, r.norm_sqr()]))
            .collect();
        let (slow, fast) = real.split_at(real.len() / 2);
        for (&r1, &r2) in slow.iter().zip(fast.iter().rev()) {
            out.push((vec![c(r1), c(r2)], [-(r1 + r2), r1 * r2]));
        }
        // An odd one out, the middle root, alone.
        if real.len() % 2 == 1 {
            if let Some(&r) = fast.first() {
                out.push((vec![c(r)], [-r, 0.0]));
            }
        }
        out
    }
    let mut pq = quads(&zpk.poles);
    let mut zq = quads(&zpk.zeros);
    pq.sort_by(|a, b| {
        let ra = a.0.iter().map(|r| r.norm()).fold(0.0, f64::max);
        let rb = b.0.iter().map(|r| r.norm()).fold(0.0, f64::max);
        rb.total_cmp(&ra)
    });
    let mut sections = Vec::new();
    for (proots, [a1, a2]) in pq {
        // Nearest zero factor to these poles: each pole's distance to its nearest zero in
        // it, summed.
        let best = zq
            .iter()
            .enumerate()
            .map(|(i, (zr, _))| {
                let d: f64 = proots
                    .iter()
                    .map(|p| {
                        zr.iter()
                            .map(|z| (*p - *z).norm())
                            .fold(f64::INFINITY, f64::min)
                    })
                    .sum();
                (i, d)
            })
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .map(|(i, _)| i);
        let [b1, b2] = match best {
            Some(i) => zq.remove(i).1,
            None => [0.0, 0.0],
        };
        sections.push([1.0, b1, b2, a1, a2]);
    }
    // Zeros left over (more zeros than poles): sections with poles at the origin.
    for (_, [b1, b2]) in zq {
        sections.push([1.0, b1, b2, 0.0, 0.0]);
    }
    (zpk.gain, sections)
}

/// Response of a cascade at `z`.
#[must_use]
pub fn cascade_response(gain: f64, sections: &[[f64; 5]], z: Complex) -> Complex {
    cascade_response_at_inverse(gain, sections, c(1.0) / z)
}

/// [`cascade_response`] at `z` given as `zi = 1 / z`.
pub(crate) fn cascade_response_at_inverse(
    gain: f64,
    sections: &[[f64; 5]],
    zi: Complex,
) -> Complex {
    sections.iter().fold(c(gain), |acc, s| {
        let num = c(s[0]) + zi * (c(s[1]) + zi * c(s[2]));
        let den = c(1.0) + zi * (c(s[3]) + zi * c(s[4]));
        acc * num / den
    })
}

/// Impulse response energy of a cascade: its noise gain, `sqrt(sum h^2)`.
pub(crate) fn noise_gain(gain: f64, sections: &[[f64; 5]]) -> f64 {
    let mut st = vec![[0.0f64; 2]; sections.len()];
    let mut energy = 0.0;
    let mut tail = 0.0;
    for k in 0..2_000_000 {
        let mut v = if k == 0 { gain } else { 0.0 };
        for (s, st) in sections.iter().zip(st.iter_mut()) {
            let y = s[0] * v + st[0];
            *st = [s[1] * v - s[3] * y + st[1], s[2] * v - s[4] * y];
            v = y;
        }
        energy += v * v;
        tail = if k % 256 == 0 { 0.0 } else { tail + v * v };
        if k > 1024 && k % 256 == 255 && tail < 1e-14 * energy {
            break;
        }
    }
    energy.sqrt()
}

/// Unwrapped phase of `values` along a frequency grid.
pub(crate) fn unwrap(values: &[Complex]) -> Vec<f64> {
    let mut out = Vec::with_capacity(values.len());
    let mut offset = 0.0;
    let mut prev: Option<f64> = None;
    for v in values {
        let mut ph = v.im.atan2(v.re) + offset;
        if let Some(p) = prev {
            while ph - p > PI {
                ph -= 2.0 * PI;
                offset -= 2.0 * PI;
            }
            while ph - p < -PI {
                ph += 2.0 * PI;
                offset += 2.0 * PI;
            }
        }
        prev = Some(ph);
        out.push(ph);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// DC gain of a cascade ([`cascade_response`] at `z = 1`), with its sections'
    /// coefficients rounded to `f32` when `round`.
    #[allow(clippy::cast_possible_truncation)]
    fn dc(gain: f64, sections: &[[f64; 5]], round: bool) -> f64 {
        let r = |v: f64| if round { f64::from(v as f32) } else { v };
        let rounded: Vec<[f64; 5]> = sections.iter().map(|s| s.map(r)).collect();
        cascade_response(gain, &rounded, c(1.0)).re
    }

    /// A thermal creep's compensator: two slow poles with zeros beside them, and the smoother's
    /// poles at the origin. Each slow pole goes with a fast one and its own zero, and `f32`
    /// rounding keeps the DC gain to 0.1 %; the two slow roots in one section lose percents.
    #[test]
    fn slow_real_roots_are_paired_with_fast_ones() {
        let zpk = Zpk {
            zeros: vec![c(0.999_61), c(0.996_17), c(0.0), c(0.0)],
            poles: vec![c(0.999_60), c(0.996_07), c(0.0), c(0.0)],
            gain: 1.0,
        };
        let (gain, sections) = to_sections(&zpk);
        assert_eq!(sections.len(), 2, "{sections:?}");
        for s in &sections {
            // One slow pole per section, with the zero beside it.
            assert!(s[4].abs() < 1e-12 && s[2].abs() < 1e-12, "{s:?}");
            assert!((s[1] - s[3]).abs() < 2e-4, "{s:?}");
        }
        let exact = dc(gain, &sections, false);
        assert!((dc(gain, &sections, true) / exact - 1.0).abs() < 1e-3);
        let paired = [
            [
                1.0,
                -(0.999_61 + 0.996_17),
                0.999_61 * 0.996_17,
                -(0.999_60 + 0.996_07),
                0.999_60 * 0.996_07,
            ],
            [1.0, 0.0, 0.0, 0.0, 0.0],
        ];
        assert!((dc(1.0, &paired, true) / dc(1.0, &paired, false) - 1.0).abs() > 1e-2);
    }

    /// Five real poles: the slowest with the fastest, the next with the next, the middle one
    /// alone; the response is the roots' whatever the pairing.
    #[test]
    fn real_roots_pair_outside_in() {
        let roots = [0.9, 0.7, 0.5, 0.3, 0.1];
        let zpk = Zpk {
            zeros: vec![],
            poles: roots.iter().map(|&r| c(r)).collect(),
            gain: 2.0,
        };
        let (gain, sections) = to_sections(&zpk);
        let sums: Vec<f64> = sections.iter().map(|s| -s[3]).collect();
        assert_eq!(sections.len(), 3);
        for (got, want) in sums.iter().zip([1.0, 1.0, 0.5]) {
            assert!((got - want).abs() < 1e-12, "{sums:?}");
        }
        let z = Complex::new(0.3, 0.4);
        let want = roots
            .iter()
            .fold(c(gain), |acc, &r| acc / (c(1.0) - c(r) / z));
        assert!((cascade_response(gain, &sections, z) - want).norm() < 1e-12);
    }
}
