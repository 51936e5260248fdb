//! FFT helpers for [`super::simulate`](mod@super::simulate): turning the (non-rational) frequency response of a
//! line into an impulse response, and linear convolution with an excitation.
//!
//! The transforms are `rustfft`'s (the crate the residual spectra of the modelling loop use
//! too); this module adds the conventions the simulation relies on: power-of-two lengths, an
//! inverse scaled by `1/N`, and zero padding so that a convolution never wraps around.

use num_complex::Complex64;

use super::PhysicsError;
use crate::error::Result;

/// Forward (`e^{-2πikn/N}`) or inverse (`e^{+2πikn/N}`, scaled by `1/N`) transform, in place.
///
/// # Errors
/// [`PhysicsError::FftLength`] when the length is not a power of two.
pub fn fft_in_place(buf: &mut [Complex64], inverse: bool) -> Result<()> {
    let n = buf.len();
    if n <= 1 {
        return Ok(());
    }
    if !n.is_power_of_two() {
        return Err(PhysicsError::FftLength { length: n }.into());
    }
    let mut planner = rustfft::FftPlanner::new();
    let plan = if inverse {
        planner.plan_fft_inverse(n)
    } else {
        planner.plan_fft_forward(n)
    };
    plan.process(buf);
    if inverse {
        let scale = 1.0 / n as f64;
        for v in buf.iter_mut() {
            *v *= scale;
        }
    }
    Ok(())
}

/// Linear (not circular) convolution of two real sequences, first `out_len` samples, by FFT of
/// a power-of-two length of at least `a.len() + b.len() - 1` (so nothing wraps around).
///
/// # Errors
/// [`PhysicsError::ConvolutionLength`] if the transform length would overflow.
pub fn convolve(a: &[f64], b: &[f64], out_len: usize) -> Result<Vec<f64>> {
    if a.is_empty() || b.is_empty() {
        return Ok(vec![0.0; out_len]);
    }
    let need = a.len() + b.len() - 1;
    let n = need
        .checked_next_power_of_two()
        .ok_or(PhysicsError::ConvolutionLength { length: need })?;
    let mut fa: Vec<Complex64> = a.iter().map(|&x| Complex64::new(x, 0.0)).collect();
    fa.resize(n, Complex64::new(0.0, 0.0));
    let mut fb: Vec<Complex64> = b.iter().map(|&x| Complex64::new(x, 0.0)).collect();
    fb.resize(n, Complex64::new(0.0, 0.0));
    fft_in_place(&mut fa, false)?;
    fft_in_place(&mut fb, false)?;
    for (x, y) in fa.iter_mut().zip(&fb) {
        *x *= y;
    }
    fft_in_place(&mut fa, true)?;
    let mut out: Vec<f64> = fa.iter().take(out_len.min(need)).map(|c| c.re).collect();
    out.resize(out_len, 0.0);
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dft(x: &[Complex64]) -> Vec<Complex64> {
        let n = x.len();
        (0..n)
            .map(|k| {
                x.iter()
                    .enumerate()
                    .map(|(j, v)| {
                        v * Complex64::from_polar(
                            1.0,
                            -2.0 * core::f64::consts::PI * (k * j) as f64 / n as f64,
                        )
                    })
                    .sum()
            })
            .collect()
    }

    #[test]
    fn matches_direct_dft_and_inverts() {
        for n in [1_usize, 2, 8, 64, 256] {
            let x: Vec<Complex64> = (0..n)
                .map(|i| Complex64::new((i as f64 * 0.37).sin(), (i as f64 * 1.3).cos() * 0.5))
                .collect();
            let mut y = x.clone();
            fft_in_place(&mut y, false).expect("fft");
            for (a, b) in y.iter().zip(dft(&x)) {
                assert!((a - b).norm() < 1e-10 * (n as f64), "n {n}: {a} vs {b}");
            }
            fft_in_place(&mut y, true).expect("fft");
            for (a, b) in y.iter().zip(&x) {
                assert!((a - b).norm() < 1e-12, "n {n}");
            }
        }
        assert!(fft_in_place(&mut [Complex64::new(0.0, 0.0); 6], false).is_err());
    }

    #[test]
    fn linear_convolution() {
        let a = [1.0, 2.0, 3.0];
        let b = [0.5, -1.0];
        let c = convolve(&a, &b, 5).expect("fft");
        let want = [0.5, 0.0, -0.5, -3.0, 0.0];
        for (x, y) in c.iter().zip(want) {
            assert!((x - y).abs() < 1e-12, "{c:?}");
        }
    }

    #[test]
    fn a_length_that_is_not_a_power_of_two_is_refused() {
        let mut buf = vec![Complex64::new(1.0, 0.0); 6];
        let e = fft_in_place(&mut buf, false).unwrap_err();
        assert!(
            matches!(e.stage(), Some(PhysicsError::FftLength { length: 6 })),
            "{e:?}"
        );
        assert_eq!(e.to_string(), "FFT: length 6 is not a power of two");
        assert_eq!(e.kind(), "numerical");
        assert_eq!(e.location(), (None, None, None));
    }
}
