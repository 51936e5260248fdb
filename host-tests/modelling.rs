//! The modelling loop on step tests with hidden effects: for every case the diagnosis names the
//! hidden kind first (or `none`), and adding it cuts the validation error at least 3x or to
//! within 1.5x of the noise floor; an offset the plain fit removes by itself leaves nothing to
//! name. The cases are in `common/hidden.rs`; the score table in
//! BENCHMARKS.md comes from `examples/bench_diagnose.rs` on the same cases. The `physics ...`
//! cases are simulated by the physics module; their step tests, and the physical cases kept
//! apart from the criterion, are checked against what the physics predicts.

// Test code: a failed unwrap is a failed test, with its location.
#![allow(clippy::unwrap_used)]

mod common;

use common::hidden::{cases, physical_cases, physical_limits, run, Hidden, REFERENCE_K};

#[test]
fn every_hidden_effect_is_named_and_adding_it_cuts_the_error() {
    let mut failures = Vec::new();
    for case in cases() {
        let o = run(&case, 11);
        eprintln!(
            "{:<45} named {:?}: {:.3} % -> {:.3} % (floor {:.3} %)",
            case.name,
            o.named,
            100.0 * o.before,
            100.0 * o.after,
            100.0 * o.floor
        );
        if !o.passed(case.kind) {
            failures.push(format!("{}: {:?}", case.name, o));
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// The physics cases' step tests are the Bergh-Tijdeman response: the probe stays at its level
/// until the front has travelled the line (`ΣL/a`) and settles at the line's DC gain times the
/// new level, while the reference reaches it within the facility's opening time.
#[test]
fn physical_step_tests_wait_for_the_front_and_settle() {
    for case in physical_cases() {
        let Hidden::Physics(p) = case.hidden else {
            panic!("{}: not a physics case", case.name);
        };
        for &(lo, hi) in case.steps {
            let at = case.n / 8;
            let (u, y) = p.step_test(case.fs, case.n, at, (lo, hi), REFERENCE_K);
            let gas = unlag::physics::Gas::air(REFERENCE_K, 101_325.0);
            let dc = p.line().dc_gain(&gas);
            let front = (p.line().front_delay_s(&gas) * case.fs).floor() as usize;
            assert!(front >= 2, "{}: front {front}", case.name);
            let size = (hi - lo).abs();
            for (k, v) in y.iter().enumerate().take(at + front - 1) {
                assert!(
                    (v - dc * lo).abs() < 1e-6 * size,
                    "{} at {k}: {v}",
                    case.name
                );
            }
            // The slowest facility (the balloon) takes 0.7 ms.
            let opened = at + (1e-3 * case.fs) as usize;
            assert!(
                (u[at - 1] - lo).abs() < 1e-9 && (u[opened] - hi).abs() < 1e-9,
                "{}",
                case.name
            );
            let last = y.last().unwrap();
            assert!(
                (last - dc * hi).abs() < 2e-3 * size,
                "{}: {last}",
                case.name
            );
        }
    }
}

/// The physical cases kept apart from the criterion (`physical_limits` in `common/hidden.rs`)
/// still show what the physics predicts: a reference transducer ringing far above the line's
/// band leaves the plain model at its noise floor (nothing to add); describing-function minor
/// losses raise the damping with the step's amplitude. (The well-damped line at another
/// temperature, once kept here, now meets the criterion with the viscous damping law.)
#[test]
fn physical_limits_show_what_the_physics_predicts() {
    assert!(
        physical_limits().iter().all(|c| c.kind != "temperature"),
        "a temperature case is kept apart again"
    );
    for case in physical_limits() {
        let o = run(&case, 11);
        match case.kind {
            "sensor-resonance" => {
                assert!(o.before < 1.5 * o.floor, "{}: {o:?}", case.name);
                assert_eq!(
                    o.named.first().copied(),
                    Some(unlag::modelling::diagnose::Finding::Nothing),
                    "{}: {o:?}",
                    case.name
                );
            }
            "nonlinear-damping" => {
                let s = o.signature.as_ref().unwrap();
                assert!(
                    s.damping_rise >= unlag::modelling::diagnose::MIN_DAMPING_RISE,
                    "{}: {s:?}",
                    case.name
                );
                assert!(
                    s.damping.windows(2).all(|w| w[1] > w[0]),
                    "{}: {s:?}",
                    case.name
                );
            }
            _ => {}
        }
    }
}

/// The damping law of `temperature` the diagnosis offers follows the hidden truth: the lumped
/// cases, whose damping is kept, get `--add temperature`; the well-damped Bergh-Tijdeman line,
/// whose damping rises with the kinematic viscosity, gets `--add temperature-viscous`, and the
/// trial's held-out error with it is at least 3x below the plain model's.
#[test]
fn the_diagnosis_offers_the_damping_law_the_physics_has() {
    use unlag::effects;
    use unlag::fit::Test;
    use unlag::modelling::diagnose::{self, Current};
    let wanted = [
        ("temperature: validation at 343 K", "temperature"),
        (
            "physics temperature: BT 0.1 m x 1 mm, 1000 mm3, validation at 343 K",
            "temperature-viscous",
        ),
    ];
    for (name, add) in wanted {
        let case = cases().into_iter().find(|c| c.name == name).unwrap();
        let data = case.tests(11);
        let tests: Vec<Test<'_>> = data
            .iter()
            .zip(["estimation", "validation", "validation 2", "validation 3"])
            .map(|((u, y), name)| Test { name, u, y })
            .collect();
        let options = case.options();
        let (plain, fx) =
            effects::fit_with(&tests[0], &tests[1..], case.fs, &options, &[]).unwrap();
        let current = Current {
            model: &plain.model,
            effects: &fx,
            method: options.method,
            uncertainty: plain.report.uncertainty.as_ref(),
            order_given: true,
        };
        let evidence = diagnose::evidence(&current, &tests);
        let candidates = diagnose::diagnose(&current, &tests, &evidence).unwrap();
        let c = candidates.first().unwrap();
        let diagnose::Evidence::Temperature(t) = &c.evidence else {
            panic!("{name}: {c:?}")
        };
        eprintln!(
            "{name}: {} {} ({:.3} % -> {:.3} %, damping x{:.3} measured, x{:.3} viscous)",
            c.kind,
            t.add,
            100.0 * c.nrmse_before,
            100.0 * c.nrmse_after,
            t.damping_ratio,
            t.viscous_damping_ratio
        );
        // The kind is exactly what `--add` takes, the damping law with it.
        assert_eq!(c.kind.as_str(), add, "{name}: {c:?}");
        assert_eq!(t.add.as_str(), add, "{name}: {c:?}");
        assert_eq!(
            c.change.kind().map(|k| k.as_str()),
            Some(add),
            "{}",
            c.change
        );
        assert!(c.nrmse_before / c.nrmse_after >= 3.0, "{name}: {c:?}");
    }
}

/// The README's walkthrough, through the command line, on the shipped example data (whose probe
/// has a second line mode): a plain 2nd-order model, the diagnosis, the effect added, the
/// error history falling, and nothing left.
#[test]
fn the_readme_walkthrough_on_the_shipped_data() {
    use std::process::Command;
    let dir = std::env::temp_dir().join(format!("unlag-loop-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let model = dir.join("probe.toml");
    let m = model.to_str().unwrap();
    let t1 = concat!(env!("CARGO_MANIFEST_DIR"), "/examples/data/step_test_1.csv");
    let t2 = concat!(env!("CARGO_MANIFEST_DIR"), "/examples/data/step_test_2.csv");
    let run = |args: &[&str]| -> serde_json::Value {
        let o = Command::new(env!("CARGO_BIN_EXE_unlag"))
            .args(args)
            .output()
            .unwrap();
        let out = String::from_utf8_lossy(&o.stdout).into_owned();
        assert!(
            o.status.success(),
            "{args:?}: {out}{}",
            String::from_utf8_lossy(&o.stderr)
        );
        serde_json::from_str(out.trim()).expect(&out)
    };
    run(&["fit", t1, t2, "--order", "2", "--fresh", "-o", m, "--json"]);
    let d = run(&["diagnose", m, t1, t2, "--json"]);
    let first = &d["candidates"][0];
    assert_eq!(first["kind"], "mode", "{d}");
    let scores: Vec<f64> = d["candidates"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c["score"].as_f64().unwrap())
        .collect();
    assert!(scores.windows(2).all(|w| w[0] >= w[1]), "{scores:?}");
    assert!(d["tests"][0]["fit_percent"].as_f64().unwrap() > 90.0);
    run(&[
        "fit", t1, t2, "--order", "2", "--add", "mode", "-o", m, "--json",
    ]);
    let c = run(&["compare", m, t1, t2, "--json"]);
    let history = c["history"].as_array().unwrap();
    assert_eq!(history.len(), 2, "{c}");
    let mean = |row: &serde_json::Value| {
        let t = row["tests"].as_array().unwrap();
        t.iter().map(|x| x["nrmse"].as_f64().unwrap()).sum::<f64>() / t.len() as f64
    };
    assert!(mean(&history[1]) < mean(&history[0]) / 2.0, "{c}");
    assert_eq!(history[1]["effects"][0], "mode");
    for t in c["tests"].as_array().unwrap() {
        let (e, floor) = (
            t["nrmse"].as_f64().unwrap(),
            t["noise_floor"].as_f64().unwrap(),
        );
        assert!(e < 1.5 * floor, "{e} against {floor}");
    }
    assert_eq!(c["across_tests"].as_array().unwrap().len(), 2);
    let d = run(&["diagnose", m, t1, t2, "--json"]);
    assert_eq!(d["candidates"][0]["kind"], "none", "{d}");
    // Bad input is one line and exit 1.
    let o = Command::new(env!("CARGO_BIN_EXE_unlag"))
        .args(["diagnose", m, "no-such-test.csv"])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1));
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.contains("no-such-test.csv"), "{err}");
}

/// A diagnosis's `delay` is what `--add` takes (as every kind it names): the delay searched
/// again, as the diagnosis did, and kept in the model file as a `delay` effect, so that a
/// later refit keeps it.
#[test]
fn a_delay_named_by_the_diagnosis_is_added_with_add_delay() {
    let dir = std::env::temp_dir().join(format!("unlag-add-delay-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let model = dir.join("probe.toml");
    let m = model.to_str().unwrap();
    let t1 = concat!(env!("CARGO_MANIFEST_DIR"), "/examples/data/step_test_1.csv");
    let t2 = concat!(env!("CARGO_MANIFEST_DIR"), "/examples/data/step_test_2.csv");
    let searched = unlag_json(&["fit", t1, t2, "--order", "2", "--fresh", "-o", m, "--json"]);
    let d_true = searched["delay"].as_u64().unwrap();
    let wrong = (d_true + 8).to_string();
    unlag_json(&[
        "fit", t1, t2, "--order", "2", "--delay", &wrong, "--fresh", "-o", m, "--json",
    ]);
    let d = unlag_json(&["diagnose", m, t1, t2, "--json"]);
    let named: Vec<&str> = d["candidates"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c["kind"].as_str().unwrap())
        .collect();
    assert!(named.contains(&"delay"), "{d}");
    let f = unlag_json(&[
        "fit", t1, t2, "--order", "2", "--add", "delay", "-o", m, "--json",
    ]);
    assert_eq!(f["delay"].as_u64(), Some(d_true), "{f}");
    assert_eq!(f["effects"][0]["kind"], "delay", "{f}");
    assert_eq!(f["effects"][0]["samples"].as_u64(), Some(d_true), "{f}");
    // The next refit keeps it.
    let g = unlag_json(&["fit", t1, t2, "--order", "2", "-o", m, "--json"]);
    assert_eq!(g["effects"], f["effects"], "{g}");
}

/// The nonlinear-damping cases in detail: the signature across tests is in the evidence with
/// its numbers (damping rising with the step, residual growing faster than the step), the
/// refit finds the quadratic loss that was simulated, and no other case (their tests have
/// different amplitudes too, but a linear probe's damping does not change with them) shows
/// the signature.
#[test]
fn nonlinear_damping_is_named_from_its_amplitude_signature() {
    use unlag::effects::{self, Effect};
    use unlag::fit::Test;
    use unlag::modelling::diagnose::{self, Current};
    for case in cases() {
        let data = case.tests(5);
        let tests: Vec<Test<'_>> = data.iter().map(|(u, y)| Test { name: "t", u, y }).collect();
        let options = case.options();
        let (plain, fx) =
            effects::fit_with(&tests[0], &tests[1..], case.fs, &options, &[]).unwrap();
        let current = Current {
            model: &plain.model,
            effects: &fx,
            method: options.method,
            uncertainty: plain.report.uncertainty.as_ref(),
            order_given: true,
        };
        let evidence = diagnose::evidence(&current, &tests);
        let across = diagnose::per_test(&current, &tests, &evidence);
        let sig = diagnose::amplitude_signature(&across).unwrap();
        eprintln!(
            "{:<45} damping rise {:+.3}, slope {:+.4}, residual exponent {:.2}",
            case.name, sig.damping_rise, sig.damping_slope, sig.residual_exponent
        );
        if case.kind != "nonlinear-damping" {
            assert!(!sig.nonlinear_damping(), "{}: {sig:?}", case.name);
            if case.kind == "none" {
                // A linear probe's damping does not change with the step.
                assert!(sig.damping_rise.abs() < 0.03, "{sig:?}");
            }
            continue;
        }
        assert!(sig.nonlinear_damping(), "{sig:?}");
        assert!(sig.residual_exponent > 1.4, "{sig:?}");
        assert!(sig.damping_slope > 0.0, "{sig:?}");
        // The refit's loss against the one simulated: k = gain * w^2.
        let (f, fx) = effects::fit_with(
            &tests[0],
            &tests[1..],
            case.fs,
            &options,
            &[Effect::NonlinearDamping { gain: 0.0 }],
        )
        .unwrap();
        let w = 2.0 * std::f64::consts::PI * case.mode.0;
        let k = effects::nonlinear_gain(&fx) * w * w;
        let common::hidden::Hidden::NonlinearDamping(k_true) = case.hidden else {
            unreachable!()
        };
        let errors: Vec<f64> = tests[1..]
            .iter()
            .map(|t| unlag::fit::nrmse_of(t.y, &effects::predict(&f.model, &fx, t.u, t.y)))
            .collect();
        eprintln!(
            "{}: k fitted {k:.4}, simulated {k_true}; held-out errors {errors:?} against {:?}",
            case.name,
            evidence[1..].iter().map(|e| e.nrmse).collect::<Vec<_>>()
        );
        assert!((k / k_true - 1.0).abs() < 0.25, "k {k} against {k_true}");
        let candidates = diagnose::diagnose(&current, &tests, &evidence).unwrap();
        let first = &candidates[0];
        assert_eq!(
            first.kind,
            unlag::effects::EffectKind::NonlinearDamping,
            "{candidates:#?}"
        );
        let diagnose::Evidence::NonlinearDamping(nl) = &first.evidence else {
            panic!("{first:?}")
        };
        assert!(nl.residual_exponent > 1.4, "{first:?}");
        assert_eq!(
            first.change.kind(),
            Some(unlag::effects::EffectKind::NonlinearDamping)
        );
    }
}

/// The nonlinear-damping loop through the command line, down to the board: a plain model, the
/// diagnosis, the effect added (the error history falls), `simulate` with it, the compensator
/// with its correction reconstructing a large step better than the linear compensator, the
/// correction carried by every export format (the blob parsed back by the board's parser
/// gives the same reconstruction), and fixed point refused with one clear line.
#[test]
fn nonlinear_damping_through_the_cli_down_to_the_board() {
    use std::process::Command;
    let case = cases()
        .into_iter()
        .find(|c| c.kind == "nonlinear-damping")
        .unwrap();
    let dir = std::env::temp_dir().join(format!("unlag-nonlinear-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let p = |f: &str| dir.join(f).to_str().unwrap().to_string();
    let data = case.tests(3);
    let files: Vec<String> = (0..data.len())
        .map(|i| p(&format!("test{i}.csv")))
        .collect();
    for ((u, y), f) in data.iter().zip(&files) {
        common::write_csv(std::path::Path::new(f), case.fs, u, y);
    }
    // A large step, beyond the tests' amplitudes, with its true reference.
    let big_u = common::step(case.n, case.n / 8, 0.0, 1.5);
    let common::hidden::Hidden::NonlinearDamping(k) = case.hidden else {
        unreachable!()
    };
    let mut rng = common::Rng::new(99);
    let big_y = common::add_noise(
        &common::hidden::quadratic_line(&big_u, case.fs, case.mode, k, case.delay),
        0.002,
        &mut rng,
    );
    let big = p("big.csv");
    common::write_csv(std::path::Path::new(&big), case.fs, &big_u, &big_y);

    let unlag = |args: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_unlag"))
            .args(args)
            .output()
            .unwrap()
    };
    let run = |args: &[&str]| -> serde_json::Value {
        let o = unlag(args);
        let out = String::from_utf8_lossy(&o.stdout).into_owned();
        assert!(
            o.status.success(),
            "{args:?}: {out}{}",
            String::from_utf8_lossy(&o.stderr)
        );
        serde_json::from_str(out.trim()).expect(&out)
    };
    let (model, linear) = (p("probe.toml"), p("linear.toml"));
    let tests: Vec<&str> = files.iter().map(String::as_str).collect();
    let with = |head: &[&str], tail: &[&str]| -> Vec<String> {
        head.iter()
            .chain(&tests)
            .chain(tail)
            .map(|s| s.to_string())
            .collect()
    };
    let args = with(
        &["fit"],
        &["--order", "2", "--fresh", "-o", &model, "--json"],
    );
    run(&args.iter().map(String::as_str).collect::<Vec<_>>());
    std::fs::copy(&model, &linear).unwrap();
    let args = with(&["diagnose", &model], &["--json"]);
    let d = run(&args.iter().map(String::as_str).collect::<Vec<_>>());
    let first = &d["candidates"][0];
    assert_eq!(first["kind"], "nonlinear-damping", "{d}");
    assert!(first["evidence"]["residual_exponent"].as_f64().unwrap() > 1.3);
    assert!(
        first["evidence"]["damping_slope_per_unit_step"]
            .as_f64()
            .unwrap()
            > 0.0
    );
    let args = with(&["compare", &model], &["--json"]);
    let c = run(&args.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(
        c["amplitude_signature"]["residual_exponent"]
            .as_f64()
            .unwrap()
            > 1.3,
        "{c}"
    );

    let args = with(
        &["fit"],
        &[
            "--order",
            "2",
            "--add",
            "nonlinear-damping",
            "-o",
            &model,
            "--json",
        ],
    );
    run(&args.iter().map(String::as_str).collect::<Vec<_>>());
    let file = unlag::file::ModelFile::load(std::path::Path::new(&model)).unwrap();
    let gain = unlag::effects::nonlinear_gain(&file.effects);
    let w = 2.0 * std::f64::consts::PI * case.mode.0;
    assert!((gain * w * w / k - 1.0).abs() < 0.25, "gain {gain}");
    let args = with(&["compare", &model], &["--json"]);
    let c = run(&args.iter().map(String::as_str).collect::<Vec<_>>());
    let history = c["history"].as_array().unwrap();
    let mean = |row: &serde_json::Value| {
        let t = row["tests"].as_array().unwrap();
        t.iter().map(|x| x["nrmse"].as_f64().unwrap()).sum::<f64>() / t.len() as f64
    };
    assert_eq!(history.len(), 2, "{c}");
    assert!(mean(&history[1]) < mean(&history[0]) / 3.0, "{c}");
    assert_eq!(history[1]["effects"][0], "nonlinear-damping");
    // Every test is within 1.5x of its noise floor, and the loss is not named again.
    for t in c["tests"].as_array().unwrap() {
        let (e, floor) = (
            t["nrmse"].as_f64().unwrap(),
            t["noise_floor"].as_f64().unwrap(),
        );
        assert!(e < 1.5 * floor, "{e} against {floor}");
    }
    let args = with(&["diagnose", &model], &["--json"]);
    let d = run(&args.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(
        d["candidates"]
            .as_array()
            .unwrap()
            .iter()
            .all(|c| c["kind"] != "nonlinear-damping"),
        "{d}"
    );
    // simulate applies the loss: the large step is followed far better than by the plain
    // model.
    let s_nl = run(&["simulate", &model, &big, "-o", &p("sim.csv"), "--json"]);
    let s_lin = run(&["simulate", &linear, &big, "-o", &p("sim.csv"), "--json"]);
    let (e_nl, e_lin) = (
        s_nl["nrmse"].as_f64().unwrap(),
        s_lin["nrmse"].as_f64().unwrap(),
    );
    eprintln!("simulate on the large step: {e_nl:.5} with the loss, {e_lin:.5} without");
    assert!(e_nl < e_lin / 3.0, "{e_nl} against {e_lin}");

    // Compensation of the large step, the same band limit for both.
    let mut rebuilt = Vec::new();
    for m in [&model, &linear] {
        let v = run(&[
            "invert",
            m,
            &files[0],
            "--bandwidth",
            "1000",
            "-o",
            m,
            "--json",
        ]);
        rebuilt.push(v["reconstruction"][0]["nrmse_u_hat"].as_f64().unwrap());
    }
    // invert's own numbers include the correction.
    eprintln!("invert's reconstruction of the estimation test: {rebuilt:?}");
    // The default fit (Box-Jenkins) makes the plain linear model a better compensator than
    // output error did (here 2.0 % against 3.7 %), which narrows the correction's margin:
    // measured 1.13x here, 1.25x on the large step below (2.1x and 2.4x against output error).
    assert!(rebuilt[0] < rebuilt[1] / 1.1, "{rebuilt:?}");
    let comp = |m: &str, arith: &str| -> f64 {
        let tag = if m == model { "nl" } else { "lin" };
        let v = run(&[
            "compensate",
            m,
            &big,
            "-o",
            &p(&format!("comp-{tag}-{arith}.csv")),
            "--arithmetic",
            arith,
            "--json",
        ]);
        v["nrmse_u_hat"].as_f64().unwrap()
    };
    let (c_nl, c_lin) = (comp(&model, "f32"), comp(&linear, "f32"));
    let c_nl64 = comp(&model, "f64");
    eprintln!(
        "compensation of the large step: {c_nl:.5} with the correction (f64 {c_nl64:.5}), {c_lin:.5} linear"
    );
    assert!(c_nl < c_lin / 1.2, "{c_nl} against {c_lin}");
    assert!((c_nl - c_nl64).abs() < 0.05 * c_nl64);

    // The board's view: the blob carries the correction; parsed and run by the board's
    // code, it gives what `unlag compensate` gave.
    run(&[
        "export",
        &model,
        "--format",
        "bin",
        "-o",
        &p("nl.bin"),
        "--json",
    ]);
    let bytes = std::fs::read(p("nl.bin")).unwrap();
    let set: unlag::board::blob::CoefficientSet<8> = unlag::board::blob::parse(&bytes).unwrap();
    let correction = set.nonlinear.expect("the correction in the blob");
    let mut st = set.cascade.equilibrium(big_y[0] as f32);
    let mut sn = correction.equilibrium(big_y[0] as f32);
    let board: Vec<f64> = big_y
        .iter()
        .map(|&y| {
            let y = y as f32;
            f64::from(set.cascade.process(&mut st, y) + correction.process(&mut sn, y))
        })
        .collect();
    let text = std::fs::read_to_string(p("comp-nl-f32.csv")).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = header.iter().position(|h| *h == "u_hat").unwrap();
    let host: Vec<f64> = lines
        .map(|l| l.split(',').nth(col).unwrap().parse().unwrap())
        .collect();
    let worst = board
        .iter()
        .zip(&host)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(worst < 1e-3, "board and host differ by {worst}");
    for (format, needle) in [("rust", "NONLINEAR_GAIN"), ("c", "unlag_nonlinear_gain")] {
        let out = p(&format!("nl.{format}"));
        run(&["export", &model, "--format", format, "-o", &out, "--json"]);
        assert!(std::fs::read_to_string(&out).unwrap().contains(needle));
    }
    // The linear model's blob stays format version 1.
    run(&[
        "export",
        &linear,
        "--format",
        "bin",
        "-o",
        &p("lin.bin"),
        "--json",
    ]);
    let lin = std::fs::read(p("lin.bin")).unwrap();
    assert_eq!(
        u16::from_le_bytes([lin[4], lin[5]]),
        unlag::board::blob::FORMAT_VERSION
    );

    // Fixed point does not run the correction: refused, one line, exit 1, nothing written.
    let out = p("nl-fixed.bin");
    let o = unlag(&[
        "export",
        &model,
        "--format",
        "bin",
        "--number-format",
        "fixed",
        "--full-scale",
        "4",
        "-o",
        &out,
    ]);
    assert_eq!(o.status.code(), Some(1));
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.contains("nonlinear damping"), "{err}");
    assert!(!std::path::Path::new(&out).exists());
    let path = std::path::Path::new(&model);
    let file = unlag::file::ModelFile::load(path).unwrap();
    assert!(matches!(
        unlag::export::FixedBoardCoefficients::from_model_file(&file, path, Some(4.0))
            .as_ref()
            .map_err(unlag::error::Error::unadvised),
        Err(unlag::error::Error::UnsupportedOnBoard { .. })
    ));
    let o = unlag(&[
        "compensate",
        &model,
        &big,
        "-o",
        &p("fixed.csv"),
        "--arithmetic",
        "fixed",
    ]);
    assert_eq!(o.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&o.stderr).contains("nonlinear damping"));
}

/// Runs the binary; `(success, stdout, stderr)`.
fn unlag(args: &[&str]) -> (bool, String, String) {
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_unlag"))
        .args(args)
        .output()
        .unwrap();
    (
        o.status.success(),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

fn unlag_json(args: &[&str]) -> serde_json::Value {
    let (ok, out, err) = unlag(args);
    assert!(ok, "{args:?}: {out}{err}");
    serde_json::from_str(out.trim()).expect(&out)
}

/// The two cases' tests written as CSV: `(estimation, validation)` paths.
fn case_files(kind: &str, dir: &std::path::Path) -> (String, String, common::hidden::Case) {
    let case = cases().into_iter().find(|c| c.kind == kind).unwrap();
    let tests = case.tests(11);
    let [(ue, ye), (uv, yv)] = [&tests[0], &tests[1]];
    let (e, v) = (
        dir.join(format!("{kind}-est.csv")),
        dir.join(format!("{kind}-val.csv")),
    );
    common::write_csv(&e, case.fs, ue, ye);
    common::write_csv(&v, case.fs, uv, yv);
    (
        e.to_str().unwrap().to_string(),
        v.to_str().unwrap().to_string(),
        case,
    )
}

/// An offset the plain fit reads by itself is in the model file, and the diagnosis says the
/// model carries it rather than leaving the user with `none` alone: `carried` in `--json`,
/// one line in the text.
#[test]
fn the_diagnosis_lists_what_the_plain_fit_already_carries() {
    let dir = std::env::temp_dir().join(format!("unlag-carried-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (est, val, _) = case_files("offset", &dir);
    let m = dir.join("plain.toml");
    let m = m.to_str().unwrap();
    unlag_json(&["fit", &est, "--order", "2", "-o", m, "--json"]);
    let d = unlag_json(&["diagnose", m, &est, &val, "--json"]);
    assert_eq!(d["carried"], serde_json::json!(["offset"]), "{d}");
    assert!(
        d["candidates"]
            .as_array()
            .unwrap()
            .iter()
            .all(|c| c["kind"] != "offset"),
        "{d}"
    );
    let (ok, text, err) = unlag(&["diagnose", m, &est, &val]);
    assert!(ok, "{err}");
    assert!(text.contains("the model already carries: offset"), "{text}");
    // A model without effects carries nothing.
    let bare = dir.join("bare.toml");
    let bare = bare.to_str().unwrap();
    let (e2, v2, _) = case_files("none", &dir);
    unlag_json(&["fit", &e2, "--order", "2", "-o", bare, "--json"]);
    let d = unlag_json(&["diagnose", bare, &e2, &v2, "--json"]);
    assert_eq!(d["carried"], serde_json::json!([]), "{d}");
}

/// The held-out test's error in the JSON of `unlag fit ... --json`.
fn validation_nrmse(v: &serde_json::Value) -> f64 {
    v["sources"]
        .as_array()
        .unwrap()
        .iter()
        .find(|s| s["role"] == "validation")
        .unwrap()["nrmse"]
        .as_f64()
        .unwrap()
}

/// The path of a trace kept from the drawn bank (`examples/bench_bank.rs`, seed 13 unless its
/// test says another) under `host-tests/data/bank/`.
fn bank_trace(name: &str) -> String {
    format!("{}/host-tests/data/bank/{name}", env!("CARGO_MANIFEST_DIR"))
}

/// A bank case as a user meets it: its two traces (under `host-tests/data/bank/`) and the
/// diagnosis on both of the plain model `unlag fit --order 2` writes from the first, in a
/// scratch folder of its own that goes when the case does.
struct Diagnosed {
    dir: std::path::PathBuf,
    est: String,
    val: String,
    json: serde_json::Value,
}

fn diagnose_bank(tag: &str, est: &str, val: &str) -> Diagnosed {
    let dir = std::env::temp_dir().join(format!("unlag-{tag}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (est, val) = (bank_trace(est), bank_trace(val));
    let model = dir.join("plain.toml").to_str().unwrap().to_string();
    unlag_json(&["fit", &est, "--order", "2", "-o", &model, "--json"]);
    let json = unlag_json(&["diagnose", &model, &est, &val, "--json"]);
    Diagnosed {
        dir,
        est,
        val,
        json,
    }
}

impl Diagnosed {
    /// `unlag fit --order 2` on both traces with `--add kind`, as its change says: the JSON.
    fn fit_adding(&self, kind: &str) -> serde_json::Value {
        self.fit_adding_all(&[kind])
    }

    /// `unlag fit --order 2` on both traces, nothing added, to a model file of its own (a fit
    /// to an existing model file continues that model, with its effects): the JSON.
    fn fit_plain(&self) -> serde_json::Value {
        self.fit_to("plain-on-both.toml", &[])
    }

    /// `unlag fit --order 2` on both traces with `--add` for each of `kinds`: the JSON.
    fn fit_adding_all(&self, kinds: &[&str]) -> serde_json::Value {
        self.fit_to("added.toml", kinds)
    }

    /// `unlag fit --order 2` on both traces with `--add` for each of `kinds`, written to
    /// `file` in the case's folder: the JSON.
    fn fit_to(&self, file: &str, kinds: &[&str]) -> serde_json::Value {
        let model = self.dir.join(file);
        let mut args = vec![
            "fit",
            &self.est,
            &self.val,
            "--order",
            "2",
            "-o",
            model.to_str().unwrap(),
            "--json",
        ];
        for kind in kinds {
            args.extend(["--add", kind]);
        }
        unlag_json(&args)
    }

    /// The validation test's error after `--add kind` ([`Diagnosed::fit_adding`]).
    fn validation_after(&self, kind: &str) -> f64 {
        self.validation_after_all(&[kind])
    }

    /// The validation test's error after `--add` for each of `kinds`.
    fn validation_after_all(&self, kinds: &[&str]) -> f64 {
        let fitted = self.fit_adding_all(kinds);
        let val = &fitted["sources"][1];
        assert_eq!(val["role"], "validation", "{fitted}");
        val["nrmse"].as_f64().unwrap()
    }

    /// The validation test's error before any change and the floor both channels leave on it,
    /// as the diagnosis states them.
    fn validation_before(&self) -> (f64, f64) {
        let val = &self.json["tests"][1];
        (
            val["nrmse"].as_f64().unwrap(),
            val["noise_floor"].as_f64().unwrap(),
        )
    }

    /// The first candidate, asserted to be of `kind` with `how` in its reading.
    fn first_named(&self, kind: &str, how: &str) -> &serde_json::Value {
        let first = &self.json["candidates"][0];
        assert_eq!(first["kind"], kind, "{}", self.json);
        assert!(
            first["reading"].as_str().is_some_and(|r| r.contains(how)),
            "{first}"
        );
        first
    }

    /// Asserts that no leak is offered: the model's DC gain is 1 and no settled creep stands
    /// out of the noise after the step, so its trial is not run.
    fn no_leak_offered(&self) {
        assert!(
            self.json["candidates"]
                .as_array()
                .unwrap()
                .iter()
                .all(|c| c["kind"] != "leak"),
            "{}",
            self.json
        );
    }

    /// Whether any candidate is a temperature, under any damping law.
    fn names_temperature(&self) -> bool {
        self.json["candidates"]
            .as_array()
            .unwrap()
            .iter()
            .any(|c| c["kind"].as_str().unwrap().starts_with("temperature"))
    }
}

impl Drop for Diagnosed {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

/// Bank case 104: a capillary (overdamped, 6.7 kHz sampling) with a hidden line mode near
/// 50 Hz, validated on a valve test. A leak's trial would take the ringing as well as the
/// mode's (both add poles), but the plain model's static gain is 1.004, and a leak lowers it
/// (`1 / (1 + R G)`), and no creep stands out after the step: the leak's trial is not run, and
/// the mode is named.
#[test]
fn a_leak_is_not_tried_where_the_static_gain_is_not_below_one_and_no_creep_settles() {
    let case = diagnose_bank("mode-leak", "mode-est.csv", "mode-val.csv");
    let d = &case.json;
    let c = d["candidates"].as_array().unwrap();
    assert_eq!(c[0]["kind"], "mode", "{d}");
    assert!(c[0]["ordered_by"].is_null(), "{d}");
    case.no_leak_offered();
    let (before, _) = case.validation_before();
    let after = case.validation_after("mode");
    assert!(after < before / 3.0, "{before} -> {after}");
}

/// Bank case 040: a flush sensor whose probe noise is coloured (AR(1), pole 0.90, 10x the
/// white level), validated on a wake traverse. Both the traverse's increments and the noise
/// are slow, so their cross-correlation strays far beyond the white band by chance; read
/// against that band, the residual looked caused by the input and the noise model was never
/// tried (`unexplained`). Against Bartlett's band the noise model is tried, named, and lowers
/// the traverse's error.
#[test]
fn coloured_noise_on_a_traverse_is_named_against_the_band_of_two_slow_series() {
    let case = diagnose_bank(
        "coloured-wake",
        "coloured-wake-est.csv",
        "coloured-wake-val.csv",
    );
    let d = &case.json;
    let first = &d["candidates"][0];
    assert_eq!(first["kind"], "coloured-noise", "{d}");
    let (before, after) = (
        first["nrmse_before"].as_f64().unwrap(),
        first["nrmse_after"].as_f64().unwrap(),
    );
    assert!(before / after >= 1.5, "{before} -> {after}");
    // The traverse's peak cross-correlation is outside the white band, inside Bartlett's.
    let xc = &d["tests"][1]["cross_correlation"];
    let (peak, band) = (
        xc["peak"].as_f64().unwrap().abs(),
        xc["band"].as_f64().unwrap(),
    );
    let n = (xc["values"].as_array().unwrap().len() * 4) as f64;
    assert!(peak < 2.0 * band, "peak {peak}, band {band}");
    assert!(band > 1.5 * 2.576 / n.sqrt(), "band {band}");
}

/// The same case after `--add coloured-noise`: the traverse's error is then a one-step-ahead
/// prediction error, whose floor is not the probe noise's level (what its highest frequencies
/// show, all a traverse has) but the part of the noise no predictor removes, its innovation.
/// The fit states that floor, read from the estimation test's quiet segment as the traverse
/// has none, and the noise model brings the traverse's error to it; against the simulation
/// error's floor it would seem 1.7x short.
#[test]
fn a_noise_model_is_judged_against_the_floor_of_a_prediction_error() {
    let case = diagnose_bank(
        "coloured-floor",
        "coloured-wake-est.csv",
        "coloured-wake-val.csv",
    );
    let fit = case.fit_adding("coloured-noise");
    let val = &fit["sources"][1];
    assert_eq!(val["role"], "validation", "{fit}");
    let floor = &val["prediction_floor"];
    assert!(
        floor["from"]
            .as_str()
            .is_some_and(|f| f.ends_with("coloured-wake-est.csv")),
        "{floor}"
    );
    let (error, prediction, white) = (
        val["nrmse"].as_f64().unwrap(),
        floor["value"].as_f64().unwrap(),
        val["noise_floor"].as_f64().unwrap(),
    );
    assert!(error <= 1.2 * prediction, "{error} against {prediction}");
    assert!(error >= 1.4 * white, "{error} against {white}");
    // Round the loop again: the model with its noise model is at the floor of the error it is
    // judged by, so nothing is missing (against the simulation error's floor it was
    // `unexplained`, "3x what the noise leaves").
    let added = case.dir.join("added.toml");
    let again = unlag_json(&[
        "diagnose",
        added.to_str().unwrap(),
        &case.est,
        &case.val,
        "--json",
    ]);
    assert_eq!(again["candidates"][0]["kind"], "none", "{again}");
    let judged = &again["tests"][1]["prediction"];
    assert!(
        judged["nrmse"].as_f64().unwrap() <= 1.2 * judged["floor"]["value"].as_f64().unwrap(),
        "{judged}"
    );
    // Without a noise model no such floor is stated.
    let plain = case.fit_plain();
    assert!(
        plain["sources"][1].get("prediction_floor").is_none(),
        "{plain}"
    );
}

/// Seed 80's case 040: a flush probe of three sharp modes (damping near 0.016) whose probe
/// noise is coloured, behind a reference as noisy as the probe's white part. What the model
/// leaves carries the reference's noise ringing through each mode, a narrow peak in the
/// residual's spectrum at each: an AR noise model of order up to 4 left the change's
/// one-step-ahead prediction error 1.53x its floor (the error fell 2.35x). The noise model of
/// `--add coloured-noise` goes up to order 32, and the change as printed reaches 1.21x.
#[test]
fn a_noise_model_whitens_the_reference_noise_ringing_through_a_resonant_probe() {
    let case = diagnose_bank(
        "coloured-resonant",
        "coloured-resonant-est.csv",
        "coloured-resonant-val.csv",
    );
    let first = &case.json["candidates"][0];
    assert_eq!(first["kind"], "coloured-noise", "{}", case.json);
    let change = first["change"].as_str().unwrap();
    let command = change.split("   (").next().unwrap();
    let kinds: Vec<&str> = command
        .split_whitespace()
        .collect::<Vec<_>>()
        .windows(2)
        .filter(|w| w[0] == "--add")
        .map(|w| w[1])
        .collect();
    assert_eq!(kinds.first(), Some(&"coloured-noise"), "{change}");
    let fit = case.fit_adding_all(&kinds);
    let val = &fit["sources"][1];
    assert_eq!(val["role"], "validation", "{fit}");
    let (after, floor) = (
        val["nrmse"].as_f64().unwrap(),
        val["prediction_floor"]["value"].as_f64().unwrap(),
    );
    let before = first["nrmse_before"].as_f64().unwrap();
    assert!(after <= 1.35 * floor, "{after} against its floor {floor}");
    assert!(before >= 2.5 * after, "{before} -> {after}");
    // The diagnosis said what the change gives (with the mode beside it, if one is).
    let said = first["beside"]["nrmse_after"]
        .as_f64()
        .or(first["nrmse_after"].as_f64())
        .unwrap();
    assert!((after / said - 1.0).abs() < 0.02, "{after} against {said}");
    // It took a noise model longer than a channel's own (order 4).
    let order = fit["effects"]
        .as_array()
        .unwrap()
        .iter()
        .find(|e| e["kind"] == "coloured-noise")
        .and_then(|e| e["ar"].as_array())
        .map_or(0, Vec::len);
    assert!(order > 4, "{fit}");
}

/// Bank case 088: a pneumatic line (50 Hz) with quadratic losses, one step to fit on and a
/// wake traverse to validate on. No pair of steps shows how the damping grows with the step, so
/// the signature that names nonlinear damping cannot be read; the residual on the traverse
/// stays 12x above the floor and used to be `unexplained`. One model fitted to the step and
/// the traverse together explains both with a quadratic loss where no linear one does: it is
/// named, with the change that fits the loss on both; judged on another traverse held out
/// (`nonlinear-wake-2.csv`, a sibling run), the error falls to near its floor.
#[test]
fn nonlinear_damping_is_named_by_the_tests_fitted_together_and_judged_on_another_run() {
    let case = diagnose_bank("nonlinear-wake", "nonlinear-est.csv", "nonlinear-wake.csv");
    let (dir, est, val, d) = (&case.dir, &case.est, &case.val, &case.json);
    let first = &d["candidates"][0];
    assert_eq!(first["kind"], "nonlinear-damping", "{d}");
    assert_eq!(first["evidence"]["amplitude_signature"], false, "{first}");
    let joint = &first["evidence"]["joint"];
    assert!(joint["fall"].as_f64().unwrap() > 3.0, "{joint}");
    let change = first["change"].as_str().unwrap();
    assert!(
        change.contains("--also ") && change.contains("nonlinear-wake.csv --add nonlinear-damping"),
        "{change}"
    );
    let run = bank_trace("nonlinear-wake-2.csv");
    let held_out = |extra: &[&str]| {
        let out = dir.join("v.toml");
        let mut args = vec!["fit", &est, "--order", "2", "--json", "-o"];
        args.push(out.to_str().unwrap());
        args.extend_from_slice(extra);
        args.push(&run);
        let v = unlag_json(&args);
        let s = v["sources"]
            .as_array()
            .unwrap()
            .iter()
            .find(|s| s["role"] == "validation")
            .unwrap()
            .clone();
        (
            s["nrmse"].as_f64().unwrap(),
            s["noise_floor"].as_f64().unwrap(),
            v,
        )
    };
    let (before, floor, _) = held_out(&[]);
    let (after, _, v) = held_out(&["--also", val, "--add", "nonlinear-damping"]);
    assert!(before > 5.0 * floor, "{before} against a floor of {floor}");
    assert!(
        before / after >= 3.0 && after <= 1.5 * floor,
        "{before} -> {after}, floor {floor}"
    );
    // The traverse fitted on is recorded as an estimation test, the sibling as held out.
    let roles: Vec<&str> = v["sources"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["role"].as_str().unwrap())
        .collect();
    assert_eq!(roles, ["estimation", "estimation", "validation"], "{v}");
    // The uncertainty stated is the joint fit's, from both tests: the damping of the 50 Hz
    // line known to a fraction of a percent, the loss within three of its standard
    // deviations of the drawn 3.64e-9 (as the note states it).
    let u = &v["fit"]["uncertainty"];
    let mode = &u["resonances"][0];
    assert!(
        mode["damping_std"].as_f64().unwrap() < 0.01 * mode["damping"].as_f64().unwrap(),
        "{u}"
    );
    let note = v["fit"]["notes"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|n| n.as_str())
        .find(|n| n.contains("fitted on") && n.contains("+/-"))
        .unwrap_or_else(|| panic!("{v}"))
        .to_string();
    let number = |s: &str| {
        s.trim_end_matches(|c: char| !c.is_ascii_digit())
            .parse::<f64>()
    };
    let after_loss = note.split("a loss of ").nth(1).unwrap();
    let mut words = after_loss.split_whitespace();
    let (loss, _, std) = (words.next().unwrap(), words.next(), words.next().unwrap());
    let (loss, std) = (number(loss).unwrap(), number(std).unwrap());
    assert!((loss - 3.64e-9).abs() < 3.0 * std, "{loss} +/- {std}");
}

/// Bank seed 152, case 043: a flush probe with a light quadratic loss, two steps of other
/// sizes. Fitted on both together, the loss lowers the first step's error (0.306 % to
/// 0.220 %) and raises the second's (0.247 % to 0.258 %), 1.16x in all: the loss is named,
/// right, but the tests do not agree on it, and a further run held out rises with it too
/// (0.283 % to 0.294 %). The diagnosis' reading and the fit's note say which test rose.
#[test]
fn a_loss_that_raises_one_of_the_tests_fitted_together_says_so() {
    let case = diagnose_bank(
        "light-loss",
        "flush-light-loss-est.csv",
        "flush-light-loss-val.csv",
    );
    let d = &case.json;
    let first = &d["candidates"][0];
    assert_eq!(first["kind"], "nonlinear-damping", "{d}");
    let reading = first["reading"].as_str().unwrap();
    assert!(
        reading.contains("the loss raises the error over the linear model's on")
            && reading.contains("flush-light-loss-val.csv (0.247 % -> 0.258 %)")
            && !reading.contains("flush-light-loss-est.csv ("),
        "{reading}"
    );
    // The change as the diagnosis gives it, with a further run held out.
    let run = bank_trace("flush-light-loss-run.csv");
    let fit = |extra: &[&str]| {
        let out = case.dir.join("m.toml");
        let mut args = vec!["fit", &case.est, "--order", "2", "--json", "-o"];
        args.push(out.to_str().unwrap());
        args.extend_from_slice(extra);
        args.push(&run);
        unlag_json(&args)
    };
    let linear = fit(&["--fresh"]);
    let with_loss = fit(&["--fresh", "--also", &case.val, "--add", "nonlinear-damping"]);
    assert!(
        validation_nrmse(&with_loss) > validation_nrmse(&linear),
        "the run held out: {} -> {}",
        validation_nrmse(&linear),
        validation_nrmse(&with_loss)
    );
    let notes = with_loss["fit"]["notes"].to_string();
    assert!(
        notes.contains("flush-light-loss-val.csv (0.247 % -> 0.258 %): it is not confirmed on every test, so judge it on a further test"),
        "{notes}"
    );
    std::fs::remove_dir_all(&case.dir).ok();
}

/// Bank seed 72, case 020: a capillary with a drift, its second round (`unlag fit --add drift`
/// on both steps, then `diagnose` again). A loss fitted on the two steps together ended at
/// zero loss, and its linear part left 1.34x less than the joint linear fit, which had
/// stopped short: the diagnosis named `nonlinear-damping` with a loss of 0 s^2 per unit.
/// The loss is now judged against the best linear model either fit found, and a loss of
/// zero is no loss.
#[test]
fn a_loss_fitted_to_zero_is_not_named_a_loss() {
    let dir = std::env::temp_dir().join(format!("unlag-zero-loss-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let est = bank_trace("capillary-drift-second-round-est.csv");
    let val = bank_trace("capillary-drift-second-round-val.csv");
    let model = dir.join("drift.toml").to_str().unwrap().to_string();
    unlag_json(&[
        "fit", &est, &val, "--order", "2", "--add", "drift", "-o", &model, "--json",
    ]);
    let d = unlag_json(&["diagnose", &model, &est, &val, "--json"]);
    let c = d["candidates"].as_array().unwrap();
    assert!(!c.is_empty(), "{d}");
    for candidate in c {
        assert_ne!(candidate["kind"], "nonlinear-damping", "{candidate}");
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// Bank case 047: a capillary with a drift of 5 % of the step per second, two steps. A
/// quadratic loss refitted on one step takes the drift's shape too and scores as well (within
/// 0.03), but it is read from its trial alone, while the drift's ramp is seen: the drift goes
/// first, and the two are named as close with the test that separates them.
#[test]
fn a_drift_goes_before_nonlinear_damping_read_from_its_trial_alone() {
    let case = diagnose_bank("drift-nl", "drift-est.csv", "drift-val.csv");
    let d = &case.json;
    let c = d["candidates"].as_array().unwrap();
    assert_eq!(c[0]["kind"], "drift", "{d}");
    let nl = c
        .iter()
        .find(|c| c["kind"] == "nonlinear-damping")
        .expect("nonlinear damping still offered");
    assert_eq!(nl["evidence"]["amplitude_signature"], false, "{nl}");
    assert!(
        c[0]["separated_by"]["text"]
            .as_str()
            .is_some_and(|t| t.contains("steps of other sizes")),
        "{d}"
    );
    // A real drift runs before the step too: its slope there agrees with the fitted rate.
    let e = &c[0]["evidence"];
    let (pre, se, rate) = (
        e["pre_step_slope_per_s"].as_f64().unwrap(),
        e["pre_step_slope_se_per_s"].as_f64().unwrap(),
        e["rate_per_s"].as_f64().unwrap(),
    );
    assert!((pre - rate).abs() < 4.0 * se && pre * rate > 0.0, "{e}");
    assert!(
        c[0]["reading"]
            .as_str()
            .unwrap()
            .contains("already before the step"),
        "{}",
        c[0]["reading"]
    );
}

/// `coloured-noise` says which error falls (the one-step-ahead prediction error) and states the
/// parameter uncertainty before and after: before from white noise, after from the noise its
/// AR model whitens.
#[test]
fn coloured_noise_states_the_uncertainty_before_and_after() {
    let dir = std::env::temp_dir().join(format!("unlag-coloured-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let case = cases()
        .into_iter()
        .find(|c| c.kind == "coloured-noise" && c.name.contains("output-error"))
        .unwrap();
    let tests = case.tests(11);
    let [(ue, ye), (uv, yv)] = [&tests[0], &tests[1]];
    let (est, val) = (dir.join("est.csv"), dir.join("val.csv"));
    common::write_csv(&est, case.fs, ue, ye);
    common::write_csv(&val, case.fs, uv, yv);
    let (est, val) = (est.to_str().unwrap(), val.to_str().unwrap());
    let m = dir.join("oe.toml");
    let m = m.to_str().unwrap();
    unlag_json(&[
        "fit", est, val, "--order", "2", "--method", "oe", "-o", m, "--json",
    ]);
    let d = unlag_json(&["diagnose", m, est, val, "--json"]);
    let c = &d["candidates"][0];
    assert_eq!(c["kind"], "coloured-noise", "{d}");
    assert!(
        c["evidence"]["fit"]
            .as_str()
            .unwrap()
            .contains("one-step-ahead prediction error"),
        "{c}"
    );
    let (b, a) = (&c["uncertainty_before"], &c["uncertainty_after"]);
    assert_eq!(b["noise_model"], false, "{c}");
    assert_eq!(a["noise_model"], true, "{c}");
    for u in [b, a] {
        let dc = u["dc_gain_std"].as_f64().unwrap();
        assert!(dc > 0.0 && dc < 0.1, "{u}");
        assert_eq!(u["resonances"].as_array().unwrap().len(), 1, "{u}");
    }
    let (ok, text, err) = unlag(&["diagnose", m, est, val]);
    assert!(ok, "{err}");
    assert!(
        text.contains("stated uncertainty (1 sigma): before"),
        "{text}"
    );
}

/// `sensor-resonance` through the whole product: `fit --add` finds the diaphragm in the
/// reference and prefilters at half of it, `simulate` applies it, the compensator (and so the
/// export) runs the prefilter's sections first.
#[test]
fn sensor_resonance_through_the_command_line() {
    let dir = std::env::temp_dir().join(format!("unlag-sensor-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (est, val, _) = case_files("sensor-resonance", &dir);
    let p = dir.join("plain.toml");
    let s = dir.join("sensor.toml");
    let (p, s) = (p.to_str().unwrap(), s.to_str().unwrap());
    unlag_json(&["fit", &est, &val, "--order", "2", "-o", p, "--json"]);
    let d = unlag_json(&["diagnose", p, &est, &val, "--json"]);
    assert_eq!(d["candidates"][0]["kind"], "sensor-resonance", "{d}");
    // `unlag fit EST VAL --order 2 --add KIND -o OUT --json`.
    let fit_adding = |kind: &str, out: &str| {
        unlag_json(&[
            "fit", &est, &val, "--order", "2", "--add", kind, "-o", out, "--json",
        ])
    };
    let f = fit_adding("sensor-resonance", s);
    let e = &f["effects"][0];
    assert_eq!(e["kind"], "sensor-resonance", "{f}");
    assert_eq!(e["remedy"], "modes", "{f}");
    let fn_hz = e["natural_frequency_hz"].as_f64().unwrap();
    assert!((fn_hz / 2000.0 - 1.0).abs() < 0.05, "{fn_hz}");
    // The transducers' modes are in the model: order 2 + 2, no prefilter.
    assert_eq!(e["prefilter_hz"].as_f64().unwrap(), 0.0, "{f}");
    assert_eq!(f["a"].as_array().map(Vec::len), Some(4), "{f}");
    let sections = f["inverse"]["sections"].as_array().unwrap().len();
    // The paper's way is still there: both channels prefiltered, the prefilter on the board.
    let pre = dir.join("prefilter.toml");
    let g = fit_adding("sensor-resonance-prefilter", pre.to_str().unwrap());
    assert!(
        (g["effects"][0]["prefilter_hz"].as_f64().unwrap() - 0.5 * fn_hz).abs() < 0.05 * fn_hz,
        "{g}"
    );
    assert!(
        g["inverse"]["method"]
            .as_str()
            .unwrap()
            .starts_with("sensor-resonance prefilter"),
        "{g}"
    );
    let out = dir.join("y.csv");
    let o = out.to_str().unwrap();
    let plain = unlag_json(&["simulate", p, &val, "-o", o, "--json"])["nrmse"]
        .as_f64()
        .unwrap();
    let with = unlag_json(&["simulate", s, &val, "-o", o, "--json"])["nrmse"]
        .as_f64()
        .unwrap();
    // Against the measured probe, not a prefiltered one: the error falls 3x or to within
    // 1.5x of the validation test's noise floor.
    let floor = f["sources"][1]["noise_floor"].as_f64().unwrap();
    assert!(
        with * 3.0 < plain || with < 1.5 * floor,
        "{with} against {plain} (floor {floor})"
    );
    // And the reconstruction against the reference improves on the plain model's (written
    // beside: compensate does not replace simulate's output).
    let compensated = dir.join("u_hat.csv");
    let o = compensated.to_str().unwrap();
    let c = unlag_json(&["compensate", s, &val, "-o", o, "--json"]);
    let (u_hat, raw) = (
        c["nrmse_u_hat"].as_f64().unwrap(),
        c["nrmse_raw"].as_f64().unwrap(),
    );
    assert!(u_hat < raw, "{c}");
    let c0 = unlag_json(&["compensate", p, &val, "-o", o, "--json"]);
    let u_hat_plain = c0["nrmse_u_hat"].as_f64().unwrap();
    eprintln!("u_hat: plain {u_hat_plain}, with the transducers' modes {u_hat}, raw {raw}");
    assert!(u_hat < u_hat_plain, "{c} against {c0}");
    let bin = dir.join("s.bin");
    let x = unlag_json(&[
        "export",
        s,
        "--format",
        "bin",
        "-o",
        bin.to_str().unwrap(),
        "--json",
    ]);
    assert_eq!(x["sections"].as_u64().unwrap() as usize, sections, "{x}");
}

/// `temperature` through the whole product: `fit --add temperature`, then `simulate`,
/// `compensate` and `export` at the gas temperature of the recording; a model without the
/// effect refuses `--temperature` in one line.
#[test]
fn temperature_through_the_command_line() {
    let dir = std::env::temp_dir().join(format!("unlag-temperature-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (est, val, case) = case_files("temperature", &dir);
    let t_val = match case.hidden {
        common::hidden::Hidden::Temperature(t) => t,
        _ => unreachable!(),
    };
    let t = format!("{t_val}");
    let m = dir.join("t.toml");
    let p = dir.join("plain.toml");
    let (m, p) = (m.to_str().unwrap(), p.to_str().unwrap());
    unlag_json(&["fit", &est, &val, "--order", "2", "-o", p, "--json"]);
    let d = unlag_json(&["diagnose", p, &est, &val, "--json"]);
    assert_eq!(d["candidates"][0]["kind"], "temperature", "{d}");
    let ratio = d["candidates"][0]["evidence"]["temperature_ratio"]
        .as_f64()
        .unwrap();
    assert!((ratio / (t_val / 293.15) - 1.0).abs() < 0.03, "{ratio}");
    unlag_json(&[
        "fit",
        &est,
        &val,
        "--order",
        "2",
        "--add",
        "temperature",
        "-o",
        m,
        "--json",
    ]);
    // One output per command: compensate does not replace simulate's output.
    let at = |model: &str, extra: &[&str], cmd: &str, key: &str| {
        let out = dir.join(format!("{cmd}.csv"));
        let o = out.to_str().unwrap();
        let mut args = vec![cmd, model, val.as_str(), "-o", o, "--json"];
        args.extend_from_slice(extra);
        unlag_json(&args)[key].as_f64().unwrap()
    };
    let hot = at(m, &["--temperature", &t], "simulate", "nrmse");
    let cold = at(m, &["--temperature", "293.15"], "simulate", "nrmse");
    assert!(hot * 3.0 < cold, "{hot} against {cold}");
    let hot = at(m, &["--temperature", &t], "compensate", "nrmse_u_hat");
    let cold = at(m, &[], "compensate", "nrmse_u_hat");
    assert!(hot < cold, "{hot} against {cold}");
    let rs = dir.join("t.rs");
    unlag_json(&[
        "export",
        m,
        "--format",
        "rust",
        "--temperature",
        &t,
        "-o",
        rs.to_str().unwrap(),
        "--json",
    ]);
    let (ok, _, err) = unlag(&[
        "export",
        p,
        "--format",
        "rust",
        "--temperature",
        "300",
        "-o",
        rs.to_str().unwrap(),
    ]);
    assert!(
        !ok && err.lines().count() == 1 && err.contains("temperature"),
        "{err}"
    );
}

/// Issue 7, the board's share of `temperature`: `export --temperatures` writes a bank of sets
/// (Rust and C; `bin` and a model without the effect are refused in one line, writing
/// nothing), and the board's `TemperatureBank`, built from exactly the exported numbers and
/// given the validation test's true gas temperature, reconstructs that test (recorded 50 K
/// above the model's) better than the reference-temperature set; a swap from the reference set
/// to the true one in the middle of the step does not disturb the output.
#[test]
fn temperature_bank_picks_the_set_for_the_measured_temperature() {
    use unlag::board::compensator::TemperatureBank;
    use unlag::export::bank::{BoardBank, TemperatureRange};
    let dir = std::env::temp_dir().join(format!("unlag-tempbank-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (est, val, case) = case_files("temperature", &dir);
    let common::hidden::Hidden::Temperature(t_val) = case.hidden else {
        unreachable!()
    };
    let m = dir.join("t.toml");
    let p = dir.join("plain.toml");
    let (m, p) = (m.to_str().unwrap(), p.to_str().unwrap());
    unlag_json(&["fit", &est, &val, "--order", "2", "-o", p, "--json"]);
    let fit = unlag_json(&[
        "fit",
        &est,
        &val,
        "--order",
        "2",
        "--add",
        "temperature",
        "-o",
        m,
        "--json",
    ]);
    let reference_k = fit["effects"][0]["reference_k"].as_f64().unwrap();

    // The command line: Rust and C tables; refusals write nothing.
    let rs = dir.join("bank.rs");
    let x = unlag_json(&[
        "export",
        m,
        "--format",
        "rust",
        "--temperatures",
        "253:353:10",
        "-o",
        rs.to_str().unwrap(),
        "--json",
    ]);
    assert_eq!(x["temperatures_k"].as_array().unwrap().len(), 11, "{x}");
    let sections = x["sections"].as_u64().unwrap() as usize;
    let h = dir.join("bank.h");
    unlag_json(&[
        "export",
        m,
        "--format",
        "c",
        "--temperatures",
        "253:353:10",
        "-o",
        h.to_str().unwrap(),
        "--json",
    ]);
    let header = std::fs::read_to_string(&h).unwrap();
    assert!(
        header.contains("#define UNLAG_BANK_SET_COUNT 11u"),
        "{header}"
    );
    assert!(header.contains("unlag_bank_select(uint32_t current, float temp_k)"));
    for (model, format, range, extra, what) in [
        (p, "rust", "253:353:10", None, "temperature"),
        (m, "bin", "253:353:10", None, "bank"),
        (m, "rust", "253:353", None, "FROM:TO:STEP"),
        (m, "c", "253:353:10", Some("fixed"), "f32 only"),
    ] {
        let out = dir.join(format!("refused-{format}-{what}"));
        let mut args = vec![
            "export",
            model,
            "--format",
            format,
            "--temperatures",
            range,
            "-o",
            out.to_str().unwrap(),
        ];
        if let Some(number_format) = extra {
            args.extend(["--number-format", number_format]);
        }
        let (ok, _, err) = unlag(&args);
        assert!(
            !ok && err.lines().count() == 1 && err.contains(what),
            "{model} {format}: {err}"
        );
        assert!(!out.exists(), "{}", out.display());
    }

    // The same library call the exporter makes: the Rust file holds exactly these numbers.
    let file = unlag::file::ModelFile::load(std::path::Path::new(m)).unwrap();
    let range = TemperatureRange::parse("253:353:10").unwrap();
    let exported = BoardBank::from_model_file(&file, std::path::Path::new(m), &range).unwrap();
    assert_eq!(
        std::fs::read_to_string(&rs).unwrap(),
        exported.to_rust("t.toml")
    );
    assert!(exported.sets.iter().all(|s| s.sections.len() == sections));
    let bank: TemperatureBank<f32, 11, 16> = exported.board_bank().unwrap();

    // The validation test, recorded at t_val, through the board's f32 bank.
    let tests = case.tests(11);
    let (u, y) = (&tests[1].0, &tests[1].1);
    let run = |temperature_at: &dyn Fn(usize) -> f32| {
        let mut ch = bank.channel(temperature_at(0), y[0] as f32);
        let mut swaps = 0;
        let out: Vec<f64> = y
            .iter()
            .enumerate()
            .map(|(k, &v)| {
                swaps += usize::from(bank.set_temperature(&mut ch, temperature_at(k)));
                f64::from(bank.process(&mut ch, v as f32))
            })
            .collect();
        (out, ch.selected(), swaps)
    };
    let error = |out: &[f64]| unlag::design::inverse::aligned_error(u, out, 0..=60);
    let (hot, hot_set, _) = run(&|_| t_val as f32);
    let (cold, cold_set, _) = run(&|_| reference_k as f32);
    assert_eq!(bank.temperatures_k()[hot_set], 343.0);
    assert_eq!(bank.temperatures_k()[cold_set], 293.0);
    let ((e_hot, lag_hot), (e_cold, lag_cold)) = (error(&hot), error(&cold));
    eprintln!(
        "validation at {t_val} K: bank at {t_val} K {:.4} % (lag {lag_hot}), reference set {:.4} % (lag {lag_cold})",
        100.0 * e_hot,
        100.0 * e_cold
    );
    assert!(e_hot < e_cold, "{e_hot} against {e_cold}");
    // Most of that error is the design's own low-pass rounding the step, the same for both.
    // Against what each set is designed to give (its low-pass of the reference pressure), the
    // error is the model's mismatch (and the noise): there the true temperature's set wins
    // clearly.
    let ideal = |t: f64| {
        let d = unlag::pipeline::at_temperature(&file, t)
            .unwrap()
            .inverse
            .unwrap();
        let (g, lp) = d.lowpass_sections(case.fs).unwrap();
        let c = unlag::board::compensator::CascadeCoefficients::<f64, 8>::new(g, &lp).unwrap();
        let mut st = c.equilibrium(u[0]);
        u.iter()
            .map(|&v| c.process(&mut st, v))
            .collect::<Vec<f64>>()
    };
    let mismatch = |out: &[f64], set: usize| {
        let t = f64::from(bank.temperatures_k()[set]);
        unlag::design::inverse::aligned_error(&ideal(t), out, 0..=60).0
    };
    let (m_hot, m_cold) = (mismatch(&hot, hot_set), mismatch(&cold, cold_set));
    eprintln!(
        "against each set's band-limited reference: bank {:.4} %, reference set {:.4} %",
        100.0 * m_hot,
        100.0 * m_cold
    );
    assert!(m_hot < 0.75 * m_cold, "{m_hot} against {m_cold}");

    // A thermocouple that reads the reference until 40 samples into the step (the output is
    // in the middle of its transient), then the true temperature: one swap. The hot set warms
    // up beside the reference one for the exported WARM_UP_SAMPLES, then takes over: the
    // output is the reference set's run, then the hot set's, with nothing in between. At once
    // (no warm-up) it is off by a large part of the step.
    let onset = case.n / 5;
    let switch = onset + 40;
    let w = exported.warm_up_samples as usize;
    assert!((1..1000).contains(&w), "{w}");
    let reading = |k: usize| {
        if k < switch {
            reference_k as f32
        } else {
            t_val as f32
        }
    };
    let (swapped, set, swaps) = run(&reading);
    assert_eq!((set, swaps), (hot_set, 1));
    let spliced = |k: usize| if k < switch + w { cold[k] } else { hot[k] };
    let seamless = (0..swapped.len())
        .map(|k| (swapped[k] - spliced(k)).abs())
        .fold(0.0, f64::max);
    let at_once: TemperatureBank<f32, 11, 16> = TemperatureBank::new(
        &exported.temperatures_k,
        &exported.gains(),
        &exported.sections(),
        exported.hysteresis_k,
        0,
    )
    .unwrap();
    let mut ch = at_once.channel(reading(0), y[0] as f32);
    let jumped = y
        .iter()
        .enumerate()
        .map(|(k, &v)| {
            at_once.set_temperature(&mut ch, reading(k));
            (f64::from(at_once.process(&mut ch, v as f32))
                - if k < switch { cold[k] } else { hot[k] })
            .abs()
        })
        .fold(0.0, f64::max);
    eprintln!(
        "swap at sample {switch} (a step of 0.65), warm-up {w} samples: off the two sets' own runs by at most {seamless:.2e}; handed over at once: {jumped:.4}"
    );
    assert!(seamless < 1e-4, "{seamless}");
    assert!(jumped > 0.05, "{jumped}");
}

/// Bank case 107: a capillary (Bergh-Tijdeman line, 2.28 m x 0.67 mm into 156 mm3, damping
/// 2.9) fitted on a step at 293 K and validated on a balloon in gas at 350.4 K. Its fast corner
/// trades with the delay, so the corners of the two tests did not move by one factor and the
/// diagnosis said `drift`. The dominant corner and the whole lag both read 0.87: the capillary
/// is slower, and a hotter gas is what slows a line whose pressure diffuses (every time scale
/// goes as the viscosity). The diffusive law is named, reads the temperature the right way
/// round, and lowers the balloon's error.
#[test]
fn a_capillary_in_hotter_gas_is_named_by_the_viscosity_that_slows_it() {
    let case = diagnose_bank(
        "capillary-hot",
        "capillary-hot-est.csv",
        "capillary-hot-val.csv",
    );
    let d = &case.json;
    let first = &d["candidates"][0];
    assert_eq!(first["kind"], "temperature-diffusive", "{d}");
    // 350.4 K over 293.15 K is 1.195.
    let ratio = first["evidence"]["temperature_ratio"].as_f64().unwrap();
    assert!((1.1..1.3).contains(&ratio), "T/T_ref {ratio}");
    let (before, after) = (
        first["nrmse_before"].as_f64().unwrap(),
        first["nrmse_after"].as_f64().unwrap(),
    );
    assert!(before / after >= 3.0, "{before} -> {after}");
    // Its change, made: the balloon's error falls as the trial said.
    let f = case.fit_adding("temperature-diffusive");
    let held_out = f["sources"][1]["nrmse"].as_f64().unwrap();
    assert!(held_out < 0.5 * before, "{held_out} against {before}");
}

/// Bank case 053: an overdamped probe (the bank's lumped generator, damping 2.9) fitted on a
/// step and validated on a balloon at another gas temperature. The delay search took one
/// sample too many from the fast corner (delays 5 to 7 within 0.3 %), leaving a pole on the
/// negative real axis: a model with no continuous-time equivalent, which a temperature cannot
/// scale, so adding the temperature changed nothing (2.245 % before and after) and the
/// diagnosis said `drift`. A fit with a temperature now steps back to a delay whose model can
/// be scaled when it explains the step as well, says so, and the balloon's error falls to its
/// floor.
#[test]
fn a_temperature_steps_back_from_a_delay_whose_model_cannot_be_scaled() {
    let case = diagnose_bank(
        "capillary-cold",
        "capillary-cold-est.csv",
        "capillary-cold-val.csv",
    );
    let d = &case.json;
    let first = &d["candidates"][0];
    assert!(
        first["kind"].as_str().unwrap().starts_with("temperature"),
        "{d}"
    );
    let before = first["nrmse_before"].as_f64().unwrap();
    // The drift its first diagnosis named is not offered: the line through the balloon's
    // residual climbs, but by the end of the record the residual is back at its level before
    // the step (a hump the dynamics leave, which a sensor's drift is not).
    assert!(
        !d["candidates"]
            .as_array()
            .unwrap()
            .iter()
            .any(|c| c["kind"] == "drift"),
        "{d}"
    );
    let balloon = &d["tests"][1];
    let level = |key: &str| balloon["trend"][key].as_f64().unwrap_or(f64::INFINITY);
    let trend = unlag::evidence::Trend {
        pre_mean: level("pre_mean"),
        pre_slope_per_s: level("pre_slope_per_s"),
        pre_slope_se_per_s: level("pre_slope_se_per_s"),
        late_mean: level("late_mean"),
        late_slope_per_s: level("late_slope_per_s"),
        slope_per_s: level("slope_per_s"),
        pre_mean_se: level("pre_mean_se"),
        late_mean_se: level("late_mean_se"),
    };
    // The sample rate from the record's time column.
    let times: Vec<f64> = std::fs::read_to_string(&case.val)
        .unwrap()
        .lines()
        .skip(1)
        .take(2)
        .map(|l| l.split(',').next().unwrap().parse().unwrap())
        .collect();
    let (kept, _) = unlag::modelling::diagnose::ramp_kept(
        &trend,
        balloon["samples"].as_u64().unwrap() as usize,
        balloon["step_onset"].as_u64().unwrap() as usize,
        1.0 / (times[1] - times[0]),
    )
    .expect("a segment before the step and a line");
    assert!(kept < unlag::modelling::diagnose::RAMP_KEPT_BELOW, "{kept}");
    let f = case.fit_adding(first["kind"].as_str().unwrap());
    let notes = f["fit"]["notes"].to_string();
    assert!(notes.contains("negative real axis"), "{notes}");
    let (held_out, floor) = (
        f["sources"][1]["nrmse"].as_f64().unwrap(),
        f["sources"][1]["noise_floor"].as_f64().unwrap(),
    );
    assert!(
        held_out < before / 3.0 && held_out < 1.5 * floor,
        "{before} -> {held_out} (floor {floor})"
    );
}

/// Bank seed 24, case 025: a capillary with a quadratic loss, fitted on a step and validated on
/// a valve test of another size. The second-order model misses the valve's tail (92 units low a
/// tenth of a second after it, back at its level before it by the end), and a line through
/// that residual climbs: the diagnosis said `drift`, whose trial halves the miss. A sensor's
/// drift runs on to the end of the record; this ramp keeps nothing of its rise there, so no
/// drift is offered. The loss fitted on both tests together is named, as the bank hid it: until
/// the joint fit searched in `w = z - 1` as well (stop 55), it stopped short of the loss and the
/// residual above the floor was said to be unexplained.
#[test]
fn a_hump_that_comes_back_by_the_end_of_the_record_is_not_a_drift() {
    let case = diagnose_bank(
        "capillary-hump",
        "capillary-hump-est.csv",
        "capillary-hump-val.csv",
    );
    let d = &case.json;
    let c = d["candidates"].as_array().unwrap();
    assert!(!c.iter().any(|c| c["kind"] == "drift"), "{d}");
    assert_eq!(c[0]["kind"], "nonlinear-damping", "{d}");
    assert!(c[0]["change"].as_str().unwrap().contains("--also"), "{d}");
    let (before, after) = (
        c[0]["nrmse_before"].as_f64().unwrap(),
        c[0]["nrmse_after"].as_f64().unwrap(),
    );
    assert!(after < before / 1.15, "{before} -> {after}");
    // The valve's residual: a line through it climbs, its level at the end is where it was
    // before the step.
    let trend = &d["tests"][1]["trend"];
    let (pre, late, se) = (
        trend["pre_mean"].as_f64().unwrap(),
        trend["late_mean"].as_f64().unwrap(),
        trend["late_mean_se"]
            .as_f64()
            .unwrap()
            .hypot(trend["pre_mean_se"].as_f64().unwrap()),
    );
    assert!((late - pre).abs() < 5.0 * se, "{trend}");
    assert!(
        trend["slope_per_s"].as_f64().unwrap().abs() > 10.0,
        "{trend}"
    );
}

/// Bank seed 30, case 023: a capillary (an overdamped probe, 2.4 kHz) fitted on a step and
/// validated on a wake traverse recorded from the middle of it. Simulated from rest, the plain
/// model missed the traverse's first 0.2 s by up to 180 Pa (6.2 % of the range, 3.7 times the
/// floor both channels' noise leaves), and the diagnosis said `drift`. A record with no quiet
/// segment is simulated from the state that best explains it: the same model is at the floor
/// on the traverse and nothing is missing.
#[test]
fn a_traverse_caught_mid_motion_is_simulated_from_the_state_that_explains_it() {
    let case = diagnose_bank(
        "capillary-traverse",
        "capillary-traverse-est.csv",
        "capillary-traverse-val.csv",
    );
    let d = &case.json;
    let traverse = &d["tests"][1];
    let (error, floor) = (
        traverse["nrmse"].as_f64().unwrap(),
        traverse["noise_floor"].as_f64().unwrap(),
    );
    assert!(error < 1.2 * floor, "{error} against {floor}");
    assert_eq!(d["candidates"][0]["kind"], "none", "{d}");
    // `simulate` says the same, and its output starts where the probe was.
    let out = case.dir.join("sim.csv");
    let model = case.dir.join("plain.toml");
    let (ok, stdout, stderr) = unlag(&[
        "simulate",
        model.to_str().unwrap(),
        &case.val,
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(ok, "{stderr}");
    let said: f64 = format!("{stdout}{stderr}")
        .split("nrmse ")
        .nth(1)
        .and_then(|s| s.split(' ').next())
        .and_then(|s| s.parse().ok())
        .expect("simulate states its error");
    assert!(
        (said - 100.0 * error).abs() < 2e-3,
        "{said} % against {error}"
    );
    let first: Vec<f64> = std::fs::read_to_string(&out)
        .unwrap()
        .lines()
        .skip(1)
        .take(50)
        .map(|l| {
            let v: Vec<f64> = l.split(',').map(|x| x.parse().unwrap()).collect();
            v[2] - v[3]
        })
        .collect();
    let mean = first.iter().sum::<f64>() / first.len() as f64;
    assert!(
        mean.abs() < 30.0,
        "the first 50 samples miss by {mean} on average"
    );
}

/// Bank case 032: a pneumatic line with a second mode (the model error peaks 7 dB out at
/// 584 Hz), fitted on a step and validated on a wake traverse. The model's DC gain is 1 and no
/// creep stands out of the noise: neither of a leak's signatures, so its trial (which took the
/// traverse's error lower than the mode's) is not run, and the mode is named.
#[test]
fn a_leak_without_its_signatures_is_not_tried_beside_a_mode_whose_peak_was_seen() {
    let case = diagnose_bank("mode-wake", "mode-wake-est.csv", "mode-wake-val.csv");
    let d = &case.json;
    let first = &d["candidates"][0];
    assert_eq!(first["kind"], "mode", "{d}");
    case.no_leak_offered();
    assert!(
        first["nrmse_after"].as_f64().unwrap() < 0.7 * first["nrmse_before"].as_f64().unwrap(),
        "{first}"
    );
}

/// Bank case 000: a pneumatic probe (71.6 Hz, damping 0.22) with no hidden effect, a valve
/// step to fit on, a sibling valve run and a balloon burst held out. `fit --also` fits one
/// linear model to both runs: the resonance is stated 1.2x narrower than from the first run
/// alone, the balloon's error does not rise, the sibling run is recorded as an estimation test,
/// and the compensator is judged on the balloon alone (not on a run the model was fitted on).
#[test]
fn runs_fitted_together_give_one_model_judged_on_the_test_held_out() {
    let dir = std::env::temp_dir().join(format!("unlag-plain-runs-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (est, run, val) = (
        bank_trace("plain-est.csv"),
        bank_trace("plain-run.csv"),
        bank_trace("plain-val.csv"),
    );
    let out = dir.join("m.toml");
    let out = out.to_str().unwrap();
    let fit = |extra: &[&str]| {
        let mut args = vec!["fit", &est, "--order", "2", "--json", "-o", out];
        args.extend_from_slice(extra);
        args.push(&val);
        unlag_json(&args)
    };
    let frequency = |v: &serde_json::Value| {
        let r = &v["fit"]["uncertainty"]["resonances"][0];
        (
            r["natural_frequency_hz"].as_f64().unwrap(),
            r["natural_frequency_std_hz"].as_f64().unwrap(),
        )
    };
    let alone = fit(&["--fresh"]);
    let together = fit(&["--fresh", "--also", &run]);
    let roles: Vec<&str> = together["sources"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["role"].as_str().unwrap())
        .collect();
    assert_eq!(
        roles,
        ["estimation", "estimation", "validation"],
        "{together}"
    );
    let ((f1, s1), (fj, sj)) = (frequency(&alone), frequency(&together));
    assert!(s1 > 1.2 * sj, "alone {f1} +/- {s1}, together {fj} +/- {sj}");
    assert!(
        validation_nrmse(&together) <= 1.02 * validation_nrmse(&alone),
        "{} against {}",
        validation_nrmse(&together),
        validation_nrmse(&alone)
    );
    let notes = together["fit"]["notes"].to_string();
    assert!(notes.contains("plain-run.csv together"), "{notes}");
    let judged: Vec<&str> = together["inverse"]["reconstruction"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r["file"].as_str().unwrap())
        .collect();
    assert_eq!(judged, [val.as_str()], "{together}");
    std::fs::remove_dir_all(&dir).ok();
}

/// The kinds a diagnosis names, best first.
fn named(d: &serde_json::Value) -> Vec<String> {
    d["candidates"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c["kind"].as_str().unwrap().to_string())
        .collect()
}

/// Case 036 of the bank drawn from seed 14: a flush sensor at 1 MHz (a diaphragm at 99 kHz,
/// damping 0.003) with no hidden effect, whose reference is twenty times noisier through the
/// model than the probe (what both channels leave, 2.7 % of the range, against the probe's
/// own 0.12 %). That noise rings through the lightly damped model into the residual, which
/// is coloured, and a noise model lowers its one-step-ahead error 7x: it was named
/// `coloured-noise` with a margin of 2. The probe's own noise before the step is white, so a
/// noise model on the probe is not what is missing, and nothing is.
#[test]
fn a_white_probe_behind_a_noisy_reference_gets_no_noise_model() {
    let case = diagnose_bank(
        "noisy-reference",
        "flush-noisy-reference-est.csv",
        "flush-noisy-reference-val.csv",
    );
    let d = &case.json;
    let kinds = named(d);
    assert!(!kinds.iter().any(|k| k == "coloured-noise"), "{d}");
    assert_eq!(kinds.first().map(String::as_str), Some("none"), "{d}");
    // The residual is coloured, beyond a white floor: this is the case the gate is for.
    assert!(
        d["tests"][0]["autocorrelation"]["p_value"]
            .as_f64()
            .unwrap()
            < 1e-3,
        "{d}"
    );
}

/// Case 031 of seed 14's bank: a pneumatic probe whose own noise is coloured (its quiet
/// segment's std 2.2 times its innovation's), validated on a step. The slow noise lifts the
/// residual's correlation with the input out of its white band on both tests, which read as
/// a cause in the input, so the noise model was never tried and `mode` was named. The quiet
/// segment shows the colour is the probe's own: the noise model is tried, named first, and
/// lowers the error.
#[test]
fn coloured_probe_noise_is_tried_where_the_residual_seems_caused_by_the_input() {
    let case = diagnose_bank(
        "coloured-input",
        "coloured-input-est.csv",
        "coloured-input-val.csv",
    );
    let d = &case.json;
    let first = &d["candidates"][0];
    assert_eq!(first["kind"], "coloured-noise", "{d}");
    let own = first["evidence"]["probe_noise_predictability"]
        .as_f64()
        .unwrap();
    assert!(own > 1.5, "{first}");
    let (before, after) = (
        first["nrmse_before"].as_f64().unwrap(),
        first["nrmse_after"].as_f64().unwrap(),
    );
    assert!(before / after >= 1.5, "{before} -> {after}");
    // The residual correlates with the input beyond the white band on some test.
    let caused = d["tests"].as_array().unwrap().iter().any(|t| {
        let xc = &t["cross_correlation"];
        xc["peak"].as_f64().unwrap().abs() > 2.0 * xc["band"].as_f64().unwrap()
    });
    assert!(caused, "{d}");
}

/// Case 019 of seed 14's bank: a capillary with a hidden leak, validated on a balloon. The
/// leak's creep after the step leaves a broad hump at the bottom of the residual's spectrum,
/// 31 dB out of the floor at 2 Hz but with a Q about 1; read as a resonance, `mode` went
/// before the leak, which scored more. A resonance is narrow (Q at least 2): the leak goes
/// first.
#[test]
fn a_creeps_broad_hump_does_not_put_a_mode_before_a_leak() {
    let case = diagnose_bank("leak-creep", "leak-creep-est.csv", "leak-creep-val.csv");
    let d = &case.json;
    assert_eq!(named(d).first().map(String::as_str), Some("leak"), "{d}");
    let mode = d["candidates"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["kind"] == "mode")
        .expect("the mode is still offered");
    assert!(mode["evidence"]["q"].as_f64().unwrap() < 2.0, "{mode}");
    assert!(
        mode["evidence"]["above_floor_db"].as_f64().unwrap() >= 20.0,
        "{mode}"
    );
}

/// Case 033 of seed 15's bank: a pneumatic probe whose transducers ring at 2.3 kHz, validated
/// on a valve test. The reference rings there in both tests; the probe shows no peak near it
/// (the line before its transducer filters the ringing out), so the signature that wanted a
/// probe peak beside the reference's was never read, and the mode's trial, two free poles and
/// zeros that land on the same model, was named. A reference that rings at one frequency in
/// every step is its transducer: the sensor resonance is tried and goes first.
#[test]
fn a_reference_ringing_in_every_step_names_the_transducers_the_probe_hides() {
    let case = diagnose_bank(
        "sensor-unseen",
        "sensor-unseen-est.csv",
        "sensor-unseen-val.csv",
    );
    let d = &case.json;
    let first = &d["candidates"][0];
    assert_eq!(first["kind"], "sensor-resonance", "{d}");
    let evidence = &first["evidence"];
    assert!(evidence.get("probe_peak_hz").is_none(), "{evidence}");
    let f = evidence["reference_peak_hz"].as_f64().unwrap();
    assert!((2.1e3..2.5e3).contains(&f), "{evidence}");
    // Both tests' references ring there.
    for t in d["tests"].as_array().unwrap() {
        let r = t["reference_ringing"]["frequency_hz"].as_f64().unwrap();
        assert!((r / f - 1.0).abs() < 0.15, "{t}");
    }
    let (before, after) = (
        first["nrmse_before"].as_f64().unwrap(),
        first["nrmse_after"].as_f64().unwrap(),
    );
    assert!(before / after >= 1.15, "{before} -> {after}");
}

/// Case 087 of seed 20's bank: a pneumatic probe whose two transducers ring at about 1.4 kHz,
/// validated on a burst balloon. The second-order fit met the transducers' rise with a short
/// delay (12 samples, the probe's is 19), and the sensor-resonance trial kept that delay, so
/// no trial lowered the held-out error and the diagnosis said `unexplained`. The trial now
/// searches the delay again too, and the change it names brings the validation error down
/// more than twofold.
#[test]
fn a_sensor_trial_searches_the_delay_its_modes_move() {
    let case = diagnose_bank(
        "sensor-late-onset",
        "sensor-late-onset-est.csv",
        "sensor-late-onset-val.csv",
    );
    let d = &case.json;
    let first = &d["candidates"][0];
    assert_eq!(first["kind"], "sensor-resonance", "{d}");
    let f = first["evidence"]["reference_peak_hz"].as_f64().unwrap();
    assert!((1.3e3..1.6e3).contains(&f), "{first}");
    let change = first["change"].as_str().unwrap();
    let add = change
        .split("--add ")
        .nth(1)
        .unwrap()
        .split_whitespace()
        .next()
        .unwrap();
    let before = first["nrmse_before"].as_f64().unwrap();
    let after = case.validation_after(add);
    assert!(before / after >= 2.0, "{before} -> {after}");
}

/// Case 002 of seed 20's bank: a pneumatic probe with a slow drift (too small to show),
/// validated on a fast valve whose chamber rings at about 250 Hz. That ringing is in the
/// pressure, so the reference shows it, and the second-order model leaves it in the probe's
/// residual too: a sensor resonance was named first. The estimation step's reference does not
/// ring, and a transducer's diaphragm rings in a step: no sensor resonance is offered, and the
/// mode the probe lacks is named.
#[test]
fn a_reference_ringing_only_after_a_valve_is_the_pressure_not_the_transducer() {
    let case = diagnose_bank(
        "valve-chamber",
        "valve-chamber-est.csv",
        "valve-chamber-val.csv",
    );
    let d = &case.json;
    let tests = d["tests"].as_array().unwrap();
    assert!(tests[0]["reference_ringing"].is_null(), "{}", tests[0]);
    let ringing = tests[1]["reference_ringing"]["frequency_hz"]
        .as_f64()
        .unwrap();
    assert!((200.0..300.0).contains(&ringing), "{}", tests[1]);
    let kinds: Vec<&str> = d["candidates"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c["kind"].as_str().unwrap())
        .collect();
    assert!(!kinds.contains(&"sensor-resonance"), "{kinds:?}");
    assert_eq!(kinds.first(), Some(&"mode"), "{d}");
}

/// Case 013 of seed 15's bank: a flush sensor whose probe noise is coloured (a slow AR(1)),
/// validated on a step. Both tests' errors are within 1.2x of what both channels' noise
/// leaves and the residual looks white enough (Ljung-Box p above 1e-3), so the diagnosis
/// said `none`. The probe's quiet segment before the step shows its noise is coloured, and a
/// noise model lowers the error it reports, the one-step-ahead prediction error, threefold.
#[test]
fn coloured_probe_noise_is_named_at_the_floor_of_a_simulation_error() {
    let case = diagnose_bank(
        "coloured-at-floor",
        "coloured-at-floor-est.csv",
        "coloured-at-floor-val.csv",
    );
    let d = &case.json;
    let first = &d["candidates"][0];
    assert_eq!(first["kind"], "coloured-noise", "{d}");
    let evidence = &first["evidence"];
    assert!(
        evidence["probe_noise_predictability"].as_f64().unwrap() >= 1.15,
        "{evidence}"
    );
    assert!(
        evidence["ljung_box_p"].as_f64().unwrap() > 1e-3,
        "{evidence}"
    );
    for t in d["tests"].as_array().unwrap() {
        let (e, floor) = (
            t["nrmse"].as_f64().unwrap(),
            t["noise_floor"].as_f64().unwrap(),
        );
        assert!(e <= 1.2 * floor, "{e} against {floor}");
    }
    let (before, after) = (
        first["nrmse_before"].as_f64().unwrap(),
        first["nrmse_after"].as_f64().unwrap(),
    );
    assert!(before / after >= 2.0, "{before} -> {after}");
}

/// Bank seed 30, case 044: a flush probe resonant at 40 kHz (damping 0.013), fitted on a step
/// and validated on a wake traverse in a gas at another temperature. A traverse has no step
/// to fit alone, so no test could show its natural frequencies moved, and the diagnosis said
/// `unexplained` at 18.5 %, 80 times what both channels' noise leaves. The temperature's trial
/// now runs without that signature where the residual is above the floor: the model's one
/// time scale, fitted to the traverse, moves by about 0.91 (a colder gas, viscous law) and
/// takes the error under 1 %. `temperature-viscous` is named from the trial alone, and its
/// change does what the trial said.
#[test]
fn a_traverse_at_another_temperature_is_read_from_its_trial_alone() {
    let case = diagnose_bank(
        "flush-cold-traverse",
        "flush-cold-traverse-est.csv",
        "flush-cold-traverse-val.csv",
    );
    let d = &case.json;
    let first = &d["candidates"][0];
    assert_eq!(first["kind"], "temperature-viscous", "{d}");
    let e = &first["evidence"];
    assert_eq!(e["signature"], false, "{e}");
    assert!(e["per_test"].as_array().unwrap().is_empty(), "{e}");
    let k = e["common_ratio"].as_f64().unwrap();
    assert!((0.85..0.97).contains(&k), "{e}");
    let before = first["nrmse_before"].as_f64().unwrap();
    let (_, floor) = case.validation_before();
    assert!(before > 20.0 * floor, "{before} against {floor}");
    let after = case.validation_after("temperature-viscous");
    assert!(before / after >= 10.0, "{before} -> {after}");
}

/// Bank seed 34, case 036: a flush probe with nothing hidden, validated on a wake traverse.
/// The second-order start misses the probe's own dynamics on the step (1.4 times its floor),
/// so the residual is above the floor and the temperature's trial runs without a signature.
/// A free time scale then takes the traverse's error from 3.1 % to about 1.9 %, below the
/// 3.6 % that both channels' noise leaves through the model: it passes less of the
/// reference's noise through the resonance than the probe does (errors in variables), which
/// is no gas temperature. Counted down to the floor and no further, the trial lowers nothing,
/// and no temperature is named.
#[test]
fn a_time_scale_that_beats_the_noise_floor_is_not_a_temperature() {
    let case = diagnose_bank(
        "flush-plain-traverse",
        "flush-plain-traverse-est.csv",
        "flush-plain-traverse-val.csv",
    );
    assert!(!case.names_temperature(), "{}", case.json);
    // The trap is there: adding a temperature lowers the traverse's error by more than a
    // temperature read from its trial alone needs, to below the floor.
    let (before, floor) = case.validation_before();
    let after = case.validation_after("temperature");
    assert!(
        before / after >= 1.32 && after < floor,
        "{before} -> {after}, floor {floor}"
    );
}

/// Bank seed 91, case 043: a flush probe with a quadratic loss, fitted on a step and validated
/// on a wake traverse. The traverse fitted alone shows every natural frequency 0.79x the
/// model's, a temperature's signature (a colder gas) with the damping kept; but the
/// temperature's own trial moves the traverse's time scale the other way (1.06x, a hotter
/// gas), where a temperature moves both by the one factor. A signature its own trial
/// contradicts is not a temperature's: the trial still lowers the traverse's error 1.39x, but
/// the residual is said to be unexplained (the loss itself lowers it less than 1.15x, which no
/// name can show).
#[test]
fn a_signature_its_own_trial_contradicts_is_not_a_temperature() {
    let case = diagnose_bank(
        "flush-loss-wake",
        "flush-loss-wake-est.csv",
        "flush-loss-wake-val.csv",
    );
    let d = &case.json;
    assert!(!case.names_temperature(), "{d}");
    assert_eq!(d["candidates"][0]["kind"], "unexplained", "{d}");
    // The trap: adding a temperature lowers the traverse's error past the diagnosis' threshold.
    let (before, _) = case.validation_before();
    let after = case.validation_after("temperature");
    assert!(before / after >= 1.3, "{before} -> {after}");
}

/// Bank seed 39, case 079: a capillary with a quadratic loss, fitted on a large step and
/// validated on a wake traverse of a fifteenth of its size. Its second-order fit is a
/// resonance damped at 0.996, which has no peak. The traverse's one time scale, fitted to it
/// alone, lowers its error 1.56x counted to the floor, enough for a temperature read from its
/// trial alone; but without a peak to move, a time scale is what an amplitude-dependent
/// resistance moves too, so no temperature is read that way. Nor as the last resort before
/// `unexplained`: the smaller traverse runs faster (1.137), as a loss fitted on the large step
/// makes it. The residual above the floor is said to be unexplained.
#[test]
fn a_time_scale_without_a_resonant_peak_is_not_read_as_a_temperature() {
    let case = diagnose_bank(
        "capillary-loss-traverse",
        "capillary-loss-traverse-est.csv",
        "capillary-loss-traverse-val.csv",
    );
    let d = &case.json;
    assert!(!case.names_temperature(), "{d}");
    assert_eq!(d["candidates"][0]["kind"], "unexplained", "{d}");
    // The trial alone would have passed: a temperature lowers the traverse's error by more
    // than 1.32x counted to the floor.
    let (before, floor) = case.validation_before();
    let after = case.validation_after("temperature");
    assert!(
        before / after.max(floor) >= 1.32,
        "{before} -> {after}, floor {floor}"
    );
}

/// Bank seed 65, case 026: a capillary (no resonance, so no temperature is read from its
/// trial alone while another effect is offered) validated on a wake traverse at another gas
/// temperature. No trial at the plain model's delay lowers the traverse's error, which is
/// 2.5x the floor. As the last resort before `unexplained`, the temperature read from its
/// trial alone on any model is named: the traverse, a third of the step's size, runs slower
/// (0.872), which a gas temperature does and a loss fitted on the larger step cannot (the
/// capillary's loss of `a_time_scale_without_a_resonant_peak_is_not_read_as_a_temperature`
/// runs faster and stays unexplained).
#[test]
fn a_capillary_at_another_temperature_on_a_traverse_is_named_as_a_last_resort() {
    let case = diagnose_bank(
        "capillary-warm-traverse",
        "capillary-warm-traverse-est.csv",
        "capillary-warm-traverse-val.csv",
    );
    case.first_named("temperature-diffusive", "found as a last resort");
    // Its change, as printed, brings the traverse to the floor.
    let (before, floor) = case.validation_before();
    assert!(before > 2.0 * floor, "{before}, floor {floor}");
    let after = case.validation_after("temperature-diffusive");
    assert!(after < 1.1 * floor, "{before} -> {after}, floor {floor}");
}

/// Bank seed 71, case 026: an overdamped capillary (2066 Hz) stepped at 293 K and validated
/// on a wake traverse in a colder gas. No test fitted alone can show a temperature (a
/// traverse has no step, and the model no resonance), and the trial alone was kept from it
/// while another effect was offered; a quadratic loss fitted on both tests together was, and
/// it was named. The temperature is now tried beside it and the two set on one footing, each
/// fitted on both tests: the temperature leaves less, and goes first, with the test that
/// tells the two apart.
#[test]
fn a_capillary_in_a_colder_gas_beside_a_joint_loss_is_named_a_temperature() {
    let case = diagnose_bank(
        "capillary-cold-traverse",
        "capillary-cold-traverse-est.csv",
        "capillary-cold-traverse-val.csv",
    );
    let d = &case.json;
    let first = case.first_named("temperature-diffusive", "read from the trial alone");
    let second = &d["candidates"][1];
    assert_eq!(second["kind"], "nonlinear-damping", "{d}");
    let loss = rms_of(&second["evidence"]["joint"]["nrmse"]);
    assert!(temperature_rms(first) < loss, "{d}");
    // Close on that footing, so the diagnosis says which test separates them.
    let margin = first["margin"].as_f64().unwrap();
    assert!(
        (margin - (loss / temperature_rms(first)).ln()).abs() < 1e-9,
        "{d}"
    );
    assert!(margin < 0.3, "{d}");
    assert_eq!(first["separated_by"]["test"], "steps-of-other-sizes", "{d}");
    // The change as printed brings the traverse to its floor.
    let (before, floor) = case.validation_before();
    assert!(before > 3.0 * floor, "{before}, floor {floor}");
    let after = case.validation_after("temperature-diffusive");
    assert!(after < 1.1 * floor, "{before} -> {after}, floor {floor}");
}

/// Bank seed 66, case 113: a pneumatic probe with a hidden line mode, validated on a valve
/// test. At the plain model's delay no trial lowers the valve's error by 1.15x; the mode adds
/// poles that trade with the delay, and with the delay searched again in each trial, as
/// `unlag fit --add` does, the mode's trial passes. The diagnosis names it, and says how.
#[test]
fn a_mode_whose_poles_trade_with_the_delay_is_found_with_the_delay_searched() {
    let case = diagnose_bank("mode-delay", "mode-delay-est.csv", "mode-delay-val.csv");
    case.first_named("mode", "found with the delay searched again");
    // The change as printed (`--add mode`, the delay searched) gives the trial's fall.
    let (before, _) = case.validation_before();
    let after = case.validation_after("mode");
    assert!(before / after >= 1.15, "{before} -> {after}");
}

/// The root mean square of a JSON array of errors.
fn rms_of(errors: &serde_json::Value) -> f64 {
    let e: Vec<f64> = errors
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    (e.iter().map(|v| v * v).sum::<f64>() / e.len() as f64).sqrt()
}

/// What a temperature candidate leaves over all the tests: the lesser of its trial's and its
/// fit on all the tests.
fn temperature_rms(t: &serde_json::Value) -> f64 {
    let e = &t["evidence"];
    rms_of(&e["trial_nrmse"]).min(rms_of(&e["joint_nrmse"]))
}

/// The candidate of `kind` (a temperature under any damping law for `temperature`).
fn candidate_of<'a>(d: &'a serde_json::Value, kind: &str) -> &'a serde_json::Value {
    d["candidates"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["kind"].as_str().unwrap().starts_with(kind))
        .unwrap_or_else(|| panic!("no {kind} in {d}"))
}

/// Bank seed 37, case 097: a flush probe (45 kHz, damping 0.22) with a quadratic loss,
/// fitted on a step of 3600 and validated on a wake traverse whose rates are some seven
/// times smaller. Fitted alone, the traverse shows every natural frequency moved by 0.91,
/// which reads as a gas 0.83 times as warm, and the temperature's trial lowers the traverse's
/// error more than the loss's. But that trial runs the traverse faster (1.14, a warmer gas),
/// where a temperature moves both by one factor: a signature its own trial contradicts is not
/// a temperature's, and the loss is named. (Until stop 51 the temperature was offered and
/// scored ahead; the loss went first as it leaves less over the two tests fitted on both.)
#[test]
fn a_loss_that_explains_both_tests_better_goes_before_the_temperature_they_seem_to_show() {
    let case = diagnose_bank(
        "flush-loss-traverse",
        "flush-loss-traverse-est.csv",
        "flush-loss-traverse-val.csv",
    );
    let d = &case.json;
    assert_eq!(d["candidates"][0]["kind"], "nonlinear-damping", "{d}");
    assert!(!case.names_temperature(), "{d}");
    // The trap: a temperature lowers the traverse's error more than the loss's trial does.
    let loss = candidate_of(d, "nonlinear-damping");
    let (before, floor) = case.validation_before();
    let temperature = case.validation_after("temperature");
    let loss_after = loss["nrmse_after"].as_f64().unwrap();
    assert!(
        temperature < loss_after && before / temperature >= 1.15,
        "{before} -> temperature {temperature}, loss {loss_after}"
    );
    // The loss explains the traverse to the noise both channels leave on it, fitted on both.
    let joint = &loss["evidence"]["joint"];
    let on_traverse = joint["nrmse"][1].as_f64().unwrap();
    assert!(on_traverse < 1.5 * floor, "{on_traverse} against {floor}");
}

/// Bank seed 46, case 008: a pneumatic probe fitted on a step and validated on another step
/// in a colder gas, of about the same size (2707 and 3125). The plain model misses the
/// probe's own dynamics (4.5 times the floor on the step), and a loss fitted on both tests
/// lowers their error by refitting the dynamics on both, which the temperature's trial does
/// not (0.60 % over the two against the loss's 0.53 %). Fitted on both tests too, the
/// temperature leaves 0.45 % and is named. (Its validation error falls little after `--add`:
/// the plain model's misfit of the probe's own dynamics dominates it.)
#[test]
fn a_temperature_fitted_on_both_tests_goes_before_a_loss_that_leaves_more() {
    let case = diagnose_bank(
        "pneumatic-warm-step",
        "pneumatic-warm-step-est.csv",
        "pneumatic-warm-step-val.csv",
    );
    let d = &case.json;
    let first = &d["candidates"][0];
    let kind = first["kind"].as_str().unwrap();
    assert!(kind.starts_with("temperature"), "{d}");
    let loss = candidate_of(d, "nonlinear-damping");
    let l = rms_of(&loss["evidence"]["joint"]["nrmse"]);
    let e = &first["evidence"];
    // The trap: the trial alone leaves more than the loss; fitted on both tests, less.
    assert!(rms_of(&e["trial_nrmse"]) > l, "{e}");
    assert!(temperature_rms(first) < l, "{e} against {l}");
    // Both below the one linear model fitted to the two tests.
    let linear = rms_of(&loss["evidence"]["joint"]["linear_nrmse"]);
    assert!(l < linear, "{l} against {linear}");
}

/// Bank seed 38, case 028: a pneumatic probe with a leaking cavity, fitted on a step and
/// validated on a wake traverse. The mode's trial (two poles and zeros) scored 0.11 ahead of
/// the leak's (one of each): it can take a slow pole's shape. But both of the leak's
/// signatures were seen, a DC gain of 0.95 and a creep after the step far out of the noise,
/// and the creep has settled by the end of the record, as a filling volume's does; no
/// acoustic mode lowers a static gain. The leak is named, and adding it takes the traverse
/// to its floor.
#[test]
fn a_leak_whose_creep_settles_goes_before_a_mode_it_ties_with() {
    let case = diagnose_bank(
        "pneumatic-leak-traverse",
        "pneumatic-leak-traverse-est.csv",
        "pneumatic-leak-traverse-val.csv",
    );
    let d = &case.json;
    let first = &d["candidates"][0];
    assert_eq!(first["kind"], "leak", "{d}");
    let e = &first["evidence"];
    assert!(e["dc_gain"].as_f64().unwrap() < 0.998, "{e}");
    assert!(
        e["creep_in_standard_errors"].as_f64().unwrap().abs() >= 3.0,
        "{e}"
    );
    assert!(e["creep_slope_kept"].as_f64().unwrap().abs() < 0.5, "{e}");
    // The trap: a mode that scores ahead of it, within the close margin.
    let mode = candidate_of(d, "mode");
    let (m, l) = (
        mode["score"].as_f64().unwrap(),
        first["score"].as_f64().unwrap(),
    );
    assert!(m > l && m - l < 0.3, "mode {m}, leak {l}");
    let (before, floor) = case.validation_before();
    let after = case.validation_after("leak");
    assert!(before / after >= 3.0, "{before} -> {after}");
    assert!(after < 1.5 * floor, "{after} against {floor}");
}

/// Bank seed 46, case 029: a pneumatic probe whose sensor drifts, with dynamics beyond
/// second order of its own. The drift lowers the fitted DC gain (0.992) and leaves a creep
/// 46 standard errors out after the step, a leak's two signatures, and the leak's trial ties
/// with the mode's. But the residual's slope over the last 30 % of the estimation test is
/// 3.2 times the line's through the whole of it: it runs on, as a drift does, where a leak's
/// creep settles. The leak does not go before the mode.
#[test]
fn a_drift_whose_creep_runs_on_is_not_put_before_a_mode_as_a_leak() {
    let case = diagnose_bank(
        "pneumatic-drift-creep",
        "pneumatic-drift-creep-est.csv",
        "pneumatic-drift-creep-val.csv",
    );
    let d = &case.json;
    let first = &d["candidates"][0];
    assert_eq!(first["kind"], "mode", "{d}");
    let leak = candidate_of(d, "leak");
    let e = &leak["evidence"];
    // The trap: both of a leak's signatures, and a score within the close margin.
    assert!(e["dc_gain"].as_f64().unwrap() < 0.998, "{e}");
    assert!(
        e["creep_in_standard_errors"].as_f64().unwrap().abs() >= 3.0,
        "{e}"
    );
    let (m, l) = (
        first["score"].as_f64().unwrap(),
        leak["score"].as_f64().unwrap(),
    );
    assert!(m > l && m - l < 0.3, "mode {m}, leak {l}");
    // What tells it apart: the creep keeps its rate to the end.
    assert!(e["creep_slope_kept"].as_f64().unwrap() >= 1.0, "{e}");
    // And the drift's own trial is offered ahead of the leak's.
    let drift = candidate_of(d, "drift");
    assert!(drift["score"].as_f64().unwrap() > l, "{d}");
}

/// The damping of a second-order model file's resonance (1 for real poles), read from its
/// `a = [a1, a2]`.
fn damping_of(model: &std::path::Path) -> f64 {
    let text = std::fs::read_to_string(model).unwrap();
    let a: Vec<f64> = text
        .lines()
        .find_map(|l| l.strip_prefix("a = "))
        .map(|v| serde_json::from_str(v).unwrap())
        .unwrap();
    let (a1, a2) = (a[0], a[1]);
    if a1 * a1 >= 4.0 * a2 {
        return 1.0;
    }
    let r = a2.sqrt();
    let angle = (-a1 / (2.0 * r)).acos();
    -r.ln() / r.ln().hypot(angle)
}

/// Bank seed 50, case 035: a pneumatic probe in a warmer gas, fitted on a step and validated
/// on a wake traverse, which no fit alone can read a frequency from. The plain model is
/// damped 0.91: its response has no peak, and until stop 44 a temperature was only read
/// from its trial alone where it had one (damping below 0.707), so the diagnosis said
/// `unexplained`. The pair is still short of critical damping, with a ringing and a decay
/// the gas moves together: the temperature is named, and adding it takes the traverse to
/// the floor both channels' noise leaves.
#[test]
fn a_temperature_read_from_its_trial_alone_on_a_probe_without_a_peak() {
    let case = diagnose_bank(
        "pneumatic-warm-wake",
        "pneumatic-warm-wake-est.csv",
        "pneumatic-warm-wake-val.csv",
    );
    let d = &case.json;
    let zeta = damping_of(&case.dir.join("plain.toml"));
    assert!(
        zeta > std::f64::consts::FRAC_1_SQRT_2 && zeta < 0.93,
        "{zeta}"
    );
    let first = &d["candidates"][0];
    let kind = first["kind"].as_str().unwrap();
    assert!(kind.starts_with("temperature"), "{d}");
    assert_eq!(first["evidence"]["signature"], false, "{first}");
    let (before, floor) = case.validation_before();
    let after = case.validation_after(kind);
    assert!(before / after >= 1.5, "{before} -> {after}");
    assert!(after < 1.2 * floor, "{after} against {floor}");
}

/// Bank seed 37, case 025: a capillary with a quadratic loss, fitted on a step and validated
/// on a step of another size. Its plain model is damped 0.98, near critical: the pair acts
/// as one time scale, which the loss moves with the step's size as a temperature would move
/// it, and a temperature's trial alone would lower the validation error too. The trial alone
/// is not offered there, and the loss is named.
#[test]
fn a_loss_near_critical_damping_is_not_read_as_a_temperature_from_its_trial_alone() {
    let case = diagnose_bank(
        "capillary-loss-steps",
        "capillary-loss-steps-est.csv",
        "capillary-loss-steps-val.csv",
    );
    let d = &case.json;
    let zeta = damping_of(&case.dir.join("plain.toml"));
    assert!(zeta >= 0.93, "{zeta}");
    assert_eq!(d["candidates"][0]["kind"], "nonlinear-damping", "{d}");
    // The trap: a temperature's trial, fitted as `--add temperature` fits it, lowers the
    // validation error as much as the loss fitted on both tests does.
    let (before, _) = case.validation_before();
    let warm = case.validation_after("temperature");
    assert!(before / warm >= 1.3225, "{before} -> {warm}");
    let from_trial_alone = d["candidates"].as_array().unwrap().iter().any(|c| {
        c["kind"].as_str().unwrap().starts_with("temperature")
            && c["evidence"]["signature"] == false
    });
    assert!(!from_trial_alone, "{d}");
}

/// Bank seed 50, case 001: a pneumatic probe with a leak and dynamics beyond second order of
/// its own, validated on a wake traverse. The diagnosis names the leak and its trial, at the
/// plain model's delay (6 samples), takes the traverse from 0.963 % to 0.711 %. `fit --add
/// leak` searches the delay again, finds 8 (lower on the estimation test) and the traverse
/// rises to 1.100 %: the loop's change made the model worse where it is judged. The fit that
/// continues the model file says so, names the delay that moved, and `--add delay=6`, as it
/// says, gives the fall. The diagnosis, refitting its first change as the fit will, already
/// prints the change with `--add delay=6`.
#[test]
fn a_change_that_raises_the_held_out_error_is_said_with_the_delay_that_moved() {
    let dir = std::env::temp_dir().join(format!("unlag-error-rise-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let est = bank_trace("pneumatic-leak-delay-est.csv");
    let val = bank_trace("pneumatic-leak-delay-val.csv");
    let model = dir.join("probe.toml").to_str().unwrap().to_string();
    let fit = |extra: &[&str]| {
        let (ok, out, err) = unlag(
            &[
                &["fit", &est, &val, "--order", "2", "-o", &model, "--json"][..],
                extra,
            ]
            .concat(),
        );
        assert!(ok, "{extra:?}: {out}{err}");
        let v: serde_json::Value = serde_json::from_str(out.trim()).expect(&out);
        let held_out = v["sources"][1]["nrmse"].as_f64().unwrap();
        (v, held_out, err)
    };
    let (plain, before, _) = fit(&[]);
    assert_eq!(plain["error_rises"], serde_json::json!([]), "{plain}");
    // The diagnosis makes its change as the fit will: searched again, the delay would raise
    // the traverse's error, so the change keeps it. The model is short of its own step test
    // too (the probe's dynamics beyond second order), so the change carries a mode beside the
    // leak.
    let (ok, out, err) = unlag(&["diagnose", &model, &est, &val, "--json"]);
    assert!(ok, "{out}{err}");
    let v: serde_json::Value = serde_json::from_str(out.trim()).expect(&out);
    let first = &v["candidates"][0];
    assert_eq!(first["kind"], "leak", "{v}");
    assert_eq!(first["beside"]["kind"], "mode", "{first}");
    let change = first["change"].as_str().unwrap();
    assert!(
        change.starts_with("unlag fit ... --add leak --add mode --add delay=6 ")
            && change.contains(r#"{ kind = "delay", samples = 6 }"#),
        "{change}"
    );
    // A copy of the plain model, continued in text: the fit says what the change did.
    let text_model = dir.join("probe-text.toml");
    std::fs::copy(&model, &text_model).unwrap();
    let (ok, printed, _) = unlag(&[
        "fit",
        &est,
        &val,
        "--order",
        "2",
        "--add",
        "leak",
        "--add",
        "delay=6",
        "-o",
        text_model.to_str().unwrap(),
    ]);
    assert!(ok, "{printed}");
    let line = printed
        .lines()
        .find(|l| l.starts_with("held-out errors against the fit before (order 2, delay 6"))
        .unwrap_or_else(|| panic!("{printed}"));
    assert!(
        line.contains(&format!("{:.3} % ->", 100.0 * before)) && line.ends_with("x lower)"),
        "{line}"
    );
    let (leak, after, warned) = fit(&["--add", "leak"]);
    assert!(after > 1.05 * before, "{before} -> {after}");
    let rises = leak["error_rises"].as_array().unwrap();
    assert_eq!(rises.len(), 1, "{leak}");
    let rise = &rises[0];
    assert_eq!(
        (&rise["delay_before"], &rise["delay_after"]),
        (&serde_json::json!(6), &serde_json::json!(8)),
        "{rise}"
    );
    assert!(
        (rise["before"].as_f64().unwrap() - before).abs() < 1e-12,
        "{rise}"
    );
    assert!(
        warned.contains("warning: the held-out error of")
            && warned.contains("rose from")
            && warned.contains("`--add delay=6` keeps the one before"),
        "{warned}"
    );
    // As the warning says: the delay before, and the leak's fall.
    let (kept, with_delay, quiet) = fit(&["--add", "leak", "--add", "delay=6"]);
    assert_eq!(kept["error_rises"], serde_json::json!([]), "{kept}");
    assert!(!quiet.contains("rose from"), "{quiet}");
    assert!(with_delay < before / 1.3, "{before} -> {with_delay}");
    // The change as the diagnosis prints it, with the mode beside the leak, does better still.
    let (_, with_mode, _) = fit(&["--add", "leak", "--add", "mode", "--add", "delay=6"]);
    let said = first["beside"]["nrmse_after"].as_f64().unwrap();
    assert!(
        (with_mode / said - 1.0).abs() < 0.01,
        "{with_mode} against {said}"
    );
    assert!(with_mode < with_delay / 1.15, "{with_delay} -> {with_mode}");
}

/// Bank seed 79, case 089: a pneumatic probe (a line and a cavity, modes above the first)
/// stepped at 293 K and validated by a wake traverse in a colder gas. The plain second-order
/// model is short of its own step test (0.93 % against a floor of 0.25 %) as well as of the
/// temperature. The temperature is named first; its effect alone takes the traverse from
/// 6.64 % to 4.17 %, where the floor is 0.28 %, and the next round of the loop named the mode.
/// The first change now carries the mode beside the temperature, and says why; made as
/// printed, it takes the traverse below 1.3 %.
#[test]
fn a_model_short_of_its_own_test_gets_a_mode_beside_the_first_change() {
    let case = diagnose_bank(
        "pneumatic-cold-short",
        "pneumatic-cold-short-est.csv",
        "pneumatic-cold-short-val.csv",
    );
    let first = case.first_named("temperature-viscous", "short of its own estimation test");
    let beside = &first["beside"];
    assert_eq!(beside["kind"], "mode", "{first}");
    let change = first["change"].as_str().unwrap();
    let command = change.split("   (").next().unwrap();
    let adds: Vec<&str> = command
        .split(" --add ")
        .skip(1)
        .map(|a| a.split_whitespace().next().unwrap())
        .collect();
    assert_eq!(adds[..2], ["temperature-viscous", "mode"], "{change}");
    let (before, floor) = case.validation_before();
    // The temperature alone falls short: the traverse stays at many times its floor.
    let alone = case.validation_after("temperature-viscous");
    assert!(
        before / alone < 2.0 && alone > 10.0 * floor,
        "{before} -> {alone}"
    );
    // The change as printed gives what the diagnosis says, and a 3x fall.
    let after = case.validation_after_all(&adds);
    let said = beside["nrmse_after"].as_f64().unwrap();
    assert!((after / said - 1.0).abs() < 0.01, "{after} against {said}");
    assert!(before / after >= 3.0, "{before} -> {after}, floor {floor}");
}

/// Bank seed 83, case 081: a pneumatic probe with no hidden effect, whose own modes beyond
/// second order leave the plain model's step test at 5.5x its floor. The measured response
/// rises above the model's towards the top of the band the noise leaves (179 Hz). A leak's
/// trial, which scored more, is not run: the DC gain is 1 and no creep stands out after the
/// step. The resonance seen rising towards the band's edge is named.
#[test]
fn a_leak_with_neither_signature_is_not_tried_beside_a_rise_towards_the_band_edge() {
    let case = diagnose_bank(
        "pneumatic-own-modes",
        "pneumatic-own-modes-est.csv",
        "pneumatic-own-modes-val.csv",
    );
    let first = case.first_named("mode", "where the noise takes over");
    assert!(first["evidence"]["rise_db"].as_f64().is_some(), "{first}");
    assert!(first["ordered_by"].is_null(), "{first}");
    case.no_leak_offered();
    // The change as printed lowers the validation test's error.
    let (before, _) = case.validation_before();
    let after = case.validation_after("mode");
    assert!(before / after >= 1.15, "{before} -> {after}");
}

/// Bank seed 85, case 032: a pneumatic probe whose line and cavity have three modes (the
/// plain model has one), a hidden mode among them. One mode added leaves its own step test at
/// twice its floor; the first change now carries a second mode beside it, which takes the
/// held-out step to where the true model of order 6 leaves it (0.36 %).
///
/// And the second round, on the model with one mode: a mode is tried beside the model's, as
/// `unlag fit --add mode` adds it, where before it replaced the model's and so could never
/// lower anything; the change names the model's mode again, since the refit with `--order 2`
/// drops the modes the model carries. Before, the second round named a leak whose trial kept
/// the mode (0.512 % -> 0.438 %) and whose change, made as printed, dropped it (0.654 %).
#[test]
fn a_probe_with_more_modes_gets_a_second_mode_and_a_change_keeps_the_models_own() {
    let case = diagnose_bank(
        "pneumatic-three-modes",
        "pneumatic-three-modes-est.csv",
        "pneumatic-three-modes-val.csv",
    );
    let first = case.first_named("mode", "with a second mode beside it");
    assert_eq!(first["beside"]["kind"], "mode", "{first}");
    let change = first["change"].as_str().unwrap();
    assert!(
        change.starts_with("unlag fit ... --add mode --add mode   ("),
        "{change}"
    );
    let (before, _) = case.validation_before();
    let alone = first["beside"]["nrmse_alone"].as_f64().unwrap();
    let said = first["beside"]["nrmse_after"].as_f64().unwrap();
    let after = case.validation_after_all(&["mode", "mode"]);
    assert!((after / said - 1.0).abs() < 0.01, "{after} against {said}");
    assert!(
        alone >= 1.15 * after && before >= 2.5 * after,
        "{before} -> {alone} -> {after}"
    );

    // The second round, from the model with one mode, continued as a user continues it.
    let model = case.dir.join("one-mode.toml");
    let model = model.to_str().unwrap();
    let fit = |adds: &[&str]| {
        let mut args = vec![
            "fit", &case.est, &case.val, "--order", "2", "-o", model, "--json",
        ];
        for a in adds {
            args.extend(["--add", a]);
        }
        unlag_json(&args)
    };
    fit(&["mode"]);
    let again = unlag_json(&["diagnose", model, &case.est, &case.val, "--json"]);
    let first = &again["candidates"][0];
    assert_eq!(first["kind"], "mode", "{again}");
    let change = first["change"].as_str().unwrap();
    assert!(
        change.starts_with("unlag fit ... --add mode --add mode   (")
            && change.contains("the model's mode named again"),
        "{change}"
    );
    // Every change names the model's mode again, whatever it adds.
    for c in again["candidates"].as_array().unwrap() {
        let change = c["change"].as_str().unwrap();
        assert!(
            change == "none" || change.starts_with("unlag fit ... --add mode"),
            "{change}"
        );
    }
    let said = first["nrmse_after"].as_f64().unwrap();
    let one_mode = first["nrmse_before"].as_f64().unwrap();
    let refitted = fit(&["mode", "mode"]);
    let after = refitted["sources"][1]["nrmse"].as_f64().unwrap();
    assert_eq!(refitted["sources"][1]["role"], "validation", "{refitted}");
    assert!((after / said - 1.0).abs() < 0.02, "{after} against {said}");
    assert!(one_mode >= 1.15 * after, "{one_mode} -> {after}");
    let kinds: Vec<&str> = refitted["effects"]
        .as_array()
        .unwrap()
        .iter()
        .map(|e| e["kind"].as_str().unwrap())
        .collect();
    assert_eq!(kinds, ["mode", "mode"], "{refitted}");
}

/// Bank seed 87, case 053: a capillary validated on a step in a colder gas. Its record shows
/// one corner, and the second-order fit spends its second pole on the noise, on the negative
/// real axis (poles 0.84 and -0.16), where a model has no continuous-time equivalent and a
/// temperature cannot scale it, at any delay the fit steps back to. Until stop 52 the
/// temperature's trial then changed nothing (1.36 % before and after, the floor 0.22 %), and
/// the case was counted an effect its tests cannot show. The fit now steps down an order:
/// order 1 explains the step as well and can be scaled, and the temperature is named and
/// brings the held-out step to its floor.
#[test]
fn a_spare_pole_on_the_negative_real_axis_does_not_hide_a_temperature() {
    let case = diagnose_bank(
        "capillary-spare-pole",
        "capillary-spare-pole-est.csv",
        "capillary-spare-pole-val.csv",
    );
    case.first_named("temperature-diffusive", "fitted alone");
    let (before, floor) = case.validation_before();
    assert!(before > 4.0 * floor, "{before}, floor {floor}");
    let fitted = case.fit_adding("temperature-diffusive");
    assert_eq!(fitted["a"].as_array().map(Vec::len), Some(1), "{fitted}");
    let notes = fitted["fit"]["notes"].to_string();
    assert!(notes.contains("order 1 explains"), "{notes}");
    let after = fitted["sources"][1]["nrmse"].as_f64().unwrap();
    assert!(after < 1.1 * floor, "{before} -> {after}, floor {floor}");
}

/// Bank seed 131, case 047 (its validation step cut to its first 8000 samples): a capillary
/// whose probe drifts. After the searched delay its record shows one corner, and the
/// second-order fit spent its second pole on the drift: a pole 7e-11 and a zero 1e-6 from
/// z = 1, slower than the record by a factor of two million, with a DC gain of -53616 that
/// the step never reaches but a held-out test's level does (the validation error was 1.5e7 %,
/// and with the whole validation record the diagnosis named a temperature first). The fit
/// now steps down an order when the slow pole's order explains the estimation test no better:
/// order 1 has the probe's DC gain, and the drift is named and brings the step to near its
/// floor.
#[test]
fn a_pole_slower_than_the_record_does_not_set_the_dc_gain() {
    let case = diagnose_bank(
        "capillary-slow-pair",
        "capillary-slow-pair-est.csv",
        "capillary-slow-pair-val.csv",
    );
    let fitted = case.fit_plain();
    assert_eq!(fitted["a"].as_array().map(Vec::len), Some(1), "{fitted}");
    // Rounding puts the slow pole a hair inside the circle (slower than the record) or on it
    // (an integrator): either reading steps down to order 1.
    let notes = fitted["fit"]["notes"].to_string();
    assert!(
        (notes.contains("which the record cannot resolve") || notes.contains("unit circle"))
            && (notes.contains("order 1 explains") || notes.contains("order 1 was kept")),
        "{notes}"
    );
    let dc = fitted["dc_gain"].as_f64().unwrap();
    assert!((dc - 1.0).abs() < 0.05, "DC gain {dc}");
    let val_nrmse = fitted["sources"][1]["nrmse"].as_f64().unwrap();
    assert!(val_nrmse < 0.05, "validation error {val_nrmse}");
    case.first_named("drift", "a ramp through the whole residual");
    let (before, floor) = case.validation_before();
    let after = case.validation_after("drift");
    assert!(
        after < before / 3.0 || after < 1.5 * floor,
        "{before} -> {after}, floor {floor}"
    );
}

/// Bank seed 142, case 074 (its validation step cut to its first 8000 samples): a capillary
/// whose probe drifts 200 units per second. Its second-order fit put a pole at 1.000000 at
/// every delay, and `fit` refused the model as unstable, so the loop could not start. The fit
/// now reads the creep as the drift it is, and the plain model carries it: both tests are at
/// their floor, and the diagnosis says so, listing the drift as carried.
#[test]
fn a_pole_on_the_unit_circle_is_read_as_a_drift() {
    let case = diagnose_bank(
        "capillary-unit-pole",
        "capillary-unit-pole-est.csv",
        "capillary-unit-pole-val.csv",
    );
    assert_eq!(
        case.json["carried"],
        serde_json::json!(["drift"]),
        "{}",
        case.json
    );
    assert_eq!(case.json["candidates"][0]["kind"], "none", "{}", case.json);
    let fitted = case.fit_plain();
    // The pole lands on the circle or a hair inside it (slower than the record), as rounding
    // puts it: either way the creep is read as the drift.
    let notes = fitted["fit"]["notes"].to_string();
    assert!(notes.contains("read as a drift"), "{notes}");
    let rate = fitted["effects"][0]["rate_per_s"].as_f64().unwrap();
    assert!((150.0..250.0).contains(&rate), "drift {rate} per second");
    for source in fitted["sources"].as_array().unwrap() {
        let (error, floor) = (
            source["nrmse"].as_f64().unwrap(),
            source["noise_floor"].as_f64().unwrap(),
        );
        assert!(error < 1.1 * floor, "{source}");
    }
}

/// Seed 109's case 081: a pneumatic probe with no hidden effect, whose own modes beyond
/// second order leave the step tests at 1.27x what its true model leaves. A leak's trial
/// would lower the held-out error 1.18x, with the DC gain at 1 and no creep after the step
/// (neither of a leak's signatures): its pole and zero would stand for the dynamics the model
/// lacks. It is not tried, and the diagnosis finds a mode with the delay searched again.
#[test]
fn a_leak_with_neither_of_its_signatures_is_not_named() {
    let case = diagnose_bank(
        "pneumatic-lone-leak",
        "pneumatic-lone-leak-est.csv",
        "pneumatic-lone-leak-val.csv",
    );
    let first = case.first_named("mode", "delay searched again");
    assert!(first["ordered_by"].is_null(), "{first}");
    case.no_leak_offered();
}

/// Seed 122's case 077: a capillary with a hidden mode, validated by a wake. A leak's trial
/// ties with the mode's (0.669 % and 0.666 % held out), but the model's DC gain is 1 (no
/// leaking volume) and no creep stands out of the noise: the leak is not tried, and the mode,
/// whose residual peak at 28 Hz is 42 dB out and broad (Q about 2), is named.
#[test]
fn a_broad_peak_at_unit_gain_is_named_a_mode_and_no_leak_is_tried() {
    let case = diagnose_bank(
        "capillary-mode-at-unit-gain",
        "capillary-mode-at-unit-gain-est.csv",
        "capillary-mode-at-unit-gain-val.csv",
    );
    let first = case.first_named("mode", "residual peak");
    assert!(first["ordered_by"].is_null(), "{first}");
    let peak = &first["evidence"];
    assert!(peak["q"].as_f64().unwrap() < 2.0, "{peak}");
    case.no_leak_offered();
    // The change lowers the held-out error as its trial said.
    let (before, _) = case.validation_before();
    let after = case.validation_after("mode");
    assert!(after < before / 3.0, "{before} -> {after}");
}
