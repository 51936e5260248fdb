//! Fuzzing the three readers of outside bytes (the CSV trace reader, the model-file loader and
//! the board's blob parser) with proptest: random bytes, and valid files mutated byte by byte
//! (a blob also with its CRC made right again, so that the mutation reaches the checks behind
//! it). Each must answer every input with a value or a typed error, never a panic; a model
//! file that loads must be one a board can run. Cases per property: `FUZZ_CASES` (default
//! 2000; `PROPTEST_CASES` is not read here), drawn from the fixed seed `FUZZ_SEED` (default
//! 61): every run of `cargo test` tries the same inputs, and a failure reproduces. A release
//! is fuzzed with a million cases each:
//! `FUZZ_CASES=1000000 FUZZ_SEED=<new> cargo test --release --test fuzz`.

// Test code: a failed unwrap is a failed test, with its location.
#![allow(clippy::unwrap_used)]

use std::path::Path;

use proptest::prelude::*;
use unlag::board::blob;
use unlag::file::ModelFile;
use unlag::trace::{Columns, Trace};

fn cases() -> u32 {
    std::env::var("FUZZ_CASES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(2000)
}

/// The fuzzing budget and seed: [`cases`] cases from the seed `FUZZ_SEED` (default 61).
fn config() -> ProptestConfig {
    let seed = std::env::var("FUZZ_SEED")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(61);
    ProptestConfig {
        cases: cases(),
        rng_seed: proptest::test_runner::RngSeed::Fixed(seed),
        ..ProptestConfig::default()
    }
}

const CSV: &str = "t,u,y\n0,0,0\n0.001,0,0.01\n0.002,1,0.2\n0.003,1,0.5\n0.004,1,0.7\n\
                   0.005,1,0.85\n0.006,1,0.93\n0.007,1,0.97\n0.008,1,0.99\n0.009,1,1\n";

fn model_text() -> String {
    std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/examples/data/board_model.toml"
    ))
    .unwrap()
}

/// The shipped model with both fixed-point plans stored, as `unlag invert --board fixed`
/// writes them: the mutations then reach the plans' checks.
fn model_with_plans_text() -> String {
    use unlag::design::quantise::{DirectPlan, FixedPlan};
    static TEXT: std::sync::OnceLock<String> = std::sync::OnceLock::new();
    TEXT.get_or_init(|| {
        let mut f = ModelFile::parse(Path::new("m.toml"), &model_text()).unwrap();
        let d = f.inverse.as_mut().unwrap();
        d.fixed = Some(FixedPlan::new(&*d, 20_000.0).unwrap());
        d.fixed_direct = Some(DirectPlan::new(&*d, 20_000.0).unwrap());
        f.to_toml().unwrap()
    })
    .clone()
}

/// What a loaded model file promises: a usable model, and a stored compensator (with its
/// plans) that belongs to it.
fn usable(m: &ModelFile) -> Result<(), TestCaseError> {
    use unlag::design::quantise::{DirectPlan, FixedPlan};
    prop_assert!(m.model.fs.is_finite() && m.model.fs >= unlag::file::MIN_SAMPLE_RATE_HZ);
    prop_assert!(m.model.delay <= unlag::file::MAX_DELAY);
    prop_assert!(m.model.a.iter().chain(&m.model.b).all(|c| c.is_finite()));
    prop_assert!(m.model.b.len() <= m.model.a.len() + 1);
    if let Some(d) = &m.inverse {
        let fingerprint = m.model.fingerprint();
        prop_assert_eq!(d.model_sha256.as_deref(), Some(fingerprint.as_str()));
        if let Some(p) = &d.fixed {
            let again = FixedPlan::new(d, p.full_scale).unwrap();
            prop_assert_eq!(p.output_exponent, again.output_exponent);
            prop_assert_eq!(p.board_sections(), again.board_sections());
        }
        if let Some(p) = &d.fixed_direct {
            let again = DirectPlan::new(d, p.full_scale).unwrap();
            prop_assert_eq!(p.output_exponent, again.output_exponent);
            prop_assert_eq!(p.board_sections(), again.board_sections());
        }
    }
    Ok(())
}

fn blob_bytes() -> Vec<u8> {
    std::fs::read(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/examples/data/board_coefficients.bin"
    ))
    .unwrap()
}

/// One edit of a byte string: replace, insert or delete at a position (taken modulo length).
#[derive(Debug, Clone)]
enum Edit {
    Replace(usize, u8),
    Insert(usize, u8),
    Delete(usize),
}

fn edit() -> impl Strategy<Value = Edit> {
    edit_with(any::<u8>())
}

/// [`edit`] with the bytes drawn from `byte`.
fn edit_with(byte: impl Strategy<Value = u8> + Clone) -> impl Strategy<Value = Edit> {
    prop_oneof![
        (any::<usize>(), byte.clone()).prop_map(|(i, b)| Edit::Replace(i, b)),
        (any::<usize>(), byte).prop_map(|(i, b)| Edit::Insert(i, b)),
        any::<usize>().prop_map(Edit::Delete),
    ]
}

/// Bytes a text is likely to break on: digits, separators, signs, quotes, brackets.
fn text_byte() -> impl Strategy<Value = u8> + Clone {
    prop_oneof![
        any::<u8>(),
        prop::sample::select(b"0123456789,.-+eE\n\r\"[]=# naif".to_vec()),
    ]
}

fn apply(mut bytes: Vec<u8>, edits: &[Edit]) -> Vec<u8> {
    for e in edits {
        let n = bytes.len().max(1);
        match *e {
            Edit::Replace(i, b) => {
                if let Some(x) = bytes.get_mut(i % n) {
                    *x = b;
                }
            }
            Edit::Insert(i, b) => bytes.insert(i % (bytes.len() + 1), b),
            Edit::Delete(i) => {
                if !bytes.is_empty() {
                    bytes.remove(i % n);
                }
            }
        }
    }
    bytes
}

fn parse_csv(bytes: &[u8]) {
    for columns in [
        Columns::default(),
        Columns {
            sample_rate_hz: Some(1000.0),
            ..Columns::default()
        },
    ] {
        let _ = Trace::parse(Path::new("fuzz.csv"), bytes, &columns);
    }
}

proptest! {
    #![proptest_config(config())]

    #[test]
    fn the_csv_reader_never_panics_on_random_bytes(bytes in prop::collection::vec(text_byte(), 0..400)) {
        parse_csv(&bytes);
    }

    #[test]
    fn the_csv_reader_never_panics_on_a_mutated_trace(
        edits in prop::collection::vec(edit_with(text_byte()), 1..12)
    ) {
        parse_csv(&apply(CSV.as_bytes().to_vec(), &edits));
    }

    #[test]
    fn the_model_loader_never_panics_on_a_mutated_model(
        edits in prop::collection::vec(edit_with(text_byte()), 1..8)
    ) {
        let bytes = apply(model_text().into_bytes(), &edits);
        if let Ok(text) = String::from_utf8(bytes) {
            if let Ok(m) = ModelFile::parse(Path::new("fuzz.toml"), &text) {
                usable(&m)?;
            }
        }
    }

    #[test]
    fn a_mutated_model_with_fixed_point_plans_loads_only_when_its_plans_belong(
        edits in prop::collection::vec(edit_with(text_byte()), 1..8)
    ) {
        let bytes = apply(model_with_plans_text().into_bytes(), &edits);
        if let Ok(text) = String::from_utf8(bytes) {
            if let Ok(m) = ModelFile::parse(Path::new("fuzz.toml"), &text) {
                usable(&m)?;
            }
        }
    }

    #[test]
    fn the_model_loader_never_panics_on_random_text(text in "[a-z_ =\\[\\],.0-9\\n\"#-]{0,300}") {
        let _ = ModelFile::parse(Path::new("fuzz.toml"), &text);
    }

    #[test]
    fn the_blob_parser_never_panics_on_random_bytes(bytes in prop::collection::vec(any::<u8>(), 0..200)) {
        let _ = blob::parse::<16>(&bytes);
        let _ = blob::parse_fixed::<16>(&bytes);
        let _ = unlag::export::verify::read(&bytes);
    }

    #[test]
    fn the_blob_parser_never_panics_on_a_mutated_blob_with_its_crc_made_right(
        edits in prop::collection::vec(edit(), 1..6)
    ) {
        let mut bytes = apply(blob_bytes(), &edits);
        // Recompute the CRC over everything but the last four bytes, as a buggy host would.
        if bytes.len() >= 4 {
            let n = bytes.len() - 4;
            let crc = blob::crc32(&bytes[..n]);
            bytes[n..].copy_from_slice(&crc.to_le_bytes());
        }
        if let Ok(set) = blob::parse::<16>(&bytes) {
            // What parses runs, and its sections are stable. (Its output for an input of 1
            // may still overflow f32 when a mutated exponent makes a coefficient ~1e38: the
            // parser guarantees finite, stable coefficients, not a bounded gain.)
            let mut state = Default::default();
            let _ = set.cascade.process(&mut state, 1.0f32);
            let ok = unlag::export::verify::read(&bytes);
            prop_assert!(ok.is_ok_and(|s| s.pole_radius.iter().all(|r| *r < 1.0)));
        }
        let _ = blob::parse_fixed::<16>(&bytes);
    }
}
