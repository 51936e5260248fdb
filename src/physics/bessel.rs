//! The complex Bessel-function ratio `J₂(z)/J₀(z)` that carries the viscous and thermal
//! boundary layers of the Bergh-Tijdeman line model.
//!
//! Only the ratio is needed, and it is an even, meromorphic function of `z`: a function of
//! `w = z²` alone, with poles where `J₀` vanishes (real `z`). It is evaluated as
//!
//! * `|z| ≤ 28`: the Gauss continued fraction
//!   `J₁(z)/(z J₀(z)) = 1/(2 − w/(4 − w/(6 − w/(8 − …))))`, so `J₂/J₀ = 2 J₁/(z J₀) − 1`
//!   (from `J₂ = (2/z) J₁ − J₀`), summed backwards from depth `N = 24 + 2|z|`, which is far
//!   past the point where the partial denominators `2k` dominate `|w|/(2k)`;
//! * `|z| > 28`: Hankel's asymptotic expansions `P_ν`, `Q_ν` (Abramowitz & Stegun 9.2.5-10),
//!   written with `t = e^{2iχ₀}` so nothing overflows (`|t| ≤ 1` on the chosen branch
//!   `Im z ≥ 0`); the smallest term at `|z| = 28` is below 1e-20.
//!
//! Tested against values tabulated with mpmath at 30 digits (relative error below 1e-12
//! everywhere tested, including near the switch and far into the boundary-layer regime
//! `|z| ≈ 1000`). No crate dependency: the pure-Rust complex Bessel crates found
//! (`complex-bessel`, 0.x, first released 2025) are young, and the ratio needs only this.

use num_complex::Complex64;

/// Above this `|z|` the asymptotic expansion is used.
const SWITCH_ABS_Z: f64 = 28.0;

/// `J₂(z)/J₀(z)` for complex `z` (dimensionless).
///
/// Equals [`j2_over_j0_of_square`]`(z²)`: the ratio is even in `z`.
#[must_use]
pub fn j2_over_j0(z: Complex64) -> Complex64 {
    j2_over_j0_of_square(z * z)
}

/// `J₂(z)/J₀(z)` as a function of `w = z²` (dimensionless).
///
/// The Bergh-Tijdeman model needs it at `w = α² = −sR²/ν` (shear wave number squared) and
/// `w = α² Pr`. Small `w`: `J₂/J₀ = (w/8)(1 + w/6 + …)`; large `w` away from the positive real
/// axis: `J₂/J₀ → −1`. At a zero of `J₀` (real `z`) the result is infinite or very large.
#[must_use]
pub fn j2_over_j0_of_square(w: Complex64) -> Complex64 {
    let abs_z = w.norm().sqrt();
    if abs_z <= SWITCH_ABS_Z {
        continued_fraction(w, abs_z)
    } else {
        asymptotic(w)
    }
}

/// `2/(2 − w/(4 − w/(6 − …))) − 1`, backwards from depth `24 + 2|z|`.
fn continued_fraction(w: Complex64, abs_z: f64) -> Complex64 {
    // 24 + 2*28 = 80 at most; the cast is exact for these small values.
    let depth = 24 + (2.0 * abs_z).ceil() as u32;
    let mut t = Complex64::new(f64::from(2 * depth), 0.0);
    for k in (1..depth).rev() {
        t = Complex64::new(f64::from(2 * k), 0.0) - w / t;
    }
    Complex64::new(2.0, 0.0) / t - 1.0
}

/// Hankel asymptotic expansion of `J₂/J₀` for `|z| > 28`.
fn asymptotic(w: Complex64) -> Complex64 {
    let mut z = w.sqrt(); // principal branch: Re z ≥ 0
    let conjugated = z.im < 0.0;
    if conjugated {
        z = z.conj(); // J(conj z) = conj J(z): work with Im z ≥ 0, conjugate back
    }
    let (p0, q0) = hankel_pq(0.0, z);
    let (p2, q2) = hankel_pq(16.0, z);
    let i = Complex64::i();
    let chi0 = z - core::f64::consts::FRAC_PI_4;
    let t = (2.0 * i * chi0).exp(); // |t| = e^{-2 Im z} ≤ 1
    let one = Complex64::new(1.0, 0.0);
    // cos χ₀ ∝ (1 + t), sin χ₀ ∝ i(1 − t) (common factor e^{−iχ₀}/2); χ₂ = χ₀ − π.
    let num = p2 * (one + t) - i * q2 * (one - t);
    let den = p0 * (one + t) - i * q0 * (one - t);
    let r = -num / den;
    if conjugated {
        r.conj()
    } else {
        r
    }
}

/// `P_ν(z)`, `Q_ν(z)` of A&S 9.2.9-10 with `mu = 4ν²`, summed to the smallest term.
fn hankel_pq(mu: f64, z: Complex64) -> (Complex64, Complex64) {
    let mut p = Complex64::new(1.0, 0.0);
    let mut q = Complex64::new(0.0, 0.0);
    let mut term = Complex64::new(1.0, 0.0); // a_k(ν)/z^k
    let mut last = f64::INFINITY;
    for k in 1..200_u32 {
        let odd = f64::from(2 * k - 1);
        term *= (mu - odd * odd) / (f64::from(k) * 8.0 * z);
        let size = term.norm();
        if size >= last {
            break; // the asymptotic series has started to diverge
        }
        last = size;
        // P collects even k with sign (-1)^{k/2}; Q odd k with sign (-1)^{(k-1)/2}.
        let sign = if (k / 2) % 2 == 0 { 1.0 } else { -1.0 };
        if k % 2 == 0 {
            p += sign * term;
        } else {
            q += sign * term;
        }
        if size < 1e-18 {
            break;
        }
    }
    (p, q)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `(Re z, Im z, Re J₂/J₀, Im J₂/J₀)`, computed with mpmath 1.3
    /// (`besselj(2,z)/besselj(0,z)`, 30 significant digits), independent of this code; the
    /// digits are kept as printed (rounded to f64 on parsing), hence the `allow`.
    #[allow(clippy::excessive_precision)]
    const TABLE: [(f64, f64, f64, f64); 16] = [
        (1.0, 0.0, 0.150_161_830_008_611_92, 0.0),
        (5.0, 0.0, -0.262_195_736_629_322_23, 0.0),
        (0.0, 1.0, -0.107_220_068_206_930_99, 0.0),
        (0.0, 10.0, -0.810_280_034_809_030_81, 0.0),
        (
            1.0,
            1.0,
            -0.074_494_346_376_500_687,
            0.224_410_265_920_980_63,
        ),
        (
            3.0,
            -2.0,
            -0.668_939_536_543_548_5,
            -0.406_807_058_000_934_5,
        ),
        (
            -0.5,
            4.0,
            -0.572_388_931_341_799_7,
            -0.044_028_806_774_621_185,
        ),
        (
            10.0,
            10.0,
            -0.899_930_779_992_217_5,
            0.094_938_101_685_954_847,
        ),
        (
            -20.0,
            20.0,
            -0.949_991_781_735_615_05,
            -0.048_742_204_446_318_256,
        ),
        (
            24.0,
            -24.0,
            -0.958_328_617_730_850_47,
            -0.040_794_096_680_282_257,
        ),
        (
            26.0,
            18.0,
            -0.963_640_146_130_998_52,
            0.051_062_253_355_175_157,
        ),
        (
            40.0,
            -3.0,
            -0.995_608_392_955_698_47,
            -0.049_874_563_703_556_33,
        ),
        (
            0.3,
            60.0,
            -0.966_946_433_963_941_16,
            0.000_163_867_102_684_758_82,
        ),
        (
            -150.0,
            150.0,
            -0.993_333_314_690_715_1,
            -0.006_644_425_926_577_923,
        ),
        (
            700.0,
            700.0,
            -0.998_571_428_388_952_23,
            0.001_427_550_838_192_711_2,
        ),
        (
            30.0,
            0.2,
            -0.917_471_736_395_178_74,
            0.034_370_013_970_608_1,
        ),
    ];

    #[test]
    fn matches_tabulated_values() {
        for (re, im, want_re, want_im) in TABLE {
            let got = j2_over_j0(Complex64::new(re, im));
            let want = Complex64::new(want_re, want_im);
            let err = (got - want).norm() / want.norm();
            assert!(
                err < 1e-12,
                "z = {re}+{im}i: got {got}, want {want}, rel err {err:e}"
            );
        }
    }

    #[test]
    fn pole_at_first_zero_of_j0() {
        // j_{0,1} = 2.404825557695773: the ratio blows up there.
        let r = j2_over_j0(Complex64::new(2.404_825_557_695_773, 0.0));
        assert!(!r.is_finite() || r.norm() > 1e6, "{r}");
    }

    #[test]
    fn small_argument_series() {
        // J₂/J₀ = (w/8)(1 + w/6 + 11w²/384 + …), from J₀ = 1 − w/4 + w²/64 − …, J₂ = w/8 − w²/96 + w³/3072 − ….
        for w in [
            Complex64::new(1e-3, 0.0),
            Complex64::new(0.0, -2e-3),
            Complex64::new(-1e-3, 1e-3),
        ] {
            let series = w / 8.0 * (1.0 + w / 6.0 + 11.0 * w * w / 384.0);
            // truncation error ~ w³ relative: 1e-8; the w² term itself is 3e-5 relative.
            assert!((j2_over_j0_of_square(w) - series).norm() < 1e-10 * series.norm());
        }
    }

    #[test]
    fn continuous_across_the_switch() {
        for arg in [0.1_f64, 0.8, 1.6, 2.35, 3.0] {
            let below = Complex64::from_polar(SWITCH_ABS_Z * (1.0 - 1e-13), arg);
            let above = Complex64::from_polar(SWITCH_ABS_Z * (1.0 + 1e-13), arg);
            let (a, b) = (j2_over_j0(below), j2_over_j0(above));
            assert!(
                (a - b).norm() < 1e-10 * a.norm().max(1.0),
                "arg {arg}: {a} vs {b}"
            );
        }
    }

    #[test]
    fn conjugate_and_even_symmetry() {
        let z = Complex64::new(7.5, -3.25);
        let r = j2_over_j0(z);
        assert!((j2_over_j0(z.conj()) - r.conj()).norm() < 1e-14);
        assert!((j2_over_j0(-z) - r).norm() < 1e-14);
    }
}
