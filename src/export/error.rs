//! What can go wrong in exporting, in the export room's own words: a compensator its check
//! found not better than the raw probe, the board's code refusing the rounded coefficients,
//! and a blob that does not read back as what was written. (A model file without a design to
//! export is the file's error, [`crate::error::Error::Model`].)

use std::path::PathBuf;

use crate::board::blob::BlobError;
use crate::error::BoardRefusal;

/// Everything export itself can find wrong; each stops the file from being written.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ExportError {
    /// The compensator's check found it not better than the raw probe, and the export was not
    /// forced ([`crate::export::ExportRequest::force`]).
    #[error("invalid compensator: {}: it is not better than the raw probe on the tests it was checked on (worst error ratio {worst_ratio:.2}); refusing to export it unless forced", model.display())]
    NotBetter {
        /// The model file.
        model: PathBuf,
        /// The check's worst ratio of the compensated error to the raw probe's.
        worst_ratio: f64,
    },
    /// The board's encoder or constructor refused the rounded coefficients (it does not for a
    /// design that passed its checks).
    #[error("export: {0}")]
    BoardRefused(BoardRefusal),
    /// An encoded blob does not read back, through the board's parser, as what was written
    /// (it does not happen for a design that passed its checks).
    #[error("export: {}", match .parsed {
        Some(e) => format!("the blob does not parse back: {e}"),
        None => "the blob parses back to other coefficients".into(),
    })]
    BlobRoundTrip {
        /// The parser's error, or `None` when it parsed to other coefficients.
        parsed: Option<BlobError>,
    },
}

impl crate::error::StageError for ExportError {
    fn kind(&self) -> &'static str {
        match self {
            // The request's: as an invalid argument is.
            Self::NotBetter { .. } => "invalid-argument",
            Self::BoardRefused(_) | Self::BlobRoundTrip { .. } => "numerical",
        }
    }
}
crate::error::stage_error!(ExportError);

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error::Error;

    #[test]
    fn the_text_and_kind_are_those_of_before() {
        let e: Error = ExportError::BlobRoundTrip { parsed: None }.into();
        assert_eq!(
            e.to_string(),
            "export: the blob parses back to other coefficients"
        );
        assert_eq!(e.kind(), "numerical");
        assert_eq!(e.location(), (None, None, None));
        let e: Error = ExportError::BoardRefused(BlobError::BadMagic.into()).into();
        assert_eq!(e.to_string(), format!("export: {}", BlobError::BadMagic));
        assert!(matches!(
            e.stage(),
            Some(ExportError::BoardRefused(BoardRefusal::Blob(
                BlobError::BadMagic
            )))
        ));
    }
}
