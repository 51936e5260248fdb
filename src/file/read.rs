//! Reading a model file: its text within a size limit, its fields checked against what the
//! numbers may be, and every refusal placed at the field's line and column.

use std::path::Path;

use super::{ModelFile, FORMAT_VERSION};
use crate::design::inverse::Design;
use crate::design::quantise::{DirectPlan, FixedPlan};
use crate::error::{number, Error, Result};
use crate::fit::model::{Model, MAX_ORDER};
use crate::trace::MAX_SAMPLE_RATE_HZ;

impl ModelFile {
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
        check_model(&file.model, &field)?;
        // Stale: designed for another model (a compensator that names this model but is
        // broken is refused all the same).
        let belongs = file
            .inverse
            .as_ref()
            .map(|d| check_belongs(d, &file.model, &field));
        let stale = match belongs {
            Some(Err(_)) if stored == Stored::DroppedWhenStale => true,
            Some(Err(e)) => return Err(e),
            _ => false,
        };
        if stale {
            file.inverse = None;
        }
        if let Some(d) = &file.inverse {
            check_inverse(d, &field)?;
        }
        check_board_and_probe(&file, &field)?;
        Ok((file, stale))
    }
}

/// The model's numbers within the file's limits: sample rate, delay, coefficient lengths,
/// finite coefficients, order, stability.
fn check_model(m: &Model, field: &dyn Fn(&[&str], String) -> Error) -> Result<()> {
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
    Ok(())
}

/// A stored compensator's numbers: finite, a cascade the board can run, and fixed-point
/// plans its design gives.
fn check_inverse(d: &Design, field: &dyn Fn(&[&str], String) -> Error) -> Result<()> {
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
    check_plans(d, field)
}

/// The board's stated full scale and the probe's geometry, when the file gives them.
fn check_board_and_probe(file: &ModelFile, field: &dyn Fn(&[&str], String) -> Error) -> Result<()> {
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
    Ok(())
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
