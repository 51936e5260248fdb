//! The direct-form fixed-point blob (number format 2): the cascade of
//! [`crate::board::fixed::direct`], its encoder and its parser.

use super::header::{self, Fields};
use super::{encoded_len_direct, BlobError, NumberFormat, FORMAT_VERSION};
use crate::board::fixed::direct::{DirectCascade, DirectSection, COEFFICIENT_BITS};

/// The number format this module reads and writes: fractional bits [`COEFFICIENT_BITS`].
#[allow(clippy::cast_possible_truncation)]
const FORMAT: NumberFormat = NumberFormat::FixedDirect {
    frac_bits: COEFFICIENT_BITS as u8,
};

/// A validated direct-form fixed-point coefficient set (number format 2) received from the
/// host.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DirectCoefficientSet<const N: usize> {
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
    pub cascade: DirectCascade<N>,
}

impl<const N: usize> DirectCoefficientSet<N> {
    /// Parses `bytes` and, only if the whole blob is valid, replaces `self` with it; on any
    /// error `self` is left as it was.
    ///
    /// # Errors
    /// See [`parse_direct`].
    pub fn update(&mut self, bytes: &[u8]) -> Result<(), BlobError> {
        *self = parse_direct(bytes)?;
        Ok(())
    }
}

/// Parses and validates a direct-form fixed-point blob (number format 2) for a board with
/// room for `N` sections: the same header checks as [`super::parse`], then the fractional bits, the
/// full scale and every section as [`crate::board::fixed::direct::DirectCascade::new`] checks it.
///
/// # Errors
/// The first [`BlobError`] found; never panics, whatever the bytes.
///
/// ```
/// use unlag::board::blob::{self, BlobError};
/// use unlag::board::fixed::direct::{DirectSection, DirectState};
///
/// let lag = DirectSection { b: [1 << 29, 0, 0], neg_a: [1 << 29, 0] };
/// let mut buf = [0u8; blob::encoded_len_direct(1)];
/// let n = blob::encode_direct(&mut buf, 10_000.0, 3, 2500.0, 0, &[lag])?;
/// let set = blob::parse_direct::<2>(&buf[..n])?;
/// assert_eq!(set.cascade.sections()[0], lag);
/// let mut state = DirectState::default();
/// assert_eq!(set.cascade.process(&mut state, 1000), 500);
/// // An unstable section is refused with the cascade's own error.
/// let ring = DirectSection { b: [1 << 29, 0, 0], neg_a: [0, -(1 << 30)] };
/// let n = blob::encode_direct(&mut buf, 10_000.0, 3, 2500.0, 0, &[ring])?;
/// assert!(matches!(
///     blob::parse_direct::<2>(&buf[..n]),
///     Err(BlobError::InvalidDirectSections(_))
/// ));
/// # Ok::<(), BlobError>(())
/// ```
pub fn parse_direct<const N: usize>(bytes: &[u8]) -> Result<DirectCoefficientSet<N>, BlobError> {
    let mut h = header::read(bytes)?;
    h.expect(FORMAT, N)?;
    let (output_exponent, full_scale) = h.fixed_scale()?;
    let mut sections = [DirectSection::IDENTITY; N];
    for section in sections.iter_mut().take(h.sections) {
        let mut v = [0i32; 5];
        for x in &mut v {
            *x = h.rest.i32().ok_or(h.truncated())?;
        }
        let [b0, b1, b2, na1, na2] = v;
        *section = DirectSection {
            b: [b0, b1, b2],
            neg_a: [na1, na2],
        };
    }
    let used = sections.get(..h.sections).ok_or(h.truncated())?;
    let cascade = DirectCascade::new(used).map_err(BlobError::InvalidDirectSections)?;
    Ok(DirectCoefficientSet {
        sample_rate_hz: h.sample_rate_hz,
        delay_samples: h.delay_samples,
        sections: h.sections,
        full_scale,
        output_exponent,
        cascade,
    })
}

/// Writes a version-[`FORMAT_VERSION`] direct-form fixed-point blob (number format 2) into
/// `out` and returns its length ([`encoded_len_direct`]`(sections.len())`).
///
/// # Errors
/// [`BlobError::BufferTooSmall`] when `out` is too short, [`BlobError::TooManySections`] for
/// more than [`super::MAX_SECTIONS`] sections.
pub fn encode_direct(
    out: &mut [u8],
    sample_rate_hz: f64,
    delay_samples: u32,
    full_scale: f64,
    output_exponent: i32,
    sections: &[DirectSection],
) -> Result<usize, BlobError> {
    let fields = Fields {
        version: FORMAT_VERSION,
        format: FORMAT,
        sample_rate_hz,
        delay_samples,
        sections: sections.len(),
        lowpass_sections: 0,
    };
    header::write(out, encoded_len_direct(sections.len()), &fields, |w| {
        w.fixed_scale(output_exponent, full_scale);
        for s in sections {
            for v in s.b.iter().chain(&s.neg_a) {
                w.put(&v.to_le_bytes());
            }
        }
    })
}
