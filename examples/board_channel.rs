//! Board example: the complete code of a probe channel as a firmware engineer writes it.
//! docs/firmware.md walks through it.
//!
//! ```sh
//! # In QEMU (Cortex-M4F, mps2-an386), through the runner in .cargo/config.toml:
//! cargo run --release --target thumbv7em-none-eabihf --no-default-features --example board_channel
//! # The same code on the host, same checks:
//! cargo run --release --example board_channel
//! ```
//!
//! What it shows, in this order:
//! * start-up: the exported coefficients (`unlag export --format rust`, built in with
//!   `include!`) checked once, each channel started in equilibrium with its first reading;
//! * the per-sample call in an ADC interrupt handler: on the board, SysTick at the sample rate
//!   stands in for the ADC's data-ready interrupt (QEMU has no ADC);
//! * the DMA half-buffer callback: a block of interleaved readings, one `process_in_place`
//!   per channel;
//! * three channels sharing one set of coefficients, each with its own state;
//! * the fixed-point variant: readings to codes with `AdcInput`, the clamp count, the overflow
//!   flag;
//! * swapping the coefficients at run time from a received blob (`unlag export --format bin`).
//!
//! The ADC is synthetic: a 16-bit converter reading +-1250 Pa, fed with a recorded probe trace
//! (`examples/data/board_trace.rs`, a falling pressure step) on three channels at different
//! levels. The run checks that the interrupt path and the DMA path give the same bits, that the
//! fixed-point channels agree with the `f32` ones and count their clamped readings, and that a
//! damaged blob is refused and an intact one taken. It prints a few lines and `DONE ok`, and
//! exits 0 (semihosting on the board), 1 when a check fails.
#![cfg_attr(target_os = "none", no_std, no_main)]

use core::fmt::Write;

use unlag::board::blob::{self, BlobError};
use unlag::board::compensator::{CascadeCoefficients, CascadeState, InverseError};
use unlag::board::fixed::input::{AdcInput, InputError};
use unlag::board::fixed::{FixedCascade, FixedError, FixedState};

/// The `f32` compensator, as `unlag export probe.toml --format rust -o src/coefficients.rs`
/// writes it.
mod coefficients {
    #![allow(dead_code)]
    include!("data/board_coefficients.rs");
}

/// The fixed-point compensator of the same design, planned for a full scale of +-1000 Pa. Its
/// `SECTIONS_M8`, `OUTPUT_EXPONENT_M8` and `FULL_SCALE` are what `unlag export probe.toml
/// --format rust --number-format fixed` writes as `SECTIONS`, `OUTPUT_EXPONENT` and
/// `FULL_SCALE`.
mod fixed_plan {
    #![allow(dead_code)]
    include!("data/board_fixed.rs");
}

/// A coefficient set as it arrives over a serial link: `unlag export probe.toml --format bin`.
static RECEIVED_BLOB: &[u8] = include_bytes!("data/board_coefficients.bin");

/// The recorded probe trace the synthetic ADC plays.
mod trace {
    include!("data/board_trace.rs");
}

// ---- The board -------------------------------------------------------------------------------

/// Probe channels on this board.
pub const CHANNELS: usize = 3;
/// Sections the compensator has room for: the exported `SECTION_COUNT`.
pub const SECTIONS: usize = coefficients::SECTION_COUNT;
/// The ADC's width in bits (two's complement).
pub const ADC_BITS: u32 = 16;
/// The ADC reads +-`ADC_RANGE_PA`.
pub const ADC_RANGE_PA: f32 = 1250.0;
/// Pressure of one ADC step.
pub const PA_PER_LSB: f32 = ADC_RANGE_PA / 32768.0;
/// Samples per channel in one half of the DMA buffer.
pub const HALF: usize = 64;

/// An ADC reading in Pa.
#[must_use]
pub fn pressure_pa(reading: i16) -> f32 {
    f32::from(reading) * PA_PER_LSB
}

// ---- f32: coefficients shared, one state per channel ---------------------------------------

/// The compensation of every channel: one set of coefficients, shared, and one state per
/// channel. Build it at start-up; call [`Compensation::on_sample`] from the ADC interrupt, or
/// [`Compensation::on_dma_half`] from the DMA callback.
pub struct Compensation {
    coefficients: CascadeCoefficients<f32, SECTIONS>,
    states: [CascadeState<f32, SECTIONS>; CHANNELS],
    /// Each channel's last reading, to restart from after a coefficient swap.
    last: [f32; CHANNELS],
}

impl Compensation {
    /// Start-up: checks the exported coefficients once (a set that passes can no longer fail
    /// per sample) and starts each channel in equilibrium with its first reading, so there is
    /// no start-up transient.
    ///
    /// # Errors
    /// [`InverseError`] when the coefficients are refused (exported ones never are).
    pub fn new(first_pa: [f32; CHANNELS]) -> Result<Self, InverseError> {
        let coefficients = CascadeCoefficients::new(coefficients::GAIN, &coefficients::SECTIONS)?;
        Ok(Self {
            states: first_pa.map(|p| coefficients.equilibrium(p)),
            coefficients,
            last: first_pa,
        })
    }

    /// ADC interrupt: one reading per channel in (Pa), the reconstructed pressure per channel
    /// out. About 30 instructions per channel with 4 sections on a Cortex-M4F (bench/board.sh).
    pub fn on_sample(&mut self, readings_pa: [f32; CHANNELS]) -> [f32; CHANNELS] {
        let mut out = [0.0; CHANNELS];
        for ((u, state), p) in out.iter_mut().zip(&mut self.states).zip(readings_pa) {
            *u = self.coefficients.process(state, p);
        }
        self.last = readings_pa;
        out
    }

    /// DMA callback (half transfer, or transfer complete): `raw` is the half of the circular
    /// buffer the DMA has just filled, the channels interleaved as a scanning ADC writes them
    /// (`ch0 ch1 ch2 ch0 ch1 ch2 ...`). Each channel's block is converted to Pa and compensated
    /// in place into `out`: the same bits as [`Self::on_sample`] sample by sample, in fewer
    /// instructions (the coefficients and the state stay in registers over the block).
    pub fn on_dma_half(&mut self, raw: &[i16; HALF * CHANNELS], out: &mut [[f32; HALF]; CHANNELS]) {
        let channels = out.iter_mut().zip(&mut self.states).zip(&mut self.last);
        for (c, ((block, state), last)) in channels.enumerate() {
            for (p, frame) in block.iter_mut().zip(raw.chunks_exact(CHANNELS)) {
                *p = pressure_pa(frame.get(c).copied().unwrap_or(0));
            }
            *last = block.last().copied().unwrap_or(*last);
            self.coefficients.process_in_place(state, block);
        }
    }

    /// A coefficient blob received (serial link, CAN, ...), between two samples or two DMA
    /// blocks. Parsed and checked whole: on any error nothing changes and the running set goes
    /// on. When it is taken, each channel restarts in equilibrium with its last reading (the
    /// old states belong to the old coefficients).
    ///
    /// # Errors
    /// [`SwapError::Blob`] for a damaged, truncated or incompatible blob, and
    /// [`SwapError::SampleRate`] for one designed for another sample rate.
    pub fn receive(&mut self, bytes: &[u8]) -> Result<(), SwapError> {
        let set = blob::parse::<SECTIONS>(bytes).map_err(SwapError::Blob)?;
        if set.sample_rate_hz != coefficients::SAMPLE_RATE_HZ {
            return Err(SwapError::SampleRate {
                hz: set.sample_rate_hz,
            });
        }
        self.coefficients = set.cascade;
        for (state, &p) in self.states.iter_mut().zip(&self.last) {
            *state = self.coefficients.equilibrium(p);
        }
        Ok(())
    }
}

/// Why a received coefficient blob was not taken.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub enum SwapError {
    /// The blob was refused by `unlag::board::blob::parse`.
    Blob(BlobError),
    /// The blob is valid but for another sample rate than this board's ADC runs at.
    SampleRate {
        /// The blob's sample rate in Hz.
        hz: f64,
    },
}

impl core::fmt::Display for SwapError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Blob(e) => write!(f, "blob refused: {e}"),
            Self::SampleRate { hz } => write!(f, "blob for {hz} Hz, not this board's rate"),
        }
    }
}

// ---- Fixed point: the same channels without an FPU ------------------------------------------

/// The fixed-point compensation of every channel: readings to Q1.31 codes of the plan's full
/// scale ([`AdcInput`]), one shared cascade, one state per channel, and per channel the count
/// of readings clamped to the plan's range and of blocks that overflowed.
pub struct FixedCompensation {
    input: AdcInput,
    cascade: FixedCascade<SECTIONS>,
    states: [FixedState<SECTIONS>; CHANNELS],
    /// Readings beyond the plan's full scale, per channel (saturated to it).
    pub clamped: [u32; CHANNELS],
    /// Blocks in which a state or an output saturated, per channel.
    pub overflowed_blocks: [u32; CHANNELS],
}

/// Why the fixed-point compensation could not be built.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub enum FixedSetupError {
    /// The ADC's range does not suit the plan's full scale.
    Input(InputError),
    /// The sections were refused.
    Sections(FixedError),
}

impl FixedCompensation {
    /// Start-up. The plan was made for +-`fixed_plan::FULL_SCALE` (1000 Pa) and this ADC reads
    /// +-1250 Pa, so readings beyond 1000 Pa clamp and are counted. Export with the ADC's range
    /// (`--full-scale 1250`) and nothing can clamp: `AdcInput::matching(ADC_BITS)` then does
    /// the same with a shift alone.
    ///
    /// # Errors
    /// [`FixedSetupError`] when the ADC's range or the sections are refused.
    pub fn new(first: [i16; CHANNELS]) -> Result<Self, FixedSetupError> {
        let input = AdcInput::new(ADC_BITS, f64::from(ADC_RANGE_PA), fixed_plan::FULL_SCALE)
            .map_err(FixedSetupError::Input)?;
        let cascade =
            FixedCascade::new(&fixed_plan::SECTIONS_M8).map_err(FixedSetupError::Sections)?;
        Ok(Self {
            states: first.map(|r| cascade.equilibrium(input.code(i32::from(r)).0)),
            input,
            cascade,
            clamped: [0; CHANNELS],
            overflowed_blocks: [0; CHANNELS],
        })
    }

    /// ADC interrupt, fixed point: one reading per channel in, one output code per channel
    /// out (Q1.31 of `FULL_SCALE * 2^OUTPUT_EXPONENT`, see [`output_pa`]).
    pub fn on_sample(&mut self, readings: [i16; CHANNELS]) -> [i32; CHANNELS] {
        let mut out = [0; CHANNELS];
        let channels = out.iter_mut().zip(&mut self.states).zip(&mut self.clamped);
        for (((y, state), clamped), r) in channels.zip(readings) {
            let (code, was_clamped) = self.input.code(i32::from(r));
            *clamped = clamped.saturating_add(u32::from(was_clamped));
            *y = self.cascade.process(state, code);
        }
        out
    }

    /// DMA callback, fixed point: as [`Compensation::on_dma_half`], with the readings turned
    /// into codes a block at a time (counting the clamped ones) and the overflow flag read once
    /// per block.
    pub fn on_dma_half(&mut self, raw: &[i16; HALF * CHANNELS], out: &mut [[i32; HALF]; CHANNELS]) {
        let channels = out
            .iter_mut()
            .zip(&mut self.states)
            .zip(self.clamped.iter_mut().zip(&mut self.overflowed_blocks));
        for (c, ((block, state), (clamped, overflowed))) in channels.enumerate() {
            let mut readings = [0i32; HALF];
            for (r, frame) in readings.iter_mut().zip(raw.chunks_exact(CHANNELS)) {
                *r = i32::from(frame.get(c).copied().unwrap_or(0));
            }
            *clamped = clamped.saturating_add(self.input.block(&readings, block));
            self.cascade.process_in_place(state, block);
            *overflowed = overflowed.saturating_add(u32::from(state.take_overflow()));
        }
    }
}

/// A fixed-point output code in Pa: Q1.31 of `FULL_SCALE * 2^OUTPUT_EXPONENT`.
#[must_use]
pub fn output_pa(code: i32) -> f32 {
    let unit = fixed_plan::FULL_SCALE * libm::exp2(f64::from(fixed_plan::OUTPUT_EXPONENT_M8));
    (f64::from(code) / 2_147_483_648.0 * unit) as f32
}

// ---- The synthetic ADC ------------------------------------------------------------------------

/// Samples per channel in one run: the recorded trace.
pub const SAMPLES: usize = trace::TRACE.len();

/// Each channel's level above the recorded probe: channel 2 reads up to about 1050 Pa, beyond
/// the fixed-point plan's 1000 Pa (and inside the ADC's 1250 Pa).
const OFFSETS_PA: [f32; CHANNELS] = [0.0, -300.0, 250.0];

/// Stands in for a scanning 16-bit ADC: frame `k` holds the recorded probe's sample `k` on
/// every channel, each at its level, rounded to the ADC's steps; after the trace it holds the
/// last sample.
#[derive(Debug, Clone, Default)]
pub struct SyntheticAdc {
    k: usize,
}

impl SyntheticAdc {
    /// Frame `k`, without moving on.
    #[must_use]
    pub fn frame(k: usize) -> [i16; CHANNELS] {
        let last = trace::TRACE.last().copied().unwrap_or(0.0);
        let p = trace::TRACE.get(k).copied().unwrap_or(last);
        OFFSETS_PA.map(|offset| {
            // `as` saturates at the ADC's ends, as the converter does.
            libm::roundf((p + offset) / PA_PER_LSB) as i16
        })
    }

    /// The next frame: one reading per channel.
    pub fn read(&mut self) -> [i16; CHANNELS] {
        let f = Self::frame(self.k);
        self.k = self.k.saturating_add(1);
        f
    }

    /// The next half buffer, as the DMA writes it: `HALF` frames, channels interleaved.
    pub fn fill(&mut self, half: &mut [i16; HALF * CHANNELS]) {
        for frame in half.chunks_exact_mut(CHANNELS) {
            frame.copy_from_slice(&self.read());
        }
    }
}

// ---- The interrupt-driven run -----------------------------------------------------------------

/// What the ADC interrupt owns: the compensation, the ADC, and where the outputs go.
pub struct IsrRun {
    compensation: Compensation,
    fixed: FixedCompensation,
    adc: SyntheticAdc,
    k: usize,
    /// The reconstructed pressure, per channel and sample.
    pub out: [[f32; SAMPLES]; CHANNELS],
    /// The fixed-point output codes, per channel and sample.
    pub out_fixed: [[i32; SAMPLES]; CHANNELS],
}

impl IsrRun {
    /// The interrupt handler's body: read one frame, compensate every channel, store.
    pub fn on_adc_ready(&mut self) {
        if self.done() {
            return;
        }
        let raw = self.adc.read();
        let u = self.compensation.on_sample(raw.map(pressure_pa));
        let y = self.fixed.on_sample(raw);
        let dst = self.out.iter_mut().zip(&mut self.out_fixed);
        for (((o, of), u), y) in dst.zip(u).zip(y) {
            if let (Some(o), Some(of)) = (o.get_mut(self.k), of.get_mut(self.k)) {
                *o = u;
                *of = y;
            }
        }
        self.k = self.k.saturating_add(1);
    }

    /// Whether every sample has been taken.
    #[must_use]
    pub fn done(&self) -> bool {
        self.k >= SAMPLES
    }
}

/// The start-up of the interrupt-driven run: both compensations started on the first frame.
fn start() -> Option<IsrRun> {
    let first = SyntheticAdc::frame(0);
    Some(IsrRun {
        compensation: Compensation::new(first.map(pressure_pa)).ok()?,
        fixed: FixedCompensation::new(first).ok()?,
        adc: SyntheticAdc::default(),
        k: 0,
        out: [[0.0; SAMPLES]; CHANNELS],
        out_fixed: [[0; SAMPLES]; CHANNELS],
    })
}

// ---- The checks -------------------------------------------------------------------------------

/// How far the fixed-point output may stray from the `f32` one on a channel that never
/// clamped, in Pa (0.005 % of the plan's 1000 Pa; the two differ by rounding only).
const FIXED_TOLERANCE_PA: f32 = 0.05;

/// Runs everything after the interrupt-driven run `isr` (one frame per interrupt), writing a
/// report to `out`; `Ok(true)` when every check passed.
fn check(out: &mut impl Write, isr: &IsrRun) -> Result<bool, core::fmt::Error> {
    let mut ok = true;
    writeln!(
        out,
        "channel: {CHANNELS} channels, {SECTIONS} sections, fs {} Hz, {SAMPLES} samples each",
        coefficients::SAMPLE_RATE_HZ
    )?;

    // The DMA path on the same feed: the same bits as the interrupt path.
    let first = SyntheticAdc::frame(0);
    let (Ok(mut compensation), Ok(mut fixed)) = (
        Compensation::new(first.map(pressure_pa)),
        FixedCompensation::new(first),
    ) else {
        writeln!(out, "ERROR coefficients refused")?;
        return Ok(false);
    };
    let mut adc = SyntheticAdc::default();
    let mut raw = [0i16; HALF * CHANNELS];
    let mut block = [[0.0f32; HALF]; CHANNELS];
    let mut block_fixed = [[0i32; HALF]; CHANNELS];
    let (mut differ, mut differ_fixed) = (0usize, 0usize);
    let mut worst = [0.0f32; CHANNELS];
    for start in (0..SAMPLES).step_by(HALF) {
        adc.fill(&mut raw);
        compensation.on_dma_half(&raw, &mut block);
        fixed.on_dma_half(&raw, &mut block_fixed);
        let per_channel = block
            .iter()
            .zip(&block_fixed)
            .zip(&isr.out)
            .zip(&isr.out_fixed);
        for (c, (((b, bf), o), of)) in per_channel.enumerate() {
            let o = o.get(start..).unwrap_or(&[]);
            let of = of.get(start..).unwrap_or(&[]);
            differ += b
                .iter()
                .zip(o)
                .filter(|(x, y)| x.to_bits() != y.to_bits())
                .count();
            differ_fixed += bf.iter().zip(of).filter(|(x, y)| x != y).count();
            // Fixed point against f32 (compared below only where nothing clamped).
            if let Some(w) = worst.get_mut(c) {
                for (&u, &y) in b.iter().zip(bf) {
                    *w = w.max((output_pa(y) - u).abs());
                }
            }
        }
    }
    writeln!(
        out,
        "DMA blocks of {HALF}: {differ} f32 and {differ_fixed} fixed-point outputs differ from the interrupt path"
    )?;
    ok &= differ == 0 && differ_fixed == 0;

    // The clamp count: exactly the readings beyond the plan's full scale.
    for c in 0..CHANNELS {
        let beyond = (0..SAMPLES)
            .filter(|&k| {
                let p = pressure_pa(SyntheticAdc::frame(k).get(c).copied().unwrap_or(0));
                p.abs() > fixed_plan::FULL_SCALE as f32
            })
            .count();
        let clamped = fixed.clamped.get(c).copied().unwrap_or(0);
        let isr_clamped = isr.fixed.clamped.get(c).copied().unwrap_or(0);
        let overflowed = fixed.overflowed_blocks.get(c).copied().unwrap_or(0);
        let w = worst.get(c).copied().unwrap_or(f32::INFINITY);
        write!(
            out,
            "fixed ch{c}: {clamped} readings clamped (beyond +-{} Pa: {beyond}), {overflowed} blocks overflowed",
            fixed_plan::FULL_SCALE
        )?;
        ok &= clamped as usize == beyond && isr_clamped == clamped && overflowed == 0;
        if clamped == 0 {
            writeln!(out, ", max |fixed - f32| {w:.4} Pa")?;
            ok &= w <= FIXED_TOLERANCE_PA;
        } else {
            // After a clamped reading the fixed-point channel has seen another input than
            // the f32 one: nothing to compare. Export for the ADC's range instead.
            writeln!(out, ": export with --full-scale {ADC_RANGE_PA}")?;
        }
    }

    // A blob received at run time, between two DMA blocks: a damaged copy is refused and the
    // running set kept; the intact one is taken.
    let before = compensation.coefficients;
    let mut damaged = [0u8; blob::encoded_len(SECTIONS)];
    for (d, s) in damaged.iter_mut().zip(RECEIVED_BLOB) {
        *d = *s;
    }
    if let Some(b) = damaged.get_mut(40) {
        *b ^= 0x10;
    }
    let len = RECEIVED_BLOB.len().min(damaged.len());
    match compensation.receive(damaged.get(..len).unwrap_or(&[])) {
        Err(e) => writeln!(out, "damaged blob: {e}; running set kept")?,
        Ok(()) => {
            writeln!(out, "ERROR a damaged blob was taken")?;
            ok = false;
        }
    }
    ok &= compensation.coefficients == before;
    match compensation.receive(RECEIVED_BLOB) {
        // This blob and the Rust constants were exported from the same model file.
        Ok(()) => writeln!(
            out,
            "intact blob taken: {}",
            if compensation.coefficients == before {
                "the same coefficients as the Rust constants, bit for bit"
            } else {
                "other coefficients than the Rust constants"
            }
        )?,
        Err(e) => {
            writeln!(out, "ERROR intact blob refused: {e}")?;
            ok = false;
        }
    }
    ok &= compensation.coefficients == before;
    // The swap restarted each channel in equilibrium with its last reading; the pressure is
    // steady here, so the output is the pressure, with no transient.
    adc.fill(&mut raw);
    compensation.on_dma_half(&raw, &mut block);
    let jump = block
        .iter()
        .zip(&compensation.last)
        .flat_map(|(b, &p)| b.iter().map(move |u| (u - p).abs()))
        .fold(0.0f32, f32::max);
    writeln!(
        out,
        "after the swap: max |compensated - reading| {jump:.4} Pa over the next block"
    )?;
    ok &= jump < 0.05;

    writeln!(out, "DONE {}", if ok { "ok" } else { "FAILED" })?;
    Ok(ok)
}

// ---- On the board -----------------------------------------------------------------------------

#[cfg(target_os = "none")]
mod board {
    use core::cell::RefCell;

    use cortex_m::interrupt::{self, Mutex};
    use cortex_m::peripheral::syst::SystClkSource;
    use cortex_m_rt::{entry, exception};
    use cortex_m_semihosting::{debug, hio};
    use panic_semihosting as _;

    use super::IsrRun;

    /// What the interrupt handler and `main` share.
    static RUN: Mutex<RefCell<Option<IsrRun>>> = Mutex::new(RefCell::new(None));

    /// SysTick ticks per sample: QEMU's mps2 SysTick runs at 25 MHz.
    const TICKS_PER_SAMPLE: u32 = 25_000_000 / 10_000;

    /// The ADC's data-ready interrupt. On a real board this is your HAL's or PAC's
    /// `#[interrupt] fn ADC()` (or the external ADC's data-ready pin interrupt), which reads
    /// the converter's data register; here SysTick at the sample rate stands in for it.
    #[exception]
    fn SysTick() {
        interrupt::free(|cs| {
            if let Some(run) = RUN.borrow(cs).borrow_mut().as_mut() {
                run.on_adc_ready();
            }
        });
    }

    fn exit(ok: bool) -> ! {
        debug::exit(if ok {
            debug::EXIT_SUCCESS
        } else {
            debug::EXIT_FAILURE
        });
        #[allow(clippy::empty_loop)]
        loop {}
    }

    #[entry]
    fn main() -> ! {
        let (Some(mut cp), Some(run)) = (cortex_m::Peripherals::take(), super::start()) else {
            exit(false)
        };
        interrupt::free(|cs| RUN.borrow(cs).replace(Some(run)));
        // The sample clock: one interrupt per sample.
        cp.SYST.set_clock_source(SystClkSource::Core);
        cp.SYST.set_reload(TICKS_PER_SAMPLE - 1);
        cp.SYST.clear_current();
        cp.SYST.enable_interrupt();
        cp.SYST.enable_counter();
        while !interrupt::free(|cs| RUN.borrow(cs).borrow().as_ref().is_none_or(IsrRun::done)) {
            cortex_m::asm::wfi();
        }
        cp.SYST.disable_interrupt();
        let Some(run) = interrupt::free(|cs| RUN.borrow(cs).take()) else {
            exit(false)
        };
        let ok = match hio::hstdout() {
            Ok(mut out) => matches!(super::check(&mut out, &run), Ok(true)),
            Err(()) => false,
        };
        exit(ok)
    }
}

/// On the host: the interrupt handler's body called once per sample, then the same checks.
#[cfg(not(target_os = "none"))]
fn main() -> std::process::ExitCode {
    let Some(mut run) = start().map(Box::new) else {
        eprintln!("ERROR coefficients refused");
        return std::process::ExitCode::FAILURE;
    };
    while !run.done() {
        run.on_adc_ready();
    }
    let mut out = String::new();
    let ok = matches!(check(&mut out, &run), Ok(true));
    print!("{out}");
    if ok {
        std::process::ExitCode::SUCCESS
    } else {
        std::process::ExitCode::FAILURE
    }
}
