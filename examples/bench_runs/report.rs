//! The bench's results: Markdown tables per run kind, per probe family and overall of the
//! board's two arithmetics against the raw probe and the host's best, judged on the true
//! pressure and on the recorded reference; the targets; each probe's ratios; the runs that
//! miss a target; and `results.csv`, one row per run.

use std::error::Error;
use std::fmt::Write as _;
use std::path::Path;

use super::execute::{Column, Output, ProbeResult, RunResult, COLUMNS};
use super::probe::FAMILIES;
use super::runs::RUN_KINDS;

/// A raw/output ratio below this is worse than the raw probe (a compensator that passes the
/// probe through ties with it to rounding).
const WORSE: f64 = 1.0 - 1e-6;
/// A raw/output ratio that is worse than the raw probe (a NaN is).
fn is_worse(ratio: f64) -> bool {
    ratio.is_nan() || ratio < WORSE
}

/// A board output is close to the host's when its error is at most this times the host's
/// best.
const WITHIN: f64 = 1.5;
/// The median ratio a board must reach.
const TARGET_MEDIAN: f64 = 2.5;

/// What the errors are measured against.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Against {
    /// The run's true pressure.
    Truth,
    /// The run's recorded (noisy, quantised) reference.
    Recorded,
}

impl Against {
    fn raw(self, r: &RunResult) -> f64 {
        match self {
            Self::Truth => r.raw.0,
            Self::Recorded => r.raw.1,
        }
    }

    fn output(self, o: &Output) -> f64 {
        match self {
            Self::Truth => o.error,
            Self::Recorded => o.error_recorded,
        }
    }
}

/// The least error of the host's columns that ran (f64, offline, adapt-to-run).
fn host_best(r: &RunResult, a: Against) -> Option<f64> {
    COLUMNS
        .iter()
        .filter(|c| !c.is_board())
        .filter_map(|&c| r.output(c).map(|o| a.output(o)))
        .filter(|e| e.is_finite())
        .min_by(f64::total_cmp)
}

/// Median of `v`, `None` if empty.
fn median(mut v: Vec<f64>) -> Option<f64> {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    (n > 0).then(|| 0.5 * (v[(n - 1) / 2] + v[n / 2]))
}

/// A board column's figures over some runs.
#[derive(Debug, Default)]
struct Board {
    /// raw / output, one per run it ran on.
    ratios: Vec<f64>,
    /// Runs worse than raw.
    worse: usize,
    /// Runs with clamped samples.
    clamped: usize,
    /// Runs where the CLI ran another compensator than the stored one.
    fell_back: usize,
    /// Runs within [`WITHIN`] of the host's best, and runs with a host's best to judge by.
    within: (usize, usize),
    /// Runs it did not run on.
    failed: usize,
}

fn board(rows: &[&RunResult], c: Column, a: Against) -> Board {
    let mut b = Board::default();
    for r in rows {
        let Some(o) = r.output(c) else {
            b.failed += 1;
            continue;
        };
        let ratio = a.raw(r) / a.output(o);
        b.ratios.push(ratio);
        b.worse += usize::from(is_worse(ratio));
        b.clamped += usize::from(o.clamped > 0);
        b.fell_back += usize::from(o.fell_back.is_some());
        if let Some(h) = host_best(r, a) {
            b.within.1 += 1;
            b.within.0 += usize::from(a.output(o) <= WITHIN * h);
        }
    }
    b
}

fn ratio_text(v: Option<f64>) -> String {
    v.map_or("-".into(), |x| format!("{x:.2}"))
}

/// One row of a summary table.
fn row(name: &str, rows: &[&RunResult], a: Against, pair: Pair) -> String {
    let f = board(rows, pair[0], a);
    let x = board(rows, pair[1], a);
    let host: Vec<f64> = rows
        .iter()
        .filter_map(|r| host_best(r, a).map(|h| a.raw(r) / h))
        .collect();
    let worst = |b: &Board| ratio_text(b.ratios.iter().copied().min_by(f64::total_cmp));
    format!(
        "| {name} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {}/{} | {}/{} | {}/{} | {}/{} |\n",
        rows.len(),
        ratio_text(median(f.ratios.clone())),
        worst(&f),
        f.worse,
        f.clamped,
        ratio_text(median(x.ratios.clone())),
        worst(&x),
        x.worse,
        x.clamped,
        ratio_text(median(host)),
        f.within.0,
        f.within.1,
        x.within.0,
        x.within.1,
        f.fell_back,
        x.fell_back,
        f.failed,
        x.failed,
    )
}

const HEADER: &str = "| | runs | f32 median | f32 worst | f32 worse than raw | f32 clamped | \
fixed median | fixed worst | fixed worse than raw | fixed clamped | host best median | \
f32 within 1.5x host | fixed within 1.5x host | CLI fell back f32/fixed | no output f32/fixed |\n\
|---|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|\n";

/// A board's two arithmetics running one compensator: `[f32, fixed]`.
pub type Pair = [Column; 2];

/// The compensator fitted on the step test alone.
pub const STEP_TEST: Pair = [Column::BoardF32, Column::BoardFixed];
/// The compensator fitted on the step test with `--signal` a rehearsal of the run's kind.
pub const FOR_RUNS: Pair = [Column::RunsF32, Column::RunsFixed];

/// The summary tables (per run kind, per probe family) against `a`.
fn tables(r: &mut String, results: &[ProbeResult], a: Against, pair: Pair) {
    let all: Vec<&RunResult> = results.iter().flat_map(|p| &p.runs).collect();
    let _ = writeln!(r, "\nBy run kind:\n\n{HEADER}");
    r.pop();
    for kind in RUN_KINDS {
        let rows: Vec<&RunResult> = all.iter().copied().filter(|x| x.kind == kind).collect();
        r.push_str(&row(kind.name(), &rows, a, pair));
    }
    r.push_str(&row("**all**", &all, a, pair));
    let _ = writeln!(r, "\nBy probe family:\n\n{HEADER}");
    r.pop();
    for family in FAMILIES {
        let rows: Vec<&RunResult> = results
            .iter()
            .filter(|p| p.probe.family == family)
            .flat_map(|p| &p.runs)
            .collect();
        r.push_str(&row(family.name(), &rows, a, pair));
    }
    r.push_str(&row("**all**", &all, a, pair));
}

/// The three targets for one board column, over every run.
fn targets(r: &mut String, results: &[ProbeResult], c: Column) {
    let all: Vec<&RunResult> = results.iter().flat_map(|p| &p.runs).collect();
    let b = board(&all, c, Against::Truth);
    let verdict = |ok: bool| if ok { "met" } else { "MISSED" };
    let m = median(b.ratios.clone());
    let _ = writeln!(
        r,
        "- board {}: never worse than raw: {} ({} of {} runs worse, {} without output); \
         median at least {TARGET_MEDIAN}x: {} ({}); within {WITHIN}x of the host's best: {} ({} of {} runs)",
        c.name(),
        verdict(b.worse == 0 && b.failed == 0),
        b.worse,
        b.ratios.len(),
        b.failed,
        verdict(m.is_some_and(|m| m >= TARGET_MEDIAN)),
        ratio_text(m),
        verdict(b.within.0 == b.within.1 && b.within.1 > 0),
        b.within.0,
        b.within.1,
    );
}

/// A ratio of `c` on `r` against the truth, or `-`.
fn cell(r: &RunResult, c: Column) -> String {
    ratio_text(r.output(c).map(|o| r.raw.0 / o.error))
}

/// The host's best ratio on `r` against the truth, or `-`.
fn host_cell(r: &RunResult) -> String {
    ratio_text(host_best(r, Against::Truth).map(|h| r.raw.0 / h))
}

/// Each probe: its model and, per run kind, f32 / fixed / host best ratios.
fn probes_table(r: &mut String, results: &[ProbeResult], pair: Pair) {
    r.push_str(
        "\nEach probe (ratios against the true pressure, f32 / fixed / host best):\n\n\
         | probe | family | gen | f_n Hz | damping | fs Hz | model | design | full scale / step |",
    );
    for kind in RUN_KINDS {
        let _ = write!(r, " {} |", kind.name());
    }
    r.push_str("\n|---|---|---|--:|--:|--:|---|---|--:|");
    r.push_str(&"--:|".repeat(RUN_KINDS.len()));
    r.push('\n');
    for p in results {
        let pr = &p.probe;
        let (model, design, fs) = match &p.model {
            Some(m) => (
                format!("order {}, delay {}", m.order, m.delay),
                format!("{}, latency {:.0}", m.method, m.latency),
                m.full_scale
                    .map_or("-".into(), |f| format!("{:.1}", f / pr.step_pa)),
            ),
            None => (
                p.failure.clone().unwrap_or_else(|| "?".into()),
                "-".into(),
                "-".into(),
            ),
        };
        let _ = write!(
            r,
            "| {:03} | {} | {} | {:.4e} | {:.3} | {:.0} | {model} | {design} | {fs} |",
            pr.id,
            pr.family.name(),
            pr.generator(),
            pr.f_hz,
            pr.zeta,
            pr.fs
        );
        for kind in RUN_KINDS {
            match p.runs.iter().find(|x| x.kind == kind) {
                Some(x) => {
                    let _ = write!(
                        r,
                        " {} / {} / {} |",
                        cell(x, pair[0]),
                        cell(x, pair[1]),
                        host_cell(x)
                    );
                }
                None => r.push_str(" - |"),
            }
        }
        r.push('\n');
    }
}

/// The runs where a board output is worse than raw or beyond [`WITHIN`] of the host's best.
fn misses(r: &mut String, results: &[ProbeResult], pair: Pair) {
    let mut rows: Vec<(f64, String)> = Vec::new();
    for p in results {
        for x in &p.runs {
            let host = host_best(x, Against::Truth);
            let mut why = Vec::new();
            let mut least = f64::INFINITY;
            for c in pair {
                let Some(o) = x.output(c) else {
                    why.push(format!("{}: no output", c.name()));
                    continue;
                };
                let ratio = x.raw.0 / o.error;
                least = least.min(ratio);
                let mut notes = Vec::new();
                if is_worse(ratio) {
                    notes.push("worse than raw".to_string());
                }
                if host.is_some_and(|h| o.error > WITHIN * h) {
                    notes.push(format!(
                        "{:.1}x the host's error",
                        o.error / host.unwrap_or(1.0)
                    ));
                }
                if o.clamped > 0 {
                    notes.push(format!("{} clamped", o.clamped));
                }
                if let Some(f) = &o.fell_back {
                    let cli = o
                        .cli_error
                        .map_or(String::new(), |e| format!(" ({:.2})", x.raw.0 / e));
                    notes.push(format!("the CLI ran {f}{cli}"));
                }
                if !notes.is_empty() {
                    why.push(format!("{} {:.2}: {}", c.name(), ratio, notes.join(", ")));
                }
            }
            if !why.is_empty() {
                rows.push((
                    least,
                    format!(
                        "| {:03} {} {} | {} | {} | {} | {} |\n",
                        p.probe.id,
                        p.probe.family.name(),
                        p.probe.generator(),
                        x.kind.name(),
                        host_cell(x),
                        why.join("; "),
                        x.text
                    ),
                ));
            }
        }
    }
    rows.sort_by(|a, b| a.0.total_cmp(&b.0));
    let _ = writeln!(
        r,
        "\nRuns where a board output misses a target ({}; worst first):\n\n\
         | probe | run | host best | board | run's parameters |\n|---|---|--:|---|---|",
        rows.len()
    );
    for (_, line) in rows {
        r.push_str(&line);
    }
}

/// The printed report.
pub fn report(results: &[ProbeResult], adapt: bool, seconds: f64) -> String {
    let mut r = String::new();
    let runs: usize = results.iter().map(|p| p.runs.len()).sum();
    let _ = writeln!(
        r,
        "\n{} probes, {runs} runs, {:.0} s. Ratio = raw probe's RMS error / output's (higher is \
         better, below 1 worse than raw), each at its best whole-sample lag, after the first \
         tenth of the run. Board f32 and fixed: `unlag compensate --arithmetic f32|fixed`; where \
         the CLI ran another compensator than the stored one (its run fall-back, host only: \
         \"CLI fell back\"), the stored one run through the library as the board runs it. \
         Host best: the least error of f64, offline{}.",
        results.len(),
        seconds,
        if adapt {
            " and adapt-to-run"
        } else {
            " (the binary has no --adapt-to-run: that column is skipped)"
        }
    );
    for p in results.iter().filter(|p| p.failure.is_some()) {
        let _ = writeln!(
            r,
            "- probe {:03} ({}): {}",
            p.probe.id,
            p.probe.family.name(),
            p.failure.as_deref().unwrap_or("")
        );
    }
    r.push_str("\nTargets (against the true pressure, every run):\n\n");
    for pair in [STEP_TEST, FOR_RUNS] {
        for c in pair {
            targets(&mut r, results, c);
        }
    }
    for (pair, title) in [
        (
            STEP_TEST,
            "fitted on the step test alone (`unlag fit step-test.csv`)",
        ),
        (
            FOR_RUNS,
            "fitted on the step test for the runs (`unlag fit step-test.csv --signal REHEARSAL.csv`, \
             a run of the same kind drawn anew, the probe alone)",
        ),
    ] {
        let _ = writeln!(r, "\n## The board's compensator {title}");
        r.push_str("\n### Against the true pressure\n");
        tables(&mut r, results, Against::Truth, pair);
        r.push_str("\n### Against the recorded reference (noise and ADC included)\n");
        tables(&mut r, results, Against::Recorded, pair);
        probes_table(&mut r, results, pair);
        misses(&mut r, results, pair);
    }
    r
}

fn number(v: f64) -> String {
    if v.is_finite() {
        format!("{v:.6e}")
    } else {
        String::new()
    }
}

/// Writes `results.csv`: one row per run with the probe's parameters and every error.
pub fn write_csv(path: &Path, results: &[ProbeResult]) -> Result<(), Box<dyn Error>> {
    let mut w = csv::Writer::from_path(path)?;
    let mut head: Vec<String> = [
        "probe",
        "family",
        "generator",
        "probe_text",
        "fs",
        "f_hz",
        "zeta",
        "band_hz",
        "lag_s",
        "slowest_s",
        "step_pa",
        "noise_u",
        "noise_y",
        "model_order",
        "model_delay",
        "design",
        "design_latency",
        "design_band_hz",
        "full_scale",
        "step_adc_min",
        "step_adc_max",
        "run",
        "run_text",
        "n",
        "adc_min",
        "adc_max",
        "adc_clipped",
        "raw_err",
        "raw_err_recorded",
        "raw_lag",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    for c in COLUMNS {
        for what in [
            "err",
            "err_recorded",
            "ratio",
            "lag",
            "latency",
            "clamped",
            "overflowed",
            "fell_back",
            "cli_err",
            "compensator",
            "cli_nrmse",
            "failure",
        ] {
            head.push(format!("{}_{what}", c.name()));
        }
    }
    head.extend([
        "host_best_err".into(),
        "host_best_ratio".into(),
        "probe_failure".into(),
    ]);
    w.write_record(&head)?;
    for p in results {
        let pr = &p.probe;
        let m = p.model.clone().unwrap_or_default();
        let probe_fields = vec![
            pr.id.to_string(),
            pr.family.name().into(),
            pr.generator().into(),
            pr.text.clone(),
            number(pr.fs),
            number(pr.f_hz),
            number(pr.zeta),
            number(pr.band_hz),
            number(pr.lag_s),
            number(pr.slowest_s),
            number(pr.step_pa),
            number(pr.noise_u),
            number(pr.noise_y),
            p.model
                .as_ref()
                .map_or(String::new(), |_| m.order.to_string()),
            p.model
                .as_ref()
                .map_or(String::new(), |_| m.delay.to_string()),
            m.method.clone(),
            number(m.latency),
            number(m.bandwidth_hz),
            m.full_scale.map_or(String::new(), number),
            number(p.step_adc.0),
            number(p.step_adc.1),
        ];
        if p.runs.is_empty() {
            let mut rec = probe_fields.clone();
            rec.resize(head.len() - 1, String::new());
            rec.push(p.failure.clone().unwrap_or_default());
            w.write_record(&rec)?;
        }
        for x in &p.runs {
            let mut rec = probe_fields.clone();
            rec.extend([
                x.kind.name().into(),
                x.text.clone(),
                x.n.to_string(),
                number(x.adc.0),
                number(x.adc.1),
                x.adc_clipped.to_string(),
                number(x.raw.0),
                number(x.raw.1),
                x.raw.2.to_string(),
            ]);
            for (_, o) in &x.outputs {
                match o {
                    Ok(o) => rec.extend([
                        number(o.error),
                        number(o.error_recorded),
                        number(x.raw.0 / o.error),
                        o.lag.to_string(),
                        number(o.latency),
                        o.clamped.to_string(),
                        o.overflowed.to_string(),
                        o.fell_back.clone().unwrap_or_default(),
                        o.cli_error.map_or(String::new(), number),
                        o.compensator.clone(),
                        o.cli.0.map_or(String::new(), number),
                        String::new(),
                    ]),
                    Err(e) => {
                        rec.extend(std::iter::repeat_n(String::new(), 11));
                        rec.push(e.clone());
                    }
                }
            }
            let host = host_best(x, Against::Truth);
            rec.push(host.map_or(String::new(), number));
            rec.push(host.map_or(String::new(), |h| number(x.raw.0 / h)));
            rec.push(String::new());
            w.write_record(&rec)?;
        }
    }
    w.flush()?;
    Ok(())
}
