//! Export of the designed compensator from the PC to the board (`unlag export`).
//!
//! This module owns the step from a model file's `[inverse]` design (f64, host) to what a
//! firmware builds in: the coefficients rounded once to the board's `f32`, checked again after
//! the rounding, and rendered as
//!
//! * [`Format::Rust`]: `const` items a Rust firmware `include!`s and hands to
//!   [`CascadeCoefficients::new`];
//! * [`Format::C`]: a header for C firmware (`static const float` arrays);
//! * [`Format::Bin`]: the versioned, CRC-protected blob of [`crate::blob`], for updating a
//!   running board over a serial link.
//!
//! All three carry the same `f32` values, so a board gets bit-identical coefficients whichever
//! way they arrive. With [`NumberFormat::Fixed`] the same three forms carry the fixed-point
//! compensator of [`crate::fixed`] (the integers of [`crate::design::quantise::FixedPlan`]), and with
//! [`NumberFormat::FixedDirect`] its direct form ([`crate::design::quantise::DirectPlan`]). The output file is written atomically. Every section is
//! `[b0, b1, b2, a1, a2]` in the crate's sign convention (see [`crate::compensator`]);
//! CMSIS-DSP's biquad functions want `a1`, `a2` negated, which the C header says.
//!
//! A table of sets, one per gas temperature, for a board that measures it (`--temperatures`),
//! is [`bank`]'s.

use std::fmt::Write as _;
use std::path::Path;

pub mod bank;
pub mod verify;

use crate::blob;
use crate::compensator::{CascadeCoefficients, NonlinearDampingCoefficients};
use crate::design::quantise::{DirectPlan, FixedPlan};
use crate::error::{Error, Result};
use crate::file::ModelFile;
use crate::fixed::direct::{DirectCascade, DirectSection};
use crate::fixed::{FixedCascade, FixedSection};
use crate::trace::write_atomically;

/// Largest section count `unlag export` writes: as many as a design may have.
pub const MAX_EXPORT_SECTIONS: usize = crate::design::inverse::optimal::MAX_SECTIONS;

/// What `unlag export` writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// Rust `const` items for `include!`.
    Rust,
    /// A C header.
    C,
    /// The binary blob of [`crate::blob`].
    Bin,
}

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
/// ([`crate::compensator::NonlinearDampingCoefficients`]), rounded to `f32`.
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

/// Refuses a model the fixed-point compensator cannot run (the nonlinear-damping correction
/// is `f32` only).
fn check_fixed_point(file: &ModelFile, path: &Path) -> Result<()> {
    if crate::modelling::effects::nonlinear_gain(&file.effects) != 0.0 {
        return Err(Error::UnsupportedOnBoard {
            path: path.to_path_buf(),
            effect: "nonlinear damping",
            arithmetic: "fixed-point",
            hint: "export it as f32",
        });
    }
    Ok(())
}

#[allow(clippy::cast_possible_truncation)]
fn to_f32(x: f64) -> f32 {
    x as f32
}

impl BoardCoefficients {
    /// Takes the `[inverse]` design of a model file, rounds it to `f32` and checks the rounded
    /// set the way the board will (finite, every section stable by the pole margin).
    ///
    /// # Errors
    /// [`Error::Model`] naming `path` when the file has no `[inverse]` design, the design has
    /// no sections or more than [`MAX_EXPORT_SECTIONS`], the sample rate or delay cannot be
    /// stored, or the rounded coefficients are not valid; [`Error::Numerical`] when the design's
    /// pole margin is too small to export.
    pub fn from_model_file(file: &ModelFile, path: &Path) -> Result<Self> {
        let bad = |message: String| Error::Model {
            path: path.to_path_buf(),
            message,
        };
        let Some(design) = &file.inverse else {
            return Err(bad(
                "no [inverse] compensator design to export (run `unlag invert` first)".into(),
            ));
        };
        design.check_exportable()?;
        let n = design.sections.len();
        if n == 0 || n > MAX_EXPORT_SECTIONS {
            return Err(bad(format!(
                "the compensator has {n} sections; export needs 1 to {MAX_EXPORT_SECTIONS}"
            )));
        }
        let fs = file.model.fs;
        if !(fs.is_finite() && fs > 0.0) {
            return Err(bad(format!(
                "sample rate {fs} Hz is not finite and positive"
            )));
        }
        let delay_samples = u32::try_from(file.model.delay).map_err(|_| {
            bad(format!(
                "delay {} does not fit in 32 bits",
                file.model.delay
            ))
        })?;
        let gain = to_f32(design.gain);
        let sections: Vec<[f32; 5]> = design.sections.iter().map(|s| s.map(to_f32)).collect();
        let widened: Vec<[f64; 5]> = sections.iter().map(|s| s.map(f64::from)).collect();
        CascadeCoefficients::<f32, MAX_EXPORT_SECTIONS>::new(f64::from(gain), &widened)
            .map_err(|e| bad(format!("the compensator rounded to f32 is not valid: {e}")))?;
        let loss = crate::modelling::effects::nonlinear_gain(&file.effects);
        let nonlinear = if loss == 0.0 {
            None
        } else {
            let (lp_gain, lp) = design.lowpass_sections(fs)?;
            let n = BoardNonlinear {
                gain: to_f32(loss * fs * fs),
                lowpass_gain: to_f32(lp_gain),
                lowpass: lp.iter().map(|s| s.map(to_f32)).collect(),
            };
            let widened: Vec<[f64; 5]> = n.lowpass.iter().map(|s| s.map(f64::from)).collect();
            NonlinearDampingCoefficients::<f32, MAX_EXPORT_SECTIONS>::new(
                f64::from(n.gain),
                f64::from(n.lowpass_gain),
                &widened,
            )
            .map_err(|e| {
                bad(format!(
                    "the nonlinear-damping correction rounded to f32 is not valid: {e}"
                ))
            })?;
            Some(n)
        };
        Ok(Self {
            sample_rate_hz: fs,
            delay_samples,
            latency_samples: design.latency_samples,
            gain,
            sections,
            nonlinear,
        })
    }

    /// Rust source: `const` items to `include!` in a firmware module.
    #[must_use]
    pub fn to_rust(&self, source: &str) -> String {
        let n = self.sections.len();
        let mut s = String::new();
        let _ = writeln!(
            s,
            "// Generated by `unlag export --format rust` from {source} (unlag {}). Do not edit.",
            env!("CARGO_PKG_VERSION")
        );
        s.push_str(
            "// The board's compensator: u_hat = cascade(GAIN * y), each section [b0, b1, b2, a1, a2]\n\
             // with y = b0 x + b1 x[k-1] + b2 x[k-2] - a1 y[k-1] - a2 y[k-2]. The values are the f32\n\
             // coefficients the board runs, widened exactly to f64. Build the compensator with\n\
             // `unlag::compensator::CascadeCoefficients::<f32, SECTION_COUNT>::new(GAIN, &SECTIONS)`.\n",
        );
        let _ = writeln!(
            s,
            "/// Sample rate in Hz the coefficients belong to.\npub const SAMPLE_RATE_HZ: f64 = {:?};",
            self.sample_rate_hz
        );
        let _ = writeln!(
            s,
            "/// The probe model's delay in samples.\npub const DELAY_SAMPLES: u32 = {};",
            self.delay_samples
        );
        let _ = writeln!(
            s,
            "/// Latency of the reconstruction behind the true pressure, in samples.\npub const LATENCY_SAMPLES: f64 = {:?};",
            self.latency_samples
        );
        let _ = writeln!(
            s,
            "/// Number of second-order sections.\npub const SECTION_COUNT: usize = {n};"
        );
        let _ = writeln!(
            s,
            "/// Input gain of the cascade.\npub const GAIN: f64 = {:?};",
            f64::from(self.gain)
        );
        s.push_str("/// Sections `[b0, b1, b2, a1, a2]`.\npub const SECTIONS: [[f64; 5]; SECTION_COUNT] = [\n");
        for sec in &self.sections {
            let v: Vec<String> = sec.iter().map(|c| format!("{:?}", f64::from(*c))).collect();
            let _ = writeln!(s, "    [{}],", v.join(", "));
        }
        s.push_str("];\n");
        if let Some(n) = &self.nonlinear {
            s.push_str(
                "// Nonlinear damping: add `NonlinearDampingCoefficients::<f32, NONLINEAR_SECTION_COUNT>::new(\n\
                 // NONLINEAR_GAIN, NONLINEAR_LOWPASS_GAIN, &NONLINEAR_SECTIONS)`'s output, fed the same\n\
                 // probe sample, to the cascade's output.\n",
            );
            let _ = writeln!(
                s,
                "/// Nonlinear-damping correction: gain per squared sample difference.\npub const NONLINEAR_GAIN: f64 = {:?};",
                f64::from(n.gain)
            );
            let _ = writeln!(
                s,
                "/// Input gain of the correction's low-pass.\npub const NONLINEAR_LOWPASS_GAIN: f64 = {:?};",
                f64::from(n.lowpass_gain)
            );
            let _ = writeln!(
                s,
                "/// Sections of the correction's low-pass.\npub const NONLINEAR_SECTION_COUNT: usize = {};",
                n.lowpass.len()
            );
            s.push_str("/// The correction's low-pass sections `[b0, b1, b2, a1, a2]`.\npub const NONLINEAR_SECTIONS: [[f64; 5]; NONLINEAR_SECTION_COUNT] = [\n");
            for sec in &n.lowpass {
                let v: Vec<String> = sec.iter().map(|c| format!("{:?}", f64::from(*c))).collect();
                let _ = writeln!(s, "    [{}],", v.join(", "));
            }
            s.push_str("];\n");
        }
        s
    }

    /// A C header with `static const float` coefficients.
    #[must_use]
    pub fn to_c(&self, source: &str) -> String {
        let n = self.sections.len();
        let mut s = String::new();
        let _ = writeln!(
            s,
            "/* Generated by `unlag export --format c` from {source} (unlag {}). Do not edit.",
            env!("CARGO_PKG_VERSION")
        );
        for line in [
            " * The board's compensator: u_hat = cascade(unlag_gain * y), each section",
            " * {b0, b1, b2, a1, a2} with y = b0 x + b1 x[k-1] + b2 x[k-2] - a1 y[k-1] - a2 y[k-2].",
            " * CMSIS-DSP's arm_biquad_cascade_df1_f32 / _df2T_f32 take {b0, b1, b2, -a1, -a2}",
            " * (the opposite sign of a1, a2) and apply no input gain: scale the input, or b of",
            " * the first section, by unlag_gain. */",
        ] {
            s.push_str(line);
            s.push('\n');
        }
        s.push_str("#ifndef UNLAG_COEFFICIENTS_H\n#define UNLAG_COEFFICIENTS_H\n\n");
        let _ = writeln!(
            s,
            "#define UNLAG_SAMPLE_RATE_HZ {:?} /* Hz */",
            self.sample_rate_hz
        );
        let _ = writeln!(
            s,
            "#define UNLAG_DELAY_SAMPLES {}u /* model delay, samples */",
            self.delay_samples
        );
        let _ = writeln!(
            s,
            "#define UNLAG_LATENCY_SAMPLES {:?} /* reconstruction latency, samples */",
            self.latency_samples
        );
        let _ = writeln!(s, "#define UNLAG_SECTION_COUNT {n}u\n");
        let _ = writeln!(s, "static const float unlag_gain = {:?}f;", self.gain);
        s.push_str("static const float unlag_sections[UNLAG_SECTION_COUNT][5] = {\n");
        for sec in &self.sections {
            let v: Vec<String> = sec.iter().map(|c| format!("{c:?}f")).collect();
            let _ = writeln!(s, "    {{{}}},", v.join(", "));
        }
        s.push_str("};\n");
        if let Some(n) = &self.nonlinear {
            s.push_str(
                "\n/* Nonlinear damping: with d = y[k] - y[k-1], add\n\
                 * cascade(unlag_nonlinear_gain * unlag_nonlinear_lowpass_gain * |d| d) through the\n\
                 * sections below to the compensator's output for the same sample. */\n",
            );
            let _ = writeln!(
                s,
                "#define UNLAG_NONLINEAR_SECTION_COUNT {}u",
                n.lowpass.len()
            );
            let _ = writeln!(
                s,
                "static const float unlag_nonlinear_gain = {:?}f;",
                n.gain
            );
            let _ = writeln!(
                s,
                "static const float unlag_nonlinear_lowpass_gain = {:?}f;",
                n.lowpass_gain
            );
            s.push_str("static const float unlag_nonlinear_sections[UNLAG_NONLINEAR_SECTION_COUNT][5] = {\n");
            for sec in &n.lowpass {
                let v: Vec<String> = sec.iter().map(|c| format!("{c:?}f")).collect();
                let _ = writeln!(s, "    {{{}}},", v.join(", "));
            }
            s.push_str("};\n");
        }
        s.push_str("\n#endif /* UNLAG_COEFFICIENTS_H */\n");
        s
    }

    /// The binary blob of [`crate::blob`], checked by parsing it back before it is returned.
    ///
    /// # Errors
    /// [`Error::Numerical`] if the blob cannot be encoded or does not parse back to the same
    /// coefficients (neither happens for a set built by [`Self::from_model_file`]).
    pub fn to_bin(&self) -> Result<Vec<u8>> {
        let fail = |message: String| Error::Numerical {
            context: "export".into(),
            message,
        };
        let mut out = vec![
            0u8;
            blob::encoded_len_nonlinear(
                self.sections.len(),
                self.nonlinear.as_ref().map_or(0, |n| n.lowpass.len())
            )
        ];
        let n = match &self.nonlinear {
            None => blob::encode(
                &mut out,
                self.sample_rate_hz,
                self.delay_samples,
                self.gain,
                &self.sections,
            ),
            Some(n) => blob::encode_nonlinear(
                &mut out,
                self.sample_rate_hz,
                self.delay_samples,
                self.gain,
                &self.sections,
                &blob::NonlinearCorrection {
                    gain: n.gain,
                    lowpass_gain: n.lowpass_gain,
                    lowpass: &n.lowpass,
                },
            ),
        }
        .map_err(|e| fail(e.to_string()))?;
        out.truncate(n);
        let back = blob::parse::<MAX_EXPORT_SECTIONS>(&out)
            .map_err(|e| fail(format!("the blob does not parse back: {e}")))?;
        let widened: Vec<[f64; 5]> = self.sections.iter().map(|s| s.map(f64::from)).collect();
        let direct =
            CascadeCoefficients::<f32, MAX_EXPORT_SECTIONS>::new(f64::from(self.gain), &widened)
                .map_err(|e| fail(e.to_string()))?;
        let direct_nonlinear = match &self.nonlinear {
            None => None,
            Some(n) => {
                let widened: Vec<[f64; 5]> = n.lowpass.iter().map(|s| s.map(f64::from)).collect();
                Some(
                    NonlinearDampingCoefficients::<f32, MAX_EXPORT_SECTIONS>::new(
                        f64::from(n.gain),
                        f64::from(n.lowpass_gain),
                        &widened,
                    )
                    .map_err(|e| fail(e.to_string()))?,
                )
            }
        };
        if back.cascade != direct
            || back.sections != self.sections.len()
            || back.nonlinear != direct_nonlinear
        {
            return Err(fail("the blob parses back to other coefficients".into()));
        }
        Ok(out)
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

impl FixedBoardCoefficients {
    /// Takes the fixed-point plan of the model file's `[inverse]` design, or plans one for
    /// `full_scale` when it is given (it replaces a stored plan).
    ///
    /// # Errors
    /// [`Error::UnsupportedOnBoard`] when the model has nonlinear damping (the fixed-point
    /// compensator does not run its correction); [`Error::Model`] naming `path` when there is
    /// no design, no plan and no full
    /// scale, or the plan's sections are refused by the board's validation; the planner's
    /// errors.
    pub fn from_model_file(file: &ModelFile, path: &Path, full_scale: Option<f64>) -> Result<Self> {
        check_fixed_point(file, path)?;
        let bad = |message: String| Error::Model {
            path: path.to_path_buf(),
            message,
        };
        let Some(design) = &file.inverse else {
            return Err(bad(
                "no [inverse] compensator design to export (run `unlag invert` first)".into(),
            ));
        };
        design.check_exportable()?;
        let plan = match (full_scale, &design.fixed) {
            (Some(f), _) => FixedPlan::new(design, f)?,
            (None, Some(p)) => p.clone(),
            (None, None) => {
                return Err(bad(
                    "no fixed-point plan in the model file: give --full-scale (the ADC's full scale in the probe's units)".into(),
                ))
            }
        };
        let sections = plan.board_sections();
        if sections.is_empty() || sections.len() > MAX_EXPORT_SECTIONS {
            return Err(bad(format!(
                "the fixed-point compensator has {} sections; export needs 1 to {MAX_EXPORT_SECTIONS}",
                sections.len()
            )));
        }
        FixedCascade::<MAX_EXPORT_SECTIONS>::new(&sections)
            .map_err(|e| bad(format!("the fixed-point sections are not valid: {e}")))?;
        let fs = file.model.fs;
        if !(fs.is_finite() && fs > 0.0) {
            return Err(bad(format!(
                "sample rate {fs} Hz is not finite and positive"
            )));
        }
        let delay_samples = u32::try_from(file.model.delay).map_err(|_| {
            bad(format!(
                "delay {} does not fit in 32 bits",
                file.model.delay
            ))
        })?;
        Ok(Self {
            sample_rate_hz: fs,
            delay_samples,
            latency_samples: design.latency_samples,
            full_scale: plan.full_scale,
            output_exponent: plan.output_exponent,
            sections,
        })
    }

    /// Rust source: `const` items, with the sections as `unlag::fixed::FixedSection`.
    #[must_use]
    pub fn to_rust(&self, source: &str) -> String {
        let mut s = String::new();
        let _ = writeln!(
            s,
            "// Generated by `unlag export --format rust --number-format fixed` from {source} (unlag {}). Do not edit.",
            env!("CARGO_PKG_VERSION")
        );
        s.push_str(
            "// The board's fixed-point compensator: input codes are Q1.31 of FULL_SCALE, outputs\n\
             // Q1.31 of FULL_SCALE * 2^OUTPUT_EXPONENT. Build it with\n\
             // `unlag::fixed::FixedCascade::<SECTION_COUNT>::new(&SECTIONS)`.\n",
        );
        let _ = writeln!(s, "/// Sample rate in Hz the coefficients belong to.\npub const SAMPLE_RATE_HZ: f64 = {:?};", self.sample_rate_hz);
        let _ = writeln!(
            s,
            "/// The probe model's delay in samples.\npub const DELAY_SAMPLES: u32 = {};",
            self.delay_samples
        );
        let _ = writeln!(s, "/// Latency of the reconstruction behind the true pressure, in samples.\npub const LATENCY_SAMPLES: f64 = {:?};", self.latency_samples);
        let _ = writeln!(s, "/// ADC full scale in the probe's units: the input code 2^31.\npub const FULL_SCALE: f64 = {:?};", self.full_scale);
        let _ = writeln!(s, "/// The output is Q1.31 of FULL_SCALE * 2^OUTPUT_EXPONENT.\npub const OUTPUT_EXPONENT: i32 = {};", self.output_exponent);
        let _ = writeln!(
            s,
            "/// Number of sections.\npub const SECTION_COUNT: usize = {};",
            self.sections.len()
        );
        s.push_str("/// The sections.\npub const SECTIONS: [unlag::fixed::FixedSection; SECTION_COUNT] = [\n");
        for f in &self.sections {
            let _ = writeln!(
                s,
                "    unlag::fixed::FixedSection {{ a: {:?}, b: {:?}, c: {:?}, d: {}, shift: {} }},",
                f.a, f.b, f.c, f.d, f.shift
            );
        }
        s.push_str("];\n");
        s
    }

    /// A C header with `int32_t` sections.
    #[must_use]
    pub fn to_c(&self, source: &str) -> String {
        let mut s = String::new();
        let _ = writeln!(
            s,
            "/* Generated by `unlag export --format c --number-format fixed` from {source} (unlag {}). Do not edit.",
            env!("CARGO_PKG_VERSION")
        );
        for line in [
            " * Normal-form sections, per sample and section (u the section input, x its states):",
            " *   x1' = trunc((a11 x1 + a12 x2 + b1 u) >> 30)   x2' = trunc((a21 x1 + a22 x2 + b2 u) >> 30)",
            " *   y   = round((c1 x1 + c2 x2 + d u) >> shift)   in 64-bit accumulators, saturated to int32;",
            " * see unlag::fixed for the exact arithmetic. Input: Q1.31 of UNLAG_FULL_SCALE; output:",
            " * Q1.31 of UNLAG_FULL_SCALE * 2^UNLAG_OUTPUT_EXPONENT. */",
        ] {
            s.push_str(line);
            s.push('\n');
        }
        s.push_str("#ifndef UNLAG_FIXED_COEFFICIENTS_H\n#define UNLAG_FIXED_COEFFICIENTS_H\n\n#include <stdint.h>\n\n");
        let _ = writeln!(
            s,
            "#define UNLAG_SAMPLE_RATE_HZ {:?} /* Hz */",
            self.sample_rate_hz
        );
        let _ = writeln!(
            s,
            "#define UNLAG_DELAY_SAMPLES {}u /* model delay, samples */",
            self.delay_samples
        );
        let _ = writeln!(
            s,
            "#define UNLAG_LATENCY_SAMPLES {:?} /* reconstruction latency, samples */",
            self.latency_samples
        );
        let _ = writeln!(
            s,
            "#define UNLAG_FULL_SCALE {:?} /* input code 2^31 */",
            self.full_scale
        );
        let _ = writeln!(s, "#define UNLAG_OUTPUT_EXPONENT {}", self.output_exponent);
        let _ = writeln!(s, "#define UNLAG_SECTION_COUNT {}u\n", self.sections.len());
        s.push_str("/* {a11, a12, a21, a22, b1, b2, c1, c2, d, shift} per section */\n");
        s.push_str("static const int32_t unlag_fixed_sections[UNLAG_SECTION_COUNT][10] = {\n");
        for f in &self.sections {
            let v: Vec<String> =
                f.a.iter()
                    .chain(&f.b)
                    .chain(&f.c)
                    .chain([&f.d])
                    .map(|x| {
                        if *x == i32::MIN {
                            "INT32_MIN".to_string()
                        } else {
                            x.to_string()
                        }
                    })
                    .chain([f.shift.to_string()])
                    .collect();
            let _ = writeln!(s, "    {{{}}},", v.join(", "));
        }
        s.push_str("};\n\n#endif /* UNLAG_FIXED_COEFFICIENTS_H */\n");
        s
    }

    /// The fixed-point blob of [`crate::blob`] (number format 1), checked by parsing it back.
    ///
    /// # Errors
    /// [`Error::Numerical`] if the blob cannot be encoded or does not parse back.
    pub fn to_bin(&self) -> Result<Vec<u8>> {
        let fail = |message: String| Error::Numerical {
            context: "export".into(),
            message,
        };
        let mut out = vec![0u8; blob::encoded_len_fixed(self.sections.len())];
        let n = blob::encode_fixed(
            &mut out,
            self.sample_rate_hz,
            self.delay_samples,
            self.full_scale,
            self.output_exponent,
            &self.sections,
        )
        .map_err(|e| fail(e.to_string()))?;
        out.truncate(n);
        let back = blob::parse_fixed::<MAX_EXPORT_SECTIONS>(&out)
            .map_err(|e| fail(format!("the blob does not parse back: {e}")))?;
        let direct = FixedCascade::<MAX_EXPORT_SECTIONS>::new(&self.sections)
            .map_err(|e| fail(e.to_string()))?;
        if back.cascade != direct || back.sections != self.sections.len() {
            return Err(fail("the blob parses back to other coefficients".into()));
        }
        Ok(out)
    }

    /// The file's bytes in `format`.
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

/// The board's direct-form fixed-point compensator as exported (`--number-format fixed
/// --fixed-form direct`): the integer sections of [`crate::design::quantise::DirectPlan`], validated as
/// the board validates them; as Rust, C, or the blob's number format 2.
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

impl DirectBoardCoefficients {
    /// Takes the direct-form plan of the model file's `[inverse]` design, or plans one for
    /// `full_scale` when it is given (it replaces a stored plan).
    ///
    /// # Errors
    /// [`Error::UnsupportedOnBoard`] when the model has nonlinear damping; [`Error::Model`]
    /// naming `path` when there is no design, no direct-form plan and no full scale, or the
    /// sections are refused by the board's validation; the planner's errors.
    pub fn from_model_file(file: &ModelFile, path: &Path, full_scale: Option<f64>) -> Result<Self> {
        check_fixed_point(file, path)?;
        let bad = |message: String| Error::Model {
            path: path.to_path_buf(),
            message,
        };
        let Some(design) = &file.inverse else {
            return Err(bad(
                "no [inverse] compensator design to export (run `unlag invert` first)".into(),
            ));
        };
        design.check_exportable()?;
        let plan = match (full_scale, &design.fixed_direct) {
            (Some(f), _) => DirectPlan::new(design, f)?,
            (None, Some(p)) => p.clone(),
            (None, None) => {
                return Err(bad(
                    "no direct-form fixed-point plan in the model file: give --full-scale (the ADC's full scale in the probe's units)".into(),
                ))
            }
        };
        let sections = plan.board_sections();
        if sections.is_empty() || sections.len() > MAX_EXPORT_SECTIONS {
            return Err(bad(format!(
                "the direct-form compensator has {} sections; export needs 1 to {MAX_EXPORT_SECTIONS}",
                sections.len()
            )));
        }
        DirectCascade::<MAX_EXPORT_SECTIONS>::new(&sections)
            .map_err(|e| bad(format!("the direct-form sections are not valid: {e}")))?;
        let fs = file.model.fs;
        if !(fs.is_finite() && fs > 0.0) {
            return Err(bad(format!(
                "sample rate {fs} Hz is not finite and positive"
            )));
        }
        let delay_samples = u32::try_from(file.model.delay).map_err(|_| {
            bad(format!(
                "delay {} does not fit in 32 bits",
                file.model.delay
            ))
        })?;
        Ok(Self {
            sample_rate_hz: fs,
            delay_samples,
            latency_samples: design.latency_samples,
            full_scale: plan.full_scale,
            output_exponent: plan.output_exponent,
            sections,
        })
    }

    /// Rust source: `const` items, with the sections as `unlag::fixed::direct::DirectSection`.
    #[must_use]
    pub fn to_rust(&self, source: &str) -> String {
        let mut s = String::new();
        let _ = writeln!(
            s,
            "// Generated by `unlag export --format rust --number-format fixed --fixed-form direct` from {source} (unlag {}). Do not edit.",
            env!("CARGO_PKG_VERSION")
        );
        s.push_str(
            "// The board's direct-form fixed-point compensator: input codes are Q1.31 of FULL_SCALE,\n\
             // outputs Q1.31 of FULL_SCALE * 2^OUTPUT_EXPONENT. Build it with\n\
             // `unlag::fixed::direct::DirectCascade::<SECTION_COUNT>::new(&SECTIONS)`.\n",
        );
        let _ = writeln!(s, "/// Sample rate in Hz the coefficients belong to.\npub const SAMPLE_RATE_HZ: f64 = {:?};", self.sample_rate_hz);
        let _ = writeln!(
            s,
            "/// The probe model's delay in samples.\npub const DELAY_SAMPLES: u32 = {};",
            self.delay_samples
        );
        let _ = writeln!(s, "/// Latency of the reconstruction behind the true pressure, in samples.\npub const LATENCY_SAMPLES: f64 = {:?};", self.latency_samples);
        let _ = writeln!(s, "/// ADC full scale in the probe's units: the input code 2^31.\npub const FULL_SCALE: f64 = {:?};", self.full_scale);
        let _ = writeln!(s, "/// The output is Q1.31 of FULL_SCALE * 2^OUTPUT_EXPONENT.\npub const OUTPUT_EXPONENT: i32 = {};", self.output_exponent);
        let _ = writeln!(
            s,
            "/// Number of sections.\npub const SECTION_COUNT: usize = {};",
            self.sections.len()
        );
        s.push_str("/// The sections.\npub const SECTIONS: [unlag::fixed::direct::DirectSection; SECTION_COUNT] = [\n");
        for f in &self.sections {
            let _ = writeln!(
                s,
                "    unlag::fixed::direct::DirectSection {{ b: {:?}, neg_a: {:?} }},",
                f.b, f.neg_a
            );
        }
        s.push_str("];\n");
        s
    }

    /// A C header with `int32_t` sections.
    #[must_use]
    pub fn to_c(&self, source: &str) -> String {
        let mut s = String::new();
        let _ = writeln!(
            s,
            "/* Generated by `unlag export --format c --number-format fixed --fixed-form direct` from {source} (unlag {}). Do not edit.",
            env!("CARGO_PKG_VERSION")
        );
        for line in [
            " * Direct-form-I sections with first-order error feedback, per sample and section (x the",
            " * section input, y its output, e the residual carried, all int32, 64-bit accumulator):",
            " *   acc = e + b0 x0 + b1 x1 + b2 x2 + na1 y1 + na2 y2      (na = -a: the NEGATED denominator)",
            " *   y = acc >> 30 (floor; high word saturated to 30 bits), e = acc & (2^30 - 1);",
            " * see unlag::fixed::direct for the exact arithmetic. Input: Q1.31 of UNLAG_FULL_SCALE;",
            " * output: Q1.31 of UNLAG_FULL_SCALE * 2^UNLAG_OUTPUT_EXPONENT. */",
        ] {
            s.push_str(line);
            s.push('\n');
        }
        s.push_str("#ifndef UNLAG_DIRECT_COEFFICIENTS_H\n#define UNLAG_DIRECT_COEFFICIENTS_H\n\n#include <stdint.h>\n\n");
        let _ = writeln!(
            s,
            "#define UNLAG_SAMPLE_RATE_HZ {:?} /* Hz */",
            self.sample_rate_hz
        );
        let _ = writeln!(
            s,
            "#define UNLAG_DELAY_SAMPLES {}u /* model delay, samples */",
            self.delay_samples
        );
        let _ = writeln!(
            s,
            "#define UNLAG_LATENCY_SAMPLES {:?} /* reconstruction latency, samples */",
            self.latency_samples
        );
        let _ = writeln!(
            s,
            "#define UNLAG_FULL_SCALE {:?} /* input code 2^31 */",
            self.full_scale
        );
        let _ = writeln!(s, "#define UNLAG_OUTPUT_EXPONENT {}", self.output_exponent);
        let _ = writeln!(s, "#define UNLAG_SECTION_COUNT {}u\n", self.sections.len());
        s.push_str("/* {b0, b1, b2, -a1, -a2} per section, Q2.30 */\n");
        s.push_str("static const int32_t unlag_direct_sections[UNLAG_SECTION_COUNT][5] = {\n");
        for f in &self.sections {
            let v: Vec<String> =
                f.b.iter()
                    .chain(&f.neg_a)
                    .map(|x| {
                        if *x == i32::MIN {
                            "INT32_MIN".to_string()
                        } else {
                            x.to_string()
                        }
                    })
                    .collect();
            let _ = writeln!(s, "    {{{}}},", v.join(", "));
        }
        s.push_str("};\n\n#endif /* UNLAG_DIRECT_COEFFICIENTS_H */\n");
        s
    }

    /// The direct-form blob of [`crate::blob`] (number format 2), checked by parsing it back.
    ///
    /// # Errors
    /// [`Error::Numerical`] if the blob cannot be encoded or does not parse back.
    pub fn to_bin(&self) -> Result<Vec<u8>> {
        let fail = |message: String| Error::Numerical {
            context: "export".into(),
            message,
        };
        let mut out = vec![0u8; blob::encoded_len_direct(self.sections.len())];
        let n = blob::encode_direct(
            &mut out,
            self.sample_rate_hz,
            self.delay_samples,
            self.full_scale,
            self.output_exponent,
            &self.sections,
        )
        .map_err(|e| fail(e.to_string()))?;
        out.truncate(n);
        let back = blob::parse_direct::<MAX_EXPORT_SECTIONS>(&out)
            .map_err(|e| fail(format!("the blob does not parse back: {e}")))?;
        let cascade = DirectCascade::<MAX_EXPORT_SECTIONS>::new(&self.sections)
            .map_err(|e| fail(e.to_string()))?;
        if back.cascade != cascade || back.sections != self.sections.len() {
            return Err(fail("the blob parses back to other coefficients".into()));
        }
        Ok(out)
    }

    /// The file's bytes in `format`.
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

/// The board's number format for [`export_with`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum NumberFormat {
    /// `f32` (the default).
    F32,
    /// Fixed point: the model file's plan, or a new one for this full scale.
    Fixed {
        /// ADC full scale in the probe's units; `None` takes the plan stored in the model file.
        full_scale: Option<f64>,
    },
    /// Fixed point in the direct form ([`DirectBoardCoefficients`]): the model file's plan, or
    /// a new one for this full scale.
    FixedDirect {
        /// ADC full scale in the probe's units; `None` takes the plan stored in the model file.
        full_scale: Option<f64>,
    },
}

/// What [`export`] wrote.
#[derive(Debug, Clone, PartialEq)]
pub struct Summary {
    /// `"f32"` or `"fixed"`.
    pub number_format: &'static str,
    /// Sample rate in Hz.
    pub sample_rate_hz: f64,
    /// Model delay in samples.
    pub delay_samples: u32,
    /// Reconstruction latency in samples.
    pub latency_samples: f64,
    /// Sections exported.
    pub sections: usize,
    /// Bytes written.
    pub bytes: usize,
}

/// Loads `model`, exports its `f32` compensator in `format` and writes `output` atomically.
///
/// # Errors
/// Loading the model file, [`BoardCoefficients::from_model_file`], or writing the output.
pub fn export(model: &Path, format: Format, output: &Path) -> Result<Summary> {
    export_with(model, format, NumberFormat::F32, output)
}

/// Loads `model`, exports its compensator in `format` and `number_format`, and writes
/// `output` atomically (nothing is written on error).
///
/// # Errors
/// Loading the model file, [`BoardCoefficients::from_model_file`] or
/// [`FixedBoardCoefficients::from_model_file`], or writing the output.
pub fn export_with(
    model: &Path,
    format: Format,
    number_format: NumberFormat,
    output: &Path,
) -> Result<Summary> {
    let file = ModelFile::load(model)?;
    export_file(&file, model, format, number_format, output)
}

/// Exports the compensator of an already loaded (or derived, e.g. rescaled to a temperature)
/// model file `file` that came from `model`, and writes `output` atomically.
///
/// # Errors
/// As [`export_with`], less the loading.
pub fn export_file(
    file: &ModelFile,
    model: &Path,
    format: Format,
    number_format: NumberFormat,
    output: &Path,
) -> Result<Summary> {
    let file = file.clone();
    let source = model.file_name().map_or_else(
        || model.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    );
    let (bytes, summary) = match number_format {
        NumberFormat::F32 => {
            let c = BoardCoefficients::from_model_file(&file, model)?;
            let bytes = c.render(format, &source)?;
            let summary = Summary {
                number_format: "f32",
                sample_rate_hz: c.sample_rate_hz,
                delay_samples: c.delay_samples,
                latency_samples: c.latency_samples,
                sections: c.sections.len(),
                bytes: bytes.len(),
            };
            (bytes, summary)
        }
        NumberFormat::Fixed { full_scale } => {
            let c = FixedBoardCoefficients::from_model_file(&file, model, full_scale)?;
            let bytes = c.render(format, &source)?;
            let summary = Summary {
                number_format: "fixed",
                sample_rate_hz: c.sample_rate_hz,
                delay_samples: c.delay_samples,
                latency_samples: c.latency_samples,
                sections: c.sections.len(),
                bytes: bytes.len(),
            };
            (bytes, summary)
        }
        NumberFormat::FixedDirect { full_scale } => {
            let c = DirectBoardCoefficients::from_model_file(&file, model, full_scale)?;
            let bytes = c.render(format, &source)?;
            let summary = Summary {
                number_format: "fixed",
                sample_rate_hz: c.sample_rate_hz,
                delay_samples: c.delay_samples,
                latency_samples: c.latency_samples,
                sections: c.sections.len(),
                bytes: bytes.len(),
            };
            (bytes, summary)
        }
    };
    write_atomically(output, &bytes)?;
    Ok(summary)
}
