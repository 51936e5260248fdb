//! The board's share of the `temperature` effect: a table of compensators, one per gas
//! temperature, and the choice among them by the temperature the board measures.
//!
//! This module owns [`TemperatureBank`] (the coefficient sets with their temperatures, checked
//! once when built), the selection (nearest set, with hysteresis so that a reading wandering
//! around the middle between two sets does not swap back and forth) and the handover of a
//! running channel ([`BankChannel`]) from one set to the next without a jump. The sets are
//! designed on the host (`unlag export MODEL --temperatures FROM:TO:STEP`, see
//! `unlag::effects` (host)): a board cannot redesign the inverse itself.
//!
//! # Selection
//!
//! With temperatures `T0 < T1 < ...` the nearest set changes at the midpoints
//! `(Ti + Ti+1) / 2`. A channel on set `i` leaves it only when the temperature passes a
//! midpoint by more than half the hysteresis `h` (the band of width `h` centred on each
//! midpoint belongs to the set in use); it then takes the nearest set. With `h` half a step
//! (what the export writes), a reading must move a quarter step past the midpoint to swap,
//! and the set in use is never more than three quarters of a step away. Readings outside the
//! table take its end sets; a NaN reading keeps the set in use (a failed thermocouple must
//! not swap the inverse); [`TemperatureBank::nearest`] of NaN is the first set.
//!
//! # Handover
//!
//! Keeping the old state with the new coefficients is wrong: the states of a transposed direct
//! form hold the signal scaled by the coefficients, so the output steps by the coefficient
//! change times the level (on the `temperature` test case, a 293 K to 343 K swap that keeps the
//! state is off by 12 to 86 times the step, depending on when it swaps). Two handovers instead, chosen by the bank's warm-up
//! length `W` (the export writes one from the slowest pole of the sets):
//!
//! * `W > 0` (the default of the export): the new set is warmed up. It starts in its
//!   equilibrium at the last input ([`CascadeCoefficients::equilibrium`]) and runs beside the
//!   old one for `W` samples while the old one still gives the output; then it takes over with
//!   the state it would have had if it had run all along (to the decay of its slowest pole over
//!   `W` samples). Twice the work for `W` samples, no step at all, even in the middle of a
//!   transient.
//! * `W = 0`: at once. Each section's state is split into the equilibrium at the last input and
//!   the deviation from it (the transient in progress); the new set starts in its own
//!   equilibrium plus the same deviation. A steady signal is handed over exactly, whatever its
//!   level; in the middle of a transient the output is disturbed about as much as by a restart
//!   in equilibrium.
//!
//! Everything here is `no_std`, allocation-free and panic-free; the per-sample path is one
//! bounds-checked lookup and [`CascadeCoefficients::process`] (two while a set warms up).
//!
//! ```
//! use unlag::board::compensator::TemperatureBank;
//! // Two one-section sets, at 273 K and 313 K: the hysteresis is half the step.
//! let bank = TemperatureBank::<f32, 2, 1>::new(
//!     &[273.0, 313.0],
//!     &[1.0, 1.0],
//!     &[[[0.5, 0.0, 0.0, -0.5, 0.0]], [[0.6, 0.0, 0.0, -0.4, 0.0]]],
//!     20.0,
//!     0,
//! )
//! .unwrap();
//! let mut ch = bank.channel(280.0, 1.0);
//! assert_eq!(ch.selected(), 0);
//! assert_eq!(bank.process(&mut ch, 1.0), 1.0);
//! // 297 K is past the midpoint (293 K) but inside the hysteresis band: no swap.
//! assert!(!bank.set_temperature(&mut ch, 297.0));
//! // 304 K is past the band: the warm set, handed over without a step.
//! assert!(bank.set_temperature(&mut ch, 304.0));
//! assert!((bank.process(&mut ch, 1.0) - 1.0).abs() < 1e-6);
//! ```

use core::fmt;

use heapless::Vec;

use super::{CascadeCoefficients, CascadeState, InverseError, Sample};

/// Why a temperature bank was refused. Checked once, when the bank is built; a built
/// [`TemperatureBank`] is valid and neither selection nor processing can fail.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum BankError {
    /// No temperature given, or more than the capacity `SETS`.
    SetCount {
        /// Temperatures given.
        given: usize,
        /// The bank's capacity `SETS`.
        capacity: usize,
    },
    /// The gains or the section sets are not as many as the temperatures.
    LengthMismatch {
        /// Temperatures given.
        temperatures: usize,
        /// Gains given.
        gains: usize,
        /// Section sets given.
        sets: usize,
    },
    /// A temperature is not a finite positive number of kelvin in `f32`, or the temperatures
    /// are not strictly ascending.
    Temperatures {
        /// 0-based index of the first offending temperature.
        index: usize,
    },
    /// The hysteresis is not finite, negative, or not smaller than the smallest step.
    Hysteresis,
    /// A set has another number of sections than the first (the sets of one bank must all
    /// have the same shape, so that the state can be handed over section by section).
    SectionCount {
        /// 0-based index of the set.
        index: usize,
        /// Its sections.
        sections: usize,
        /// The first set's sections.
        first: usize,
    },
    /// A set's coefficients were refused ([`CascadeCoefficients::new`]).
    Set {
        /// 0-based index of the set.
        index: usize,
        /// Why.
        error: InverseError,
    },
}

impl fmt::Display for BankError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::SetCount { given, capacity } => write!(
                f,
                "{given} temperatures given for a bank of 1 to {capacity} sets"
            ),
            Self::LengthMismatch {
                temperatures,
                gains,
                sets,
            } => write!(
                f,
                "{temperatures} temperatures, {gains} gains and {sets} section sets: one of each per set"
            ),
            Self::Temperatures { index } => write!(
                f,
                "temperature {index} is not a positive number of kelvin above the one before"
            ),
            Self::Hysteresis => write!(
                f,
                "the hysteresis must be at least 0 K and smaller than the smallest temperature step"
            ),
            Self::SectionCount {
                index,
                sections,
                first,
            } => write!(
                f,
                "set {index} has {sections} sections, the first set {first}: every set of a bank needs the same"
            ),
            Self::Set { index, error } => write!(f, "set {index}: {error}"),
        }
    }
}

impl core::error::Error for BankError {}

/// Up to `SETS` compensators of up to `N` sections (capacities), each for one gas
/// temperature, ascending.
///
/// Built once from the exported tables (see the module docs); shared by any number of
/// channels, each a [`BankChannel`].
#[derive(Debug, Clone, PartialEq)]
pub struct TemperatureBank<T, const SETS: usize, const N: usize> {
    /// The sets' temperatures, ascending: its length is the number of sets in use (1..=SETS).
    temperatures_k: Vec<f32, SETS>,
    /// The sets, the unused capacity filled with identities: the per-sample path indexes a
    /// whole array, its bound a constant (a `heapless::Vec` here costs a load and a register,
    /// 4 instructions per call on a Cortex-M4F, BENCHMARKS.md).
    sets: [CascadeCoefficients<T, N>; SETS],
    hysteresis_k: f32,
    /// Samples a new set runs beside the old one before it takes over (0: at once).
    warm_up: u32,
}

/// One channel running on a [`TemperatureBank`]: the set in use, its state, and the last input
/// sample (the level the handover starts the next set at).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BankChannel<T, const N: usize> {
    selected: usize,
    state: CascadeState<T, N>,
    last_input: T,
    /// The set warming up (`selected` when none).
    pending: usize,
    /// Its state.
    warm: CascadeState<T, N>,
    /// Samples left before it takes over (0: none warming up).
    remaining: u32,
}

impl<T: Sample, const N: usize> BankChannel<T, N> {
    /// Index of the set in use (giving the output).
    #[must_use]
    pub fn selected(&self) -> usize {
        self.selected
    }

    /// Index of the set the channel is going to: the set warming up, else the set in use.
    #[must_use]
    pub fn target(&self) -> usize {
        if self.remaining > 0 {
            self.pending
        } else {
            self.selected
        }
    }

    /// The state of the set in use.
    #[must_use]
    pub fn state(&self) -> &CascadeState<T, N> {
        &self.state
    }
}

#[allow(clippy::cast_possible_truncation)]
fn narrow(x: f64) -> f32 {
    x as f32
}

impl<T: Sample, const SETS: usize, const N: usize> TemperatureBank<T, SETS, N> {
    /// Builds a bank from the exported tables: ascending temperatures (K), the input gain of
    /// each set, each set's sections `[b0, b1, b2, a1, a2]` (the same number in every set, at
    /// most `N`), the hysteresis (K; the export writes half the step), and the warm-up of a
    /// new set in samples (0: hand over at once; see the module docs).
    ///
    /// # Errors
    /// [`BankError`]: no temperature or more than `SETS`, not as many gains and section
    /// sets as temperatures, temperatures not finite,
    /// positive and strictly ascending, a hysteresis not in `[0, smallest step)`, sets of
    /// different section counts, or a set [`CascadeCoefficients::new`] refuses.
    ///
    /// ```
    /// use unlag::board::compensator::{BankError, TemperatureBank};
    ///
    /// let sets = [[[0.5, 0.0, 0.0, -0.5, 0.0]], [[0.6, 0.0, 0.0, -0.4, 0.0]]];
    /// let bank = TemperatureBank::<f32, 2, 1>::new(&[273.0, 313.0], &[1.0, 1.0], &sets, 20.0, 0);
    /// assert!(bank.is_ok());
    /// // Temperatures must ascend, and the hysteresis must be smaller than the step.
    /// assert_eq!(
    ///     TemperatureBank::<f32, 2, 1>::new(&[313.0, 273.0], &[1.0, 1.0], &sets, 20.0, 0).err(),
    ///     Some(BankError::Temperatures { index: 1 })
    /// );
    /// assert_eq!(
    ///     TemperatureBank::<f32, 2, 1>::new(&[273.0, 313.0], &[1.0, 1.0], &sets, 40.0, 0).err(),
    ///     Some(BankError::Hysteresis)
    /// );
    /// // Each set's coefficients are checked as CascadeCoefficients::new checks them.
    /// let unstable = [[[0.5, 0.0, 0.0, -0.5, 0.0]], [[1.0, 0.0, 0.0, -1.0, 0.0]]];
    /// assert!(matches!(
    ///     TemperatureBank::<f32, 2, 1>::new(&[273.0, 313.0], &[1.0, 1.0], &unstable, 20.0, 0),
    ///     Err(BankError::Set { index: 1, .. })
    /// ));
    /// ```
    pub fn new<S: AsRef<[[f64; 5]]>>(
        temperatures_k: &[f64],
        gains: &[f64],
        sections: &[S],
        hysteresis_k: f64,
        warm_up_samples: u32,
    ) -> Result<Self, BankError> {
        let count = temperatures_k.len();
        if count == 0 || count > SETS {
            return Err(BankError::SetCount {
                given: count,
                capacity: SETS,
            });
        }
        if gains.len() != count || sections.len() != count {
            return Err(BankError::LengthMismatch {
                temperatures: count,
                gains: gains.len(),
                sets: sections.len(),
            });
        }
        let mut temps = Vec::<f32, SETS>::new();
        let mut previous = 0.0f32;
        let mut smallest_step = f32::INFINITY;
        for (index, &t) in temperatures_k.iter().enumerate() {
            let t = narrow(t);
            if !(t.is_finite() && t > previous) {
                return Err(BankError::Temperatures { index });
            }
            if index > 0 {
                smallest_step = smallest_step.min(t - previous);
            }
            // Not refused: `count <= SETS` was checked above.
            temps.push(t).map_err(|_| BankError::SetCount {
                given: count,
                capacity: SETS,
            })?;
            previous = t;
        }
        let h = narrow(hysteresis_k);
        if !(h.is_finite() && h >= 0.0 && (count == 1 || h < smallest_step)) {
            return Err(BankError::Hysteresis);
        }
        let identity = CascadeCoefficients::new(1.0, &[])
            .map_err(|error| BankError::Set { index: 0, error })?;
        let mut sets = [identity; SETS];
        let first = sections.first().map_or(0, |s| s.as_ref().len());
        for (index, (dst, (&gain, secs))) in
            sets.iter_mut().zip(gains.iter().zip(sections)).enumerate()
        {
            let secs = secs.as_ref();
            if secs.len() != first {
                return Err(BankError::SectionCount {
                    index,
                    sections: secs.len(),
                    first,
                });
            }
            *dst = CascadeCoefficients::new(gain, secs)
                .map_err(|error| BankError::Set { index, error })?;
        }
        Ok(Self {
            temperatures_k: temps,
            sets,
            hysteresis_k: h,
            warm_up: warm_up_samples,
        })
    }

    /// The temperatures of the sets in use (K), ascending.
    #[must_use]
    pub fn temperatures_k(&self) -> &[f32] {
        &self.temperatures_k
    }

    /// Number of sets in use.
    #[must_use]
    pub fn len(&self) -> usize {
        self.temperatures_k.len()
    }

    /// Always `false`: a bank holds at least one set.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.temperatures_k.is_empty()
    }

    /// The hysteresis (K).
    #[must_use]
    pub fn hysteresis_k(&self) -> f32 {
        self.hysteresis_k
    }

    /// Samples a new set warms up before it takes over (0: at once).
    #[must_use]
    pub fn warm_up_samples(&self) -> u32 {
        self.warm_up
    }

    /// Set `index`'s coefficients, if there is one.
    #[must_use]
    pub fn set(&self, index: usize) -> Option<&CascadeCoefficients<T, N>> {
        self.sets.get(..self.len()).and_then(|s| s.get(index))
    }

    /// The set nearest to `temperature_k`, no hysteresis (a tie goes to the colder set).
    /// Below the table: the first set, above it: the last; NaN: the first.
    #[must_use]
    pub fn nearest(&self, temperature_k: f32) -> usize {
        let used = self.temperatures_k();
        used.iter()
            .zip(used.iter().skip(1))
            .filter(|&(&lo, &hi)| temperature_k > 0.5 * (lo + hi))
            .count()
    }

    /// The set to use at `temperature_k` for a channel now on set `current`: `current` while
    /// the temperature stays within its midpoints widened by half the hysteresis, else the
    /// nearest set. NaN keeps `current` (brought into range).
    #[must_use]
    pub fn select(&self, current: usize, temperature_k: f32) -> usize {
        let current = current.min(self.len().saturating_sub(1));
        if temperature_k.is_nan() {
            return current;
        }
        let half = 0.5 * self.hysteresis_k;
        let used = self.temperatures_k();
        let t = |i: usize| used.get(i).copied();
        let here = t(current).unwrap_or(0.0);
        let below = current
            .checked_sub(1)
            .and_then(t)
            .map_or(f32::NEG_INFINITY, |lo| 0.5 * (lo + here) - half);
        let above = current
            .checked_add(1)
            .and_then(t)
            .map_or(f32::INFINITY, |hi| 0.5 * (here + hi) + half);
        if temperature_k >= below && temperature_k <= above {
            current
        } else {
            self.nearest(temperature_k)
        }
    }

    /// A channel on the set nearest to `temperature_k`, in equilibrium with the input `x0`
    /// (no start-up transient).
    #[must_use]
    pub fn channel(&self, temperature_k: f32, x0: T) -> BankChannel<T, N> {
        let selected = self.nearest(temperature_k);
        BankChannel {
            selected,
            state: self
                .set(selected)
                .map_or_else(CascadeState::default, |c| c.equilibrium(x0)),
            last_input: x0,
            pending: selected,
            warm: CascadeState::default(),
            remaining: 0,
        }
    }

    /// One sample through the channel's set ([`CascadeCoefficients::process`]), and through
    /// the set warming up, if any, which takes over after its last warm-up sample.
    #[inline]
    pub fn process(&self, channel: &mut BankChannel<T, N>, x: T) -> T {
        channel.last_input = x;
        let out = match self.sets.get(channel.selected) {
            Some(c) => c.process(&mut channel.state, x),
            // Not reached: a channel's set is always one of the bank's.
            None => x,
        };
        if channel.remaining > 0 {
            if let Some(c) = self.sets.get(channel.pending) {
                c.process(&mut channel.warm, x);
            }
            channel.remaining -= 1;
            if channel.remaining == 0 {
                channel.selected = channel.pending;
                channel.state = channel.warm;
            }
        }
        out
    }

    /// Gives the channel the gas temperature just measured (K), between two samples: selects
    /// with hysteresis ([`Self::select`], from [`BankChannel::target`]) and, when the set
    /// changes, starts the handover (see the module docs): at once, or by warming the new set
    /// up (a reading back to the set in use cancels a warm-up). Returns whether the target set
    /// changed. Allocation-free and panic-free.
    pub fn set_temperature(&self, channel: &mut BankChannel<T, N>, temperature_k: f32) -> bool {
        let target = channel.target();
        let next = self.select(target, temperature_k);
        if next == target {
            return false;
        }
        if next == channel.selected {
            channel.remaining = 0;
            channel.pending = next;
            return true;
        }
        let (Some(old), Some(new)) = (self.set(channel.selected), self.set(next)) else {
            return false;
        };
        if self.warm_up == 0 {
            channel.state = handover(old, new, &channel.state, channel.last_input);
            channel.selected = next;
            channel.pending = next;
        } else {
            channel.warm = new.equilibrium(channel.last_input);
            channel.pending = next;
            channel.remaining = self.warm_up;
        }
        true
    }
}

/// The state of `new` equivalent to `state` of `old` after the input `level`: `new`'s
/// equilibrium at `level` plus the deviation of `state` from `old`'s.
fn handover<T: Sample, const N: usize>(
    old: &CascadeCoefficients<T, N>,
    new: &CascadeCoefficients<T, N>,
    state: &CascadeState<T, N>,
    level: T,
) -> CascadeState<T, N> {
    let from = old.equilibrium(level);
    let mut to = new.equilibrium(level);
    let pairs = to.s1.iter_mut().zip(state.s1.iter().zip(&from.s1));
    for (dst, (&s, &e)) in pairs.chain(to.s2.iter_mut().zip(state.s2.iter().zip(&from.s2))) {
        *dst = *dst + (s - e);
    }
    to
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Five one-section low-passes, DC gain 1, at 253..=333 K by 20 K; pole at 0.5 + i/10.
    fn bank(h: f64) -> TemperatureBank<f64, 5, 2> {
        let sections: std::vec::Vec<[[f64; 5]; 1]> = (0..5)
            .map(|i| {
                let p = 0.5 + f64::from(i) / 10.0;
                [[1.0 - p, 0.0, 0.0, -p, 0.0]]
            })
            .collect();
        TemperatureBank::new(
            &[253.0, 273.0, 293.0, 313.0, 333.0],
            &[1.0; 5],
            &sections,
            h,
            0,
        )
        .unwrap()
    }

    #[test]
    fn nearest_clamps_and_takes_the_colder_set_on_a_tie() {
        let b = bank(10.0);
        assert_eq!(b.nearest(100.0), 0);
        assert_eq!(b.nearest(f32::NEG_INFINITY), 0);
        assert_eq!(b.nearest(262.9), 0);
        assert_eq!(b.nearest(263.0), 0);
        assert_eq!(b.nearest(263.1), 1);
        assert_eq!(b.nearest(300.0), 2);
        assert_eq!(b.nearest(333.0), 4);
        assert_eq!(b.nearest(1.0e9), 4);
        assert_eq!(b.nearest(f32::INFINITY), 4);
        assert_eq!(b.nearest(f32::NAN), 0);
    }

    #[test]
    fn hysteresis_holds_a_set_a_quarter_step_past_the_midpoint() {
        let b = bank(10.0);
        // On set 2 (293 K): midpoints 283 and 303, band +-5 K.
        assert_eq!(b.select(2, 307.9), 2);
        assert_eq!(b.select(2, 308.1), 3);
        assert_eq!(b.select(2, 278.1), 2);
        assert_eq!(b.select(2, 277.9), 1);
        // Back from set 3 to set 2 needs 303 - 5 = 298 K: a reading wandering around the
        // midpoint 303 K does not chatter.
        let mut s = 2;
        let mut swaps = 0;
        for k in 0..100 {
            let t = 303.0 + if k % 2 == 0 { 4.5 } else { -4.5 };
            let n = b.select(s, t);
            swaps += usize::from(n != s);
            s = n;
        }
        assert_eq!((s, swaps), (2, 0));
        // Without hysteresis the same readings swap every time.
        let b0 = bank(0.0);
        let mut s = 2;
        let mut swaps = 0;
        for k in 0..100 {
            let t = 303.0 + if k % 2 == 0 { 4.5 } else { -4.5 };
            let n = b0.select(s, t);
            swaps += usize::from(n != s);
            s = n;
        }
        assert_eq!(swaps, 100);
        // A big jump goes straight to the nearest set, and out of range to the ends.
        assert_eq!(b.select(0, 330.0), 4);
        assert_eq!(b.select(4, -5.0), 0);
        assert_eq!(b.select(1, f32::INFINITY), 4);
    }

    #[test]
    fn nan_keeps_the_set_and_a_stale_index_is_brought_into_range() {
        let b = bank(10.0);
        assert_eq!(b.select(3, f32::NAN), 3);
        assert_eq!(b.select(99, f32::NAN), 4);
        assert_eq!(b.select(99, 250.0), 0);
        let mut ch = b.channel(313.0, 2.0);
        assert!(!b.set_temperature(&mut ch, f32::NAN));
        assert_eq!(ch.selected(), 3);
        // A NaN sample does not panic either.
        assert!(b.process(&mut ch, f64::NAN).is_nan());
    }

    #[test]
    fn a_steady_level_is_handed_over_without_a_step() {
        let b = bank(10.0);
        let level = 1.0e5; // an absolute pressure, Pa
        let mut ch = b.channel(253.0, level);
        for _ in 0..10 {
            assert!((b.process(&mut ch, level) - level).abs() < 1e-9);
        }
        for (t, set) in [(313.0, 3), (333.0, 4), (253.0, 0)] {
            assert!(b.set_temperature(&mut ch, t));
            assert_eq!(ch.selected(), set);
            for _ in 0..10 {
                let out = b.process(&mut ch, level);
                assert!((out - level).abs() < 1e-9, "{t} K: {out}");
            }
        }
        // Keeping the old state instead steps by the coefficient change times the level.
        let mut st = b.set(0).unwrap().equilibrium(level);
        let kept = b.set(4).unwrap().process(&mut st, level);
        assert!((kept - level).abs() > 1.0e3, "{kept}");
    }

    #[test]
    fn a_transient_keeps_its_memory_through_the_handover() {
        // A step from 0 to 1 at k = 0; swap from set 0 (pole 0.5) to set 1 (pole 0.6) at k = 3.
        let b = bank(10.0);
        let mut ch = b.channel(253.0, 0.0);
        let mut out = [0.0; 8];
        for (k, o) in out.iter_mut().enumerate() {
            if k == 3 {
                assert!(b.set_temperature(&mut ch, 280.0));
            }
            *o = b.process(&mut ch, 1.0);
        }
        // Set 0's step response is 1 - 0.5^(k+1): 0.875 at k = 2. The carried deviation is
        // what set 0 would have left at k = 3 (error 0.0625), which then decays by set 1's
        // pole 0.6. Keeping the raw state would dip to 0.4375 + 0.4 = 0.8375; restarting in
        // equilibrium would jump to 1.
        assert!((out[2] - 0.875).abs() < 1e-12);
        for (k, &o) in out.iter().enumerate().skip(3) {
            let expected = 1.0 - 0.0625 * 0.6f64.powi(i32::try_from(k - 3).unwrap());
            assert!((o - expected).abs() < 1e-12, "{k}: {o} vs {expected}");
        }
    }

    #[test]
    fn a_bank_below_its_capacity_uses_only_its_sets() {
        let s = [[[0.5, 0.0, 0.0, -0.5, 0.0]], [[0.6, 0.0, 0.0, -0.4, 0.0]]];
        let b =
            TemperatureBank::<f32, 8, 2>::new(&[273.0, 293.0], &[1.0, 1.0], &s, 5.0, 0).unwrap();
        assert_eq!((b.len(), b.temperatures_k()), (2, &[273.0f32, 293.0][..]));
        assert_eq!(b.nearest(1.0e6), 1);
        assert_eq!(b.select(7, 1.0e6), 1);
        assert_eq!(b.select(7, f32::NAN), 1);
        assert!(b.set(2).is_none());
        let one = TemperatureBank::<f32, 4, 1>::new(&[300.0], &[2.0], &s[..1], 100.0, 0).unwrap();
        assert_eq!((one.nearest(10.0), one.select(0, 1.0e9)), (0, 0));
        let mut ch = one.channel(f32::NAN, 1.0);
        assert!(!one.set_temperature(&mut ch, 250.0));
        assert!((one.process(&mut ch, 1.0) - 2.0).abs() < 1e-6);
    }

    #[test]
    fn a_warmed_up_set_takes_over_as_if_it_had_run_all_along() {
        // Set 0 (pole 0.5) to set 1 (pole 0.6) during a step, with 40 samples of warm-up.
        let sections = [[[0.5, 0.0, 0.0, -0.5, 0.0]], [[0.4, 0.0, 0.0, -0.6, 0.0]]];
        let b = TemperatureBank::<f64, 2, 1>::new(&[273.0, 293.0], &[1.0; 2], &sections, 5.0, 40)
            .unwrap();
        let input = |k: usize| {
            if k < 3 {
                0.0
            } else {
                1.0 + 0.1 * (k as f64).sin()
            }
        };
        let alone = |set: usize| {
            let c = b.set(set).unwrap();
            let mut st = c.equilibrium(0.0);
            (0..100)
                .map(|k| c.process(&mut st, input(k)))
                .collect::<std::vec::Vec<_>>()
        };
        let (cold, warm) = (alone(0), alone(1));
        let mut ch = b.channel(273.0, 0.0);
        for k in 0..100 {
            if k == 5 {
                assert!(b.set_temperature(&mut ch, 300.0));
                assert_eq!((ch.selected(), ch.target()), (0, 1));
                // The same reading again changes nothing.
                assert!(!b.set_temperature(&mut ch, 300.0));
            }
            let out = b.process(&mut ch, input(k));
            if k < 45 {
                assert_eq!(out, cold[k], "{k}");
            } else {
                assert_eq!(ch.selected(), 1);
                // 0.6^40 of the start's error is left.
                assert!((out - warm[k]).abs() < 1e-8, "{k}: {out} vs {}", warm[k]);
            }
        }
        // A reading back to the set in use cancels a warm-up.
        let mut ch = b.channel(273.0, 0.0);
        assert!(b.set_temperature(&mut ch, 300.0));
        assert!(b.set_temperature(&mut ch, 270.0));
        for (k, &c) in cold.iter().enumerate().take(60) {
            assert_eq!(b.process(&mut ch, input(k)), c);
        }
        assert_eq!((ch.selected(), ch.target()), (0, 0));
    }

    #[test]
    fn refuses_bad_tables() {
        let s = [[[0.5, 0.0, 0.0, -0.5, 0.0]]; 2];
        let new = |t: &[f64], h: f64| TemperatureBank::<f32, 2, 1>::new(t, &[1.0, 1.0], &s, h, 0);
        assert!(new(&[273.0, 293.0], 5.0).is_ok());
        assert_eq!(
            new(&[273.0], 5.0),
            Err(BankError::LengthMismatch {
                temperatures: 1,
                gains: 2,
                sets: 2
            })
        );
        assert_eq!(
            TemperatureBank::<f32, 1, 1>::new(&[273.0, 293.0], &[1.0, 1.0], &s, 5.0, 0),
            Err(BankError::SetCount {
                given: 2,
                capacity: 1
            })
        );
        assert_eq!(
            new(&[293.0, 273.0], 5.0),
            Err(BankError::Temperatures { index: 1 })
        );
        assert_eq!(
            new(&[f64::NAN, 273.0], 5.0),
            Err(BankError::Temperatures { index: 0 })
        );
        assert_eq!(
            new(&[-1.0, 273.0], 5.0),
            Err(BankError::Temperatures { index: 0 })
        );
        assert_eq!(new(&[273.0, 293.0], 20.0), Err(BankError::Hysteresis));
        assert_eq!(new(&[273.0, 293.0], f64::NAN), Err(BankError::Hysteresis));
        assert_eq!(new(&[273.0, 293.0], -1.0), Err(BankError::Hysteresis));
        let mixed: [&[[f64; 5]]; 2] = [&[[0.5, 0.0, 0.0, -0.5, 0.0]], &[]];
        assert_eq!(
            TemperatureBank::<f32, 2, 1>::new(&[273.0, 293.0], &[1.0, 1.0], &mixed, 5.0, 0),
            Err(BankError::SectionCount {
                index: 1,
                sections: 0,
                first: 1
            })
        );
        let unstable = [[[1.0, 0.0, 0.0, -1.0, 0.0]]; 2];
        assert!(matches!(
            TemperatureBank::<f32, 2, 1>::new(&[273.0, 293.0], &[1.0, 1.0], &unstable, 5.0, 0),
            Err(BankError::Set { index: 0, .. })
        ));
        assert!(matches!(
            TemperatureBank::<f32, 0, 1>::new(&[], &[], &[] as &[[[f64; 5]; 1]], 0.0, 0),
            Err(BankError::SetCount { .. })
        ));
    }
}
