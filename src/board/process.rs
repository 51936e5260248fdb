//! The board's compensators as `dsp_process` processors: [`SplitProcess`] and
//! [`SplitInplace`], the traits the `idsp` filters implement, so that a compensator composes
//! with them (in series, in parallel, across channels) without glue.
//!
//! Each compensator's coefficients are the configuration and its state the state, as the
//! crate already splits them: `Split::new(coefficients, state)` is a stateful processor, and
//! `(Split::new(a, sa) * Split::new(b, sb)).minor::<f32>()` runs `a` then `b`. Every method
//! forwards to the compensator's own `process` or `process_in_place`: the same bits, the
//! Cortex-M kernels where the target has them, panic-free (a block whose input and output
//! differ in length is processed over the shorter).

#![deny(
    clippy::indexing_slicing,
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::unreachable,
    clippy::todo,
    clippy::arithmetic_side_effects
)]

use dsp_process::{SplitInplace, SplitProcess};

use super::compensator::{
    CascadeCoefficients, CascadeState, InverseCoefficients, InverseState,
    NonlinearDampingCoefficients, NonlinearDampingState, Sample,
};
use super::fixed::direct::{DirectCascade, DirectState};
use super::fixed::{FixedCascade, FixedState};

/// `y = x` over the common length, then `run` over it in place.
#[inline]
fn copy_then<X: Copy>(x: &[X], y: &mut [X], run: impl FnOnce(&mut [X])) {
    let n = x.len().min(y.len());
    let (Some(x), Some(y)) = (x.get(..n), y.get_mut(..n)) else {
        return;
    };
    for (y, x) in y.iter_mut().zip(x) {
        *y = *x;
    }
    run(y);
}

/// Implements both traits for a compensator whose `process` and `process_in_place` take
/// `(&self, &mut State, ...)`.
macro_rules! split_process {
    ($sample:ty, $coefficients:ty, $state:ty, [$($generics:tt)*]) => {
        impl<$($generics)*> SplitProcess<$sample, $sample, $state> for $coefficients {
            #[inline]
            fn process(&self, state: &mut $state, x: $sample) -> $sample {
                <$coefficients>::process(self, state, x)
            }

            #[inline]
            fn block(&self, state: &mut $state, x: &[$sample], y: &mut [$sample]) {
                copy_then(x, y, |y| self.process_in_place(state, y));
            }
        }

        impl<$($generics)*> SplitInplace<$sample, $state> for $coefficients {
            #[inline]
            fn inplace(&self, state: &mut $state, xy: &mut [$sample]) {
                self.process_in_place(state, xy);
            }
        }
    };
}

split_process!(T, CascadeCoefficients<T, N>, CascadeState<T, N>, [T: Sample, const N: usize]);
split_process!(T, InverseCoefficients<T, M>, InverseState<T, M>, [T: Sample, const M: usize]);
split_process!(i32, FixedCascade<N>, FixedState<N>, [const N: usize]);
split_process!(i32, DirectCascade<N>, DirectState<N>, [const N: usize]);

/// The nonlinear-damping correction: the probe sample in, the term to add to `u_hat` out.
impl<T: Sample, const N: usize> SplitProcess<T, T, NonlinearDampingState<T, N>>
    for NonlinearDampingCoefficients<T, N>
{
    #[inline]
    fn process(&self, state: &mut NonlinearDampingState<T, N>, y: T) -> T {
        NonlinearDampingCoefficients::process(self, state, y)
    }
}

#[cfg(test)]
mod tests {
    // Test code: a failed unwrap is a failed test.
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]

    use dsp_process::{Inplace, Process, Split};

    use super::*;

    /// A first-order lag `u = 0.2 y + 0.8 u[-1]` and a first-difference-ish section.
    fn two() -> (CascadeCoefficients<f32, 1>, CascadeCoefficients<f32, 1>) {
        (
            CascadeCoefficients::new(0.2, &[[1.0, 0.0, 0.0, -0.8, 0.0]]).unwrap(),
            CascadeCoefficients::new(2.0, &[[1.0, -0.5, 0.0, 0.1, 0.0]]).unwrap(),
        )
    }

    #[test]
    fn a_split_cascade_gives_the_cascades_own_bits() {
        let (a, _) = two();
        let x: [f32; 8] = [0.0, 1.0, 1.0, 0.5, -0.25, 2.0, 0.0, 1.5];
        let mut own = CascadeState::default();
        let expected: [f32; 8] = x.map(|v| a.process(&mut own, v));
        let mut p = Split::new(a, CascadeState::default());
        let one_by_one: [f32; 8] = x.map(|v| p.process(v));
        assert_eq!(one_by_one, expected);
        let mut q = Split::new(a, CascadeState::default());
        let mut y = [0.0f32; 8];
        q.block(&x, &mut y);
        assert_eq!(y, expected);
        let mut r = Split::new(a, CascadeState::default());
        let mut xy = x;
        r.inplace(&mut xy);
        assert_eq!(xy, expected);
    }

    #[test]
    fn two_compensators_compose_in_series() {
        let (a, b) = two();
        let x: [f32; 6] = [1.0, 1.0, 0.0, -1.0, 3.0, 0.5];
        let (mut sa, mut sb) = (CascadeState::default(), CascadeState::default());
        let expected = x.map(|v| b.process(&mut sb, a.process(&mut sa, v)));
        let mut series = (Split::new(a, CascadeState::default())
            * Split::new(b, CascadeState::default()))
        .minor::<f32>();
        assert_eq!(x.map(|v| series.process(v)), expected);
    }

    #[test]
    fn a_compensator_composes_with_an_idsp_filter() {
        use idsp::iir::{Biquad, DirectForm2Transposed};
        // idsp's biquad after the compensator: a two-tap average, `[[b], [a]]` with a0 = 1.
        let smooth: Biquad<f32> = [[0.5f32, 0.5, 0.0], [1.0, 0.0, 0.0]].into();
        let (a, _) = two();
        let x: [f32; 6] = [1.0, 1.0, 0.0, -1.0, 3.0, 0.5];
        let (mut sa, mut ss) = (CascadeState::default(), DirectForm2Transposed::default());
        let expected = x.map(|v| smooth.process(&mut ss, a.process(&mut sa, v)));
        let mut chain = (Split::new(a, CascadeState::default())
            * Split::new(smooth, DirectForm2Transposed::default()))
        .minor::<f32>();
        let got = x.map(|v| chain.process(v));
        assert_eq!(got, expected);
        // The average of the lag's first two outputs, 0.2 and 0.36.
        assert!((got[1] - 0.28).abs() < 1e-6, "{got:?}");
    }

    #[test]
    fn fixed_point_compensators_are_processors_too() {
        // A stable section (pole 0.5, the identity's numerator) so that the state matters.
        let mut section = crate::fixed::direct::DirectSection::IDENTITY;
        section.neg_a = [1 << 29, 0];
        let c = DirectCascade::<1>::new(&[section]).unwrap();
        let mut p = Split::new(c, DirectState::default());
        let mut own = DirectState::default();
        let x = [5, -7, 1 << 20, 0, 0, 3];
        let mut y = [0; 6];
        p.block(&x, &mut y);
        assert_eq!(y, x.map(|v| c.process(&mut own, v)));
        assert_ne!(y[4], 0, "the pole's memory shows: {y:?}");
        let f = FixedCascade::<1>::new(&[crate::fixed::FixedSection::IDENTITY]).unwrap();
        let mut q = Split::new(f, FixedState::default());
        let mut own = FixedState::default();
        for v in [0, 1000, -2000, i32::MAX / 4] {
            assert_eq!(q.process(v), f.process(&mut own, v));
        }
    }

    #[test]
    fn a_block_of_unequal_lengths_is_processed_over_the_shorter() {
        let (a, _) = two();
        let mut p = Split::new(a, CascadeState::default());
        let mut y = [9.0f32; 3];
        p.block(&[1.0, 1.0], &mut y);
        assert_eq!(y[2], 9.0);
        assert!((y[0] - 0.2).abs() < 1e-7);
    }
}
