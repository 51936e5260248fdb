//! The reference C implementation that `unlag export --format c` writes into its headers,
//! against the library's kernels, bit for bit.
//!
//! For each number format the board runs (the `f32` cascade, the fixed-point normal form, the
//! fixed-point direct form) a header is exported with the `unlag` CLI from the shipped model
//! (and the blob beside it, with the same flags, for the Rust side), a small C driver is
//! compiled against the header, and the driver and the library's portable kernels
//! (`process_portable`) are run on the same script: the recorded trace
//! (`examples/data/step_test_2.csv`, `y`; Q1.31 codes of the full scale for fixed point) and
//! adversarial inputs (full-scale square waves, alternating extremes, zeros, impulses,
//! pseudo-random codes), from reset and from the equilibrium start. Every output word and the
//! overflow flag after every sample must be the same. Hand-made coefficient sets that saturate
//! (states, outputs, the equilibrium's conversions), and the `f32` nonlinear-damping
//! correction, go through the library's writer (`to_c`) in the same way.
//!
//! The driver is built with the system C compiler (`$CC`, else `cc`) as C99 with
//! `-Wall -Wextra -Werror -pedantic`, at `-O2` and `-O0`, and once more with the undefined
//! behaviour sanitizer (aborting on the first report) when the compiler has it. Skips with a
//! message when there is no C compiler, unless `UNLAG_REQUIRE_CC=1` (`.ci/run` sets it), which
//! turns a missing compiler (or sanitizer) into a failure.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

use unlag::board::blob;
use unlag::board::compensator::{
    CascadeCoefficients, CascadeState, NonlinearDampingCoefficients, NonlinearDampingState,
};
use unlag::board::fixed::direct::{DirectCascade, DirectSection, DirectState};
use unlag::board::fixed::{FixedCascade, FixedSection, FixedState};
use unlag::export::{
    BoardCoefficients, BoardNonlinear, DirectBoardCoefficients, FixedBoardCoefficients,
};

/// Sections of the shipped design (`examples/data/board_model.toml`): the capacity the Rust
/// side runs with, so that it has no identity sections the C does not run.
const SECTIONS: usize = 4;

/// ADC full scale in Pa the fixed-point plans are made for (the trace reads -163 to 802 Pa).
const FULL_SCALE: f64 = 1000.0;

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn required() -> bool {
    std::env::var("UNLAG_REQUIRE_CC").is_ok_and(|v| v == "1")
}

// ---------------------------------------------------------------------------------------------
// The script both sides run.

/// One step of the script: a line `<op> <hex>` for the driver, a call for the library.
#[derive(Debug, Clone, Copy)]
enum Op {
    /// `unlag_reset`: every state zero.
    Reset,
    /// `unlag_init` with this input (bits): the equilibrium start.
    Init(u32),
    /// `unlag_process` with this input (bits): one output line.
    Sample(u32),
    /// `unlag_take_overflow`: one output line, the flag taken.
    Take,
    /// `unlag_nonlinear_init` with this probe sample (bits).
    NonlinearInit(u32),
    /// `unlag_nonlinear_process` with this probe sample (bits): one output line.
    Nonlinear(u32),
}

impl Op {
    fn line(self) -> String {
        match self {
            Op::Reset => "r 0".into(),
            Op::Init(b) => format!("i {b:x}"),
            Op::Sample(b) => format!("x {b:x}"),
            Op::Take => "t 0".into(),
            Op::NonlinearInit(b) => format!("n {b:x}"),
            Op::Nonlinear(b) => format!("m {b:x}"),
        }
    }
}

/// Named runs, each a list of steps.
#[derive(Default)]
struct Script {
    runs: Vec<(String, Vec<Op>)>,
}

impl Script {
    fn run(&mut self, name: impl Into<String>, start: Op, inputs: &[u32]) {
        let mut ops = vec![start];
        ops.extend(inputs.iter().map(|&b| Op::Sample(b)));
        self.runs.push((name.into(), ops));
    }
}

/// What one output line says: the output word and the overflow flag.
type Line = (u32, bool);

/// The library's side of the script.
trait Reference {
    fn apply(&mut self, op: Op) -> Option<Line>;
}

/// The `f32` cascade (and, when given, the nonlinear-damping correction) of the library.
struct F32Ref<const N: usize, const L: usize> {
    cascade: CascadeCoefficients<f32, N>,
    state: CascadeState<f32, N>,
    nonlinear: Option<(
        NonlinearDampingCoefficients<f32, L>,
        NonlinearDampingState<f32, L>,
    )>,
}

impl<const N: usize, const L: usize> Reference for F32Ref<N, L> {
    fn apply(&mut self, op: Op) -> Option<Line> {
        let f = f32::from_bits;
        match op {
            Op::Reset => self.state = CascadeState::default(),
            Op::Init(x) => self.state = self.cascade.equilibrium(f(x)),
            Op::Sample(x) => {
                let y = self.cascade.process_portable(&mut self.state, f(x));
                return Some((y.to_bits(), false));
            }
            Op::Take => unreachable!("no overflow flag in f32"),
            Op::NonlinearInit(y) => {
                let (c, s) = self.nonlinear.as_mut().expect("a nonlinear correction");
                *s = c.equilibrium(f(y));
            }
            Op::Nonlinear(y) => {
                let (c, s) = self.nonlinear.as_mut().expect("a nonlinear correction");
                return Some((c.process(s, f(y)).to_bits(), false));
            }
        }
        None
    }
}

/// The fixed-point cascade in normal form.
struct FixedRef<const N: usize> {
    cascade: FixedCascade<N>,
    state: FixedState<N>,
}

impl<const N: usize> Reference for FixedRef<N> {
    fn apply(&mut self, op: Op) -> Option<Line> {
        let code = |b: u32| b as i32;
        match op {
            Op::Reset => self.state = FixedState::default(),
            Op::Init(x) => self.state = self.cascade.equilibrium(code(x)),
            Op::Sample(x) => {
                let y = self.cascade.process_portable(&mut self.state, code(x));
                return Some((y as u32, self.state.overflowed()));
            }
            Op::Take => return Some((0, self.state.take_overflow())),
            Op::NonlinearInit(_) | Op::Nonlinear(_) => unreachable!("f32 only"),
        }
        None
    }
}

/// The fixed-point cascade in direct form.
struct DirectRef<const N: usize> {
    cascade: DirectCascade<N>,
    state: DirectState<N>,
}

impl<const N: usize> Reference for DirectRef<N> {
    fn apply(&mut self, op: Op) -> Option<Line> {
        let code = |b: u32| b as i32;
        match op {
            Op::Reset => self.state = DirectState::default(),
            Op::Init(x) => self.state = self.cascade.equilibrium(code(x)),
            Op::Sample(x) => {
                let y = self.cascade.process_portable(&mut self.state, code(x));
                return Some((y as u32, self.state.overflowed()));
            }
            Op::Take => return Some((0, self.state.take_overflow())),
            Op::NonlinearInit(_) | Op::Nonlinear(_) => unreachable!("f32 only"),
        }
        None
    }
}

// ---------------------------------------------------------------------------------------------
// Inputs.

/// The probe signal `y` of the recorded step test, in Pa.
fn trace() -> Vec<f64> {
    let text = std::fs::read_to_string(root().join("examples/data/step_test_2.csv")).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let y = header
        .iter()
        .position(|h| h.trim() == "y")
        .expect("a y column");
    lines
        .filter(|l| !l.trim().is_empty())
        .map(|l| l.split(',').nth(y).unwrap().trim().parse().unwrap())
        .collect()
}

/// `y` as the Q1.31 code of [`FULL_SCALE`] (`y / F * 2^31`, rounded, clamped to `i32`).
fn code(y: f64) -> i32 {
    (y / FULL_SCALE * 2f64.powi(31))
        .round()
        .clamp(f64::from(i32::MIN), f64::from(i32::MAX)) as i32
}

/// Deterministic pseudo-random words (an LCG's high half, at random loudness).
fn random_codes(n: usize, seed: u64) -> Vec<i32> {
    let mut s = seed;
    (0..n)
        .map(|_| {
            s = s
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            ((s >> 32) as i32) >> (s % 8)
        })
        .collect()
}

/// A square wave between `lo` and `hi`, `half` samples each, for `n` samples.
fn square<T: Copy>(lo: T, hi: T, half: usize, n: usize) -> Vec<T> {
    (0..n)
        .map(|k| if (k / half).is_multiple_of(2) { hi } else { lo })
        .collect()
}

/// The runs of a fixed-point script: the trace from rest and from equilibrium, then
/// adversarial codes, from rest or from an equilibrium at an extreme; each run ends by taking
/// the overflow flag twice.
fn fixed_script() -> Script {
    let trace: Vec<u32> = trace().into_iter().map(|y| code(y) as u32).collect();
    let bits = |v: &[i32]| v.iter().map(|&c| c as u32).collect::<Vec<u32>>();
    let (min, max) = (i32::MIN, i32::MAX);
    let mut s = Script::default();
    s.run("trace from rest", Op::Reset, &trace);
    s.run("trace from equilibrium", Op::Init(trace[0]), &trace);
    s.run(
        "square wave at full scale",
        Op::Reset,
        &bits(&square(min, max, 50, 1000)),
    );
    s.run(
        "alternating extremes",
        Op::Init(max as u32),
        &bits(&square(min, max, 1, 400)),
    );
    s.run(
        "from the top to the bottom",
        Op::Init(max as u32),
        &bits(&[min; 300]),
    );
    s.run(
        "from the bottom to the top",
        Op::Init(min as u32),
        &bits(&[max; 300]),
    );
    s.run(
        "zeros after the extremes",
        Op::Reset,
        &bits(&[max, min, max, min]),
    );
    let mut zeros = vec![0u32; 600];
    zeros.extend(bits(&[1, -1, 1, -1, 0, 0, -1, -1, 2, -2]));
    s.runs
        .last_mut()
        .unwrap()
        .1
        .extend(zeros.iter().map(|&b| Op::Sample(b)));
    s.run(
        "impulse",
        Op::Init(0),
        &bits(&[max, 0, 0, 0, 0, 0, 0, 0, min, 0, 0, 0, 0]),
    );
    s.run(
        "pseudo-random codes",
        Op::Reset,
        &bits(&random_codes(3000, 0x2545_f491)),
    );
    s.run("equilibrium at -1", Op::Init(u32::MAX), &bits(&[-1; 50]));
    // The flag is sticky until taken; taken, it is clear.
    for (_, ops) in &mut s.runs {
        ops.push(Op::Take);
        ops.push(Op::Take);
    }
    s
}

/// The runs of an `f32` script, in Pa.
fn f32_script() -> Script {
    let trace: Vec<f32> = trace().into_iter().map(|y| y as f32).collect();
    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<u32>>();
    let fs = FULL_SCALE as f32;
    let mut s = Script::default();
    s.run("trace from rest", Op::Reset, &bits(&trace));
    s.run(
        "trace from equilibrium",
        Op::Init(trace[0].to_bits()),
        &bits(&trace),
    );
    s.run(
        "square wave at full scale",
        Op::Reset,
        &bits(&square(-fs, fs, 50, 1000)),
    );
    s.run(
        "alternating extremes",
        Op::Init(fs.to_bits()),
        &bits(&square(-fs, fs, 1, 400)),
    );
    let mut quiet = vec![0.0f32; 300];
    quiet.extend([-0.0, 0.0, -0.0, 1e-38, -1e-45, 0.0]);
    s.run("zeros", Op::Reset, &bits(&quiet));
    s.run(
        "equilibrium at -0",
        Op::Init((-0.0f32).to_bits()),
        &bits(&quiet),
    );
    s.run(
        "impulse",
        Op::Init(0),
        &bits(&[fs, 0.0, 0.0, 0.0, 0.0, 0.0, -fs, 0.0, 0.0, 0.0]),
    );
    let noise: Vec<f32> = random_codes(2000, 7)
        .into_iter()
        .map(|c| c as f32 / 2f32.powi(31) * fs)
        .collect();
    s.run("pseudo-random readings", Op::Reset, &bits(&noise));
    // Past the float range: infinities, then NaN (its payload is not compared).
    s.run(
        "beyond the float range",
        Op::Reset,
        &bits(&square(-3.0e38, 3.0e38, 1, 60)),
    );
    s
}

/// The nonlinear correction's runs: the same inputs, fed to `unlag_nonlinear_process`.
fn nonlinear_runs(s: &mut Script) {
    let runs: Vec<(String, Vec<Op>)> = s
        .runs
        .iter()
        .map(|(name, ops)| {
            let ops = ops.iter().map(|&op| match op {
                Op::Reset => Op::NonlinearInit(0),
                Op::Init(y) => Op::NonlinearInit(y),
                Op::Sample(y) => Op::Nonlinear(y),
                other => other,
            });
            (format!("nonlinear correction, {name}"), ops.collect())
        })
        .collect();
    s.runs.extend(runs);
}

// ---------------------------------------------------------------------------------------------
// The C side.

/// The C driver: reads `<op> <hex>` lines from the file named by its argument, calls the
/// header's functions and prints `<output bits> <overflow flag>` per sample.
const DRIVER: &str = r#"#include <stdio.h>
#include <string.h>
#include "coefficients.h"

#if defined(UNLAG_COEFFICIENTS_H)
typedef float sample;
#define OVERFLOWED(s) 0
#define TAKE(s) 0
#else
typedef int32_t sample;
#define OVERFLOWED(s) unlag_overflowed(&(s))
#define TAKE(s) unlag_take_overflow(&(s))
#endif

static sample from_bits(unsigned long bits)
{
    const uint32_t word = (uint32_t)bits;
    sample v;
    memcpy(&v, &word, sizeof v);
    return v;
}

static unsigned long to_bits(sample v)
{
    uint32_t word;
    memcpy(&word, &v, sizeof word);
    return (unsigned long)word;
}

int main(int argc, char **argv)
{
    FILE *in;
    char op;
    unsigned long bits;
    unlag_state s;
#if defined(UNLAG_NONLINEAR_SECTION_COUNT)
    unlag_nonlinear_state n;
    unlag_nonlinear_init(&n, 0.0f);
#endif
    if (argc != 2 || (in = fopen(argv[1], "r")) == NULL) {
        return 2;
    }
    unlag_reset(&s);
    while (fscanf(in, " %c %lx", &op, &bits) == 2) {
        switch (op) {
        case 'r': unlag_reset(&s); break;
        case 'i': unlag_init(&s, from_bits(bits)); break;
        case 'x': {
            const sample y = unlag_process(&s, from_bits(bits));
            printf("%08lx %d\n", to_bits(y), OVERFLOWED(s) != 0);
            break;
        }
        case 't': printf("%08lx %d\n", 0ul, TAKE(s) != 0); break;
#if defined(UNLAG_NONLINEAR_SECTION_COUNT)
        case 'n': unlag_nonlinear_init(&n, from_bits(bits)); break;
        case 'm': printf("%08lx 0\n", to_bits(unlag_nonlinear_process(&n, from_bits(bits)))); break;
#endif
        default: return 3;
        }
    }
    return feof(in) ? 0 : 4;
}
"#;

/// The C compiler: `$CC`, else `cc`, if it runs.
fn compiler() -> Option<String> {
    let cc = std::env::var("CC").unwrap_or_else(|_| "cc".into());
    let runs = Command::new(&cc)
        .arg("--version")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    runs.then_some(cc)
}

/// The flags every build takes: C99, every warning an error.
const STRICT: &[&str] = &[
    "-std=c99",
    "-Wall",
    "-Wextra",
    "-Werror",
    "-pedantic",
    "-ffp-contract=off",
];

/// The builds the driver is checked in: a name and the flags beside [`STRICT`].
const BUILDS: &[(&str, &[&str])] = &[
    ("-O2", &["-O2"]),
    ("-O0", &["-O0"]),
    (
        "-O1 with the undefined behaviour sanitizer",
        &[
            "-O1",
            "-fsanitize=undefined,float-cast-overflow",
            "-fno-sanitize-recover=all",
        ],
    ),
];

fn compile(cc: &str, dir: &Path, flags: &[&str], out: &str) -> Output {
    Command::new(cc)
        .current_dir(dir)
        .args(STRICT)
        .args(flags)
        .args(["driver.c", "-o", out])
        .output()
        .unwrap()
}

/// `true` when `cc` builds and runs a program with `flags` (the sanitizer needs its library).
fn builds_with(cc: &str, flags: &[&str]) -> bool {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("driver.c"),
        "int main(void) { return 0; }\n",
    )
    .unwrap();
    compile(cc, dir.path(), flags, "probe").status.success()
        && Command::new(dir.path().join("probe"))
            .status()
            .is_ok_and(|s| s.success())
}

/// Compiles the driver against `header` in each of [`BUILDS`], runs `script` through it and
/// through `reference`, and checks every line. `float`: the outputs are `f32` words (NaN
/// matches NaN: C and IEEE 754 leave its payload open).
fn check(what: &str, header: &str, script: &Script, reference: &mut dyn Reference, float: bool) {
    let Some(cc) = compiler() else {
        let reason = "no C compiler (cc, or $CC) found";
        assert!(!required(), "UNLAG_REQUIRE_CC=1 but {reason}");
        println!("SKIPPED the C reference of {what}: {reason}");
        eprintln!("SKIPPED the C reference of {what}: {reason}");
        return;
    };
    let mut input = String::new();
    let mut expected: Vec<(usize, usize, Line)> = Vec::new();
    for (run, (_, ops)) in script.runs.iter().enumerate() {
        let mut sample = 0;
        for &op in ops {
            let _ = writeln!(input, "{}", op.line());
            if let Some(line) = reference.apply(op) {
                expected.push((run, sample, line));
                sample += 1;
            }
        }
    }
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("coefficients.h"), header).unwrap();
    std::fs::write(dir.path().join("driver.c"), DRIVER).unwrap();
    std::fs::write(dir.path().join("script.txt"), &input).unwrap();
    for (i, (build, flags)) in BUILDS.iter().enumerate() {
        if flags.iter().any(|f| f.starts_with("-fsanitize")) && !builds_with(&cc, flags) {
            let reason = format!("{cc} cannot build with the sanitizer (libubsan)");
            assert!(!required(), "UNLAG_REQUIRE_CC=1 but {reason}");
            println!("note: the C reference of {what} not checked {build}: {reason}");
            continue;
        }
        let exe = format!("driver{i}");
        let o = compile(&cc, dir.path(), flags, &exe);
        assert!(
            o.status.success(),
            "{what}: the C reference does not build {build}:\n{}",
            String::from_utf8_lossy(&o.stderr)
        );
        let o = Command::new(dir.path().join(&exe))
            .arg(dir.path().join("script.txt"))
            .output()
            .unwrap();
        assert!(
            o.status.success(),
            "{what}: the C driver built {build} failed ({}):\n{}",
            o.status,
            String::from_utf8_lossy(&o.stderr)
        );
        let got: Vec<Line> = String::from_utf8(o.stdout)
            .unwrap()
            .lines()
            .map(|l| {
                let (bits, flag) = l.split_once(' ').expect("<bits> <flag>");
                (u32::from_str_radix(bits, 16).unwrap(), flag == "1")
            })
            .collect();
        assert_eq!(
            got.len(),
            expected.len(),
            "{what}, built {build}: the C driver wrote {} lines, the library {}",
            got.len(),
            expected.len()
        );
        let same = |a: u32, b: u32| {
            a == b || (float && f32::from_bits(a).is_nan() && f32::from_bits(b).is_nan())
        };
        for (&(run, k, (want, want_flag)), &(have, have_flag)) in expected.iter().zip(&got) {
            assert!(
                same(want, have) && want_flag == have_flag,
                "{what}, built {build}, {}, output {k}: C gave {have:#010x} (overflow {have_flag}), \
                 the library {want:#010x} (overflow {want_flag}){}",
                script.runs[run].0,
                if float {
                    format!(" = {} vs {}", f32::from_bits(have), f32::from_bits(want))
                } else {
                    format!(" = {} vs {}", have as i32, want as i32)
                }
            );
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Exports through the CLI.

fn model() -> PathBuf {
    root().join("examples/data/board_model.toml")
}

/// `unlag export` of the shipped model with `flags`, as a C header and as a blob (the same
/// coefficients, for the library's side).
fn export(flags: &[&str]) -> (String, Vec<u8>) {
    let dir = tempfile::tempdir().unwrap();
    let model = model();
    let mut outputs = Vec::new();
    for (format, file) in [("c", "coefficients.h"), ("bin", "coefficients.bin")] {
        let path = dir.path().join(file);
        let mut args = vec![
            "export",
            model.to_str().unwrap(),
            "--format",
            format,
            "-o",
            path.to_str().unwrap(),
        ];
        args.extend_from_slice(flags);
        let o = Command::new(env!("CARGO_BIN_EXE_unlag"))
            .args(&args)
            .output()
            .unwrap();
        assert!(
            o.status.success(),
            "unlag {}: {}",
            args.join(" "),
            String::from_utf8_lossy(&o.stderr)
        );
        outputs.push(std::fs::read(&path).unwrap());
    }
    let bin = outputs.pop().unwrap();
    (String::from_utf8(outputs.pop().unwrap()).unwrap(), bin)
}

#[test]
fn the_f32_cascade_in_c_is_the_librarys_bit_for_bit() {
    let (header, bin) = export(&[]);
    assert!(header.contains("static inline float unlag_process(unlag_state *state, float x)"));
    let set = blob::parse::<SECTIONS>(&bin).unwrap();
    assert_eq!(
        set.sections, SECTIONS,
        "the shipped design's section count changed"
    );
    assert!(set.nonlinear.is_none());
    let mut reference = F32Ref::<SECTIONS, 1> {
        cascade: set.cascade,
        state: CascadeState::default(),
        nonlinear: None,
    };
    check(
        "the f32 cascade",
        &header,
        &f32_script(),
        &mut reference,
        true,
    );
}

#[test]
fn the_fixed_point_normal_form_in_c_is_the_librarys_bit_for_bit() {
    let full_scale = FULL_SCALE.to_string();
    let (header, bin) = export(&["--number-format", "fixed", "--full-scale", &full_scale]);
    assert!(
        header.contains("static inline int32_t unlag_process(unlag_state *state, int32_t input)")
    );
    let set = blob::parse_fixed::<SECTIONS>(&bin).unwrap();
    assert_eq!(
        set.sections, SECTIONS,
        "the shipped design's section count changed"
    );
    let mut reference = FixedRef {
        cascade: set.cascade,
        state: FixedState::default(),
    };
    check(
        "the normal form",
        &header,
        &fixed_script(),
        &mut reference,
        false,
    );
}

#[test]
fn the_fixed_point_direct_form_in_c_is_the_librarys_bit_for_bit() {
    let full_scale = FULL_SCALE.to_string();
    let (header, bin) = export(&[
        "--number-format",
        "fixed",
        "--fixed-form",
        "direct",
        "--full-scale",
        &full_scale,
    ]);
    assert!(header.contains("unlag_direct_sections"));
    let set = blob::parse_direct::<SECTIONS>(&bin).unwrap();
    assert_eq!(
        set.sections, SECTIONS,
        "the shipped design's section count changed"
    );
    let mut reference = DirectRef {
        cascade: set.cascade,
        state: DirectState::default(),
    };
    check(
        "the direct form",
        &header,
        &fixed_script(),
        &mut reference,
        false,
    );
}

// ---------------------------------------------------------------------------------------------
// Hand-made sets, through the library's writer: the paths planned coefficients never take.

/// How many of `script`'s output lines `reference` gives with the overflow flag set.
fn flagged(script: &Script, reference: &mut dyn Reference) -> usize {
    let mut n = 0;
    for &op in script.runs.iter().flat_map(|(_, ops)| ops) {
        n += usize::from(reference.apply(op).is_some_and(|(_, flag)| flag));
    }
    n
}

fn q30(v: f64) -> i32 {
    (v * 2f64.powi(30)).round() as i32
}

/// Three normal-form sets with coefficients at the limits the board accepts: one that rounds
/// halves of both signs (shift 1) and saturates its states and outputs for loud inputs
/// without losing what quieter ones carry, one whose output step is 2^-32 of a state
/// (shift 62: -2^31 / 2^32 = -1/2 rounds up to 0), and one whose equilibrium state for an odd
/// code is a half (rounded away from zero), which its output shows.
fn hand_made_normal_forms() -> [Vec<FixedSection>; 3] {
    let (r, th) = (0.95f64, 0.2f64);
    let (sg, w) = (r * th.cos(), r * th.sin());
    [
        vec![
            // A rotation, output rounded at half a code: y = round((x1 - x2 + u) / 2).
            FixedSection {
                a: [q30(sg), q30(-w), q30(w), q30(sg)],
                b: [1 << 28, -(1 << 29)],
                c: [1, -1],
                d: 1,
                shift: 1,
            },
            // Gain four: saturates above a quarter of full scale.
            FixedSection {
                d: 1 << 30,
                shift: 28,
                ..FixedSection::IDENTITY
            },
            // Lower triangular, b at the limit: the states leave int32 for loud inputs; the
            // output y = round((x1 - x2 + u) / 2).
            FixedSection {
                a: [q30(0.9), 0, q30(0.5), q30(-0.8)],
                b: [1 << 30, -(1 << 30)],
                c: [1 << 30, -(1 << 30)],
                d: 1 << 30,
                shift: 31,
            },
        ],
        vec![FixedSection {
            a: [q30(0.5), 0, 0, q30(0.25)],
            b: [-(1 << 30), 1 << 30],
            c: [1 << 30, -(1 << 30)],
            d: -(1 << 30),
            shift: 62,
        }],
        // x1 = 0.25 u / (1 - 0.5) = u / 2 at equilibrium, and y = x1.
        vec![FixedSection {
            a: [1 << 29, 0, 0, 1 << 29],
            b: [1 << 28, 0],
            c: [1 << 30, 0],
            d: 0,
            shift: 30,
        }],
    ]
}

#[test]
fn saturation_rounding_and_the_flag_of_the_normal_form_in_c_are_the_librarys() {
    let script = fixed_script();
    for (i, sections) in hand_made_normal_forms().into_iter().enumerate() {
        // Capacity 3: the library pads with identities, which pass codes through exactly.
        let cascade = FixedCascade::<3>::new(&sections).unwrap();
        let header = FixedBoardCoefficients {
            sample_rate_hz: 10_000.0,
            delay_samples: 3,
            latency_samples: 4.5,
            full_scale: FULL_SCALE,
            output_exponent: 2,
            sections,
        }
        .to_c("hand-made.toml");
        let mut reference = FixedRef {
            cascade,
            state: FixedState::default(),
        };
        if i == 0 {
            // The script does take this set's saturating paths (every run starts with a reset
            // or an equilibrium, so this dry run leaves nothing behind for the check).
            let flags = flagged(&script, &mut reference);
            assert!(flags > 100, "only {flags} outputs with the flag set");
        }
        let what = format!("hand-made normal form {i}");
        check(&what, &header, &script, &mut reference, false);
    }
}

#[test]
fn saturation_and_the_flag_of_the_direct_form_in_c_are_the_librarys() {
    let lowpass = |r: f64, th: f64, gain: f64| {
        let (a1, a2) = (-2.0 * r * th.cos(), r * r);
        let g = gain * (1.0 + a1 + a2) / 4.0;
        DirectSection {
            b: [q30(g), q30(2.0 * g), q30(g)],
            neg_a: [q30(-a1), q30(-a2)],
        }
    };
    let sections = vec![
        // DC gain 2: saturates for loud inputs.
        lowpass(0.5, 0.3, 2.0),
        // A resonance near z = 1 with a sign-flipped numerator.
        DirectSection {
            b: [-(1 << 29), 1 << 28, -(1 << 27)],
            neg_a: [q30(1.9), q30(-0.95)],
        },
        lowpass(0.9, 1.0, 1.0),
    ];
    let cascade = DirectCascade::<3>::new(&sections).unwrap();
    let header = DirectBoardCoefficients {
        sample_rate_hz: 10_000.0,
        delay_samples: 3,
        latency_samples: 4.5,
        full_scale: FULL_SCALE,
        output_exponent: -1,
        sections,
    }
    .to_c("hand-made.toml");
    let script = fixed_script();
    let mut probe = DirectRef {
        cascade,
        state: DirectState::default(),
    };
    let flags = flagged(&script, &mut probe);
    assert!(flags > 100, "only {flags} outputs with the flag set");
    let mut reference = DirectRef {
        cascade,
        state: DirectState::default(),
    };
    check(
        "a saturating direct form",
        &header,
        &script,
        &mut reference,
        false,
    );
}

#[test]
fn a_hand_made_f32_set_with_the_nonlinear_correction_in_c_is_the_librarys() {
    // Sections whose DC gains (the equilibrium start) differ when formed in float rather than
    // in double, as the board forms them.
    let gain = 0.37f32;
    let sections = vec![
        [0.3, 0.2, 0.1, -1.1, 0.35],
        [-0.53, -0.54, -0.56, -0.97, 0.23],
    ];
    for (i, s) in sections.iter().enumerate() {
        let g = if i == 0 { gain } else { 1.0 };
        let in_float = g * (s[0] + s[1] + s[2]) / (1.0 + s[3] + s[4]);
        let wide = s.map(f64::from);
        let in_double = f64::from(g) * (wide[0] + wide[1] + wide[2]) / (1.0 + wide[3] + wide[4]);
        assert_ne!(in_float, in_double as f32, "section {i}");
    }
    // Gains whose product is not a float, and a first numerator of no powers of two, so that
    // the double rounding of the folded numerator matters; a two-section low-pass.
    let nonlinear = BoardNonlinear {
        gain: 0.7,
        lowpass_gain: 0.13,
        lowpass: vec![
            [
                0.020_083_4,
                0.040_166_8,
                0.020_083_4,
                -1.561_018,
                0.641_351_4,
            ],
            [0.7, 0.3, 0.0, -0.2, 0.0],
        ],
    };
    let g = f64::from(nonlinear.gain) * f64::from(nonlinear.lowpass_gain);
    let folded_in_float = |b: f32| g as f32 * b != (g * f64::from(b)) as f32;
    assert!(nonlinear.lowpass[0][..3]
        .iter()
        .all(|&b| folded_in_float(b)));
    let widened = |s: &[[f32; 5]]| s.iter().map(|s| s.map(f64::from)).collect::<Vec<_>>();
    let correction = NonlinearDampingCoefficients::<f32, 2>::new(
        f64::from(nonlinear.gain),
        f64::from(nonlinear.lowpass_gain),
        &widened(&nonlinear.lowpass),
    )
    .unwrap();
    let cascade = CascadeCoefficients::<f32, 2>::new(f64::from(gain), &widened(&sections)).unwrap();
    let header = BoardCoefficients {
        sample_rate_hz: 10_000.0,
        delay_samples: 3,
        latency_samples: 4.5,
        gain,
        sections,
        nonlinear: Some(nonlinear),
    }
    .to_c("hand-made.toml");
    assert!(header.contains("unlag_nonlinear_process"));
    let mut script = f32_script();
    nonlinear_runs(&mut script);
    let mut reference = F32Ref {
        cascade,
        state: CascadeState::default(),
        nonlinear: Some((correction, correction.equilibrium(0.0))),
    };
    check(
        "a hand-made f32 set with the nonlinear correction",
        &header,
        &script,
        &mut reference,
        true,
    );
}
