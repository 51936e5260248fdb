//! `unlag invert` and the compensator arguments it shares with `unlag fit`: what is asked of the
//! design on the command line, and the design printed.

use std::path::PathBuf;

use clap::{Args, ValueEnum};
use serde_json::json;

use super::{as_tests, check_rate, console, json_err, name, pct, read_test, ColumnArgs};
use crate::design::inverse;
use crate::error::{Error, Result};
use crate::file::{Board, BoardArithmetic, ModelFile};
use crate::pipeline::{self, CompensatorRequest, CompensatorSpec, FullScale, Roles, Shape};
use crate::trace::{PressureUnit, Trace};

/// How to design the compensator (shared by `fit` and `invert`).
#[derive(Debug, Clone, Args)]
pub struct InverseArgs {
    /// Instead of the noise-aware optimum (the default), a stable inverse times a low-pass at
    /// this corner in Hz, or `auto`: the corner that reconstructs the tests' references best.
    #[arg(long, value_name = "HZ|auto")]
    pub bandwidth: Option<String>,
    /// Longest latency of `u_hat` behind the true pressure the optimum may take (the model's
    /// delay included): `3ms`, `250us`, `0.002s` or a number of samples. Default: the
    /// shortest within 2 % of the best error the board's 16 sections allow.
    #[arg(long, value_name = "TIME|SAMPLES")]
    pub max_latency: Option<String>,
    /// Largest -3 dB band in Hz the optimum may take (a quieter prior narrows it to this).
    #[arg(long, value_name = "HZ")]
    pub max_band: Option<f64>,
    /// Runs of the kind the board will compensate (CSV, repeatable; the probe alone will do):
    /// the pressure's prior is learnt from them instead of the step tests. From their
    /// reference column, the increments' level and correlation (steps and ramps); from a run
    /// recorded by the probe alone, the level whose compensator the runs' own spectra predict
    /// the least error for. Give the fastest runs you will make.
    #[arg(long = "signal", value_name = "RUN.csv")]
    pub signal: Vec<PathBuf>,
    /// Low-pass family of the band limit.
    #[arg(long, value_enum, default_value_t = LowpassArg::Bessel)]
    pub lowpass: LowpassArg,
    /// Low-pass order.
    #[arg(long, default_value_t = 4, value_name = "N")]
    pub lowpass_order: usize,
    /// Use the paper's direct inverse A/B (times the low-pass) instead of the stable one; fails
    /// for a non-minimum-phase model.
    #[arg(long)]
    pub direct: bool,
    /// The ADC's range in the probe's units: the fixed-point compensator is planned for
    /// readings within +-FS, and never clamps or overflows there. Stored in the model file's
    /// `[board]`. Default: the range stated there, else the tests' largest |y| plus 3 times
    /// their swing, rounded up to 1, 2 or 5 x 10^k (room for a reflected shock of 2.6 times
    /// the step, with the probe's overshoot).
    #[arg(long, value_name = "FS")]
    pub full_scale: Option<f64>,
    /// The traces' pressure unit (Pa, hPa, kPa, MPa, mbar, bar, psi, mmHg, V, mV): pressures
    /// are then printed in it with the prefix that suits them (`6.562 kPa`). Stored in the
    /// model file's `[board]`. Default: the unit the --u or --y column's name ends with
    /// (`p_kPa`, `u [Pa]`), else the model file's.
    #[arg(long, value_name = "UNIT")]
    pub unit: Option<crate::trace::PressureUnit>,
    /// The board's arithmetic: `f32` (a board with an FPU: Cortex-M4F, M7) or `fixed` (32-bit
    /// fixed point, a board without one). Stored in the model file's `[board]`: `unlag
    /// compensate` computes in it and `unlag export` writes it unless told otherwise. Default:
    /// the model file's, else f32.
    #[arg(long, value_enum, value_name = "ARITHMETIC")]
    pub board: Option<BoardArg>,
    /// The fixed-point form: `normal` (coupled sections: no limit cycles, 100 dB at
    /// fs/fn = 1000, about 115 instructions a sample for m = 4 on a Cortex-M4) or `direct`
    /// (direct form I with error feedback: about 33, limit cycles of a few codes possible,
    /// about 90 dB at fs/fn = 1000). See BENCHMARKS.md, "Fixed point: the two forms".
    #[arg(long, value_enum, default_value_t = FixedFormArg::Normal)]
    pub fixed_form: FixedFormArg,
}

/// The board's arithmetic on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum BoardArg {
    /// IEEE single precision (`unlag::board::compensator`).
    F32,
    /// 32-bit fixed point (`unlag::board::fixed`).
    Fixed,
}

impl From<BoardArg> for BoardArithmetic {
    fn from(v: BoardArg) -> Self {
        match v {
            BoardArg::F32 => Self::F32,
            BoardArg::Fixed => Self::Fixed,
        }
    }
}

/// Fixed-point form on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum FixedFormArg {
    /// Normal (coupled) state-space sections (`unlag::board::fixed::FixedCascade`).
    Normal,
    /// Direct-form-I sections with error feedback (`unlag::board::fixed::direct::DirectCascade`).
    Direct,
}

impl From<FixedFormArg> for crate::design::quantise::FixedForm {
    fn from(v: FixedFormArg) -> Self {
        match v {
            FixedFormArg::Normal => Self::Normal,
            FixedFormArg::Direct => Self::Direct,
        }
    }
}

/// Low-pass family on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum LowpassArg {
    /// Bessel: maximally flat delay, a step barely overshoots.
    Bessel,
    /// Butterworth: maximally flat magnitude.
    Butterworth,
}

impl InverseArgs {
    /// The board the output model file is for: the arithmetic and the range given here, else
    /// those `stated` in the model file it replaces.
    #[must_use]
    pub fn board(&self, stated: Board, columns: &ColumnArgs) -> Board {
        let named = [&columns.input_column, &columns.output_column]
            .into_iter()
            .find_map(|c| crate::trace::PressureUnit::of_column(c));
        Board {
            arithmetic: self.board.map_or(stated.arithmetic, Into::into),
            full_scale: self.full_scale.or(stated.full_scale),
            unit: self.unit.or(named).or(stated.unit),
        }
    }

    /// The compensator asked for: the noise-aware optimum unless `--bandwidth` or `--direct`
    /// asks for the band-limited inverse; the optimum's `--signal` runs read, its caps checked
    /// and its latency in samples at `fs`; the fixed-point plan for the full scale of `board`.
    ///
    /// # Errors
    /// The runs' read errors; [`Error::InvalidArgument`] for a `--bandwidth`, `--max-band` or
    /// `--max-latency` that is not what it should be.
    pub fn spec(&self, columns: &ColumnArgs, fs: f64, board: &Board) -> Result<CompensatorSpec> {
        let band_limited = |bandwidth_hz| Shape::BandLimited {
            bandwidth_hz,
            stabilise: !self.direct,
        };
        let (shape, signal) = match self.bandwidth.as_deref() {
            None if !self.direct => {
                let signal = self
                    .signal
                    .iter()
                    .map(|f| Trace::read(f, &columns.columns(false)))
                    .collect::<Result<Vec<_>, _>>()?;
                let max_band_hz = match self.max_band {
                    Some(f) if !(f.is_finite() && f > 0.0) => {
                        return Err(Error::InvalidArgument {
                            what: "--max-band",
                            message: format!("expected a frequency in Hz, got {f}"),
                        })
                    }
                    other => other,
                };
                let max_latency_samples = self
                    .max_latency
                    .as_deref()
                    .map(|v| parse_latency(v, fs))
                    .transpose()?;
                let shape = Shape::Optimal {
                    max_latency_samples,
                    max_band_hz,
                };
                (shape, signal)
            }
            None | Some("auto") => (band_limited(None), Vec::new()),
            Some(text) => match text.parse::<f64>() {
                Ok(f) if f.is_finite() && f > 0.0 => (band_limited(Some(f)), Vec::new()),
                _ => {
                    return Err(Error::InvalidArgument {
                        what: "--bandwidth",
                        message: format!("expected 'auto' or a frequency in Hz, got '{text}'"),
                    })
                }
            },
        };
        Ok(CompensatorSpec {
            shape,
            lowpass: match self.lowpass {
                LowpassArg::Bessel => inverse::LowpassKind::Bessel,
                LowpassArg::Butterworth => inverse::LowpassKind::Butterworth,
            },
            lowpass_order: self.lowpass_order,
            signal,
            fixed_form: self.fixed_form.into(),
            full_scale: board.full_scale,
        })
    }
}

/// The board the model file is for, in one line; with a default full scale, its rule and the
/// resolution it costs, and how to state the ADC's range instead.
pub(super) fn print_board(board: &Board, full_scale: &FullScale) {
    let p = |v: f64| console::pressure(v, board.unit);
    let arithmetic = match board.arithmetic {
        BoardArithmetic::F32 => "f32 (`unlag compensate` and `unlag export` default to it; --board fixed for a board without an FPU)",
        BoardArithmetic::Fixed => "32-bit fixed point (`unlag compensate` and `unlag export` default to it)",
    };
    crate::outln!("  board: {arithmetic}");
    if full_scale.stated {
        crate::outln!(
            "  full scale +-{} (the ADC's range, as stated): the tests reach {} of it",
            p(full_scale.value),
            pct(full_scale.tests_peak / full_scale.value)
        );
        if full_scale.tests_peak > full_scale.value {
            crate::errln!(
                "warning: the tests reach {} but the full scale is +-{}: a fixed-point board clamps \
                 their readings beyond it; give the ADC's range with --full-scale",
                p(full_scale.tests_peak),
                p(full_scale.value)
            );
        }
    } else {
        crate::outln!(
            "  full scale +-{} (default: the tests' largest |y|, {}, plus {} times their swing, \
             rounded up: room for a reflected shock of 2 to 2.6 times the step and the probe's \
             overshoot); it costs {} bits of fixed-point resolution against the tests' own \
             range. Give the ADC's range with --full-scale",
            p(full_scale.value),
            p(full_scale.tests_peak),
            pipeline::DEFAULT_FULL_SCALE_SWINGS,
            console::significant(full_scale.unused_bits())
        );
    }
}

/// The full scale as `--json` gives it.
pub(super) fn full_scale_json(full_scale: &FullScale) -> serde_json::Value {
    json!({
        "value": full_scale.value,
        "stated": full_scale.stated,
        "tests_peak": full_scale.tests_peak,
        "unused_bits": full_scale.unused_bits(),
    })
}

/// Tells each fixed-point plan that could not be made: the f32 compensator does not depend on
/// it.
pub(super) fn warn_unplanned(unplanned: &[Error]) {
    for e in unplanned {
        crate::errln!("warning: no fixed-point compensator: {e}");
    }
}

/// `3ms`, `250us`, `0.002s` or a number of samples, as samples at `fs`.
fn parse_latency(text: &str, fs: f64) -> Result<usize> {
    let t = text.trim();
    let seconds = |v: &str, unit: f64| v.trim().parse::<f64>().ok().map(|x| x * unit * fs);
    let samples = if let Some(v) = t.strip_suffix("ms") {
        seconds(v, 1e-3)
    } else if let Some(v) = t.strip_suffix("us") {
        seconds(v, 1e-6)
    } else if let Some(v) = t.strip_suffix('s') {
        seconds(v, 1.0)
    } else {
        t.parse::<f64>().ok()
    };
    match samples {
        Some(n) if (0.0..1e9).contains(&n) => Ok(n.floor() as usize),
        _ => Err(Error::InvalidArgument {
            what: "--max-latency",
            message: format!(
                "expected a time such as 3ms, 250us or 0.002s, or a number of samples, got '{text}'"
            ),
        }),
    }
}

/// Arguments of `unlag invert`.
#[derive(Debug, Args)]
pub struct InvertArgs {
    /// The model file.
    #[arg(value_name = "MODEL.toml")]
    pub model: PathBuf,
    /// Tests with a reference, to choose the bandwidth on and to report the reconstruction.
    #[arg(value_name = "FILE")]
    pub files: Vec<PathBuf>,
    /// Where to write the model with its compensator (may be MODEL.toml itself).
    #[arg(short = 'o', long = "output", value_name = "OUT.toml")]
    pub output: PathBuf,
    /// Compensator design.
    #[command(flatten)]
    pub inverse: InverseArgs,
    /// Column names.
    #[command(flatten)]
    pub columns: ColumnArgs,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
}

/// The design as `unlag fit` and `unlag invert` print it: its method, band, noise, latency,
/// fixed-point plans, error budget, reconstructions and the check's verdict.
pub(super) fn print_inverse(d: &inverse::Design, fs: f64, unit: Option<PressureUnit>) {
    crate::outln!("compensator: {}", d.method);
    print_structure(d);
    print_band(d);
    print_fixed_plans(d, unit);
    print_error_sources(d, fs, unit);
    crate::outln!(
        "  realised as {} sections: about {} multiply-adds per sample",
        d.sections.len(),
        5 * d.sections.len() + 1
    );
    print_reconstruction(d);
    warn_check(d);
}

/// The design's structure: the zeros of B moved to make it invertible, and the bandwidth search's table.
fn print_structure(d: &inverse::Design) {
    if !d.reflected_zeros.is_empty() {
        crate::outln!(
            "  zeros of B reflected into the unit circle: {}",
            d.reflected_zeros.join(", ")
        );
    }
    if !d.pulled_zeros.is_empty() {
        crate::outln!(
            "  zeros of B pulled in to |z| = {}: {}",
            inverse::ZERO_RADIUS_MAX,
            d.pulled_zeros.join(", ")
        );
    }
    if !d.candidates.is_empty() {
        crate::outln!("  bandwidth search ({}):", d.bandwidth_selection);
        for row in d.candidates.chunks(3) {
            let cells: Vec<String> = row
                .iter()
                .map(|c| {
                    let mark = if (c.lowpass_hz - d.lowpass_hz).abs() < 1e-9 {
                        '*'
                    } else {
                        ' '
                    };
                    format!(
                        "{mark}{:>9.1} Hz {:>9} (noise x{:<8.3})",
                        c.lowpass_hz,
                        pct(c.nrmse),
                        c.noise_gain
                    )
                })
                .collect();
            crate::outln!("   {}", cells.join(" "));
        }
    }
}

/// The band: the low-pass (or the smoother's -3 dB band), the corrected bandwidth, noise gain, latency and in-band errors.
fn print_band(d: &inverse::Design) {
    // The smoother has no low-pass of its own: its band is where H C falls by 3 dB.
    let smoother = d.is_smoother();
    if smoother {
        crate::outln!(
            "  -3 dB band of the corrected probe {}; {} sections",
            console::hz(d.lowpass_hz),
            d.sections.len()
        );
    } else {
        crate::outln!(
            "  {:?} low-pass, order {}, corner {}; {} sections",
            d.lowpass,
            d.lowpass_order,
            console::hz(d.lowpass_hz),
            d.sections.len()
        );
    }
    crate::outln!(
        "  corrected bandwidth {} (+/-1 dB, +/-5 deg); noise gain {}; latency {} samples ({})",
        console::hz(d.corrected_bandwidth_hz),
        console::significant(d.noise_gain),
        console::significant(d.latency_samples),
        super::console::duration(d.latency_s)
    );
    crate::outln!(
        "  in band ({}): worst magnitude error {:.3} dB, worst phase error {:.2} deg; pole margin {:.4}",
        if smoother {
            "to half the -3 dB band, against a pure delay"
        } else {
            "to the corner"
        },
        d.in_band_magnitude_error_db,
        d.in_band_phase_error_deg,
        d.pole_margin
    );
}

/// The fixed-point plans of both forms: input range, output scaling, L1 gain and headroom.
fn print_fixed_plans(d: &inverse::Design, unit: Option<PressureUnit>) {
    let p = |v: f64| console::pressure(v, unit);
    // Both fixed-point forms: the same scaling and bound, told alike.
    let plan_line = |form: &str,
                     full_scale: f64,
                     exponent: i32,
                     l1: f64,
                     headroom: f64,
                     sections: String| {
        crate::outln!(
            "  fixed point{form}: inputs within +-{} (Q1.31), output Q1.31 of {} x 2^{exponent}; L1 gain {}; headroom {} bits by the L1 bound (no overflow possible); {sections}",
            p(full_scale),
            p(full_scale),
            console::significant(l1),
            console::significant(headroom),
        );
    };
    if let Some(plan) = &d.fixed {
        let forms: Vec<&str> = plan.sections.iter().map(|s| s.form.as_str()).collect();
        plan_line(
            "",
            plan.full_scale,
            plan.output_exponent,
            plan.l1_gain,
            plan.headroom_bits,
            format!("sections {}", forms.join(", ")),
        );
    }
    if let Some(plan) = &d.fixed_direct {
        plan_line(
            " (direct form with error feedback)",
            plan.full_scale,
            plan.output_exponent,
            plan.l1_gain,
            plan.headroom_bits,
            format!("{} sections", plan.sections.len()),
        );
    }
}

/// What the error is made of: the predicted error budget, the noise and the signal prior.
fn print_error_sources(d: &inverse::Design, fs: f64, unit: Option<PressureUnit>) {
    let p = |v: f64| console::pressure(v, unit);
    if let Some(b) = &d.budget {
        crate::outln!(
            "  predicted error of u_hat (RMS): {} = noise {} + band limit {} (in quadrature); a noisy reference adds {}",
            p(b.total),
            p(b.noise),
            p(b.band_limit),
            p(b.reference)
        );
    }
    if let Some(n) = &d.noise {
        crate::outln!(
            "  noise ({:?}, RMS): probe {} white{}, reference {}",
            n.source,
            p(n.probe_white_std),
            if n.probe_ar_std > 0.0 {
                format!(
                    " + {} AR(1) pole {}",
                    p(n.probe_ar_std),
                    console::significant(n.probe_ar_pole)
                )
            } else {
                String::new()
            },
            p(n.reference_std)
        );
    }
    if let Some(prior) = &d.prior {
        let from = match prior.source {
            inverse::optimal::PriorSource::StepTests => "the step tests' references",
            inverse::optimal::PriorSource::Runs => "the --signal runs",
            inverse::optimal::PriorSource::Given => "given",
        };
        if prior.increment_pole > 0.0 {
            // The increments' pole as a corner: rho = exp(-2 pi f / fs).
            let corner = -prior.increment_pole.ln() * fs / (2.0 * std::f64::consts::PI);
            crate::outln!(
                "  signal prior (from {from}): steps and ramps, increments correlated {} (its spectrum falls as 1/f^4 above {}), innovation {}",
                console::significant(prior.increment_pole),
                console::hz(corner),
                p(prior.increment_std)
            );
        } else {
            crate::outln!(
                "  signal prior (from {from}): steps, a random walk of increment {} per sample (its spectrum falls as 1/f^2)",
                p(prior.increment_std)
            );
        }
    }
}

/// The reconstruction of each test against its reference, with the error the budget expects.
fn print_reconstruction(d: &inverse::Design) {
    for r in &d.reconstruction {
        let expected = match (&d.budget, r.range) {
            (Some(b), Some(range)) if range > 0.0 => format!(
                "; expected {} from noise and band limit{}",
                pct(b.total.hypot(b.reference) / range),
                match r.model_part {
                    Some(m) => format!(", the rest ({}) is the model's", pct(m)),
                    None => String::new(),
                }
            ),
            _ => String::new(),
        };
        crate::outln!(
            "  reconstruction of {}: u_hat {} against the reference, raw probe {} ({:.1}x better){expected}",
            r.file,
            pct(r.nrmse_u_hat),
            pct(r.nrmse_raw),
            r.nrmse_raw / r.nrmse_u_hat
        );
    }
}

/// The check's verdict on stderr when the design fell back or beat nothing.
fn warn_check(d: &inverse::Design) {
    if let Some(c) = &d.check {
        match c.verdict {
            inverse::check::Verdict::Better | inverse::check::Verdict::Unchecked => {}
            inverse::check::Verdict::FellBack => crate::errln!(
                "warning: fell back to {}: {}",
                d.method.short(),
                c.rejected.join("; ")
            ),
            inverse::check::Verdict::NotBetter => crate::errln!(
                "warning: no compensator is better than the raw probe on these tests ({}); stored marked not-better, `unlag export` refuses it without --force",
                c.rejected.join("; ")
            ),
        }
    }
}

/// `unlag invert`: the model file's compensator designed anew on the tests given.
///
/// # Errors
/// The model file's, the traces' and the design's errors.
pub fn run_invert(args: &InvertArgs) -> Result<()> {
    // A stored compensator that no longer belongs to the model (the model edited since) is
    // what this command replaces: said, not refused.
    let (file, stale) = ModelFile::load_for_redesign(&args.model)?;
    if stale {
        crate::errln!(
            "note: the compensator stored in {} was designed for another model; designing a new \
             one for the model in the file",
            name(&args.model)
        );
    }
    let columns = args.columns.columns(true);
    let traces = args
        .files
        .iter()
        .map(|f| read_test(f, &columns))
        .collect::<Result<Vec<_>>>()?;
    for t in &traces {
        check_rate(&file, t)?;
    }
    let names: Vec<String> = traces.iter().map(|t| name(&t.path)).collect();
    let tests = as_tests(&traces, &names)?;
    let board = args.inverse.board(file.board, &args.columns);
    let spec = args.inverse.spec(&args.columns, file.model.fs, &board)?;
    let compensator = pipeline::design_compensator(&CompensatorRequest {
        model: &file.model,
        effects: &file.effects,
        tests: &tests,
        roles: Roles::Alike,
        stored: file.inverse.as_ref(),
        spec: &spec,
        exportable: true,
    })?;
    let design = compensator.design?;
    warn_unplanned(&compensator.unplanned);
    let out = ModelFile {
        inverse: Some(design),
        board,
        ..file
    };
    out.save(&args.output)?;
    if args.json {
        let mut v = serde_json::to_value(&out.inverse).map_err(json_err)?;
        v["output"] = json!(name(&args.output));
        v["board"] = json!(out.board.arithmetic.as_str());
        v["full_scale"] = full_scale_json(&compensator.full_scale);
        crate::outln!("{v}");
        return Ok(());
    }
    if let Some(d) = &out.inverse {
        print_inverse(d, out.model.fs, out.board.unit);
    }
    print_board(&out.board, &compensator.full_scale);
    crate::outln!("wrote {}", args.output.display());
    Ok(())
}
