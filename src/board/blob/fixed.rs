//! The fixed-point blob (number format 1): the normal-form cascade of [`crate::board::fixed`], its
//! encoder and its parser.

use super::header::{self, Fields};
use super::{encoded_len_fixed, BlobError, NumberFormat, FORMAT_VERSION};
use crate::board::fixed::{FixedCascade, FixedSection, STATE_BITS};

/// The number format this module reads and writes: fractional bits [`STATE_BITS`].
#[allow(clippy::cast_possible_truncation)]
const FORMAT: NumberFormat = NumberFormat::Fixed {
    frac_bits: STATE_BITS as u8,
};

/// A validated fixed-point coefficient set (number format 1) received from the host.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FixedCoefficientSet<const N: usize> {
    /// Sample rate in Hz the coefficients were designed for.
    pub sample_rate_hz: f64,
    /// The model's delay in samples.
    pub delay_samples: u32,
    /// Sections in use (the rest of the `N` are identities).
    pub sections: usize,
    /// The ADC full scale in the probe's units: the input code `2^31`.
    pub full_scale: f64,
    /// The output is Q1.31 of `full_scale * 2^output_exponent`.
    pub output_exponent: i32,
    /// The compensator, ready for `process(&mut state, code)`.
    pub cascade: FixedCascade<N>,
}

impl<const N: usize> FixedCoefficientSet<N> {
    /// Parses `bytes` and, only if the whole blob is valid, replaces `self` with it; on any
    /// error `self` is left as it was.
    ///
    /// # Errors
    /// See [`parse_fixed`].
    pub fn update(&mut self, bytes: &[u8]) -> Result<(), BlobError> {
        *self = parse_fixed(bytes)?;
        Ok(())
    }
}

/// Parses and validates a fixed-point blob (number format 1) for a board with room for `N`
/// sections: the same header checks as [`super::parse`], then the fractional bits, the full scale and
/// every section as [`crate::board::fixed::FixedCascade::new`] checks it.
///
/// # Errors
/// The first [`BlobError`] found; never panics, whatever the bytes.
///
/// ```
/// use unlag::board::blob::{self, BlobError};
/// use unlag::board::fixed::{FixedSection, FixedState};
///
/// let sections = [FixedSection::IDENTITY; 2];
/// let mut buf = [0u8; blob::encoded_len_fixed(2)];
/// let n = blob::encode_fixed(&mut buf, 10_000.0, 3, 2500.0, 0, &sections)?;
/// let set = blob::parse_fixed::<4>(&buf[..n])?;
/// assert_eq!((set.sections, set.full_scale), (2, 2500.0));
/// let mut state = FixedState::default();
/// assert_eq!(set.cascade.process(&mut state, -123_456), -123_456);
/// // A board with room for one section only refuses it; an f32 blob is no fixed-point one.
/// assert!(matches!(blob::parse_fixed::<1>(&buf[..n]), Err(BlobError::TooManySections { .. })));
/// let mut f32_blob = [0u8; blob::encoded_len(1)];
/// let m = blob::encode(&mut f32_blob, 10_000.0, 3, 1.0, &[[1.0, 0.0, 0.0, 0.0, 0.0]])?;
/// assert!(matches!(
///     blob::parse_fixed::<4>(&f32_blob[..m]),
///     Err(BlobError::UnsupportedNumberFormat { .. })
/// ));
/// # Ok::<(), BlobError>(())
/// ```
pub fn parse_fixed<const N: usize>(bytes: &[u8]) -> Result<FixedCoefficientSet<N>, BlobError> {
    let mut h = header::read(bytes)?;
    h.expect(FORMAT, N)?;
    let (output_exponent, full_scale) = h.fixed_scale()?;
    let mut sections = [FixedSection::IDENTITY; N];
    for section in sections.iter_mut().take(h.sections) {
        let mut v = [0i32; 9];
        for x in &mut v {
            *x = h.rest.i32().ok_or(h.truncated())?;
        }
        let [shift, pad0, pad1, pad2]: [u8; 4] = h.rest.take().ok_or(h.truncated())?;
        if (pad0, pad1, pad2) != (0, 0, 0) {
            return Err(BlobError::ReservedNotZero {
                // The first of the three padding bytes just read.
                offset: h.rest.offset().saturating_sub(3),
            });
        }
        let [a11, a12, a21, a22, b1, b2, c1, c2, d] = v;
        *section = FixedSection {
            a: [a11, a12, a21, a22],
            b: [b1, b2],
            c: [c1, c2],
            d,
            shift,
        };
    }
    let used = sections.get(..h.sections).ok_or(h.truncated())?;
    let cascade = FixedCascade::new(used).map_err(BlobError::InvalidFixedSections)?;
    Ok(FixedCoefficientSet {
        sample_rate_hz: h.sample_rate_hz,
        delay_samples: h.delay_samples,
        sections: h.sections,
        full_scale,
        output_exponent,
        cascade,
    })
}

/// Writes a version-[`FORMAT_VERSION`] fixed-point blob (number format 1) into `out` and
/// returns its length ([`encoded_len_fixed`]`(sections.len())`).
///
/// # Errors
/// [`BlobError::BufferTooSmall`] when `out` is too short, [`BlobError::TooManySections`] for
/// more than [`super::MAX_SECTIONS`] sections.
pub fn encode_fixed(
    out: &mut [u8],
    sample_rate_hz: f64,
    delay_samples: u32,
    full_scale: f64,
    output_exponent: i32,
    sections: &[FixedSection],
) -> Result<usize, BlobError> {
    let fields = Fields {
        version: FORMAT_VERSION,
        format: FORMAT,
        sample_rate_hz,
        delay_samples,
        sections: sections.len(),
        lowpass_sections: 0,
    };
    header::write(out, encoded_len_fixed(sections.len()), &fields, |w| {
        w.fixed_scale(output_exponent, full_scale);
        for s in sections {
            let [a11, a12, a21, a22] = s.a;
            let [b1, b2] = s.b;
            let [c1, c2] = s.c;
            for v in [a11, a12, a21, a22, b1, b2, c1, c2, s.d] {
                w.put(&v.to_le_bytes());
            }
            w.put(&[s.shift, 0, 0, 0]);
        }
    })
}
