//! The modelling loop's report: the confusion matrix of the hidden kind against the first
//! name, the counts the issue judges by, and the tables of the misnamed cases and of the
//! changes that leave the error above the floor.

use std::fmt::Write as _;

use super::case::{Case, Kind, KINDS};
use super::modelling_loop::{LoopOutcome, Shown, VISIBLE_FALL};

/// Names a diagnosis can give, in the confusion matrix's column order.
const NAMES: [&str; 12] = [
    "none",
    "unexplained",
    "leak",
    "drift",
    "offset",
    "coloured-noise",
    "mode",
    "sensor-resonance",
    "nonlinear-damping",
    "temperature",
    "delay",
    "other",
];

fn column(name: &str) -> usize {
    let name = if name.starts_with("temperature") {
        "temperature"
    } else {
        name
    };
    NAMES
        .iter()
        .position(|n| *n == name)
        .unwrap_or(NAMES.len() - 1)
}

/// The loop's report: the confusion matrix, the falls of the error, the misnamed cases.
pub fn report(rows: &[(Case, LoopOutcome)]) -> String {
    let mut r = String::new();
    let _ = writeln!(
        r,
        "## The modelling loop on the bank: {} cases\n",
        rows.len()
    );
    let _ = writeln!(r, "From `unlag fit --order 2 est.csv`, `unlag diagnose loop.toml est.csv val.csv` names the missing effect; rows are the hidden kind, columns the first name. The error is the validation test's (`fit --order 2 est.csv val.csv`, then the same with `--add FIRST`). *Carried*: the diagnosis names nothing (`none`, counted in that column) because the plain fit found the hidden effect itself and the diagnosis lists it as carried; it counts as right, and its error is judged by the fit that carries it (at most 1.5x the floor). *The floor* is what a correct model's simulation leaves on the validation test, the probe's noise and the reference's through the model (`sigma_y^2 + |G|^2 sigma_u^2`, the diagnosis' expected residual, with the plain fit's `G`); the last column judges against the probe's noise alone, as `fit` states its floor, which no model reaches when the reference is noisy. A change fitted on the estimation and validation tests together (`--also val.csv`: a quadratic loss, which one step cannot identify) is judged on `run.csv`, another run of the validation's kind, held out, against the plain fit's error there. A change that fits a noise model (`coloured-noise`) reports the one-step-ahead prediction error, so it is judged against that error's floor as `fit` states it, the innovation of both channels' noise through the model read before the step (the part of a coloured noise, and of the reference's noise through the model, no predictor removes), in both columns.\n");
    let _ = write!(r, "| hidden \\ named first |");
    for n in NAMES {
        let _ = write!(r, " {n} |");
    }
    let _ = writeln!(
        r,
        " carried | right | error falls 3x or to 1.5x the floor | (the probe's floor alone) | (within two rounds) |"
    );
    let _ = writeln!(r, "|---|{}---|---|---|---|---|", "---|".repeat(NAMES.len()));
    let (mut right_all, mut carried_all, mut total) = (0, 0, 0);
    for k in KINDS {
        let group: Vec<&(Case, LoopOutcome)> = rows.iter().filter(|(c, _)| c.kind == k).collect();
        let mut counts = [0usize; NAMES.len()];
        for (_, o) in &group {
            if o.named.is_empty() {
                continue;
            }
            counts[column(o.first())] += 1;
        }
        let right = group.iter().filter(|(_, o)| o.right_or_carried(k)).count();
        let carried = group.iter().filter(|(_, o)| o.carried_right(k)).count();
        let judged: Vec<&&(Case, LoopOutcome)> = group
            .iter()
            .filter(|(_, o)| o.right_or_carried(k) && k != Kind::None)
            .collect();
        let falls: Vec<bool> = judged
            .iter()
            .filter_map(|(_, o)| o.falls(k, true))
            .collect();
        let falls_probe: Vec<bool> = judged
            .iter()
            .filter_map(|(_, o)| o.falls(k, false))
            .collect();
        let falls_two: Vec<bool> = judged
            .iter()
            .filter_map(|(_, o)| o.falls_within_two(k))
            .collect();
        right_all += right;
        carried_all += carried;
        total += group.len();
        let _ = write!(r, "| {} |", k.name());
        for c in counts {
            let _ = write!(
                r,
                " {} |",
                if c == 0 { String::new() } else { c.to_string() }
            );
        }
        let count = |f: &[bool]| {
            if k == Kind::None {
                "-".to_string()
            } else {
                format!("{}/{}", f.iter().filter(|f| **f).count(), f.len())
            }
        };
        let _ = writeln!(
            r,
            " {} | {right}/{} | {} | {} | {} |",
            if carried == 0 {
                String::new()
            } else {
                carried.to_string()
            },
            group.len(),
            count(&falls),
            count(&falls_probe),
            count(&falls_two),
        );
    }
    let none: Vec<&(Case, LoopOutcome)> =
        rows.iter().filter(|(c, _)| c.kind == Kind::None).collect();
    // A false alarm names an effect; "unexplained" says something is missing without naming one.
    let false_alarm = none
        .iter()
        .filter(|(_, o)| !matches!(o.first(), "none" | "unexplained"))
        .count();
    let unexplained = rows
        .iter()
        .filter(|(c, o)| c.kind != Kind::None && o.first() == "unexplained")
        .count();
    let _ = writeln!(
        r,
        "\n- named right first: {right_all}/{total} ({:.0} %; target 95 %), {carried_all} of them carried by the plain fit; by the diagnosis' first name alone {}/{total}",
        100.0 * right_all as f64 / total.max(1) as f64,
        right_all - carried_all
    );
    let within_two = rows
        .iter()
        .filter(|(c, o)| o.right_within_two(c.kind))
        .count();
    let _ = writeln!(
        r,
        "- named right within two rounds (the first name added, then diagnosed again, as a user goes round the loop): {within_two}/{total} ({:.0} %)",
        100.0 * within_two as f64 / total.max(1) as f64
    );
    let _ = writeln!(
        r,
        "- no effect named as an effect: {false_alarm}/{} (target at most 5 %)",
        none.len()
    );
    // A change that made the model worse where it is judged: the first name added, its
    // held-out error against the plain fit's (on the further run for a change fitted on two
    // tests together), by the share `unlag fit` warns of when it continues a model file.
    let judged = |o: &LoopOutcome| {
        if o.joint {
            o.before_run.zip(o.after_run)
        } else {
            o.before.zip(o.after)
        }
    };
    let changed: Vec<&(Case, LoopOutcome)> = rows
        .iter()
        .filter(|(_, o)| !matches!(o.first(), "none" | "unexplained" | ""))
        .filter(|(_, o)| judged(o).is_some())
        .collect();
    let raised: Vec<String> = changed
        .iter()
        .filter_map(|(c, o)| {
            let (before, after) = judged(o)?;
            unlag::fit::error_rose(before, after).then(|| {
                format!(
                    "case-{:03} ({} named {}, {:.3} % -> {:.3} %)",
                    c.id,
                    c.kind.name(),
                    o.first(),
                    100.0 * before,
                    100.0 * after
                )
            })
        })
        .collect();
    let _ = writeln!(
        r,
        "- the first name's change raised the held-out error (by more than {:.0} %, what `unlag fit` warns of when it continues a model file): {}/{}{}",
        100.0 * unlag::fit::ERROR_RISE_NOTED,
        raised.len(),
        changed.len(),
        if raised.is_empty() {
            String::new()
        } else {
            format!(": {}", raised.join("; "))
        }
    );
    // Nothing is hidden, but the probe itself may be more than the second-order start: where
    // its true model beats the plain fit by the diagnosis' own threshold, the probe's own
    // dynamics are visible in these tests, as a hidden effect is, and `mode` names them.
    let (own, plain): (Vec<&&(Case, LoopOutcome)>, Vec<_>) = none
        .iter()
        .partition(|(c, o)| o.own_dynamics_visible(c.kind).is_some());
    let plain_alarms = plain
        .iter()
        .filter(|(_, o)| !matches!(o.first(), "none" | "unexplained"))
        .count();
    let _ = writeln!(
        r,
        "  - where the probe's own dynamics beyond second order do not show (on either test its true model beats the second-order start by less than {VISIBLE_FALL}x): {plain_alarms}/{} named as an effect",
        plain.len()
    );
    if !own.is_empty() {
        let _ = writeln!(
            r,
            "  - where they do, {} cases, named `mode` or `unexplained` (a higher order) {}: {}",
            own.len(),
            own.iter()
                .filter(|(_, o)| matches!(o.first(), "mode" | "unexplained"))
                .count(),
            own.iter()
                .map(|(c, o)| format!(
                    "case-{:03} (named {}; on validation the true model's error {:.3} % against the second-order fit's {:.3} %, {:.2}x below it on the test that shows it most; after the change {})",
                    c.id,
                    o.first(),
                    100.0 * o.bare_truth.map(|t| t[1]).or(o.truth_error).unwrap_or(f64::NAN),
                    100.0 * o.bare_before.map(|b| b[1]).or(o.before).unwrap_or(f64::NAN),
                    o.own_dynamics_visible(c.kind).unwrap_or(f64::NAN),
                    o.after.map_or("-".into(), |a| format!("{:.3} %", 100.0 * a)),
                ))
                .collect::<Vec<_>>()
                .join("; ")
        );
    }
    // The floors against the oracle: where nothing is hidden, the true model's own error is
    // what a floor should predict.
    let ratios = |f: fn(&LoopOutcome) -> Option<f64>| -> Vec<f64> {
        let mut v: Vec<f64> = none
            .iter()
            .filter_map(|(_, o)| Some(o.truth_error? / f(o)?))
            .collect();
        v.sort_by(f64::total_cmp);
        v
    };
    let spread = |v: &[f64]| match (v.first(), v.get(v.len() / 2), v.last()) {
        (Some(lo), Some(med), Some(hi)) => format!("median {med:.2}, from {lo:.2} to {hi:.2}"),
        _ => "-".into(),
    };
    let (both, probe) = (ratios(|o| o.floor_both), ratios(|o| o.floor));
    let _ = writeln!(
        r,
        "- the floors against the oracle, on the {} cases with no effect whose true model is known: the true model's validation error is {} times the floor both channels leave, and {} times the probe's floor alone",
        both.len(),
        spread(&both),
        spread(&probe)
    );
    let _ = writeln!(
        r,
        "- a hidden effect called `unexplained` (the residual is above what the noise leaves and no effect in the catalogue lowers it): {unexplained}; called `none`: {}",
        rows.iter()
            .filter(|(c, o)| c.kind != Kind::None
                && o.first() == "none"
                && !o.carried_right(c.kind))
            .count()
    );
    // The same score where the tests can show the effect: adding the hidden kind itself lowers
    // the validation error by the diagnosis' threshold.
    let hidden: Vec<&(Case, LoopOutcome)> =
        rows.iter().filter(|(c, _)| c.kind != Kind::None).collect();
    let visible: Vec<&&(Case, LoopOutcome)> = hidden
        .iter()
        .filter(|(c, o)| o.visible(c.kind) != Some(false))
        .collect();
    let invisible: Vec<&&(Case, LoopOutcome)> = hidden
        .iter()
        .filter(|(c, o)| o.visible(c.kind) == Some(false))
        .collect();
    let _ = writeln!(
        r,
        "- visible in its tests (adding the hidden kind itself lowers the validation error by at least {VISIBLE_FALL}x, the diagnosis' own threshold, counted down to the floor both channels' noise leaves through the true model and no further, or that refit failed; a nonlinear damping also when, fitted on both tests together, a loss is found and it lowers both their own error, as the diagnosis sees it, and `run.csv`'s, held out, by that factor): {} of {} hidden effects; named right first among them: {}/{} ({:.0} %); within two rounds {}/{}",
        visible.len(),
        hidden.len(),
        visible.iter().filter(|(c, o)| o.right_or_carried(c.kind)).count(),
        visible.len(),
        100.0 * visible.iter().filter(|(c, o)| o.right_or_carried(c.kind)).count() as f64
            / visible.len().max(1) as f64,
        visible.iter().filter(|(c, o)| o.right_within_two(c.kind)).count(),
        visible.len(),
    );
    let _ = writeln!(
        r,
        "- not visible: {} (named `none` {}, `unexplained` {}, right {}, another effect {})",
        invisible.len(),
        invisible
            .iter()
            .filter(|(c, o)| o.first() == "none" && !o.right_or_carried(c.kind))
            .count(),
        invisible
            .iter()
            .filter(|(_, o)| o.first() == "unexplained")
            .count(),
        invisible
            .iter()
            .filter(|(c, o)| o.right_or_carried(c.kind))
            .count(),
        invisible
            .iter()
            .filter(|(c, o)| !o.right_or_carried(c.kind)
                && !matches!(o.first(), "none" | "unexplained"))
            .count()
    );
    // The count the tests can support: an effect they cannot show is right when the diagnosis
    // names nothing for it (`none`, or `unexplained`: something is missing, unnamed).
    let supported = rows
        .iter()
        .filter(|(c, o)| {
            o.right_or_carried(c.kind)
                || (c.kind != Kind::None
                    && o.visible(c.kind) == Some(false)
                    && matches!(o.first(), "none" | "unexplained"))
        })
        .count();
    let _ = writeln!(
        r,
        "- named right first, an effect its tests cannot show counted right when named `none` or `unexplained` (the count offered as option (b)): {supported}/{} ({:.0} %)",
        rows.len(),
        100.0 * supported as f64 / rows.len().max(1) as f64
    );
    // What the tests show is missing: the hidden kind where it is visible; where it is not,
    // the probe's own dynamics beyond second order if they show on the bare twin (the same
    // probe without the hidden effect, on the same noise), which `mode` names; else nothing.
    let by_tests = rows
        .iter()
        .filter(|(c, o)| o.right_by_tests(c.kind))
        .count();
    let own_named: Vec<String> = rows
        .iter()
        .filter(|(c, o)| o.right_by_tests(c.kind) && o.first() == "mode" && c.kind != Kind::Mode)
        .map(|(c, o)| {
            format!(
                "case-{:03} ({}, {:.2}x)",
                c.id,
                c.kind.name(),
                o.own_dynamics_visible(c.kind).unwrap_or(f64::NAN)
            )
        })
        .collect();
    let own_missed = rows
        .iter()
        .filter(|(c, o)| {
            !o.right_by_tests(c.kind)
                && (c.kind == Kind::None || o.visible(c.kind) == Some(false))
                && o.own_dynamics_visible(c.kind).is_some()
        })
        .count();
    let _ = writeln!(
        r,
        "- (d) named right for what the tests show: the hidden kind where it is visible, else `mode`, or `unexplained` whose change is a higher order, where the probe's own dynamics beyond second order show (on the bare twin, the same probe without the hidden effect and on the same noise, its true model beats the second-order start by at least {VISIBLE_FALL}x on the estimation or the validation test), else `none` or `unexplained` (`none` alone with nothing hidden): {by_tests}/{} ({:.0} %); `mode` right for the probe's own dynamics {}{}; those dynamics shown but named neither `mode` nor `unexplained` {own_missed}",
        rows.len(),
        100.0 * by_tests as f64 / rows.len().max(1) as f64,
        own_named.len(),
        if own_named.is_empty() {
            String::new()
        } else {
            format!(" ({})", own_named.join(", "))
        }
    );
    // The count as the bench made it up to stop 41, visibility not counted to the floor, and
    // the cases it judges otherwise.
    let uncapped = rows
        .iter()
        .filter(|(c, o)| o.right_by_tests_to(c.kind, None))
        .count();
    let moved: Vec<String> = rows
        .iter()
        .filter(|(c, o)| o.right_by_tests(c.kind) != o.right_by_tests_to(c.kind, None))
        .map(|(c, o)| {
            format!(
                "case-{:03} ({}, named {}: {})",
                c.id,
                c.kind.name(),
                o.first(),
                if o.right_by_tests(c.kind) {
                    "right only counted to the floor"
                } else {
                    "right only not counted to the floor"
                }
            )
        })
        .collect();
    let _ = writeln!(
        r,
        "  - (d) with visibility not counted to the true model's floor (the bench up to stop 41): {uncapped}/{}; judged otherwise: {}",
        rows.len(),
        if moved.is_empty() {
            "none".to_string()
        } else {
            moved.join("; ")
        }
    );
    let missed: Vec<String> = rows
        .iter()
        .filter(|(c, o)| !o.right_by_tests(c.kind))
        .map(|(c, o)| {
            format!(
                "case-{:03} ({} {}, own dynamics {}: named {})",
                c.id,
                c.kind.name(),
                match o.visible(c.kind) {
                    _ if c.kind == Kind::None => "",
                    Some(true) => "visible",
                    Some(false) => "not visible",
                    None => "visibility unknown",
                },
                o.own_dynamics_visible(c.kind)
                    .map_or("not shown".into(), |g| format!("{g:.2}x")),
                o.named.join(", ")
            )
        })
        .collect();
    let _ = writeln!(r, "  - not right by (d): {}", missed.join("; "));
    for k in KINDS.iter().filter(|k| **k != Kind::None) {
        let of_kind = |v: &Vec<&&(Case, LoopOutcome)>| -> (usize, usize) {
            let g: Vec<_> = v.iter().filter(|(c, _)| c.kind == *k).collect();
            (
                g.iter().filter(|(c, o)| o.right_or_carried(c.kind)).count(),
                g.len(),
            )
        };
        let (vr, vn) = of_kind(&visible);
        let (_, inn) = of_kind(&invisible);
        let _ = writeln!(
            r,
            "  - {}: visible {vn}, named right {vr}/{vn}; not visible {inn}",
            k.name()
        );
    }
    by_tests_matrix(&mut r, rows);
    let _ = writeln!(r, "\n### Misnamed cases\n");
    let _ = writeln!(r, "| case | family | hidden | validation | named (best first) | margin | error before | after | floor (both channels) | probe's floor | after adding the hidden kind | second round |");
    let _ = writeln!(r, "|---|---|---|---|---|---|---|---|---|---|---|---|");
    for (c, o) in rows.iter().filter(|(c, o)| !o.right_or_carried(c.kind)) {
        let pct = |v: Option<f64>| v.map_or("-".into(), |x| format!("{:.3} %", 100.0 * x));
        let _ = writeln!(
            r,
            "| case-{:03} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |",
            c.id,
            c.family.name(),
            c.kind.name(),
            c.val.name,
            o.failure.as_deref().map_or_else(
                || o.named
                    .iter()
                    .take(3)
                    .cloned()
                    .collect::<Vec<_>>()
                    .join(", "),
                |f| format!("FAILED {}", f.replace('|', "/"))
            ),
            o.margin.map_or("-".into(), |m| format!("{m:.2}")),
            pct(o.before),
            pct(o.after),
            pct(o.floor_both),
            pct(o.floor),
            pct(o.true_after),
            o.second.as_deref().unwrap_or("-"),
        );
    }
    let _ = writeln!(
        r,
        "\n### Named right, and the error falls less than 3x and stays above 1.5x a floor\n"
    );
    let _ = writeln!(r, "| case | family | hidden | validation | error before | after | fall | floor (both channels) | after / floor | probe's floor | after / probe's floor | second round: named, after, fall from before |");
    let _ = writeln!(r, "|---|---|---|---|---|---|---|---|---|---|---|---|");
    for (c, o) in rows.iter().filter(|(c, o)| {
        c.kind != Kind::None
            && o.right_or_carried(c.kind)
            && (o.falls(c.kind, true) == Some(false) || o.falls(c.kind, false) == Some(false))
    }) {
        let pct = |v: Option<f64>| v.map_or("-".into(), |x| format!("{:.3} %", 100.0 * x));
        let (before, after, probe, both) = o.judged();
        let after = if o.carried_right(c.kind) {
            before
        } else {
            after
        };
        let ratio = |a: Option<f64>, b: Option<f64>| match (a, b) {
            (Some(a), Some(b)) if b > 0.0 => format!("{:.2}x", a / b),
            _ => "-".into(),
        };
        let _ = writeln!(
            r,
            "| case-{:03} | {} | {} | {}{} | {} | {} | {} | {} | {} | {} | {} | {} |",
            c.id,
            c.family.name(),
            c.kind.name(),
            c.val.name,
            if o.joint { " (judged on run.csv)" } else { "" },
            pct(before),
            pct(after),
            ratio(before, after),
            pct(both),
            ratio(after, both),
            pct(probe),
            ratio(after, probe),
            match (&o.round_two, o.after_two) {
                (Some(n), Some(a)) => format!("{n}, {}, {}", pct(Some(a)), ratio(before, Some(a))),
                (Some(n), None) => n.clone(),
                _ => "-".into(),
            },
        );
    }
    r
}

/// The confusion matrix count (d) judges: rows are what the tests show is missing
/// ([`LoopOutcome::shown`]), columns the first name, and the cases right by (d) per row.
fn by_tests_matrix(r: &mut String, rows: &[(Case, LoopOutcome)]) {
    let _ = writeln!(
        r,
        "\n### By what the tests show is missing (count (d))\n\nRows: the hidden kind where its tests show it; else the probe's own dynamics beyond second order where they show (`mode`, or `unexplained` and a higher order, is right); else nothing (`none`, or `unexplained` where an effect is hidden). Columns: the first name; a hidden effect the plain fit found by itself and the diagnosis lists as carried counts in `none`, and is right. The hidden kind named where its tests do not show it is right too. Where both the hidden kind and the probe's own dynamics show, `mode` first is right when its change lowers the error more.\n"
    );
    let _ = write!(r, "| tests show \\ named first |");
    for n in NAMES {
        let _ = write!(r, " {n} |");
    }
    let _ = writeln!(r, " right by (d) |");
    let _ = writeln!(r, "|---|{}---|", "---|".repeat(NAMES.len()));
    let groups = KINDS
        .iter()
        .filter(|k| **k != Kind::None)
        .map(|k| {
            (
                k.name().to_string(),
                rows.iter()
                    .filter(|(c, o)| c.kind == *k && o.shown(c.kind) == Shown::Hidden)
                    .collect::<Vec<_>>(),
            )
        })
        .chain(
            [
                (Shown::OwnDynamics, "the probe's own dynamics"),
                (Shown::Nothing, "nothing"),
            ]
            .map(|(s, label)| {
                (
                    label.to_string(),
                    rows.iter()
                        .filter(|(c, o)| o.shown(c.kind) == s)
                        .collect::<Vec<_>>(),
                )
            }),
        );
    for (label, group) in groups {
        let mut counts = [0usize; NAMES.len()];
        for (_, o) in group.iter().filter(|(_, o)| !o.named.is_empty()) {
            counts[column(o.first())] += 1;
        }
        let right = group
            .iter()
            .filter(|(c, o)| o.right_by_tests(c.kind))
            .count();
        let _ = write!(r, "| {label} |");
        for c in counts {
            let _ = write!(
                r,
                " {} |",
                if c == 0 { String::new() } else { c.to_string() }
            );
        }
        let _ = writeln!(r, " {right}/{} |", group.len());
    }
}
