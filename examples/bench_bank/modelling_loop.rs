//! The modelling loop on the bank (issue 14): from a second-order fit of the estimation test,
//! `unlag diagnose` names the missing effect from the estimation and validation tests; the
//! first name is scored against the hidden kind, and `unlag fit --add` of that name is
//! scored by the validation test's error before and after.

use std::fmt::Write as _;
use std::path::Path;

use super::draw::{Case, Kind, KINDS};

/// What the loop gave on one case.
#[derive(Debug, Default, Clone)]
pub struct LoopOutcome {
    /// Candidates, best first (their `kind`, as `--add` takes it).
    pub named: Vec<String>,
    /// Score gap between the first and the second candidate.
    pub margin: Option<f64>,
    /// Validation error of the second-order fit.
    pub before: Option<f64>,
    /// ... after `--add` of the first candidate.
    pub after: Option<f64>,
    /// The validation test's noise floor (as `fit` states it).
    pub floor: Option<f64>,
    /// The failed step and its first stderr line.
    pub failure: Option<String>,
}

impl LoopOutcome {
    /// The first candidate.
    pub fn first(&self) -> &str {
        self.named.first().map_or("-", String::as_str)
    }

    /// The first candidate is the hidden kind (`temperature` and `temperature-viscous` are one
    /// kind with two damping laws).
    pub fn right(&self, kind: Kind) -> bool {
        let first = self.first();
        match kind {
            Kind::Temperature => first.starts_with("temperature"),
            _ => first == kind.name(),
        }
    }
}

/// The validation error in the JSON of `unlag fit ... --json`.
fn validation_error(json: &str) -> Result<(f64, f64), String> {
    let v: serde_json::Value =
        serde_json::from_str(json.trim()).map_err(|e| format!("fit: unreadable JSON ({e})"))?;
    let source = v
        .get("sources")
        .and_then(|s| s.get(1))
        .ok_or("fit: no validation source in the JSON")?;
    let get = |k: &str| {
        source
            .get(k)
            .and_then(serde_json::Value::as_f64)
            .ok_or_else(|| format!("fit: no {k}"))
    };
    Ok((get("nrmse")?, get("noise_floor")?))
}

/// Runs the loop in the case's folder (its `est.csv` and `val.csv` made).
pub fn run(bin: &Path, dir: &Path) -> LoopOutcome {
    let mut o = LoopOutcome::default();
    let run = |args: &[&str], log: &str| super::unlag(bin, dir, args, log);
    let diagnosis = run(
        &["fit", "--order", "2", "est.csv", "-o", "loop.toml"],
        "loop-fit.log",
    )
    .and_then(|_| {
        run(
            &["diagnose", "loop.toml", "est.csv", "val.csv", "--json"],
            "loop-diagnose.log",
        )
    });
    let json = match diagnosis {
        Ok(j) => j,
        Err(e) => {
            o.failure = Some(e);
            return o;
        }
    };
    let v: serde_json::Value = match serde_json::from_str(json.trim()) {
        Ok(v) => v,
        Err(e) => {
            o.failure = Some(format!("diagnose: unreadable JSON ({e})"));
            return o;
        }
    };
    let candidates = v
        .get("candidates")
        .and_then(serde_json::Value::as_array)
        .cloned()
        .unwrap_or_default();
    o.named = candidates
        .iter()
        .filter_map(|c| c.get("kind")?.as_str().map(str::to_string))
        .collect();
    let score = |i: usize| candidates.get(i).and_then(|c| c.get("score")?.as_f64());
    o.margin = score(0).map(|a| a - score(1).unwrap_or(0.0));
    let base = ["fit", "--order", "2", "est.csv", "val.csv", "--json"];
    match run(&[&base[..], &["-o", "base.toml"]].concat(), "loop-base.log")
        .and_then(|j| validation_error(&j))
    {
        Ok((e, floor)) => {
            o.before = Some(e);
            o.floor = Some(floor);
        }
        Err(e) => o.failure = Some(e),
    }
    let first = o.first().to_string();
    // What the user copies: the first candidate's `--add` argument (a sensor resonance with
    // the frequency the diagnosis read).
    let add = candidates
        .first()
        .and_then(|c| c.get("change")?.as_str())
        .and_then(|c| c.split("--add ").nth(1))
        .and_then(|rest| rest.split_whitespace().next())
        .map_or_else(|| first.clone(), str::to_string);
    // Nothing to add for `none`, and nothing named for `unexplained`.
    if !matches!(first.as_str(), "none" | "unexplained" | "-") {
        match run(
            &[&base[..], &["--add", &add, "-o", "added.toml"]].concat(),
            "loop-added.log",
        )
        .and_then(|j| validation_error(&j))
        {
            Ok((e, _)) => o.after = Some(e),
            Err(e) => o.failure = Some(format!("--add {first}: {e}")),
        }
    }
    o
}

/// Names a diagnosis can give, in the confusion matrix's column order.
const NAMES: [&str; 12] = [
    "none",
    "unexplained",
    "leak",
    "drift",
    "offset",
    "coloured-noise",
    "mode",
    "sensor-resonance",
    "nonlinear-damping",
    "temperature",
    "delay",
    "other",
];

fn column(name: &str) -> usize {
    let name = if name.starts_with("temperature") {
        "temperature"
    } else {
        name
    };
    NAMES
        .iter()
        .position(|n| *n == name)
        .unwrap_or(NAMES.len() - 1)
}

/// The loop's report: the confusion matrix, the falls of the error, the misnamed cases.
pub fn report(rows: &[(Case, LoopOutcome)]) -> String {
    let mut r = String::new();
    let _ = writeln!(
        r,
        "## The modelling loop on the bank: {} cases\n",
        rows.len()
    );
    let _ = writeln!(r, "From `unlag fit --order 2 est.csv`, `unlag diagnose loop.toml est.csv val.csv` names the missing effect; rows are the hidden kind, columns the first name. The error is the validation test's (`fit --order 2 est.csv val.csv`, then the same with `--add FIRST`).\n");
    let _ = write!(r, "| hidden \\ named first |");
    for n in NAMES {
        let _ = write!(r, " {n} |");
    }
    let _ = writeln!(r, " right | error falls 3x or to 1.5x the floor |");
    let _ = writeln!(r, "|---|{}---|---|", "---|".repeat(NAMES.len()));
    let (mut right_all, mut total) = (0, 0);
    for k in KINDS {
        let group: Vec<&(Case, LoopOutcome)> = rows.iter().filter(|(c, _)| c.kind == k).collect();
        let mut counts = [0usize; NAMES.len()];
        for (_, o) in &group {
            if o.named.is_empty() {
                continue;
            }
            counts[column(o.first())] += 1;
        }
        let right = group.iter().filter(|(_, o)| o.right(k)).count();
        let falls: Vec<bool> = group
            .iter()
            .filter(|(_, o)| o.right(k) && k != Kind::None)
            .filter_map(|(_, o)| {
                let (b, a, f) = (o.before?, o.after?, o.floor?);
                Some(b / a >= 3.0 || a <= 1.5 * f)
            })
            .collect();
        right_all += right;
        total += group.len();
        let _ = write!(r, "| {} |", k.name());
        for c in counts {
            let _ = write!(
                r,
                " {} |",
                if c == 0 { String::new() } else { c.to_string() }
            );
        }
        let _ = writeln!(
            r,
            " {right}/{} | {} |",
            group.len(),
            if k == Kind::None {
                "-".to_string()
            } else {
                format!("{}/{}", falls.iter().filter(|f| **f).count(), falls.len())
            }
        );
    }
    let none: Vec<&(Case, LoopOutcome)> =
        rows.iter().filter(|(c, _)| c.kind == Kind::None).collect();
    // A false alarm names an effect; "unexplained" says something is missing without naming one.
    let false_alarm = none
        .iter()
        .filter(|(_, o)| !matches!(o.first(), "none" | "unexplained"))
        .count();
    let unexplained = rows
        .iter()
        .filter(|(c, o)| c.kind != Kind::None && o.first() == "unexplained")
        .count();
    let _ = writeln!(
        r,
        "\n- named right first: {right_all}/{total} ({:.0} %; target 95 %)",
        100.0 * right_all as f64 / total.max(1) as f64
    );
    let _ = writeln!(
        r,
        "- no effect named as an effect: {false_alarm}/{} (target at most 5 %)",
        none.len()
    );
    let _ = writeln!(
        r,
        "- a hidden effect called `unexplained` (the residual is above what the noise leaves and no effect in the catalogue lowers it): {unexplained}; called `none`: {}",
        rows.iter()
            .filter(|(c, o)| c.kind != Kind::None && o.first() == "none")
            .count()
    );
    let _ = writeln!(r, "\n### Misnamed cases\n");
    let _ = writeln!(r, "| case | family | hidden | validation | named (best first) | margin | error before | after | floor |");
    let _ = writeln!(r, "|---|---|---|---|---|---|---|---|---|");
    for (c, o) in rows.iter().filter(|(c, o)| !o.right(c.kind)) {
        let pct = |v: Option<f64>| v.map_or("-".into(), |x| format!("{:.3} %", 100.0 * x));
        let _ = writeln!(
            r,
            "| case-{:03} | {} | {} | {} | {} | {} | {} | {} | {} |",
            c.id,
            c.family.name(),
            c.kind.name(),
            c.val.name,
            o.failure.as_deref().map_or_else(
                || o.named
                    .iter()
                    .take(3)
                    .cloned()
                    .collect::<Vec<_>>()
                    .join(", "),
                |f| format!("FAILED {}", f.replace('|', "/"))
            ),
            o.margin.map_or("-".into(), |m| format!("{m:.2}")),
            pct(o.before),
            pct(o.after),
            pct(o.floor),
        );
    }
    r
}
