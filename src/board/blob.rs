//! The coefficient blob: a versioned binary image of the board's compensator, for updating a
//! running board over a serial link (`unlag export --format bin`).
//!
//! This module owns the wire format, both directions: [`encode`] (used by the host's
//! `unlag export`, and by a board that wants to echo its set) and [`parse`], the board-side
//! parser. Both are `no_std`, allocation-free and panic-free. The parser checks every field and
//! answers a corrupted, truncated or incompatible blob with a typed [`BlobError`]; a parsed
//! [`CoefficientSet`] is valid (finite, stable), so [`CoefficientSet::update`] swaps to a new set
//! only when the whole set is valid and keeps the old one otherwise.
//!
//! # Layout (format version 1, all fields little-endian)
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 4 | magic `b"UNLG"` ([`MAGIC`]) |
//! | 4 | 2 | format version, `u16` ([`FORMAT_VERSION`]) |
//! | 6 | 1 | number format, `u8`: 0 = `f32`, 1 = fixed point (see [`NumberFormat`]) |
//! | 7 | 1 | fractional bits of the fixed-point format, `u8`; 0 for `f32` |
//! | 8 | 8 | sample rate in Hz, `f64`, finite and > 0 |
//! | 16 | 4 | model delay in samples, `u32` |
//! | 20 | 2 | section count `n`, `u16` |
//! | 22 | 2 | reserved, must be 0 |
//! | 24 | 4 | input gain, `f32` |
//! | 28 | 20 `n` | sections, each `[b0, b1, b2, a1, a2]` as five `f32` |
//! | 28 + 20 `n` | 4 | CRC-32 (ISO-HDLC, the zlib/PNG CRC) of bytes `0 .. 28 + 20 n`, `u32` |
//!
//! # Format version 2: the nonlinear-damping correction
//!
//! A compensator with the `nonlinear-damping` correction
//! ([`crate::compensator::NonlinearDampingCoefficients`], `f32` only) is written as format
//! version 2 ([`FORMAT_VERSION_NONLINEAR`], [`encode_nonlinear`]); a compensator without it is
//! still written as version 1, so boards that read version 1 only keep working and refuse a
//! correction they cannot run. Version 2 differs in two places:
//!
//! | offset | size | field |
//! |---|---|---|
//! | 22 | 2 | the correction's low-pass section count `m`, `u16` (reserved in version 1) |
//! | 28 + 20 `n` | 4 | the correction's gain (per squared sample difference), `f32` |
//! | 32 + 20 `n` | 4 | the correction's low-pass input gain, `f32` |
//! | 36 + 20 `n` | 20 `m` | the low-pass sections, five `f32` each |
//! | 36 + 20 (`n` + `m`) | 4 | CRC-32 of every byte before it |
//!
//! The parser checks the correction like the cascade: finite, every low-pass section stable,
//! `m` within the capacity `N`. Fixed point has no version 2.
//!
//! With number format 1 (fixed point, [`parse_fixed`], [`encode_fixed`]) the fractional-bits
//! byte is [`crate::fixed::STATE_BITS`] (30), the four bytes at offset 24 hold the output
//! exponent `e` (`i32`: the output is Q1.31 of `full_scale 2^e`), an `f64` full scale (the
//! input code `2^31`, in the probe's units) follows at offset 28, and each section is 40
//! bytes: `a11 a12 a21 a22 b1 b2 c1 c2 d` as `i32`, `shift` as `u8` and three zero bytes
//! (see [`crate::fixed::FixedSection`]); the CRC-32 ends the blob as before.
//!
//! With number format 2 (the direct form of the fixed-point compensator, [`parse_direct`],
//! [`encode_direct`]) the header is the same as for number format 1 (fractional bits
//! [`crate::fixed::direct::COEFFICIENT_BITS`], output exponent, `f64` full scale) and each
//! section is 20 bytes: `b0 b1 b2 na1 na2` as `i32`, with `na = -a` **negated** (see
//! [`crate::fixed::direct::DirectSection`]).
//!
//! Sections follow the crate's sign convention (see [`crate::compensator`]):
//! `y = b0 x + b1 x[k-1] + b2 x[k-2] - a1 y[k-1] - a2 y[k-2]`. The CRC detects every single-bit
//! error and every burst up to 32 bits; the checks of magic, version, length, number format,
//! reserved bytes, sample rate and stability catch an incompatible but intact blob.
//!
//! # Example
//!
//! ```
//! use unlag::blob::{self, CoefficientSet};
//! let sections = [[1.0f32, -0.5, 0.0, -0.25, 0.0]];
//! let mut buf = [0u8; blob::encoded_len(1)];
//! let n = blob::encode(&mut buf, 10_000.0, 3, 0.5, &sections).unwrap();
//! let set: CoefficientSet<2> = blob::parse(&buf[..n]).unwrap();
//! assert_eq!(set.sample_rate_hz, 10_000.0);
//! assert_eq!(set.delay_samples, 3);
//! // One flipped bit and the blob is refused.
//! buf[30] ^= 0x04;
//! assert!(blob::parse::<2>(&buf[..n]).is_err());
//! ```
#![deny(
    clippy::indexing_slicing,
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::unreachable,
    clippy::todo,
    clippy::unimplemented,
    clippy::arithmetic_side_effects
)]

use core::fmt;

use crate::compensator::{CascadeCoefficients, InverseError, NonlinearDampingCoefficients};
use crate::fixed::direct::{DirectCascade, DirectError, DirectSection, COEFFICIENT_BITS};
use crate::fixed::{FixedCascade, FixedError, FixedSection, STATE_BITS};

/// The first four bytes of every blob.
pub const MAGIC: [u8; 4] = *b"UNLG";

/// The blob format version this crate writes for a compensator without the nonlinear-damping
/// correction (and reads).
pub const FORMAT_VERSION: u16 = 1;

/// The blob format version with the nonlinear-damping correction (`f32` only, see the module
/// docs); this crate reads both.
pub const FORMAT_VERSION_NONLINEAR: u16 = 2;

/// Bytes of the version-2 extension before the correction's sections: two `f32` gains.
pub const NONLINEAR_EXTRA_LEN: usize = 8;

/// Bytes before the sections: magic, version, number format, fractional bits, sample rate,
/// delay, section count, reserved, gain.
pub const HEADER_LEN: usize = 28;

/// Bytes per section: five `f32`.
pub const SECTION_LEN: usize = 20;

/// Bytes of the trailing CRC-32.
pub const CRC_LEN: usize = 4;

/// Bytes per fixed-point section: nine `i32`, the shift and three zero bytes.
pub const FIXED_SECTION_LEN: usize = 40;

/// Bytes of the fixed-point header extension (the `f64` full scale).
pub const FIXED_EXTRA_LEN: usize = 8;

/// Bytes per direct-form fixed-point section: five `i32`.
pub const DIRECT_SECTION_LEN: usize = 20;

/// Largest section count the format can carry.
pub const MAX_SECTIONS: usize = u16::MAX as usize;

/// CRC-32/ISO-HDLC (the zlib, PNG and Ethernet CRC): poly 0x04C11DB7, reflected, init and
/// xor-out 0xFFFFFFFF; check value 0xCBF43926.
const CRC32: crc::Crc<u32> = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC);

/// Length in bytes of a blob with `sections` sections (saturates for absurd counts).
#[must_use]
pub const fn encoded_len(sections: usize) -> usize {
    HEADER_LEN
        .saturating_add(sections.saturating_mul(SECTION_LEN))
        .saturating_add(CRC_LEN)
}

/// Length in bytes of a version-2 blob with `sections` sections and `lowpass` sections of the
/// nonlinear-damping correction (saturates).
#[must_use]
pub const fn encoded_len_nonlinear(sections: usize, lowpass: usize) -> usize {
    encoded_len(sections)
        .saturating_add(NONLINEAR_EXTRA_LEN)
        .saturating_add(lowpass.saturating_mul(SECTION_LEN))
}

/// Length in bytes of a fixed-point blob with `sections` sections (saturates).
#[must_use]
pub const fn encoded_len_fixed(sections: usize) -> usize {
    HEADER_LEN
        .saturating_add(FIXED_EXTRA_LEN)
        .saturating_add(sections.saturating_mul(FIXED_SECTION_LEN))
        .saturating_add(CRC_LEN)
}

/// Length in bytes of a direct-form fixed-point blob with `sections` sections (saturates).
#[must_use]
pub const fn encoded_len_direct(sections: usize) -> usize {
    HEADER_LEN
        .saturating_add(FIXED_EXTRA_LEN)
        .saturating_add(sections.saturating_mul(DIRECT_SECTION_LEN))
        .saturating_add(CRC_LEN)
}

/// CRC-32/ISO-HDLC of `bytes`, as stored in the blob.
#[must_use]
pub fn crc32(bytes: &[u8]) -> u32 {
    CRC32.checksum(bytes)
}

/// How the coefficients are stored in the blob.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum NumberFormat {
    /// IEEE-754 single precision (code 0).
    F32,
    /// Fixed point with the given number of fractional bits (code 1): the
    /// [`crate::fixed::FixedCascade`] of issue 4, read by [`parse_fixed`]; [`parse`] refuses
    /// it with [`BlobError::UnsupportedNumberFormat`].
    Fixed {
        /// Fractional bits of the coefficient format.
        frac_bits: u8,
    },
    /// The direct form of the fixed-point compensator (code 2):
    /// [`crate::fixed::direct::DirectCascade`], read by [`parse_direct`].
    FixedDirect {
        /// Fractional bits of the coefficient format.
        frac_bits: u8,
    },
}

impl NumberFormat {
    /// The code stored at offset 6.
    #[must_use]
    pub const fn code(self) -> u8 {
        match self {
            Self::F32 => 0,
            Self::Fixed { .. } => 1,
            Self::FixedDirect { .. } => 2,
        }
    }
}

/// Why a blob was refused. Nothing is swapped in when any of these is returned.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub enum BlobError {
    /// Fewer bytes than the header and section count call for: the transfer was cut short.
    Truncated {
        /// Bytes the blob must have.
        needed: usize,
        /// Bytes received.
        got: usize,
    },
    /// More bytes than the header and section count call for.
    TrailingBytes {
        /// Bytes the blob must have.
        expected: usize,
        /// Bytes received.
        got: usize,
    },
    /// The first four bytes are not [`MAGIC`]: not an unlag coefficient blob.
    BadMagic,
    /// The blob was written in a format version this firmware does not read.
    UnsupportedVersion {
        /// The version found.
        found: u16,
    },
    /// The stored CRC-32 does not match the contents: the blob was corrupted.
    CrcMismatch {
        /// CRC stored in the blob.
        stored: u32,
        /// CRC computed over the received bytes.
        computed: u32,
    },
    /// The number format code is unknown, or one this firmware cannot run (fixed point).
    UnsupportedNumberFormat {
        /// The code found at offset 6.
        code: u8,
    },
    /// A reserved field (the fractional bits of an `f32` blob, or bytes 22..24) is not zero.
    ReservedNotZero {
        /// Byte offset of the field.
        offset: usize,
    },
    /// The sample rate is not finite or not positive.
    InvalidSampleRate,
    /// More sections than this firmware's capacity `N`.
    TooManySections {
        /// Sections in the blob.
        sections: usize,
        /// The capacity `N`.
        capacity: usize,
    },
    /// The coefficients are not finite, or a section is not stable.
    InvalidCoefficients(InverseError),
    /// A fixed-point blob's fractional bits are not [`crate::fixed::STATE_BITS`].
    UnsupportedFractionalBits {
        /// The value found at offset 7.
        found: u8,
    },
    /// A fixed-point blob's full scale is not finite and positive.
    InvalidFullScale,
    /// The fixed-point sections are refused by [`crate::fixed::FixedCascade::new`].
    InvalidFixedSections(FixedError),
    /// The direct-form sections are refused by
    /// [`crate::fixed::direct::DirectCascade::new`].
    InvalidDirectSections(DirectError),
    /// [`encode`]: the output buffer is shorter than [`encoded_len`].
    BufferTooSmall {
        /// Bytes needed.
        needed: usize,
        /// Bytes available.
        available: usize,
    },
}

impl fmt::Display for BlobError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Truncated { needed, got } => {
                write!(f, "blob truncated: {got} bytes, {needed} needed")
            }
            Self::TrailingBytes { expected, got } => {
                write!(f, "blob has {got} bytes, {expected} expected")
            }
            Self::BadMagic => write!(f, "not an unlag coefficient blob (bad magic)"),
            Self::UnsupportedVersion { found } => write!(
                f,
                "blob format version {found} is not supported (this firmware reads {FORMAT_VERSION} and, for f32, {FORMAT_VERSION_NONLINEAR})"
            ),
            Self::CrcMismatch { stored, computed } => write!(
                f,
                "blob corrupted: CRC-32 {computed:#010x} does not match the stored {stored:#010x}"
            ),
            Self::UnsupportedNumberFormat { code } => {
                write!(f, "number format {code} is not supported (0 = f32)")
            }
            Self::ReservedNotZero { offset } => {
                write!(f, "reserved field at byte {offset} is not zero")
            }
            Self::InvalidSampleRate => write!(f, "sample rate is not finite and positive"),
            Self::TooManySections { sections, capacity } => write!(
                f,
                "{sections} sections exceed the firmware's capacity {capacity}"
            ),
            Self::InvalidCoefficients(e) => write!(f, "invalid coefficients: {e}"),
            Self::BufferTooSmall { needed, available } => write!(
                f,
                "output buffer of {available} bytes is too small, {needed} needed"
            ),
            Self::UnsupportedFractionalBits { found } => write!(
                f,
                "fixed-point blob with {found} fractional bits (this firmware runs {STATE_BITS})"
            ),
            Self::InvalidFullScale => write!(f, "full scale is not finite and positive"),
            Self::InvalidFixedSections(e) => write!(f, "invalid fixed-point sections: {e}"),
            Self::InvalidDirectSections(e) => write!(f, "invalid direct-form sections: {e}"),
        }
    }
}

impl core::error::Error for BlobError {}

#[cfg(feature = "defmt")]
impl defmt::Format for BlobError {
    fn format(&self, f: defmt::Formatter) {
        match self {
            Self::Truncated { needed, got } => {
                defmt::write!(f, "Truncated({=usize} < {=usize})", got, needed)
            }
            Self::TrailingBytes { expected, got } => {
                defmt::write!(f, "TrailingBytes({=usize} > {=usize})", got, expected)
            }
            Self::BadMagic => defmt::write!(f, "BadMagic"),
            Self::UnsupportedVersion { found } => {
                defmt::write!(f, "UnsupportedVersion({=u16})", found)
            }
            Self::CrcMismatch { stored, computed } => {
                defmt::write!(f, "CrcMismatch({=u32:x} != {=u32:x})", computed, stored)
            }
            Self::UnsupportedNumberFormat { code } => {
                defmt::write!(f, "UnsupportedNumberFormat({=u8})", code)
            }
            Self::ReservedNotZero { offset } => {
                defmt::write!(f, "ReservedNotZero(@{=usize})", offset)
            }
            Self::InvalidSampleRate => defmt::write!(f, "InvalidSampleRate"),
            Self::TooManySections { sections, capacity } => {
                defmt::write!(
                    f,
                    "TooManySections({=usize} > {=usize})",
                    sections,
                    capacity
                )
            }
            Self::InvalidCoefficients(e) => defmt::write!(f, "InvalidCoefficients({})", e),
            Self::BufferTooSmall { needed, available } => {
                defmt::write!(f, "BufferTooSmall({=usize} < {=usize})", available, needed)
            }
            Self::UnsupportedFractionalBits { found } => {
                defmt::write!(f, "UnsupportedFractionalBits({=u8})", found)
            }
            Self::InvalidFullScale => defmt::write!(f, "InvalidFullScale"),
            Self::InvalidFixedSections(e) => defmt::write!(f, "InvalidFixedSections({})", e),
            Self::InvalidDirectSections(e) => defmt::write!(f, "InvalidDirectSections({})", e),
        }
    }
}

impl From<InverseError> for BlobError {
    fn from(e: InverseError) -> Self {
        Self::InvalidCoefficients(e)
    }
}

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
    /// use unlag::blob::{self, BlobError, CoefficientSet};
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

/// A cursor over the blob that hands out fixed-size fields without panicking.
struct Reader<'a> {
    rest: &'a [u8],
}

impl<'a> Reader<'a> {
    fn take<const K: usize>(&mut self) -> Option<[u8; K]> {
        let (head, rest) = self.rest.split_first_chunk::<K>()?;
        self.rest = rest;
        Some(*head)
    }
    fn u16(&mut self) -> Option<u16> {
        self.take().map(u16::from_le_bytes)
    }
    fn u32(&mut self) -> Option<u32> {
        self.take().map(u32::from_le_bytes)
    }
    fn i32(&mut self) -> Option<i32> {
        self.take().map(i32::from_le_bytes)
    }
    fn f32(&mut self) -> Option<f32> {
        self.take().map(f32::from_le_bytes)
    }
    fn f64(&mut self) -> Option<f64> {
        self.take().map(f64::from_le_bytes)
    }
}

/// The fields every blob starts with, checked for length and integrity.
struct Header<'a> {
    version: u16,
    /// Version 2: the correction's low-pass section count (offset 22).
    lowpass_sections: usize,
    format_code: u8,
    frac_bits: u8,
    sample_rate_hz: f64,
    delay_samples: u32,
    sections: usize,
    /// The bytes after the fixed header, CRC excluded.
    rest: Reader<'a>,
}

/// Checks magic, version, total length (by the number format's section size) and CRC.
fn header(bytes: &[u8]) -> Result<Header<'_>, BlobError> {
    let short = |needed: usize| BlobError::Truncated {
        needed,
        got: bytes.len(),
    };
    let min_len = encoded_len(0);
    let mut r = Reader { rest: bytes };
    let magic: [u8; 4] = r.take().ok_or(short(min_len))?;
    if magic != MAGIC {
        return Err(BlobError::BadMagic);
    }
    let version = r.u16().ok_or(short(min_len))?;
    if version != FORMAT_VERSION && version != FORMAT_VERSION_NONLINEAR {
        return Err(BlobError::UnsupportedVersion { found: version });
    }
    let [format_code, frac_bits] = r.take().ok_or(short(min_len))?;
    let sample_rate_hz = r.f64().ok_or(short(min_len))?;
    let delay_samples = r.u32().ok_or(short(min_len))?;
    let sections = usize::from(r.u16().ok_or(short(min_len))?);
    let reserved = r.u16().ok_or(short(min_len))?;

    // Length, then integrity, before any value is trusted. An unknown number format is
    // measured as f32; its CRC then fails or it is refused by the caller.
    let expected = if format_code == (NumberFormat::Fixed { frac_bits }).code() {
        encoded_len_fixed(sections)
    } else if format_code == (NumberFormat::FixedDirect { frac_bits }).code() {
        encoded_len_direct(sections)
    } else if version == FORMAT_VERSION_NONLINEAR {
        encoded_len_nonlinear(sections, usize::from(reserved))
    } else {
        encoded_len(sections)
    };
    if bytes.len() < expected {
        return Err(short(expected));
    }
    if bytes.len() > expected {
        return Err(BlobError::TrailingBytes {
            expected,
            got: bytes.len(),
        });
    }
    let body_len = expected.saturating_sub(CRC_LEN);
    let (body, stored) = match (bytes.get(..body_len), bytes.get(body_len..)) {
        (Some(body), Some(tail)) => (body, tail),
        _ => return Err(short(expected)),
    };
    let stored = stored
        .first_chunk::<4>()
        .map(|c| u32::from_le_bytes(*c))
        .ok_or(short(expected))?;
    let computed = crc32(body);
    if computed != stored {
        return Err(BlobError::CrcMismatch { stored, computed });
    }
    // Offset 22: reserved in version 1, the correction's section count in version 2.
    let nonlinear_f32 =
        version == FORMAT_VERSION_NONLINEAR && format_code == NumberFormat::F32.code();
    if reserved != 0 && !nonlinear_f32 {
        return Err(BlobError::ReservedNotZero { offset: 22 });
    }
    if !(sample_rate_hz.is_finite() && sample_rate_hz > 0.0) {
        return Err(BlobError::InvalidSampleRate);
    }
    let after_header = body
        .get(HEADER_LEN.saturating_sub(4)..)
        .ok_or(short(expected))?;
    Ok(Header {
        version,
        lowpass_sections: if nonlinear_f32 {
            usize::from(reserved)
        } else {
            0
        },
        format_code,
        frac_bits,
        sample_rate_hz,
        delay_samples,
        sections,
        rest: Reader { rest: after_header },
    })
}

/// Parses and validates an `f32` blob for a board with room for `N` sections.
///
/// Checks, in order: length of the fixed header, magic, format version, total length against
/// the section count, CRC-32, reserved bytes, sample rate, number format, fractional bits,
/// section count against `N`, and finally every coefficient (finite, each section stable by
/// [`crate::compensator::MIN_POLE_MARGIN`]).
///
/// # Errors
/// The first [`BlobError`] found; never panics, whatever the bytes.
pub fn parse<const N: usize>(bytes: &[u8]) -> Result<CoefficientSet<N>, BlobError> {
    let mut h = header(bytes)?;
    let short = BlobError::Truncated {
        needed: encoded_len(h.sections),
        got: bytes.len(),
    };
    if h.format_code != NumberFormat::F32.code() {
        return Err(BlobError::UnsupportedNumberFormat {
            code: h.format_code,
        });
    }
    if h.frac_bits != 0 {
        return Err(BlobError::ReservedNotZero { offset: 7 });
    }
    if h.sections > N {
        return Err(BlobError::TooManySections {
            sections: h.sections,
            capacity: N,
        });
    }
    let gain = h.rest.f32().ok_or(short)?;
    let mut designed = [[0.0f64; 5]; N];
    for section in designed.iter_mut().take(h.sections) {
        for c in section.iter_mut() {
            *c = f64::from(h.rest.f32().ok_or(short)?);
        }
    }
    let used = designed.get(..h.sections).ok_or(short)?;
    // f32 -> f64 -> f32 is exact, so the board runs exactly the exported values.
    let cascade = CascadeCoefficients::new(f64::from(gain), used)?;
    let nonlinear = if h.version == FORMAT_VERSION_NONLINEAR {
        let short = BlobError::Truncated {
            needed: encoded_len_nonlinear(h.sections, h.lowpass_sections),
            got: bytes.len(),
        };
        if h.lowpass_sections > N {
            return Err(BlobError::TooManySections {
                sections: h.lowpass_sections,
                capacity: N,
            });
        }
        let gain = h.rest.f32().ok_or(short)?;
        let lowpass_gain = h.rest.f32().ok_or(short)?;
        let mut lowpass = [[0.0f64; 5]; N];
        for section in lowpass.iter_mut().take(h.lowpass_sections) {
            for c in section.iter_mut() {
                *c = f64::from(h.rest.f32().ok_or(short)?);
            }
        }
        let used = lowpass.get(..h.lowpass_sections).ok_or(short)?;
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
/// sections: the same header checks as [`parse`], then the fractional bits, the full scale and
/// every section as [`crate::fixed::FixedCascade::new`] checks it.
///
/// # Errors
/// The first [`BlobError`] found; never panics, whatever the bytes.
///
/// ```
/// use unlag::blob::{self, BlobError};
/// use unlag::fixed::{FixedSection, FixedState};
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
    let mut h = header(bytes)?;
    let short = BlobError::Truncated {
        needed: encoded_len_fixed(h.sections),
        got: bytes.len(),
    };
    if h.format_code != (NumberFormat::Fixed { frac_bits: 0 }).code() {
        return Err(BlobError::UnsupportedNumberFormat {
            code: h.format_code,
        });
    }
    if h.version != FORMAT_VERSION {
        return Err(BlobError::UnsupportedVersion { found: h.version });
    }
    if u32::from(h.frac_bits) != STATE_BITS {
        return Err(BlobError::UnsupportedFractionalBits { found: h.frac_bits });
    }
    if h.sections > N {
        return Err(BlobError::TooManySections {
            sections: h.sections,
            capacity: N,
        });
    }
    let output_exponent = h.rest.i32().ok_or(short)?;
    let full_scale = h.rest.f64().ok_or(short)?;
    if !(full_scale.is_finite() && full_scale > 0.0) {
        return Err(BlobError::InvalidFullScale);
    }
    let mut sections = [FixedSection::IDENTITY; N];
    for section in sections.iter_mut().take(h.sections) {
        let mut v = [0i32; 9];
        for x in &mut v {
            *x = h.rest.i32().ok_or(short)?;
        }
        let [shift, pad0, pad1, pad2]: [u8; 4] = h.rest.take().ok_or(short)?;
        if (pad0, pad1, pad2) != (0, 0, 0) {
            return Err(BlobError::ReservedNotZero {
                offset: bytes
                    .len()
                    .saturating_sub(h.rest.rest.len().saturating_add(3 + CRC_LEN)),
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
    let used = sections.get(..h.sections).ok_or(short)?;
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
/// room for `N` sections: the same header checks as [`parse`], then the fractional bits, the
/// full scale and every section as [`crate::fixed::direct::DirectCascade::new`] checks it.
///
/// # Errors
/// The first [`BlobError`] found; never panics, whatever the bytes.
///
/// ```
/// use unlag::blob::{self, BlobError};
/// use unlag::fixed::direct::{DirectSection, DirectState};
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
    let mut h = header(bytes)?;
    let short = BlobError::Truncated {
        needed: encoded_len_direct(h.sections),
        got: bytes.len(),
    };
    if h.format_code != (NumberFormat::FixedDirect { frac_bits: 0 }).code() {
        return Err(BlobError::UnsupportedNumberFormat {
            code: h.format_code,
        });
    }
    if h.version != FORMAT_VERSION {
        return Err(BlobError::UnsupportedVersion { found: h.version });
    }
    if u32::from(h.frac_bits) != COEFFICIENT_BITS {
        return Err(BlobError::UnsupportedFractionalBits { found: h.frac_bits });
    }
    if h.sections > N {
        return Err(BlobError::TooManySections {
            sections: h.sections,
            capacity: N,
        });
    }
    let output_exponent = h.rest.i32().ok_or(short)?;
    let full_scale = h.rest.f64().ok_or(short)?;
    if !(full_scale.is_finite() && full_scale > 0.0) {
        return Err(BlobError::InvalidFullScale);
    }
    let mut sections = [DirectSection::IDENTITY; N];
    for section in sections.iter_mut().take(h.sections) {
        let mut v = [0i32; 5];
        for x in &mut v {
            *x = h.rest.i32().ok_or(short)?;
        }
        let [b0, b1, b2, na1, na2] = v;
        *section = DirectSection {
            b: [b0, b1, b2],
            neg_a: [na1, na2],
        };
    }
    let used = sections.get(..h.sections).ok_or(short)?;
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
/// more than [`MAX_SECTIONS`] sections.
pub fn encode_direct(
    out: &mut [u8],
    sample_rate_hz: f64,
    delay_samples: u32,
    full_scale: f64,
    output_exponent: i32,
    sections: &[DirectSection],
) -> Result<usize, BlobError> {
    let count = u16::try_from(sections.len()).map_err(|_| BlobError::TooManySections {
        sections: sections.len(),
        capacity: MAX_SECTIONS,
    })?;
    let needed = encoded_len_direct(sections.len());
    let available = out.len();
    let too_small = BlobError::BufferTooSmall { needed, available };
    let out = out.get_mut(..needed).ok_or(too_small)?;
    let body_len = needed.saturating_sub(CRC_LEN);
    let (body, crc_out) = out.split_at_mut(body_len);
    let mut w = Writer {
        rest: body,
        ok: true,
    };
    w.put(&MAGIC);
    w.put(&FORMAT_VERSION.to_le_bytes());
    #[allow(clippy::cast_possible_truncation)]
    let frac_bits = COEFFICIENT_BITS as u8;
    w.put(&[NumberFormat::FixedDirect { frac_bits }.code(), frac_bits]);
    w.put(&sample_rate_hz.to_le_bytes());
    w.put(&delay_samples.to_le_bytes());
    w.put(&count.to_le_bytes());
    w.put(&0u16.to_le_bytes());
    w.put(&output_exponent.to_le_bytes());
    w.put(&full_scale.to_le_bytes());
    for s in sections {
        for v in s.b.iter().chain(&s.neg_a) {
            w.put(&v.to_le_bytes());
        }
    }
    if !w.ok {
        return Err(too_small);
    }
    let crc = crc32(body).to_le_bytes();
    for (dst, src) in crc_out.iter_mut().zip(crc) {
        *dst = src;
    }
    Ok(needed)
}

/// Writes a version-[`FORMAT_VERSION`] fixed-point blob (number format 1) into `out` and
/// returns its length ([`encoded_len_fixed`]`(sections.len())`).
///
/// # Errors
/// [`BlobError::BufferTooSmall`] when `out` is too short, [`BlobError::TooManySections`] for
/// more than [`MAX_SECTIONS`] sections.
pub fn encode_fixed(
    out: &mut [u8],
    sample_rate_hz: f64,
    delay_samples: u32,
    full_scale: f64,
    output_exponent: i32,
    sections: &[FixedSection],
) -> Result<usize, BlobError> {
    let count = u16::try_from(sections.len()).map_err(|_| BlobError::TooManySections {
        sections: sections.len(),
        capacity: MAX_SECTIONS,
    })?;
    let needed = encoded_len_fixed(sections.len());
    let available = out.len();
    let too_small = BlobError::BufferTooSmall { needed, available };
    let out = out.get_mut(..needed).ok_or(too_small)?;
    let body_len = needed.saturating_sub(CRC_LEN);
    let (body, crc_out) = out.split_at_mut(body_len);
    let mut w = Writer {
        rest: body,
        ok: true,
    };
    w.put(&MAGIC);
    w.put(&FORMAT_VERSION.to_le_bytes());
    #[allow(clippy::cast_possible_truncation)]
    let frac_bits = STATE_BITS as u8;
    w.put(&[NumberFormat::Fixed { frac_bits }.code(), frac_bits]);
    w.put(&sample_rate_hz.to_le_bytes());
    w.put(&delay_samples.to_le_bytes());
    w.put(&count.to_le_bytes());
    w.put(&0u16.to_le_bytes());
    w.put(&output_exponent.to_le_bytes());
    w.put(&full_scale.to_le_bytes());
    for s in sections {
        let [a11, a12, a21, a22] = s.a;
        let [b1, b2] = s.b;
        let [c1, c2] = s.c;
        for v in [a11, a12, a21, a22, b1, b2, c1, c2, s.d] {
            w.put(&v.to_le_bytes());
        }
        w.put(&[s.shift, 0, 0, 0]);
    }
    if !w.ok {
        return Err(too_small);
    }
    let crc = crc32(body).to_le_bytes();
    for (dst, src) in crc_out.iter_mut().zip(crc) {
        *dst = src;
    }
    Ok(needed)
}

/// Writes a version-[`FORMAT_VERSION`] `f32` blob into `out` and returns its length
/// ([`encoded_len`]`(sections.len())`). Values are written as given; [`parse`] validates them.
///
/// # Errors
/// [`BlobError::BufferTooSmall`] when `out` is too short, [`BlobError::TooManySections`] for
/// more than [`MAX_SECTIONS`] sections.
pub fn encode(
    out: &mut [u8],
    sample_rate_hz: f64,
    delay_samples: u32,
    gain: f32,
    sections: &[[f32; 5]],
) -> Result<usize, BlobError> {
    encode_any(out, sample_rate_hz, delay_samples, gain, sections, None)
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
/// As [`encode`]; [`BlobError::TooManySections`] also for more than [`MAX_SECTIONS`] low-pass
/// sections.
pub fn encode_nonlinear(
    out: &mut [u8],
    sample_rate_hz: f64,
    delay_samples: u32,
    gain: f32,
    sections: &[[f32; 5]],
    correction: &NonlinearCorrection<'_>,
) -> Result<usize, BlobError> {
    encode_any(
        out,
        sample_rate_hz,
        delay_samples,
        gain,
        sections,
        Some(correction),
    )
}

fn encode_any(
    out: &mut [u8],
    sample_rate_hz: f64,
    delay_samples: u32,
    gain: f32,
    sections: &[[f32; 5]],
    correction: Option<&NonlinearCorrection<'_>>,
) -> Result<usize, BlobError> {
    let count = |n: usize| {
        u16::try_from(n).map_err(|_| BlobError::TooManySections {
            sections: n,
            capacity: MAX_SECTIONS,
        })
    };
    let n = count(sections.len())?;
    let (version, m, needed) = match correction {
        Some(c) => (
            FORMAT_VERSION_NONLINEAR,
            count(c.lowpass.len())?,
            encoded_len_nonlinear(sections.len(), c.lowpass.len()),
        ),
        None => (FORMAT_VERSION, 0, encoded_len(sections.len())),
    };
    let available = out.len();
    let too_small = BlobError::BufferTooSmall { needed, available };
    let out = out.get_mut(..needed).ok_or(too_small)?;
    let body_len = needed.saturating_sub(CRC_LEN);
    let (body, crc_out) = out.split_at_mut(body_len);
    let mut w = Writer {
        rest: body,
        ok: true,
    };
    w.put(&MAGIC);
    w.put(&version.to_le_bytes());
    w.put(&[NumberFormat::F32.code(), 0]);
    w.put(&sample_rate_hz.to_le_bytes());
    w.put(&delay_samples.to_le_bytes());
    w.put(&n.to_le_bytes());
    w.put(&m.to_le_bytes());
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
    if !w.ok {
        return Err(too_small);
    }
    let crc = crc32(body).to_le_bytes();
    for (dst, src) in crc_out.iter_mut().zip(crc) {
        *dst = src;
    }
    Ok(needed)
}

/// A cursor that writes fields into a buffer and remembers whether all of them fitted.
struct Writer<'a> {
    rest: &'a mut [u8],
    ok: bool,
}

impl Writer<'_> {
    fn put(&mut self, bytes: &[u8]) {
        let rest = core::mem::take(&mut self.rest);
        if rest.len() < bytes.len() {
            self.ok = false;
            self.rest = rest;
            return;
        }
        let (head, tail) = rest.split_at_mut(bytes.len());
        head.copy_from_slice(bytes);
        self.rest = tail;
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;

    const SECTIONS: [[f32; 5]; 2] = [[1.0, -1.5, 0.6, -1.2, 0.72], [0.3, 0.2, 0.0, -0.5, 0.0]];

    fn blob() -> ([u8; encoded_len(2)], usize) {
        let mut buf = [0u8; encoded_len(2)];
        let n = encode(&mut buf, 10_000.0, 21, 0.125, &SECTIONS).unwrap();
        (buf, n)
    }

    #[test]
    fn crc_is_the_iso_hdlc_one() {
        assert_eq!(crc32(b"123456789"), 0xCBF4_3926);
    }

    #[test]
    fn round_trip_keeps_every_value() {
        let (buf, n) = blob();
        assert_eq!(n, 28 + 2 * 20 + 4);
        let set: CoefficientSet<4> = parse(&buf).unwrap();
        assert_eq!(set.sample_rate_hz, 10_000.0);
        assert_eq!(set.delay_samples, 21);
        assert_eq!(set.sections, 2);
        let direct =
            CascadeCoefficients::<f32, 4>::new(0.125, &SECTIONS.map(|s| s.map(f64::from))).unwrap();
        assert_eq!(set.cascade, direct);
    }

    #[test]
    fn typed_errors_for_each_field() {
        let (buf, n) = blob();
        assert_eq!(
            parse::<4>(&buf[..n - 1]),
            Err(BlobError::Truncated {
                needed: n,
                got: n - 1
            })
        );
        assert!(matches!(
            parse::<4>(&buf[..3]),
            Err(BlobError::Truncated { .. })
        ));
        assert!(matches!(parse::<4>(&[]), Err(BlobError::Truncated { .. })));
        let mut long = [0u8; encoded_len(2) + 1];
        long[..n].copy_from_slice(&buf);
        assert!(matches!(
            parse::<4>(&long),
            Err(BlobError::TrailingBytes { .. })
        ));
        let mut bad = buf;
        bad[0] = b'X';
        assert_eq!(parse::<4>(&bad), Err(BlobError::BadMagic));
        let mut bad = buf;
        bad[4] = 3;
        assert_eq!(
            parse::<4>(&bad),
            Err(BlobError::UnsupportedVersion { found: 3 })
        );
        let mut bad = buf;
        bad[30] ^= 1;
        assert!(matches!(
            parse::<4>(&bad),
            Err(BlobError::CrcMismatch { .. })
        ));
        assert_eq!(
            parse::<1>(&buf),
            Err(BlobError::TooManySections {
                sections: 2,
                capacity: 1
            })
        );
        // Intact but incompatible: re-sign after changing a field.
        let resign = |mut b: [u8; encoded_len(2)]| {
            let crc = crc32(&b[..n - 4]).to_le_bytes();
            b[n - 4..].copy_from_slice(&crc);
            b
        };
        let mut unknown = buf;
        unknown[6] = 7;
        assert_eq!(
            parse::<4>(&resign(unknown)),
            Err(BlobError::UnsupportedNumberFormat { code: 7 })
        );
        let mut frac = buf;
        frac[7] = 3;
        assert_eq!(
            parse::<4>(&resign(frac)),
            Err(BlobError::ReservedNotZero { offset: 7 })
        );
        let mut res = buf;
        res[23] = 1;
        assert_eq!(
            parse::<4>(&resign(res)),
            Err(BlobError::ReservedNotZero { offset: 22 })
        );
        let mut fs = buf;
        fs[8..16].copy_from_slice(&(-1.0f64).to_le_bytes());
        assert_eq!(parse::<4>(&resign(fs)), Err(BlobError::InvalidSampleRate));
        let mut unstable = buf;
        // Section 0: a2 = 1.5 puts its poles outside the unit circle.
        unstable[28 + 16..28 + 20].copy_from_slice(&1.5f32.to_le_bytes());
        assert!(matches!(
            parse::<4>(&resign(unstable)),
            Err(BlobError::InvalidCoefficients(
                InverseError::UnstableSection { index: 0, .. }
            ))
        ));
        let mut nan = buf;
        nan[24..28].copy_from_slice(&f32::NAN.to_le_bytes());
        assert_eq!(
            parse::<4>(&resign(nan)),
            Err(BlobError::InvalidCoefficients(InverseError::NonFinite))
        );
    }

    #[test]
    fn update_keeps_the_old_set_on_error() {
        let (buf, _) = blob();
        let mut set: CoefficientSet<4> = parse(&buf).unwrap();
        let before = set;
        let mut bad = buf;
        bad[40] ^= 0x80;
        assert!(set.update(&bad).is_err());
        assert_eq!(set, before);
        let mut other = [0u8; encoded_len(1)];
        let n = encode(&mut other, 5_000.0, 2, 1.0, &SECTIONS[..1]).unwrap();
        set.update(&other[..n]).unwrap();
        assert_eq!(set.sample_rate_hz, 5_000.0);
        assert_eq!(set.sections, 1);
    }

    /// A stable rotation section (poles 0.5 +- 0.5j) in Q2.30.
    const ROTATION: FixedSection = FixedSection {
        a: [1 << 29, -(1 << 29), 1 << 29, 1 << 29],
        b: [1 << 28, 0],
        c: [1 << 29, 1 << 27],
        d: 1 << 30,
        shift: 30,
    };

    #[test]
    fn direct_round_trip_and_typed_errors() {
        let s = DirectSection {
            b: [1 << 28, -(1 << 29), 1 << 28],
            neg_a: [1_900_000_000, -900_000_000],
        };
        let mut buf = [0u8; encoded_len_direct(2)];
        let n = encode_direct(&mut buf, 50_000.0, 3, 1000.0, 2, &[s, s]).unwrap();
        assert_eq!(n, 28 + 8 + 2 * 20 + 4);
        let set: DirectCoefficientSet<4> = parse_direct(&buf).unwrap();
        assert_eq!(
            (set.sample_rate_hz, set.delay_samples, set.full_scale),
            (50_000.0, 3, 1000.0)
        );
        assert_eq!((set.output_exponent, set.sections), (2, 2));
        assert_eq!(set.cascade, DirectCascade::new(&[s, s]).unwrap());
        // The three formats do not read each other.
        assert_eq!(
            parse::<4>(&buf),
            Err(BlobError::UnsupportedNumberFormat { code: 2 })
        );
        assert_eq!(
            parse_fixed::<4>(&buf),
            Err(BlobError::UnsupportedNumberFormat { code: 2 })
        );
        let mut fixed = [0u8; encoded_len_fixed(1)];
        encode_fixed(&mut fixed, 50_000.0, 3, 1000.0, 2, &[ROTATION]).unwrap();
        assert_eq!(
            parse_direct::<4>(&fixed),
            Err(BlobError::UnsupportedNumberFormat { code: 1 })
        );
        assert!(matches!(
            parse_direct::<1>(&buf),
            Err(BlobError::TooManySections { .. })
        ));
        // An unstable section, correctly signed, is refused by the board's validation.
        let bad = DirectSection {
            neg_a: [1 << 30, 1 << 29],
            ..s
        };
        let mut b = [0u8; encoded_len_direct(1)];
        encode_direct(&mut b, 50_000.0, 3, 1000.0, 2, &[bad]).unwrap();
        assert!(matches!(
            parse_direct::<4>(&b),
            Err(BlobError::InvalidDirectSections(_))
        ));
        // Every single flipped bit is refused.
        for i in 0..n * 8 {
            let mut c = buf;
            c[i / 8] ^= 1 << (i % 8);
            assert!(parse_direct::<4>(&c).is_err(), "bit {i}");
        }
    }

    #[test]
    fn fixed_round_trip_and_typed_errors() {
        let mut buf = [0u8; encoded_len_fixed(2)];
        let n = encode_fixed(&mut buf, 50_000.0, 3, 1000.0, 2, &[ROTATION, ROTATION]).unwrap();
        assert_eq!(n, 28 + 8 + 2 * 40 + 4);
        let set: FixedCoefficientSet<4> = parse_fixed(&buf).unwrap();
        assert_eq!(set.sample_rate_hz, 50_000.0);
        assert_eq!(set.delay_samples, 3);
        assert_eq!(set.full_scale, 1000.0);
        assert_eq!(set.output_exponent, 2);
        assert_eq!(set.sections, 2);
        assert_eq!(
            set.cascade,
            FixedCascade::new(&[ROTATION, ROTATION]).unwrap()
        );
        // The two formats do not read each other.
        assert_eq!(
            parse::<4>(&buf),
            Err(BlobError::UnsupportedNumberFormat { code: 1 })
        );
        let (f32_blob, _) = blob();
        assert_eq!(
            parse_fixed::<4>(&f32_blob),
            Err(BlobError::UnsupportedNumberFormat { code: 0 })
        );
        let resign = |mut b: [u8; encoded_len_fixed(2)]| {
            let crc = crc32(&b[..n - 4]).to_le_bytes();
            b[n - 4..].copy_from_slice(&crc);
            b
        };
        let mut bits = buf;
        bits[7] = 15;
        assert_eq!(
            parse_fixed::<4>(&resign(bits)),
            Err(BlobError::UnsupportedFractionalBits { found: 15 })
        );
        let mut fs = buf;
        fs[28..36].copy_from_slice(&0.0f64.to_le_bytes());
        assert_eq!(
            parse_fixed::<4>(&resign(fs)),
            Err(BlobError::InvalidFullScale)
        );
        let mut pad = buf;
        pad[36 + 37] = 1;
        assert_eq!(
            parse_fixed::<4>(&resign(pad)),
            Err(BlobError::ReservedNotZero { offset: 36 + 37 })
        );
        let mut unstable = buf;
        // a11 = a22 = 2^30 (radius > 1): not a stable rotation.
        unstable[36..40].copy_from_slice(&(1i32 << 30).to_le_bytes());
        unstable[48..52].copy_from_slice(&(1i32 << 30).to_le_bytes());
        assert!(matches!(
            parse_fixed::<4>(&resign(unstable)),
            Err(BlobError::InvalidFixedSections(_))
        ));
        assert_eq!(
            parse_fixed::<1>(&buf),
            Err(BlobError::TooManySections {
                sections: 2,
                capacity: 1
            })
        );
        for byte in 0..n {
            for bit in 0..8 {
                let mut b = buf;
                b[byte] ^= 1 << bit;
                assert!(parse_fixed::<4>(&b).is_err(), "flip {byte}:{bit}");
            }
        }
        let mut set2 = set;
        assert!(set2.update(&buf[..n - 1]).is_err());
        assert_eq!(set2, set);
    }

    #[test]
    fn encode_refuses_a_short_buffer() {
        let mut small = [0u8; 10];
        assert_eq!(
            encode(&mut small, 1.0, 0, 1.0, &SECTIONS),
            Err(BlobError::BufferTooSmall {
                needed: 72,
                available: 10
            })
        );
    }

    const LOWPASS: [[f32; 5]; 1] = [[0.25, 0.5, 0.25, -0.2, 0.1]];

    fn blob_v2() -> ([u8; encoded_len_nonlinear(2, 1)], usize) {
        let mut buf = [0u8; encoded_len_nonlinear(2, 1)];
        let correction = NonlinearCorrection {
            gain: 37.5,
            lowpass_gain: 0.9,
            lowpass: &LOWPASS,
        };
        let n = encode_nonlinear(&mut buf, 20_000.0, 30, 0.125, &SECTIONS, &correction).unwrap();
        (buf, n)
    }

    #[test]
    fn version_2_carries_the_nonlinear_correction() {
        let (buf, n) = blob_v2();
        assert_eq!(n, 28 + 2 * 20 + 8 + 20 + 4);
        assert_eq!(
            u16::from_le_bytes([buf[4], buf[5]]),
            FORMAT_VERSION_NONLINEAR
        );
        let set: CoefficientSet<4> = parse(&buf).unwrap();
        assert_eq!(set.delay_samples, 30);
        let direct = NonlinearDampingCoefficients::<f32, 4>::new(
            37.5,
            0.9,
            &LOWPASS.map(|s| s.map(f64::from)),
        )
        .unwrap();
        assert_eq!(set.nonlinear, Some(direct));
        // A version-1 blob has none.
        let (v1, _) = blob();
        assert_eq!(parse::<4>(&v1).unwrap().nonlinear, None);

        // Every field of the extension is checked.
        let resign = |mut b: [u8; encoded_len_nonlinear(2, 1)]| {
            let crc = crc32(&b[..n - 4]).to_le_bytes();
            b[n - 4..].copy_from_slice(&crc);
            b
        };
        assert!(matches!(
            parse::<4>(&buf[..n - 1]),
            Err(BlobError::Truncated { .. })
        ));
        let mut bad = buf;
        bad[70] ^= 0x10;
        assert!(matches!(
            parse::<4>(&bad),
            Err(BlobError::CrcMismatch { .. })
        ));
        // The correction's gain (offset 68) not finite.
        let mut bad = buf;
        bad[68..72].copy_from_slice(&f32::NAN.to_le_bytes());
        assert_eq!(
            parse::<4>(&resign(bad)),
            Err(BlobError::InvalidCoefficients(InverseError::NonFinite))
        );
        // An unstable low-pass section (a1 = -2.1 at offset 76 + 12).
        let mut bad = buf;
        bad[88..92].copy_from_slice(&(-2.1f32).to_le_bytes());
        assert!(matches!(
            parse::<4>(&resign(bad)),
            Err(BlobError::InvalidCoefficients(
                InverseError::UnstableSection { .. }
            ))
        ));
        // More low-pass sections than the capacity.
        let mut wide = [0u8; encoded_len_nonlinear(1, 3)];
        let lp = [LOWPASS[0]; 3];
        let c = NonlinearCorrection {
            gain: 1.0,
            lowpass_gain: 1.0,
            lowpass: &lp,
        };
        let m = encode_nonlinear(&mut wide, 1000.0, 1, 1.0, &SECTIONS[..1], &c).unwrap();
        assert_eq!(
            parse::<2>(&wide[..m]),
            Err(BlobError::TooManySections {
                sections: 3,
                capacity: 2
            })
        );
        // A version-2 header on a version-1 length.
        let (v1, n1) = blob();
        let mut bad = v1;
        bad[4] = 2;
        assert!(matches!(
            parse::<4>(&bad[..n1]),
            Err(BlobError::Truncated { .. })
        ));
        // The parser never panics on any single-byte corruption of the extension.
        for i in 0..n {
            let mut b = buf;
            b[i] = b[i].wrapping_add(0x5a);
            let _ = parse::<4>(&b);
            let _ = parse::<4>(&resign(b));
        }
    }
}
