//! Polynomials in `z^-1`: roots (the poles and zeros of a model), evaluation on the unit circle.
//!
//! Owns the convention that a coefficient vector `p = [p0, p1, ..., pn]` means
//! `p0 + p1 z^-1 + ... + pn z^-n`, whose roots in `z` are those of
//! `p0 z^n + p1 z^(n-1) + ... + pn`. Roots are the eigenvalues of the companion matrix,
//! computed by faer (Hessenberg QR), never by a hand-written root finder.

use faer::Mat;

use crate::error::{Error, Result};

/// A complex number (faer's `c64`).
pub type Complex = faer::c64;

/// Roots in `z` of `p0 + p1 z^-1 + ... + pn z^-n`. Leading zeros of `p` are dropped (they lower
/// the degree); trailing zeros give roots at `z = 0`.
///
/// # Errors
/// [`Error::Numerical`] when the eigenvalue iteration does not converge or `p` is all zeros.
pub fn roots(p: &[f64]) -> Result<Vec<Complex>> {
    let first = p.iter().position(|&c| c != 0.0);
    let Some(first) = first else {
        return Err(Error::Numerical {
            context: "roots".into(),
            message: "the polynomial is zero".into(),
        });
    };
    let p = p.get(first..).unwrap_or(&[]);
    let n = p.len().saturating_sub(1);
    if n == 0 {
        return Ok(Vec::new());
    }
    let lead = p.first().copied().unwrap_or(1.0);
    // Companion matrix: first row -p[1..]/p0, ones on the sub-diagonal.
    let c = Mat::<f64>::from_fn(n, n, |i, j| {
        if i == 0 {
            -p.get(j + 1).copied().unwrap_or(0.0) / lead
        } else if i == j + 1 {
            1.0
        } else {
            0.0
        }
    });
    let mut r = c.eigenvalues().map_err(|e| Error::Numerical {
        context: "roots".into(),
        message: format!("eigenvalues of the companion matrix did not converge: {e:?}"),
    })?;
    // Largest magnitude first: that is the one that decides stability.
    r.sort_by(|x, y| y.norm().total_cmp(&x.norm()));
    Ok(r)
}

/// `p0 + p1 z^-1 + ... + pn z^-n` at `z`.
#[must_use]
pub fn eval(p: &[f64], z: Complex) -> Complex {
    let zi = Complex::new(1.0, 0.0) / z;
    // Horner in z^-1, from the highest power.
    p.iter().rev().fold(Complex::new(0.0, 0.0), |acc, &c| {
        acc * zi + Complex::new(c, 0.0)
    })
}

/// Formats a complex root for messages: `0.95+0.12j`.
#[must_use]
pub fn format_root(z: Complex) -> String {
    if z.im.abs() < 1e-12 {
        format!("{:.6}", z.re)
    } else {
        format!("{:.6}{:+.6}j", z.re, z.im)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn roots_of_known_polynomials() {
        // (1 - 0.5 z^-1)(1 - 2.1 z^-1) = 1 - 2.6 z^-1 + 1.05 z^-2
        let r = roots(&[1.0, -2.6, 1.05]).unwrap();
        assert!((r[0].re - 2.1).abs() < 1e-12 && r[0].im.abs() < 1e-12);
        assert!((r[1].re - 0.5).abs() < 1e-12);
        // Complex pair 0.9 e^{+-j 0.3}
        let (rad, th): (f64, f64) = (0.9, 0.3);
        let r = roots(&[2.0, -4.0 * rad * th.cos(), 2.0 * rad * rad]).unwrap();
        for z in r {
            assert!((z.norm() - rad).abs() < 1e-12);
            assert!((z.im.abs() - rad * th.sin()).abs() < 1e-12);
        }
        // Leading zero lowers the degree.
        assert_eq!(roots(&[0.0, 1.0, -0.5]).unwrap().len(), 1);
        assert!(roots(&[0.0, 0.0]).is_err());
    }

    #[test]
    fn eval_matches_roots() {
        let p = [0.3, -0.2, 0.05, 0.01];
        for z in roots(&p).unwrap() {
            assert!(eval(&p, z).norm() < 1e-12);
        }
    }
}
