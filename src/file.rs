//! The model file: the stage outputs (model, fit report, design, effects, history) composed
//! into one versioned, human-readable TOML file, read and written.
//!
//! [`ModelFile`] is what `unlag fit` writes and every later command reads. It sits above the
//! stages it composes: the fit stage's [`Model`] and [`FitReport`], the design stage's
//! [`Design`](crate::design::inverse::Design), the modelling loop's
//! [`Effect`](crate::effects::Effect)s; and it says the state a diagnosis of it starts
//! from ([`ModelFile::current`]).

mod read;
mod write;
pub use read::{read_model_text, MAX_DELAY, MAX_MODEL_FILE_BYTES, MIN_SAMPLE_RATE_HZ};
pub use write::{
    check_replace, remove_unfinished, write_atomically, write_atomically_with, written,
    WriteFailure, STALE_AFTER,
};

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::fit::model::{FitReport, Model, Source, Uncertainty};
use crate::fit::{Method, TestRole};

/// Model file format version written by this crate.
pub const FORMAT_VERSION: u32 = 1;

/// The model file: the model, how it was fitted and from what.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(from = "RawModelFile")]
pub struct ModelFile {
    /// Format version ([`FORMAT_VERSION`]).
    pub format_version: u32,
    /// The model itself (flattened: `fs`, `delay`, `a`, `b` at the top of the file).
    #[serde(flatten)]
    pub model: Model,
    /// How it was fitted.
    pub fit: Option<FitReport>,
    /// The traces it came from and the errors on each.
    #[serde(default)]
    pub sources: Vec<Source>,
    /// The compensator designed for the board (stable, band-limited inverse), if any.
    #[serde(default)]
    pub inverse: Option<crate::design::inverse::Design>,
    /// Physical effects added in the modelling loop (`unlag fit --add KIND`).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub effects: Vec<crate::effects::Effect>,
    /// Every fit of this file, with its errors per test: the error falling as effects are
    /// added.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub history: Vec<HistoryRow>,
    /// The probe's physical geometry, when the user writes it into the file (`[probe]`): the
    /// report then draws the physical prediction beside the fitted model.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub probe: Option<ProbeGeometry>,
    /// The acquisition board the compensator is for (`[board]`): the arithmetic it runs and
    /// the ADC's range. `unlag compensate` and `unlag export` default to them.
    #[serde(default, skip_serializing_if = "Board::is_default")]
    pub board: Board,
}

/// The acquisition board a model file's compensator is for: what `unlag compensate` computes
/// and `unlag export` writes unless told otherwise.
///
/// ```toml
/// [board]
/// arithmetic = "fixed"   # "f32" (a board with an FPU) or "fixed" (32-bit fixed point)
/// full_scale = 20000.0   # the ADC's range in the probe's units: readings within +-full_scale
/// unit = "Pa"            # the traces' pressure unit, for printing (Pa, kPa, psi, mV, ...)
/// ```
///
/// The full scale is a property of the acquisition chain, not of a test: the fixed-point
/// compensator is planned for it (`unlag fit` and `unlag invert --full-scale`, or this field
/// written by hand: `unlag compensate` and `unlag export` plan anew for it when the stored
/// plan was made for another).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Board {
    /// The arithmetic the board runs the compensator in.
    #[serde(default)]
    pub arithmetic: BoardArithmetic,
    /// The ADC's range in the probe's units, as stated by the user; `None`: the default the
    /// design chose ([`crate::pipeline::default_full_scale`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub full_scale: Option<f64>,
    /// The unit the traces' pressures (and the full scale) are in, as stated by the user or
    /// read from the column names (`p_kPa`): only for printing them (`6.562 kPa`); `None`:
    /// not known, numbers printed alone.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub unit: Option<crate::trace::PressureUnit>,
}

impl Board {
    /// `true` for an f32 board with no stated range: nothing to write.
    #[must_use]
    pub fn is_default(&self) -> bool {
        *self == Self::default()
    }
}

/// The arithmetic a board runs the compensator in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum BoardArithmetic {
    /// IEEE single precision (a Cortex-M4F or M7: [`crate::board::compensator`]).
    #[default]
    F32,
    /// 32-bit fixed point (a board without an FPU: [`crate::board::fixed`]), the plan stored with the
    /// design.
    Fixed,
}

impl BoardArithmetic {
    /// Its name in the file and on the command line.
    #[must_use]
    pub fn as_str(self) -> &'static str {
        match self {
            Self::F32 => "f32",
            Self::Fixed => "fixed",
        }
    }
}

/// [`ModelFile`] as the file spells it, the model's fields at the top: read field by field
/// (no flattening), so that every error keeps its line and column and an unknown field is
/// refused where it stands.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawModelFile {
    format_version: u32,
    fs: f64,
    delay: usize,
    a: Vec<f64>,
    b: Vec<f64>,
    fit: Option<FitReport>,
    #[serde(default)]
    sources: Vec<Source>,
    #[serde(default)]
    inverse: Option<crate::design::inverse::Design>,
    #[serde(default)]
    effects: Vec<crate::effects::Effect>,
    #[serde(default)]
    history: Vec<HistoryRow>,
    #[serde(default)]
    probe: Option<ProbeGeometry>,
    #[serde(default)]
    board: Board,
}

impl From<RawModelFile> for ModelFile {
    fn from(r: RawModelFile) -> Self {
        Self {
            format_version: r.format_version,
            model: Model {
                fs: r.fs,
                delay: r.delay,
                a: r.a,
                b: r.b,
            },
            fit: r.fit,
            sources: r.sources,
            inverse: r.inverse,
            effects: r.effects,
            history: r.history,
            probe: r.probe,
            board: r.board,
        }
    }
}

/// A probe's geometry in a model file: tubes in series from the measuring point on, then the
/// transducer volume (the `unlag predict --line L,D --volume V` description).
///
/// ```toml
/// [probe]
/// lines = [[0.6, 1.1e-3]]   # [length, inner diameter] in m, from the measuring point on
/// volume_m3 = 20e-9
/// ```
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProbeGeometry {
    /// Tubes as `[length_m, diameter_m]`, from the measuring point on.
    pub lines: Vec<[f64; 2]>,
    /// Volume at the closed end in m^3.
    pub volume_m3: f64,
    /// Mean gas temperature in K (air).
    #[serde(default = "default_temperature_k")]
    pub temperature_k: f64,
    /// Mean absolute pressure in Pa.
    #[serde(default = "default_pressure_pa")]
    pub pressure_pa: f64,
}

fn default_temperature_k() -> f64 {
    293.15
}

fn default_pressure_pa() -> f64 {
    101_325.0
}

/// One fit in a model file's history.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HistoryRow {
    /// The effects the fit had (kinds), in the order added; stored by name (`mode`,
    /// `coloured-noise`, ...), an unknown name refused when the file is read.
    pub effects: Vec<crate::effects::EffectKind>,
    /// Model order.
    pub order: usize,
    /// Delay (samples).
    pub delay: usize,
    /// Simulation error per test.
    pub tests: Vec<HistoryTest>,
}

impl HistoryRow {
    /// The effects' names joined by `sep`: `mode, leak` for `", "`.
    #[must_use]
    pub fn effect_names(&self, sep: &str) -> String {
        let names: Vec<&str> = self.effects.iter().map(|k| k.as_str()).collect();
        names.join(sep)
    }
}

/// A held-out test's simulation error with the latest fit in a model file's history and with
/// the fit before it ([`ModelFile::held_out_changes`]): what the loop's last change did where
/// the model is judged.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct HeldOutChange {
    /// The test's file name.
    pub file: String,
    /// Its error with the fit before.
    pub before: f64,
    /// Its error with the latest fit.
    pub after: f64,
    /// The fit before's delay (samples).
    pub delay_before: usize,
    /// The latest fit's delay (samples).
    pub delay_after: usize,
}

impl HeldOutChange {
    /// Whether the error rose by more than [`ERROR_RISE_NOTED`](crate::fit::ERROR_RISE_NOTED): the change made the model
    /// worse on data it was not fitted to.
    #[must_use]
    pub fn rose(&self) -> bool {
        crate::fit::error_rose(self.before, self.after)
    }
}

/// The current state of a model file that a diagnosis starts from.
#[derive(Debug, Clone)]
pub struct Current<'a> {
    /// The model.
    pub model: &'a Model,
    /// Its effects.
    pub effects: &'a [crate::effects::Effect],
    /// The method it was fitted with.
    pub method: Method,
    /// Its stated uncertainty (the fit report's), if any.
    pub uncertainty: Option<&'a Uncertainty>,
    /// Whether its order was given (`--order N`) rather than chosen. A refit with an order
    /// given drops the modes the model carries, so a change names them again
    /// ([`crate::modelling::diagnose::Remedy::KeepingModes`]).
    pub order_given: bool,
}

/// One test's error in a history row.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HistoryTest {
    /// File name.
    pub file: String,
    /// What the test was used for, written `estimation` or `validation`.
    pub role: TestRole,
    /// Normalised RMS simulation error (effects included).
    pub nrmse: f64,
}

const HEADER: &str = "\
# unlag probe model.
# y[k] = sum_{i=0..m} b[i] u[k-i-delay] - sum_{i=1..m} a[i] y[k-i]
# fs in Hz, delay in samples; a = [a1..am], b = [b0..bm].
";

impl ModelFile {
    /// The fit's stated uncertainty, when the file records one.
    #[must_use]
    pub fn uncertainty(&self) -> Option<&Uncertainty> {
        self.fit.as_ref()?.uncertainty.as_ref()
    }

    /// The state a diagnosis of this file starts from: its model and effects, the method it
    /// was fitted with (output error when the file records no fit) and its stated
    /// uncertainty. `unlag compare`, `unlag diagnose` and the report all start here.
    #[must_use]
    pub fn current(&self) -> Current<'_> {
        Current {
            model: &self.model,
            effects: &self.effects,
            method: self.fit.as_ref().map_or(Method::Oe, |f| f.method),
            uncertainty: self.uncertainty(),
            order_given: self
                .fit
                .as_ref()
                .is_none_or(|f| f.order_selection == crate::fit::OrderSelection::Fixed),
        }
    }

    /// Each validation test in both of the last two rows of the history, with its error before
    /// and after the latest fit. Empty for a file with fewer than two rows.
    #[must_use]
    pub fn held_out_changes(&self) -> Vec<HeldOutChange> {
        let [.., before, after] = self.history.as_slice() else {
            return Vec::new();
        };
        let held_out = |row: &'_ HistoryRow, file: &str| {
            row.tests
                .iter()
                .find(|t| t.file == file && t.role == TestRole::Validation)
                .map(|t| t.nrmse)
        };
        after
            .tests
            .iter()
            .filter(|t| t.role == TestRole::Validation)
            .filter_map(|t| {
                Some(HeldOutChange {
                    file: t.file.clone(),
                    before: held_out(before, &t.file)?,
                    after: t.nrmse,
                    delay_before: before.delay,
                    delay_after: after.delay,
                })
            })
            .collect()
    }

    /// The [`ModelFile::held_out_changes`] whose error rose ([`HeldOutChange::rose`]): a
    /// change of the modelling loop that made the model worse where it is judged.
    #[must_use]
    pub fn error_rises(&self) -> Vec<HeldOutChange> {
        self.held_out_changes()
            .into_iter()
            .filter(HeldOutChange::rose)
            .collect()
    }

    /// Renders the file as TOML.
    ///
    /// # Errors
    /// [`Error::Serialise`] if serialisation fails (it does not for finite values).
    pub fn to_toml(&self) -> Result<String> {
        // A compensator designed in this run names the model it was designed for; one read
        // from a file keeps the name it had (and was checked against the model when read).
        let stamped;
        let file = match &self.inverse {
            Some(d) if d.model_sha256.is_none() => {
                let mut f = self.clone();
                if let Some(d) = f.inverse.as_mut() {
                    d.model_sha256 = Some(self.model.fingerprint());
                }
                stamped = f;
                &stamped
            }
            _ => self,
        };
        let body = toml::to_string(file).map_err(|e| Error::Serialise {
            what: "model file",
            message: e.to_string(),
        })?;
        Ok(format!("{HEADER}{body}"))
    }

    /// Writes the file atomically, after reading the text back as [`ModelFile::load`] will:
    /// a file the loader would refuse is never written.
    ///
    /// # Errors
    /// [`Error::Model`] for a model out of the file's limits, [`Error::Io`] when it cannot
    /// be written.
    pub fn save(&self, path: &Path) -> Result<()> {
        let text = self.to_toml()?;
        Self::parse(path, &text).map_err(|e| Error::Model {
            path: path.to_path_buf(),
            message: format!("not written: the model would not load again ({e})"),
        })?;
        write_atomically(path, text.as_bytes())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::design::quantise::{DirectPlan, FixedPlan};

    #[test]
    fn file_round_trip() {
        let f = ModelFile {
            format_version: FORMAT_VERSION,
            model: Model {
                fs: 1000.0,
                delay: 3,
                a: vec![-1.5, 0.7],
                b: vec![0.1, 0.08, 0.02],
            },
            fit: None,
            sources: vec![],
            inverse: None,
            effects: Vec::new(),
            history: Vec::new(),
            probe: None,
            board: Default::default(),
        };
        let text = f.to_toml().unwrap();
        assert!(text.contains("delay = 3"), "{text}");
        let back: ModelFile = toml::from_str(&text).unwrap();
        assert_eq!(back, f);
        // A file with no fit is diagnosed as an output-error fit.
        assert_eq!(f.current().method, crate::fit::Method::Oe);
        assert!(f.current().uncertainty.is_none());
        // ... and as one whose order was given (the trials refit at a fixed order).
        assert!(f.current().order_given);
    }

    #[test]
    fn a_held_out_error_the_latest_fit_raised_is_an_error_rise() {
        let row = |delay: usize, val: f64, other: f64| HistoryRow {
            effects: Vec::new(),
            order: 2,
            delay,
            tests: vec![
                HistoryTest {
                    file: "est.csv".into(),
                    role: TestRole::Estimation,
                    nrmse: 0.02,
                },
                HistoryTest {
                    file: "val.csv".into(),
                    role: TestRole::Validation,
                    nrmse: val,
                },
                HistoryTest {
                    file: "wake.csv".into(),
                    role: TestRole::Validation,
                    nrmse: other,
                },
            ],
        };
        let mut f = ModelFile {
            format_version: FORMAT_VERSION,
            model: Model {
                fs: 1000.0,
                delay: 3,
                a: vec![-0.5],
                b: vec![0.5],
            },
            fit: None,
            sources: vec![],
            inverse: None,
            effects: Vec::new(),
            history: vec![row(6, 0.00963, 0.004)],

            probe: None,

            board: Default::default(),
        };
        assert!(
            f.held_out_changes().is_empty(),
            "one row: nothing to compare"
        );
        // val.csv rises 14 %, wake.csv falls; an estimation error that rose is not held out.
        let mut latest = row(8, 0.0110, 0.003);
        latest.tests[0].nrmse = 0.05;
        f.history.push(latest);
        let rise = HeldOutChange {
            file: "val.csv".into(),
            before: 0.00963,
            after: 0.0110,
            delay_before: 6,
            delay_after: 8,
        };
        assert_eq!(f.error_rises(), [rise]);
        assert_eq!(f.held_out_changes().len(), 2);
        assert!(!f.held_out_changes()[1].rose());
        // A rise within the refit's own spread is not one.
        f.history.push(row(8, 0.0110 * 1.005, 0.003));
        assert!(f.error_rises().is_empty());
    }

    /// The shipped model with a fixed-point plan for a 20000 full scale, as `unlag invert
    /// --board fixed` stores it.
    fn with_plan() -> String {
        let shipped = include_str!("../examples/data/board_model.toml");
        let mut f = ModelFile::parse(Path::new("m.toml"), shipped).unwrap();
        let d = f.inverse.as_mut().unwrap();
        d.fixed = Some(FixedPlan::new(&*d, 20_000.0).unwrap());
        d.fixed_direct = Some(DirectPlan::new(&*d, 20_000.0).unwrap());
        f.to_toml().unwrap()
    }

    /// The error for `text` and the 1-based line of the first line of `text` that starts
    /// with `marker` at or after the line containing `after`.
    fn refused(text: &str) -> (usize, String) {
        match ModelFile::parse(Path::new("m.toml"), text).unwrap_err() {
            Error::ModelAt { line, message, .. } => (line, message),
            e => panic!("{e:?}"),
        }
    }

    fn line_of(text: &str, after: &str, marker: &str) -> usize {
        let start = text.find(after).unwrap();
        let at = start + text[start..].find(marker).unwrap();
        text[..at].matches('\n').count() + 1
    }

    #[test]
    fn a_stored_compensator_names_its_model_and_another_model_is_refused() {
        let text = with_plan();
        let f = ModelFile::parse(Path::new("m.toml"), &text).unwrap();
        let d = f.inverse.as_ref().unwrap();
        assert_eq!(
            d.model_sha256.as_deref(),
            Some(f.model.fingerprint().as_str())
        );
        // A design made in this run is stamped when written, and reads back the same.
        let mut fresh = f.clone();
        fresh.inverse.as_mut().unwrap().model_sha256 = None;
        assert_eq!(fresh.to_toml().unwrap(), text);
        // The model changed under the compensator: refused at the compensator's model name.
        let mut moved = f.clone();
        moved.model.b[0] *= 1.0 + 1e-12;
        let moved_text = toml::to_string(&moved).unwrap();
        let (line, message) = refused(&moved_text);
        assert!(message.contains("designed for another model"), "{message}");
        assert_eq!(line, line_of(&moved_text, "[inverse]", "model_sha256"));
    }

    #[test]
    fn a_fixed_point_plan_that_the_compensator_does_not_give_is_refused_at_its_field() {
        let text = with_plan();
        let cases = [
            (
                "output_exponent = ",
                "output_exponent = 100",
                "inverse.fixed.output_exponent is 100",
            ),
            (
                "form = \"",
                "form = \"banana",
                "inverse.fixed.sections[0].form is \"banana",
            ),
            (
                "full_scale = 20000.0",
                "full_scale = -1.0",
                "inverse.fixed.full_scale = -1 must be",
            ),
            (
                "shift = ",
                "shift = 70\n# ",
                "inverse.fixed.sections[0].shift is 70",
            ),
        ];
        for (from, to, expected) in cases {
            let at = text.find("[inverse.fixed]").unwrap();
            let k = at + text[at..].find(from).unwrap();
            let edited = format!("{}{to}{}", &text[..k], &text[k + from.len()..]);
            let (line, message) = refused(&edited);
            assert!(message.contains(expected), "{from}: {message}");
            assert_eq!(
                line,
                line_of(&edited, "[inverse.fixed]", to.trim_end_matches("\n# ")),
                "{message}"
            );
        }
        // The direct form's plan is checked too.
        let at = text.find("[inverse.fixed_direct]").unwrap();
        let k = at + text[at..].find("output_exponent = ").unwrap();
        let edited = format!("{}output_exponent = -7\n#{}", &text[..k], &text[k..]);
        let (_, message) = refused(&edited);
        assert!(
            message.contains("inverse.fixed_direct.output_exponent is -7"),
            "{message}"
        );
    }

    #[test]
    fn coefficient_lengths_and_rates_out_of_physics_are_refused() {
        let shipped = include_str!("../examples/data/board_model.toml");
        let a = shipped.lines().find(|l| l.starts_with("a = [")).unwrap();
        let (line, message) = refused(&shipped.replacen(a, "a = []", 1));
        assert!(
            message.contains("b has 5 coefficients but a has 0"),
            "{message}"
        );
        assert_eq!(line, line_of(shipped, "", "\nb = ") + 1);
        for (fs, shown) in [("1e-300", "1e-300"), ("1e300", "1e300"), ("0.5", "0.5")] {
            let text = shipped.replacen("fs = 10000.0", &format!("fs = {fs}"), 1);
            let (_, message) = refused(&text);
            assert!(message.ends_with(&format!("not {shown}")), "{message}");
            assert!(message.len() < 120, "{message}");
        }
    }

    #[test]
    fn a_model_file_is_read_within_its_limit_and_as_utf8_with_a_position() {
        let dir = tempfile::tempdir().unwrap();
        let big = dir.path().join("big.toml");
        let f = std::fs::File::create(&big).unwrap();
        f.set_len(MAX_MODEL_FILE_BYTES + 1).unwrap();
        let e = read_model_text(&big).unwrap_err().to_string();
        assert!(e.contains("larger than 16 MiB"), "{e}");
        if Path::new("/dev/zero").exists() {
            let e = read_model_text(Path::new("/dev/zero"))
                .unwrap_err()
                .to_string();
            assert!(e.contains("larger than 16 MiB"), "{e}");
        }
        let bad = dir.path().join("bad.toml");
        std::fs::write(&bad, b"format_version = 1\nfs = 1\xff0\n").unwrap();
        let e = ModelFile::load(&bad).unwrap_err();
        let Error::ModelAt {
            line,
            column,
            ref message,
            ..
        } = e
        else {
            panic!("{e:?}");
        };
        assert_eq!((line, column), (2, 7), "{e}");
        assert!(message.contains("byte 0xff"), "{e}");
    }

    /// The fit's method is stored by its name, read back as the method, and written as it
    /// was read; an unknown name is refused at its line with the names there are.
    #[test]
    fn the_fit_method_round_trips_by_name_and_an_unknown_one_is_refused() {
        let shipped = include_str!("../examples/data/board_model.toml");
        let path = Path::new("board_model.toml");
        let f = ModelFile::parse(path, shipped).unwrap();
        assert_eq!(f.fit.as_ref().unwrap().method, crate::fit::Method::Oe);
        // Its order was chosen (`order_selection = "auto ..."`), not given.
        assert!(!f.current().order_given);
        for method in crate::fit::Method::ALL {
            let text = shipped.replacen(
                "method = \"oe\"",
                &format!("method = \"{}\"", method.name()),
                1,
            );
            let f = ModelFile::parse(path, &text).unwrap();
            assert_eq!(f.fit.as_ref().unwrap().method, method);
            assert_eq!(f.current().method, method);
            let written = f.to_toml().unwrap();
            assert!(
                written.contains(&format!("\n[fit]\nmethod = \"{}\"\n", method.name())),
                "{written}"
            );
            assert_eq!(ModelFile::parse(path, &written).unwrap(), f);
        }
        let unknown = shipped.replacen("method = \"oe\"", "method = \"lsq\"", 1);
        let e = ModelFile::parse(path, &unknown).unwrap_err();
        let Error::ModelAt {
            line, ref message, ..
        } = e
        else {
            panic!("{e:?}");
        };
        assert_eq!(line, 11, "{e}");
        assert!(
            message.contains("unknown fit method `lsq`: one of oe, bj, sm, arx"),
            "{e}"
        );
    }

    /// A history row's effects are kinds, stored by their names as before: a known one
    /// round-trips to the same bytes, an unknown one is refused with its name.
    #[test]
    fn history_effects_are_kinds_by_name_and_an_unknown_one_is_refused() {
        use crate::effects::EffectKind;
        let shipped = include_str!("../examples/data/board_model.toml");
        let path = Path::new("board_model.toml");
        let mut f = ModelFile::parse(path, shipped).unwrap();
        assert_eq!(f.to_toml().unwrap(), shipped);
        f.history.push(HistoryRow {
            effects: vec![EffectKind::Mode, EffectKind::ColouredNoise],
            order: 2,
            delay: 3,
            tests: vec![HistoryTest {
                file: "est.csv".into(),
                role: TestRole::Estimation,
                nrmse: 0.25,
            }],
        });
        let written = f.to_toml().unwrap();
        assert!(
            written.contains("effects = [\"mode\", \"coloured-noise\"]"),
            "{written}"
        );
        let back = ModelFile::parse(path, &written).unwrap();
        assert_eq!(back, f);
        assert_eq!(back.to_toml().unwrap(), written);
        assert_eq!(back.history[0].effect_names(", "), "mode, coloured-noise");
        let unknown = written.replacen("\"coloured-noise\"]", "\"gremlins\"]", 1);
        let e = ModelFile::parse(path, &unknown).unwrap_err().to_string();
        assert!(e.contains("unknown effect kind 'gremlins'"), "{e}");
    }
}
