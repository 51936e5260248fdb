//! `unlag inspect` and `unlag resample`: what a model file says about the probe, and the same
//! model at another sample rate.
//!
//! Owns the printing of [`crate::fit::analysis::Analysis`] and [`crate::fit::continuous::Continuous`]
//! (tables for people, one JSON object with `--json`); the numbers come from those modules.

use std::path::PathBuf;

use clap::Args;
use serde_json::json;

use crate::error::{Error, Result};
use crate::file::ModelFile;
use crate::fit::analysis::{self, Analysis};
use crate::fit::continuous::{self, Continuous};
use crate::pipeline::{self, InspectRequest, ResampleRequest};
use crate::poly::{self, Complex};

/// Arguments of `unlag inspect`.
#[derive(Debug, Args)]
pub struct InspectArgs {
    /// The model file, or a coefficient blob from `unlag export --format bin` (read as the
    /// board reads it, to check it before flashing).
    #[arg(value_name = "MODEL.toml|BLOB.bin")]
    pub model: PathBuf,
    /// Print one JSON object instead of tables.
    #[arg(long)]
    pub json: bool,
    /// Frequencies (Hz) of the frequency-response table, comma-separated.
    #[arg(long, value_delimiter = ',', value_name = "F1,F2,...")]
    pub freqs: Vec<f64>,
    /// A linear grid of frequencies: START:STOP:N (Hz, N points). Without --freqs and --grid,
    /// 0 Hz and four points per decade from fs/1000 to fs/2.
    #[arg(long, value_name = "START:STOP:N")]
    pub grid: Option<String>,
}

/// Arguments of `unlag resample`.
#[derive(Debug, Args)]
pub struct ResampleArgs {
    /// The model file.
    #[arg(value_name = "MODEL.toml")]
    pub model: PathBuf,
    /// The new sample rate in Hz.
    #[arg(long, value_name = "HZ", allow_negative_numbers = true)]
    pub fs: f64,
    /// Where to write the resampled model file (written atomically).
    #[arg(short, long, value_name = "NEW.toml")]
    pub output: PathBuf,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
}

fn json_err(e: serde_json::Error) -> Error {
    Error::Serialise {
        what: "json",
        message: e.to_string(),
    }
}

/// Parses `START:STOP:N` into `N` evenly spaced frequencies.
/// Most frequencies a `--grid` may ask for.
const MAX_GRID: usize = 100_000;

fn parse_grid(text: &str) -> Result<Vec<f64>> {
    let bad = |why: &str| {
        Error::InvalidArgument {
        what: "--grid",
        message: format!("expected START:STOP:N (Hz, Hz, points) with 0 <= START < STOP and N >= 1, got '{text}': {why}"),
    }
    };
    let parts: Vec<&str> = text.split(':').collect();
    let [start, stop, n] = parts.as_slice() else {
        return Err(bad("three fields are needed"));
    };
    let start: f64 = start
        .trim()
        .parse()
        .map_err(|_| bad("START is not a number"))?;
    let stop: f64 = stop
        .trim()
        .parse()
        .map_err(|_| bad("STOP is not a number"))?;
    let n: usize = n
        .trim()
        .parse()
        .map_err(|_| bad("N is not a whole number"))?;
    if !(start.is_finite() && stop.is_finite() && start >= 0.0 && stop > start) {
        return Err(bad("the range is empty or not finite"));
    }
    match n {
        0 => Err(bad("N must be at least 1")),
        n if n > MAX_GRID => Err(bad(&format!("N may be at most {MAX_GRID}"))),
        1 => Ok(vec![start]),
        _ => Ok((0..n)
            .map(|k| start + (stop - start) * k as f64 / (n - 1) as f64)
            .collect()),
    }
}

/// The frequencies `--freqs` and `--grid` ask for, sorted; empty for the library's default.
fn frequencies(args: &InspectArgs) -> Result<Vec<f64>> {
    let mut f = args.freqs.clone();
    if let Some(g) = &args.grid {
        f.extend(parse_grid(g)?);
    }
    if let Some(bad) = f.iter().find(|v| !v.is_finite() || **v < 0.0) {
        return Err(Error::InvalidArgument {
            what: "--freqs",
            message: format!("frequencies must be finite and >= 0 Hz, got {bad}"),
        });
    }
    f.sort_by(f64::total_cmp);
    Ok(f)
}

fn response_rows(points: &[analysis::ResponsePoint]) -> Vec<serde_json::Value> {
    points
        .iter()
        .map(|p| {
            json!({
                "frequency_hz": p.frequency_hz,
                "magnitude": p.magnitude,
                "magnitude_db": p.magnitude_db,
                "phase_rad": p.phase_rad,
                "phase_deg": p.phase_deg,
            })
        })
        .collect()
}

/// `unlag inspect`: prints the analysis of a model file.
///
/// # Errors
/// The model file's errors (including an unstable model, named by its pole), an invalid
/// `--grid` or `--freqs`, or a numerical failure.
pub fn run_inspect(args: &InspectArgs) -> Result<()> {
    if let Some(bytes) = blob_bytes(&args.model)? {
        return inspect_blob(args, &bytes);
    }
    let file = ModelFile::load(&args.model)?;
    let name = args.model.display().to_string();
    let pipeline::Inspected {
        analysis,
        response,
        continuous: ct,
        stability,
    } = pipeline::inspect(&InspectRequest {
        file: &file,
        model_name: &name,
        frequencies_hz: &frequencies(args)?,
    })?;
    if args.json {
        let (continuous, why) = match &ct {
            Ok(c) => (serde_json::to_value(c).map_err(json_err)?, None),
            Err(e) => (serde_json::Value::Null, Some(e.to_string())),
        };
        let v = json!({
            "model": args.model.display().to_string(),
            "analysis": serde_json::to_value(&analysis).map_err(json_err)?,
            "continuous": continuous,
            "continuous_error": why,
            "frequency_response": response_rows(&response),
        });
        crate::outln!("{v}");
        // The analysis shows which pole is outside; the exit status says the model is unusable.
        return stability;
    }
    print_analysis(&name, &analysis);
    print_continuous(&ct, file.model.fs);
    crate::outln!("frequency response (the paper's eq. 6, delay included):");
    crate::outln!(
        "  {:>12} {:>12} {:>10} {:>12}",
        "f [Hz]",
        "magnitude",
        "dB",
        "phase [deg]"
    );
    for p in &response {
        crate::outln!(
            "  {:>12.3} {:>12.6} {:>10.3} {:>12.3}",
            p.frequency_hz,
            p.magnitude,
            p.magnitude_db,
            p.phase_deg
        );
    }
    stability
}

fn print_roots(what: &str, roots: &[analysis::Root]) {
    if roots.is_empty() {
        crate::outln!("{what}: none");
        return;
    }
    crate::outln!("{what} (largest |z| first):");
    for r in roots {
        crate::outln!(
            "  {:<32} |z| = {:.6}",
            poly::format_root(Complex::new(r.re, r.im)),
            r.magnitude
        );
    }
}

fn print_analysis(name: &str, a: &Analysis) {
    crate::outln!(
        "model {name}: order {}, fs {} Hz, delay {} samples ({})",
        a.order,
        a.sample_rate_hz,
        a.delay_samples,
        super::console::duration(a.delay_s)
    );
    print_roots("poles", &a.poles);
    print_roots("zeros of B", &a.zeros);
    crate::outln!(
        "stable: {}, margin {} (1 - max |pole|)",
        if a.stable { "yes" } else { "NO" },
        super::console::significant(a.stability_margin)
    );
    crate::outln!(
        "minimum phase: {}, margin {} (1 - max |zero|){}",
        if a.minimum_phase { "yes" } else { "no" },
        super::console::significant(a.minimum_phase_margin),
        if a.minimum_phase {
            ""
        } else {
            ": the paper's direct inverse A/B is unstable; use the stable inverse design"
        }
    );
    crate::outln!(
        "DC gain {:.6} ({:+.4} % from 1, the gain of a calibrated transducer)",
        a.dc_gain,
        100.0 * a.dc_gain_deviation
    );
    crate::outln!("modes (each real pole and complex pole pair):");
    for mode in &a.modes {
        crate::outln!("  {}", mode.description);
    }
    if a.resonances().next().is_none() {
        crate::outln!("  no resonance (no complex pole pair)");
    }
}

fn print_continuous(ct: &Result<Continuous>, fs: f64) {
    match ct {
        Err(e) => crate::outln!("continuous-time equivalent: none ({e})"),
        Ok(c) => {
            crate::outln!("continuous-time equivalent (step invariant, H(s) = (D + sum r/(s - s_i)) e^(-s tau)):");
            crate::outln!(
                "  delay tau = {} = {} samples ({}), feedthrough D = {}",
                super::console::duration(c.delay_s),
                super::console::significant(c.delay_s * fs),
                match c.delay_found {
                    continuous::DelayFound::ZeroCrossing => "where the step response crosses zero",
                    continuous::DelayFound::MinimumOfResponse =>
                        "no zero crossing: where the step response is smallest; the rest is D",
                    continuous::DelayFound::NoDelay => "no delay",
                },
                super::console::significant(c.feedthrough)
            );
            for (s, r) in c.poles.iter().zip(&c.residues) {
                let (fn_hz, zeta) = (
                    s.magnitude / (2.0 * std::f64::consts::PI),
                    -s.re / s.magnitude,
                );
                crate::outln!(
                    "  pole s = {:<36} fn {fn_hz:>12.4} Hz, damping {zeta:>9.6}, residue {}",
                    poly::format_root(Complex::new(s.re, s.im)),
                    poly::format_root(Complex::new(r.re, r.im))
                );
            }
        }
    }
}

/// `unlag resample`: the model file at another sample rate ([`pipeline::resample`]), written
/// atomically, and what changed printed.
///
/// The fit report and sources are kept (they describe where the model came from); a
/// compensator designed at the old rate is dropped, because its coefficients belong to that
/// rate: run `unlag invert` on the new file.
///
/// # Errors
/// An invalid `--fs`, the model file's errors, a model without a continuous-time equivalent
/// (named by its pole), or the output file's.
pub fn run_resample(args: &ResampleArgs) -> Result<()> {
    // The rate is checked before the model file is read, as a parsed argument.
    pipeline::check_sample_rate(args.fs)?;
    let file = ModelFile::load(&args.model)?;
    let r = pipeline::resample(&ResampleRequest {
        file: &file,
        model_path: &args.model,
        sample_rate_hz: args.fs,
    })?;
    r.file.save(&args.output)?;
    let (old, new, agreement) = (&file.model, &r.discretised, r.agreement);
    let vs_continuous = r.max_error_vs_continuous;
    if args.json {
        let v = json!({
            "output": args.output.display().to_string(),
            "from_hz": old.fs,
            "to_hz": args.fs,
            "old_delay_samples": old.delay,
            "new_delay_samples": new.delay_samples,
            "delay_s": new.delay_s,
            "delay_in_samples": new.delay_in_samples,
            "delay_note": new.delay_note,
            "step_agreement": serde_json::to_value(agreement).map_err(json_err)?,
            "max_error_vs_continuous": vs_continuous,
            "continuous": serde_json::to_value(&r.continuous).map_err(json_err)?,
            "model": serde_json::to_value(&new.model).map_err(json_err)?,
            "warnings": new.warnings,
            "dropped_inverse": r.dropped_inverse,
        });
        crate::outln!("{v}");
        return Ok(());
    }
    crate::outln!(
        "resampled {} from {} Hz to {} Hz (step invariant, through the continuous-time equivalent)",
        args.model.display(),
        old.fs,
        args.fs
    );
    crate::outln!(
        "  delay: {} samples ({:.9} s) at {} Hz -> {} samples ({:.9} s) at {} Hz",
        old.delay,
        old.delay as f64 / old.fs,
        old.fs,
        new.delay_samples,
        new.delay_samples as f64 / args.fs,
        args.fs
    );
    crate::outln!(
        "  fractional delay tau = {:.9} s ({:.6} samples at the new rate)",
        new.delay_s,
        new.delay_in_samples
    );
    crate::outln!("  {}", new.delay_note);
    if agreement.instants > 1 {
        crate::outln!(
            "  step response, old against new at {} common sample instants: max error {:.3e}, RMS {:.3e} (fractions of the step)",
            agreement.instants, agreement.max_error, agreement.rms_error
        );
    } else {
        crate::outln!("  the two rates share no sample instants after t = 0: compared with the continuous step response only");
    }
    crate::outln!(
        "  step response of the new model against the continuous one: max error {vs_continuous:.3e} of the step"
    );
    for w in &new.warnings {
        crate::outln!("  warning: {w}");
    }
    if r.dropped_inverse {
        crate::outln!(
            "  the compensator designed at {} Hz was not carried over: run `unlag invert` on the new file",
            old.fs
        );
    }
    crate::outln!("wrote {}", args.output.display());
    Ok(())
}

/// The file's bytes when it is a coefficient blob (it starts with the blob's magic, or is
/// named `.bin`), else `None`.
fn blob_bytes(path: &std::path::Path) -> Result<Option<Vec<u8>>> {
    use std::io::Read as _;
    let io = |source| Error::Io {
        path: path.to_path_buf(),
        action: "cannot read",
        source,
    };
    let mut f = std::fs::File::open(path).map_err(io)?;
    let mut head = [0u8; 4];
    let n = f.read(&mut head).map_err(io)?;
    let named_bin = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("bin"));
    if head.get(..n) != Some(&crate::board::blob::MAGIC[..]) && !named_bin {
        return Ok(None);
    }
    // A blob is small: read at most a little more than the largest one.
    let limit = crate::board::blob::encoded_len_fixed(crate::board::blob::MAX_SECTIONS) as u64 + 1;
    let mut bytes = head.get(..n).unwrap_or_default().to_vec();
    f.take(limit).read_to_end(&mut bytes).map_err(io)?;
    Ok(Some(bytes))
}

/// `unlag inspect BLOB.bin`: the board parser's verdict and what the blob holds.
fn inspect_blob(args: &InspectArgs, bytes: &[u8]) -> Result<()> {
    let s = crate::export::verify::read(bytes).map_err(|error| Error::Blob {
        path: args.model.clone(),
        error,
    })?;
    if args.json {
        let v = json!({
            "blob": args.model.display().to_string(),
            "valid": true,
            "contents": serde_json::to_value(&s).map_err(json_err)?,
        });
        crate::outln!("{v}");
        return Ok(());
    }
    crate::outln!(
        "{}: a valid coefficient blob (the board's parser accepts it; CRC-32 {:08x} matches)",
        args.model.display(),
        s.crc32
    );
    crate::outln!(
        "  format version {}, {} bytes, number format {}{}",
        s.format_version,
        s.bytes,
        s.number_format,
        if s.nonlinear {
            ", with the nonlinear-damping correction"
        } else {
            ""
        }
    );
    crate::outln!(
        "  sample rate {} Hz, model delay {} samples ({}), {} sections ({} multiply-adds per sample)",
        s.sample_rate_hz,
        s.delay_samples,
        super::console::duration(f64::from(s.delay_samples) / s.sample_rate_hz),
        s.sections,
        5 * s.sections + 1
    );
    if let (Some(full_scale), Some(exp)) = (s.full_scale, s.output_exponent) {
        crate::outln!(
            "  ADC full scale {}, output Q1.31 of full scale x 2^{exp}",
            super::console::significant(full_scale)
        );
    }
    if let (Some(gain), Some(dc)) = (s.gain, s.dc_gain) {
        crate::outln!("  input gain {gain:.7}, steady-state gain of the cascade {dc:.6}");
        crate::outln!(
            "  {:>3} {:>13} {:>13} {:>13} {:>13} {:>13} {:>8}",
            "#",
            "b0",
            "b1",
            "b2",
            "a1",
            "a2",
            "|pole|"
        );
        for (i, (c, r)) in s.coefficients.iter().zip(&s.pole_radius).enumerate() {
            crate::outln!(
                "  {i:>3} {:>13.6e} {:>13.6e} {:>13.6e} {:>13.6e} {:>13.6e} {r:>8.5}",
                c[0],
                c[1],
                c[2],
                c[3],
                c[4]
            );
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grids() {
        assert_eq!(parse_grid("0:10:3").unwrap(), vec![0.0, 5.0, 10.0]);
        assert_eq!(parse_grid("5:10:1").unwrap(), vec![5.0]);
        for bad in [
            "", "1:2", "1:2:3:4", "x:2:3", "2:1:3", "0:1:0", "-1:1:3", "0:inf:3",
        ] {
            let e = parse_grid(bad).unwrap_err().to_string();
            assert!(e.contains("--grid"), "{bad}: {e}");
        }
    }
}
