//! Reading a coefficient blob back on the PC, as the board will, before it is flashed or sent:
//! the board's own parser ([`crate::board::blob::parse`], [`crate::board::blob::parse_fixed`]) decides
//! whether it is valid, and a valid blob is described field by field.

use crate::board::blob::{self, BlobError, NumberFormat};
use crate::board::compensator::section_pole_radius;

/// Sections a board built with [`crate::board::compensator::MAX_TEST_ORDER`] room reads.
const CAPACITY: usize = crate::board::compensator::MAX_TEST_ORDER;

/// What a valid blob holds.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct BlobSummary {
    /// Total length in bytes.
    pub bytes: usize,
    /// Format version (1 linear, 2 with the nonlinear-damping correction).
    pub format_version: u16,
    /// `f32` or `fixed`.
    pub number_format: &'static str,
    /// Sample rate in Hz.
    pub sample_rate_hz: f64,
    /// The model's delay in samples.
    pub delay_samples: u32,
    /// Second-order sections of the compensator.
    pub sections: usize,
    /// Input gain (`f32` blobs).
    pub gain: Option<f64>,
    /// Each section as `[b0, b1, b2, a1, a2]` (`f32` blobs).
    pub coefficients: Vec<[f64; 5]>,
    /// Largest pole radius of each section (`f32` blobs): all below 1.
    pub pole_radius: Vec<f64>,
    /// Steady-state gain of the cascade (`f32` blobs): about 1 over the probe's DC gain.
    pub dc_gain: Option<f64>,
    /// Whether the nonlinear-damping correction is present.
    pub nonlinear: bool,
    /// ADC full scale (fixed-point blobs).
    pub full_scale: Option<f64>,
    /// Output scale exponent (fixed-point blobs).
    pub output_exponent: Option<i32>,
    /// The stored CRC-32 (checked by the parser).
    pub crc32: u32,
}

/// Parses `bytes` with the board's parser for its number format (a board with room for
/// [`crate::board::compensator::MAX_TEST_ORDER`] sections) and describes it.
///
/// # Errors
/// The board parser's [`BlobError`].
pub fn read(bytes: &[u8]) -> Result<BlobSummary, BlobError> {
    // The frame, read and checked by the board's own header reader (the one its parsers start
    // with, so a blob it refuses gets the parsers' error); the number format picks the parser.
    let header = blob::read_header(bytes)?;
    // The two fixed-point forms carry the same header fields; only their parsers differ.
    let fixed = |number_format, sample_rate_hz, delay_samples, sections, full_scale, exponent| {
        BlobSummary {
            bytes: bytes.len(),
            format_version: header.format_version,
            number_format,
            sample_rate_hz,
            delay_samples,
            sections,
            gain: None,
            coefficients: Vec::new(),
            pole_radius: Vec::new(),
            dc_gain: None,
            nonlinear: false,
            full_scale: Some(full_scale),
            output_exponent: Some(exponent),
            crc32: header.crc32,
        }
    };
    match header.number_format {
        NumberFormat::FixedDirect { .. } => {
            let s = blob::parse_direct::<CAPACITY>(bytes)?;
            return Ok(fixed(
                "fixed-direct",
                s.sample_rate_hz,
                s.delay_samples,
                s.sections,
                s.full_scale,
                s.output_exponent,
            ));
        }
        NumberFormat::Fixed { .. } => {
            let s = blob::parse_fixed::<CAPACITY>(bytes)?;
            return Ok(fixed(
                "fixed",
                s.sample_rate_hz,
                s.delay_samples,
                s.sections,
                s.full_scale,
                s.output_exponent,
            ));
        }
        NumberFormat::F32 => {}
    }
    let set = blob::parse::<CAPACITY>(bytes)?;
    // Valid, so the fields are where the layout says: gain at 24, sections from 28.
    let f32_at = |offset: usize| {
        bytes
            .get(offset..offset + 4)
            .and_then(|t| <[u8; 4]>::try_from(t).ok())
            .map_or(f64::NAN, |b| f64::from(f32::from_le_bytes(b)))
    };
    let gain = f32_at(24);
    let coefficients: Vec<[f64; 5]> = (0..set.sections)
        .map(|i| {
            let base = blob::HEADER_LEN + i * blob::SECTION_LEN;
            [0, 1, 2, 3, 4].map(|j| f32_at(base + 4 * j))
        })
        .collect();
    let pole_radius = coefficients
        .iter()
        .map(|&[_, _, _, a1, a2]| section_pole_radius(a1, a2))
        .collect();
    let dc_gain = coefficients.iter().fold(gain, |g, &[b0, b1, b2, a1, a2]| {
        g * (b0 + b1 + b2) / (1.0 + a1 + a2)
    });
    Ok(BlobSummary {
        bytes: bytes.len(),
        format_version: header.format_version,
        number_format: "f32",
        sample_rate_hz: set.sample_rate_hz,
        delay_samples: set.delay_samples,
        sections: set.sections,
        gain: Some(gain),
        coefficients,
        pole_radius,
        dc_gain: Some(dc_gain),
        nonlinear: set.nonlinear.is_some(),
        full_scale: None,
        output_exponent: None,
        crc32: header.crc32,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn blob_of(gain: f32, sections: &[[f32; 5]]) -> Vec<u8> {
        let mut buf = vec![0u8; blob::encoded_len(sections.len())];
        let n = blob::encode(&mut buf, 10_000.0, 3, gain, sections).unwrap();
        buf.truncate(n);
        buf
    }

    #[test]
    fn a_blob_reads_back_as_written() {
        let s = [[1.0, -0.5, 0.0, -0.8, 0.0], [1.0, 0.2, 0.1, -1.2, 0.5]];
        let b = blob_of(2.0, &s);
        let r = read(&b).unwrap();
        assert_eq!(r.sections, 2);
        assert_eq!(r.delay_samples, 3);
        assert_eq!(r.sample_rate_hz, 10_000.0);
        assert_eq!(r.number_format, "f32");
        assert_eq!(
            r.coefficients[1],
            [1.0, 0.2f32 as f64, 0.1f32 as f64, -1.2f32 as f64, 0.5]
        );
        // DC: 2 * (0.5 / 0.2) * (1.3 / 0.3).
        let dc = 2.0 * (0.5 / 0.2) * (1.3f32 as f64 / (1.0 - 1.2f32 as f64 + 0.5));
        assert!((r.dc_gain.unwrap() - dc).abs() < 1e-5, "{:?}", r.dc_gain);
        assert!(r.pole_radius.iter().all(|p| *p < 1.0));
    }

    /// A direct-form blob is read by the direct-form parser, not refused by the normal form's.
    #[test]
    fn a_direct_form_blob_reads_back() {
        use crate::board::fixed::direct::DirectSection;
        use crate::export::image::{BoardImage, DirectBoardCoefficients};
        let image: BoardImage = DirectBoardCoefficients {
            sample_rate_hz: 10_000.0,
            delay_samples: 3,
            latency_samples: 4.5,
            full_scale: 1000.0,
            output_exponent: -1,
            sections: vec![DirectSection {
                b: [1 << 29, 0, 0],
                neg_a: [1 << 29, 0],
            }],
        }
        .into();
        let r = read(&image.to_bin().unwrap()).unwrap();
        assert_eq!(r.number_format, "fixed-direct");
        assert_eq!((r.sections, r.delay_samples), (1, 3));
        assert_eq!((r.full_scale, r.output_exponent), (Some(1000.0), Some(-1)));
    }

    /// `read` before it took the header from the board's reader: the number format from byte 6
    /// (0 when absent) picked the parser, the version came from bytes 4..6 and the CRC from the
    /// last four bytes. The outcome it had: the parser's error, or version and CRC.
    fn by_the_bytes(bytes: &[u8]) -> Result<(u16, u32), BlobError> {
        match bytes.get(6).copied().unwrap_or(0) {
            0 => blob::parse::<CAPACITY>(bytes).map(drop)?,
            2 => blob::parse_direct::<CAPACITY>(bytes).map(drop)?,
            _ => blob::parse_fixed::<CAPACITY>(bytes).map(drop)?,
        }
        let n = bytes.len();
        Ok((
            u16::from_le_bytes([bytes[4], bytes[5]]),
            u32::from_le_bytes(bytes[n - 4..].try_into().unwrap()),
        ))
    }

    /// Every blob form, cut at every length and with every header byte changed (the CRC made
    /// right again, so that the field checks behind it are reached): the summary's version and
    /// CRC, and every error, are what reading the bytes directly gave.
    #[test]
    fn the_header_reader_gives_what_the_bytes_gave() {
        use crate::board::fixed::direct::DirectSection;
        use crate::board::fixed::FixedSection;
        let s = [[1.0f32, -0.5, 0.0, -0.8, 0.0]];
        let mut f32_v1 = vec![0u8; blob::encoded_len(1)];
        blob::encode(&mut f32_v1, 1e4, 3, 2.0, &s).unwrap();
        let mut f32_v2 = vec![0u8; blob::encoded_len_nonlinear(1, 1)];
        let correction = blob::NonlinearCorrection {
            gain: 0.5,
            lowpass_gain: 1.0,
            lowpass: &[[0.5, 0.0, 0.0, -0.5, 0.0]],
        };
        blob::encode_nonlinear(&mut f32_v2, 1e4, 3, 2.0, &s, &correction).unwrap();
        let mut fixed = vec![0u8; blob::encoded_len_fixed(1)];
        blob::encode_fixed(&mut fixed, 1e4, 3, 1e3, -1, &[FixedSection::IDENTITY]).unwrap();
        let mut direct = vec![0u8; blob::encoded_len_direct(1)];
        blob::encode_direct(&mut direct, 1e4, 3, 1e3, -1, &[DirectSection::IDENTITY]).unwrap();
        let mut cases = 0;
        let mut refused = std::collections::BTreeSet::new();
        for whole in [f32_v1, f32_v2, fixed, direct] {
            let mut variants: Vec<Vec<u8>> =
                (0..=whole.len()).map(|n| whole[..n].to_vec()).collect();
            for at in 0..blob::HEADER_LEN {
                for value in [0u8, 1, 2, 3, 0x80, 0xff, whole[at] ^ 1] {
                    let mut b = whole.clone();
                    b[at] = value;
                    let n = b.len() - blob::CRC_LEN;
                    let crc = blob::crc32(&b[..n]);
                    b[n..].copy_from_slice(&crc.to_le_bytes());
                    variants.push(b);
                }
            }
            for b in variants {
                let got = read(&b).map(|r| (r.format_version, r.crc32));
                assert_eq!(got, by_the_bytes(&b), "{b:?}");
                if let Err(e) = got {
                    refused.insert(
                        format!("{e:?}")
                            .split([' ', '('])
                            .next()
                            .unwrap()
                            .to_owned(),
                    );
                }
                cases += 1;
            }
        }
        assert!(cases > 500, "{cases}");
        // The header checks behind the CRC were reached, not only the CRC and the length.
        for kind in [
            "BadMagic",
            "UnsupportedVersion",
            "UnsupportedNumberFormat",
            "ReservedNotZero",
            "InvalidSampleRate",
            "UnsupportedFractionalBits",
            "Truncated",
        ] {
            assert!(refused.contains(kind), "{kind} not reached: {refused:?}");
        }
    }

    #[test]
    fn a_flipped_bit_gets_the_board_parsers_error() {
        let mut b = blob_of(1.0, &[[1.0, 0.0, 0.0, -0.5, 0.0]]);
        b[30] ^= 0x10;
        assert!(matches!(read(&b), Err(BlobError::CrcMismatch { .. })));
        assert!(matches!(read(b"nope"), Err(BlobError::BadMagic)));
        assert!(matches!(read(b"UN"), Err(BlobError::Truncated { .. })));
    }
}
