//! `unlag report` and the `--report FILE` of `unlag fit` and `unlag compare`: the HTML report
//! written from a model file and its tests, and the progress indication of long commands.
//! The page itself is [`crate::report`]'s.

use std::io::IsTerminal as _;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

use clap::Args;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use serde_json::json;

use super::{name, ColumnArgs};
use crate::error::{Error, Result};
use crate::file::ModelFile;
use crate::fit::Test;
use crate::modelling::diagnose::Remedy;
use crate::pipeline::{self, DiagnoseRequest, DiagnoseStage, Diagnosis};
use crate::report::{self, Inputs};

/// Arguments of `unlag report`.
#[derive(Debug, Args)]
pub struct ReportArgs {
    /// The model file.
    #[arg(value_name = "MODEL.toml")]
    pub model: PathBuf,
    /// Step tests (CSV with the reference): the first is the estimation test, the others are
    /// held out (as for `unlag compare`).
    #[arg(required = true, value_name = "TEST.csv")]
    pub files: Vec<PathBuf>,
    /// Where to write the report (one self-contained HTML file).
    #[arg(short = 'o', long = "output", value_name = "REPORT.html")]
    pub output: PathBuf,
    /// Replace an existing file at the output's path that is not an output of this command
    /// (a read-only file is never replaced).
    #[arg(long)]
    pub force: bool,
    /// Column names.
    #[command(flatten)]
    pub columns: ColumnArgs,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
}

/// Seconds between two progress lines when stdout is not a terminal.
const PROGRESS_LINE_SECONDS: u64 = 5;

/// Progress on stderr for work that may take more than a second, in a known number of
/// stages: on a terminal a bar of the stages done, the current one and the time taken, shown
/// after a second; off a terminal (a log, a pipe) one line every few seconds, the first after
/// that many. Never under `--json`.
pub(crate) struct Progress {
    bar: Option<ProgressBar>,
    done: Arc<AtomicBool>,
    message: Arc<std::sync::Mutex<String>>,
    stage: std::cell::Cell<u64>,
    stages: u64,
}

impl Progress {
    /// Starts the (hidden) bar, or the line printer, for `stages` stages; each begins with
    /// [`Progress::step`].
    pub(crate) fn start(json: bool, stages: u64) -> Self {
        let mut progress = Self {
            bar: None,
            done: Arc::new(AtomicBool::new(false)),
            message: Arc::new(std::sync::Mutex::new(String::new())),
            stage: std::cell::Cell::new(0),
            stages,
        };
        if json {
            return progress;
        }
        if !std::io::stdout().is_terminal() {
            let (flag, shown) = (Arc::clone(&progress.done), Arc::clone(&progress.message));
            std::thread::spawn(move || {
                let start = std::time::Instant::now();
                let mut next = PROGRESS_LINE_SECONDS;
                while !flag.load(Ordering::SeqCst) {
                    std::thread::sleep(Duration::from_millis(100));
                    let elapsed = start.elapsed().as_secs();
                    if elapsed >= next && !flag.load(Ordering::SeqCst) {
                        let now = shown.lock().map(|m| m.clone()).unwrap_or_default();
                        crate::errln!("unlag: {now} ({elapsed} s)");
                        next = elapsed + PROGRESS_LINE_SECONDS;
                    }
                }
            });
            return progress;
        }
        let bar = ProgressBar::with_draw_target(Some(stages), ProgressDrawTarget::hidden());
        if let Ok(style) = ProgressStyle::with_template("{bar:16} {msg} ({elapsed})") {
            bar.set_style(style);
        }
        let (shown, flag) = (bar.clone(), Arc::clone(&progress.done));
        std::thread::spawn(move || {
            std::thread::sleep(Duration::from_secs(1));
            if !flag.load(Ordering::SeqCst) {
                shown.set_draw_target(ProgressDrawTarget::stderr());
                shown.enable_steady_tick(Duration::from_millis(120));
            }
        });
        progress.bar = Some(bar);
        progress
    }

    /// The next stage begins: `[stage/stages] message`, the stages before it done.
    pub(crate) fn step(&self, message: &str) {
        let stage = (self.stage.get() + 1).min(self.stages.max(1));
        self.stage.set(stage);
        let text = format!("[{stage}/{}] {message}", self.stages.max(stage));
        if let Some(b) = &self.bar {
            b.set_position(stage - 1);
            b.set_message(text.clone());
        }
        if let Ok(mut m) = self.message.lock() {
            *m = text;
        }
    }

    /// Removes the bar (also on drop).
    pub(crate) fn finish(&self) {
        self.done.store(true, Ordering::SeqCst);
        if let Some(b) = &self.bar {
            b.finish_and_clear();
        }
    }
}

impl Drop for Progress {
    fn drop(&mut self) {
        self.finish();
    }
}

/// The stages [`diagnosis`] and [`write_report`] report to their [`Progress`].
pub(crate) const REPORT_STAGES: u64 = 3;

/// The diagnosis of `file` on `tests` that the report draws ([`pipeline::diagnose`], the
/// candidates ranked), each stage told to `progress`; `across` also fits each test alone
/// (for `unlag compare`).
///
/// # Errors
/// [`Error::InvalidArgument`] without a test; the diagnosis' errors.
pub(crate) fn diagnosis(
    file: &ModelFile,
    tests: &[Test<'_>],
    across: bool,
    progress: &Progress,
) -> Result<Diagnosis> {
    if tests.is_empty() {
        return Err(Error::InvalidArgument {
            what: "TEST.csv",
            message: "give at least one step test for the report".into(),
        });
    }
    pipeline::diagnose(&DiagnoseRequest {
        file,
        tests,
        across,
        rank: true,
        on_stage: &|stage| {
            progress.step(match stage {
                DiagnoseStage::Candidates => "report: diagnosing (trial refits)",
                _ => "report: measuring the residuals",
            });
        },
    })
}

/// Writes the report of `file`, its `tests` and their `diagnosis` to `output`; returns the
/// report's size in bytes.
///
/// # Errors
/// The report's errors.
pub(crate) fn write_report(
    output: &Path,
    model_name: &str,
    file: &ModelFile,
    tests: &[Test<'_>],
    diagnosis: &Diagnosis,
    progress: &Progress,
) -> Result<usize> {
    progress.step("report: drawing");
    report::write(
        output,
        &Inputs {
            model_name,
            file,
            tests,
            evidence: &diagnosis.evidence,
            candidates: &diagnosis.candidates,
            change_text: Remedy::command,
        },
    )
}

/// `unlag report`.
///
/// # Errors
/// The traces', the model file's and the report's errors.
pub fn run_report(args: &ReportArgs) -> Result<()> {
    let file = ModelFile::load(&args.model)?;
    let columns = args.columns.columns(true);
    let progress = Progress::start(args.json, 1 + REPORT_STAGES);
    progress.step("reading the tests");
    let traces = args
        .files
        .iter()
        .map(|f| super::read_test(f, &columns))
        .collect::<Result<Vec<_>>>()?;
    for t in &traces {
        super::check_rate(&file, t)?;
    }
    let names: Vec<String> = traces.iter().map(|t| name(&t.path)).collect();
    let tests = super::as_tests(&traces, &names)?;
    let diagnosis = diagnosis(&file, &tests, false, &progress)?;
    let bytes = write_report(
        &args.output,
        &name(&args.model),
        &file,
        &tests,
        &diagnosis,
        &progress,
    )?;
    progress.finish();
    if args.json {
        crate::outln!(
            "{}",
            json!({"output": name(&args.output), "bytes": bytes, "tests": names})
        );
    } else {
        crate::outln!(
            "wrote the report {} ({:.0} kB): open it in a browser",
            args.output.display(),
            bytes as f64 / 1e3
        );
    }
    Ok(())
}
