//! The frame every blob shares: the header at offsets 0..24 and the trailing CRC-32, written
//! by one writer ([`write`]) and read and checked by one reader ([`read`], [`Header::expect`]),
//! with the cursors that move over the bytes without panicking.
//!
//! The number formats differ only in what lies between the header and the CRC (see the layout
//! in [`super`]); their encoders hand [`write`] a closure that writes it, their parsers read it
//! from [`Header::rest`]. [`read_header`] is the same reader for a caller outside the blob
//! module: the frame's version, number format and stored CRC, without parsing the body.

use super::{
    crc32, encoded_len, encoded_len_direct, encoded_len_fixed, encoded_len_nonlinear, BlobError,
    NumberFormat, CRC_LEN, FORMAT_VERSION, FORMAT_VERSION_NONLINEAR, HEADER_LEN, MAGIC,
    MAX_SECTIONS,
};

/// Offset of the field that is reserved in version 1 and the correction's low-pass section
/// count in an `f32` version-2 blob.
const RESERVED_OFFSET: usize = 22;

/// Offset of the fractional-bits byte (reserved, zero, in an `f32` blob).
const FRAC_BITS_OFFSET: usize = 7;

/// A cursor over the blob that hands out fixed-size fields without panicking, and knows the
/// offset in the blob of the next field.
pub(super) struct Reader<'a> {
    rest: &'a [u8],
    offset: usize,
}

impl Reader<'_> {
    pub(super) fn take<const K: usize>(&mut self) -> Option<[u8; K]> {
        let (head, rest) = self.rest.split_first_chunk::<K>()?;
        self.rest = rest;
        self.offset = self.offset.saturating_add(K);
        Some(*head)
    }
    fn u16(&mut self) -> Option<u16> {
        self.take().map(u16::from_le_bytes)
    }
    fn u32(&mut self) -> Option<u32> {
        self.take().map(u32::from_le_bytes)
    }
    pub(super) fn i32(&mut self) -> Option<i32> {
        self.take().map(i32::from_le_bytes)
    }
    pub(super) fn f32(&mut self) -> Option<f32> {
        self.take().map(f32::from_le_bytes)
    }
    fn f64(&mut self) -> Option<f64> {
        self.take().map(f64::from_le_bytes)
    }
    /// Offset in the blob of the next byte this reader hands out.
    pub(super) fn offset(&self) -> usize {
        self.offset
    }
    /// `count` sections of five `f32`, widened exactly to `f64`, into an array of `N` (the
    /// rest zero); `None` when the bytes run out or `count > N`.
    pub(super) fn f32_sections<const N: usize>(&mut self, count: usize) -> Option<[[f64; 5]; N]> {
        let mut sections = [[0.0f64; 5]; N];
        for section in sections.get_mut(..count)? {
            for c in section.iter_mut() {
                *c = f64::from(self.f32()?);
            }
        }
        Some(sections)
    }
}

/// A cursor that writes fields into a buffer and remembers whether all of them fitted.
pub(super) struct Writer<'a> {
    rest: &'a mut [u8],
    ok: bool,
}

impl Writer<'_> {
    pub(super) fn put(&mut self, bytes: &[u8]) {
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

    /// The fixed-point scale after the header (both fixed-point number formats): the output
    /// exponent at offset 24, the `f64` full scale at offset 28.
    pub(super) fn fixed_scale(&mut self, output_exponent: i32, full_scale: f64) {
        self.put(&output_exponent.to_le_bytes());
        self.put(&full_scale.to_le_bytes());
    }
}

/// The header fields a blob is written with.
pub(super) struct Fields {
    /// [`FORMAT_VERSION`], or [`FORMAT_VERSION_NONLINEAR`] for an `f32` blob with the
    /// correction.
    pub(super) version: u16,
    /// The number format (offset 6) with its fractional bits (offset 7).
    pub(super) format: NumberFormat,
    pub(super) sample_rate_hz: f64,
    pub(super) delay_samples: u32,
    /// The section count (offset 20).
    pub(super) sections: usize,
    /// Offset 22: the correction's low-pass section count in a version-2 blob, else 0.
    pub(super) lowpass_sections: usize,
}

/// A count as the `u16` the header stores.
fn count(sections: usize) -> Result<u16, BlobError> {
    u16::try_from(sections).map_err(|_| BlobError::TooManySections {
        sections,
        capacity: MAX_SECTIONS,
    })
}

/// Writes one blob of `len` bytes into `out`: the header `fields`, then what `body` writes
/// (everything between the header and the CRC), then the CRC-32 of all of it. Returns `len`.
///
/// # Errors
/// [`BlobError::TooManySections`] for a count above [`MAX_SECTIONS`] (checked first),
/// [`BlobError::BufferTooSmall`] when `out` is shorter than `len` or the fields do not fit.
pub(super) fn write(
    out: &mut [u8],
    len: usize,
    fields: &Fields,
    body: impl FnOnce(&mut Writer<'_>),
) -> Result<usize, BlobError> {
    let sections = count(fields.sections)?;
    let lowpass_sections = count(fields.lowpass_sections)?;
    let too_small = BlobError::BufferTooSmall {
        needed: len,
        available: out.len(),
    };
    let out = out.get_mut(..len).ok_or(too_small)?;
    let (covered, crc_out) = out.split_at_mut(len.saturating_sub(CRC_LEN));
    let mut w = Writer {
        rest: covered,
        ok: true,
    };
    let frac_bits = match fields.format {
        NumberFormat::F32 => 0,
        NumberFormat::Fixed { frac_bits } | NumberFormat::FixedDirect { frac_bits } => frac_bits,
    };
    w.put(&MAGIC);
    w.put(&fields.version.to_le_bytes());
    w.put(&[fields.format.code(), frac_bits]);
    w.put(&fields.sample_rate_hz.to_le_bytes());
    w.put(&fields.delay_samples.to_le_bytes());
    w.put(&sections.to_le_bytes());
    w.put(&lowpass_sections.to_le_bytes());
    body(&mut w);
    if !w.ok {
        return Err(too_small);
    }
    let crc = crc32(covered).to_le_bytes();
    for (dst, src) in crc_out.iter_mut().zip(crc) {
        *dst = src;
    }
    Ok(len)
}

/// The fields every blob starts with, checked for length and integrity by [`read`].
pub(super) struct Header<'a> {
    pub(super) version: u16,
    /// Version 2: the correction's low-pass section count (offset 22).
    pub(super) lowpass_sections: usize,
    format_code: u8,
    frac_bits: u8,
    pub(super) sample_rate_hz: f64,
    pub(super) delay_samples: u32,
    pub(super) sections: usize,
    /// The blob's length, checked against the fields.
    len: usize,
    /// The CRC-32 stored at the end (checked against the contents).
    stored_crc: u32,
    /// The bytes after the header (offset 24 on), CRC excluded.
    pub(super) rest: Reader<'a>,
}

/// Checks magic, version, total length (by the number format's section size and the
/// section counts), CRC-32, the reserved field at offset 22 and the sample rate: everything
/// that does not depend on which number format the caller reads.
pub(super) fn read(bytes: &[u8]) -> Result<Header<'_>, BlobError> {
    let short = |needed: usize| BlobError::Truncated {
        needed,
        got: bytes.len(),
    };
    let min_len = encoded_len(0);
    let mut r = Reader {
        rest: bytes,
        offset: 0,
    };
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
        return Err(BlobError::ReservedNotZero {
            offset: RESERVED_OFFSET,
        });
    }
    if !(sample_rate_hz.is_finite() && sample_rate_hz > 0.0) {
        return Err(BlobError::InvalidSampleRate);
    }
    let after_header = HEADER_LEN.saturating_sub(4);
    let rest = body.get(after_header..).ok_or(short(expected))?;
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
        len: expected,
        stored_crc: stored,
        rest: Reader {
            rest,
            offset: after_header,
        },
    })
}

/// What the frame of a blob says about it: the fields every number format shares, read and
/// checked by the reader the parsers start with ([`read_header`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub struct BlobHeader {
    /// Format version (offset 4): [`FORMAT_VERSION`], or [`FORMAT_VERSION_NONLINEAR`] for an
    /// `f32` blob with the nonlinear-damping correction.
    pub format_version: u16,
    /// The number format (offset 6) with the fractional bits stored at offset 7.
    pub number_format: NumberFormat,
    /// The CRC-32 stored at the end of the blob, equal to the one computed over its contents.
    pub crc32: u32,
}

/// Reads and checks the frame of `bytes` as every parser does before it reads the body: magic,
/// version, total length, CRC-32, the reserved field at offset 22 and the sample rate, then the
/// number format code, which must be one this crate knows. No field of the body is read, so a
/// blob this accepts can still be refused by its format's parser ([`super::parse`],
/// [`super::parse_fixed`], [`super::parse_direct`]: capacity, fractional bits, version of a
/// fixed-point blob, coefficients); a blob this refuses, every parser refuses with the same
/// error. `no_std`, allocation-free and panic-free.
///
/// # Errors
/// The [`BlobError`] of the parsers' header checks, and
/// [`BlobError::UnsupportedNumberFormat`] for an unknown number format code.
///
/// ```
/// use unlag::board::blob::{self, NumberFormat};
/// let mut buf = [0u8; blob::encoded_len(1)];
/// let n = blob::encode(&mut buf, 10_000.0, 3, 0.5, &[[1.0, -0.5, 0.0, -0.25, 0.0]]).unwrap();
/// let header = blob::read_header(&buf[..n]).unwrap();
/// assert_eq!(header.format_version, blob::FORMAT_VERSION);
/// assert_eq!(header.number_format, NumberFormat::F32);
/// assert_eq!(header.crc32, blob::crc32(&buf[..n - blob::CRC_LEN]));
/// ```
pub fn read_header(bytes: &[u8]) -> Result<BlobHeader, BlobError> {
    let header = read(bytes)?;
    Ok(BlobHeader {
        format_version: header.version,
        number_format: header.number_format()?,
        crc32: header.stored_crc,
    })
}

impl Header<'_> {
    /// The number format the code at offset 6 names, with the fractional bits at offset 7;
    /// [`BlobError::UnsupportedNumberFormat`] for a code this crate does not know.
    fn number_format(&self) -> Result<NumberFormat, BlobError> {
        let frac_bits = self.frac_bits;
        [
            NumberFormat::F32,
            NumberFormat::Fixed { frac_bits },
            NumberFormat::FixedDirect { frac_bits },
        ]
        .into_iter()
        .find(|format| format.code() == self.format_code)
        .ok_or(BlobError::UnsupportedNumberFormat {
            code: self.format_code,
        })
    }

    /// The checks of the parser for `format` on a board with room for `capacity` sections,
    /// in order: the number format, the version (fixed point has version 1 only), the
    /// fractional bits (zero for `f32`, the format's own for fixed point), the section count.
    pub(super) fn expect(&self, format: NumberFormat, capacity: usize) -> Result<(), BlobError> {
        if self.format_code != format.code() {
            return Err(BlobError::UnsupportedNumberFormat {
                code: self.format_code,
            });
        }
        match format {
            NumberFormat::F32 => {
                if self.frac_bits != 0 {
                    return Err(BlobError::ReservedNotZero {
                        offset: FRAC_BITS_OFFSET,
                    });
                }
            }
            NumberFormat::Fixed { frac_bits } | NumberFormat::FixedDirect { frac_bits } => {
                if self.version != FORMAT_VERSION {
                    return Err(BlobError::UnsupportedVersion {
                        found: self.version,
                    });
                }
                if self.frac_bits != frac_bits {
                    return Err(BlobError::UnsupportedFractionalBits {
                        found: self.frac_bits,
                    });
                }
            }
        }
        if self.sections > capacity {
            return Err(BlobError::TooManySections {
                sections: self.sections,
                capacity,
            });
        }
        Ok(())
    }

    /// The error for a field the length promised but the reader did not find. [`read`] has
    /// checked the length, so this is never returned; it keeps the reading panic-free.
    pub(super) fn truncated(&self) -> BlobError {
        BlobError::Truncated {
            needed: self.len,
            got: self.len,
        }
    }

    /// The fixed-point scale after the header: the output exponent (offset 24) and the full
    /// scale (offset 28), which must be finite and positive.
    pub(super) fn fixed_scale(&mut self) -> Result<(i32, f64), BlobError> {
        let output_exponent = self.rest.i32().ok_or(self.truncated())?;
        let full_scale = self.rest.f64().ok_or(self.truncated())?;
        if !(full_scale.is_finite() && full_scale > 0.0) {
            return Err(BlobError::InvalidFullScale);
        }
        Ok((output_exponent, full_scale))
    }
}
