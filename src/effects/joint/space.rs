//! The coordinates a joint fit searches: a model's coefficients as they are, or as
//! polynomials in `w = z - 1`, and the loss beside them.

use crate::fit::Model;

/// The coordinates the search moves a model's coefficients in.
///
/// A probe sampled far above its corners has its poles and zeros crowded near `z = 1`, where
/// the coefficients of `A(z)` and `B(z)` are nearly dependent: their sums, which set the DC
/// gain and the slow corner, are small differences of numbers near 1, so that moving one pole
/// far is a long curved path through them. The same polynomials in `w = z - 1` (the delta
/// operator's, Middleton and Goodwin, unscaled) have coefficients of the poles' and zeros'
/// own size, and there the path is short. On an overdamped capillary with a quadratic loss,
/// the search in `a` and `b` can stop at a loss many times too small, its linear part still
/// the one that had taken the loss in as damping, where in `w` it reaches the noise floor
/// with the loss drawn. Neither is better everywhere, so each fit is made in both
/// ([`Coordinates::BOTH`]) and the one that leaves less is kept.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Coordinates {
    /// The coefficients `a` and `b` themselves: the polynomials in the shift operator `z`.
    Shift,
    /// The coefficients of `A` and `B` as polynomials in `w = z - 1`.
    Delta,
}

impl Coordinates {
    pub const BOTH: [Self; 2] = [Self::Shift, Self::Delta];
}

/// The space a fit searches: the coordinates of the coefficients, and the loss in units of
/// `unit` (kept within `[0, max]`) when `loss = Some((unit, max))`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Space {
    pub coordinates: Coordinates,
    pub loss: Option<(f64, f64)>,
}

impl Space {
    /// The linear fit's space: the coefficients alone.
    pub fn linear(coordinates: Coordinates) -> Self {
        Self {
            coordinates,
            loss: None,
        }
    }

    /// The parameters of `model` (the loss not among them).
    pub fn pack(self, model: &Model) -> Vec<f64> {
        match self.coordinates {
            Coordinates::Shift => model.a.iter().chain(&model.b).copied().collect(),
            Coordinates::Delta => {
                let a = taylor_shift(&monic(&model.a), 1.0);
                let b = taylor_shift(&model.b, 1.0);
                a.into_iter().skip(1).chain(b).collect()
            }
        }
    }

    /// One model's `a`, `b` and its loss from the parameters, the other fields as `start`'s.
    pub fn unpack(self, start: &Model, theta: &[f64]) -> (Model, f64) {
        let m = start.a.len();
        let nb = start.b.len();
        let mut model = start.clone();
        let a: Vec<f64> = theta.iter().take(m).copied().collect();
        let b: Vec<f64> = theta.iter().skip(m).take(nb).copied().collect();
        (model.a, model.b) = match self.coordinates {
            Coordinates::Shift => (a, b),
            Coordinates::Delta => (
                taylor_shift(&monic(&a), -1.0).into_iter().skip(1).collect(),
                taylor_shift(&b, -1.0),
            ),
        };
        let gain = match self.loss {
            Some((unit, max)) => theta
                .get(m + nb)
                .map_or(0.0, |g| (g * unit).clamp(0.0, max)),
            None => 0.0,
        };
        (model, gain)
    }
}

/// `[1, a1, .., am]`: the denominator's coefficients, highest power of `z` first.
fn monic(a: &[f64]) -> Vec<f64> {
    std::iter::once(1.0).chain(a.iter().copied()).collect()
}

/// The coefficients of `p(x + by)`, those of `p(x)` given highest power first (synthetic
/// division repeated: `n (n - 1) / 2` multiply-adds).
fn taylor_shift(p: &[f64], by: f64) -> Vec<f64> {
    let mut c = p.to_vec();
    for end in (1..c.len()).rev() {
        for j in 1..=end {
            let prev = c.get(j - 1).copied().unwrap_or(0.0);
            if let Some(cj) = c.get_mut(j) {
                *cj += by * prev;
            }
        }
    }
    c
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_taylor_shift_moves_the_variable_and_back() {
        // (x + 1)^2 = x^2 + 2x + 1; x^3 - 1 at x - 1 is x^3 - 3x^2 + 3x - 2.
        assert_eq!(taylor_shift(&[1.0, 0.0, 0.0], 1.0), vec![1.0, 2.0, 1.0]);
        assert_eq!(
            taylor_shift(&[1.0, 0.0, 0.0, -1.0], -1.0),
            vec![1.0, -3.0, 3.0, -2.0]
        );
        let model = Model {
            fs: 4070.0,
            delay: 8,
            a: vec![-1.992_068, 0.992_085],
            b: vec![0.001_869, -0.001_094, -0.000_759],
        };
        for coordinates in Coordinates::BOTH {
            let space = Space::linear(coordinates);
            let (back, _) = space.unpack(&model, &space.pack(&model));
            for (x, y) in back
                .a
                .iter()
                .chain(&back.b)
                .zip(model.a.iter().chain(&model.b))
            {
                assert!((x - y).abs() < 1e-15, "{coordinates:?}: {back:?}");
            }
        }
        // In `w = z - 1`, A(1) and B(1) (which set the DC gain) are coordinates of their own.
        let delta = Space::linear(Coordinates::Delta).pack(&model);
        let a1: f64 = 1.0 + model.a.iter().sum::<f64>();
        let b1: f64 = model.b.iter().sum();
        assert!(
            (delta[1] - a1).abs() < 1e-15 && (delta[4] - b1).abs() < 1e-15,
            "{delta:?}"
        );
    }
}
