//! The binary writer of a [`BoardImage`]: the blob of [`crate::board::blob`] for its number format,
//! encoded by the board's own encoder and parsed back by the board's own parser before it is
//! returned.

use super::image::{board_cascade, BoardImage};
use super::ExportError;
use super::MAX_EXPORT_SECTIONS;
use crate::board::blob::{self, BlobError};
use crate::board::fixed::direct::DirectCascade;
use crate::board::fixed::FixedCascade;
use crate::error::{BoardRefusal, Error, Result};

/// The board's refusal of what export built, as the host's error.
fn fail(refusal: impl Into<BoardRefusal>) -> Error {
    ExportError::BoardRefused(refusal.into()).into()
}

/// A blob of `len` bytes written by `encode`.
fn encoded(
    len: usize,
    encode: impl FnOnce(&mut [u8]) -> std::result::Result<usize, BlobError>,
) -> Result<Vec<u8>> {
    let mut out = vec![0u8; len];
    let n = encode(&mut out).map_err(fail)?;
    out.truncate(n);
    Ok(out)
}

/// The board's parse of the blob.
fn parsed_back<T>(parsed: std::result::Result<T, BlobError>) -> Result<T> {
    parsed.map_err(|e| ExportError::BlobRoundTrip { parsed: Some(e) }.into())
}

/// Refuses a blob whose parse differs from what was encoded.
fn same(equal: bool) -> Result<()> {
    if equal {
        Ok(())
    } else {
        Err(ExportError::BlobRoundTrip { parsed: None }.into())
    }
}

impl BoardImage {
    /// The binary blob of [`crate::board::blob`]: format version 1 (number format 0, `f32`; 1, fixed
    /// point; 2, its direct form), or version 2 for `f32` with the nonlinear-damping
    /// correction. It is checked by parsing it back with the board's parser before it is
    /// returned.
    ///
    /// # Errors
    /// [`ExportError::BoardRefused`] if the blob cannot be encoded, [`ExportError::BlobRoundTrip`] if it
    /// does not parse back to the same
    /// coefficients (neither happens for an image built from a model file);
    /// [`Error::InvalidArgument`] for a bank (a blob carries one set).
    pub fn to_bin(&self) -> Result<Vec<u8>> {
        match self {
            Self::F32(c) => {
                let lowpass = c.nonlinear.as_ref().map_or(0, |n| n.lowpass.len());
                let len = blob::encoded_len_nonlinear(c.sections.len(), lowpass);
                let out = encoded(len, |out| match &c.nonlinear {
                    None => {
                        blob::encode(out, c.sample_rate_hz, c.delay_samples, c.gain, &c.sections)
                    }
                    Some(n) => blob::encode_nonlinear(
                        out,
                        c.sample_rate_hz,
                        c.delay_samples,
                        c.gain,
                        &c.sections,
                        &blob::NonlinearCorrection {
                            gain: n.gain,
                            lowpass_gain: n.lowpass_gain,
                            lowpass: &n.lowpass,
                        },
                    ),
                })?;
                let back = parsed_back(blob::parse::<MAX_EXPORT_SECTIONS>(&out))?;
                let cascade = board_cascade(c.gain, &c.sections).map_err(fail)?;
                let nonlinear = match &c.nonlinear {
                    None => None,
                    Some(n) => Some(n.board().map_err(fail)?),
                };
                same(
                    back.cascade == cascade
                        && back.sections == c.sections.len()
                        && back.nonlinear == nonlinear,
                )?;
                Ok(out)
            }
            Self::Fixed(c) => {
                let out = encoded(blob::encoded_len_fixed(c.sections.len()), |out| {
                    blob::encode_fixed(
                        out,
                        c.sample_rate_hz,
                        c.delay_samples,
                        c.full_scale,
                        c.output_exponent,
                        &c.sections,
                    )
                })?;
                let back = parsed_back(blob::parse_fixed::<MAX_EXPORT_SECTIONS>(&out))?;
                let cascade =
                    FixedCascade::<MAX_EXPORT_SECTIONS>::new(&c.sections).map_err(fail)?;
                same(back.cascade == cascade && back.sections == c.sections.len())?;
                Ok(out)
            }
            Self::Direct(c) => {
                let out = encoded(blob::encoded_len_direct(c.sections.len()), |out| {
                    blob::encode_direct(
                        out,
                        c.sample_rate_hz,
                        c.delay_samples,
                        c.full_scale,
                        c.output_exponent,
                        &c.sections,
                    )
                })?;
                let back = parsed_back(blob::parse_direct::<MAX_EXPORT_SECTIONS>(&out))?;
                let cascade =
                    DirectCascade::<MAX_EXPORT_SECTIONS>::new(&c.sections).map_err(fail)?;
                same(back.cascade == cascade && back.sections == c.sections.len())?;
                Ok(out)
            }
            Self::Bank(_) => Err(super::bank::not_a_blob()),
        }
    }
}
