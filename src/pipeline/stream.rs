//! A recording compensated in passes over its file, in memory that does not grow with it: what
//! [`compensate`](super::compensate) computes for the board's compensator (or the paper's
//! direct inverse), row by row.
//!
//! The first pass checks every row and finds the length and the sample rate
//! ([`crate::trace::stream::scan`]); the second measures what needs the whole run before the
//! compensator runs: the probe's spectrum (parts of at most
//! [`SEGMENT`](crate::design::inverse::optimal::on_run::SEGMENT) samples, averaged, as
//! [`RunSpectrum::measure`] cuts a long record), the reference's excitation and range, the
//! clipping checks' typical change; the third runs the compensator, writes each row with its
//! `u_hat` and sums the error against the reference at every lag searched. The figures are
//! [`compensate`](super::compensate)'s. This room reads the run through the trace room's rows;
//! the caller gives the output.
//!
//! [`RunSpectrum::measure`]: crate::design::inverse::optimal::RunSpectrum::measure

use std::io::Write;
use std::path::Path;

use super::compensate::{
    direct_not_in_fixed_point, fixed_runner, unfiltered_correction, Arithmetic, Compensated,
    Compensation, ReferenceError,
};
use super::FixedRunSummary;
use crate::design::inverse::optimal::on_run::SpectrumStream;
use crate::design::inverse::{self, AlignedErrorStream, Design, Runner};
use crate::design::quantise::FixedRunner;
use crate::effects::{self, Additive, PrefilterStream};
use crate::error::{Advice, Error, Result};
use crate::file::{ModelFile, WriteFailure};
use crate::fit::step::{ExcitationStream, MIN_EXCITATION};
use crate::trace::stream::{self as rows, Row, RunChecks, RunInfo};
use crate::trace::Columns;

/// A recording to compensate in passes over its file.
#[derive(Debug, Clone, Copy)]
pub struct StreamRequest<'a> {
    /// The model file.
    pub file: &'a ModelFile,
    /// Where the model file was read from, for messages.
    pub model_path: &'a Path,
    /// The recording (a regular file: it is read three times).
    pub run: &'a Path,
    /// Its columns.
    pub columns: &'a Columns,
    /// Which compensator: [`Compensation::Designed`] or [`Compensation::Direct`] (the
    /// host-only ones need the whole run and are refused).
    pub compensation: Compensation,
    /// The recording's gas temperature (K), as [`super::CompensateRequest::temperature_k`].
    pub temperature_k: Option<f64>,
}

/// Whether `compensation` is computed in passes ([`prepare`]): the board's compensator and
/// the direct inverse are; the offline optimum and a compensator chosen for the run hold the
/// run in memory.
#[must_use]
pub fn streams(compensation: Compensation) -> bool {
    matches!(
        compensation,
        Compensation::Designed(_) | Compensation::Direct(_)
    )
}

/// The compensator as it runs sample by sample.
enum Filter {
    Float(Runner),
    Fixed(FixedRunner),
}

/// What runs on each probe sample (offset and drift removed): the prefilter (the direct inverse
/// of a model fitted below a sensor resonance), the compensator, the nonlinear-damping
/// correction added.
struct Chain {
    prefilter: Option<PrefilterStream>,
    filter: Filter,
    nonlinear: Option<Runner>,
    full_scale: f64,
}

impl Chain {
    fn step(&mut self, y: f64) -> f64 {
        let x = self.prefilter.as_mut().map_or(y, |p| p.step(y));
        let mut u = match &mut self.filter {
            Filter::Float(f) => f(x),
            Filter::Fixed(f) => f.step(x),
        };
        if let Some(c) = &mut self.nonlinear {
            u += c(y);
        }
        u
    }

    fn summary(&self) -> Option<FixedRunSummary> {
        match &self.filter {
            Filter::Fixed(f) => Some(FixedRunSummary {
                clamped_inputs: f.clipped_inputs(),
                full_scale: self.full_scale,
                overflowed: f.overflowed(),
            }),
            Filter::Float(_) => None,
        }
    }
}

/// A run checked and measured (the first two passes), ready to be compensated and written
/// ([`Prepared::write`]).
pub struct Prepared {
    info: RunInfo,
    columns: Columns,
    checks: RunChecks,
    file: ModelFile,
    chain: Chain,
    additive: Additive,
    /// The error's searches and the reference's prefilter, when it is measured.
    error: Option<(AlignedErrorStream, AlignedErrorStream, PrefilterStream)>,
    result: Compensated,
}

impl Prepared {
    /// What the first pass found (the length, the sample rate, the header).
    #[must_use]
    pub fn info(&self) -> &RunInfo {
        &self.info
    }
}

/// The model file as the request puts it (at its temperature), the compensator built, its
/// latency and name, whether designed; the checks in [`compensate`](super::compensate)'s
/// order.
struct Setup {
    file: ModelFile,
    design: Option<Design>,
    chain: Chain,
    latency: f64,
    compensator: &'static str,
    stored_not_better: Option<inverse::DesignMethod>,
}

fn setup(request: &StreamRequest<'_>, info: &RunInfo) -> Result<Setup> {
    super::check_model_rate(request.file, &info.path, info.sample_rate_hz)?;
    let file = match request.temperature_k {
        Some(t) => super::at_temperature(request.file, t)?,
        None => request.file.clone(),
    };
    let model_path = request.model_path;
    let m = &file.model;
    let additive = Additive::of(&file.effects);
    let first = info
        .probe_head
        .first()
        .map_or(0.0, |y| y - additive.at(0, m.fs));
    let (design, arithmetic) = match request.compensation {
        Compensation::Designed(a) => (file.inverse.clone(), a),
        Compensation::Direct(a) => (None, a),
        Compensation::AdaptedToRun | Compensation::Offline => {
            return Err(Error::InvalidArgument {
                what: "compensation",
                message: "the host-only compensators hold the run: not streamed".into(),
            })
        }
    };
    let nonlinear = effects::nonlinear_gain(&file.effects);
    let stored_not_better = design
        .as_ref()
        .and_then(|d| d.check.as_ref().map(|c| (d, c)))
        .filter(|(_, c)| c.verdict == inverse::check::Verdict::NotBetter)
        .map(|(d, _)| d.method.clone());
    let (chain, latency, compensator) = match &design {
        Some(d) => {
            d.check_exportable()?;
            let (filter, full_scale) = match arithmetic {
                Arithmetic::F32 => (Filter::Float(d.runner::<f32>(first)?), 0.0),
                Arithmetic::F64 => (Filter::Float(d.runner::<f64>(first)?), 0.0),
                Arithmetic::Fixed if nonlinear != 0.0 => {
                    return Err(Error::UnsupportedOnBoard {
                        path: model_path.to_path_buf(),
                        effect: "nonlinear damping",
                        arithmetic: "fixed-point",
                    }
                    .advised(Advice::UseF32))
                }
                Arithmetic::Fixed => {
                    let (runner, fs) = fixed_runner(d, file.board.full_scale, model_path, first)?;
                    (Filter::Fixed(runner), fs)
                }
            };
            let nonlinear = if nonlinear == 0.0 {
                None
            } else {
                Some(match arithmetic {
                    Arithmetic::F64 => d.nonlinear_runner::<f64>(m.fs, nonlinear, first)?,
                    _ => d.nonlinear_runner::<f32>(m.fs, nonlinear, first)?,
                })
            };
            let chain = Chain {
                prefilter: None,
                filter,
                nonlinear,
                full_scale,
            };
            (chain, d.latency_samples, "the model file's compensator")
        }
        None => direct_chain(
            &file,
            info,
            &additive,
            model_path,
            (arithmetic, nonlinear, first),
        )?,
    };
    Ok(Setup {
        file,
        design,
        chain,
        latency,
        compensator,
        stored_not_better,
    })
}

/// The chain of the paper's direct inverse of `file`'s model (no designed compensator): the
/// prefilter below a sensor resonance, the inverse in `arithmetic` (not fixed point), and the
/// nonlinear-damping correction of gain `nonlinear` unfiltered, both starting from the probe's
/// `first` sample less the additive effects; with its latency and name.
fn direct_chain(
    file: &ModelFile,
    info: &RunInfo,
    additive: &Additive,
    model_path: &Path,
    (arithmetic, nonlinear, first): (Arithmetic, f64, f64),
) -> Result<(Chain, f64, &'static str)> {
    let m = &file.model;
    m.check_invertible(&model_path.display().to_string())?;
    // The direct inverse of a model fitted below a sensor resonance gets the prefilter.
    let head: Vec<f64> = info
        .probe_head
        .iter()
        .enumerate()
        .map(|(k, y)| y - additive.at(k, m.fs))
        .collect();
    let prefilter = PrefilterStream::new(&file.effects, m.fs, &head);
    let first_in = prefilter.clone().step(first);
    let filter = match arithmetic {
        Arithmetic::F32 => m.compensator::<f32>(first_in)?,
        Arithmetic::F64 => m.compensator::<f64>(first_in)?,
        Arithmetic::Fixed => return Err(direct_not_in_fixed_point()),
    };
    // The direct inverse has no band limit: the correction is not filtered either.
    let nonlinear = if nonlinear == 0.0 {
        None
    } else {
        let c = unfiltered_correction(nonlinear, m.fs)?;
        let mut st = c.equilibrium(first);
        let step: Runner = Box::new(move |y| c.process(&mut st, y));
        Some(step)
    };
    let chain = Chain {
        prefilter: Some(prefilter),
        filter: Filter::Float(filter),
        nonlinear,
        full_scale: 0.0,
    };
    Ok((chain, m.delay as f64, "the paper's direct inverse (eq. 7)"))
}

/// The first two passes over the run of `request`: every row checked (the trace's errors
/// first, in [`crate::trace::Trace::read`]'s order), the model's sample rate and the
/// compensator's own refusals (in [`compensate`](super::compensate)'s), then the run's
/// spectrum, its reference's excitation and range.
///
/// # Errors
/// As [`crate::trace::Trace::read`] and [`compensate`](super::compensate);
/// [`crate::trace::TraceError::NotRereadable`] for a pipe or a device.
pub fn prepare(request: &StreamRequest<'_>) -> Result<Prepared> {
    let columns = request.columns;
    let mut excitation = ExcitationStream::new();
    let (info, mut checks) = rows::scan(request.run, columns, |row: &Row| {
        if let Some(u) = row.u {
            excitation.first(u);
        }
    })?;
    excitation.end_first();
    let setup = match setup(request, &info) {
        Ok(s) => s,
        Err(e) => {
            // A clipped channel is the trace's error, and told first.
            clip_only(&info, columns, &mut checks)?;
            return Err(e);
        }
    };
    let Setup {
        file,
        design,
        chain,
        latency,
        compensator,
        stored_not_better,
    } = setup;
    let m = &file.model;
    let additive = Additive::of(&file.effects);
    let mut spectrum = design
        .as_ref()
        .filter(|d| inverse::check::judges_runs(d))
        .and_then(|_| SpectrumStream::new(info.len));
    let mut observed = PrefilterStream::new(&file.effects, m.fs, &info.reference_head);
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    let mut again = rows::again(&info, columns)?;
    let mut k = 0;
    while let Some(row) = again.next_row()? {
        checks.second(&row);
        if let Some(s) = &mut spectrum {
            s.push(row.y - additive.at(k, m.fs));
        }
        if let Some(u) = row.u {
            excitation.second(u);
            let v = observed.step(u);
            (lo, hi) = (lo.min(v), hi.max(v));
        }
        k += 1;
    }
    rows::end_pass(&info, again, k)?;
    checks.end_second();
    // The stored design judged on the run's own probe spectrum.
    let predicted = design
        .as_ref()
        .and_then(|d| {
            inverse::check::on_run_measured(
                d,
                m,
                || spectrum.and_then(SpectrumStream::finish),
                inverse::check::RunCandidates::JudgeOnly,
            )
        })
        .map(|j| j.stored);
    // A reference that does not move above its noise says nothing about u_hat.
    let still_reference = info.has_reference && excitation.value() < MIN_EXCITATION;
    let error = (info.has_reference && !still_reference).then(|| {
        let prefilter = if design.is_some() {
            effects::prefilter_delay(&file.effects, m.fs)
        } else {
            0.0
        };
        let nominal = (latency - prefilter).round().max(0.0) as usize;
        // The raw probe is searched over the same lags whatever the compensator's latency.
        let causal = design
            .as_ref()
            .map_or(latency, |d| d.latency_samples)
            .round()
            .max(0.0) as usize;
        let (lags, raw_lags) = inverse::comparison_lags(design.as_ref(), nominal, causal, m.delay);
        let range = hi - lo;
        (
            AlignedErrorStream::new(info.len, lags, range),
            AlignedErrorStream::new(info.len, raw_lags, range),
            PrefilterStream::new(&file.effects, m.fs, &info.reference_head),
        )
    });
    let result = Compensated {
        u_hat: Vec::new(),
        latency_samples: latency,
        compensator,
        designed: design.is_some(),
        error: None,
        still_reference,
        fixed: None,
        predicted,
        fall_back: None,
        stored_not_better,
        host_only: false,
    };
    Ok(Prepared {
        columns: columns.clone(),
        info,
        checks,
        file,
        chain,
        additive,
        error,
        result,
    })
}

/// The clipping checks alone, over the second and third passes: for a run refused for another
/// reason after its first pass, whose clipped channel is told first.
fn clip_only(info: &RunInfo, columns: &Columns, checks: &mut RunChecks) -> Result<()> {
    for pass in [2, 3] {
        let mut again = rows::again(info, columns)?;
        let mut k = 0;
        while let Some(row) = again.next_row()? {
            if pass == 2 {
                checks.second(&row);
            } else {
                checks.third(&row);
            }
            k += 1;
        }
        rows::end_pass(info, again, k)?;
        if pass == 2 {
            checks.end_second();
        }
    }
    Ok(checks.finish()?)
}

impl Prepared {
    /// The clipping checks alone, in a pass of their own, before anything is written: for an
    /// output that cannot be taken back (standard output, a device), which would otherwise
    /// have received the rows before a clipped channel is found at the end of the writing
    /// pass.
    ///
    /// # Errors
    /// [`crate::trace::TraceError::Clipped`], or the file changed.
    pub fn check_clipping(&self) -> Result<()> {
        let mut checks = self.checks.clone();
        let mut again = rows::again(&self.info, &self.columns)?;
        let mut k = 0;
        while let Some(row) = again.next_row()? {
            checks.third(&row);
            k += 1;
        }
        rows::end_pass(&self.info, again, k)?;
        Ok(checks.finish()?)
    }

    /// The third pass: each row written to `out` with its `u_hat` after its own fields (the
    /// header first), the error against the reference summed as it goes. What it computed,
    /// `u_hat` left empty (it is in `out`).
    ///
    /// # Errors
    /// [`WriteFailure::Output`] when `out` fails; [`WriteFailure::Content`] with the trace's
    /// error when a channel is clipped or the file changed since the first pass.
    pub fn write(mut self, out: &mut dyn Write) -> std::result::Result<Compensated, WriteFailure> {
        let fs = self.file.model.fs;
        let header = rows::header_line(&self.info.headers, &["u_hat"], &self.columns);
        out.write_all(header.as_bytes())?;
        let mut again = rows::again(&self.info, &self.columns).map_err(Error::from)?;
        let mut line = Vec::with_capacity(128);
        let mut k = 0;
        while let Some(row) = again.next_row().map_err(Error::from)? {
            self.checks.third(&row);
            let y_probe = row.y - self.additive.at(k, fs);
            let u_hat = self.chain.step(y_probe);
            if let (Some((e, raw, observed)), Some(u)) = (&mut self.error, row.u) {
                let u = observed.step(u);
                e.push(u, u_hat);
                raw.push(u, row.y);
            }
            rows::write_row(again.record(), &[u_hat], &self.columns, &mut line);
            out.write_all(&line)?;
            k += 1;
        }
        rows::end_pass(&self.info, again, k).map_err(Error::from)?;
        self.checks.finish().map_err(Error::from)?;
        let mut result = self.result;
        result.fixed = self.chain.summary();
        result.error = self.error.map(|(e, raw, _)| {
            let (u_hat, lag) = e.finish();
            let (raw, _) = raw.finish();
            ReferenceError { u_hat, raw, lag }
        });
        Ok(result)
    }
}

#[cfg(test)]
mod tests {
    use super::super::testing::{probe, step_test};
    use super::*;
    use crate::file::FORMAT_VERSION;
    use crate::trace::Trace;

    /// A run written as a CSV file, its columns read with and without the reference required.
    fn run_file(dir: &Path, name: &str, u: &[f64], y: &[f64]) -> std::path::PathBuf {
        let mut csv = String::from("t,u,y\n");
        for (k, (u, y)) in u.iter().zip(y).enumerate() {
            csv.push_str(&format!("{:.6},{u:e},{y:e}\n", k as f64 / 10_000.0));
        }
        let path = dir.join(name);
        std::fs::write(&path, csv).unwrap();
        path
    }

    fn file_with_design() -> ModelFile {
        let m = probe();
        let (u, y) = step_test(1.0, 3);
        let tests = [crate::fit::Test {
            name: "step",
            u: &u,
            y: &y,
        }];
        let noise = inverse::optimal::estimate_noise(&tests);
        let prior = inverse::optimal::estimate_prior(&tests, &noise);
        let mut d = inverse::optimal::design(&m, &noise, &prior, &Default::default()).unwrap();
        d.fixed = Some(crate::design::quantise::FixedPlan::new(&d, 2.0).unwrap());
        ModelFile {
            format_version: FORMAT_VERSION,
            model: m,
            fit: None,
            sources: Vec::new(),
            inverse: Some(d),
            effects: vec![crate::effects::Effect::Offset { value: 0.01 }],
            history: Vec::new(),
            probe: None,
            board: Default::default(),
        }
    }

    /// The streamed run gives the batch run's numbers, its output the batch output's bytes,
    /// in every arithmetic and for the direct inverse.
    #[test]
    fn the_streamed_run_is_the_batch_run() {
        let dir = std::env::temp_dir().join(format!("unlag-stream-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let (u, y) = step_test(1.0, 11);
        let path = run_file(&dir, "run.csv", &u, &y);
        let columns = Columns {
            require_input: false,
            ..Columns::default()
        };
        let trace = Trace::read(&path, &columns).unwrap();
        let file = file_with_design();
        for compensation in [
            Compensation::Designed(Arithmetic::F32),
            Compensation::Designed(Arithmetic::F64),
            Compensation::Designed(Arithmetic::Fixed),
            Compensation::Direct(Arithmetic::F32),
        ] {
            let batch = super::super::compensate(&super::super::CompensateRequest {
                file: &file,
                model_path: Path::new("m.toml"),
                probe: &trace.y,
                reference: trace.u.as_deref(),
                compensation,
                temperature_k: None,
            })
            .unwrap();
            let mut expected = Vec::new();
            trace
                .write_csv_with(&mut expected, &[("u_hat", &batch.u_hat)])
                .unwrap();
            let prepared = prepare(&StreamRequest {
                file: &file,
                model_path: Path::new("m.toml"),
                run: &path,
                columns: &columns,
                compensation,
                temperature_k: None,
            })
            .unwrap();
            assert_eq!(prepared.info().len, trace.len());
            let mut written = Vec::new();
            let streamed = prepared.write(&mut written).unwrap();
            assert!(written == expected, "{compensation:?}");
            assert_eq!(
                streamed,
                Compensated {
                    u_hat: Vec::new(),
                    ..batch.clone()
                },
                "{compensation:?}"
            );
            assert!(batch.error.is_some());
            if compensation == Compensation::Designed(Arithmetic::F32) {
                assert!(batch.predicted.is_some());
            }
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// A clipped channel, time that jitters or goes back, a file too short, a bad cell: the
    /// streamed run is refused with the message the run read whole gets; a clipped one after
    /// its writing pass (its output discarded by the caller), or before it when asked.
    #[test]
    fn a_bad_run_gets_the_message_of_the_run_read_whole() {
        let dir = std::env::temp_dir().join(format!("unlag-stream-bad-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let columns = Columns {
            require_input: false,
            ..Columns::default()
        };
        let file = file_with_design();
        fn request<'a>(
            file: &'a ModelFile,
            columns: &'a Columns,
            run: &'a Path,
        ) -> StreamRequest<'a> {
            StreamRequest {
                file,
                model_path: Path::new("m.toml"),
                run,
                columns,
                compensation: Compensation::Designed(Arithmetic::F32),
                temperature_k: None,
            }
        }
        let whole = |path: &Path| Error::from(Trace::read(path, &columns).unwrap_err()).to_string();
        // The probe flat at a new largest value for 30 samples, entered by a jump.
        let (u, mut y) = step_test(1.0, 12);
        y[2000..2030].iter_mut().for_each(|v| *v = 5.0);
        let clipped = run_file(&dir, "clipped.csv", &u, &y);
        let expected = whole(&clipped);
        assert!(expected.contains("looks clipped"), "{expected}");
        let prepared = prepare(&request(&file, &columns, &clipped)).unwrap();
        assert_eq!(prepared.check_clipping().unwrap_err().to_string(), expected);
        match prepared.write(&mut Vec::new()) {
            Err(WriteFailure::Content(e)) => assert_eq!(e.to_string(), expected),
            other => panic!("{:?}", other.map(|c| c.compensator)),
        }

        // Time that jitters at line 52, and also goes back at line 90 (told first); one row.
        let mut text = String::from("t,u,y\n");
        for k in 0..400 {
            let t = k as f64 * 1e-4 + if k == 50 { 5e-6 } else { 0.0 };
            text.push_str(&format!("{t:.7},0,{}\n", (k as f64 * 0.1).sin()));
        }
        let jitter = dir.join("jitter.csv");
        std::fs::write(&jitter, &text).unwrap();
        let back = dir.join("back.csv");
        std::fs::write(&back, text.replace("0.0088000,", "0.0080000,")).unwrap();
        let one = dir.join("one.csv");
        std::fs::write(&one, "t,u,y\n0,0,0\n").unwrap();
        let bad_cell = dir.join("cell.csv");
        std::fs::write(&bad_cell, text.replace("0.0100000,0,", "0.0100000,x,")).unwrap();
        for path in [&jitter, &back, &one, &bad_cell] {
            let expected = whole(path);
            let streamed = prepare(&request(&file, &columns, path))
                .err()
                .map(|e| e.to_string());
            assert_eq!(streamed.as_deref(), Some(expected.as_str()));
        }
        assert!(whole(&jitter).contains(":52:1:"), "{}", whole(&jitter));
        assert!(
            whole(&back).contains("does not increase"),
            "{}",
            whole(&back)
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
