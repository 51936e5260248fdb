//! What can go wrong in exporting, in the export room's own words: the board's code refusing
//! the rounded coefficients, and a blob that does not read back as what was written. (A model
//! file without a design to export is the file's error, [`crate::error::Error::Model`].)

use crate::blob::BlobError;
use crate::error::BoardRefusal;

/// Everything export itself can find wrong; neither happens for an image built from a model
/// file whose design passed its checks, and both stop the file from being written.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ExportError {
    /// The board's encoder or constructor refused the rounded coefficients.
    #[error("export: {0}")]
    BoardRefused(BoardRefusal),
    /// An encoded blob does not read back, through the board's parser, as what was written.
    #[error("export: {}", match .parsed {
        Some(e) => format!("the blob does not parse back: {e}"),
        None => "the blob parses back to other coefficients".into(),
    })]
    BlobRoundTrip {
        /// The parser's error, or `None` when it parsed to other coefficients.
        parsed: Option<BlobError>,
    },
}

impl crate::error::StageError for ExportError {}
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
