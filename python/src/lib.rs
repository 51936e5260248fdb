//! The native half of the `unlag` Python package (`unlag._unlag`): thin bindings to the
//! library's pipeline, each taking its options as the command line's flags (parsed by the
//! command line's own argument types, so that the checks and the messages are the CLI's).
//! The Python half (`python/unlag/__init__.py`) checks the arrays and holds the API and its
//! documentation.

use std::path::{Path, PathBuf};

use clap::Parser;
use numpy::{IntoPyArray, PyArray1, PyReadonlyArray1};
use pyo3::prelude::*;
use pyo3::types::PyBytes;
use sha2::{Digest, Sha256};

use unlag::cli::export::ExportArgs;
use unlag::cli::inspect::ResampleArgs;
use unlag::cli::physics::SimulateTestArgs;
use unlag::cli::predict::PredictArgs;
use unlag::cli::{ColumnArgs, FitArgs, InvertArgs};
use unlag::file::{BoardArithmetic, ModelFile};
use unlag::fit::Test;
use unlag::pipeline::{self, Arithmetic, CompensateRequest, Compensation};

/// The Python exception for a library error: the class (in `unlag._errors`) by the error's
/// kind, with the message the command line prints.
fn py_err(e: &unlag::Error) -> PyErr {
    raise(&unlag::cli::describe(e), e.kind())
}

/// The exception of `kind` with `message`.
fn raise(message: &str, kind: &str) -> PyErr {
    let class = match kind {
        "invalid-argument" | "usage" => "InvalidArgumentError",
        "io" | "overwrite" | "not-replaced" => "FileError",
        "model" => "ModelFileError",
        "unstable-model" | "unstable-inverse" => "UnstableError",
        "unsupported-on-board" | "blob" => "BoardError",
        "numerical" | "plot" => "Error",
        _ => "DataError",
    };
    Python::attach(|py| {
        match py
            .import("unlag._errors")
            .and_then(|m| m.getattr(class))
            .and_then(|c| c.call1((message, kind)))
        {
            Ok(instance) => PyErr::from_value(instance),
            Err(e) => e,
        }
    })
}

/// The command line's arguments of type `T` from `argv` (the program name first), or the
/// usage error as an `InvalidArgumentError` with clap's message (without the usage lines).
fn parse<T: Parser>(argv: Vec<String>) -> PyResult<T> {
    T::try_parse_from(argv).map_err(|e| {
        let text = e.to_string();
        // The first paragraph: the usage lines and the pointer to `--help` follow it.
        let message = text.split("\n\n").next().unwrap_or("").trim();
        let message = message.strip_prefix("error: ").unwrap_or(message);
        raise(message, "invalid-argument")
    })
}

/// `unlag fit`'s arguments.
#[derive(Parser)]
struct FitCli {
    #[command(flatten)]
    fit: FitArgs,
}

/// The column arguments of every command that reads a CSV file.
#[derive(Parser)]
struct ColumnsCli {
    #[command(flatten)]
    columns: ColumnArgs,
}

/// `unlag export`'s arguments.
#[derive(Parser)]
struct ExportCli {
    #[command(flatten)]
    export: ExportArgs,
}

/// `unlag invert`'s arguments.
#[derive(Parser)]
struct InvertCli {
    #[command(flatten)]
    invert: InvertArgs,
}

/// `unlag resample`'s arguments.
#[derive(Parser)]
struct ResampleCli {
    #[command(flatten)]
    resample: ResampleArgs,
}

/// `unlag simulate-test`'s arguments.
#[derive(Parser)]
struct SimulateTestCli {
    #[command(flatten)]
    simulate: SimulateTestArgs,
}

/// `unlag predict`'s arguments.
#[derive(Parser)]
struct PredictCli {
    #[command(flatten)]
    predict: PredictArgs,
}

/// `argv` of the command `program` (its name first): `head`, then `flags`.
fn argv(program: &str, head: &[&str], flags: Vec<String>) -> Vec<String> {
    std::iter::once(program)
        .chain(head.iter().copied())
        .map(String::from)
        .chain(flags)
        .collect()
}

/// A float64 array returned to Python (the vector moved into it, not copied).
type Array<'py> = Bound<'py, PyArray1<f64>>;

/// What `compensate` returns to Python: `u_hat`, its latency (samples), the warnings, and the
/// error against the reference when one was given (`u_hat`'s, the raw probe's, the lag).
type CompensateResult<'py> = (Array<'py>, f64, Vec<String>, Option<(f64, f64, usize)>);

/// A model file in memory, and the path it is named by in messages.
#[pyclass(module = "unlag._unlag", name = "NativeModel", frozen)]
struct NativeModel {
    file: ModelFile,
    path: PathBuf,
}

/// A test as Python gives it: its name, reference and probe output.
type PyTest<'py> = (
    String,
    PyReadonlyArray1<'py, f64>,
    PyReadonlyArray1<'py, f64>,
);

/// The slices of `tests` (contiguous f64 arrays: the Python side makes them so).
fn slices<'a>(tests: &'a [PyTest<'_>]) -> PyResult<Vec<Test<'a>>> {
    tests
        .iter()
        .map(|(name, u, y)| {
            Ok(Test {
                name,
                u: u.as_slice()?,
                y: y.as_slice()?,
            })
        })
        .collect()
}

/// A digest of a test given as arrays (the model file records one per test, as it records the
/// SHA-256 of a test file): SHA-256 of the reference's then the probe's little-endian f64s.
fn digest(t: &Test<'_>) -> String {
    let mut h = Sha256::new();
    for x in t.u.iter().chain(t.y) {
        h.update(x.to_le_bytes());
    }
    h.finalize().iter().map(|b| format!("{b:02x}")).collect()
}

/// Each test's reference must move above its noise, as `unlag fit` requires of its files.
fn check_steps(tests: &[Test<'_>]) -> unlag::error::Result<()> {
    for t in tests {
        pipeline::check_excitation(Path::new(t.name), t.u)?;
    }
    Ok(())
}

/// Reads a CSV file as the command line does: `(u or None, y, fs, sha256)`.
#[pyfunction]
fn read_csv<'py>(
    py: Python<'py>,
    path: PathBuf,
    flags: Vec<String>,
) -> PyResult<(Option<Array<'py>>, Array<'py>, f64, String)> {
    let argv = std::iter::once("unlag".to_string()).chain(flags).collect();
    let columns = parse::<ColumnsCli>(argv)?.columns.columns(false);
    let trace = py
        .detach(|| unlag::trace::Trace::read(&path, &columns))
        .map_err(|e| py_err(&e.into()))?;
    let fs = trace.sample_rate_hz;
    let sha = trace.sha256.clone();
    let u = trace.u.map(|u| u.into_pyarray(py));
    Ok((u, trace.y.into_pyarray(py), fs, sha))
}

/// Fits a model to `tests` (the estimation tests first, `estimation_tests` of them, then the
/// held-out ones), sampled at `rates` (Hz, one per test), and designs its compensator, as `unlag fit` with `flags`; continues
/// `previous`'s modelling loop when given. Returns the model and the warnings.
#[pyfunction]
#[pyo3(signature = (tests, estimation_tests, rates, flags, previous=None, fresh=false))]
fn fit(
    py: Python<'_>,
    tests: Vec<PyTest<'_>>,
    estimation_tests: usize,
    rates: Vec<f64>,
    flags: Vec<String>,
    previous: Option<PyRef<'_, NativeModel>>,
    fresh: bool,
) -> PyResult<(NativeModel, Vec<String>)> {
    let argv = ["unlag fit", "-", "-o", "-"]
        .into_iter()
        .map(String::from)
        .chain(flags)
        .collect();
    let args = parse::<FitCli>(argv)?.fit;
    let tests = slices(&tests)?;
    let previous = previous.as_ref().map(|p| &p.file);
    let run = || -> unlag::error::Result<(ModelFile, Vec<String>)> {
        let options = args.options()?;
        if let Some(fs) = rates.iter().find(|fs| !(fs.is_finite() && **fs > 0.0)) {
            return Err(unlag::Error::InvalidArgument {
                what: "fs",
                message: format!("the sample rate must be a positive number of Hz, got {fs}"),
            });
        }
        pipeline::check_same_rate(
            &tests
                .iter()
                .map(|t| t.name)
                .zip(rates.iter().copied())
                .collect::<Vec<_>>(),
        )?;
        check_steps(&tests)?;
        let digests: Vec<String> = tests.iter().map(digest).collect();
        let board = args.inverse.board(
            previous.map_or_else(Default::default, |p| p.board),
            &args.columns,
        );
        let fitted = pipeline::fit_and_design(&pipeline::FitDesignRequest {
            tests: &tests,
            estimation_tests,
            digests: &digests,
            sample_rates_hz: &rates,
            options,
            previous,
            fresh,
            add: &args.add,
            reference_column: (0, &args.columns.input_column),
            spec: &|fs| args.inverse.spec(&args.columns, fs, &board),
            on_stage: &|_| {},
        })?;
        let mut warnings = Vec::new();
        if let Some(e) = &fitted.no_compensator {
            warnings.push(format!(
                "no compensator designed: {}",
                unlag::cli::describe(e)
            ));
        }
        let mut file = fitted.file;
        file.board = board;
        for c in file.held_out_changes().iter().filter(|c| c.rose()) {
            warnings.push(format!(
                "the held-out error of {} rose from {:.4e} to {:.4e} with this fit: the change \
                 does not help on data it was not fitted to",
                c.file, c.before, c.after
            ));
        }
        Ok((file, warnings))
    };
    let (file, warnings) = py.detach(run).map_err(|e| py_err(&e))?;
    Ok((
        NativeModel {
            file,
            path: PathBuf::from("model"),
        },
        warnings,
    ))
}

/// Loads a model file as the command line does.
#[pyfunction]
fn load(path: PathBuf) -> PyResult<NativeModel> {
    let file = ModelFile::load(&path).map_err(|e| py_err(&e))?;
    Ok(NativeModel { file, path })
}

/// Parses the text of a model file named `name` in messages.
#[pyfunction]
fn loads(text: &str, name: PathBuf) -> PyResult<NativeModel> {
    let file = ModelFile::parse(&name, text).map_err(|e| py_err(&e))?;
    Ok(NativeModel { file, path: name })
}

/// Tests given to the modelling loop: each must be at the model's rate and have a step.
fn loop_tests(file: &ModelFile, tests: &[Test<'_>], rates: &[f64]) -> unlag::error::Result<()> {
    for (t, &fs) in tests.iter().zip(rates) {
        pipeline::check_model_rate(file, Path::new(t.name), fs)?;
    }
    check_steps(tests)
}

/// `unlag diagnose` on tests given as arrays: `(candidates, tests)` as its `--json` writes
/// them.
#[pyfunction]
fn diagnose(
    py: Python<'_>,
    model: PyRef<'_, NativeModel>,
    tests: Vec<PyTest<'_>>,
    rates: Vec<f64>,
) -> PyResult<(String, String)> {
    let tests = slices(&tests)?;
    let file = &model.file;
    let run = || -> unlag::error::Result<(String, String)> {
        loop_tests(file, &tests, &rates)?;
        let d = pipeline::diagnose(&pipeline::DiagnoseRequest {
            file,
            tests: &tests,
            across: false,
            rank: true,
            on_stage: &|_| {},
        })?;
        Ok((
            unlag::cli::modelling::candidates_json(&d.candidates)?.to_string(),
            unlag::cli::modelling::tests_json(&d.evidence)?.to_string(),
        ))
    };
    py.detach(run).map_err(|e| py_err(&e))
}

/// `unlag simulate-test` with `flags` (the CLI's, less `-o`): the columns of the CSV file it
/// writes, `(t, u, y)`, and the lines it prints on stderr where the simulation fell short.
#[pyfunction]
fn simulate_test<'py>(
    py: Python<'py>,
    flags: Vec<String>,
) -> PyResult<(Array<'py>, Array<'py>, Array<'py>, Vec<String>)> {
    let args = parse::<SimulateTestCli>(argv("unlag simulate-test", &["-o", "-"], flags))?.simulate;
    let (test, notes) = py
        .detach(|| {
            let mut notes = Vec::new();
            let (test, _system, _adc) =
                unlag::cli::physics::simulated_test(&args, &mut |line| notes.push(line))?;
            Ok::<_, unlag::Error>((test, notes))
        })
        .map_err(|e| py_err(&e))?;
    Ok((
        test.t.into_pyarray(py),
        test.reference.into_pyarray(py),
        test.probe.into_pyarray(py),
        notes,
    ))
}

/// `unlag predict --json` with `flags` (the CLI's, less `--model` and `--json`), compared
/// with `model` when given: its JSON object.
#[pyfunction]
#[pyo3(signature = (flags, model=None))]
fn predict(
    py: Python<'_>,
    flags: Vec<String>,
    model: Option<PyRef<'_, NativeModel>>,
) -> PyResult<String> {
    let args = parse::<PredictCli>(argv("unlag predict", &[], flags))?.predict;
    let fitted = model.as_ref().map(|m| &m.file.model);
    let run = || -> unlag::error::Result<String> {
        // A wrong count is told before the probe is built, as the command line does.
        unlag::physics::check_mode_count(args.modes).map_err(unlag::Error::from)?;
        let system = args.system.build()?;
        let p = unlag::physics::predict_and_compare(&unlag::physics::PredictRequest {
            line: &system.line,
            gas: &system.gas,
            modes: args.modes,
            model: fitted,
        })?;
        let v =
            unlag::cli::predict::prediction_json(&system, &p.prediction, p.comparison.as_ref())?;
        Ok(v.to_string())
    };
    py.detach(run).map_err(|e| py_err(&e))
}

/// `unlag compare` on tests given as arrays: its `--json` object.
#[pyfunction]
fn compare(
    py: Python<'_>,
    model: PyRef<'_, NativeModel>,
    tests: Vec<PyTest<'_>>,
    rates: Vec<f64>,
) -> PyResult<String> {
    let tests = slices(&tests)?;
    let file = &model.file;
    let run = || -> unlag::error::Result<String> {
        loop_tests(file, &tests, &rates)?;
        let d = pipeline::diagnose(&pipeline::DiagnoseRequest {
            file,
            tests: &tests,
            across: true,
            rank: false,
            on_stage: &|_| {},
        })?;
        let json_err = |e: serde_json::Error| unlag::Error::Serialise {
            what: "json",
            message: e.to_string(),
        };
        let v = serde_json::json!({
            "tests": unlag::cli::modelling::tests_json(&d.evidence)?,
            "across_tests": serde_json::to_value(&d.across).map_err(json_err)?,
            "amplitude_signature": serde_json::to_value(&d.amplitude_signature).map_err(json_err)?,
            "history": serde_json::to_value(&file.history).map_err(json_err)?,
        });
        Ok(v.to_string())
    };
    py.detach(run).map_err(|e| py_err(&e))
}

#[pymethods]
impl NativeModel {
    /// The path the model is named by in messages.
    #[getter]
    fn path(&self) -> PathBuf {
        self.path.clone()
    }

    /// The same model named by `path` in messages.
    fn named(&self, path: PathBuf) -> NativeModel {
        NativeModel {
            file: self.file.clone(),
            path,
        }
    }

    /// Writes the model file (TOML) to `path`, as `unlag fit -o` does.
    fn save(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        py.detach(|| self.file.save(&path)).map_err(|e| py_err(&e))
    }

    /// The model file's TOML.
    fn to_toml(&self) -> PyResult<String> {
        self.file.to_toml().map_err(|e| py_err(&e))
    }

    /// The model file as JSON (as `unlag fit --json` writes it).
    fn to_json(&self) -> PyResult<String> {
        serde_json::to_string(&self.file).map_err(|e| raise(&e.to_string(), "numerical"))
    }

    /// The compensator run on the probe signal `y`, as `unlag compensate`: `arithmetic`
    /// `f32`, `f64`, `fixed` or None (the board's); `how` `designed`, `direct`, `offline` or
    /// `adapt`. Returns `u_hat`, its latency in samples and the warnings.
    #[pyo3(signature = (y, arithmetic, how, temperature=None, reference=None))]
    fn compensate<'py>(
        &self,
        py: Python<'py>,
        y: PyReadonlyArray1<'py, f64>,
        arithmetic: Option<&str>,
        how: &str,
        temperature: Option<f64>,
        reference: Option<PyReadonlyArray1<'py, f64>>,
    ) -> PyResult<CompensateResult<'py>> {
        let arithmetic = match arithmetic {
            Some("f32") => Arithmetic::F32,
            Some("f64") => Arithmetic::F64,
            Some("fixed") => Arithmetic::Fixed,
            None => match self.file.board.arithmetic {
                BoardArithmetic::F32 => Arithmetic::F32,
                BoardArithmetic::Fixed => Arithmetic::Fixed,
            },
            Some(other) => {
                return Err(raise(
                    &format!(
                        "invalid --arithmetic: expected 'f32', 'f64' or 'fixed', got '{other}'"
                    ),
                    "invalid-argument",
                ))
            }
        };
        let compensation = match how {
            "designed" => Compensation::Designed(arithmetic),
            "direct" => Compensation::Direct(arithmetic),
            "offline" => Compensation::Offline,
            "adapt" => Compensation::AdaptedToRun,
            other => {
                return Err(raise(
                    &format!("unknown compensation '{other}'"),
                    "invalid-argument",
                ))
            }
        };
        let probe = y.as_slice()?;
        let reference = match &reference {
            Some(r) => Some(r.as_slice()?),
            None => None,
        };
        let c = py
            .detach(|| {
                pipeline::compensate(&CompensateRequest {
                    file: &self.file,
                    model_path: &self.path,
                    probe,
                    reference,
                    compensation,
                    temperature_k: temperature,
                })
            })
            .map_err(|e| py_err(&e))?;
        let mut warnings = Vec::new();
        if let Some(f) = &c.fixed {
            if f.clamped_inputs > 0 {
                warnings.push(format!(
                    "{} samples of {} lie outside the fixed-point full scale +-{} and were clamped",
                    f.clamped_inputs,
                    probe.len(),
                    f.full_scale
                ));
            }
            if f.overflowed {
                warnings.push("the fixed-point compensator saturated (overflow flag set)".into());
            }
        }
        if c.still_reference {
            warnings.push(
                "the reference does not move above its noise: no error against it is reported"
                    .into(),
            );
        }
        let error = c.error.map(|e| (e.u_hat, e.raw, e.lag));
        Ok((c.u_hat.into_pyarray(py), c.latency_samples, warnings, error))
    }

    /// The model's probe output for the reference `u` (its effects estimated on the recorded
    /// probe `y` when given), as `unlag simulate`. Returns `y_model` and its nrmse against `y`.
    #[pyo3(signature = (u, y=None, temperature=None))]
    fn simulate<'py>(
        &self,
        py: Python<'py>,
        u: PyReadonlyArray1<'py, f64>,
        y: Option<PyReadonlyArray1<'py, f64>>,
        temperature: Option<f64>,
    ) -> PyResult<(Array<'py>, Option<f64>)> {
        let u = u.as_slice()?;
        let recorded = match &y {
            Some(y) => Some(y.as_slice()?),
            None => None,
        };
        let s = py
            .detach(|| {
                // Without a recording, the model's own output stands for it: no offset or
                // drift is estimated.
                let own;
                let y = match recorded {
                    Some(y) => y,
                    None => {
                        own = self.file.model.simulate(u);
                        &own
                    }
                };
                pipeline::simulate(&pipeline::SimulateRequest {
                    file: &self.file,
                    u,
                    y,
                    temperature_k: temperature,
                })
            })
            .map_err(|e| py_err(&e))?;
        let nrmse = recorded.map(|_| s.nrmse);
        Ok((s.y_model.into_pyarray(py), nrmse))
    }

    /// `unlag inspect --json` of the model, its response at `frequencies` (Hz; empty for the
    /// default grid), with the model's stability as `(json, error message or None)`.
    fn inspect(&self, frequencies: Vec<f64>) -> PyResult<(String, Option<String>)> {
        let name = self.path.display().to_string();
        let i = pipeline::inspect(&pipeline::InspectRequest {
            file: &self.file,
            model_name: &name,
            frequencies_hz: &frequencies,
        })
        .map_err(|e| py_err(&e))?;
        let json = |v: Result<serde_json::Value, serde_json::Error>| {
            v.map_err(|e| raise(&e.to_string(), "numerical"))
        };
        let (continuous, why) = match &i.continuous {
            Ok(c) => (json(serde_json::to_value(c))?, None),
            Err(e) => (serde_json::Value::Null, Some(e.to_string())),
        };
        let v = serde_json::json!({
            "analysis": json(serde_json::to_value(&i.analysis))?,
            "resonances": i.analysis.resonance_pairs(),
            "continuous": continuous,
            "continuous_error": why,
        });
        Ok((
            v.to_string(),
            i.stability.err().map(|e| unlag::cli::describe(&e)),
        ))
    }

    /// The model's frequency response (delay included) at `f` Hz: magnitude and phase (rad).
    fn response<'py>(
        &self,
        py: Python<'py>,
        f: PyReadonlyArray1<'py, f64>,
    ) -> PyResult<(Array<'py>, Array<'py>)> {
        let f = f.as_slice()?;
        let points = unlag::fit::analysis::response_points(&self.file.model, f);
        let magnitude: Vec<f64> = points.iter().map(|p| p.magnitude).collect();
        let phase: Vec<f64> = points.iter().map(|p| p.phase_rad).collect();
        Ok((magnitude.into_pyarray(py), phase.into_pyarray(py)))
    }

    /// The default frequency grid of `unlag inspect` (Hz).
    fn default_frequencies<'py>(&self, py: Python<'py>) -> Array<'py> {
        unlag::fit::analysis::default_frequencies(self.file.model.fs).into_pyarray(py)
    }

    /// The model with its compensator designed anew on `tests` (each at its rate in `rates`),
    /// as `unlag invert` with `flags` (the compensator's and the column flags). Returns the
    /// model and the warnings.
    fn invert(
        &self,
        py: Python<'_>,
        tests: Vec<PyTest<'_>>,
        rates: Vec<f64>,
        flags: Vec<String>,
    ) -> PyResult<(NativeModel, Vec<String>)> {
        let path = self.path.display().to_string();
        let args = parse::<InvertCli>(argv("unlag invert", &[&path, "-o", "-"], flags))?.invert;
        let tests = slices(&tests)?;
        let file = &self.file;
        let run = || -> unlag::error::Result<(ModelFile, Vec<String>)> {
            // As the command line: each test's step as it is read, then each one's rate.
            check_steps(&tests)?;
            for (t, &fs) in tests.iter().zip(&rates) {
                pipeline::check_model_rate(file, Path::new(t.name), fs)?;
            }
            let board = args.inverse.board(file.board, &args.columns);
            let spec = args.inverse.spec(&args.columns, file.model.fs, &board)?;
            let compensator = pipeline::design_compensator(&pipeline::CompensatorRequest {
                model: &file.model,
                effects: &file.effects,
                tests: &tests,
                roles: pipeline::Roles::Alike,
                stored: file.inverse.as_ref(),
                spec: &spec,
                exportable: true,
            })?;
            let design = compensator.design?;
            let warnings = compensator
                .unplanned
                .iter()
                .map(|e| format!("no fixed-point compensator: {e}"))
                .collect();
            let out = ModelFile {
                inverse: Some(design),
                board,
                ..file.clone()
            };
            Ok((out, warnings))
        };
        let (file, warnings) = py.detach(run).map_err(|e| py_err(&e))?;
        Ok((
            NativeModel {
                file,
                path: self.path.clone(),
            },
            warnings,
        ))
    }

    /// The model at the sample rate `fs` (the text of a number, as `--fs` takes it), as
    /// `unlag resample`: without a compensator. Returns the model and the warnings.
    fn resample(&self, py: Python<'_>, fs: String) -> PyResult<(NativeModel, Vec<String>)> {
        let path = self.path.display().to_string();
        let args = parse::<ResampleCli>(argv(
            "unlag resample",
            &[&path, "--fs", &fs, "-o", "-"],
            vec![],
        ))?
        .resample;
        let run = || {
            pipeline::resample(&pipeline::ResampleRequest {
                file: &self.file,
                model_path: &self.path,
                sample_rate_hz: args.fs,
            })
        };
        let r = py.detach(run).map_err(|e| py_err(&e))?;
        Ok((
            NativeModel {
                file: r.file,
                path: self.path.clone(),
            },
            r.discretised.warnings,
        ))
    }

    /// What `unlag export` writes for the model with `flags` (`--format` and the rest).
    fn export<'py>(&self, py: Python<'py>, flags: Vec<String>) -> PyResult<Bound<'py, PyBytes>> {
        let argv = [
            "unlag export".to_string(),
            self.path.display().to_string(),
            "-o".into(),
            "-".into(),
        ]
        .into_iter()
        .chain(flags)
        .collect();
        let args = parse::<ExportCli>(argv)?.export;
        let exported = py
            .detach(|| unlag::cli::export::exported(&args, &self.file))
            .map_err(|e| py_err(&e))?;
        Ok(PyBytes::new(py, &exported.bytes))
    }
}

/// The native half of the `unlag` package.
#[pymodule]
fn _unlag(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<NativeModel>()?;
    m.add_function(wrap_pyfunction!(read_csv, m)?)?;
    m.add_function(wrap_pyfunction!(fit, m)?)?;
    m.add_function(wrap_pyfunction!(load, m)?)?;
    m.add_function(wrap_pyfunction!(loads, m)?)?;
    m.add_function(wrap_pyfunction!(diagnose, m)?)?;
    m.add_function(wrap_pyfunction!(compare, m)?)?;
    m.add_function(wrap_pyfunction!(simulate_test, m)?)?;
    m.add_function(wrap_pyfunction!(predict, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
