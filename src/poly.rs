//! Polynomials in `z^-1`: roots (the poles and zeros of a model), evaluation on the unit circle.
//!
//! Owns the convention that a coefficient vector `p = [p0, p1, ..., pn]` means
//! `p0 + p1 z^-1 + ... + pn z^-n`, whose roots in `z` are those of
//! `p0 z^n + p1 z^(n-1) + ... + pn`. Roots are the eigenvalues of the companion matrix,
//! computed by faer (Hessenberg QR), never by a hand-written root finder.

use faer::Mat;

use crate::error::Result;

/// A complex number (faer's `c64`).
pub type Complex = faer::c64;

/// What can go wrong in finding a polynomial's roots: the polynomial is zero, or the
/// eigenvalue iteration does not converge. Reached as [`crate::Error::Stage`].
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum PolyError {
    /// Every coefficient is zero: the roots are not defined.
    #[error("roots: the polynomial is zero")]
    Zero,
    /// The eigenvalues of the companion matrix did not converge.
    #[error("roots: eigenvalues of the companion matrix did not converge: {error:?}")]
    NoConvergence {
        /// faer's reason.
        error: faer::linalg::evd::EvdError,
    },
}

impl PolyError {
    /// What went wrong, without the "roots" it happened in (for a caller that names its own
    /// step).
    #[must_use]
    pub(crate) fn reason(&self) -> String {
        let text = self.to_string();
        match text.strip_prefix("roots: ") {
            Some(reason) => reason.to_string(),
            None => text,
        }
    }
}

/// Roots in `z` of `p0 + p1 z^-1 + ... + pn z^-n`. Leading zeros of `p` are dropped (they lower
/// the degree); trailing zeros give roots at `z = 0`.
///
/// # Errors
/// [`PolyError::NoConvergence`] when the eigenvalue iteration does not converge,
/// [`PolyError::Zero`] when `p` is all zeros.
pub fn roots(p: &[f64]) -> Result<Vec<Complex>> {
    let first = p.iter().position(|&c| c != 0.0);
    let Some(first) = first else {
        return Err(PolyError::Zero.into());
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
    let mut r = c
        .eigenvalues()
        .map_err(|error| PolyError::NoConvergence { error })?;
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

/// The product of two polynomials in `z^-1` (their coefficients' convolution).
#[must_use]
pub fn times(p: &[f64], q: &[f64]) -> Vec<f64> {
    let mut out = vec![0.0; (p.len() + q.len()).saturating_sub(1)];
    for (i, a) in p.iter().enumerate() {
        for (j, b) in q.iter().enumerate() {
            if let Some(o) = out.get_mut(i + j) {
                *o += a * b;
            }
        }
    }
    out
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

impl crate::error::StageError for PolyError {}
crate::error::stage_error!(PolyError);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_product_is_the_convolution_and_its_roots_are_both_factors() {
        // (1 - 0.5 z^-1)(1 - 2.1 z^-1) = 1 - 2.6 z^-1 + 1.05 z^-2
        let p = times(&[1.0, -0.5], &[1.0, -2.1]);
        assert_eq!(p.len(), 3);
        assert!(
            (p[1] + 2.6).abs() < 1e-12 && (p[2] - 1.05).abs() < 1e-12,
            "{p:?}"
        );
        assert!(times(&[], &[1.0]).is_empty());
    }

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
    fn a_zero_polynomial_has_no_roots() {
        let e = roots(&[0.0, 0.0, 0.0]).unwrap_err();
        assert!(matches!(e.stage(), Some(PolyError::Zero)), "{e:?}");
        assert_eq!(e.to_string(), "roots: the polynomial is zero");
        assert_eq!(e.kind(), "numerical");
        assert_eq!(e.location(), (None, None, None));
        assert_eq!(PolyError::Zero.reason(), "the polynomial is zero");
        let e = PolyError::NoConvergence {
            error: faer::linalg::evd::EvdError::NoConvergence,
        };
        assert_eq!(
            e.to_string(),
            "roots: eigenvalues of the companion matrix did not converge: NoConvergence"
        );
    }

    #[test]
    fn eval_matches_roots() {
        let p = [0.3, -0.2, 0.05, 0.01];
        for z in roots(&p).unwrap() {
            assert!(eval(&p, z).norm() < 1e-12);
        }
    }
}
