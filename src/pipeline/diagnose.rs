//! A model file judged against its step tests: the residual evidence measured on each test,
//! the same structure fitted to each test alone (and the residual against the step's amplitude
//! across those fits), and the missing effects ranked by trial
//! refits ([`diagnose()`]). `unlag compare`, `unlag diagnose` and the report all ask here.

use crate::error::{Error, Result};
use crate::evidence::TestEvidence;
use crate::file::ModelFile;
use crate::fit::Test;
use crate::modelling::diagnose::{self, AmplitudeSignature, Candidate, PerTest};

/// The stages of a [`diagnose()`] that may take long, as [`DiagnoseRequest::on_stage`] hears
/// them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum DiagnoseStage {
    /// Measuring the residual evidence on every test.
    Evidence,
    /// Ranking the candidates: the trial refits.
    Candidates,
}

/// A model file and the tests to judge it on.
#[derive(Clone, Copy)]
pub struct DiagnoseRequest<'a> {
    /// The model file: its model, effects, method and stated uncertainty
    /// ([`ModelFile::current`]) are where the diagnosis starts.
    pub file: &'a ModelFile,
    /// The step tests; the first is the estimation test (refitted on by the trials), the
    /// others are held out.
    pub tests: &'a [Test<'a>],
    /// Also fit the same structure to each test alone ([`Diagnosis::across`]), and read the
    /// residual against the step's amplitude from those fits
    /// ([`Diagnosis::amplitude_signature`]).
    pub across: bool,
    /// Also rank the missing effects by trial refits ([`Diagnosis::candidates`]).
    pub rank: bool,
    /// Told as each long stage starts (a front end's progress indication).
    pub on_stage: &'a dyn Fn(DiagnoseStage),
}

impl core::fmt::Debug for DiagnoseRequest<'_> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("DiagnoseRequest")
            .field("tests", &self.tests.len())
            .field("across", &self.across)
            .field("rank", &self.rank)
            .finish_non_exhaustive()
    }
}

/// What a [`diagnose()`] found.
#[derive(Debug, Clone)]
pub struct Diagnosis {
    /// The residual evidence, one per test in the request's order.
    pub evidence: Vec<TestEvidence>,
    /// The structure fitted to each test alone, when asked ([`DiagnoseRequest::across`]);
    /// empty otherwise.
    pub across: Vec<PerTest>,
    /// How the fitted damping and the own-fit residual change with the step's size across
    /// [`Diagnosis::across`] ([`diagnose::amplitude_signature`]): `None` when not asked, or
    /// without two tests with a resonance and steps of different sizes.
    pub amplitude_signature: Option<AmplitudeSignature>,
    /// The candidates for the missing effect, best first, when asked
    /// ([`DiagnoseRequest::rank`]); empty otherwise.
    pub candidates: Vec<Candidate>,
}

/// Measures the evidence of the model file on the tests, then (as asked) fits each test
/// alone and ranks the missing effects.
///
/// # Errors
/// [`Error::InvalidArgument`] (`tests`) when ranking without a test;
/// [`super::check_excitation`]'s for a test whose reference does not move (it tells nothing
/// about the probe, as for [`super::fit_probe`]); [`diagnose::diagnose`]'s errors.
pub fn diagnose(request: &DiagnoseRequest<'_>) -> Result<Diagnosis> {
    let DiagnoseRequest {
        file,
        tests,
        across,
        rank,
        on_stage,
    } = *request;
    if rank && tests.is_empty() {
        return Err(Error::InvalidArgument {
            what: "tests",
            message: "give at least one step test".into(),
        });
    }
    for test in tests {
        super::check_excitation(std::path::Path::new(test.name), test.u)?;
    }
    let current = file.current();
    on_stage(DiagnoseStage::Evidence);
    let evidence = diagnose::evidence(&current, tests);
    let across = if across {
        diagnose::per_test(&current, tests, &evidence)
    } else {
        Vec::new()
    };
    let amplitude_signature = diagnose::amplitude_signature(&across);
    let candidates = if rank {
        on_stage(DiagnoseStage::Candidates);
        diagnose::diagnose(&current, tests, &evidence)?
    } else {
        Vec::new()
    };
    Ok(Diagnosis {
        evidence,
        across,
        amplitude_signature,
        candidates,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_test_whose_reference_does_not_move_is_refused() {
        let file = crate::testing::model_file(super::super::testing::probe());
        // A reference resting at 1 with its noise, no step.
        let flat: Vec<f64> = (0..400)
            .map(|k| 1.0 + 1e-3 * f64::from(k * 7 % 5))
            .collect();
        let y: Vec<f64> = (0..400).map(|k| 1.0 + 1e-3 * f64::from(k % 7)).collect();
        let tests = [Test {
            name: "flat.csv",
            u: &flat,
            y: &y,
        }];
        let request = DiagnoseRequest {
            file: &file,
            tests: &tests,
            across: false,
            rank: false,
            on_stage: &|_| {},
        };
        match diagnose(&request) {
            Err(Error::NoStep { path, reason, .. }) => {
                assert_eq!(path, std::path::Path::new("flat.csv"));
                assert!(reason.contains("does not move"), "{reason}");
            }
            other => panic!("expected NoStep, got {other:?}"),
        }
        // Ranking needs a test to refit on.
        let none = diagnose(&DiagnoseRequest {
            tests: &[],
            rank: true,
            ..request
        });
        assert!(
            matches!(none, Err(Error::InvalidArgument { what: "tests", .. })),
            "{none:?}"
        );
    }

    #[test]
    fn fitting_each_test_alone_reads_the_residual_against_amplitude() {
        let (model, _) = crate::testing::second_order(300.0, 0.2, 10_000.0, 3);
        let file = crate::testing::model_file(model.clone());
        // Two steps of different sizes through the same resonant probe, with noise.
        let traces: Vec<(Vec<f64>, Vec<f64>)> = [(1.0, 3), (2.5, 4)]
            .into_iter()
            .map(|(level, seed)| super::super::testing::step_test_through(&model, level, seed))
            .collect();
        let names = ["small.csv", "large.csv"];
        let tests: Vec<Test<'_>> = traces
            .iter()
            .zip(names)
            .map(|((u, y), name)| Test { name, u, y })
            .collect();
        let request = DiagnoseRequest {
            file: &file,
            tests: &tests,
            across: true,
            rank: false,
            on_stage: &|_| {},
        };
        let d = diagnose(&request).unwrap();
        let signature = d.amplitude_signature.expect("two steps of different sizes");
        assert_eq!(
            Some(&signature),
            diagnose::amplitude_signature(&d.across).as_ref()
        );
        assert_eq!(signature.amplitudes.len(), 2);
        // Not asked to fit each test alone: no signature either.
        let d = diagnose(&DiagnoseRequest {
            across: false,
            ..request
        })
        .unwrap();
        assert!(d.across.is_empty());
        assert_eq!(d.amplitude_signature, None);
    }
}
