//! The board's compensators as `dsp_process` processors: [`SplitProcess`] and
//! [`SplitInplace`], the traits the `idsp` filters implement, so that a compensator composes
//! with them (in series, in parallel, across channels) without glue.
//!
//! Each compensator's coefficients are the configuration and its state the state, as the
//! crate already splits them: `Split::new(coefficients, state)` is a stateful processor, and
//! `(Split::new(a, sa) * Split::new(b, sb)).minor::<f32>()` runs `a` then `b`. The processors:
//!
//! | configuration | state | sample |
//! |---|---|---|
//! | [`CascadeCoefficients`] | [`CascadeState`] | `f32`, `f64` |
//! | [`InverseCoefficients`] | [`InverseState`] | `f32`, `f64` |
//! | [`FixedCascade`] | [`FixedState`] | `i32` |
//! | [`DirectCascade`] | [`DirectState`] | `i32` |
//! | [`NonlinearDampingCoefficients`] | [`NonlinearDampingState`] | `f32`, `f64` |
//! | [`TemperatureBank`] | [`BankChannel`] | `f32`, `f64` |
//!
//! Every method gives the compensator's own bits. The first four forward to their own
//! `process` and `process_in_place` (the Cortex-M kernels where the target has them); the last
//! two have no `process_in_place`, so their blocks run their `process` sample by sample. All
//! are panic-free: a block whose input and output differ in length is processed over the
//! shorter.
//!
//! The nonlinear-damping correction takes the probe sample and gives the term to add to the
//! linear compensator's output for the same sample (in place: each probe sample is replaced by
//! its term). A temperature bank's temperature is not an input of its processor: the
//! processor runs the set the channel is on (and the set warming up, if any), and the board
//! gives the channel the measured temperature between blocks with
//! [`TemperatureBank::set_temperature`] on the `Split`'s `state`.
//!
//! A compensator as a processor, a block at a time, gives the bits of its own `process`:
//!
//! ```
//! use dsp_process::{Inplace, Process, Split};
//! use unlag::board::compensator::{CascadeCoefficients, CascadeState};
//!
//! // A first-order lag: u = 0.2 y + 0.8 u[-1].
//! let c = CascadeCoefficients::<f32, 1>::new(0.2, &[[1.0, 0.0, 0.0, -0.8, 0.0]])?;
//! let x: [f32; 6] = [0.0, 1.0, 1.0, 0.5, -0.25, 2.0];
//! let mut own = CascadeState::default();
//! let expected = x.map(|v| c.process(&mut own, v));
//!
//! let mut p = Split::new(c, CascadeState::default());
//! let mut y = [0.0f32; 6];
//! p.block(&x, &mut y);
//! assert_eq!(y, expected);
//! // The same in place, and the state carries on to the next block.
//! let mut q = Split::new(c, CascadeState::default());
//! let mut xy = x;
//! q.inplace(&mut xy);
//! assert_eq!(xy, expected);
//! assert_eq!(p.state, q.state);
//! # Ok::<(), unlag::board::compensator::InverseError>(())
//! ```

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
    BankChannel, CascadeCoefficients, CascadeState, InverseCoefficients, InverseState,
    NonlinearDampingCoefficients, NonlinearDampingState, Sample, TemperatureBank,
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

/// Implements both traits for a compensator that has a per-sample `process` taking
/// `(&self, &mut State, x)` and no `process_in_place`: a block and an in-place block run
/// `process` sample by sample (over the shorter of input and output).
macro_rules! split_process_per_sample {
    ($(#[$doc:meta])* $sample:ty, $coefficients:ty, $state:ty, [$($generics:tt)*]) => {
        $(#[$doc])*
        impl<$($generics)*> SplitProcess<$sample, $sample, $state> for $coefficients {
            #[inline]
            fn process(&self, state: &mut $state, x: $sample) -> $sample {
                <$coefficients>::process(self, state, x)
            }

            #[inline]
            fn block(&self, state: &mut $state, x: &[$sample], y: &mut [$sample]) {
                for (y, &x) in y.iter_mut().zip(x) {
                    *y = <$coefficients>::process(self, state, x);
                }
            }
        }

        $(#[$doc])*
        impl<$($generics)*> SplitInplace<$sample, $state> for $coefficients {
            #[inline]
            fn inplace(&self, state: &mut $state, xy: &mut [$sample]) {
                for v in xy.iter_mut() {
                    *v = <$coefficients>::process(self, state, *v);
                }
            }
        }
    };
}

split_process_per_sample!(
    /// The nonlinear-damping correction: each probe sample in, the term to add to the linear
    /// compensator's output for the same sample out; in place, each probe sample is replaced
    /// by its term. The same bits as [`NonlinearDampingCoefficients::process`].
    T,
    NonlinearDampingCoefficients<T, N>,
    NonlinearDampingState<T, N>,
    [T: Sample, const N: usize]
);
split_process_per_sample!(
    /// The temperature bank on one channel: each sample through the set the channel is on, and
    /// through the set warming up, if any ([`TemperatureBank::process`], the same bits). The
    /// temperature is not an input here: the processor runs the set in use, and the board
    /// gives the channel the measured temperature between samples or blocks with
    /// [`TemperatureBank::set_temperature`] on the channel (a `Split`'s `state`).
    T,
    TemperatureBank<T, SETS, N>,
    BankChannel<T, N>,
    [T: Sample, const SETS: usize, const N: usize]
);

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
        let mut section = crate::board::fixed::direct::DirectSection::IDENTITY;
        section.neg_a = [1 << 29, 0];
        let c = DirectCascade::<1>::new(&[section]).unwrap();
        let mut p = Split::new(c, DirectState::default());
        let mut own = DirectState::default();
        let x = [5, -7, 1 << 20, 0, 0, 3];
        let mut y = [0; 6];
        p.block(&x, &mut y);
        assert_eq!(y, x.map(|v| c.process(&mut own, v)));
        assert_ne!(y[4], 0, "the pole's memory shows: {y:?}");
        let f = FixedCascade::<1>::new(&[crate::board::fixed::FixedSection::IDENTITY]).unwrap();
        let mut q = Split::new(f, FixedState::default());
        let mut own = FixedState::default();
        for v in [0, 1000, -2000, i32::MAX / 4] {
            assert_eq!(q.process(v), f.process(&mut own, v));
        }
    }

    /// A one-section low-pass for the correction, and a probe signal with steps both ways.
    fn correction() -> (NonlinearDampingCoefficients<f32, 1>, [f32; 10]) {
        let c = NonlinearDampingCoefficients::new(0.3, 0.5, &[[1.0, 0.0, 0.0, -0.5, 0.0]]).unwrap();
        (c, [0.0, 1.0, 1.5, 1.5, -2.0, 0.25, 3.0, 3.0, 0.0, -1.0])
    }

    #[test]
    fn a_split_correction_gives_the_corrections_own_bits() {
        let (c, x) = correction();
        let mut own = c.equilibrium(0.0);
        let expected = x.map(|v| c.process(&mut own, v));
        assert!(
            expected.iter().filter(|&&e| e != 0.0).count() > 5,
            "{expected:?}"
        );
        let mut p = Split::new(c, c.equilibrium(0.0));
        let one_by_one = x.map(|v| p.process(v));
        let mut q = Split::new(c, c.equilibrium(0.0));
        let mut y = [0.0f32; 10];
        q.block(&x, &mut y);
        // In place: each probe sample replaced by its correction term.
        let mut r = Split::new(c, c.equilibrium(0.0));
        let mut xy = x;
        r.inplace(&mut xy);
        for k in 0..x.len() {
            let bits = expected[k].to_bits();
            assert_eq!(one_by_one[k].to_bits(), bits, "process, sample {k}");
            assert_eq!(y[k].to_bits(), bits, "block, sample {k}");
            assert_eq!(xy[k].to_bits(), bits, "inplace, sample {k}");
        }
        // The states end alike, so the next block continues the same.
        assert_eq!((p.state, q.state, r.state), (own, own, own));
        // A block of unequal lengths: over the shorter, the rest of the output untouched.
        let mut s = Split::new(c, c.equilibrium(0.0));
        let mut y = [9.0f32; 4];
        s.block(&x[..2], &mut y);
        assert_eq!(y[..2], expected[..2]);
        assert_eq!(y[2..], [9.0, 9.0]);
    }

    /// Two one-section low-passes at 273 K and 313 K, handed over with a warm-up of `w`.
    fn bank(w: u32) -> TemperatureBank<f32, 2, 1> {
        let sets = [[[0.5, 0.0, 0.0, -0.5, 0.0]], [[0.4, 0.0, 0.0, -0.6, 0.0]]];
        TemperatureBank::new(&[273.0, 313.0], &[1.0, 1.0], &sets, 20.0, w).unwrap()
    }

    #[test]
    fn a_split_bank_gives_the_banks_own_bits_across_a_handover() {
        let x: [f32; 24] = core::array::from_fn(|k| (k as f32 * 0.7).sin() + 1.0);
        // The temperature is set between blocks of 8: warm at the second block, back to cold
        // at the third (a warm-up of 5 finishes inside the second block).
        let temperatures = [273.0, 310.0, 275.0];
        for w in [0, 5] {
            let b = bank(w);
            let mut own = b.channel(273.0, 0.0);
            let mut expected = [0.0f32; 24];
            let mut selected = [0; 3];
            for (i, (block, t)) in expected.chunks_mut(8).zip(temperatures).enumerate() {
                b.set_temperature(&mut own, t);
                for (e, &v) in block.iter_mut().zip(&x[8 * i..]) {
                    *e = b.process(&mut own, v);
                }
                selected[i] = own.selected();
            }
            assert_eq!(selected, [0, 1, 0], "warm-up {w}");
            // Through process, block and inplace, the temperature given to the Split's state.
            let mut p = Split::new(b.clone(), b.channel(273.0, 0.0));
            let mut q = p.clone();
            let mut r = p.clone();
            let (mut one_by_one, mut y, mut xy) = ([0.0f32; 24], [0.0f32; 24], x);
            let blocks = one_by_one
                .chunks_mut(8)
                .zip(y.chunks_mut(8))
                .zip(xy.chunks_mut(8))
                .zip(x.chunks(8).zip(temperatures));
            for (((o, y), xy), (x, t)) in blocks {
                p.config.set_temperature(&mut p.state, t);
                q.config.set_temperature(&mut q.state, t);
                r.config.set_temperature(&mut r.state, t);
                for (o, &v) in o.iter_mut().zip(x) {
                    *o = p.process(v);
                }
                q.block(x, y);
                r.inplace(xy);
            }
            for k in 0..x.len() {
                let bits = expected[k].to_bits();
                assert_eq!(
                    one_by_one[k].to_bits(),
                    bits,
                    "warm-up {w}, process, sample {k}"
                );
                assert_eq!(y[k].to_bits(), bits, "warm-up {w}, block, sample {k}");
                assert_eq!(xy[k].to_bits(), bits, "warm-up {w}, inplace, sample {k}");
            }
            assert_eq!((p.state, q.state, r.state), (own, own, own));
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
