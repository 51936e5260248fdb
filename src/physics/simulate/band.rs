//! What a simulated test leaves out of its band: a diaphragm resonance above where the
//! impulse response is tapered, filtered out of the simulated probe, and an internal rate
//! lowered because the response outlasts the longest transform.

use super::{Acquisition, Probe, SimulatedTest};

/// The response outlasts the longest FFT at the oversampling asked for (a slow real pole): the
/// test was simulated at a lower internal rate, its content above the taper tapered off.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReducedRate {
    /// The oversampling asked for.
    pub asked: usize,
    /// The internal rate simulated \[Hz\].
    pub rate_hz: f64,
    /// That rate as a multiple of the sample rate.
    pub achieved: f64,
    /// Where the simulated band's taper starts \[Hz\].
    pub taper_start_hz: f64,
}

/// The probe's diaphragm resonance lies above the simulated band and is filtered out of the
/// test: a higher internal rate (more oversampling) would show it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ResonanceAboveBand {
    /// The diaphragm's natural frequency \[Hz\].
    pub natural_frequency_hz: f64,
    /// Where the simulated band's taper starts \[Hz\].
    pub taper_start_hz: f64,
}

impl SimulatedTest {
    /// The internal rate this test was simulated at when it is below the one `acquisition`
    /// asked for (`oversample` times the sample rate); `None` when the rate asked was kept.
    #[must_use]
    pub fn reduced_rate(&self, acquisition: &Acquisition) -> Option<ReducedRate> {
        let asked = acquisition.sample_rate_hz * acquisition.oversample as f64;
        (self.impulse.rate_hz < asked).then(|| ReducedRate {
            asked: acquisition.oversample,
            rate_hz: self.impulse.rate_hz,
            achieved: self.impulse.rate_hz / acquisition.sample_rate_hz,
            taper_start_hz: self.impulse.taper_start_hz,
        })
    }

    /// The diaphragm resonance of `probe` (the probe this test was simulated with) when it
    /// lies above the start of the impulse response's taper, so that the test does not show
    /// it; `None` without a diaphragm or with it inside the band.
    #[must_use]
    pub fn resonance_above_band(&self, probe: &Probe) -> Option<ResonanceAboveBand> {
        let taper_start_hz = self.impulse.taper_start_hz;
        probe
            .diaphragm
            .filter(|d| d.natural_frequency_hz > taper_start_hz)
            .map(|d| ResonanceAboveBand {
                natural_frequency_hz: d.natural_frequency_hz,
                taper_start_hz,
            })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::physics::simulate::ImpulseResponse;
    use crate::physics::{Diaphragm, Gas, Line};

    /// A test with no samples, simulated at 400 kHz with its taper from 100 kHz.
    fn empty_test() -> SimulatedTest {
        SimulatedTest {
            t: Vec::new(),
            reference: Vec::new(),
            probe: Vec::new(),
            excitation: Vec::new(),
            probe_clean: Vec::new(),
            impulse: ImpulseResponse {
                rate_hz: 400e3,
                taps: Vec::new(),
                fft_length: 0,
                tail_energy: 0.0,
                noncausal_energy: 0.0,
                taper_start_hz: 100e3,
            },
            adc: None,
        }
    }

    /// A diaphragm above the taper's start is named with both frequencies; one below it, or
    /// none, is not.
    #[test]
    fn a_resonance_above_the_taper_is_named() {
        let test = empty_test();
        let mut probe = Probe::new(
            Line::new().tube(0.6, 1.1e-3).volume(20e-9),
            Gas::air(293.15, 101_325.0),
        );
        assert_eq!(test.resonance_above_band(&probe), None);
        probe.diaphragm = Some(Diaphragm::kulite_xcq062());
        assert_eq!(
            test.resonance_above_band(&probe),
            Some(ResonanceAboveBand {
                natural_frequency_hz: 250e3,
                taper_start_hz: 100e3
            })
        );
        probe.diaphragm = Some(Diaphragm {
            natural_frequency_hz: 50e3,
            damping: 0.03,
        });
        assert_eq!(test.resonance_above_band(&probe), None);
    }

    /// The internal rate is named when it fell below the oversampling asked for, not when it
    /// was kept.
    #[test]
    fn a_rate_below_the_one_asked_is_named() {
        let mut acquisition = Acquisition::new(10e3, 0.1);
        acquisition.oversample = 40;
        let test = empty_test();
        assert_eq!(test.reduced_rate(&acquisition), None);
        acquisition.oversample = 64;
        assert_eq!(
            test.reduced_rate(&acquisition),
            Some(ReducedRate {
                asked: 64,
                rate_hz: 400e3,
                achieved: 40.0,
                taper_start_hz: 100e3
            })
        );
    }
}
