//! The report's last section: the error history of the fits in the model file and the ranked
//! candidates for the missing effect, their evidence in words.

use std::fmt::Write as _;
use std::path::Path;

use super::plot::{colour, figure, Panel, Series, Style};
use super::{escape, pct, push_figure, Inputs};
use crate::error::Result;
use crate::file::HistoryRow;
use crate::modelling::diagnose::Candidate;

/// The candidate's stated uncertainty before and after its trial, as HTML (empty when either
/// is missing).
fn stated_uncertainty(c: &Candidate) -> String {
    c.uncertainty_text()
        .map(|t| format!("<br><small>{}</small>", escape(&t)))
        .unwrap_or_default()
}

pub(super) fn history(h: &mut String, inputs: &Inputs<'_>) -> Result<()> {
    let file = inputs.file;
    let rows = &file.history;
    let step_name = |i: usize| {
        rows.get(i).map_or(String::new(), |r| {
            if r.effects.is_empty() {
                format!("{}. order {}", i + 1, r.order)
            } else {
                format!("{}. +{}", i + 1, r.effect_names("+"))
            }
        })
    };
    let mut files: Vec<&str> = Vec::new();
    for t in rows.iter().flat_map(|r| r.tests.iter()) {
        if !files.contains(&t.file.as_str()) {
            files.push(&t.file);
        }
    }
    let mut series = error_series(rows, &files);
    // Marks on every step (a line alone hides where the steps are).
    let marks: Vec<(f64, f64)> = series
        .iter()
        .flat_map(|s| s.points.iter().copied())
        .collect();
    series.push(Series::with("", marks, colour::REFERENCE, Style::Crosses));
    let floor = {
        let f: Vec<f64> = file.sources.iter().map(|s| s.noise_floor).collect();
        if f.is_empty() {
            None
        } else {
            Some(100.0 * f.iter().sum::<f64>() / f.len() as f64)
        }
    };
    if rows.is_empty() {
        h.push_str(
            "<p class=\"note\">The model file has no error history (it was not written by \
             <code>unlag fit</code>).</p>\n",
        );
    }
    let mut p = Panel::new(
        "error of each fit in this model file",
        "fit (effects added)",
        "error nrmse (%)",
        series,
    );
    if let Some(f) = floor {
        p = p.guides(vec![(f, "noise floor (mean)".into())]);
    }
    // From zero, with room above the highest point for its mark.
    let top = p
        .series
        .iter()
        .flat_map(|s| s.points.iter().map(|q| q.1))
        .chain(floor)
        .fold(0.0f64, f64::max);
    p.y = 0.0..(1.15 * top).max(1e-6);
    p.x = 0.5..(rows.len().max(1) as f64 + 0.5);
    p.x_names = (0..rows.len()).map(step_name).collect();
    let svg = figure("history", &[p], 320, 1)?;
    push_figure(
        h,
        "history",
        &svg,
        "Each point is one <code>unlag fit</code> into this file (x: the fit number and what \
         it added), its simulation error on each test; the error should fall towards the noise \
         floor as effects are added.",
    );
    history_table(h, rows);
    Ok(())
}

/// One series a test file: its error at each fit of the history (a line through them, or
/// crosses for a single fit).
fn error_series(rows: &[HistoryRow], files: &[&str]) -> Vec<Series> {
    let palette = [
        colour::PROBE,
        colour::MODEL,
        colour::COMPENSATED,
        colour::PHYSICS,
    ];
    files
        .iter()
        .enumerate()
        .map(|(j, f)| {
            let pts: Vec<(f64, f64)> = rows
                .iter()
                .enumerate()
                .filter_map(|(i, r)| {
                    r.tests
                        .iter()
                        .find(|t| t.file == *f)
                        .map(|t| ((i + 1) as f64, 100.0 * t.nrmse))
                })
                .collect();
            let name = Path::new(f)
                .file_name()
                .map_or_else(|| (*f).to_string(), |n| n.to_string_lossy().into_owned());
            Series::with(
                &name,
                pts,
                palette[j % palette.len()],
                if rows.len() > 1 {
                    Style::Line(2)
                } else {
                    Style::Crosses
                },
            )
        })
        .collect()
}

/// The history as a table: each fit's order, delay, effects and error per test.
fn history_table(h: &mut String, rows: &[HistoryRow]) {
    h.push_str(
        "<table class=\"history\"><tr><th>fit</th><th>order</th><th>delay</th><th>effects</th>\
         <th>error per test</th></tr>\n",
    );
    for (i, r) in rows.iter().enumerate() {
        let errs: Vec<String> = r
            .tests
            .iter()
            .map(|t| format!("{} ({}): {}", escape(&t.file), t.role, pct(t.nrmse)))
            .collect();
        let _ = writeln!(
            h,
            "<tr><td class=\"num\">{}</td><td class=\"num\">{}</td><td class=\"num\">{}</td>\
             <td>[{}]</td><td>{}</td></tr>",
            i + 1,
            r.order,
            r.delay,
            escape(&r.effect_names(", ")),
            errs.join("<br>")
        );
    }
    h.push_str("</table>\n");
}

/// The evidence's numbers to four significant digits (the full ones are in `--json`).
fn rounded(v: &serde_json::Value) -> serde_json::Value {
    use serde_json::Value;
    match v {
        Value::Number(n) => match n.as_f64() {
            Some(x) if n.is_f64() && x != 0.0 && x.is_finite() => {
                let digits = 3 - x.abs().log10().floor() as i32;
                let scale = 10f64.powi(digits);
                serde_json::Number::from_f64((x * scale).round() / scale)
                    .map_or_else(|| v.clone(), Value::Number)
            }
            _ => v.clone(),
        },
        Value::Array(a) => Value::Array(a.iter().map(rounded).collect()),
        Value::Object(o) => Value::Object(o.iter().map(|(k, x)| (k.clone(), rounded(x))).collect()),
        _ => v.clone(),
    }
}

/// A candidate's evidence as a reader reads it: `name value` pairs, nested names joined by
/// dots, long lists cut to their first values.
fn evidence_text(v: &serde_json::Value) -> String {
    use serde_json::Value;
    fn scalar(v: &Value) -> String {
        match v {
            Value::String(s) => s.clone(),
            Value::Array(a) => {
                let mut items: Vec<String> = a.iter().take(6).map(scalar).collect();
                if a.len() > 6 {
                    items.push(format!("... {} in all", a.len()));
                }
                items.join(", ")
            }
            Value::Null => "none".into(),
            other => other.to_string(),
        }
    }
    fn walk(prefix: &str, v: &Value, out: &mut Vec<String>) {
        match v {
            Value::Object(o) => {
                for (k, x) in o {
                    let name = if prefix.is_empty() {
                        k.replace('_', " ")
                    } else {
                        format!("{prefix} {}", k.replace('_', " "))
                    };
                    walk(&name, x, out);
                }
            }
            other if prefix.is_empty() => out.push(scalar(other)),
            other => out.push(format!("{prefix}: {}", scalar(other))),
        }
    }
    let mut out = Vec::new();
    walk("", v, &mut out);
    out.join("; ")
}

pub(super) fn candidates(h: &mut String, inputs: &Inputs<'_>) {
    h.push_str(
        "<h3>Candidates for the missing effect, best first</h3>\n\
         <table class=\"candidates\"><tr><th>#</th><th>effect</th><th>score</th>\
         <th>error in its trial</th><th>reading and evidence</th><th>change</th></tr>\n",
    );
    for (i, c) in inputs.candidates.iter().enumerate() {
        let evidence = evidence_text(&rounded(
            &serde_json::to_value(&c.evidence).unwrap_or(serde_json::Value::Null),
        ));
        let _ = writeln!(
            h,
            "<tr><td class=\"num\">{}</td><td><b>{}</b></td><td class=\"num\">{:.2}</td>\
             <td class=\"num\">{}</td><td>{}{}<br><small><code>{}</code></small></td>\
             <td><code>{}</code></td></tr>",
            i + 1,
            escape(c.kind.as_str()),
            c.score,
            escape(&c.error_change()).replace(" -> ", " &rarr; "),
            escape(&c.reading),
            stated_uncertainty(c),
            escape(&evidence),
            escape(&(inputs.change_text)(&c.change))
        );
    }
    h.push_str("</table>\n<p class=\"sub\">Score: ln of the held-out error's fall in a trial refit, less BIC's charge per parameter (ln n / 2n, n the held-out residual's independent samples).</p>\n");
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn evidence_reads_as_names_and_values_not_json() {
        let v = serde_json::json!({"peak_hz": 120.5, "band": {"low_db": -3.0}, "tests": [1, 2], "why": "a mode"});
        let t = evidence_text(&v);
        assert!(!t.contains('{') && !t.contains('"'), "{t}");
        assert!(t.contains("peak hz: 120.5"), "{t}");
        assert!(t.contains("band low db: -3.0"), "{t}");
        assert!(t.contains("tests: 1, 2"), "{t}");
        assert!(t.contains("why: a mode"), "{t}");
    }

    #[test]
    fn evidence_numbers_are_shortened_not_changed() {
        let v = serde_json::json!({"a": 0.000_716_295_602_505_328_9, "b": [303.955_078_125, 7],
                                   "c": "x", "d": -2.526_434_974_417_220_8});
        let r = rounded(&v);
        assert_eq!(r["a"].as_f64(), Some(0.000_716_3));
        assert_eq!(r["b"][0].as_f64(), Some(304.0));
        assert_eq!(r["b"][1].as_u64(), Some(7));
        assert_eq!(r["c"], "x");
        assert_eq!(r["d"].as_f64(), Some(-2.526));
    }
}
