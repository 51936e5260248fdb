//! Board example: the shape of a real DAQ board. An SPI ADC, read through an `embedded-hal` 1.0
//! [`SpiDevice`], feeds the compensator one sample at a time, as an ADC-ready interrupt or a
//! timer task would.
//!
//! ```sh
//! # In QEMU, with a replayed ADC (QEMU has no ADC on the SPI bus), logs over semihosting:
//! cargo run --release --target thumbv7em-none-eabihf --no-default-features --example board_daq
//! # With defmt logging (defmt-rtt; read it with probe-rs on a real board):
//! cargo build --release --target thumbv7em-none-eabihf --no-default-features --features defmt --example board_daq
//! # The driver's unit tests, on the host, against embedded-hal-mock:
//! cargo test --example board_daq
//! ```
//!
//! On a real board, replace [`ReplayAdc`] with your HAL's SPI bus wrapped in a device (for
//! example `embedded_hal_bus::spi::ExclusiveDevice::new(spi, cs, delay)`), and call
//! [`Channel::on_sample`] from the ADC's data-ready interrupt. The coefficients come from
//! `unlag export MODEL.toml --format rust -o src/coefficients.rs`, built in with `include!`.
#![cfg_attr(target_os = "none", no_std, no_main)]

use embedded_hal::spi::SpiDevice;
use unlag::board::compensator::{CascadeCoefficients, CascadeState};

/// Exported by `unlag export examples/data/board_model.toml --format rust`.
mod coefficients {
    #![allow(dead_code)]
    include!("data/board_coefficients.rs");
}

/// Logging shim: defmt with the `defmt` feature on the board, semihosting without it, stdout
/// on the host. Only this macro knows which.
macro_rules! log {
    ($fmt:literal $(, $arg:expr)* $(,)?) => {{
        #[cfg(all(target_os = "none", feature = "defmt"))]
        defmt::info!($fmt $(, $arg)*);
        #[cfg(all(target_os = "none", not(feature = "defmt")))]
        cortex_m_semihosting::hprintln!($fmt $(, $arg)*);
        #[cfg(not(target_os = "none"))]
        println!($fmt $(, $arg)*);
    }};
}

/// The ADC driver's errors.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum AdcError<E> {
    /// The SPI transfer failed.
    Spi(E),
}

impl<E: core::fmt::Debug> core::fmt::Display for AdcError<E> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Spi(e) => write!(f, "SPI transfer failed: {e:?}"),
        }
    }
}

impl<E: core::fmt::Debug> core::error::Error for AdcError<E> {}

/// A 16-bit SPI ADC that clocks out its last conversion as one big-endian two's-complement
/// word while chip select is low (the frame of many 16-bit SAR ADCs; check your part's).
/// Generic over the `embedded-hal` 1.0 [`SpiDevice`], which owns chip select.
#[derive(Debug)]
pub struct SpiAdc16<SPI> {
    spi: SPI,
}

impl<SPI: SpiDevice> SpiAdc16<SPI> {
    /// Wraps an SPI device (mode and clock as the ADC's data sheet says, set on the bus).
    pub fn new(spi: SPI) -> Self {
        Self { spi }
    }

    /// Reads one conversion: one 2-byte frame under chip select.
    ///
    /// # Errors
    /// [`AdcError::Spi`] when the transfer fails.
    pub fn read_raw(&mut self) -> Result<i16, AdcError<SPI::Error>> {
        let mut frame = [0u8; 2];
        self.spi.read(&mut frame).map_err(AdcError::Spi)?;
        Ok(i16::from_be_bytes(frame))
    }

    /// Gives the SPI device back.
    pub fn release(self) -> SPI {
        self.spi
    }
}

/// ADC code to pressure: `p = offset_pa + pa_per_lsb * code`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Scale {
    /// Pressure of code 0, in Pa.
    pub offset_pa: f32,
    /// Pressure of one LSB, in Pa.
    pub pa_per_lsb: f32,
}

impl Scale {
    /// Pressure in Pa of an ADC code.
    #[must_use]
    pub fn pressure_pa(&self, code: i16) -> f32 {
        self.offset_pa + self.pa_per_lsb * f32::from(code)
    }
}

/// One probe channel: the ADC, its scale, the (shared) compensator coefficients and this
/// channel's state.
pub struct Channel<'c, SPI> {
    adc: SpiAdc16<SPI>,
    scale: Scale,
    coefficients: &'c CascadeCoefficients<f32, { coefficients::SECTION_COUNT }>,
    state: CascadeState<f32, { coefficients::SECTION_COUNT }>,
}

impl<'c, SPI: SpiDevice> Channel<'c, SPI> {
    /// A channel whose compensator starts in equilibrium with the pressure `p0_pa`.
    pub fn new(
        adc: SpiAdc16<SPI>,
        scale: Scale,
        coefficients: &'c CascadeCoefficients<f32, { coefficients::SECTION_COUNT }>,
        p0_pa: f32,
    ) -> Self {
        Self {
            adc,
            scale,
            coefficients,
            state: coefficients.equilibrium(p0_pa),
        }
    }

    /// Per sample (data-ready interrupt): read the ADC, scale, compensate. Returns the probe's
    /// pressure and the reconstructed reference, both in Pa.
    ///
    /// # Errors
    /// [`AdcError`] when the ADC cannot be read; the compensator state is then left unchanged.
    pub fn on_sample(&mut self) -> Result<(f32, f32), AdcError<SPI::Error>> {
        let p = self.scale.pressure_pa(self.adc.read_raw()?);
        Ok((p, self.coefficients.process(&mut self.state, p)))
    }
}

/// Stands in for the ADC in QEMU: an [`SpiDevice`] that answers each read with the next code
/// of a recorded trace (the probe column of `examples/data/step_test_2.csv`).
pub struct ReplayAdc {
    codes: core::iter::Cycle<core::slice::Iter<'static, f32>>,
    scale: Scale,
}

impl ReplayAdc {
    /// Replays `samples` (in Pa) as the codes an ADC with `scale` would give.
    pub fn new(samples: &'static [f32], scale: Scale) -> Self {
        Self {
            codes: samples.iter().cycle(),
            scale,
        }
    }

    fn next_code(&mut self) -> i16 {
        let p = self.codes.next().copied().unwrap_or(0.0);
        let code = (p - self.scale.offset_pa) / self.scale.pa_per_lsb;
        // Round to nearest and saturate, as the converter would.
        #[allow(clippy::cast_possible_truncation)]
        let c = (code + if code < 0.0 { -0.5 } else { 0.5 }) as i16;
        c
    }
}

impl embedded_hal::spi::ErrorType for ReplayAdc {
    type Error = core::convert::Infallible;
}

impl SpiDevice for ReplayAdc {
    fn transaction(
        &mut self,
        operations: &mut [embedded_hal::spi::Operation<'_, u8>],
    ) -> Result<(), Self::Error> {
        use embedded_hal::spi::Operation;
        let frame = self.next_code().to_be_bytes();
        for op in operations {
            match op {
                Operation::Read(buf) | Operation::TransferInPlace(buf) => {
                    for (b, f) in buf.iter_mut().zip(frame) {
                        *b = f;
                    }
                }
                Operation::Transfer(read, _) => {
                    for (b, f) in read.iter_mut().zip(frame) {
                        *b = f;
                    }
                }
                Operation::Write(_) | Operation::DelayNs(_) => {}
            }
        }
        Ok(())
    }
}

mod trace {
    include!("data/board_trace.rs");
}

/// The data-acquisition loop: `samples` ADC reads through the compensator, a log line every
/// 128 samples. Returns the number of failed reads.
fn run<SPI: SpiDevice>(spi: SPI, samples: usize) -> usize {
    let coefficients = match CascadeCoefficients::<f32, { coefficients::SECTION_COUNT }>::new(
        coefficients::GAIN,
        &coefficients::SECTIONS,
    ) {
        Ok(c) => c,
        Err(_) => {
            log!("coefficients refused");
            return samples;
        }
    };
    let scale = Scale {
        offset_pa: 0.0,
        pa_per_lsb: 0.05,
    };
    let p0 = trace::TRACE.first().copied().unwrap_or(0.0);
    let mut channel = Channel::new(SpiAdc16::new(spi), scale, &coefficients, p0);
    log!(
        "daq: fs {} Hz, {} sections, latency {} samples",
        coefficients::SAMPLE_RATE_HZ,
        coefficients::SECTION_COUNT,
        coefficients::LATENCY_SAMPLES
    );
    let mut errors = 0usize;
    for k in 0..samples {
        match channel.on_sample() {
            Ok((p, u)) if k % 128 == 0 => log!("k={} probe={} Pa reconstructed={} Pa", k, p, u),
            Ok(_) => {}
            Err(_) => errors = errors.saturating_add(1),
        }
    }
    log!("daq: {} samples, {} read errors", samples, errors);
    errors
}

#[cfg(target_os = "none")]
mod board {
    use cortex_m_rt::entry;
    use cortex_m_semihosting::debug;
    #[cfg(feature = "defmt")]
    use defmt_rtt as _;
    use panic_semihosting as _;

    #[entry]
    fn main() -> ! {
        let spi = super::ReplayAdc::new(
            &super::trace::TRACE,
            super::Scale {
                offset_pa: 0.0,
                pa_per_lsb: 0.05,
            },
        );
        let errors = super::run(spi, super::trace::TRACE.len());
        debug::exit(if errors == 0 {
            debug::EXIT_SUCCESS
        } else {
            debug::EXIT_FAILURE
        });
        #[allow(clippy::empty_loop)]
        loop {}
    }
}

#[cfg(not(target_os = "none"))]
fn main() {
    let spi = ReplayAdc::new(
        &trace::TRACE,
        Scale {
            offset_pa: 0.0,
            pa_per_lsb: 0.05,
        },
    );
    std::process::exit(i32::from(run(spi, trace::TRACE.len()) != 0));
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use embedded_hal::spi::{ErrorKind, ErrorType, Operation};
    use embedded_hal_mock::eh1::spi::{Mock, Transaction};

    fn frame(bytes: [u8; 2]) -> [Transaction<u8>; 3] {
        [
            Transaction::transaction_start(),
            Transaction::read_vec(bytes.to_vec()),
            Transaction::transaction_end(),
        ]
    }

    #[test]
    fn reads_big_endian_twos_complement_frames() {
        let expectations: Vec<_> = [[0x12, 0x34], [0xFF, 0xFE], [0x80, 0x00], [0x7F, 0xFF]]
            .into_iter()
            .flat_map(frame)
            .collect();
        let mut adc = SpiAdc16::new(Mock::new(&expectations));
        assert_eq!(adc.read_raw().unwrap(), 0x1234);
        assert_eq!(adc.read_raw().unwrap(), -2);
        assert_eq!(adc.read_raw().unwrap(), i16::MIN);
        assert_eq!(adc.read_raw().unwrap(), i16::MAX);
        adc.release().done();
    }

    #[test]
    fn channel_compensates_each_sample_like_the_library() {
        let codes: [i16; 6] = [2000, 2000, 16000, 16000, 16000, 16000];
        let expectations: Vec<_> = codes.iter().flat_map(|c| frame(c.to_be_bytes())).collect();
        let coefficients = CascadeCoefficients::<f32, { coefficients::SECTION_COUNT }>::new(
            coefficients::GAIN,
            &coefficients::SECTIONS,
        )
        .unwrap();
        let scale = Scale {
            offset_pa: 10.0,
            pa_per_lsb: 0.05,
        };
        let mut ch = Channel::new(
            SpiAdc16::new(Mock::new(&expectations)),
            scale,
            &coefficients,
            110.0,
        );
        let mut state = coefficients.equilibrium(110.0);
        for c in codes {
            let p = 10.0 + 0.05 * f32::from(c);
            let (got_p, got_u) = ch.on_sample().unwrap();
            assert_eq!(got_p, p);
            assert_eq!(
                got_u.to_bits(),
                coefficients.process(&mut state, p).to_bits()
            );
        }
        ch.adc.release().done();
    }

    /// An SPI device whose every transfer fails.
    struct Broken;
    impl ErrorType for Broken {
        type Error = ErrorKind;
    }
    impl SpiDevice for Broken {
        fn transaction(&mut self, _: &mut [Operation<'_, u8>]) -> Result<(), ErrorKind> {
            Err(ErrorKind::ModeFault)
        }
    }

    #[test]
    fn a_failed_read_is_an_error_and_leaves_the_state_alone() {
        let coefficients = CascadeCoefficients::<f32, { coefficients::SECTION_COUNT }>::new(
            coefficients::GAIN,
            &coefficients::SECTIONS,
        )
        .unwrap();
        let scale = Scale {
            offset_pa: 0.0,
            pa_per_lsb: 1.0,
        };
        let mut ch = Channel::new(SpiAdc16::new(Broken), scale, &coefficients, 5.0);
        let before = ch.state;
        assert_eq!(ch.on_sample(), Err(AdcError::Spi(ErrorKind::ModeFault)));
        assert_eq!(ch.state, before);
        assert_eq!(run(Broken, 3), 3);
    }

    #[test]
    fn replay_adc_reproduces_the_trace_within_one_lsb() {
        let scale = Scale {
            offset_pa: 0.0,
            pa_per_lsb: 0.05,
        };
        let mut adc = SpiAdc16::new(ReplayAdc::new(&trace::TRACE, scale));
        for &p in trace::TRACE.iter().take(64) {
            let got = scale.pressure_pa(adc.read_raw().unwrap());
            assert!((got - p).abs() <= 0.025 + 1e-3, "{got} vs {p}");
        }
    }
}
