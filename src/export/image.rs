//! The board image: what `unlag export` sends to the board, one type over every kind of
//! compensator the board runs, built from a model file and checked as the board checks it.
//!
//! [`BoardImage`] is one of
//!
//! * [`BoardCoefficients`]: the `f32` cascade, with the nonlinear-damping correction
//!   ([`BoardNonlinear`]) when the model has that effect;
//! * [`FixedBoardCoefficients`]: the fixed-point cascade in normal form;
//! * [`DirectBoardCoefficients`]: the fixed-point cascade in direct form;
//! * [`BoardBank`]: a table of `f32` sets, one per gas temperature.
//!
//! Each is written by one writer per format, [`BoardImage::to_rust`], [`BoardImage::to_c`] and
//! [`BoardImage::to_bin`] (or [`BoardImage::render`]); the methods of the same names on the
//! kinds are shorthands for them.

use std::path::Path;

use super::bank::BoardBank;
use super::{Format, NumberFormat, MAX_EXPORT_SECTIONS};
use crate::board::compensator::{CascadeCoefficients, InverseError, NonlinearDampingCoefficients};
use crate::board::fixed::direct::{DirectCascade, DirectSection};
use crate::board::fixed::{FixedCascade, FixedSection};
use crate::design::inverse::Design;
use crate::design::quantise::{DirectPlan, FixedPlan};
use crate::error::{Error, Result};
use crate::file::ModelFile;

/// One board image, in any of the kinds the board runs.
#[derive(Debug, Clone, PartialEq)]
pub enum BoardImage {
    /// The `f32` cascade, with the nonlinear-damping correction when the model has it.
    F32(BoardCoefficients),
    /// The fixed-point cascade in normal form.
    Fixed(FixedBoardCoefficients),
    /// The fixed-point cascade in direct form.
    Direct(DirectBoardCoefficients),
    /// One `f32` set per gas temperature.
    Bank(BoardBank),
}

/// The sample rate, model delay and latency a set belongs to.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SetTiming {
    /// Sample rate in Hz.
    pub sample_rate_hz: f64,
    /// The model's delay in samples.
    pub delay_samples: u32,
    /// Latency of the reconstruction behind the true pressure, in samples.
    pub latency_samples: f64,
}

impl BoardImage {
    /// The image of `file`'s `[inverse]` design (read from `path`) in `number_format`.
    ///
    /// # Errors
    /// [`BoardCoefficients::from_model_file`], [`FixedBoardCoefficients::from_model_file`] or
    /// [`DirectBoardCoefficients::from_model_file`].
    pub fn from_model_file(
        file: &ModelFile,
        path: &Path,
        number_format: NumberFormat,
    ) -> Result<Self> {
        Ok(match number_format {
            NumberFormat::F32 => Self::F32(BoardCoefficients::from_model_file(file, path)?),
            NumberFormat::Fixed { full_scale } => Self::Fixed(
                FixedBoardCoefficients::from_model_file(file, path, full_scale)?,
            ),
            NumberFormat::FixedDirect { full_scale } => Self::Direct(
                DirectBoardCoefficients::from_model_file(file, path, full_scale)?,
            ),
        })
    }

    /// `"f32"` or `"fixed"`.
    #[must_use]
    pub fn number_format(&self) -> &'static str {
        match self {
            Self::F32(_) | Self::Bank(_) => "f32",
            Self::Fixed(_) | Self::Direct(_) => "fixed",
        }
    }

    /// The set's sample rate, delay and latency; a bank's first set's (the sample rate is
    /// every set's, the delay and latency are not).
    #[must_use]
    pub fn timing(&self) -> SetTiming {
        let timing = |sample_rate_hz, delay_samples, latency_samples| SetTiming {
            sample_rate_hz,
            delay_samples,
            latency_samples,
        };
        match self {
            Self::F32(c) => timing(c.sample_rate_hz, c.delay_samples, c.latency_samples),
            Self::Fixed(c) => timing(c.sample_rate_hz, c.delay_samples, c.latency_samples),
            Self::Direct(c) => timing(c.sample_rate_hz, c.delay_samples, c.latency_samples),
            Self::Bank(b) => b.sets.first().map_or(timing(0.0, 0, 0.0), |c| {
                timing(c.sample_rate_hz, c.delay_samples, c.latency_samples)
            }),
        }
    }

    /// Sections of the compensator (per set, for a bank).
    #[must_use]
    pub fn section_count(&self) -> usize {
        match self {
            Self::F32(c) => c.sections.len(),
            Self::Fixed(c) => c.sections.len(),
            Self::Direct(c) => c.sections.len(),
            Self::Bank(b) => b.section_count(),
        }
    }

    /// The file's bytes in `format`; `source` names the model file in the comments.
    ///
    /// # Errors
    /// See [`Self::to_bin`].
    pub fn render(&self, format: Format, source: &str) -> Result<Vec<u8>> {
        match format {
            Format::Rust => Ok(self.to_rust(source).into_bytes()),
            Format::C => Ok(self.to_c(source).into_bytes()),
            Format::Bin => self.to_bin(),
        }
    }
}

impl From<BoardCoefficients> for BoardImage {
    fn from(c: BoardCoefficients) -> Self {
        Self::F32(c)
    }
}

impl From<FixedBoardCoefficients> for BoardImage {
    fn from(c: FixedBoardCoefficients) -> Self {
        Self::Fixed(c)
    }
}

impl From<DirectBoardCoefficients> for BoardImage {
    fn from(c: DirectBoardCoefficients) -> Self {
        Self::Direct(c)
    }
}

impl From<BoardBank> for BoardImage {
    fn from(b: BoardBank) -> Self {
        Self::Bank(b)
    }
}

/// The shorthands of a kind for its [`BoardImage`]'s writers (they copy the kind into one).
macro_rules! writers {
    ($kind:ty) => {
        impl $kind {
            /// Rust source: `const` items to `include!` in a firmware module
            /// ([`BoardImage::to_rust`]).
            #[must_use]
            pub fn to_rust(&self, source: &str) -> String {
                BoardImage::from(self.clone()).to_rust(source)
            }

            /// A C header ([`BoardImage::to_c`]).
            #[must_use]
            pub fn to_c(&self, source: &str) -> String {
                BoardImage::from(self.clone()).to_c(source)
            }

            /// The blob, checked by parsing it back ([`BoardImage::to_bin`]).
            ///
            /// # Errors
            /// See [`BoardImage::to_bin`].
            pub fn to_bin(&self) -> Result<Vec<u8>> {
                BoardImage::from(self.clone()).to_bin()
            }

            /// The file's bytes in `format` ([`BoardImage::render`]).
            ///
            /// # Errors
            /// See [`BoardImage::to_bin`].
            pub fn render(&self, format: Format, source: &str) -> Result<Vec<u8>> {
                BoardImage::from(self.clone()).render(format, source)
            }
        }
    };
}

writers!(BoardCoefficients);
writers!(FixedBoardCoefficients);
writers!(DirectBoardCoefficients);
writers!(BoardBank);

/// The board's compensator as exported: the design rounded to `f32` and validated.
#[derive(Debug, Clone, PartialEq)]
pub struct BoardCoefficients {
    /// Sample rate in Hz the coefficients belong to.
    pub sample_rate_hz: f64,
    /// The model's delay in samples.
    pub delay_samples: u32,
    /// Latency of the reconstruction behind the true pressure, in samples (from the design).
    pub latency_samples: f64,
    /// Input gain, rounded to `f32`.
    pub gain: f32,
    /// Sections `[b0, b1, b2, a1, a2]`, rounded to `f32`.
    pub sections: Vec<[f32; 5]>,
    /// The nonlinear-damping correction, when the model has that effect.
    pub nonlinear: Option<BoardNonlinear>,
}

/// The board's nonlinear-damping correction as exported
/// ([`crate::board::compensator::NonlinearDampingCoefficients`]), rounded to `f32`.
#[derive(Debug, Clone, PartialEq)]
pub struct BoardNonlinear {
    /// Gain per squared sample difference of the probe signal: the quadratic loss (s^2 per
    /// probe unit) times the sample rate squared.
    pub gain: f32,
    /// Input gain of the low-pass (the design's own).
    pub lowpass_gain: f32,
    /// The low-pass sections `[b0, b1, b2, a1, a2]`.
    pub lowpass: Vec<[f32; 5]>,
}

/// The board's fixed-point compensator as exported (number format `fixed`): the integer
/// sections of [`crate::design::quantise::FixedPlan`], validated as the board validates them.
#[derive(Debug, Clone, PartialEq)]
pub struct FixedBoardCoefficients {
    /// Sample rate in Hz the coefficients belong to.
    pub sample_rate_hz: f64,
    /// The model's delay in samples.
    pub delay_samples: u32,
    /// Latency of the reconstruction behind the true pressure, in samples (from the design).
    pub latency_samples: f64,
    /// ADC full scale in the probe's units: the input code `2^31`.
    pub full_scale: f64,
    /// The output is Q1.31 of `full_scale * 2^output_exponent`.
    pub output_exponent: i32,
    /// The sections.
    pub sections: Vec<FixedSection>,
}

/// The board's direct-form fixed-point compensator as exported (`--number-format fixed
/// --fixed-form direct`): the integer sections of [`crate::design::quantise::DirectPlan`], validated as
/// the board validates them.
#[derive(Debug, Clone, PartialEq)]
pub struct DirectBoardCoefficients {
    /// Sample rate in Hz the coefficients belong to.
    pub sample_rate_hz: f64,
    /// The model's delay in samples.
    pub delay_samples: u32,
    /// Latency of the reconstruction behind the true pressure, in samples (from the design).
    pub latency_samples: f64,
    /// ADC full scale in the probe's units: the input code `2^31`.
    pub full_scale: f64,
    /// The output is Q1.31 of `full_scale * 2^output_exponent`.
    pub output_exponent: i32,
    /// The sections.
    pub sections: Vec<DirectSection>,
}

#[allow(clippy::cast_possible_truncation)]
fn to_f32(x: f64) -> f32 {
    x as f32
}

/// The error for `path`'s model file.
fn bad(path: &Path, message: String) -> Error {
    Error::Model {
        path: path.to_path_buf(),
        message,
    }
}

/// The model file's `[inverse]` design, if the board may run it.
fn design<'a>(file: &'a ModelFile, path: &Path) -> Result<&'a Design> {
    let Some(design) = &file.inverse else {
        return Err(
            bad(path, "no [inverse] compensator design to export".into())
                .advised(crate::error::Advice::DesignCompensator),
        );
    };
    design.check_exportable()?;
    Ok(design)
}

/// The sample rate, delay and latency as the board stores them.
fn timing(file: &ModelFile, path: &Path, design: &Design) -> Result<SetTiming> {
    let fs = file.model.fs;
    if !(fs.is_finite() && fs > 0.0) {
        return Err(bad(
            path,
            format!("sample rate {fs} Hz is not finite and positive"),
        ));
    }
    let delay_samples = u32::try_from(file.model.delay).map_err(|_| {
        bad(
            path,
            format!("delay {} does not fit in 32 bits", file.model.delay),
        )
    })?;
    Ok(SetTiming {
        sample_rate_hz: fs,
        delay_samples,
        latency_samples: design.latency_samples,
    })
}

/// Refuses a section count the export does not write; `what` names the compensator.
fn check_count(path: &Path, what: &str, n: usize) -> Result<()> {
    if n == 0 || n > MAX_EXPORT_SECTIONS {
        return Err(bad(
            path,
            format!("{what} has {n} sections; export needs 1 to {MAX_EXPORT_SECTIONS}"),
        ));
    }
    Ok(())
}

/// The board's cascade of exactly these `f32` values (widened exactly to `f64` and back).
pub(super) fn board_cascade(
    gain: f32,
    sections: &[[f32; 5]],
) -> std::result::Result<CascadeCoefficients<f32, MAX_EXPORT_SECTIONS>, InverseError> {
    let widened: Vec<[f64; 5]> = sections.iter().map(|s| s.map(f64::from)).collect();
    CascadeCoefficients::new(f64::from(gain), &widened)
}

impl BoardNonlinear {
    /// The board's correction of exactly these `f32` values.
    pub(super) fn board(
        &self,
    ) -> std::result::Result<NonlinearDampingCoefficients<f32, MAX_EXPORT_SECTIONS>, InverseError>
    {
        let widened: Vec<[f64; 5]> = self.lowpass.iter().map(|s| s.map(f64::from)).collect();
        NonlinearDampingCoefficients::new(
            f64::from(self.gain),
            f64::from(self.lowpass_gain),
            &widened,
        )
    }
}

impl BoardCoefficients {
    /// Takes the `[inverse]` design of a model file, rounds it to `f32` and checks the rounded
    /// set the way the board will (finite, every section stable by the pole margin).
    ///
    /// # Errors
    /// [`Error::Model`] naming `path` when the file has no `[inverse]` design, the design has
    /// no sections or more than [`MAX_EXPORT_SECTIONS`], the sample rate or delay cannot be
    /// stored, or the rounded coefficients are not valid; [`crate::design::DesignError`] ([`Error::Stage`]) when the design's
    /// pole margin is too small to export.
    pub fn from_model_file(file: &ModelFile, path: &Path) -> Result<Self> {
        let design = design(file, path)?;
        check_count(path, "the compensator", design.sections.len())?;
        let timing = timing(file, path, design)?;
        let gain = to_f32(design.gain);
        let sections: Vec<[f32; 5]> = design.sections.iter().map(|s| s.map(to_f32)).collect();
        board_cascade(gain, &sections).map_err(|e| {
            bad(
                path,
                format!("the compensator rounded to f32 is not valid: {e}"),
            )
        })?;
        let loss = crate::effects::nonlinear_gain(&file.effects);
        let nonlinear = if loss == 0.0 {
            None
        } else {
            let fs = timing.sample_rate_hz;
            let (lp_gain, lp) = design.lowpass_sections(fs)?;
            let n = BoardNonlinear {
                gain: to_f32(loss * fs * fs),
                lowpass_gain: to_f32(lp_gain),
                lowpass: lp.iter().map(|s| s.map(to_f32)).collect(),
            };
            n.board().map_err(|e| {
                bad(
                    path,
                    format!("the nonlinear-damping correction rounded to f32 is not valid: {e}"),
                )
            })?;
            Some(n)
        };
        Ok(Self {
            sample_rate_hz: timing.sample_rate_hz,
            delay_samples: timing.delay_samples,
            latency_samples: timing.latency_samples,
            gain,
            sections,
            nonlinear,
        })
    }
}

/// A fixed-point form of the compensator: its plan in the model file and its board-side
/// validation.
trait FixedForm: Sized {
    /// The form in messages: "the {NAME} compensator", "the {NAME} sections".
    const NAME: &'static str;
    /// Its plan in messages: "no {PLAN} plan in the model file".
    const PLAN: &'static str;
    /// `(full scale, output exponent, sections)` of a new plan for `full_scale`, or of the
    /// model file's plan; `None` when there is neither.
    fn plan(design: &Design, full_scale: Option<f64>) -> Result<Option<(f64, i32, Vec<Self>)>>;
    /// The board's validation of the sections.
    fn validate(sections: &[Self]) -> std::result::Result<(), String>;
}

impl FixedForm for FixedSection {
    const NAME: &'static str = "fixed-point";
    const PLAN: &'static str = "fixed-point";
    fn plan(design: &Design, full_scale: Option<f64>) -> Result<Option<(f64, i32, Vec<Self>)>> {
        let plan = match (full_scale, &design.fixed) {
            (Some(f), _) => FixedPlan::new(design, f)?,
            (None, Some(p)) => p.clone(),
            (None, None) => return Ok(None),
        };
        Ok(Some((
            plan.full_scale,
            plan.output_exponent,
            plan.board_sections(),
        )))
    }
    fn validate(sections: &[Self]) -> std::result::Result<(), String> {
        FixedCascade::<MAX_EXPORT_SECTIONS>::new(sections)
            .map(drop)
            .map_err(|e| e.to_string())
    }
}

impl FixedForm for DirectSection {
    const NAME: &'static str = "direct-form";
    const PLAN: &'static str = "direct-form fixed-point";
    fn plan(design: &Design, full_scale: Option<f64>) -> Result<Option<(f64, i32, Vec<Self>)>> {
        let plan = match (full_scale, &design.fixed_direct) {
            (Some(f), _) => DirectPlan::new(design, f)?,
            (None, Some(p)) => p.clone(),
            (None, None) => return Ok(None),
        };
        Ok(Some((
            plan.full_scale,
            plan.output_exponent,
            plan.board_sections(),
        )))
    }
    fn validate(sections: &[Self]) -> std::result::Result<(), String> {
        DirectCascade::<MAX_EXPORT_SECTIONS>::new(sections)
            .map(drop)
            .map_err(|e| e.to_string())
    }
}

/// What a fixed-point image holds: its timing, full scale, output exponent and sections.
type FixedParts<S> = (SetTiming, f64, i32, Vec<S>);

/// The fixed-point plan in form `S` of `file`'s design, or a new one for `full_scale`,
/// checked as the board checks it.
fn fixed_parts<S: FixedForm>(
    file: &ModelFile,
    path: &Path,
    full_scale: Option<f64>,
) -> Result<FixedParts<S>> {
    // The nonlinear-damping correction is f32 only.
    if crate::effects::nonlinear_gain(&file.effects) != 0.0 {
        return Err(Error::UnsupportedOnBoard {
            path: path.to_path_buf(),
            effect: "nonlinear damping",
            arithmetic: "fixed-point",
        }
        .advised(crate::error::Advice::ExportF32));
    }
    let design = design(file, path)?;
    let Some((full_scale, output_exponent, sections)) = S::plan(design, full_scale)? else {
        return Err(bad(path, format!("no {} plan in the model file", S::PLAN))
            .advised(crate::error::Advice::GiveFullScale));
    };
    check_count(
        path,
        &format!("the {} compensator", S::NAME),
        sections.len(),
    )?;
    S::validate(&sections)
        .map_err(|e| bad(path, format!("the {} sections are not valid: {e}", S::NAME)))?;
    let timing = timing(file, path, design)?;
    Ok((timing, full_scale, output_exponent, sections))
}

impl FixedBoardCoefficients {
    /// Takes the fixed-point plan of the model file's `[inverse]` design, or plans one for
    /// `full_scale` when it is given (it replaces a stored plan).
    ///
    /// # Errors
    /// [`Error::UnsupportedOnBoard`] when the model has nonlinear damping (the fixed-point
    /// compensator does not run its correction); [`Error::Model`] naming `path` when there is
    /// no design, no plan and no full scale, or the plan's sections are refused by the board's
    /// validation; the planner's errors.
    pub fn from_model_file(file: &ModelFile, path: &Path, full_scale: Option<f64>) -> Result<Self> {
        let (timing, full_scale, output_exponent, sections) = fixed_parts(file, path, full_scale)?;
        Ok(Self {
            sample_rate_hz: timing.sample_rate_hz,
            delay_samples: timing.delay_samples,
            latency_samples: timing.latency_samples,
            full_scale,
            output_exponent,
            sections,
        })
    }
}

impl DirectBoardCoefficients {
    /// Takes the direct-form plan of the model file's `[inverse]` design, or plans one for
    /// `full_scale` when it is given (it replaces a stored plan).
    ///
    /// # Errors
    /// [`Error::UnsupportedOnBoard`] when the model has nonlinear damping; [`Error::Model`]
    /// naming `path` when there is no design, no direct-form plan and no full scale, or the
    /// sections are refused by the board's validation; the planner's errors.
    pub fn from_model_file(file: &ModelFile, path: &Path, full_scale: Option<f64>) -> Result<Self> {
        let (timing, full_scale, output_exponent, sections) = fixed_parts(file, path, full_scale)?;
        Ok(Self {
            sample_rate_hz: timing.sample_rate_hz,
            delay_samples: timing.delay_samples,
            latency_samples: timing.latency_samples,
            full_scale,
            output_exponent,
            sections,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::board::blob;

    const SECTION: [f32; 5] = [1.0, -0.5, 0.0, -0.25, 0.0];

    fn f32_set(nonlinear: bool) -> BoardCoefficients {
        BoardCoefficients {
            sample_rate_hz: 10_000.0,
            delay_samples: 3,
            latency_samples: 4.5,
            gain: 0.5,
            sections: vec![SECTION; 2],
            nonlinear: nonlinear.then(|| BoardNonlinear {
                gain: 2.0,
                lowpass_gain: 0.25,
                lowpass: vec![[0.25, 0.5, 0.25, -0.2, 0.1]],
            }),
        }
    }

    /// One image of every kind, with the flags and include guard its files carry.
    fn kinds() -> Vec<(BoardImage, &'static str, &'static str)> {
        let lag = DirectSection {
            b: [1 << 29, 0, 0],
            neg_a: [1 << 29, 0],
        };
        vec![
            (f32_set(false).into(), "", "UNLAG_COEFFICIENTS_H"),
            (f32_set(true).into(), "", "UNLAG_COEFFICIENTS_H"),
            (
                FixedBoardCoefficients {
                    sample_rate_hz: 10_000.0,
                    delay_samples: 3,
                    latency_samples: 4.5,
                    full_scale: 1000.0,
                    output_exponent: 2,
                    sections: vec![FixedSection::IDENTITY],
                }
                .into(),
                " --number-format fixed",
                "UNLAG_FIXED_COEFFICIENTS_H",
            ),
            (
                DirectBoardCoefficients {
                    sample_rate_hz: 10_000.0,
                    delay_samples: 3,
                    latency_samples: 4.5,
                    full_scale: 1000.0,
                    output_exponent: -1,
                    sections: vec![lag],
                }
                .into(),
                " --number-format fixed --fixed-form direct",
                "UNLAG_DIRECT_COEFFICIENTS_H",
            ),
            (
                BoardBank {
                    temperatures_k: vec![280.0, 300.0],
                    hysteresis_k: 10.0,
                    warm_up_samples: 20,
                    sets: vec![f32_set(false), f32_set(false)],
                }
                .into(),
                " --temperatures",
                "UNLAG_BANK_H",
            ),
        ]
    }

    #[test]
    fn every_kind_is_framed_alike_in_rust_and_c() {
        for (image, flags, guard) in kinds() {
            let rust = image.to_rust("m.toml");
            assert!(
                rust.starts_with(&format!(
                    "// Generated by `unlag export --format rust{flags}` from m.toml (unlag "
                )),
                "{rust}"
            );
            assert!(rust.contains("pub const SAMPLE_RATE_HZ: f64 = 10000.0;\n"));
            assert!(rust.ends_with("];\n"), "{rust}");
            let c = image.to_c("m.toml");
            assert!(
                c.starts_with(&format!(
                    "/* Generated by `unlag export --format c{flags}` from m.toml (unlag "
                )),
                "{c}"
            );
            assert!(c.contains(&format!("#ifndef {guard}\n#define {guard}\n\n")));
            assert!(c.ends_with(&format!("\n#endif /* {guard} */\n")), "{c}");
            assert_eq!(
                image.render(Format::Rust, "m.toml").unwrap(),
                rust.into_bytes()
            );
        }
    }

    #[test]
    fn every_single_set_reads_back_from_its_blob_and_a_bank_has_none() {
        for (image, _, _) in kinds() {
            let bin = image.to_bin();
            let timing = image.timing();
            match &image {
                BoardImage::F32(c) => {
                    let set = blob::parse::<4>(&bin.unwrap()).unwrap();
                    assert_eq!(set.nonlinear.is_some(), c.nonlinear.is_some());
                    assert_eq!(set.delay_samples, timing.delay_samples);
                }
                BoardImage::Fixed(_) => {
                    let set = blob::parse_fixed::<4>(&bin.unwrap()).unwrap();
                    assert_eq!((set.output_exponent, set.sections), (2, 1));
                }
                BoardImage::Direct(_) => {
                    let set = blob::parse_direct::<4>(&bin.unwrap()).unwrap();
                    assert_eq!((set.output_exponent, set.sections), (-1, 1));
                }
                BoardImage::Bank(b) => {
                    assert!(matches!(
                        bin.as_ref().map_err(Error::unadvised),
                        Err(Error::InvalidParameter { .. })
                    ));
                    assert_eq!(image.section_count(), 2);
                    assert_eq!(
                        b.to_bin().unwrap_err().to_string(),
                        bin.unwrap_err().to_string()
                    );
                }
            }
        }
    }

    #[test]
    fn every_single_set_header_ends_with_its_reference_kernel() {
        for (image, _, _) in kinds() {
            let c = image.to_c("m.toml");
            let (tables, kernel) = c
                .split_once("/* ---- Reference implementation")
                .unwrap_or((&c, ""));
            let has = |what: &str| kernel.contains(what);
            match &image {
                BoardImage::F32(f) => {
                    assert!(has(
                        "static inline float unlag_process(unlag_state *state, float x)"
                    ));
                    assert!(has(
                        "static inline void unlag_init(unlag_state *state, float x0)"
                    ));
                    assert_eq!(has("unlag_nonlinear_process"), f.nonlinear.is_some());
                }
                BoardImage::Fixed(_) | BoardImage::Direct(_) => {
                    assert!(has(
                        "static inline int32_t unlag_process(unlag_state *state, int32_t input)"
                    ));
                    assert!(has(
                        "static inline int unlag_take_overflow(unlag_state *state)"
                    ));
                    let table = if matches!(image, BoardImage::Fixed(_)) {
                        "unlag_fixed_sections[i]"
                    } else {
                        "unlag_direct_sections[i]"
                    };
                    assert!(has(table), "{c}");
                }
                BoardImage::Bank(_) => assert!(kernel.is_empty(), "{c}"),
            }
            // The functions come after every table they read, and declare none of their own.
            assert!(
                !tables.contains("static inline") || kernel.is_empty(),
                "{c}"
            );
            assert!(!kernel.contains("static const"), "{c}");
        }
    }

    #[test]
    fn the_kinds_shorthands_are_the_images_writers() {
        let c = f32_set(true);
        let image = BoardImage::from(c.clone());
        assert_eq!(c.to_rust("m.toml"), image.to_rust("m.toml"));
        assert_eq!(c.to_c("m.toml"), image.to_c("m.toml"));
        assert_eq!(c.to_bin().unwrap(), image.to_bin().unwrap());
        assert_eq!(image.number_format(), "f32");
        let c = c.to_c("m.toml");
        assert!(
            c.contains("#define UNLAG_NONLINEAR_SECTION_COUNT 1u\n"),
            "{c}"
        );
        assert!(c.contains("static const float unlag_gain = 0.5f;\n"), "{c}");
    }
}
