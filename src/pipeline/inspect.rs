//! What a model file says about its probe: the analysis of its model (poles, zeros, margins,
//! modes), its frequency response on a grid, its continuous-time equivalent and whether it is
//! stable enough to use.

use crate::error::Result;
use crate::file::ModelFile;
use crate::fit::analysis::{self, Analysis, ResponsePoint};
use crate::fit::continuous::Continuous;

/// A model file to inspect.
#[derive(Debug, Clone, Copy)]
pub struct InspectRequest<'a> {
    /// The model file.
    pub file: &'a ModelFile,
    /// The model file's name, for the instability's message.
    pub model_name: &'a str,
    /// The frequencies (Hz) of the frequency response, in the order wanted; empty for the
    /// default grid ([`analysis::default_frequencies`]: 0 Hz and four points per decade from
    /// fs/1000 to fs/2).
    pub frequencies_hz: &'a [f64],
}

/// What a model file says about its probe.
#[derive(Debug)]
pub struct Inspected {
    /// The model's analysis.
    pub analysis: Analysis,
    /// Its frequency response (the paper's eq. 6, delay included), one point per frequency.
    pub response: Vec<ResponsePoint>,
    /// Its continuous-time equivalent, or why it has none (a model without one is still
    /// inspected).
    pub continuous: Result<Continuous>,
    /// Whether the model is usable: [`crate::error::Error::UnstableModel`] names the pole on
    /// or outside the unit circle (the analysis shows it all the same).
    pub stability: Result<()>,
}

/// Inspects the model of `request.file`.
///
/// # Errors
/// [`Analysis::new`]'s: a model that cannot be analysed (its coefficients, a failed
/// eigenvalue solver). An unstable model is not an error here: [`Inspected::stability`].
pub fn inspect(request: &InspectRequest<'_>) -> Result<Inspected> {
    let m = &request.file.model;
    let analysis = Analysis::new(m)?;
    let response = if request.frequencies_hz.is_empty() {
        analysis::response_points(m, &analysis::default_frequencies(m.fs))
    } else {
        analysis::response_points(m, request.frequencies_hz)
    };
    Ok(Inspected {
        analysis,
        response,
        continuous: Continuous::from_model(m),
        stability: m.check_stable(request.model_name),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error::Error;

    /// A stable probe: its analysis, the default grid's response from 0 Hz (its DC gain) and
    /// its continuous form; the same probe with its pole outside the unit circle is inspected
    /// all the same, its instability named.
    #[test]
    fn a_model_is_inspected_and_an_unstable_one_named() {
        let file = crate::testing::model_file(super::super::testing::probe());
        let request = InspectRequest {
            file: &file,
            model_name: "probe.toml",
            frequencies_hz: &[],
        };
        let i = inspect(&request).unwrap();
        assert!(i.analysis.stable && i.stability.is_ok());
        assert_eq!(
            i.response.len(),
            analysis::default_frequencies(file.model.fs).len()
        );
        let dc = i.response.first().unwrap();
        assert_eq!(dc.frequency_hz, 0.0);
        assert!((dc.magnitude - 1.0).abs() < 1e-9, "{dc:?}");
        assert!(i.continuous.is_ok());
        let asked = inspect(&InspectRequest {
            frequencies_hz: &[10.0, 100.0],
            ..request
        })
        .unwrap();
        let at: Vec<f64> = asked.response.iter().map(|p| p.frequency_hz).collect();
        assert_eq!(at, [10.0, 100.0]);

        let mut unstable = file.clone();
        unstable.model.a = vec![-1.05];
        let i = inspect(&InspectRequest {
            file: &unstable,
            ..request
        })
        .unwrap();
        assert!(!i.analysis.stable);
        assert!(
            matches!(&i.stability, Err(Error::UnstableModel { context, .. }) if context == "probe.toml"),
            "{:?}",
            i.stability
        );
    }
}
