//! The bank's results: the printed Markdown summary (per family, per kind, per generator and
//! for the whole bank, against the CLI's reference and the noise-free one, the cases worse
//! than raw, the failed commands) and `results.csv`, one row per case.

use std::error::Error;
use std::fmt::Write as _;
use std::path::Path;

use super::case::{Case, Generator, FAMILIES, KINDS};
use super::runner::Outcome;
use super::Settings;

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
pub fn write_results(path: &Path, rows: &[(Case, Outcome)]) -> Result<(), Box<dyn Error>> {
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
pub fn report(rows: &[(Case, Outcome)], s: &Settings, seconds: f64) -> String {
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
