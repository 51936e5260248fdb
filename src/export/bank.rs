//! Export of a temperature bank (`unlag export MODEL --temperatures FROM:TO:STEP`): one `f32`
//! coefficient set per gas temperature, for a board that measures the temperature and picks
//! the set itself ([`crate::board::compensator::TemperatureBank`]).
//!
//! This module owns the temperature grid ([`TemperatureRange`]) and the sets (each designed by
//! [`crate::pipeline::at_temperature`] and checked as [`BoardCoefficients::from_model_file`]
//! checks one, then the whole table as the board's [`TemperatureBank::new`] checks it); the
//! bank is written, as [`BoardImage::Bank`], by the image's Rust and C writers. Every set must
//! have the same number of sections. The binary blob of [`crate::board::blob`] carries one set, so a
//! bank is not written as `bin`: a running board is sent one set at a time (`--temperature K
//! --format bin`).

use std::path::Path;

use crate::board::compensator::TemperatureBank;
use crate::error::{Error, Result};
use crate::export::{BoardCoefficients, BoardImage, Format, MAX_EXPORT_SECTIONS};
use crate::file::write_atomically;
use crate::file::ModelFile;

/// Most sets one bank may hold.
pub const MAX_BANK_SETS: usize = 64;

/// The temperatures of a bank: `from`, `from + step`, ... up to `to` (included when it falls
/// on the grid, within a millionth of a step).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TemperatureRange {
    /// First temperature (K).
    pub from_k: f64,
    /// Last temperature (K), at least `from_k`.
    pub to_k: f64,
    /// Step (K), positive.
    pub step_k: f64,
}

fn bad_range(message: String) -> Error {
    Error::InvalidParameter {
        parameter: crate::error::Parameter::Temperatures,
        message,
    }
}

/// The refusal of a bank as a blob, which carries one set.
pub(super) fn not_a_blob() -> Error {
    bad_range("a blob carries one coefficient set, not a bank".into())
        .advised(crate::error::Advice::BankAsSource)
}

impl TemperatureRange {
    /// Parses `FROM:TO:STEP` (kelvin), e.g. `253:353:10`.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for another shape, numbers that are not positive and finite,
    /// `TO` below `FROM`, or more than [`MAX_BANK_SETS`] temperatures.
    pub fn parse(text: &str) -> Result<Self> {
        let parts: Vec<&str> = text.split(':').collect();
        let [from, to, step] = parts.as_slice() else {
            return Err(bad_range(format!(
                "'{text}' is not FROM:TO:STEP in kelvin (e.g. 253:353:10)"
            )));
        };
        let number = |s: &str| {
            s.trim()
                .parse::<f64>()
                .ok()
                .filter(|x| x.is_finite() && *x > 0.0)
                .ok_or_else(|| {
                    bad_range(format!(
                        "'{s}' in '{text}' is not a positive number of kelvin"
                    ))
                })
        };
        let r = Self {
            from_k: number(from)?,
            to_k: number(to)?,
            step_k: number(step)?,
        };
        if r.to_k < r.from_k {
            return Err(bad_range(format!(
                "'{text}': TO ({} K) is below FROM ({} K)",
                r.to_k, r.from_k
            )));
        }
        let n = r.count();
        if n > MAX_BANK_SETS {
            return Err(bad_range(format!(
                "'{text}' makes {n} sets; a bank holds at most {MAX_BANK_SETS}: take a larger step"
            )));
        }
        Ok(r)
    }

    fn count(&self) -> usize {
        let n = ((self.to_k - self.from_k) / self.step_k + 1e-6).floor();
        // Finite and non-negative (checked by `parse`); saturates for an absurd range.
        #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
        let n = n as usize;
        n.saturating_add(1)
    }

    /// The temperatures (K), ascending.
    #[must_use]
    pub fn temperatures(&self) -> Vec<f64> {
        (0..self.count().min(MAX_BANK_SETS))
            .map(|i| {
                #[allow(clippy::cast_precision_loss)]
                let i = i as f64;
                self.from_k + i * self.step_k
            })
            .collect()
    }
}

/// A temperature bank as exported: the sets, rounded to `f32` and validated.
#[derive(Debug, Clone, PartialEq)]
pub struct BoardBank {
    /// The gas temperatures (K), ascending.
    pub temperatures_k: Vec<f64>,
    /// The hysteresis the board selects with (K): half the step.
    pub hysteresis_k: f64,
    /// Samples a new set warms up beside the old one before it takes over: long enough for
    /// the slowest pole of any set to decay to a millionth ([`warm_up_samples`]).
    pub warm_up_samples: u32,
    /// One set per temperature, each with the same number of sections.
    pub sets: Vec<BoardCoefficients>,
}

impl BoardBank {
    /// Designs one set per temperature of `range` from `file` (read from `path`), each with
    /// [`crate::pipeline::at_temperature`], and checks the table as the board will.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] when the model has no `temperature` effect;
    /// [`Error::UnsupportedOnBoard`] when it has nonlinear damping (a bank carries the linear
    /// compensator only); [`Error::Model`] when the redesign changes the number of sections
    /// between temperatures, or the board's bank refuses the table; the design's and
    /// [`BoardCoefficients::from_model_file`]'s errors.
    pub fn from_model_file(
        file: &ModelFile,
        path: &Path,
        range: &TemperatureRange,
    ) -> Result<Self> {
        let Some(reference) = crate::effects::reference_k(&file.effects) else {
            return Err(bad_range(
                "the model file has no temperature effect, so no reference temperature to scale \
                 from"
                    .into(),
            )
            .advised(crate::error::Advice::AddTemperature { by_hand: false }));
        };
        if crate::effects::nonlinear_gain(&file.effects) != 0.0 {
            return Err(Error::UnsupportedOnBoard {
                path: path.to_path_buf(),
                effect: "nonlinear damping",
                arithmetic: "temperature-bank",
            }
            .advised(crate::error::Advice::OnePerTemperature));
        }
        let bad = |message: String| Error::Model {
            path: path.to_path_buf(),
            message,
        };
        let temperatures_k = range.temperatures();
        let mut sets: Vec<BoardCoefficients> = Vec::with_capacity(temperatures_k.len());
        for &t in &temperatures_k {
            let scaled = crate::pipeline::at_temperature(file, t)?;
            let set = BoardCoefficients::from_model_file(&scaled, path).map_err(|e| {
                // The advice (a missing design) stays advice, for the command line to spell.
                let (e, advice) = match e {
                    Error::Advised { error, advice } => (*error, Some(advice)),
                    e => (e, None),
                };
                let e = bad(format!(
                    "at {t} K (model at {reference} K): {}",
                    e.to_string()
                        .trim_start_matches(&format!("{}: ", path.display()))
                ));
                match advice {
                    Some(advice) => e.advised(advice),
                    None => e,
                }
            })?;
            sets.push(set);
        }
        // The board's bank holds one section count: a set designed with fewer sections is
        // padded with identity sections ([1, 0, 0, 0, 0], exact in f32), which pass the
        // signal unchanged.
        let widest = sets.iter().map(|s| s.sections.len()).max().unwrap_or(0);
        for set in &mut sets {
            set.sections.resize(widest, [1.0, 0.0, 0.0, 0.0, 0.0]);
        }
        let bank = Self {
            hysteresis_k: 0.5 * range.step_k,
            warm_up_samples: warm_up_samples(&sets),
            temperatures_k,
            sets,
        };
        bank.board_bank::<MAX_BANK_SETS>()
            .map_err(|e| bad(format!("the board refuses the bank: {e}")))?;
        Ok(bank)
    }

    /// Each set's input gain, widened exactly from `f32`.
    #[must_use]
    pub fn gains(&self) -> Vec<f64> {
        self.sets.iter().map(|s| f64::from(s.gain)).collect()
    }

    /// Each set's sections, widened exactly from `f32`.
    #[must_use]
    pub fn sections(&self) -> Vec<Vec<[f64; 5]>> {
        self.sets
            .iter()
            .map(|s| s.sections.iter().map(|c| c.map(f64::from)).collect())
            .collect()
    }

    /// The board's bank built from exactly the exported numbers. `SETS` must be the number of
    /// sets (use [`MAX_BANK_SETS`] only through this check: the lengths must match).
    ///
    /// # Errors
    /// [`crate::board::compensator::BankError`] as the board reports it.
    pub fn board_bank<const SETS: usize>(
        &self,
    ) -> std::result::Result<
        TemperatureBank<f32, SETS, MAX_EXPORT_SECTIONS>,
        crate::board::compensator::BankError,
    > {
        TemperatureBank::new(
            &self.temperatures_k,
            &self.gains(),
            &self.sections(),
            self.hysteresis_k,
            self.warm_up_samples,
        )
    }

    /// Sections per set (every set has the same).
    #[must_use]
    pub fn section_count(&self) -> usize {
        self.sets.first().map_or(0, |s| s.sections.len())
    }
}

/// Longest warm-up written (a pole so slow would need more is capped here).
pub const MAX_WARM_UP_SAMPLES: u32 = 1 << 16;

/// Samples for the slowest pole of any set's sections to decay to a millionth (at least 1, at
/// most [`MAX_WARM_UP_SAMPLES`]).
#[must_use]
pub fn warm_up_samples(sets: &[BoardCoefficients]) -> u32 {
    let radius = sets
        .iter()
        .flat_map(|s| &s.sections)
        .map(|c| crate::board::compensator::section_pole_radius(f64::from(c[3]), f64::from(c[4])))
        .fold(0.0, f64::max);
    if radius <= 0.0 {
        return 1;
    }
    if radius >= 1.0 {
        return MAX_WARM_UP_SAMPLES;
    }
    let n = (1e-6f64.ln() / radius.ln()).ceil();
    if n >= f64::from(MAX_WARM_UP_SAMPLES) {
        MAX_WARM_UP_SAMPLES
    } else {
        // 0 < n < 2^16, checked above.
        #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
        let n = n as u32;
        n.max(1)
    }
}

/// What [`export_bank`] wrote.
#[derive(Debug, Clone, PartialEq)]
pub struct BankSummary {
    /// The temperatures (K).
    pub temperatures_k: Vec<f64>,
    /// Sections per set.
    pub sections: usize,
    /// Sample rate in Hz.
    pub sample_rate_hz: f64,
    /// Each set's model delay (samples).
    pub delay_samples: Vec<u32>,
    /// Bytes written.
    pub bytes: usize,
}

/// Loads `model`, designs its bank over `range` and writes it in `format` to `output`
/// atomically (nothing is written on error).
///
/// # Errors
/// Loading the model file, [`BoardBank::from_model_file`], [`BoardBank::render`], writing.
pub fn export_bank(
    model: &Path,
    range: &TemperatureRange,
    format: Format,
    output: &Path,
) -> Result<BankSummary> {
    if format == Format::Bin {
        // Refused before the model file is read.
        return Err(not_a_blob());
    }
    let file = ModelFile::load(model)?;
    let (bytes, summary) = render_bank(&file, model, range, format)?;
    write_atomically(output, &bytes)?;
    Ok(summary)
}

/// The bank of `file` (from `model`) over `range`, rendered in `format`, and what it holds.
///
/// # Errors
/// [`Format::Bin`] (refused before the slow design of every set), then as [`export_bank`].
pub(super) fn render_bank(
    file: &ModelFile,
    model: &Path,
    range: &TemperatureRange,
    format: Format,
) -> Result<(Vec<u8>, BankSummary)> {
    if format == Format::Bin {
        // Refused before the (slow) design of every set.
        return Err(not_a_blob());
    }
    let bank = BoardBank::from_model_file(file, model, range)?;
    let mut summary = BankSummary {
        temperatures_k: bank.temperatures_k.clone(),
        sections: bank.section_count(),
        sample_rate_hz: bank.sets.first().map_or(0.0, |c| c.sample_rate_hz),
        delay_samples: bank.sets.iter().map(|c| c.delay_samples).collect(),
        bytes: 0,
    };
    let bytes = BoardImage::from(bank).render(format, &super::source_name(model))?;
    summary.bytes = bytes.len();
    Ok((bytes, summary))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn set(sections: Vec<[f32; 5]>) -> BoardCoefficients {
        BoardCoefficients {
            sample_rate_hz: 1000.0,
            delay_samples: 1,
            latency_samples: 1.0,
            gain: 1.0,
            sections,
            nonlinear: None,
        }
    }

    #[test]
    fn the_warm_up_lasts_until_the_slowest_pole_has_decayed_to_a_millionth() {
        // Poles 0.5 and 0.9 (a real pair): 0.9^132 < 1e-6 < 0.9^131.
        let sets = [
            set(vec![[1.0, 0.0, 0.0, -0.5, 0.0]]),
            set(vec![[1.0, 0.0, 0.0, -1.4, 0.45]]),
        ];
        assert_eq!(warm_up_samples(&sets), 132);
        // A complex pair of radius 0.5: 0.5^20 < 1e-6 < 0.5^19; no pole at all: 1.
        assert_eq!(
            warm_up_samples(&[set(vec![[1.0, 0.0, 0.0, 0.0, 0.25]])]),
            20
        );
        assert_eq!(warm_up_samples(&[set(vec![[1.0, 0.0, 0.0, 0.0, 0.0]])]), 1);
        assert_eq!(
            warm_up_samples(&[set(vec![[1.0, 0.0, 0.0, -0.999_999, 0.0]])]),
            MAX_WARM_UP_SAMPLES
        );
    }

    #[test]
    fn parses_ranges_and_refuses_bad_ones() {
        let r = TemperatureRange::parse("253:353:10").unwrap();
        let t = r.temperatures();
        assert_eq!(t.len(), 11);
        assert_eq!(t.first(), Some(&253.0));
        assert!((t.last().unwrap() - 353.0).abs() < 1e-9);
        // TO off the grid: the last temperature below it.
        assert_eq!(
            TemperatureRange::parse("250:275:10")
                .unwrap()
                .temperatures(),
            vec![250.0, 260.0, 270.0]
        );
        // A fractional step that does not divide exactly in binary still reaches TO.
        assert_eq!(
            TemperatureRange::parse("290:291:0.1")
                .unwrap()
                .temperatures()
                .len(),
            11
        );
        assert_eq!(
            TemperatureRange::parse("300:300:5").unwrap().temperatures(),
            vec![300.0]
        );
        for bad in [
            "253:353",
            "253:353:10:1",
            "a:353:10",
            "253:353:0",
            "253:353:-5",
            "353:253:10",
            "0:10:1",
            "253:353:nan",
            "1:1000:1",
        ] {
            let e = TemperatureRange::parse(bad).unwrap_err();
            assert!(
                matches!(
                    e,
                    Error::InvalidParameter {
                        parameter: crate::error::Parameter::Temperatures,
                        ..
                    }
                ),
                "{bad}: {e}"
            );
            assert_eq!(e.to_string().lines().count(), 1, "{bad}: {e}");
        }
    }
}
