//! One probe through the `unlag` binary: its step test and runs written, `unlag fit` with
//! default options on the step test alone, then `unlag compensate` on every run in each
//! column (the board's two arithmetics, the host's candidates), each output scored against
//! the run's true pressure and its recorded reference.

use std::path::Path;
use std::time::Instant;

use super::draw::Rng;
use super::probe::Probe;
use super::runner::unlag;
use super::runs::{self, Recorded, RunKind};
use super::score::{aligned_rms, output_lags, raw_lags, settling};
use super::simulate::write_csv;
use super::Settings;

/// Who runs a compensator, and in what.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Column {
    /// The stored compensator in f32, as a board with an FPU runs it.
    BoardF32,
    /// The stored compensator in 32-bit fixed point, as a board without one runs it.
    BoardFixed,
    /// The stored compensator in f64 (host).
    HostF64,
    /// The non-causal optimum on the whole run (host only).
    HostOffline,
    /// A design chosen for the run (host only; `--adapt-to-run`, where the binary has it).
    HostAdapt,
    /// In f32 on the board, the compensator fitted on the same step test with `--signal` a
    /// rehearsal: another run of the same kind drawn anew (its own parameters and noise),
    /// recorded by the probe alone (no reference column).
    RunsF32,
    /// The same in fixed point.
    RunsFixed,
}

/// Every column, in report order.
pub const COLUMNS: [Column; 7] = [
    Column::BoardF32,
    Column::BoardFixed,
    Column::HostF64,
    Column::HostOffline,
    Column::HostAdapt,
    Column::RunsF32,
    Column::RunsFixed,
];

impl Column {
    /// Name in the report, the CSV and the file names.
    pub fn name(self) -> &'static str {
        match self {
            Self::BoardF32 => "f32",
            Self::BoardFixed => "fixed",
            Self::HostF64 => "f64",
            Self::HostOffline => "offline",
            Self::HostAdapt => "adapt",
            Self::RunsF32 => "runs-f32",
            Self::RunsFixed => "runs-fixed",
        }
    }

    /// Its arguments to `unlag compensate`.
    fn args(self) -> &'static [&'static str] {
        match self {
            Self::BoardF32 => &["--arithmetic", "f32"],
            Self::BoardFixed => &["--arithmetic", "fixed"],
            Self::HostF64 => &["--arithmetic", "f64"],
            Self::HostOffline => &["--offline"],
            Self::HostAdapt => &["--adapt-to-run"],
            Self::RunsF32 => &["--arithmetic", "f32"],
            Self::RunsFixed => &["--arithmetic", "fixed"],
        }
    }

    /// A board runs it.
    pub fn is_board(self) -> bool {
        matches!(
            self,
            Self::BoardF32 | Self::BoardFixed | Self::RunsF32 | Self::RunsFixed
        )
    }

    /// Its compensator was designed with a rehearsal run of the kind it runs on.
    pub fn is_for_runs(self) -> bool {
        matches!(self, Self::RunsF32 | Self::RunsFixed)
    }

    /// The model file it runs, in the probe's directory.
    fn model(self, kind: RunKind) -> String {
        if self.is_for_runs() {
            format!("model-{}.toml", kind.name())
        } else {
            "model.toml".into()
        }
    }
}

/// One column's output on one run.
#[derive(Debug, Clone, Default)]
pub struct Output {
    /// RMS error against the true pressure [Pa] at its best lag.
    pub error: f64,
    /// ... against the recorded reference.
    pub error_recorded: f64,
    /// Its best lag against the true pressure [samples].
    pub lag: usize,
    /// The latency it states (`latency_samples`).
    pub latency: f64,
    /// Probe samples clamped to the fixed-point full scale (the JSON's `clamped_inputs`
    /// where it has one, else the warning on stderr; 0 when neither says any).
    pub clamped: usize,
    /// The fixed-point compensator saturated (its warning).
    pub overflowed: bool,
    /// What the CLI ran instead of the stored compensator (the JSON's `run_fall_back.what`,
    /// host only). A board column then scores the stored compensator as the board runs it,
    /// through the library ([`replay`]), and keeps the CLI's error in `cli_error`.
    pub fell_back: Option<String>,
    /// The CLI's output's error against the true pressure where it is not the one scored.
    pub cli_error: Option<f64>,
    /// The compensator in the CLI's words.
    pub compensator: String,
    /// The CLI's own `(nrmse_u_hat, nrmse_raw)` against the recorded reference.
    pub cli: (Option<f64>, Option<f64>),
}

/// One run of a probe with every column's output.
#[derive(Debug, Clone)]
pub struct RunResult {
    /// Kind.
    pub kind: RunKind,
    /// Parameters in words.
    pub text: String,
    /// Samples.
    pub n: usize,
    /// ADC range `(min, max)` [Pa].
    pub adc: (f64, f64),
    /// Samples at the ADC's rails.
    pub adc_clipped: usize,
    /// The raw probe's RMS error against the true pressure and the recorded reference, at
    /// its best lag (the first's lag).
    pub raw: (f64, f64, usize),
    /// Each column: its output, or why there is none.
    pub outputs: Vec<(Column, Result<Output, String>)>,
}

impl RunResult {
    /// `column`'s output, if it ran.
    pub fn output(&self, column: Column) -> Option<&Output> {
        self.outputs
            .iter()
            .find(|(c, _)| *c == column)
            .and_then(|(_, o)| o.as_ref().ok())
    }
}

/// What the fitted model file holds (read with the library).
#[derive(Debug, Clone, Default)]
pub struct ModelInfo {
    /// Order and delay.
    pub order: usize,
    /// Delay [samples].
    pub delay: usize,
    /// Its compensator's method, short.
    pub method: String,
    /// Its latency [samples].
    pub latency: f64,
    /// Its corrected band [Hz].
    pub bandwidth_hz: f64,
    /// The fixed-point plan's full scale, if it has one.
    pub full_scale: Option<f64>,
}

/// One probe's results.
#[derive(Debug, Clone)]
pub struct ProbeResult {
    /// The probe.
    pub probe: Probe,
    /// The step test's ADC range `(min, max)` [Pa].
    pub step_adc: (f64, f64),
    /// The fitted model, when `fit` succeeded and the file reads.
    pub model: Option<ModelInfo>,
    /// Why the probe has no runs scored (a simulation or `fit` failed).
    pub failure: Option<String>,
    /// Its runs.
    pub runs: Vec<RunResult>,
    /// Wall time [s].
    pub seconds: f64,
}

/// The model file's figures.
fn model_info(file: &unlag::file::ModelFile) -> ModelInfo {
    let d = file.inverse.as_ref();
    ModelInfo {
        order: file.model.a.len(),
        delay: file.model.delay,
        method: d.map_or("direct inverse".into(), |d| d.method.short().to_string()),
        latency: d.map_or(file.model.delay as f64, |d| d.latency_samples),
        bandwidth_hz: d.map_or(f64::NAN, |d| d.corrected_bandwidth_hz),
        full_scale: d.and_then(|d| {
            d.fixed_direct
                .as_ref()
                .map(|p| p.full_scale)
                .or_else(|| d.fixed.as_ref().map(|p| p.full_scale))
        }),
    }
}

/// The first key `key` anywhere in `v`, as a whole number.
fn find_count(v: &serde_json::Value, key: &str) -> Option<u64> {
    match v {
        serde_json::Value::Object(m) => m
            .get(key)
            .and_then(serde_json::Value::as_u64)
            .or_else(|| m.values().find_map(|x| find_count(x, key))),
        serde_json::Value::Array(a) => a.iter().find_map(|x| find_count(x, key)),
        _ => None,
    }
}

/// Clamped samples in the stderr of a `compensate` log (its warning's first number).
fn clamped_in_log(log: &str) -> Option<usize> {
    let line = log.lines().find(|l| l.contains("were clamped"))?;
    line.trim_start_matches("warning:")
        .split_whitespace()
        .next()?
        .parse()
        .ok()
}

/// `u_hat`'s errors against the true pressure and the recorded reference, in the window
/// around `latency`: `(error, error_recorded, lag)`.
fn score(u_hat: &[f64], latency: f64, rec: &Recorded) -> (f64, f64, usize) {
    let lags = output_lags(latency);
    let from = settling(rec.truth.len());
    let (error, lag) = aligned_rms(&rec.truth, u_hat, lags.clone(), from);
    let (error_recorded, _) = aligned_rms(&rec.u, u_hat, lags, from);
    (error, error_recorded, lag)
}

/// The model file's stored compensator on the probe signal `y` as a board runs it (`f32`, or
/// the fixed-point plan the CLI runs: the direct form's if the design has one), through the
/// library: `(u_hat, latency, clamped inputs, overflowed)`.
fn replay(
    file: &unlag::file::ModelFile,
    column: Column,
    y: &[f64],
) -> Result<(Vec<f64>, f64, usize, bool), String> {
    let d = file.inverse.as_ref().ok_or("no stored compensator")?;
    if !file.effects.is_empty() {
        return Err("the model has effects: not replayed".into());
    }
    let e = |e: unlag::Error| e.to_string();
    let latency = d.latency_samples;
    match column {
        Column::BoardF32 | Column::RunsF32 => Ok((d.run::<f32>(y).map_err(e)?, latency, 0, false)),
        Column::BoardFixed | Column::RunsFixed => {
            let run = match (&d.fixed_direct, &d.fixed) {
                (Some(p), _) => p.run(y).map_err(e)?,
                (None, Some(p)) => p.run(y).map_err(e)?,
                (None, None) => return Err("no fixed-point plan".into()),
            };
            Ok((run.u_hat, latency, run.clipped_inputs, run.overflowed))
        }
        _ => Err("not a board column".into()),
    }
}

/// Reads one column's JSON, log and output file, and scores the output.
fn read_output(json: &str, log: &str, out: &Path, rec: &Recorded) -> Result<Output, String> {
    let v: serde_json::Value =
        serde_json::from_str(json.trim()).map_err(|e| format!("unreadable JSON ({e})"))?;
    let latency = v
        .get("latency_samples")
        .and_then(serde_json::Value::as_f64)
        .ok_or("no latency_samples in the JSON")?;
    let columns = unlag::trace::Columns {
        input: "u_hat".into(),
        ..unlag::trace::Columns::default()
    };
    let trace = unlag::trace::Trace::read(out, &columns).map_err(|e| e.to_string())?;
    let u_hat = trace.u.ok_or("no u_hat column")?;
    let (error, error_recorded, lag) = score(&u_hat, latency, rec);
    let f = |k: &str| v.get(k).and_then(serde_json::Value::as_f64);
    Ok(Output {
        error,
        error_recorded,
        lag,
        latency,
        cli_error: None,
        clamped: find_count(&v, "clamped_inputs")
            .map(|c| c as usize)
            .or_else(|| clamped_in_log(log))
            .unwrap_or(0),
        overflowed: log.contains("overflow flag set"),
        fell_back: v
            .get("run_fall_back")
            .and_then(|f| f.get("what"))
            .and_then(serde_json::Value::as_str)
            .map(str::to_string),
        compensator: v
            .get("compensator")
            .and_then(serde_json::Value::as_str)
            .unwrap_or("?")
            .to_string(),
        cli: (f("nrmse_u_hat"), f("nrmse_raw")),
    })
}

/// Writes `NAME.csv` (the recorded channels) and `NAME-truth.csv` (`u`: the true pressure,
/// `y`: the probe without noise or ADC) in `dir`.
fn write_record(dir: &Path, name: &str, fs: f64, rec: &Recorded) -> Result<(), String> {
    write_csv(&dir.join(format!("{name}.csv")), fs, &rec.u, &rec.y)?;
    write_csv(
        &dir.join(format!("{name}-truth.csv")),
        fs,
        &rec.truth,
        &rec.probe_clean,
    )
}

/// Writes a `t,y` CSV: a run recorded by the probe alone.
fn write_probe_alone(path: &Path, fs: f64, y: &[f64]) -> Result<(), String> {
    use std::fmt::Write as _;
    let mut s = String::with_capacity(30 * y.len());
    s.push_str("t,y\n");
    for (k, v) in y.iter().enumerate() {
        let _ = writeln!(s, "{:.9},{v:.6}", k as f64 / fs);
    }
    std::fs::write(path, s).map_err(|e| format!("cannot write {}: {e}", path.display()))
}

/// The probe's step test and runs, `fit`, and every column on every run.
pub fn run_probe(probe: &Probe, s: &Settings) -> ProbeResult {
    let start = Instant::now();
    let mut result = ProbeResult {
        probe: probe.clone(),
        step_adc: (f64::NAN, f64::NAN),
        model: None,
        failure: None,
        runs: Vec::new(),
        seconds: 0.0,
    };
    let dir = s.out.join(format!("probe-{:03}", probe.id));
    let made = (|| -> Result<Vec<(runs::Run, Recorded)>, String> {
        std::fs::create_dir_all(&dir)
            .map_err(|e| format!("cannot create {}: {e}", dir.display()))?;
        let mut rng = Rng::new(probe.seed);
        let step = runs::step_test(probe, &mut rng);
        let list = runs::draw_runs(probe, &mut rng);
        let rec = runs::record(probe, &step, &mut rng)?;
        write_record(&dir, RunKind::StepTest.name(), probe.fs, &rec)?;
        result.step_adc = (rec.adc.min_pa, rec.adc.max_pa);
        let made = list
            .into_iter()
            .map(|run| {
                let rec = runs::record(probe, &run, &mut rng)?;
                write_record(&dir, run.kind.name(), probe.fs, &rec)?;
                Ok((run, rec))
            })
            .collect::<Result<Vec<_>, String>>()?;
        // The rehearsals, drawn after the runs so that the runs are those of the same seed
        // without them: one more run of each kind, its own parameters, the probe alone.
        for run in runs::draw_runs(probe, &mut rng) {
            let rec = runs::record(probe, &run, &mut rng)?;
            write_probe_alone(
                &dir.join(format!("{}-rehearsal.csv", run.kind.name())),
                probe.fs,
                &rec.y,
            )?;
        }
        Ok(made)
    })();
    let made = match made {
        Ok(m) => m,
        Err(e) => {
            result.failure = Some(format!("simulation: {e}"));
            result.seconds = start.elapsed().as_secs_f64();
            return result;
        }
    };
    if let Err(e) = unlag(
        &s.unlag,
        &dir,
        &["fit", "step-test.csv", "-o", "model.toml"],
        "fit.log",
    ) {
        result.failure = Some(e);
        result.seconds = start.elapsed().as_secs_f64();
        return result;
    }
    let file = unlag::file::ModelFile::load(&dir.join("model.toml")).ok();
    result.model = file.as_ref().map(model_info);
    // Per kind of run, the model file fitted with its rehearsal, or why there is none.
    let mut for_runs: Vec<(RunKind, Result<unlag::file::ModelFile, String>)> = Vec::new();
    for kind in runs::RUN_KINDS {
        let model = Column::RunsF32.model(kind);
        let rehearsal = format!("{}-rehearsal.csv", kind.name());
        let log = format!("fit-{}.log", kind.name());
        let fitted = unlag(
            &s.unlag,
            &dir,
            &["fit", "step-test.csv", "--signal", &rehearsal, "-o", &model],
            &log,
        )
        .and_then(|_| unlag::file::ModelFile::load(&dir.join(&model)).map_err(|e| e.to_string()));
        for_runs.push((kind, fitted));
    }
    for (run, rec) in &made {
        let name = run.kind.name();
        let from = settling(rec.truth.len());
        let lags = raw_lags(probe.lag_s * probe.fs, run.n);
        let (raw, raw_lag) = aligned_rms(&rec.truth, &rec.y, lags.clone(), from);
        let (raw_recorded, _) = aligned_rms(&rec.u, &rec.y, lags, from);
        let outputs = COLUMNS
            .iter()
            .map(|&c| {
                if c == Column::HostAdapt && !s.adapt {
                    return (c, Err("the binary has no --adapt-to-run".into()));
                }
                let file = if c.is_for_runs() {
                    match for_runs.iter().find(|(k, _)| *k == run.kind) {
                        Some((_, Ok(f))) => Some(f),
                        Some((_, Err(e))) => return (c, Err(format!("fit --signal: {e}"))),
                        None => return (c, Err("no rehearsal".into())),
                    }
                } else {
                    file.as_ref()
                };
                let model = c.model(run.kind);
                let out = format!("{name}-{}.csv", c.name());
                let log = format!("{name}-{}.log", c.name());
                let input = format!("{name}.csv");
                let mut args = vec![
                    "compensate",
                    model.as_str(),
                    input.as_str(),
                    "-o",
                    out.as_str(),
                    "--json",
                ];
                args.extend_from_slice(c.args());
                let o = unlag(&s.unlag, &dir, &args, &log).and_then(|json| {
                    let log = std::fs::read_to_string(dir.join(&log)).unwrap_or_default();
                    let stderr = log.split("--- stderr ---").nth(1).unwrap_or("");
                    let scored = read_output(&json, stderr, &dir.join(&out), rec);
                    // The scores are in results.csv; the outputs are kept on request.
                    if !s.keep {
                        let _ = std::fs::remove_file(dir.join(&out));
                    }
                    scored
                });
                // A board does not fall back: where the CLI did, the stored compensator is
                // scored as the board runs it.
                let o = match (o, file) {
                    (Ok(cli), Some(file)) if c.is_board() && cli.fell_back.is_some() => {
                        replay(file, c, &rec.y).map(|(u_hat, latency, clamped, overflowed)| {
                            let (error, error_recorded, lag) = score(&u_hat, latency, rec);
                            Output {
                                error,
                                error_recorded,
                                lag,
                                latency,
                                clamped,
                                overflowed,
                                cli_error: Some(cli.error),
                                ..cli
                            }
                        })
                    }
                    (o, _) => o,
                };
                (c, o)
            })
            .collect();
        result.runs.push(RunResult {
            kind: run.kind,
            text: run.text.clone(),
            n: run.n,
            adc: (rec.adc.min_pa, rec.adc.max_pa),
            adc_clipped: rec.clipped,
            raw: (raw, raw_recorded, raw_lag),
            outputs,
        });
    }
    result.seconds = start.elapsed().as_secs_f64();
    result
}
