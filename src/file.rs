//! The model file: the stage outputs (model, fit report, design, effects, history) composed
//! into one versioned, human-readable TOML file, read and written.
//!
//! [`ModelFile`] is what `unlag fit` writes and every later command reads. It sits above the
//! stages it composes: the fit stage's [`Model`] and [`FitReport`], the design stage's
//! [`Design`], the modelling loop's
//! [`Effect`](crate::effects::Effect)s; and it says the state a diagnosis of it starts
//! from ([`ModelFile::current`]).

mod write;
pub use write::{
    check_replace, remove_unfinished, write_atomically, write_atomically_with, written,
    WriteFailure, STALE_AFTER,
};

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::design::inverse::Design;
use crate::design::quantise::{DirectPlan, FixedPlan};
use crate::error::{number, Error, Result};
use crate::fit::model::{FitReport, Model, Source, Uncertainty, MAX_ORDER};
use crate::fit::{Method, TestRole};
use crate::trace::MAX_SAMPLE_RATE_HZ;

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

    /// Reads and checks a model file: its syntax, every field's type and name (an unknown or
    /// misspelt field is refused with the nearest known name), and the limits of what the
    /// numbers may be: version, sample rate, delay, order, coefficient lengths, finite
    /// coefficients, a stable model, and a stable, finite stored compensator that names this
    /// model ([`crate::fit::model::Model::fingerprint`]) with fixed-point plans that its design
    /// gives. Every error names the line and column of the field. At most
    /// [`MAX_MODEL_FILE_BYTES`] are read.
    ///
    /// # Errors
    /// [`Error::ModelAt`] (or [`Error::Io`] when the file cannot be read).
    pub fn load(path: &Path) -> Result<Self> {
        let text = read_model_text(path)?;
        Self::parse(path, &text)
    }

    /// [`ModelFile::load`] on text already read (`path` names it in messages).
    ///
    /// # Errors
    /// As [`ModelFile::load`].
    pub fn parse(path: &Path, text: &str) -> Result<Self> {
        Self::parse_with(path, text, Stored::Checked).map(|(f, _)| f)
    }

    /// [`ModelFile::load`] for designing the compensator anew (`unlag invert`): a stored
    /// compensator designed for another model (the model edited after its design) is dropped
    /// instead of refused, and `true` says so; everything else, a broken compensator for this
    /// model included, is checked as [`ModelFile::load`] checks it.
    ///
    /// # Errors
    /// As [`ModelFile::load`], less the stored compensator's belonging.
    pub fn load_for_redesign(path: &Path) -> Result<(Self, bool)> {
        let text = read_model_text(path)?;
        Self::parse_with(path, &text, Stored::DroppedWhenStale)
    }

    fn parse_with(path: &Path, text: &str, stored: Stored) -> Result<(Self, bool)> {
        let at = |offset: usize, message: String| {
            let (line, column) = line_col(text, offset);
            Error::ModelAt {
                path: path.to_path_buf(),
                line,
                column,
                message,
            }
        };
        let mut file: Self = toml::from_str(text).map_err(|e| {
            let first = e.message().lines().next().unwrap_or("invalid TOML");
            at(
                e.span().map_or(0, |s| s.start),
                format!("{first}{}", nearest_field_hint(first)),
            )
        })?;
        let field = |keys: &[&str], message: String| at(offset_of(text, keys), message);
        if file.format_version != FORMAT_VERSION {
            return Err(field(
                &["format_version"],
                format!(
                    "format_version {} is not supported (this unlag reads version {FORMAT_VERSION})",
                    file.format_version
                ),
            ));
        }
        let m = &file.model;
        if !(m.fs.is_finite() && (MIN_SAMPLE_RATE_HZ..=MAX_SAMPLE_RATE_HZ).contains(&m.fs)) {
            return Err(field(
                &["fs"],
                format!(
                    "fs must be a sample rate in Hz from {MIN_SAMPLE_RATE_HZ} to \
                     {MAX_SAMPLE_RATE_HZ:e}, not {}",
                    number(m.fs)
                ),
            ));
        }
        if m.delay > MAX_DELAY {
            return Err(field(
                &["delay"],
                format!(
                    "delay {} samples ({:.3} s at fs = {} Hz) exceeds the largest supported delay, {MAX_DELAY} samples",
                    m.delay,
                    m.delay as f64 / m.fs,
                    m.fs
                ),
            ));
        }
        if m.b.is_empty() {
            return Err(field(
                &["b"],
                "b is empty: a model needs b0 at least".into(),
            ));
        }
        if m.b.len() > m.a.len() + 1 {
            return Err(field(
                &["b"],
                format!(
                    "b has {} coefficients but a has {}: a model of order m has a = [a1..am] \
                     and at most m + 1 coefficients b = [b0..bm]; restore a, or fit again",
                    m.b.len(),
                    m.a.len()
                ),
            ));
        }
        for (key, coefficients) in [("a", &m.a), ("b", &m.b)] {
            if let Some(i) = coefficients.iter().position(|c| !c.is_finite()) {
                return Err(field(&[key], format!("{key}[{i}] is not a finite number")));
            }
        }
        if m.b.iter().all(|c| *c == 0.0) {
            return Err(field(
                &["b"],
                "b is all zeros: the model passes nothing".into(),
            ));
        }
        if m.order() > MAX_ORDER {
            return Err(field(
                &["a"],
                format!(
                    "order {} exceeds the largest supported order {MAX_ORDER}",
                    m.order()
                ),
            ));
        }
        if let Some(p) = m.poles()?.first() {
            if p.norm() >= 1.0 {
                return Err(field(
                    &["a"],
                    format!(
                        "the model is unstable: pole {p:.6} has |z| = {:.6} >= 1",
                        p.norm()
                    ),
                ));
            }
        }
        // Stale: designed for another model (a compensator that names this model but is
        // broken is refused all the same).
        let belongs = file.inverse.as_ref().map(|d| check_belongs(d, m, &field));
        let stale = match belongs {
            Some(Err(_)) if stored == Stored::DroppedWhenStale => true,
            Some(Err(e)) => return Err(e),
            _ => false,
        };
        if stale {
            file.inverse = None;
        }
        if let Some(d) = &file.inverse {
            for (key, value) in [
                ("gain", d.gain),
                ("latency_samples", d.latency_samples),
                ("latency_s", d.latency_s),
                ("lowpass_hz", d.lowpass_hz),
            ] {
                if !value.is_finite() {
                    return Err(field(
                        &["inverse", key],
                        format!("inverse.{key} = {} is not a finite number", number(value)),
                    ));
                }
            }
            if let Err(e) = crate::board::compensator::CascadeCoefficients::<
                f64,
                { crate::board::compensator::MAX_TEST_ORDER },
            >::new(d.gain, &d.sections)
            {
                return Err(field(
                    &["inverse", "sections"],
                    format!("the stored compensator cannot run: {e}"),
                ));
            }
            check_plans(d, &field)?;
        }
        if let Some(fs) = file.board.full_scale {
            if !(fs.is_finite() && fs > 0.0) {
                return Err(field(
                    &["board", "full_scale"],
                    format!(
                        "board.full_scale = {} must be the ADC's range in the probe's units, a \
                         positive number",
                        number(fs)
                    ),
                ));
            }
        }
        if let Some(g) = &file.probe {
            let lines_ok =
                !g.lines.is_empty() && g.lines.iter().flatten().all(|x| x.is_finite() && *x > 0.0);
            if !lines_ok {
                return Err(field(
                    &["probe", "lines"],
                    "probe.lines must be [length_m, diameter_m] pairs, all above 0".into(),
                ));
            }
            for (key, value) in [
                ("volume_m3", g.volume_m3),
                ("temperature_k", g.temperature_k),
                ("pressure_pa", g.pressure_pa),
            ] {
                if !(value.is_finite() && (value > 0.0 || key == "volume_m3" && value == 0.0)) {
                    return Err(field(
                        &["probe", key],
                        format!("probe.{key} = {} must be a positive number", number(value)),
                    ));
                }
            }
        }
        Ok((file, stale))
    }
}

/// What [`ModelFile`]'s reader does with a stored compensator that does not belong to the
/// model beside it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Stored {
    /// Refused, at its field.
    Checked,
    /// Dropped: a new one is about to be designed.
    DroppedWhenStale,
}

/// Largest model file read (16 MiB). A model file holds a few hundred numbers and its
/// history, a few kilobytes; anything near this size is not one (a recording, a disk image,
/// a device that never ends), and is refused before it is read into memory.
pub const MAX_MODEL_FILE_BYTES: u64 = 16 << 20;

/// Lowest sample rate a model file may carry (1 Hz). The slowest pressure-measuring system
/// the crate models (a line of hundreds of metres) still responds within seconds, and a step
/// test of it is sampled at tens of Hz at least; a rate below 1 Hz is a unit mistake, and one
/// near zero would reach the board's single-precision blob as 0.
pub const MIN_SAMPLE_RATE_HZ: f64 = 1.0;

/// Reads a model file's text: at most [`MAX_MODEL_FILE_BYTES`] (a device or a huge file is
/// refused before it fills memory), UTF-8 (a stray byte is refused at its line and column).
///
/// # Errors
/// [`Error::Io`] when the file cannot be read, [`Error::Model`] when it is too large,
/// [`Error::ModelAt`] when it is not UTF-8.
pub fn read_model_text(path: &Path) -> Result<String> {
    use std::io::Read as _;
    let io = |source| Error::Io {
        path: path.to_path_buf(),
        action: "cannot read",
        source,
    };
    let f = std::fs::File::open(path).map_err(io)?;
    let meta = f.metadata().map_err(io)?;
    if meta.is_dir() {
        return Err(io(std::io::Error::other(
            "it is a directory, not a model file",
        )));
    }
    let too_large = || Error::Model {
        path: path.to_path_buf(),
        message: format!(
            "larger than {} MiB: not a model file (a model file is a few kilobytes of TOML)",
            MAX_MODEL_FILE_BYTES >> 20
        ),
    };
    if meta.len() > MAX_MODEL_FILE_BYTES {
        return Err(too_large());
    }
    let mut bytes = Vec::new();
    f.take(MAX_MODEL_FILE_BYTES + 1)
        .read_to_end(&mut bytes)
        .map_err(io)?;
    if bytes.len() as u64 > MAX_MODEL_FILE_BYTES {
        return Err(too_large());
    }
    String::from_utf8(bytes).map_err(|e| {
        let bytes = e.as_bytes();
        let at = e.utf8_error().valid_up_to();
        let valid = std::str::from_utf8(bytes.get(..at).unwrap_or_default()).unwrap_or_default();
        let (line, column) = line_col(valid, valid.len());
        Error::ModelAt {
            path: path.to_path_buf(),
            line,
            column,
            message: format!(
                "not UTF-8 text (byte 0x{:02x} at byte offset {at}): a model file is TOML as \
                 `unlag fit` writes it",
                bytes.get(at).copied().unwrap_or_default()
            ),
        }
    })
}

/// Refuses a stored compensator that does not name the model beside it: one designed for
/// another model (the file's `a`, `b`, `fs` or `delay` edited after the design) must not
/// reach a board.
fn check_belongs(d: &Design, m: &Model, field: &dyn Fn(&[&str], String) -> Error) -> Result<()> {
    let fix = "design it again for this model with `unlag invert`, or restore the model's \
               coefficients";
    match &d.model_sha256 {
        None => Err(field(
            &["inverse"],
            format!(
                "the stored compensator does not name the model it was designed for \
                 (inverse.model_sha256 is missing), so it cannot be shown to belong to this \
                 model; {fix}"
            ),
        )),
        Some(h) if *h != m.fingerprint() => Err(field(
            &["inverse", "model_sha256"],
            format!(
                "the stored compensator was designed for another model (its model_sha256 is \
                 not this file's fs, delay, a and b): {fix}"
            ),
        )),
        Some(_) => Ok(()),
    }
}

/// Refuses a fixed-point plan that is not the one the stored compensator gives: every
/// integer, shift, form and exponent is planned again from the design and its full scale,
/// and compared (the bounds, computed in floating point, to a relative 1e-9).
fn check_plans(d: &Design, field: &dyn Fn(&[&str], String) -> Error) -> Result<()> {
    let fix = "plan it again with `unlag invert --board fixed`, or remove the section";
    let planned = [
        (
            "fixed",
            d.fixed.as_ref().map(|p| {
                (
                    p.full_scale,
                    serde_json::to_value(p),
                    FixedPlan::new(d, p.full_scale).map(serde_json::to_value),
                )
            }),
        ),
        (
            "fixed_direct",
            d.fixed_direct.as_ref().map(|p| {
                (
                    p.full_scale,
                    serde_json::to_value(p),
                    DirectPlan::new(d, p.full_scale).map(serde_json::to_value),
                )
            }),
        ),
    ];
    for (key, plan) in planned {
        let Some((full_scale, stored, again)) = plan else {
            continue;
        };
        if !(full_scale.is_finite() && full_scale > 0.0) {
            return Err(field(
                &["inverse", key, "full_scale"],
                format!(
                    "inverse.{key}.full_scale = {} must be the ADC's range in the probe's units, \
                     a positive number; {fix}",
                    number(full_scale)
                ),
            ));
        }
        let again = match again {
            Ok(Ok(v)) => v,
            Ok(Err(e)) => {
                return Err(field(
                    &["inverse", key],
                    format!("inverse.{key} cannot be compared: {e}"),
                ))
            }
            Err(e) => {
                return Err(field(
                    &["inverse", key],
                    format!(
                        "inverse.{key}: the stored compensator gives no plan for full scale {} \
                         ({e}); {fix}",
                        number(full_scale)
                    ),
                ))
            }
        };
        let stored = stored.map_err(|e| {
            field(
                &["inverse", key],
                format!("inverse.{key} cannot be compared: {e}"),
            )
        })?;
        let mut path = vec![key.to_string()];
        if let Some((stored, planned)) = first_difference(&stored, &again, &mut path) {
            let keys: Vec<&str> = std::iter::once("inverse")
                .chain(path.iter().map(String::as_str))
                .collect();
            return Err(field(
                &keys,
                format!(
                    "inverse.{} is {stored}, but the stored compensator gives {planned} for this \
                     plan's full scale: the plan does not belong to the compensator; {fix}",
                    dotted(&path)
                ),
            ));
        }
    }
    Ok(())
}

/// `fixed.sections[2].shift` for the keys `fixed`, `sections`, `2`, `shift`.
fn dotted(path: &[String]) -> String {
    let mut out = String::new();
    for k in path {
        if k.parse::<usize>().is_ok() {
            out.push_str(&format!("[{k}]"));
        } else {
            if !out.is_empty() {
                out.push('.');
            }
            out.push_str(k);
        }
    }
    out
}

/// The first place two plans differ, as `(stored, planned)` texts, with `path` extended to
/// it: integers and strings exactly, other numbers to a relative 1e-9.
fn first_difference(
    stored: &serde_json::Value,
    planned: &serde_json::Value,
    path: &mut Vec<String>,
) -> Option<(String, String)> {
    use serde_json::Value;
    let text = |v: &Value| {
        let s = v.to_string();
        if s.chars().count() > 40 {
            format!("{}…", s.chars().take(40).collect::<String>())
        } else {
            s
        }
    };
    match (stored, planned) {
        (Value::Object(a), Value::Object(b)) => {
            for (k, va) in a {
                path.push(k.clone());
                let vb = b.get(k).unwrap_or(&Value::Null);
                if let Some(d) = first_difference(va, vb, path) {
                    return Some(d);
                }
                path.pop();
            }
            None
        }
        (Value::Array(a), Value::Array(b)) if a.len() == b.len() => {
            for (i, (va, vb)) in a.iter().zip(b).enumerate() {
                path.push(i.to_string());
                if let Some(d) = first_difference(va, vb, path) {
                    return Some(d);
                }
                path.pop();
            }
            None
        }
        (Value::Array(a), Value::Array(b)) => Some((
            format!("{} entries", a.len()),
            format!("{} entries", b.len()),
        )),
        (Value::Number(a), Value::Number(b)) => {
            let same = match (a.as_i64(), b.as_i64()) {
                (Some(x), Some(y)) => x == y,
                _ => match (a.as_f64(), b.as_f64()) {
                    (Some(x), Some(y)) => x == y || (x - y).abs() <= 1e-9 * x.abs().max(y.abs()),
                    _ => false,
                },
            };
            (!same).then(|| (text(stored), text(planned)))
        }
        (a, b) => (a != b).then(|| (text(a), text(b))),
    }
}

/// Longest delay a model file may carry, in samples (0.2 s at 5 MHz; a 68 m line at 340 m/s).
pub const MAX_DELAY: usize = 1 << 20;

/// Byte offset of the value (or key) at `keys` in a TOML text, as deep as the path goes;
/// 0 when the text does not parse.
fn offset_of(text: &str, keys: &[&str]) -> usize {
    let Ok(doc) = toml_edit::ImDocument::parse(text) else {
        return 0;
    };
    let mut table: &dyn toml_edit::TableLike = doc.as_table();
    let mut offset = 0;
    let mut keys = keys.iter();
    while let Some(key) = keys.next() {
        let Some((k, item)) = table.get_key_value(key) else {
            break;
        };
        if let Some(span) = item.span().or_else(|| k.span()) {
            offset = span.start;
        }
        // An array of tables (`[[inverse.fixed.sections]]`): the next key is its index.
        if let Some(array) = item.as_array_of_tables() {
            let Some(t) = keys
                .next()
                .and_then(|i| i.parse::<usize>().ok())
                .and_then(|i| array.get(i))
            else {
                break;
            };
            if let Some(span) = t.span() {
                offset = span.start;
            }
            table = t;
            continue;
        }
        if let Some(array) = item.as_array() {
            if let Some(v) = keys
                .next()
                .and_then(|i| i.parse::<usize>().ok())
                .and_then(|i| array.get(i))
            {
                if let Some(span) = v.span() {
                    offset = span.start;
                }
            }
            break;
        }
        match item.as_table_like() {
            Some(t) => table = t,
            None => break,
        }
    }
    offset
}

/// `; did you mean `x`?` for serde's "unknown field `y`, expected one of ..." message.
fn nearest_field_hint(message: &str) -> String {
    let Some(rest) = message.strip_prefix("unknown field `") else {
        return String::new();
    };
    let Some((unknown, expected)) = rest.split_once('`') else {
        return String::new();
    };
    expected
        .split('`')
        .skip(1)
        .step_by(2)
        .map(|known| (strsim::damerau_levenshtein(unknown, known), known))
        .filter(|(d, known)| *d <= 2.max(known.len() / 3))
        .min()
        .map_or_else(String::new, |(_, known)| {
            format!("; did you mean `{known}`?")
        })
}

fn line_col(text: &str, offset: usize) -> (usize, usize) {
    let before = text.get(..offset).unwrap_or(text);
    let line = before.matches('\n').count() + 1;
    let col = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    (line, col)
}

#[cfg(test)]
mod tests {
    use super::*;

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
