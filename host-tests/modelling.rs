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
