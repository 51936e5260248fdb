//! `unlag export` and the coefficient blob: round trips, the shipped example files kept in
//! step with the exporter, and corruption (random bytes, every single-bit flip, every
//! truncation) always refused with a typed error, never a panic.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use std::path::{Path, PathBuf};
use std::process::Command;

use proptest::prelude::*;
use unlag::board::blob::{self, BlobError, CoefficientSet};
use unlag::board::compensator::CascadeCoefficients;
use unlag::export::{self, BoardCoefficients, Format};
use unlag::file::ModelFile;

const SHIPPED_BLOB: &[u8] = include_bytes!("../examples/data/board_coefficients.bin");

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn model_path() -> PathBuf {
    root().join("examples/data/board_model.toml")
}

fn shipped() -> BoardCoefficients {
    let path = model_path();
    BoardCoefficients::from_model_file(&ModelFile::load(&path).unwrap(), &path).unwrap()
}

#[test]
fn shipped_example_files_are_what_export_writes() {
    let c = shipped();
    assert_eq!(
        c.render(Format::Bin, "board_model.toml").unwrap(),
        SHIPPED_BLOB,
        "examples/data/board_coefficients.bin is stale: re-run unlag export --format bin"
    );
    let rust = std::fs::read_to_string(root().join("examples/data/board_coefficients.rs")).unwrap();
    assert_eq!(
        c.to_rust("board_model.toml"),
        rust,
        "examples/data/board_coefficients.rs is stale: re-run unlag export --format rust"
    );
}

mod exported {
    #![allow(dead_code)]
    include!("../examples/data/board_coefficients.rs");
}

#[test]
fn rust_consts_and_blob_give_the_same_board_coefficients() {
    let from_rust =
        CascadeCoefficients::<f32, 4>::new(exported::GAIN, &exported::SECTIONS).unwrap();
    let from_blob: CoefficientSet<4> = blob::parse(SHIPPED_BLOB).unwrap();
    assert_eq!(from_rust, from_blob.cascade);
    assert_eq!(from_blob.sections, exported::SECTION_COUNT);
    assert_eq!(from_blob.sample_rate_hz, exported::SAMPLE_RATE_HZ);
    assert_eq!(from_blob.delay_samples, exported::DELAY_SAMPLES);
}

#[test]
fn round_trip_through_the_blob_is_exact() {
    let c = shipped();
    let bytes = c.to_bin().unwrap();
    assert_eq!(bytes.len(), blob::encoded_len(c.sections.len()));
    assert_eq!(&bytes[..4], b"UNLG");
    let set: CoefficientSet<8> = blob::parse(&bytes).unwrap();
    let widened: Vec<[f64; 5]> = c.sections.iter().map(|s| s.map(f64::from)).collect();
    let direct = CascadeCoefficients::<f32, 8>::new(f64::from(c.gain), &widened).unwrap();
    assert_eq!(set.cascade, direct);
    assert_eq!(set.sample_rate_hz, c.sample_rate_hz);
    assert_eq!(set.delay_samples, c.delay_samples);
    // The capacity of a smaller firmware is respected.
    assert_eq!(
        blob::parse::<2>(&bytes),
        Err(BlobError::TooManySections {
            sections: 4,
            capacity: 2
        })
    );
}

#[test]
fn every_single_bit_flip_and_every_truncation_is_refused() {
    let mut flipped = SHIPPED_BLOB.to_vec();
    for byte in 0..flipped.len() {
        for bit in 0..8 {
            flipped[byte] ^= 1 << bit;
            let r = blob::parse::<16>(&flipped);
            assert!(
                r.is_err(),
                "flip of bit {bit} in byte {byte} went undetected"
            );
            flipped[byte] ^= 1 << bit;
        }
    }
    assert!(blob::parse::<16>(&flipped).is_ok());
    for len in 0..SHIPPED_BLOB.len() {
        assert!(
            matches!(
                blob::parse::<16>(&SHIPPED_BLOB[..len]),
                Err(BlobError::Truncated { .. } | BlobError::TrailingBytes { .. })
            ),
            "truncation to {len} bytes"
        );
    }
}

/// A stable section: complex poles at radius `r` < 1, angle `th`, arbitrary finite zeros.
fn stable_section() -> impl Strategy<Value = [f32; 5]> {
    (
        -2.0f32..2.0,
        -2.0f32..2.0,
        -2.0f32..2.0,
        0.0f32..0.95,
        0.0f32..std::f32::consts::PI,
    )
        .prop_map(|(b0, b1, b2, r, th)| [b0, b1, b2, -2.0 * r * th.cos(), r * r])
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn random_bytes_never_panic_and_are_refused(bytes in proptest::collection::vec(any::<u8>(), 0..200)) {
        prop_assert!(blob::parse::<16>(&bytes).is_err());
    }

    #[test]
    fn random_bytes_behind_a_valid_header_are_refused(
        sections in 0u16..6,
        body in proptest::collection::vec(any::<u8>(), 0..160),
    ) {
        // Magic, version and length right; the rest random: the CRC still catches it.
        let mut bytes = b"UNLG\x01\x00".to_vec();
        bytes.extend_from_slice(&[0u8; 14]);
        bytes.extend_from_slice(&sections.to_le_bytes());
        bytes.extend_from_slice(&body);
        bytes.truncate(blob::encoded_len(usize::from(sections)).min(bytes.len()));
        prop_assert!(blob::parse::<16>(&bytes).is_err());
    }

    #[test]
    fn random_sets_round_trip_and_any_flip_is_detected(
        fs in 1.0f64..1e6,
        delay in any::<u32>(),
        gain in -10.0f32..10.0,
        sections in proptest::collection::vec(stable_section(), 1..6),
        flip in any::<prop::sample::Index>(),
    ) {
        let mut buf = vec![0u8; blob::encoded_len(sections.len())];
        let n = blob::encode(&mut buf, fs, delay, gain, &sections).unwrap();
        prop_assert_eq!(n, buf.len());
        let set: CoefficientSet<8> = blob::parse(&buf).unwrap();
        let widened: Vec<[f64; 5]> = sections.iter().map(|s| s.map(f64::from)).collect();
        prop_assert_eq!(set.cascade, CascadeCoefficients::<f32, 8>::new(f64::from(gain), &widened).unwrap());
        prop_assert_eq!(set.sample_rate_hz, fs);
        prop_assert_eq!(set.delay_samples, delay);
        let bit = flip.index(buf.len() * 8);
        buf[bit / 8] ^= 1 << (bit % 8);
        prop_assert!(blob::parse::<8>(&buf).is_err(), "flip of bit {} undetected", bit);
    }
}

fn unlag(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_unlag"))
        .args(args)
        .output()
        .unwrap()
}

#[test]
fn cli_writes_all_three_formats() {
    let dir = tempfile::tempdir().unwrap();
    let model = model_path();
    for (format, file) in [("rust", "c.rs"), ("c", "c.h"), ("bin", "c.bin")] {
        let out = dir.path().join(file);
        let o = unlag(&[
            "export",
            model.to_str().unwrap(),
            "--format",
            format,
            "-o",
            out.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        assert!(String::from_utf8_lossy(&o.stdout).contains("4 sections"));
    }
    assert_eq!(
        std::fs::read(dir.path().join("c.bin")).unwrap(),
        SHIPPED_BLOB
    );
    let header = std::fs::read_to_string(dir.path().join("c.h")).unwrap();
    assert!(header.contains("#define UNLAG_SECTION_COUNT 4u"));
    assert!(header.contains("static const float unlag_sections[UNLAG_SECTION_COUNT][5]"));
    // The C header carries exactly the board's f32 values.
    let c = shipped();
    assert!(header.contains(&format!("{:?}f", c.sections[0][1])));
}

#[test]
fn cli_refuses_a_model_without_a_design_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(model_path()).unwrap();
    let cut = text.find("[inverse]").unwrap();
    let bare = dir.path().join("bare.toml");
    std::fs::write(&bare, &text[..cut]).unwrap();
    let out = dir.path().join("out.bin");
    let o = unlag(&[
        "export",
        bare.to_str().unwrap(),
        "--format",
        "bin",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert!(err.contains("no [inverse]"), "{err}");
    assert!(!out.exists());
    let e = export::export(&bare, Format::Rust, &out).unwrap_err();
    assert!(e.to_string().contains("bare.toml"), "{e}");
}

/// A model edited after its compensator was designed (its `a` emptied, a coefficient or the
/// delay changed, the compensator's model name removed) is refused at the field, and no blob
/// of the old compensator is written.
#[test]
fn cli_never_exports_a_compensator_that_does_not_belong_to_the_model() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(model_path()).unwrap();
    let a_line = text.lines().find(|l| l.starts_with("a = [")).unwrap();
    let first_a = a_line
        .trim_start_matches("a = [")
        .split(',')
        .next()
        .unwrap()
        .to_string();
    let nudged: f64 = first_a.trim().parse::<f64>().unwrap() * (1.0 + 1e-6);
    let cases = [
        (
            "empty-a.toml",
            text.replacen(a_line, "a = []", 1),
            "b has 5 coefficients but a has 0",
        ),
        (
            "nudged-a.toml",
            text.replacen(&first_a, &nudged.to_string(), 1),
            "designed for another model",
        ),
        (
            "delay.toml",
            text.replacen("\ndelay = 21\n", "\ndelay = 22\n", 1),
            "designed for another model",
        ),
        (
            "unnamed.toml",
            text.lines()
                .filter(|l| !l.starts_with("model_sha256"))
                .map(|l| format!("{l}\n"))
                .collect(),
            "does not name the model",
        ),
    ];
    for (name, edited, expected) in cases {
        assert_ne!(edited, text, "{name}: the edit did not apply");
        let model = dir.path().join(name);
        std::fs::write(&model, &edited).unwrap();
        for format in ["bin", "rust", "c"] {
            let out = dir.path().join(format!("{name}.{format}"));
            let o = unlag(&[
                "export",
                model.to_str().unwrap(),
                "--format",
                format,
                "-o",
                out.to_str().unwrap(),
            ]);
            let err = String::from_utf8_lossy(&o.stderr);
            assert_eq!(o.status.code(), Some(1), "{name}: {err}");
            assert_eq!(err.trim().lines().count(), 1, "{err}");
            assert!(err.contains(expected), "{name}: {err}");
            // The message names the file, line and column.
            assert!(err.contains(&format!("{name}:")), "{err}");
            assert!(!out.exists(), "{name}: {format} written");
        }
    }
    // What the refusal advises works: `unlag invert` designs a compensator for the edited
    // model (saying the stored one is dropped), and that one exports.
    let edited = dir.path().join("delay.toml");
    let again = dir.path().join("again.toml");
    let test = root().join("examples/data/step_test_1.csv");
    let o = unlag(&[
        "invert",
        edited.to_str().unwrap(),
        test.to_str().unwrap(),
        "-o",
        again.to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("designed for another model"), "{err}");
    // `unlag fit` onto a model file whose compensator names no model (written before the
    // compensator named its model) continues it and designs the compensator anew.
    let unnamed = dir.path().join("unnamed.toml");
    let o = unlag(&[
        "fit",
        test.to_str().unwrap(),
        "-o",
        unnamed.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let refitted = std::fs::read_to_string(&unnamed).unwrap();
    assert!(refitted.contains("\nmodel_sha256 = \""), "{refitted}");
    let bin = dir.path().join("again.bin");
    let o = unlag(&[
        "export",
        again.to_str().unwrap(),
        "--format",
        "bin",
        "-o",
        bin.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(bin.exists());
}

/// The fixed-point sections the board benchmark runs (examples/bench_board.rs), made from the
/// shipped design by `unlag::design::quantise::FixedPlan` for the first 1, 2 and 4 sections (m = 2, 4,
/// 8). `UNLAG_BLESS=1 cargo test --test export` rewrites the file.
fn render_fixed_bench_sections() -> String {
    let path = model_path();
    let file = ModelFile::load(&path).unwrap();
    let design = file.inverse.unwrap();
    let full_scale = 1000.0;
    let mut s = String::from(
        "// Generated by host-tests/export.rs from examples/data/board_model.toml with\n\
         // unlag::design::quantise::FixedPlan (`UNLAG_BLESS=1 cargo test --test export` rewrites it):\n\
         // the fixed-point compensator for the first K = 1, 2, 4 sections of the design\n\
         // (m = 2, 4, 8), for the board benchmark. Do not edit.\n",
    );
    s.push_str(&format!(
        "/// ADC full scale in Pa: the input code 2^31.\npub const FULL_SCALE: f64 = {full_scale:?};\n"
    ));
    for k in [1usize, 2, 4] {
        let mut d = design.clone();
        d.sections.truncate(k);
        let plan = unlag::design::quantise::FixedPlan::new(&d, full_scale).unwrap();
        s.push_str(&format!(
            "/// Output exponent for m = {m}: the output is Q1.31 of FULL_SCALE * 2^e.\npub const OUTPUT_EXPONENT_M{m}: i32 = {e};\n",
            m = 2 * k,
            e = plan.output_exponent
        ));
        s.push_str(&format!(
            "/// Sections for m = {m}.\npub const SECTIONS_M{m}: [unlag::board::fixed::FixedSection; {k}] = [\n",
            m = 2 * k
        ));
        for f in plan.board_sections() {
            s.push_str(&format!(
                "    unlag::board::fixed::FixedSection {{ a: {:?}, b: {:?}, c: {:?}, d: {}, shift: {} }},\n",
                f.a, f.b, f.c, f.d, f.shift
            ));
        }
        s.push_str("];\n");
    }
    s
}

#[test]
fn fixed_bench_sections_are_current() {
    let path = root().join("examples/data/board_fixed.rs");
    let want = render_fixed_bench_sections();
    if std::env::var("UNLAG_BLESS").is_ok_and(|v| v == "1") {
        std::fs::write(&path, &want).unwrap();
    }
    let have = std::fs::read_to_string(&path).unwrap_or_default();
    assert_eq!(
        have, want,
        "examples/data/board_fixed.rs is stale: UNLAG_BLESS=1 cargo test --test export"
    );
}

/// The direct-form sections the board benchmark and the QEMU test run (examples/bench_board.rs,
/// examples/board_replay.rs), made from the shipped design by `unlag::design::quantise::DirectPlan`
/// for the first 1, 2 and 4 sections (m = 2, 4, 8). `UNLAG_BLESS=1 cargo test --test export`
/// rewrites the file.
fn render_direct_bench_sections() -> String {
    let path = model_path();
    let file = ModelFile::load(&path).unwrap();
    let design = file.inverse.unwrap();
    let full_scale = 1000.0;
    let mut s = String::from(
        "// Generated by host-tests/export.rs from examples/data/board_model.toml with\n\
         // unlag::design::quantise::DirectPlan (`UNLAG_BLESS=1 cargo test --test export` rewrites it):\n\
         // the direct-form fixed-point compensator for the first K = 1, 2, 4 sections of the\n\
         // design (m = 2, 4, 8), for the board benchmark and the QEMU test. Do not edit.\n",
    );
    s.push_str(&format!(
        "/// ADC full scale in Pa: the input code 2^31.\npub const FULL_SCALE: f64 = {full_scale:?};\n"
    ));
    for k in [1usize, 2, 4] {
        let mut d = design.clone();
        d.sections.truncate(k);
        let plan = unlag::design::quantise::DirectPlan::new(&d, full_scale).unwrap();
        s.push_str(&format!(
            "/// Output exponent for m = {m}: the output is Q1.31 of FULL_SCALE * 2^e.\npub const OUTPUT_EXPONENT_M{m}: i32 = {e};\n",
            m = 2 * k,
            e = plan.output_exponent
        ));
        s.push_str(&format!(
            "/// Sections for m = {m}.\npub const SECTIONS_M{m}: [unlag::board::fixed::direct::DirectSection; {k}] = [\n",
            m = 2 * k
        ));
        for f in plan.board_sections() {
            s.push_str(&format!(
                "    unlag::board::fixed::direct::DirectSection {{ b: {:?}, neg_a: {:?} }},\n",
                f.b, f.neg_a
            ));
        }
        s.push_str("];\n");
    }
    s
}

#[test]
fn direct_bench_sections_are_current() {
    let path = root().join("examples/data/board_direct.rs");
    let want = render_direct_bench_sections();
    if std::env::var("UNLAG_BLESS").is_ok_and(|v| v == "1") {
        std::fs::write(&path, &want).unwrap();
    }
    let have = std::fs::read_to_string(&path).unwrap_or_default();
    assert_eq!(
        have, want,
        "examples/data/board_direct.rs is stale: UNLAG_BLESS=1 cargo test --test export"
    );
}

#[test]
fn fixed_point_export_round_trips_and_every_flip_is_refused() {
    let path = model_path();
    let file = ModelFile::load(&path).unwrap();
    let c = export::FixedBoardCoefficients::from_model_file(&file, &path, Some(1000.0)).unwrap();
    let bytes = c.to_bin().unwrap();
    assert_eq!(bytes.len(), blob::encoded_len_fixed(c.sections.len()));
    let set: blob::FixedCoefficientSet<4> = blob::parse_fixed(&bytes).unwrap();
    assert_eq!(
        set.cascade,
        unlag::board::fixed::FixedCascade::<4>::new(&c.sections).unwrap()
    );
    assert_eq!(set.full_scale, 1000.0);
    assert_eq!(set.output_exponent, c.output_exponent);
    assert_eq!(set.sample_rate_hz, c.sample_rate_hz);
    // The f32 parser refuses it with a typed error, and the other way round.
    assert_eq!(
        blob::parse::<4>(&bytes),
        Err(BlobError::UnsupportedNumberFormat { code: 1 })
    );
    assert_eq!(
        blob::parse_fixed::<4>(SHIPPED_BLOB),
        Err(BlobError::UnsupportedNumberFormat { code: 0 })
    );
    let mut flipped = bytes.clone();
    for byte in 0..flipped.len() {
        for bit in 0..8 {
            flipped[byte] ^= 1 << bit;
            assert!(
                blob::parse_fixed::<16>(&flipped).is_err(),
                "flip of bit {bit} in byte {byte} went undetected"
            );
            flipped[byte] ^= 1 << bit;
        }
    }
    for len in 0..bytes.len() {
        assert!(
            blob::parse_fixed::<16>(&bytes[..len]).is_err(),
            "truncation to {len}"
        );
    }
    // The Rust and C renderings carry the same integers.
    let rust = c.to_rust("board_model.toml");
    let header = c.to_c("board_model.toml");
    for s in &c.sections {
        assert!(rust.contains(&format!("a: {:?}", s.a)), "{rust}");
        assert!(
            header.contains(&format!("{{{}, {},", s.a[0], s.a[1])),
            "{header}"
        );
    }
}

#[test]
fn cli_exports_fixed_point_and_needs_a_full_scale_or_a_plan() {
    let dir = tempfile::tempdir().unwrap();
    let model = model_path();
    let out = dir.path().join("fixed.bin");
    let args = |extra: &[&str]| {
        let mut a = vec![
            "export",
            model.to_str().unwrap(),
            "--format",
            "bin",
            "--number-format",
            "fixed",
            "-o",
            out.to_str().unwrap(),
        ];
        a.extend_from_slice(extra);
        unlag(&a)
    };
    // The shipped model file has no stored plan.
    let o = args(&[]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("--full-scale"));
    assert!(!out.exists());
    let o = args(&["--full-scale", "1000", "--json"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["number_format"], "fixed");
    assert_eq!(v["sections"], 4);
    let bytes = std::fs::read(&out).unwrap();
    assert!(blob::parse_fixed::<4>(&bytes).is_ok());
}
