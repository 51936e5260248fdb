//! The coefficient blob: a versioned binary image of the board's compensator, for updating a
//! running board over a serial link (`unlag export --format bin`).
//!
//! This module owns the wire format, both directions: [`encode`] (used by the host's
//! `unlag export`, and by a board that wants to echo its set) and [`parse`], the board-side
//! parser, with their fixed-point kin [`encode_fixed`], [`parse_fixed`], [`encode_direct`] and
//! [`parse_direct`]. The header and the CRC are written by one writer and read and checked by
//! one reader for every number format ([`read_header`] gives its fields to a caller that
//! describes a blob); each format adds only what lies between them. All of it is `no_std`,
//! allocation-free and panic-free. The parser checks every field and answers a corrupted,
//! truncated or incompatible blob with a typed [`BlobError`]; a parsed
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
//! ([`crate::board::compensator::NonlinearDampingCoefficients`], `f32` only) is written as format
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
//! byte is [`crate::board::fixed::STATE_BITS`] (30), the four bytes at offset 24 hold the output
//! exponent `e` (`i32`: the output is Q1.31 of `full_scale 2^e`), an `f64` full scale (the
//! input code `2^31`, in the probe's units) follows at offset 28, and each section is 40
//! bytes: `a11 a12 a21 a22 b1 b2 c1 c2 d` as `i32`, `shift` as `u8` and three zero bytes
//! (see [`crate::board::fixed::FixedSection`]); the CRC-32 ends the blob as before.
//!
//! With number format 2 (the direct form of the fixed-point compensator, [`parse_direct`],
//! [`encode_direct`]) the header is the same as for number format 1 (fractional bits
//! [`crate::board::fixed::direct::COEFFICIENT_BITS`], output exponent, `f64` full scale) and each
//! section is 20 bytes: `b0 b1 b2 na1 na2` as `i32`, with `na = -a` **negated** (see
//! [`crate::board::fixed::direct::DirectSection`]).
//!
//! Sections follow the crate's sign convention (see [`crate::board::compensator`]):
//! `y = b0 x + b1 x[k-1] + b2 x[k-2] - a1 y[k-1] - a2 y[k-2]`. The CRC detects every single-bit
//! error and every burst up to 32 bits; the checks of magic, version, length, number format,
//! reserved bytes, sample rate and stability catch an incompatible but intact blob.
//!
//! # Example
//!
//! ```
//! use unlag::board::blob::{self, CoefficientSet};
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

use crate::board::compensator::InverseError;
use crate::board::fixed::direct::DirectError;
use crate::board::fixed::{FixedError, STATE_BITS};

mod fixed;
mod float;
mod header;

pub use fixed::{
    encode_direct, encode_fixed, parse_direct, parse_fixed, DirectCoefficientSet,
    FixedCoefficientSet, FixedPointSet,
};
pub use float::{encode, encode_nonlinear, parse, CoefficientSet, NonlinearCorrection};
pub use header::{read_header, BlobHeader};

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
    /// [`crate::board::fixed::FixedCascade`], read by [`parse_fixed`]; [`parse`] refuses it
    /// with [`BlobError::UnsupportedNumberFormat`].
    Fixed {
        /// Fractional bits of the coefficient format.
        frac_bits: u8,
    },
    /// The direct form of the fixed-point compensator (code 2):
    /// [`crate::board::fixed::direct::DirectCascade`], read by [`parse_direct`].
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
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
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
    /// A fixed-point blob's fractional bits are not [`crate::board::fixed::STATE_BITS`].
    UnsupportedFractionalBits {
        /// The value found at offset 7.
        found: u8,
    },
    /// A fixed-point blob's full scale is not finite and positive.
    InvalidFullScale,
    /// The fixed-point sections are refused by [`crate::board::fixed::FixedCascade::new`].
    InvalidFixedSections(FixedError),
    /// The direct-form sections are refused by
    /// [`crate::board::fixed::direct::DirectCascade::new`].
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

impl From<InverseError> for BlobError {
    fn from(e: InverseError) -> Self {
        Self::InvalidCoefficients(e)
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;
    use crate::board::compensator::{CascadeCoefficients, NonlinearDampingCoefficients};
    use crate::board::fixed::direct::{DirectCascade, DirectSection};
    use crate::board::fixed::{FixedCascade, FixedSection};

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
