//! What a simulated test leaves out of its band: a diaphragm resonance above where the
//! impulse response is tapered, filtered out of the simulated probe.

use super::{Probe, SimulatedTest};

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

    /// A diaphragm above the taper's start is named with both frequencies; one below it, or
    /// none, is not.
    #[test]
    fn a_resonance_above_the_taper_is_named() {
        let test = SimulatedTest {
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
        };
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
}
