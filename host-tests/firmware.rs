//! The board example in QEMU against the host, bit for bit.
//!
//! Builds `examples/board_replay.rs` for each Cortex-M target the crate has kernels for, boots
//! it in `qemu-system-arm`, and checks that every reconstructed sample it reports over
//! semihosting has exactly the bits the host gets from the same library code, the same
//! exported blob and the same recorded trace:
//! * `thumbv7em-none-eabihf` on `mps2-an386` (Cortex-M4F): every kernel, `f32` and fixed point;
//! * `thumbv7m-none-eabi` on `mps2-an385` (Cortex-M3, no FPU, no DSP extension): the
//!   fixed-point kernels, the `f32` cascade in portable code with software floats;
//! * `thumbv7em-none-eabi` on `mps2-an386` (Cortex-M4, soft-float calling convention): the
//!   same as the M3.
//!
//! And the link of a firmware that depends on unlag: `host-tests/link-check/`, built for
//! `thumbv7em-none-eabihf` with its memory map from a board-support crate whose name sorts
//! before `unlag` (`aardvark-bsp`) or after it (`zebra-bsp`), must put its vector table where
//! that map's flash starts, never where unlag's own `memory.x` (the QEMU map, for unlag's
//! examples only) puts it. These read the ELF and need no QEMU.
//!
//! Skips with a message when `qemu-system-arm` (for the QEMU runs) or the Rust target is
//! missing, unless `UNLAG_REQUIRE_QEMU=1` (CI sets it), which turns a missing tool into a
//! failure.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use std::ops::Range;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::Mutex;
use std::time::{Duration, Instant};

use unlag::board::blob::{self, CoefficientSet};

mod trace {
    include!("../examples/data/board_trace.rs");
}

/// A Rust target, the QEMU machine that runs it, and whether its `f32` cascade has kernels.
struct Board {
    target: &'static str,
    machine: &'static str,
    f32_kernel: bool,
}

const BLOB: &[u8] = include_bytes!("../examples/data/board_coefficients.bin");

fn required() -> bool {
    std::env::var("UNLAG_REQUIRE_QEMU").is_ok_and(|v| v == "1")
}

/// `Some(reason)` when the tools to run firmware for `target` are missing.
fn missing_tools(target: &str) -> Option<String> {
    let qemu = Command::new("qemu-system-arm")
        .arg("--version")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status();
    if !qemu.is_ok_and(|s| s.success()) {
        return Some(
            "qemu-system-arm is not installed (apt-get install qemu-system-arm)".to_string(),
        );
    }
    missing_target(target)
}

/// `Some(reason)` when the Rust standard library for `target` is not installed.
fn missing_target(target: &str) -> Option<String> {
    let rustup = Command::new("rustup")
        .args(["target", "list", "--installed"])
        .output();
    match rustup {
        Ok(o)
            if String::from_utf8_lossy(&o.stdout)
                .lines()
                .any(|l| l.trim() == target) =>
        {
            None
        }
        _ => Some(format!(
            "the Rust target {target} is not installed (rustup target add {target})"
        )),
    }
}

/// Builds a board example for `target` and returns its ELF.
fn build_example(name: &str, target: &str) -> PathBuf {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    // A target directory of its own: the outer `cargo test` may hold the main one's lock.
    let target_dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("firmware");
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let out = Command::new(cargo)
        .current_dir(root)
        .args([
            "build",
            "--release",
            "--no-default-features",
            "--target",
            target,
        ])
        .args(["--example", name, "--target-dir"])
        .arg(&target_dir)
        .env_remove("RUSTFLAGS")
        .output()
        .expect("cargo runs");
    assert!(
        out.status.success(),
        "building {name} for {target} failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    target_dir
        .join(target)
        .join("release")
        .join("examples")
        .join(name)
}

/// Boots `elf` on the QEMU machine `machine` and returns (exit status, stdout).
fn run_in_qemu(elf: &Path, machine: &str) -> (Option<i32>, String) {
    let mut child = Command::new("qemu-system-arm")
        .args([
            "-M",
            machine,
            "-nographic",
            "-monitor",
            "none",
            "-serial",
            "none",
        ])
        .args([
            "-semihosting-config",
            "enable=on,target=native",
            "-icount",
            "shift=0",
        ])
        .arg("-kernel")
        .arg(elf)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("qemu starts");
    let deadline = Instant::now() + Duration::from_secs(120);
    loop {
        if child.try_wait().expect("qemu status").is_some() {
            break;
        }
        if Instant::now() > deadline {
            let _ = child.kill();
            panic!("{} did not finish in QEMU within 120 s", elf.display());
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let out = child.wait_with_output().expect("qemu output");
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
    )
}

/// The host's run of the same compensator on the same trace: one `f32` bit pattern per sample.
fn host_outputs() -> Vec<u32> {
    let set: CoefficientSet<4> = blob::parse(BLOB).expect("the shipped blob is valid");
    let mut state = set.cascade.equilibrium(trace::TRACE[0]);
    trace::TRACE
        .iter()
        .map(|&y| set.cascade.process(&mut state, y).to_bits())
        .collect()
}

#[allow(dead_code)]
mod coefficients {
    include!("../examples/data/board_coefficients.rs");
}

/// FNV-1a (64 bits) over `f32` bit patterns, as `examples/board_replay.rs` computes it.
fn fnv1a(bits: impl Iterator<Item = u32>) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in bits {
        for byte in b.to_le_bytes() {
            h ^= u64::from(byte);
            h = h.wrapping_mul(0x0000_0100_0000_01b3);
        }
    }
    h
}

/// The host's outputs for the first `K` sections, one portable call per sample.
fn host_sections<const K: usize>() -> Vec<u32> {
    let c = unlag::board::compensator::CascadeCoefficients::<f32, K>::new(
        coefficients::GAIN,
        &coefficients::SECTIONS[..K],
    )
    .expect("valid sections");
    let mut state = c.equilibrium(trace::TRACE[0]);
    trace::TRACE
        .iter()
        .map(|&y| c.process_portable(&mut state, y).to_bits())
        .collect()
}

mod stress {
    include!("../examples/data/fixed_stress.rs");
}

/// The host's run of the fixed-point stress case: the hash of outputs and overflow flags, and
/// the number of samples that overflowed (as `examples/board_replay.rs` reports them).
fn host_fixed_stress() -> (u64, u32) {
    let c = unlag::board::fixed::FixedCascade::<4>::new(&stress::STRESS_SECTIONS).expect("valid");
    let mut state = unlag::board::fixed::FixedState::default();
    let mut overflows = 0u32;
    let mut bits = Vec::new();
    for k in 0..stress::STRESS_LEN {
        let y = c.process_portable(&mut state, stress::stress_input(k));
        let flag = state.take_overflow();
        overflows += u32::from(flag);
        bits.extend([y as u32, u32::from(flag)]);
    }
    (fnv1a(bits.into_iter()), overflows)
}

#[allow(dead_code)]
mod fixed {
    include!("../examples/data/board_fixed.rs");
}

/// The host's run of the fixed-point compensator: one output code per sample.
fn host_fixed_outputs() -> Vec<u32> {
    let code = |y: f32| (f64::from(y) / fixed::FULL_SCALE * 2_147_483_648.0).round() as i32;
    let c =
        unlag::board::fixed::FixedCascade::<4>::new(&fixed::SECTIONS_M8).expect("valid sections");
    let mut state = c.equilibrium(code(trace::TRACE[0]));
    trace::TRACE
        .iter()
        .map(|&y| c.process(&mut state, code(y)) as u32)
        .collect()
}

#[allow(dead_code)]
mod direct {
    include!("../examples/data/board_direct.rs");
}

/// Block lengths of `examples/board_replay.rs`'s block runs.
const CHUNKS: [usize; 12] = [0, 1, 2, 3, 4, 5, 6, 7, 8, 11, 64, 100];

/// The host's lines for one direct-form run of `examples/board_replay.rs` (`DH <name> K=<k>
/// call <hash> overflows=<n>` and `DH <name> K=<k> block <hash>`), with the portable code.
fn host_direct<const K: usize>(
    name: &str,
    sections: &[unlag::board::fixed::direct::DirectSection],
    input: &[i32],
) -> [String; 2] {
    use unlag::board::fixed::direct::{DirectCascade, DirectState};
    let c = DirectCascade::<K>::new(&sections[..K]).expect("valid sections");
    let mut state = DirectState::<K>::default();
    let mut overflows = 0u32;
    let mut bits = Vec::new();
    for &x in input {
        let y = c.process_portable(&mut state, x);
        let flag = state.take_overflow();
        overflows += u32::from(flag);
        bits.extend([y as u32, u32::from(flag)]);
    }
    let call = format!(
        "DH {name} K={K} call {:016x} overflows={overflows}",
        fnv1a(bits.into_iter())
    );
    let mut buf = input.to_vec();
    let mut state = DirectState::<K>::default();
    let mut flags = Vec::new();
    let mut rest = &mut buf[..];
    for n in CHUNKS.iter().cycle().take(64) {
        let (head, tail) = rest.split_at_mut((*n).min(rest.len()));
        c.process_in_place_portable(&mut state, head);
        flags.push(u32::from(state.take_overflow()));
        rest = tail;
    }
    c.process_in_place_portable(&mut state, rest);
    flags.push(u32::from(state.take_overflow()));
    let block = format!(
        "DH {name} K={K} block {:016x}",
        fnv1a(buf.iter().map(|v| *v as u32).chain(flags))
    );
    [call, block]
}

/// Every direct-form line the board must print, from the host's portable code.
fn host_direct_lines() -> Vec<String> {
    let code = |y: f32| (f64::from(y) / direct::FULL_SCALE * 2_147_483_648.0).round() as i32;
    let trace: Vec<i32> = trace::TRACE.iter().map(|&y| code(y)).collect();
    let stress: Vec<i32> = (0..stress::STRESS_LEN).map(stress::stress_input).collect();
    let (s, st) = (&direct::SECTIONS_M8, &stress::DIRECT_STRESS_SECTIONS);
    [
        host_direct::<1>("trace", s, &trace),
        host_direct::<2>("trace", s, &trace),
        host_direct::<3>("trace", s, &trace),
        host_direct::<4>("trace", s, &trace),
        host_direct::<1>("stress", st, &stress),
        host_direct::<2>("stress", st, &stress),
        host_direct::<3>("stress", st, &stress),
        host_direct::<4>("stress", st, &stress),
    ]
    .into_iter()
    .flatten()
    .collect()
}

#[test]
fn board_replay_in_qemu_is_bit_identical_to_the_host() {
    check_board_replay(&Board {
        target: "thumbv7em-none-eabihf",
        machine: "mps2-an386",
        f32_kernel: true,
    });
}

#[test]
fn board_replay_on_a_cortex_m3_is_bit_identical_to_the_host() {
    check_board_replay(&Board {
        target: "thumbv7m-none-eabi",
        machine: "mps2-an385",
        f32_kernel: false,
    });
}

#[test]
fn board_replay_on_a_soft_float_cortex_m4_is_bit_identical_to_the_host() {
    check_board_replay(&Board {
        target: "thumbv7em-none-eabi",
        machine: "mps2-an386",
        f32_kernel: false,
    });
}

/// `u_hat` of `unlag compensate` with its defaults on the replayed trace (the f32 samples
/// widened exactly), with the shipped model file as it is (`None`: an f32 board), or with a
/// `[board]` section for a fixed-point board whose ADC reads +-`full_scale`.
fn cli_u_hat(full_scale: Option<f64>) -> Vec<f64> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!(
        "cli-as-board-{}",
        full_scale.map_or("f32".to_string(), |f| f.to_string())
    ));
    std::fs::create_dir_all(&dir).unwrap();
    let mut model = std::fs::read_to_string(root.join("examples/data/board_model.toml")).unwrap();
    if let Some(fs) = full_scale {
        model.push_str(&format!(
            "\n[board]\narithmetic = \"fixed\"\nfull_scale = {fs:?}\n"
        ));
    }
    let model_path = dir.join("model.toml");
    std::fs::write(&model_path, model).unwrap();
    let mut csv = String::from("t,y\n");
    for (k, y) in trace::TRACE.iter().enumerate() {
        csv.push_str(&format!("{},{}\n", k as f64 / 10_000.0, f64::from(*y)));
    }
    let (input, output) = (dir.join("trace.csv"), dir.join("out.csv"));
    std::fs::write(&input, csv).unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_unlag"))
        .arg("compensate")
        .args([&model_path, &input])
        .arg("-o")
        .arg(&output)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = std::fs::read_to_string(&output).unwrap();
    let mut lines = text.lines();
    let column = lines
        .next()
        .unwrap()
        .split(',')
        .position(|h| h == "u_hat")
        .unwrap();
    lines
        .map(|l| l.split(',').nth(column).unwrap().parse().unwrap())
        .collect()
}

/// Builds and boots `examples/board_replay.rs` for `board` and checks all it reports against
/// the host; every Cortex-M target runs the fixed-point kernels.
fn check_board_replay(board: &Board) {
    let test = format!("board_replay on {} ({})", board.target, board.machine);
    if let Some(reason) = missing_tools(board.target) {
        assert!(!required(), "UNLAG_REQUIRE_QEMU=1 but {reason}");
        println!("SKIPPED {test}: {reason}");
        eprintln!("SKIPPED {test}: {reason}");
        return;
    }
    let elf = build_example("board_replay", board.target);
    let (status, stdout) = run_in_qemu(&elf, board.machine);
    assert_eq!(status, Some(0), "{test} failed in QEMU:\n{stdout}");
    let board_y: Vec<(usize, u32)> = stdout
        .lines()
        .filter_map(|l| l.strip_prefix("Y "))
        .map(|l| {
            let (k, bits) = l.split_once(' ').expect("Y <k> <bits>");
            (
                k.parse().expect("sample index"),
                u32::from_str_radix(bits, 16).expect("hex bits"),
            )
        })
        .collect();
    let host = host_outputs();
    assert_eq!(
        board_y.len(),
        host.len(),
        "the board reported {} samples, the trace has {}",
        board_y.len(),
        host.len()
    );
    for (k, ((i, b), h)) in board_y.iter().zip(&host).enumerate() {
        assert_eq!(*i, k, "sample numbering");
        assert_eq!(
            b,
            h,
            "{test}, sample {k}: board {} ({b:#010x}) != host {} ({h:#010x})",
            f32::from_bits(*b),
            f32::from_bits(*h)
        );
    }
    // The fixed-point compensator, the same way, through its kernel.
    assert!(
        stdout.lines().any(|l| l == "FKERNEL asm"),
        "{test}: the fixed-point cascade does not run its kernel:\n{stdout}"
    );
    let board_fixed: Vec<u32> = stdout
        .lines()
        .filter_map(|l| l.strip_prefix("F "))
        .map(|l| {
            let (_, bits) = l.split_once(' ').expect("F <k> <code>");
            u32::from_str_radix(bits, 16).expect("hex code")
        })
        .collect();
    let host_fixed = host_fixed_outputs();
    assert_eq!(board_fixed.len(), host_fixed.len(), "fixed-point samples");
    for (k, (b, h)) in board_fixed.iter().zip(&host_fixed).enumerate() {
        assert_eq!(
            b, h,
            "{test}, fixed point, sample {k}: board {b:#010x} != host {h:#010x}"
        );
    }
    assert!(stdout.contains("FIXED overflow=false"), "{stdout}");
    // `unlag compensate` with its defaults computes what the board computed, in the board's
    // arithmetic: f32 for the shipped model, fixed point for the same model given a
    // fixed-point board and the ADC's range.
    let cli_f32: Vec<u32> = cli_u_hat(None)
        .into_iter()
        .map(|v| (v as f32).to_bits())
        .collect();
    let board_f32: Vec<u32> = board_y.iter().map(|&(_, b)| b).collect();
    assert_eq!(
        cli_f32, board_f32,
        "{test}: unlag compensate (f32) != the board"
    );
    let lsb = fixed::FULL_SCALE * f64::from(fixed::OUTPUT_EXPONENT_M8 - 31).exp2();
    let cli_fixed: Vec<u32> = cli_u_hat(Some(fixed::FULL_SCALE))
        .into_iter()
        .map(|v| (v / lsb).round() as i32 as u32)
        .collect();
    assert_eq!(
        cli_fixed, board_fixed,
        "{test}: unlag compensate (fixed) != the board"
    );
    assert!(
        stdout.contains("UPDATE refused: blob corrupted"),
        "{stdout}"
    );
    // The Cortex-M kernels (1 to 4 sections, one call per sample and in blocks of every
    // length modulo 3; the portable code where the target has no kernel) against the host's
    // portable code, bit for bit, through hashes.
    let host_hashes = [
        fnv1a(host_sections::<1>().into_iter()),
        fnv1a(host_sections::<2>().into_iter()),
        fnv1a(host_sections::<3>().into_iter()),
        fnv1a(host_sections::<4>().into_iter()),
    ];
    assert_eq!(
        host_hashes[3],
        fnv1a(host.iter().copied()),
        "the blob and the Rust constants describe the same design"
    );
    let f32_kind = if board.f32_kernel { "asm" } else { "portable" };
    for (k, h) in host_hashes.iter().enumerate() {
        let k = k + 1;
        assert!(
            stdout
                .lines()
                .any(|l| l == format!("KERNEL K={k} {f32_kind}")),
            "{test}: the f32 cascade of {k} sections should run the {f32_kind} code:\n{stdout}"
        );
        for mode in ["call", "block"] {
            let want = format!("H K={k} {mode} {h:016x}");
            assert!(
                stdout.lines().any(|l| l == want),
                "{test}, {k} sections, {mode}: the board's hash differs from the host's ({want}):\n{}",
                stdout
                    .lines()
                    .filter(|l| l.starts_with("H ") || l.starts_with("KERNEL"))
                    .collect::<Vec<_>>()
                    .join("\n")
            );
        }
    }
    assert!(
        host_hashes.windows(2).all(|w| w[0] != w[1]),
        "each number of sections is a different filter"
    );
    // The fixed-point kernel's saturation paths against the portable code.
    let (h, overflows) = host_fixed_stress();
    assert!(
        overflows > 100 && (overflows as usize) < stress::STRESS_LEN - 100,
        "the stress case must saturate sometimes, not always: {overflows}"
    );
    let want = format!("STRESS {h:016x} overflows={overflows}");
    assert!(
        stdout.lines().any(|l| l == want),
        "{test}, fixed-point stress: board and host differ (host: {want}):\n{}",
        stdout
            .lines()
            .filter(|l| l.starts_with("STRESS"))
            .collect::<Vec<_>>()
            .join("\n")
    );
    // The direct-form kernels (1 to 4 sections, per call and in blocks of the lengths in
    // CHUNKS, on the planned sections and on sections that saturate) against the portable code.
    for k in 1..=4 {
        for name in ["trace", "stress"] {
            assert!(
                stdout
                    .lines()
                    .any(|l| l == format!("DKERNEL {name} K={k} asm")),
                "{test}: the direct-form kernel for {k} sections does not run:\n{stdout}"
            );
        }
    }
    let direct_lines = host_direct_lines();
    for want in &direct_lines {
        assert!(
            stdout.lines().any(|l| l == want),
            "{test}, direct form: the board differs from the host (host: {want}):\n{}",
            stdout
                .lines()
                .filter(|l| l.starts_with("DH "))
                .collect::<Vec<_>>()
                .join("\n")
        );
    }
    let stress_overflows: Vec<u32> = direct_lines
        .iter()
        .filter(|l| l.starts_with("DH stress") && l.contains(" call "))
        .map(|l| l.rsplit_once('=').unwrap().1.parse().unwrap())
        .collect();
    assert!(
        stress_overflows
            .iter()
            .all(|&n| n > 10 && (n as usize) < stress::STRESS_LEN - 100),
        "the direct-form stress case must saturate sometimes, not always: {stress_overflows:?}"
    );
    assert!(stdout.contains("DONE ok"), "{stdout}");
    // The reconstruction is a real one: it falls with the step like the trace does.
    let first = f32::from_bits(host[0]);
    let last = f32::from_bits(host[host.len() - 1]);
    assert!(first > 700.0 && last < 200.0, "{first} -> {last}");
}

/// The map `host-tests/link-check/*-bsp/build.rs` give: flash, and the top of RAM (128 KiB
/// from 0x2000_0000), where cortex-m-rt starts the stack. unlag's own `memory.x` has flash at
/// 0x0000_0000 and RAM up to 0x2040_0000.
const BSP_FLASH: Range<u32> = 0x0800_0000..0x0810_0000;
const BSP_STACK_START: u32 = 0x2002_0000;

/// The link-check builds share a target directory and write the same ELF path: one at a time.
static LINK_CHECK: Mutex<()> = Mutex::new(());

#[test]
fn a_firmware_links_with_the_memory_map_of_a_bsp_named_before_unlag() {
    check_link("aardvark");
}

#[test]
fn a_firmware_links_with_the_memory_map_of_a_bsp_named_after_unlag() {
    check_link("zebra");
}

/// Builds `host-tests/link-check/` with the board-support crate `<bsp>-bsp` and checks from
/// the ELF that the vector table and the reset handler are in that crate's flash and the
/// initial stack pointer at the top of its RAM.
fn check_link(bsp: &str) {
    let target = "thumbv7em-none-eabihf";
    let test = format!("the link-check firmware with {bsp}-bsp");
    if let Some(reason) = missing_target(target) {
        assert!(!required(), "UNLAG_REQUIRE_QEMU=1 but {reason}");
        println!("SKIPPED {test}: {reason}");
        eprintln!("SKIPPED {test}: {reason}");
        return;
    }
    let elf = {
        let _one_at_a_time = LINK_CHECK.lock().unwrap_or_else(|e| e.into_inner());
        let path = build_link_check(bsp, target);
        std::fs::read(&path).unwrap_or_else(|e| panic!("reading {}: {e}", path.display()))
    };
    let sections = elf32_sections(&elf).unwrap_or_else(|e| panic!("{test}: {e}"));
    let vectors = sections
        .iter()
        .find(|s| s.name == ".vector_table")
        .unwrap_or_else(|| panic!("{test}: the ELF has no .vector_table section"));
    assert_eq!(
        vectors.addr, BSP_FLASH.start,
        "{test}: the vector table is at {:#010x}, not at the start of {bsp}-bsp's flash \
         ({:#010x}): another memory.x than {bsp}-bsp's reached the linker (unlag's own has \
         flash at 0x00000000), and this firmware would not boot",
        vectors.addr, BSP_FLASH.start
    );
    // Its first two words: the initial stack pointer and the reset vector.
    const SHT_PROGBITS: u32 = 1;
    let data = (vectors.kind == SHT_PROGBITS)
        .then(|| {
            elf.get(vectors.offset as usize..)?
                .get(..vectors.size as usize)
        })
        .flatten()
        .unwrap_or_else(|| panic!("{test}: .vector_table has no contents in the file"));
    let word = |k: usize| {
        let bytes = data.get(4 * k..4 * k + 4);
        u32::from_le_bytes(
            bytes
                .unwrap_or_else(|| panic!("{test}: .vector_table has no word {k}"))
                .try_into()
                .unwrap(),
        )
    };
    let (stack, reset) = (word(0), word(1));
    assert_eq!(
        stack, BSP_STACK_START,
        "{test}: the initial stack pointer is not the top of {bsp}-bsp's RAM"
    );
    assert!(
        reset & 1 == 1 && BSP_FLASH.contains(&(reset & !1)),
        "{test}: the reset vector {reset:#010x} is not a Thumb address in {bsp}-bsp's flash \
         {BSP_FLASH:#010x?}"
    );
    const SHF_EXECINSTR: u32 = 0x4;
    assert!(
        sections.iter().any(|s| s.flags & SHF_EXECINSTR != 0
            && (reset & !1).checked_sub(s.addr).is_some_and(|d| d < s.size)),
        "{test}: the reset vector {reset:#010x} points into no code section"
    );
}

/// Builds `host-tests/link-check/` for `target` with the feature `bsp` (release: no debug
/// information, the dependencies built once for both features) and returns its ELF.
fn build_link_check(bsp: &str, target: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("host-tests/link-check");
    let target_dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("link-check");
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    // From the crate's own directory, so that cargo reads its .cargo/config.toml (and the
    // repository's above it) as it would for someone building it there; flags from the
    // environment would replace those files' rustflags. `--locked`: the committed lock file,
    // never a rewrite of it in the source tree.
    let out = Command::new(cargo)
        .current_dir(&dir)
        .args(["build", "--release", "--locked", "--target", target])
        .args(["--features", bsp, "--target-dir"])
        .arg(&target_dir)
        .env_remove("RUSTFLAGS")
        .env_remove("CARGO_ENCODED_RUSTFLAGS")
        .env_remove("CARGO_BUILD_RUSTFLAGS")
        .output()
        .expect("cargo runs");
    assert!(
        out.status.success(),
        "building {} with --features {bsp} for {target} failed (if its Cargo.lock is out of \
         date with unlag's dependencies, run `cargo build --features {bsp}` there once and \
         commit the lock file):\n{}",
        dir.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    target_dir
        .join(target)
        .join("release")
        .join("unlag-link-check")
}

/// What the checks need of one section header of an ELF file.
struct Section {
    name: String,
    /// `sh_type`.
    kind: u32,
    flags: u32,
    addr: u32,
    offset: u32,
    size: u32,
}

/// The section headers of a little-endian 32-bit Arm ELF file (the layout of the System V ABI,
/// `Elf32_Ehdr` and `Elf32_Shdr`), with their names from the section-name string table. Every
/// read is bounds-checked: a short or malformed file is an error, never a panic.
fn elf32_sections(elf: &[u8]) -> Result<Vec<Section>, String> {
    let u16_at = |at: usize| -> Result<u32, String> {
        elf.get(at..at + 2)
            .map(|b| u32::from(u16::from_le_bytes([b[0], b[1]])))
            .ok_or(format!("ELF truncated at byte {at}"))
    };
    let u32_at = |at: usize| -> Result<u32, String> {
        elf.get(at..at + 4)
            .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .ok_or(format!("ELF truncated at byte {at}"))
    };
    // e_ident: magic, ELFCLASS32, ELFDATA2LSB; e_machine EM_ARM.
    if elf.get(..6) != Some(&[0x7f, b'E', b'L', b'F', 1, 1][..]) {
        return Err("not a little-endian 32-bit ELF file".into());
    }
    if u16_at(18)? != 40 {
        return Err(format!("e_machine {} is not EM_ARM (40)", u16_at(18)?));
    }
    let shoff = u32_at(32)? as usize;
    let shentsize = u16_at(46)? as usize;
    let shnum = u16_at(48)? as usize;
    let shstrndx = u16_at(50)? as usize;
    // 0 sections and SHN_XINDEX (0xffff) mean the real counts are elsewhere: not in a small
    // firmware.
    if shentsize != 40 || shnum == 0 || shstrndx >= shnum {
        return Err(format!(
            "unexpected section headers: e_shentsize {shentsize}, e_shnum {shnum}, \
             e_shstrndx {shstrndx}"
        ));
    }
    let header = |k: usize| -> Result<[u32; 6], String> {
        let at = shoff + k * shentsize;
        // sh_name, sh_type, sh_flags, sh_addr, sh_offset, sh_size
        Ok([
            u32_at(at)?,
            u32_at(at + 4)?,
            u32_at(at + 8)?,
            u32_at(at + 12)?,
            u32_at(at + 16)?,
            u32_at(at + 20)?,
        ])
    };
    let [_, _, _, _, strtab, strtab_size] = header(shstrndx)?;
    let strtab = elf
        .get(strtab as usize..(strtab as usize).saturating_add(strtab_size as usize))
        .ok_or("the section-name string table lies outside the file")?;
    (0..shnum)
        .map(|k| {
            let [name, kind, flags, addr, offset, size] = header(k)?;
            let name = strtab
                .get(name as usize..)
                .and_then(|rest| rest.split(|&b| b == 0).next())
                .ok_or(format!("section {k}'s name lies outside the string table"))?;
            Ok(Section {
                name: String::from_utf8_lossy(name).into_owned(),
                kind,
                flags,
                addr,
                offset,
                size,
            })
        })
        .collect()
}
