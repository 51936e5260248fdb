//! The `f32` blob (number format 0): the cascade, in format version 1, and with the
//! nonlinear-damping correction after it, in format version 2; its encoders and its parser.

use super::header::{self, Fields};
use super::{
    encoded_len, encoded_len_nonlinear, BlobError, NumberFormat, FORMAT_VERSION,
    FORMAT_VERSION_NONLINEAR,
};
use crate::board::compensator::{CascadeCoefficients, NonlinearDampingCoefficients};

/// A validated coefficient set received from the host: the board's compensator and what it
/// belongs to. Holding one means every field passed [`parse`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CoefficientSet<const N: usize> {
    /// Sample rate in Hz the coefficients were designed for.
    pub sample_rate_hz: f64,
    /// The model's delay in samples.
    pub delay_samples: u32,
    /// Sections in use (the rest of the `N` are identities).
    pub sections: usize,
    /// The compensator, ready for `process(&mut state, x)`.
    pub cascade: CascadeCoefficients<f32, N>,
    /// The nonlinear-damping correction to add to the cascade's output (format version 2),
    /// `None` for a linear compensator.
    pub nonlinear: Option<NonlinearDampingCoefficients<f32, N>>,
}

impl<const N: usize> CoefficientSet<N> {
    /// Parses `bytes` and, only if the whole blob is valid, replaces `self` with it. On any
    /// error `self` is left exactly as it was, so the running compensator goes on with the
    /// old set; the channel state is not touched either way.
    ///
    /// # Errors
    /// See [`parse`].
    ///
    /// ```
    /// use unlag::board::blob::{self, BlobError, CoefficientSet};
    ///
    /// let mut old = [0u8; blob::encoded_len(1)];
    /// let n = blob::encode(&mut old, 10_000.0, 3, 1.0, &[[1.0, 0.0, 0.0, -0.5, 0.0]])?;
    /// let mut set: CoefficientSet<2> = blob::parse(&old[..n])?;
    ///
    /// let mut new = [0u8; blob::encoded_len(1)];
    /// let n = blob::encode(&mut new, 20_000.0, 5, 1.0, &[[1.0, 0.0, 0.0, -0.25, 0.0]])?;
    /// // Damaged in transit: refused, and the running set is kept as it was.
    /// let mut damaged = new;
    /// damaged[40] ^= 0x01;
    /// assert!(matches!(set.update(&damaged[..n]), Err(BlobError::CrcMismatch { .. })));
    /// assert_eq!(set.sample_rate_hz, 10_000.0);
    /// // Cut short: refused too.
    /// assert!(set.update(&new[..n - 1]).is_err());
    /// // Whole: swapped in.
    /// set.update(&new[..n])?;
    /// assert_eq!((set.sample_rate_hz, set.delay_samples), (20_000.0, 5));
    /// # Ok::<(), BlobError>(())
    /// ```
    pub fn update(&mut self, bytes: &[u8]) -> Result<(), BlobError> {
        *self = parse(bytes)?;
        Ok(())
    }
}

/// Parses and validates an `f32` blob for a board with room for `N` sections.
///
/// Checks, in order: length of the fixed header, magic, format version, total length against
/// the section count, CRC-32, reserved bytes, sample rate, number format, fractional bits,
/// section count against `N`, and finally every coefficient (finite, each section stable by
/// [`crate::board::compensator::MIN_POLE_MARGIN`]).
///
/// # Errors
/// The first [`BlobError`] found; never panics, whatever the bytes.
pub fn parse<const N: usize>(bytes: &[u8]) -> Result<CoefficientSet<N>, BlobError> {
    let mut h = header::read(bytes)?;
    h.expect(NumberFormat::F32, N)?;
    let gain = h.rest.f32().ok_or(h.truncated())?;
    let designed: [[f64; 5]; N] = h.rest.f32_sections(h.sections).ok_or(h.truncated())?;
    let used = designed.get(..h.sections).ok_or(h.truncated())?;
    // f32 -> f64 -> f32 is exact, so the board runs exactly the exported values.
    let cascade = CascadeCoefficients::new(f64::from(gain), used)?;
    let nonlinear = if h.version == FORMAT_VERSION_NONLINEAR {
        if h.lowpass_sections > N {
            return Err(BlobError::TooManySections {
                sections: h.lowpass_sections,
                capacity: N,
            });
        }
        let gain = h.rest.f32().ok_or(h.truncated())?;
        let lowpass_gain = h.rest.f32().ok_or(h.truncated())?;
        let lowpass: [[f64; 5]; N] = h
            .rest
            .f32_sections(h.lowpass_sections)
            .ok_or(h.truncated())?;
        let used = lowpass.get(..h.lowpass_sections).ok_or(h.truncated())?;
        Some(NonlinearDampingCoefficients::new(
            f64::from(gain),
            f64::from(lowpass_gain),
            used,
        )?)
    } else {
        None
    };
    Ok(CoefficientSet {
        sample_rate_hz: h.sample_rate_hz,
        delay_samples: h.delay_samples,
        sections: h.sections,
        cascade,
        nonlinear,
    })
}

/// Writes a version-[`FORMAT_VERSION`] `f32` blob into `out` and returns its length
/// ([`encoded_len`]`(sections.len())`). Values are written as given; [`parse`] validates them.
///
/// # Errors
/// [`BlobError::BufferTooSmall`] when `out` is too short, [`BlobError::TooManySections`] for
/// more than [`super::MAX_SECTIONS`] sections.
pub fn encode(
    out: &mut [u8],
    sample_rate_hz: f64,
    delay_samples: u32,
    gain: f32,
    sections: &[[f32; 5]],
) -> Result<usize, BlobError> {
    write(out, sample_rate_hz, delay_samples, gain, sections, None)
}

/// The nonlinear-damping correction as [`encode_nonlinear`] writes it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NonlinearCorrection<'a> {
    /// Gain per squared sample difference of the probe signal.
    pub gain: f32,
    /// Input gain of the low-pass.
    pub lowpass_gain: f32,
    /// The low-pass sections `[b0, b1, b2, a1, a2]`.
    pub lowpass: &'a [[f32; 5]],
}

/// Writes a version-[`FORMAT_VERSION_NONLINEAR`] `f32` blob (the cascade and the
/// nonlinear-damping correction) into `out` and returns its length
/// ([`encoded_len_nonlinear`]). Values are written as given; [`parse`] validates them.
///
/// # Errors
/// As [`encode`]; [`BlobError::TooManySections`] also for more than
/// [`super::MAX_SECTIONS`] low-pass sections.
pub fn encode_nonlinear(
    out: &mut [u8],
    sample_rate_hz: f64,
    delay_samples: u32,
    gain: f32,
    sections: &[[f32; 5]],
    correction: &NonlinearCorrection<'_>,
) -> Result<usize, BlobError> {
    write(
        out,
        sample_rate_hz,
        delay_samples,
        gain,
        sections,
        Some(correction),
    )
}

/// The `f32` blob with the correction (version 2) or without it (version 1).
fn write(
    out: &mut [u8],
    sample_rate_hz: f64,
    delay_samples: u32,
    gain: f32,
    sections: &[[f32; 5]],
    correction: Option<&NonlinearCorrection<'_>>,
) -> Result<usize, BlobError> {
    let lowpass = correction.map_or(&[][..], |c| c.lowpass);
    let (version, len) = match correction {
        Some(_) => (
            FORMAT_VERSION_NONLINEAR,
            encoded_len_nonlinear(sections.len(), lowpass.len()),
        ),
        None => (FORMAT_VERSION, encoded_len(sections.len())),
    };
    let fields = Fields {
        version,
        format: NumberFormat::F32,
        sample_rate_hz,
        delay_samples,
        sections: sections.len(),
        lowpass_sections: lowpass.len(),
    };
    header::write(out, len, &fields, |w| {
        w.put(&gain.to_le_bytes());
        for c in sections.iter().flatten() {
            w.put(&c.to_le_bytes());
        }
        if let Some(c) = correction {
            w.put(&c.gain.to_le_bytes());
            w.put(&c.lowpass_gain.to_le_bytes());
            for v in c.lowpass.iter().flatten() {
                w.put(&v.to_le_bytes());
            }
        }
    })
}
