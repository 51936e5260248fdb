//! The library's pipeline from step tests to the board's coefficients: the probe's model fitted
//! from its tests ([`fit_probe`]), its compensator designed ([`design_compensator`]), both in
//! one request continuing a model file ([`fit_and_design`]), a stored
//! compensator designed anew for a rescaled model ([`retarget`]), a recording compensated
//! with a model file ([`compensate`]), a model file's probe simulated on a recording
//! ([`simulate`]), a model file put at another sample rate ([`resample`]), a model file's
//! analysis, frequency response and stability ([`inspect()`]), and a model file judged against
//! its tests, the missing effects ranked ([`diagnose()`]). A recording too long to hold is
//! compensated in passes over its file ([`prepare`]), the one place here that reads a file
//! (through the trace room's rows).
//!
//! Every compensator goes through one sequence: the design (checked on the tests against the
//! raw probe, or a stored design's shape redone), the sensor-resonance prefilter put in front
//! of it, then its fixed-point plans. The command line only parses its arguments into the
//! requests here and prints what comes back; nothing here prints, and nothing but [`prepare`]
//! reads a file.

mod compensate;
mod design;
mod diagnose;
mod fit;
mod fit_design;
mod inspect;
mod resample;
mod simulate;
mod stream;

pub use compensate::{
    compensate, Arithmetic, CompensateRequest, Compensated, Compensation, FixedRunSummary,
    ReferenceError,
};
pub use design::{
    at_temperature, default_full_scale, design_compensator, retarget, Compensator,
    CompensatorRequest, CompensatorSpec, FullScale, Roles, Shape, DEFAULT_FULL_SCALE_SWINGS,
};
pub use diagnose::{diagnose, DiagnoseRequest, DiagnoseStage, Diagnosis};
pub use fit::{
    add_effects, carried_effects, check_excitation, check_model_rate, check_same_rate, fit_probe,
    FitRequest,
};
pub use fit_design::{fit_and_design, FitDesignRequest, FitDesigned, FitStage};
pub use inspect::{inspect, InspectRequest, Inspected};
pub use resample::{check_sample_rate, resample, ResampleRequest, Resampled};
pub use simulate::{simulate, SimulateRequest, Simulated};
pub use stream::{prepare, streams, Prepared, StreamRequest};

/// The probe and step tests the pipeline's unit tests run on.
#[cfg(test)]
mod testing {
    use crate::fit::model::Model;
    use crate::fit::Test;

    /// A first-order probe (pole 0.95) behind 3 samples of delay, at 10 kHz.
    pub(super) fn probe() -> Model {
        Model {
            fs: 10_000.0,
            delay: 3,
            a: vec![-0.95],
            b: vec![0.05],
        }
    }

    /// A step from 0 to `level` at sample 600 of 3000, and the probe's answer with noise of
    /// 1e-3 (seeded).
    pub(super) fn step_test(level: f64, seed: u64) -> (Vec<f64>, Vec<f64>) {
        step_test_through(&probe(), level, seed)
    }

    /// As [`step_test`], through `model`.
    pub(super) fn step_test_through(model: &Model, level: f64, seed: u64) -> (Vec<f64>, Vec<f64>) {
        let u: Vec<f64> = (0..3000)
            .map(|k| if k < 600 { 0.0 } else { level })
            .collect();
        let noise = crate::testing::gaussian(u.len(), seed);
        let y = model
            .simulate(&u)
            .iter()
            .zip(noise)
            .map(|(y, n)| y + 1e-3 * n)
            .collect();
        (u, y)
    }

    /// An estimation and a validation test, `est.csv` and `val.csv`, on the samples of
    /// `est` and `val`.
    pub(super) fn est_and_val<'a>(
        est: &'a (Vec<f64>, Vec<f64>),
        val: &'a (Vec<f64>, Vec<f64>),
    ) -> [Test<'a>; 2] {
        [
            Test {
                name: "est.csv",
                u: &est.0,
                y: &est.1,
            },
            Test {
                name: "val.csv",
                u: &val.0,
                y: &val.1,
            },
        ]
    }
}
