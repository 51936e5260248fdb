//! A bank of drawn step tests, run through the `unlag` binary as a new user would (issue 13,
//! items 4-5: "a bank that is not the generator's echo").
//!
//! This example owns the bank: it draws at least 120 cases from a seed (three probe families,
//! every hidden-effect kind and none, two generators), writes each case's estimation and
//! validation tests and its true model into `target/bank/case-NNN/`, runs `unlag fit`,
//! `unlag compensate`, and the oracle (`unlag invert` on the true model, then
//! `unlag compensate`), and prints per family and per kind how much better than the raw probe
//! the compensated signal is, and how close to the oracle. `target/bank/results.csv` has one
//! row per case with every drawn parameter and every error.
//!
//! ```sh
//! cargo build --release --bin unlag
//! cargo run --release --example bench_bank                 # --seed N --cases N --unlag PATH
//! ```
//!
//! * Families: (a) pneumatic lines at 5-10 kHz, 20-150 Hz, damping 0.1-1.5; (b) flush or
//!   recessed sensors (hole and cavity) at 1 MHz, 30-120 kHz; (c) overdamped capillaries.
//! * Generators: a lumped second-order line with the effect's stages, simulated by RK4 with
//!   the input held between samples, whose true model is the exact zero-order-hold
//!   discretisation (matrix exponential; nonlinear damping: its linear part; a diaphragm on
//!   both channels cancels from reference to probe); or the physics module's Bergh-Tijdeman
//!   lines and cavities, whose "true" model is what `unlag fit` finds on a long noise-free
//!   estimation test (written by the CLI).
//! * Both channels carry white noise (0.1-0.5 % of the step) and a 16-bit ADC over 2.5 steps
//!   (wider only where a ringing probe or a drift would clip, as an experimenter would set it).
//!   The estimation test is a step; the validation test another step, a balloon, a valve or a
//!   wake traverse with a tunnel oscillation.
//! * A command that fails is a row with its first stderr line, counted, never dropped.

#[path = "bench_bank/draw.rs"]
mod draw;
#[path = "bench_bank/modelling_loop.rs"]
mod modelling_loop;
#[path = "bench_bank/simulate.rs"]
mod simulate;

use std::error::Error;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::Instant;

use draw::{Case, Effect, Generator, Kind, Rng, FAMILIES, KINDS, REFERENCE_K};

/// Command-line settings.
struct Settings {
    seed: u64,
    cases: usize,
    threads: usize,
    unlag: PathBuf,
    out: PathBuf,
    /// The modelling loop instead of the reconstruction.
    modelling_loop: bool,
}

fn settings() -> Result<Settings, Box<dyn Error>> {
    let mut seed = 13;
    let mut cases = 126;
    let mut threads = 2;
    let mut unlag = None;
    let mut out = PathBuf::from("target/bank");
    let mut modelling_loop = false;
    let mut args = std::env::args().skip(1);
    while let Some(flag) = args.next() {
        let mut value = || args.next().ok_or_else(|| format!("{flag} needs a value"));
        match flag.as_str() {
            "--seed" => seed = value()?.parse()?,
            "--cases" => cases = value()?.parse()?,
            "--threads" => threads = value()?.parse::<usize>()?.clamp(1, 2),
            "--unlag" => unlag = Some(PathBuf::from(value()?)),
            "--out" => out = PathBuf::from(value()?),
            "--loop" => modelling_loop = true,
            "-h" | "--help" => {
                println!("cargo run --release --example bench_bank -- [--seed N] [--cases N] [--threads 1|2] [--unlag PATH] [--out DIR] [--loop]");
                std::process::exit(0);
            }
            other => return Err(format!("unknown argument {other} (try --help)").into()),
        }
    }
    let unlag = match unlag {
        Some(p) => p,
        None => {
            let target = std::env::var_os("CARGO_TARGET_DIR")
                .map_or_else(|| PathBuf::from("target"), PathBuf::from);
            target.join("release").join("unlag")
        }
    };
    if !unlag.is_file() {
        return Err(format!(
            "no unlag binary at {}: run `cargo build --release --bin unlag` or pass --unlag PATH",
            unlag.display()
        )
        .into());
    }
    // The commands run inside each case's folder: the binary's path must not be relative.
    let unlag = unlag.canonicalize()?;
    Ok(Settings {
        seed,
        cases,
        threads,
        unlag,
        out,
        modelling_loop,
    })
}

/// What one case gave.
#[derive(Debug, Default, Clone)]
struct Outcome {
    /// Validation error of the raw probe (the CLI's, best alignment).
    raw: Option<f64>,
    /// ... of the compensated signal.
    comp: Option<f64>,
    /// ... of the oracle (the same design on the true model).
    oracle: Option<f64>,
    /// `unlag compensate` said the compensated signal is worse (its `verdict`, with a warning).
    said_worse: bool,
    /// The user's remedy: the compensator redesigned with `--signal` from another run of the
    /// validation's kind (`run.csv`, never the validation test itself), on the validation test.
    remedy: Option<f64>,
    /// The check given a held-out run: `unlag fit est.csv run.csv`, where `run.csv` is another
    /// run of the validation's kind, then `compensate` on the validation test: `(raw, comp)`,
    /// the raw probe's error as that `compensate` gives it (its lags depend on the model's
    /// delay, which the held-out run may move).
    held: Option<(f64, f64)>,
    /// The same with the prior learnt from that run too (`--signal run.csv`).
    held_signal: Option<(f64, f64)>,
    /// The failed step of the user's pipeline and its first stderr line.
    failure: Option<String>,
    /// The failed step of the oracle's pipeline.
    oracle_failure: Option<String>,
    /// Lumped cases: largest difference between the truth model's and RK4's noise-free
    /// estimation test, relative to the step (checks the discretisation).
    truth_check: Option<f64>,
    /// Physics cases: the truth fit's nrmse on its noise-free test.
    truth_fit: Option<f64>,
    /// The same three errors against the validation test's noise-free reference (what the
    /// reference sensor would read without its noise and ADC): `(raw, comp, oracle)`.
    clean: (Option<f64>, Option<f64>, Option<f64>),
    /// ADC full scale, in steps.
    adc_steps: f64,
    /// Order and delay of the fitted model.
    fitted: Option<(usize, usize)>,
    /// Wall time [s].
    seconds: f64,
}

/// Runs `unlag ARGS` in `dir`, stdout saved to `log`; `Err(step: first stderr line)`.
fn unlag(unlag: &Path, dir: &Path, args: &[&str], log: &str) -> Result<String, String> {
    let out = Command::new(unlag)
        .args(args)
        .current_dir(dir)
        .output()
        .map_err(|e| format!("{}: cannot run {}: {e}", args[0], unlag.display()))?;
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    let stderr = String::from_utf8_lossy(&out.stderr);
    let _ = std::fs::write(dir.join(log), format!("{stdout}\n--- stderr ---\n{stderr}"));
    if out.status.success() {
        Ok(stdout)
    } else {
        let line = stderr
            .lines()
            .map(str::trim)
            .find(|l| !l.is_empty())
            .unwrap_or("(no message)");
        Err(format!(
            "{} exit {}: {line}",
            args[0],
            out.status.code().unwrap_or(-1)
        ))
    }
}

/// What `unlag compensate ... --json` says of a run.
struct Verdict {
    /// `nrmse_u_hat`.
    comp: f64,
    /// `nrmse_raw`.
    raw: f64,
    /// Its `verdict` is "worse".
    worse: bool,
    /// The lag it aligned `u_hat` at (`alignment_samples`, 0 if it says none).
    lag: usize,
}

/// The [`Verdict`] in the JSON of `unlag compensate ... --json`.
fn verdict(json: &str) -> Result<Verdict, String> {
    let v: serde_json::Value = serde_json::from_str(json.trim())
        .map_err(|e| format!("compensate: unreadable JSON ({e})"))?;
    let get = |k: &str| {
        v.get(k)
            .and_then(serde_json::Value::as_f64)
            .ok_or_else(|| format!("compensate: no {k} in the JSON"))
    };
    Ok(Verdict {
        comp: get("nrmse_u_hat")?,
        raw: get("nrmse_raw")?,
        worse: v.get("verdict").and_then(serde_json::Value::as_str) == Some("worse"),
        lag: v
            .get("alignment_samples")
            .and_then(serde_json::Value::as_u64)
            .map_or(0, |a| a as usize),
    })
}

/// `(raw, comp)` errors of a `compensate` output (`t,u,y,u_hat`) against the noise-free
/// reference `clean`, RMS over the range of `clean`: the reconstruction judged without the
/// reference sensor's own noise. Each at its best alignment over lags like the CLI's:
/// `u_hat` within 4 samples of the lag the CLI found (`alignment`), the raw probe from 0 to
/// `alignment + 4 max(alignment, 10)`.
fn against_clean(clean: &[f64], out: &Path, alignment: usize) -> Result<(f64, f64), String> {
    let columns = unlag::trace::Columns {
        input: "u_hat".into(),
        ..unlag::trace::Columns::default()
    };
    let trace = unlag::trace::Trace::read(out, &columns).map_err(|e| e.to_string())?;
    let (y, u_hat) = (&trace.y, trace.u.as_deref().unwrap_or_default());
    let raw_lags = 0..=alignment + 4 * alignment.max(10);
    let lags = alignment.saturating_sub(4)..=alignment + 4;
    let (raw, _) = unlag::design::inverse::aligned_error(clean, y, raw_lags);
    let (comp, _) = unlag::design::inverse::aligned_error(clean, u_hat, lags);
    Ok((raw, comp))
}

/// Order and delay of a model file (read as TOML text, enough for the report).
fn order_delay(path: &Path) -> Option<(usize, usize)> {
    let text = std::fs::read_to_string(path).ok()?;
    let mut delay = None;
    let mut order = None;
    for line in text.lines() {
        if let Some(v) = line.strip_prefix("delay = ") {
            delay = v.trim().parse().ok();
        }
        if let Some(v) = line.strip_prefix("a = [") {
            order = Some(
                v.split(',')
                    .filter(|s| !s.trim().trim_end_matches(']').is_empty())
                    .count(),
            );
        }
        if delay.is_some() && order.is_some() {
            break;
        }
    }
    Some((order?, delay?))
}

/// The estimation nrmse `unlag fit` prints (`  estimation FILE nrmse X % ...`), as a fraction.
fn fitted_nrmse(text: &str) -> Option<f64> {
    let line = text
        .lines()
        .find(|l| l.trim_start().starts_with("estimation") && l.contains("nrmse"))?;
    let mut words = line
        .split_whitespace()
        .skip_while(|w| *w != "nrmse")
        .skip(1);
    words.next()?.parse::<f64>().ok().map(|p| p / 100.0)
}

/// Makes the case's files and runs the pipeline.
fn run_case(case: &Case, s: &Settings) -> Outcome {
    let start = Instant::now();
    let mut o = Outcome::default();
    let dir = s.out.join(format!("case-{:03}", case.id));
    let clean_u = match make_files(case, &dir, &s.unlag, &mut o) {
        Ok(u) => u,
        Err(e) => {
            o.failure = Some(format!("simulation: {e}"));
            o.seconds = start.elapsed().as_secs_f64();
            return o;
        }
    };
    let user = unlag(
        &s.unlag,
        &dir,
        &["fit", "est.csv", "-o", "model.toml"],
        "fit.log",
    )
    .and_then(|_| {
        unlag(
            &s.unlag,
            &dir,
            &[
                "compensate",
                "model.toml",
                "val.csv",
                "-o",
                "out.csv",
                "--json",
            ],
            "compensate.log",
        )
    })
    .and_then(|json| verdict(&json));
    match user {
        Ok(v) => {
            o.comp = Some(v.comp);
            o.raw = Some(v.raw);
            o.said_worse = v.worse;
            if let Ok((raw, comp)) = against_clean(&clean_u, &dir.join("out.csv"), v.lag) {
                o.clean.0 = Some(raw);
                o.clean.1 = Some(comp);
            }
        }
        Err(e) => o.failure = Some(e),
    }
    if o.failure.is_none() {
        // The remedy a user is told about: the signal learnt from a run of the same kind.
        let remedy = unlag(
            &s.unlag,
            &dir,
            &[
                "invert",
                "model.toml",
                "est.csv",
                "--signal",
                "run.csv",
                "-o",
                "remedy.toml",
            ],
            "remedy.log",
        )
        .and_then(|_| {
            unlag(
                &s.unlag,
                &dir,
                &[
                    "compensate",
                    "remedy.toml",
                    "val.csv",
                    "-o",
                    "r.csv",
                    "--json",
                ],
                "remedy-compensate.log",
            )
        })
        .and_then(|json| verdict(&json));
        o.remedy = remedy.ok().map(|v| v.comp);
        // A user who has such a run gives it to `fit` as a held-out test: the check judges
        // the compensator on it (and the order search sees it).
        let held = |extra: &[&str], model: &str, tag: &str| {
            let mut fit = vec!["fit", "est.csv", "run.csv", "-o", model];
            fit.extend_from_slice(extra);
            unlag(&s.unlag, &dir, &fit, &format!("{tag}.log"))
                .and_then(|_| {
                    unlag(
                        &s.unlag,
                        &dir,
                        &[
                            "compensate",
                            model,
                            "val.csv",
                            "-o",
                            &format!("{tag}.csv"),
                            "--json",
                        ],
                        &format!("{tag}-compensate.log"),
                    )
                })
                .and_then(|json| verdict(&json))
                .ok()
                .map(|v| (v.raw, v.comp))
        };
        o.held = held(&[], "held.toml", "held");
        o.held_signal = held(&["--signal", "run.csv"], "held-signal.toml", "held-signal");
    }
    o.fitted = order_delay(&dir.join("model.toml"));
    if dir.join("truth.toml").is_file() {
        let oracle = unlag(
            &s.unlag,
            &dir,
            &["invert", "truth.toml", "est.csv", "-o", "oracle.toml"],
            "invert.log",
        )
        .and_then(|_| {
            unlag(
                &s.unlag,
                &dir,
                &[
                    "compensate",
                    "oracle.toml",
                    "val.csv",
                    "-o",
                    "o.csv",
                    "--json",
                ],
                "oracle.log",
            )
        })
        .and_then(|json| verdict(&json));
        match oracle {
            Ok(v) => {
                o.oracle = Some(v.comp);
                o.raw = o.raw.or(Some(v.raw));
                o.clean.2 = against_clean(&clean_u, &dir.join("o.csv"), v.lag)
                    .ok()
                    .map(|(_, e)| e);
            }
            Err(e) => o.oracle_failure = Some(e),
        }
    } else if o.oracle_failure.is_none() {
        o.oracle_failure = Some("no truth model".into());
    }
    o.seconds = start.elapsed().as_secs_f64();
    o
}

/// Writes `est.csv`, `val.csv` and `truth.toml` (a physics case: by `unlag fit` on a long
/// noise-free estimation test; its failure is an oracle failure).
/// Returns the validation test's noise-free reference.
fn make_files(case: &Case, dir: &Path, bin: &Path, o: &mut Outcome) -> Result<Vec<f64>, String> {
    std::fs::create_dir_all(dir).map_err(|e| format!("cannot create {}: {e}", dir.display()))?;
    let mut rng = Rng::new(case.seed);
    let val_k = match case.effect {
        Effect::Temperature { kelvin } => kelvin,
        _ => REFERENCE_K,
    };
    let (u, y) = simulate::clean(case, &case.est, REFERENCE_K)?;
    let (mut um, mut ym) = simulate::measured(case, &u, &y, &mut rng);
    let (uv, yv) = simulate::clean(case, &case.val, val_k)?;
    let (mut uvm, mut yvm) = simulate::measured(case, &uv, &yv, &mut rng);
    let adc = simulate::adc_for(case, &[&um, &ym, &uvm, &yvm]);
    o.adc_steps = (adc.max_pa - adc.min_pa) / case.step_pa;
    // Another run of the validation's kind (its own draw, on the same ADC), from which the
    // remedy learns the signal: drawn after the bank's tests so that they stay as they were.
    let mut sibling_rng = Rng::new(case.seed ^ 0x5eed_0f5e_ed0f_5eed);
    let sibling = draw::sibling(&case.val, &mut sibling_rng);
    let (us, ys) = simulate::clean(case, &sibling, val_k)?;
    let (mut usm, mut ysm) = simulate::measured(case, &us, &ys, &mut sibling_rng);
    for c in [&mut um, &mut ym, &mut uvm, &mut yvm, &mut usm, &mut ysm] {
        c.iter_mut().for_each(|v| *v = adc.quantise(*v));
    }
    simulate::write_csv(&dir.join("est.csv"), case.fs, &um, &ym)?;
    simulate::write_csv(&dir.join("val.csv"), case.fs, &uvm, &yvm)?;
    simulate::write_csv(&dir.join("run.csv"), case.fs, &usm, &ysm)?;
    let truth = dir.join("truth.toml");
    let _ = std::fs::remove_file(&truth);
    match case.generator {
        Generator::Lumped { .. } => {
            let (stages, delay) = simulate::lumped_stages(case, REFERENCE_K, false);
            let model = simulate::StateSpace::cascade(&stages).zoh(case.fs, delay);
            simulate::write_model(&truth, case.fs, &model)?;
            // The truth against RK4 on the noise-free estimation test (not with nonlinear
            // damping, whose truth is only the linear part, nor with a diaphragm, whose
            // reference is no longer held between samples).
            if !matches!(case.kind, Kind::NonlinearDamping | Kind::SensorResonance) {
                let y_model = simulate::filter_model(&model, &u);
                o.truth_check = Some(simulate::max_difference(&y_model, &y, case.step_pa));
            }
        }
        Generator::Physics { .. } => {
            let long = draw::Test {
                n: (2 * case.est.n).min(30_000),
                ..case.est
            };
            let (u, y) = simulate::clean(case, &long, REFERENCE_K)?;
            simulate::write_csv(&dir.join("truth_est.csv"), case.fs, &u, &y)?;
            let fit = ["fit", "truth_est.csv", "-o", "truth.toml"];
            match unlag(bin, dir, &fit, "truth.log") {
                Ok(text) => o.truth_fit = fitted_nrmse(&text),
                Err(e) => o.oracle_failure = Some(format!("truth {e}")),
            }
        }
    }
    Ok(uv)
}

/// Median and smallest and largest of `v`.
fn stats(mut v: Vec<f64>) -> Option<(f64, f64, f64)> {
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    let n = v.len();
    let median = if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    };
    Some((median, v[0], v[n - 1]))
}

/// A raw/comp ratio that counts as worse than the raw probe. A compensator that passes the
/// probe through unchanged (the check's last fall-back) differs from it by the board's f32
/// rounding alone, some 1e-8 of the error: that is a tie, not a loss.
fn is_worse(raw_over_comp: f64) -> bool {
    raw_over_comp < 1.0 - 1e-6
}

/// One Markdown row of the summary for `rows`.
fn summary_row(name: &str, rows: &[&(Case, Outcome)]) -> String {
    let gain: Vec<f64> = rows
        .iter()
        .filter_map(|(_, o)| Some(o.raw? / o.comp?))
        .collect();
    let vs_oracle: Vec<f64> = rows
        .iter()
        .filter_map(|(_, o)| Some(o.comp? / o.oracle?))
        .collect();
    let failed = rows.iter().filter(|(_, o)| o.failure.is_some()).count();
    let no_oracle = rows
        .iter()
        .filter(|(_, o)| o.failure.is_none() && o.oracle.is_none())
        .count();
    let worse = gain.iter().filter(|g| is_worse(**g)).count();
    let silent = rows
        .iter()
        .filter(|(_, o)| {
            matches!((o.raw, o.comp), (Some(r), Some(e)) if is_worse(r / e)) && !o.said_worse
        })
        .count();
    let remedy: Vec<f64> = rows
        .iter()
        .filter_map(|(_, o)| Some(o.raw? / o.remedy?))
        .collect();
    let remedy_worse = remedy.iter().filter(|g| is_worse(**g)).count();
    let (rm, rw) = stats(remedy).map_or(("-".into(), "-".into()), |(m, lo, _)| {
        (format!("{m:.2}"), format!("{lo:.2}"))
    });
    let three = |f: &dyn Fn(&Outcome) -> Option<(f64, f64)>| {
        let g: Vec<f64> = rows
            .iter()
            .filter_map(|(_, o)| f(o).map(|(raw, comp)| raw / comp))
            .collect();
        let w = g.iter().filter(|g| is_worse(**g)).count();
        stats(g).map_or("- | - | -".into(), |(m, lo, _)| {
            format!("{m:.2} | {lo:.2} | {w}")
        })
    };
    let held = three(&|o| o.held);
    let held_signal = three(&|o| o.held_signal);
    let (gm, gw) = stats(gain).map_or(("-".into(), "-".into()), |(m, lo, _)| {
        (format!("{m:.2}"), format!("{lo:.2}"))
    });
    let (om, ow) = stats(vs_oracle).map_or(("-".into(), "-".into()), |(m, _, hi)| {
        (format!("{m:.2}"), format!("{hi:.2}"))
    });
    format!(
        "| {name} | {} | {failed} | {no_oracle} | {gm} | {gw} | {worse} | {silent} | {om} | {ow} | {rm} | {rw} | {remedy_worse} | {held} | {held_signal} |",
        rows.len()
    )
}

/// One Markdown row of the noise-free-reference summary for `rows`.
fn clean_row(name: &str, rows: &[&(Case, Outcome)]) -> String {
    let ratio = |f: &dyn Fn(&Outcome) -> Option<f64>| -> Vec<f64> {
        rows.iter().filter_map(|(_, o)| f(o)).collect()
    };
    let gain = ratio(&|o| Some(o.clean.0? / o.clean.1?));
    let oracle_gain = ratio(&|o| Some(o.clean.0? / o.clean.2?));
    let vs_oracle = ratio(&|o| Some(o.clean.1? / o.clean.2?));
    let worse = gain.iter().filter(|g| is_worse(**g)).count();
    let oracle_worse = oracle_gain.iter().filter(|g| is_worse(**g)).count();
    let two = |v: Vec<f64>, worst_low: bool| {
        stats(v).map_or("- | -".into(), |(m, lo, hi)| {
            format!("{m:.2} | {:.2}", if worst_low { lo } else { hi })
        })
    };
    format!(
        "| {name} | {} | {} | {worse} | {} | {oracle_worse} | {} |",
        gain.len(),
        two(gain, true),
        two(oracle_gain, true),
        two(vs_oracle, false),
    )
}

fn csv_field(s: &str) -> String {
    if s.contains([',', '"']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

fn opt(v: Option<f64>) -> String {
    v.map_or(String::new(), |x| format!("{x:.6e}"))
}

/// `results.csv`: one row per case.
fn write_results(path: &Path, rows: &[(Case, Outcome)]) -> Result<(), Box<dyn Error>> {
    let mut s = String::from(
        "id,family,generator,kind,effect,probe,f_hz,zeta,delay,fs,n_est,n_val,step_pa,noise_u,noise_y,adc_steps,est,val_kind,val,\
         nrmse_raw,nrmse_comp,nrmse_oracle,nrmse_remedy,nrmse_held,nrmse_held_raw,nrmse_held_signal,nrmse_held_signal_raw,clean_raw,clean_comp,clean_oracle,said_worse,raw_over_comp,comp_over_oracle,fitted_order,fitted_delay,truth_check,truth_fit_nrmse,seconds,failure,oracle_failure\n",
    );
    for (c, o) in rows {
        let delay = match c.generator {
            Generator::Lumped { delay, .. } => delay.to_string(),
            Generator::Physics { .. } => String::new(),
        };
        let fields = [
            c.id.to_string(),
            c.family.name().into(),
            c.generator_name().into(),
            c.kind.name().into(),
            c.effect.describe(),
            c.probe_text(),
            format!("{:.6e}", c.f_hz),
            format!("{:.6e}", c.zeta),
            delay,
            format!("{}", c.fs),
            c.est.n.to_string(),
            c.val.n.to_string(),
            format!("{:.3}", c.step_pa),
            format!("{:.6e}", c.noise_u),
            format!("{:.6e}", c.noise_y),
            format!("{:.3}", o.adc_steps),
            c.est.describe(),
            c.val.name.into(),
            c.val.describe(),
            opt(o.raw),
            opt(o.comp),
            opt(o.oracle),
            opt(o.remedy),
            opt(o.held.map(|h| h.1)),
            opt(o.held.map(|h| h.0)),
            opt(o.held_signal.map(|h| h.1)),
            opt(o.held_signal.map(|h| h.0)),
            opt(o.clean.0),
            opt(o.clean.1),
            opt(o.clean.2),
            o.said_worse.to_string(),
            opt(o.raw.zip(o.comp).map(|(r, e)| r / e)),
            opt(o.comp.zip(o.oracle).map(|(e, q)| e / q)),
            o.fitted.map_or(String::new(), |f| f.0.to_string()),
            o.fitted.map_or(String::new(), |f| f.1.to_string()),
            opt(o.truth_check),
            opt(o.truth_fit),
            format!("{:.2}", o.seconds),
            o.failure.clone().unwrap_or_default(),
            o.oracle_failure.clone().unwrap_or_default(),
        ];
        let line: Vec<String> = fields.iter().map(|f| csv_field(f)).collect();
        s.push_str(&line.join(","));
        s.push('\n');
    }
    std::fs::write(path, s).map_err(|e| format!("cannot write {}: {e}", path.display()))?;
    Ok(())
}

/// One `row` per family, per kind, per generator (when `generators`) and for the whole bank.
fn groups(
    rows: &[(Case, Outcome)],
    row: fn(&str, &[&(Case, Outcome)]) -> String,
    generators: bool,
) -> String {
    let of = |keep: &dyn Fn(&Case) -> bool| -> Vec<&(Case, Outcome)> {
        rows.iter().filter(|(c, _)| keep(c)).collect()
    };
    let mut lines: Vec<String> = Vec::new();
    for f in FAMILIES {
        lines.push(row(
            &format!("family {}", f.name()),
            &of(&|c| c.family == f),
        ));
    }
    for k in KINDS {
        lines.push(row(&format!("kind {}", k.name()), &of(&|c| c.kind == k)));
    }
    if generators {
        for gen in ["lumped", "physics"] {
            lines.push(row(
                &format!("generator {gen}"),
                &of(&|c| c.generator_name() == gen),
            ));
        }
    }
    lines.push(row("**all**", &of(&|_| true)));
    lines.iter().map(|l| format!("{l}\n")).collect()
}

/// The printed report.
fn report(rows: &[(Case, Outcome)], s: &Settings, seconds: f64) -> String {
    let mut r = String::new();
    let _ = writeln!(
        r,
        "## Bank: {} drawn cases, seed {}, {} ({:.0} s on {} threads)\n",
        rows.len(),
        s.seed,
        s.unlag.display(),
        seconds,
        s.threads
    );
    let _ = writeln!(r, "Errors are the CLI's `nrmse` on the validation test (RMS / range of the reference, best alignment). raw/comp above 1: the compensated signal is better than the raw probe; worst is the smallest. comp/oracle: the user's pipeline against the same design on the true model; worst is the largest.\n");
    let _ = writeln!(r, "Targets: never worse than raw anywhere (raw/comp >= 1 in every case); median raw/comp >= 3; median comp/oracle <= 1.5.\n");
    let _ = writeln!(r, "The last three columns are the remedy `compensate` names when it finds a run worse: the compensator redesigned with `unlag invert model.toml est.csv --signal run.csv`, where `run.csv` is another run of the validation test's kind (its own draw), then run on the validation test. *silent* counts runs worse than raw that `compensate` did not flag. *held-out*: the check given that run as a held-out test (`unlag fit est.csv run.csv`), then `compensate` on the validation test, each against the raw probe's error as its own `compensate` gives it; *held-out + --signal*: the same with `--signal run.csv`. A ratio within 1e-6 of 1 (the raw probe passed through) is a tie, not worse.\n");
    let _ = writeln!(r, "| group | cases | failed | no oracle | raw/comp median | raw/comp worst | worse than raw | silent | comp/oracle median | comp/oracle worst | --signal raw/comp median | --signal worst | --signal worse | held-out raw/comp median | held-out worst | held-out worse | held-out + --signal median | held-out + --signal worst | held-out + --signal worse |");
    let _ = writeln!(
        r,
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"
    );
    r.push_str(&groups(rows, summary_row, true));
    let _ = writeln!(r, "\nAgainst the noise-free reference (the reference channel without its noise and ADC, which the CLI's figure above includes): raw/comp, and the oracle's raw/oracle, each at its best alignment.\n");
    let _ = writeln!(r, "| group | cases | raw/comp median | raw/comp worst | worse than raw | raw/oracle median | raw/oracle worst | oracle worse than raw | comp/oracle median | comp/oracle worst |");
    let _ = writeln!(r, "|---|---|---|---|---|---|---|---|---|---|");
    r.push_str(&groups(rows, clean_row, false));
    let gains: Vec<f64> = rows
        .iter()
        .filter_map(|(_, o)| Some(o.raw? / o.comp?))
        .collect();
    let ratios: Vec<f64> = rows
        .iter()
        .filter_map(|(_, o)| Some(o.comp? / o.oracle?))
        .collect();
    let failed = rows.iter().filter(|(_, o)| o.failure.is_some()).count();
    let worse: Vec<&(Case, Outcome)> = rows
        .iter()
        .filter(|(_, o)| matches!((o.raw, o.comp), (Some(r), Some(e)) if is_worse(r / e)))
        .collect();
    let verdict = |ok: bool| if ok { "met" } else { "NOT met" };
    let _ = writeln!(r);
    let _ = writeln!(
        r,
        "- never worse than raw: {} ({} worse, {failed} failed)",
        verdict(worse.is_empty() && failed == 0),
        worse.len()
    );
    if let Some((m, _, _)) = stats(gains) {
        let _ = writeln!(r, "- median raw/comp {m:.2} >= 3: {}", verdict(m >= 3.0));
    }
    if let Some((m, _, _)) = stats(ratios) {
        let _ = writeln!(
            r,
            "- median comp/oracle {m:.2} <= 1.5: {}",
            verdict(m <= 1.5)
        );
    }
    let _ = writeln!(
        r,
        "\n### Cases where the compensated signal is worse than raw ({})\n",
        worse.len()
    );
    if !worse.is_empty() {
        let _ = writeln!(r, "| case | family | kind | effect | probe | fs | validation | raw | comp | oracle | fitted order/delay |");
        let _ = writeln!(r, "|---|---|---|---|---|---|---|---|---|---|---|");
        for (c, o) in &worse {
            let _ = writeln!(
                r,
                "| case-{:03} | {} | {} | {} | {} | {} Hz | {} | {:.3} % | {:.3} % | {} | {} |",
                c.id,
                c.family.name(),
                c.kind.name(),
                c.effect.describe(),
                c.probe_text(),
                c.fs,
                c.val.describe(),
                100.0 * o.raw.unwrap_or(f64::NAN),
                100.0 * o.comp.unwrap_or(f64::NAN),
                o.oracle
                    .map_or("-".into(), |q| format!("{:.3} %", 100.0 * q)),
                o.fitted.map_or("-".into(), |(m, d)| format!("{m}/{d}")),
            );
        }
    }
    let failures: Vec<&(Case, Outcome)> = rows
        .iter()
        .filter(|(_, o)| o.failure.is_some() || o.oracle_failure.is_some())
        .collect();
    let _ = writeln!(r, "\n### Failed commands ({} cases)\n", failures.len());
    if !failures.is_empty() {
        let _ = writeln!(
            r,
            "| case | family | kind | probe | user's pipeline | oracle |"
        );
        let _ = writeln!(r, "|---|---|---|---|---|---|");
        for (c, o) in failures {
            let _ = writeln!(
                r,
                "| case-{:03} | {} | {} | {} | {} | {} |",
                c.id,
                c.family.name(),
                c.kind.name(),
                c.probe_text(),
                o.failure.as_deref().unwrap_or("ok").replace('|', "/"),
                o.oracle_failure
                    .as_deref()
                    .unwrap_or("ok")
                    .replace('|', "/"),
            );
        }
    }
    let checks: Vec<f64> = rows.iter().filter_map(|(_, o)| o.truth_check).collect();
    if let Some((_, _, hi)) = stats(checks) {
        let _ = writeln!(r, "\nLumped truth models against the RK4 simulation (noise-free estimation test): largest difference {hi:.2e} of the step.");
    }
    let fits: Vec<f64> = rows.iter().filter_map(|(_, o)| o.truth_fit).collect();
    if let Some((m, _, hi)) = stats(fits) {
        let _ = writeln!(r, "Physics truth models (`unlag fit` on the long noise-free test): nrmse median {:.3} %, largest {:.3} %.", 100.0 * m, 100.0 * hi);
    }
    r
}

fn main() -> Result<(), Box<dyn Error>> {
    let s = settings()?;
    std::fs::create_dir_all(&s.out)
        .map_err(|e| format!("cannot create {}: {e}", s.out.display()))?;
    let cases = draw::draw(s.seed, s.cases);
    if s.modelling_loop {
        return run_loop(&cases, &s);
    }
    let start = Instant::now();
    let next = AtomicUsize::new(0);
    let done = AtomicUsize::new(0);
    let results: Mutex<Vec<(Case, Outcome)>> = Mutex::new(Vec::with_capacity(cases.len()));
    std::thread::scope(|scope| {
        for _ in 0..s.threads {
            scope.spawn(|| loop {
                let i = next.fetch_add(1, Ordering::SeqCst);
                let Some(case) = cases.get(i) else { break };
                let o = run_case(case, &s);
                let k = done.fetch_add(1, Ordering::SeqCst) + 1;
                let what = match (&o.failure, o.raw.zip(o.comp)) {
                    (Some(e), _) => format!("FAILED {e}"),
                    (None, Some((r, e))) => format!(
                        "raw/comp {:.2}{}",
                        r / e,
                        o.oracle
                            .map_or(String::new(), |q| format!(", comp/oracle {:.2}", e / q))
                    ),
                    _ => "no errors".into(),
                };
                eprintln!(
                    "[{k:3}/{}] case-{:03} {} {} {}: {what} ({:.1} s)",
                    cases.len(),
                    case.id,
                    case.family.name(),
                    case.generator_name(),
                    case.kind.name(),
                    o.seconds
                );
                if let Ok(mut r) = results.lock() {
                    r.push((case.clone(), o));
                }
            });
        }
    });
    let mut rows = results.into_inner().map_err(|_| "poisoned lock")?;
    rows.sort_by_key(|(c, _)| c.id);
    let path = s.out.join("results.csv");
    write_results(&path, &rows)?;
    print!("{}", report(&rows, &s, start.elapsed().as_secs_f64()));
    println!(
        "\nWrote {} and the cases in {}.",
        path.display(),
        s.out.display()
    );
    Ok(())
}

/// `--loop`: the modelling loop on every case, two at a time.
fn run_loop(cases: &[Case], s: &Settings) -> Result<(), Box<dyn Error>> {
    let start = Instant::now();
    let next = AtomicUsize::new(0);
    let rows: Mutex<Vec<(Case, modelling_loop::LoopOutcome)>> = Mutex::new(Vec::new());
    std::thread::scope(|scope| {
        for _ in 0..s.threads {
            scope.spawn(|| loop {
                let i = next.fetch_add(1, Ordering::SeqCst);
                let Some(case) = cases.get(i) else { break };
                let dir = s.out.join(format!("case-{:03}", case.id));
                let mut ignored = Outcome::default();
                let o = match make_files(case, &dir, &s.unlag, &mut ignored) {
                    Ok(_) => modelling_loop::run(&s.unlag, &dir, case.kind),
                    Err(e) => modelling_loop::LoopOutcome {
                        failure: Some(format!("simulation: {e}")),
                        ..Default::default()
                    },
                };
                eprintln!(
                    "case-{:03} {} {}: named {} ({})",
                    case.id,
                    case.family.name(),
                    case.kind.name(),
                    o.named.join(", "),
                    if o.right_or_carried(case.kind) {
                        "right"
                    } else {
                        "wrong"
                    }
                );
                if let Ok(mut r) = rows.lock() {
                    r.push((case.clone(), o));
                }
            });
        }
    });
    let mut rows = rows.into_inner().map_err(|_| "poisoned lock")?;
    rows.sort_by_key(|(c, _)| c.id);
    print!("{}", modelling_loop::report(&rows));
    println!(
        "\n{} cases in {:.0} s on {} threads, seed {}, {}.",
        rows.len(),
        start.elapsed().as_secs_f64(),
        s.threads,
        s.seed,
        s.unlag.display()
    );
    Ok(())
}
