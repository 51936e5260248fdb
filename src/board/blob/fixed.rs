//! The fixed-point blobs, one encoder and one parser for both forms ([`FixedForm`]): number
//! format 1 carries the normal-form cascade of [`crate::board::fixed`], number format 2 the
//! direct form of [`crate::board::fixed::direct`].

use super::header::{self, Fields, Header, Writer};
use super::{encoded_len_direct, encoded_len_fixed, BlobError, NumberFormat, FORMAT_VERSION};
use crate::board::fixed::direct::{DirectCascade, DirectSection, COEFFICIENT_BITS};
use crate::board::fixed::{FixedCascade, FixedSection, STATE_BITS};

/// A validated fixed-point coefficient set received from the host: [`FixedCoefficientSet`]
/// (number format 1) or [`DirectCoefficientSet`] (number format 2), as the cascade `C` is.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FixedPointSet<C> {
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
    pub cascade: C,
}

/// A validated fixed-point coefficient set (number format 1, the normal form) for a board
/// with room for `N` sections.
pub type FixedCoefficientSet<const N: usize> = FixedPointSet<FixedCascade<N>>;

/// A validated direct-form fixed-point coefficient set (number format 2) for a board with
/// room for `N` sections.
pub type DirectCoefficientSet<const N: usize> = FixedPointSet<DirectCascade<N>>;

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

/// A fixed-point section's form as a blob carries it: its number format, and its words.
trait FixedForm: Copy {
    /// The number format its blobs carry.
    const FORMAT: NumberFormat;
    /// The section that passes its input on (the unused places of a cascade).
    const IDENTITY: Self;
    /// Reads one section after the header.
    fn read(h: &mut Header<'_>) -> Result<Self, BlobError>;
    /// Writes one section.
    fn write(&self, w: &mut Writer<'_>);
}

impl FixedForm for FixedSection {
    /// Fractional bits [`STATE_BITS`].
    #[allow(clippy::cast_possible_truncation)]
    const FORMAT: NumberFormat = NumberFormat::Fixed {
        frac_bits: STATE_BITS as u8,
    };
    const IDENTITY: Self = Self::IDENTITY;

    /// Nine `i32` (`a`, `b`, `c`, `d`), the shift and three reserved zero bytes.
    fn read(h: &mut Header<'_>) -> Result<Self, BlobError> {
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
        Ok(Self {
            a: [a11, a12, a21, a22],
            b: [b1, b2],
            c: [c1, c2],
            d,
            shift,
        })
    }

    fn write(&self, w: &mut Writer<'_>) {
        let [a11, a12, a21, a22] = self.a;
        let [b1, b2] = self.b;
        let [c1, c2] = self.c;
        for v in [a11, a12, a21, a22, b1, b2, c1, c2, self.d] {
            w.put(&v.to_le_bytes());
        }
        w.put(&[self.shift, 0, 0, 0]);
    }
}

impl FixedForm for DirectSection {
    /// Fractional bits [`COEFFICIENT_BITS`].
    #[allow(clippy::cast_possible_truncation)]
    const FORMAT: NumberFormat = NumberFormat::FixedDirect {
        frac_bits: COEFFICIENT_BITS as u8,
    };
    const IDENTITY: Self = Self::IDENTITY;

    /// Five `i32`: `b` and `neg_a`.
    fn read(h: &mut Header<'_>) -> Result<Self, BlobError> {
        let mut v = [0i32; 5];
        for x in &mut v {
            *x = h.rest.i32().ok_or(h.truncated())?;
        }
        let [b0, b1, b2, na1, na2] = v;
        Ok(Self {
            b: [b0, b1, b2],
            neg_a: [na1, na2],
        })
    }

    fn write(&self, w: &mut Writer<'_>) {
        for v in self.b.iter().chain(&self.neg_a) {
            w.put(&v.to_le_bytes());
        }
    }
}

/// Parses a fixed-point blob of form `S` for a board with room for `N` sections, and builds
/// its cascade from the sections in use by `cascade`.
fn parse_form<S: FixedForm, C, const N: usize>(
    bytes: &[u8],
    cascade: impl FnOnce(&[S]) -> Result<C, BlobError>,
) -> Result<FixedPointSet<C>, BlobError> {
    let mut h = header::read(bytes)?;
    h.expect(S::FORMAT, N)?;
    let (output_exponent, full_scale) = h.fixed_scale()?;
    let mut sections = [S::IDENTITY; N];
    for section in sections.iter_mut().take(h.sections) {
        *section = S::read(&mut h)?;
    }
    let used = sections.get(..h.sections).ok_or(h.truncated())?;
    Ok(FixedPointSet {
        cascade: cascade(used)?,
        sample_rate_hz: h.sample_rate_hz,
        delay_samples: h.delay_samples,
        sections: h.sections,
        full_scale,
        output_exponent,
    })
}

/// Writes a fixed-point blob of form `S`, `len` bytes long, into `out`.
fn encode_form<S: FixedForm>(
    out: &mut [u8],
    len: usize,
    (sample_rate_hz, delay_samples): (f64, u32),
    (full_scale, output_exponent): (f64, i32),
    sections: &[S],
) -> Result<usize, BlobError> {
    let fields = Fields {
        version: FORMAT_VERSION,
        format: S::FORMAT,
        sample_rate_hz,
        delay_samples,
        sections: sections.len(),
        lowpass_sections: 0,
    };
    header::write(out, len, &fields, |w| {
        w.fixed_scale(output_exponent, full_scale);
        for s in sections {
            s.write(w);
        }
    })
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
    parse_form::<FixedSection, _, N>(bytes, |used| {
        FixedCascade::new(used).map_err(BlobError::InvalidFixedSections)
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
    encode_form(
        out,
        encoded_len_fixed(sections.len()),
        (sample_rate_hz, delay_samples),
        (full_scale, output_exponent),
        sections,
    )
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
    parse_form::<DirectSection, _, N>(bytes, |used| {
        DirectCascade::new(used).map_err(BlobError::InvalidDirectSections)
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
    encode_form(
        out,
        encoded_len_direct(sections.len()),
        (sample_rate_hz, delay_samples),
        (full_scale, output_exponent),
        sections,
    )
}
