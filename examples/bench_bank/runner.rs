//! One case through the `unlag` binary: its files written (the tests, the true model), then
//! the commands a user would run (`fit`, `compensate`, the remedy `invert --signal`, `fit` with
//! a held-out run) and the oracle's (`invert` and `compensate` on the true model), with what
//! each gave, or its first stderr line when it failed.

use std::path::Path;
use std::process::Command;
use std::time::Instant;

use super::case::{Case, Effect, Generator, Kind, Test, REFERENCE_K};
use super::draw::{self, Rng};
use super::{simulate, Settings};

/// What one case gave.
#[derive(Debug, Default, Clone)]
pub struct Outcome {
    /// Validation error of the raw probe (the CLI's, best alignment).
    pub raw: Option<f64>,
    /// ... of the compensated signal.
    pub comp: Option<f64>,
    /// ... of the oracle (the same design on the true model).
    pub oracle: Option<f64>,
    /// `unlag compensate` said the compensated signal is worse (its `verdict`, with a warning).
    pub said_worse: bool,
    /// The user's remedy: the compensator redesigned with `--signal` from another run of the
    /// validation's kind (`run.csv`, never the validation test itself), on the validation test.
    pub remedy: Option<f64>,
    /// The check given a held-out run: `unlag fit est.csv run.csv`, where `run.csv` is another
    /// run of the validation's kind, then `compensate` on the validation test: `(raw, comp)`,
    /// the raw probe's error as that `compensate` gives it (its lags depend on the model's
    /// delay, which the held-out run may move).
    pub held: Option<(f64, f64)>,
    /// The same with the prior learnt from that run too (`--signal run.csv`).
    pub held_signal: Option<(f64, f64)>,
    /// The failed step of the user's pipeline and its first stderr line.
    pub failure: Option<String>,
    /// The failed step of the oracle's pipeline.
    pub oracle_failure: Option<String>,
    /// Lumped cases: largest difference between the truth model's and RK4's noise-free
    /// estimation test, relative to the step (checks the discretisation).
    pub truth_check: Option<f64>,
    /// Physics cases: the truth fit's nrmse on its noise-free test.
    pub truth_fit: Option<f64>,
    /// The same three errors against the validation test's noise-free reference (what the
    /// reference sensor would read without its noise and ADC): `(raw, comp, oracle)`.
    pub clean: (Option<f64>, Option<f64>, Option<f64>),
    /// ADC full scale, in steps.
    pub adc_steps: f64,
    /// Order and delay of the fitted model.
    pub fitted: Option<(usize, usize)>,
    /// Wall time [s].
    pub seconds: f64,
}

/// Runs `unlag ARGS` in `dir`, stdout saved to `log`; `Err(step: first stderr line)`.
pub fn unlag(unlag: &Path, dir: &Path, args: &[&str], log: &str) -> Result<String, String> {
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

/// The estimation test's error in the JSON of `unlag fit ... --json`.
fn fitted_nrmse(json: &str) -> Option<f64> {
    let v: serde_json::Value = serde_json::from_str(json.trim()).ok()?;
    v.get("sources")?.get(0)?.get("nrmse")?.as_f64()
}

/// In the JSON of `unlag fit --order auto --json`, the stable order with the lowest estimation
/// error, when that is lower than the error of the order chosen (the model's).
fn closest_order(json: &str) -> Option<usize> {
    let v: serde_json::Value = serde_json::from_str(json.trim()).ok()?;
    let chosen = v.get("a")?.as_array()?.len();
    // (order, error) of the stable orders that have one.
    let rows: Vec<(usize, f64)> = v
        .get("fit")?
        .get("orders")?
        .as_array()?
        .iter()
        .filter(|r| r.get("stable").and_then(serde_json::Value::as_bool) == Some(true))
        .filter_map(|r| {
            let order = usize::try_from(r.get("order")?.as_u64()?).ok()?;
            Some((order, r.get("nrmse_estimation")?.as_f64()?))
        })
        .collect();
    let chosen = rows.iter().find(|r| r.0 == chosen)?;
    let best = rows.iter().min_by(|a, b| a.1.total_cmp(&b.1))?;
    (best.1 < chosen.1).then_some(best.0)
}

/// Makes the case's files and runs the pipeline.
pub fn run_case(case: &Case, s: &Settings) -> Outcome {
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
pub fn make_files(
    case: &Case,
    dir: &Path,
    bin: &Path,
    o: &mut Outcome,
) -> Result<Vec<f64>, String> {
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
            let long = Test {
                n: (2 * case.est.n).min(30_000),
                ..case.est
            };
            let (u, y) = simulate::clean(case, &long, REFERENCE_K)?;
            simulate::write_csv(&dir.join("truth_est.csv"), case.fs, &u, &y)?;
            // The order the fit's criterion chooses weighs a smaller error against more
            // parameters as noise would; on a noise-free test every error is the model's, so the
            // truth is the stable order that leaves the least. The refit at that order searches
            // its delay again, so it is kept only where it does leave less.
            let fit = ["fit", "truth_est.csv", "-o", "truth.toml", "--json"];
            match unlag(bin, dir, &fit, "truth.log") {
                Ok(text) => {
                    o.truth_fit = fitted_nrmse(&text);
                    if let Some(n) = closest_order(&text) {
                        let n = n.to_string();
                        let fit = [
                            "fit",
                            "truth_est.csv",
                            "--order",
                            &n,
                            "-o",
                            "truth-order.toml",
                            "--fresh",
                            "--json",
                        ];
                        let closer = unlag(bin, dir, &fit, "truth-order.log")
                            .ok()
                            .and_then(|t| fitted_nrmse(&t))
                            .filter(|e| o.truth_fit.is_some_and(|a| *e < a));
                        if let Some(e) = closer {
                            std::fs::rename(dir.join("truth-order.toml"), &truth)
                                .map_err(|err| format!("truth: {err}"))?;
                            o.truth_fit = Some(e);
                        }
                    }
                }
                Err(e) => o.oracle_failure = Some(format!("truth {e}")),
            }
        }
    }
    Ok(uv)
}

#[cfg(test)]
mod tests {
    use super::closest_order;
    use serde_json::json;

    /// `unlag fit --json` of a model of order `chosen` whose order table has `errors` (order
    /// 1 first; `None` for an unstable order, whose error is null).
    fn fit_json(chosen: usize, errors: &[Option<f64>]) -> String {
        let orders: Vec<_> = errors
            .iter()
            .enumerate()
            .map(|(i, e)| json!({"order": i + 1, "nrmse_estimation": e, "stable": e.is_some()}))
            .collect();
        json!({"a": vec![0.0; chosen], "fit": {"orders": orders}}).to_string()
    }

    #[test]
    fn a_noise_free_truth_is_the_stable_order_that_leaves_least() {
        // Seed 27's case 108, a pneumatic line fitted on its noise-free test.
        let table = [
            Some(0.12234),
            Some(0.02558),
            Some(0.00546),
            Some(0.00172),
            Some(0.00052),
            Some(0.00018),
        ];
        assert_eq!(closest_order(&fit_json(3, &table)), Some(6));
        // The lowest is unstable: the next stable one.
        let mut unstable = table;
        unstable[5] = None;
        assert_eq!(closest_order(&fit_json(3, &unstable)), Some(5));
        // The criterion chose the closest already: nothing to refit.
        assert_eq!(closest_order(&fit_json(6, &table)), None);
        assert_eq!(closest_order("no table"), None);
        // Seed 13's case 054: unstable orders without an error sit between the rows.
        let gaps = [
            Some(0.01973),
            Some(0.00323),
            None,
            None,
            Some(6e-5),
            Some(3e-5),
        ];
        assert_eq!(closest_order(&fit_json(5, &gaps)), Some(6));
        let mut worse = gaps;
        worse[5] = Some(9e-5);
        assert_eq!(closest_order(&fit_json(5, &worse)), None);
    }
}
