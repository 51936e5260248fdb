//! `unlag compare` and `unlag diagnose`: the modelling loop's view of a model against tests.

use std::path::PathBuf;

use clap::Args;
use serde_json::json;

use super::{json_err, name, pct, ColumnArgs};
use crate::effects::EffectKind;
use crate::error::Result;
use crate::evidence::TestEvidence;
use crate::file::ModelFile;
use crate::fit::Test;
use crate::modelling::diagnose::{self, AmplitudeSignature, Candidate, Remedy};
use crate::pipeline::{self, DiagnoseRequest, Diagnosis};
use crate::trace::Trace;

/// Arguments of `unlag compare` and `unlag diagnose`.
#[derive(Debug, Args)]
pub struct LoopArgs {
    /// The model file.
    #[arg(value_name = "MODEL.toml")]
    pub model: PathBuf,
    /// Step tests (CSV with the reference): the first is the estimation test (refitted on by
    /// `diagnose`'s trials), the others are held out.
    #[arg(required = true, value_name = "TEST.csv")]
    pub files: Vec<PathBuf>,
    /// Column names.
    #[command(flatten)]
    pub columns: ColumnArgs,
    /// Print one JSON object instead of tables.
    #[arg(long)]
    pub json: bool,
    /// Also write the HTML report (as `unlag report`).
    #[arg(long, value_name = "REPORT.html")]
    pub report: Option<PathBuf>,
    /// Replace an existing file at --report's path that is not an unlag report (a read-only
    /// file is never replaced).
    #[arg(long, requires = "report")]
    pub force: bool,
}

struct Loaded {
    file: ModelFile,
    traces: Vec<Trace>,
    names: Vec<String>,
}

fn load(args: &LoopArgs) -> Result<Loaded> {
    let file = ModelFile::load(&args.model)?;
    let columns = args.columns.columns(true);
    let traces = args
        .files
        .iter()
        .map(|f| super::read_test(f, &columns))
        .collect::<Result<Vec<_>>>()?;
    for t in &traces {
        super::check_rate(&file, t)?;
    }
    let names = traces.iter().map(|t| name(&t.path)).collect();
    Ok(Loaded {
        file,
        traces,
        names,
    })
}

fn tests(l: &Loaded) -> Result<Vec<Test<'_>>> {
    super::as_tests(&l.traces, &l.names)
}

fn print_evidence(evidence: &[TestEvidence]) {
    crate::outln!(
        "{:<28} {:<10} {:>8} {:>9} {:>9} {:>10} {:>12} {:>10}",
        "test",
        "role",
        "fit %",
        "nrmse",
        "floor",
        "x floor",
        "Ljung-Box p",
        "xcorr lag"
    );
    for e in evidence {
        crate::outln!(
            "{:<28} {:<10} {:>8.2} {:>9} {:>9} {:>10.2} {:>12.2e} {:>10}",
            e.file,
            e.role,
            e.fit_percent,
            pct(e.nrmse),
            pct(e.noise_floor),
            e.nrmse / e.noise_floor,
            e.autocorrelation.p_value,
            e.cross_correlation.peak_lag
        );
    }
    prediction_lines(evidence);
    for e in evidence {
        crate::outln!("{}:", e.file);
        let x = &e.expected;
        crate::outln!(
            "  a correct model leaves {:.4e} RMS (floor {}): probe noise {:.3e} and the reference's {:.3e} through the model, measured {}",
            x.std,
            pct(e.noise_floor),
            x.probe_std,
            x.reference_std,
            match x.source {
                crate::design::inverse::optimal::NoiseSource::PreStep => "before the step",
                crate::design::inverse::optimal::NoiseSource::HighFrequency =>
                    "from the record's highest frequencies (no quiet segment)",
                crate::design::inverse::optimal::NoiseSource::Given => "as given",
            }
        );
        crate::outln!(
            "  residual autocorrelation: {} of {} lags outside the 99 % band +-{:.3} around what that noise leaves (lag 1: {:.3}, expected {:.3}); Ljung-Box Q = {:.1}",
            e.autocorrelation.outside,
            e.autocorrelation.values.len(),
            e.autocorrelation.band,
            e.autocorrelation.values.first().copied().unwrap_or(0.0),
            e.autocorrelation.expected.first().copied().unwrap_or(0.0),
            e.autocorrelation.ljung_box
        );
        crate::outln!(
            "  against the input increments: peak {:+.3} at lag {} (band +-{:.3})",
            e.cross_correlation.peak,
            e.cross_correlation.peak_lag,
            e.cross_correlation.band
        );
        if e.spectrum.peaks.is_empty() {
            crate::outln!(
                "  residual spectrum after the step: no peak {} dB above the floor",
                crate::evidence::PEAK_DB
            );
        } else {
            let peaks: Vec<String> = e
                .spectrum
                .peaks
                .iter()
                .take(4)
                .map(|p| {
                    format!(
                        "{:.0} Hz (+{:.0} dB, Q {:.0})",
                        p.frequency_hz, p.above_floor_db, p.q
                    )
                })
                .collect();
            crate::outln!("  residual spectrum peaks: {}", peaks.join(", "));
        }
        if let Some(p) = e.reference_ringing {
            crate::outln!(
                "  the reference itself rings: {:.0} Hz (+{:.0} dB, Q {:.0}) in its increments",
                p.frequency_hz,
                p.above_floor_db,
                p.q
            );
        }
        let before = if e.trend.pre_mean.is_finite() {
            format!(
                "{:+.3e} before the step (+-{:.1e})",
                e.trend.pre_mean, e.trend.pre_mean_se
            )
        } else {
            "no quiet segment before a step".to_string()
        };
        crate::outln!(
            "  level: {before}, {:+.3e} at the end (+-{:.1e}); slope {:+.3e}/s; step {:+.4}",
            e.trend.late_mean,
            e.trend.late_mean_se,
            e.trend.slope_per_s,
            e.step_size
        );
    }
}

fn print_across(across: &[diagnose::PerTest], signature: Option<&AmplitudeSignature>) {
    if across.len() < 2 {
        return;
    }
    crate::outln!("across tests (the same structure fitted to each test alone):");
    let reference = across.first().and_then(|p| p.resonances.first().copied());
    for p in across {
        let modes: Vec<String> = p
            .resonances
            .iter()
            .map(|(f, z)| format!("{f:.1} Hz / {z:.3}"))
            .collect();
        let ratio = match (reference, p.resonances.first()) {
            (Some((f0, z0)), Some((f, z))) => {
                format!(
                    "  (fn x{:.3}, damping x{:.3} against the first test)",
                    f / f0,
                    z / z0
                )
            }
            _ => String::new(),
        };
        crate::outln!(
            "  {:<28} step {:>+10.4}  residual/|step| {:.2e} (own fit {:.2e})  {}{}",
            p.file,
            p.step_size,
            p.residual_per_step,
            p.own_residual_per_step,
            if modes.is_empty() {
                "no resonance".into()
            } else {
                modes.join(", ")
            },
            ratio
        );
    }
    if let Some(s) = signature {
        crate::outln!(
            "  residual against amplitude: damping {:+.3} per unit step ({:+.0} % from the smallest \
             step to the largest), own-fit residual ~ |step|^{:.2} (linear probe: 1){}",
            s.damping_slope,
            100.0 * s.damping_rise,
            s.residual_exponent,
            if s.nonlinear_damping() {
                ": amplitude-dependent losses"
            } else {
                ""
            }
        );
    }
}

fn print_history(file: &ModelFile) {
    if file.history.is_empty() {
        return;
    }
    crate::outln!("error history of this model file (mean nrmse over its tests):");
    for (i, h) in file.history.iter().enumerate() {
        let mean = h.tests.iter().map(|t| t.nrmse).sum::<f64>() / h.tests.len().max(1) as f64;
        let error = if h.effects.contains(&EffectKind::ColouredNoise) {
            " (one-step-ahead prediction error: the model has a noise model)"
        } else {
            ""
        };
        crate::outln!(
            "  {:>2}. order {:>2}, delay {:>3}, effects [{}]: {}{error}",
            i + 1,
            h.order,
            h.delay,
            h.effect_names(", "),
            pct(mean)
        );
    }
}

/// The candidates as `--json` writes them, each `change` the command that makes it (the
/// Python package reads its candidates from this too).
///
/// # Errors
/// [`crate::Error::Serialise`] if a candidate cannot be written as JSON.
pub fn candidates_json(candidates: &[Candidate]) -> Result<serde_json::Value> {
    let mut v = serde_json::to_value(candidates).map_err(json_err)?;
    if let Some(rows) = v.as_array_mut() {
        for (row, c) in rows.iter_mut().zip(candidates) {
            row["change"] = json!(c.change.command());
        }
    }
    Ok(v)
}

/// The residual evidence of each test as `--json` writes it.
///
/// # Errors
/// [`crate::Error::Serialise`] if the evidence cannot be written as JSON.
pub fn tests_json(evidence: &[TestEvidence]) -> Result<serde_json::Value> {
    serde_json::to_value(evidence).map_err(json_err)
}

/// `unlag compare`: the model against each test, and the residual evidence.
///
/// # Errors
/// The traces' and the model file's errors.
pub fn run_compare(args: &LoopArgs) -> Result<()> {
    let l = load(args)?;
    let tests = tests(&l)?;
    // With a report, the candidates it shows are ranked too (and told to the progress).
    let d = match &args.report {
        Some(path) => {
            let progress = super::report::Progress::start(args.json, super::report::REPORT_STAGES);
            let d = super::report::diagnosis(&l.file, &tests, true, &progress)?;
            super::report::write_report(path, &name(&args.model), &l.file, &tests, &d, &progress)?;
            d
        }
        None => pipeline::diagnose(&DiagnoseRequest {
            file: &l.file,
            tests: &tests,
            across: true,
            rank: false,
            on_stage: &|_| {},
        })?,
    };
    let (evidence, across, signature) = (&d.evidence, &d.across, &d.amplitude_signature);
    if args.json {
        let mut v = json!({
            "model": name(&args.model),
            "tests": tests_json(evidence)?,
            "across_tests": across,
            "amplitude_signature": signature,
            "history": l.file.history,
            "candidates": Vec::<Candidate>::new(),
        });
        if let Some(path) = &args.report {
            v["report"] = json!(name(path));
        }
        crate::outln!("{v}");
        return Ok(());
    }
    print_evidence(evidence);
    print_across(across, signature.as_ref());
    print_history(&l.file);
    crate::outln!("run `unlag diagnose` with the same arguments to rank the missing effects");
    if let Some(path) = &args.report {
        crate::outln!("wrote the report {}: open it in a browser", path.display());
    }
    Ok(())
}

/// The kinds of the effects a model file already carries (the fit's own readings, such as a
/// pre-step offset, and what `--add` put there), as `--add` names them.
fn carried(file: &ModelFile) -> Vec<String> {
    file.effects.iter().map(|e| e.kind().to_string()).collect()
}

/// `unlag diagnose`: candidates for the missing effect, best first.
///
/// # Errors
/// The traces' and the model file's errors.
pub fn run_diagnose(args: &LoopArgs) -> Result<()> {
    let l = load(args)?;
    let tests = tests(&l)?;
    let Diagnosis {
        evidence,
        candidates,
        ..
    } = pipeline::diagnose(&DiagnoseRequest {
        file: &l.file,
        tests: &tests,
        across: false,
        rank: true,
        on_stage: &|_| {},
    })?;
    if let Some(path) = &args.report {
        crate::report::write(
            path,
            &crate::report::Inputs {
                model_name: &name(&args.model),
                file: &l.file,
                tests: &tests,
                evidence: &evidence,
                candidates: &candidates,
                change_text: Remedy::command,
            },
        )?;
    }
    if args.json {
        let v = json!({
            "model": name(&args.model),
            "carried": carried(&l.file),
            "tests": tests_json(&evidence)?,
            "candidates": candidates_json(&candidates)?,
        });
        crate::outln!("{v}");
        return Ok(());
    }
    crate::outln!(
        "{:<28} {:>8} {:>9} {:>9}",
        "test",
        "fit %",
        "nrmse",
        "floor"
    );
    for e in &evidence {
        crate::outln!(
            "{:<28} {:>8.2} {:>9} {:>9}",
            e.file,
            e.fit_percent,
            pct(e.nrmse),
            pct(e.noise_floor)
        );
    }
    prediction_lines(&evidence);
    let carried = carried(&l.file);
    if !carried.is_empty() {
        crate::outln!(
            "the model already carries: {} (in the model file, from the fit or an --add; not a candidate)",
            carried.join(", ")
        );
    }
    crate::outln!(
        "candidates, best first (score = ln of the held-out error's fall in a trial refit, less BIC's charge per parameter):"
    );
    for (i, c) in candidates.iter().enumerate() {
        crate::outln!(
            "{:>2}. {:<15} score {:.2}: {}",
            i + 1,
            c.kind,
            c.score,
            c.error_change()
        );
        crate::outln!("    {}", c.reading);
        if let Some(text) = c.uncertainty_text() {
            crate::outln!("    {text}");
        }
        crate::outln!("    change: {}", c.change.command());
        if let Some(test) = &c.separated_by {
            let rule = c
                .ordered_by
                .or_else(|| candidates.get(i + 1).and_then(|n| n.ordered_by));
            // A temperature and a loss both fitted on all the tests: the margin is on that
            // footing.
            let one_footing = candidates
                .get(i + 1)
                .is_some_and(|n| diagnose::on_one_footing(c, n).is_some());
            match rule {
                _ if one_footing => crate::outln!(
                    "    close to the next (fitted on all the tests, it leaves {:.2}x less over \
                     them): to tell them apart, {test}",
                    c.margin.exp()
                ),
                Some(rule) if c.margin < 0.0 => crate::outln!(
                    "    ahead of the next though it scores {:.2} less, since {rule}: to tell them \
                     apart, {test}",
                    -c.margin
                ),
                _ => crate::outln!(
                    "    close to the next ({:.2} in score): to tell them apart, {test}",
                    c.margin
                ),
            }
        }
    }
    if let Some(path) = &args.report {
        crate::outln!("wrote the report {}: open it in a browser", path.display());
    }
    Ok(())
}

/// With a noise model: each test's one-step-ahead prediction error, the error the model is
/// judged by, against that error's floor.
fn prediction_lines(evidence: &[crate::evidence::TestEvidence]) {
    for e in evidence {
        if let Some(p) = &e.prediction {
            crate::outln!(
                "{:<28} one-step-ahead prediction error {} against its floor {} ({})",
                e.file,
                pct(p.nrmse),
                pct(p.floor.value),
                p.floor.origin()
            );
        }
    }
}
