//! The modelling loop on step tests with hidden effects: for every case the diagnosis names the
//! hidden kind first (or `none`), and adding it cuts the validation error at least 3x or to
//! within 1.5x of the noise floor. The cases are in `common/hidden.rs`; the score table in
//! BENCHMARKS.md comes from `examples/bench_diagnose.rs` on the same cases.

// Test code: a failed unwrap is a failed test, with its location.
#![allow(clippy::unwrap_used)]

mod common;

use common::hidden::{cases, run};

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

/// The nonlinear-damping cases in detail: the signature across tests is in the evidence with
/// its numbers (damping rising with the step, residual growing faster than the step), the
/// refit finds the quadratic loss that was simulated, and a linear probe's tests of different
/// amplitudes do not show the signature.
#[test]
fn nonlinear_damping_is_named_from_its_amplitude_signature() {
    use unlag::diagnose::{self, Current};
    use unlag::effects::{self, Effect};
    use unlag::fit::Test;
    for case in cases()
        .into_iter()
        .filter(|c| c.kind == "nonlinear-damping" || c.name == "none: clean line")
    {
        let data = case.tests(5);
        let tests: Vec<Test<'_>> = data.iter().map(|(u, y)| Test { name: "t", u, y }).collect();
        let options = case.options();
        let (plain, fx) =
            effects::fit_with(&tests[0], &tests[1..], case.fs, &options, &[]).unwrap();
        let current = Current {
            model: &plain.model,
            effects: &fx,
            method: options.method,
        };
        let evidence = diagnose::evidence(&current, &tests);
        let across = diagnose::per_test(&current, &tests, &evidence);
        let sig = diagnose::amplitude_signature(&across).unwrap();
        eprintln!("{}: {sig:?}", case.name);
        if case.kind == "none" {
            assert!(!sig.nonlinear_damping(), "{sig:?}");
            // A linear probe's damping does not change with the step.
            assert!(sig.damping_rise.abs() < 0.03, "{sig:?}");
            continue;
        }
        assert!(sig.nonlinear_damping(), "{sig:?}");
        assert!(sig.residual_exponent > 1.6, "{sig:?}");
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
        assert_eq!(first.kind, "nonlinear-damping", "{candidates:#?}");
        assert!(
            first.evidence["residual_exponent"].as_f64().unwrap() > 1.6,
            "{first:?}"
        );
        assert!(first.change.contains("--add nonlinear-damping"));
    }
}
