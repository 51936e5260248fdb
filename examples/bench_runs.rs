//! The board's output on runs unlike the step test: a bank of drawn probes, each fitted from
//! ONE step test with `unlag fit`'s default options, then its stored compensator run by
//! `unlag compensate` on runs of other kinds, as the board runs it (f32 and 32-bit fixed
//! point) and as the host can (f64, the offline optimum, a design chosen for the run); and,
//! per run kind, the board's compensator fitted on the same step test with `--signal` a
//! rehearsal (another run of that kind, drawn anew with its own parameters, the probe alone),
//! in f32 and fixed point. Every output is scored against the run's true pressure.
//!
//! The files beside it in `bench_runs/`: `probe.rs` (the probes and their drawing),
//! `runs.rs` (the step test and the runs: pressures, simulation, channels), `execute.rs`
//! (one probe through the binary), `score.rs` (the aligned RMS error, unit-tested) and
//! `report.rs` (the tables and `results.csv`). From bench_bank it takes `case.rs`
//! (geometries), `draw.rs` (the seeded generator), `simulate.rs` (the lumped state
//! equations, CSV writing) and `runner.rs` (running the binary). This file owns the flags
//! and runs the probes on its threads.
//!
//! ```sh
//! cargo build --release --bin unlag
//! cargo run --release --example bench_runs   # --seed N --probes N --threads 1|2 --unlag PATH --out DIR --keep
//! ```
//!
//! * Probes, families dealt round-robin, all else drawn over ranges: overdamped capillaries,
//!   pneumatic lines, two lines in series, flush holes into cavities at 1-2 MHz, cavities
//!   whose gas relaxes thermally (a slow creep), leaks; each a lumped model (RK4 on its state
//!   equations) or a Bergh-Tijdeman line (thermal creep: always), simulated with the pressure
//!   resolved 4 to 16 times finer than a sample and from before the record.
//! * Per probe, one step test and four runs: turbulence (a mean plus Gaussian fluctuations of
//!   von Karman's spectrum, corner and band limit drawn around the probe's band), a cascade
//!   wake traverse, a shock tube's incident and reflected shocks (2 to 2.6 times the
//!   incident, a few of the probe's time constants apart) and a step of another size and
//!   sign (up to twice the calibration step). White noise of 0.1-0.5 % of the step on both
//!   channels and a 16-bit ADC over each record's extremes plus a drawn margin.
//! * Scores: RMS error after the first tenth of the run at the best whole-sample lag, the
//!   output's within a window around its stated latency, the raw probe's from 0 to four
//!   times its lag; the ratio raw / output. The same against the recorded reference beside.
//! * `target/bench_runs/results.csv` has one row per run; `probe-NNN/` each probe's records
//!   (`RUN.csv`, and `RUN-truth.csv`: `u` the true pressure, `y` the noise-free probe), the
//!   model and every command's log.

#[allow(dead_code)]
#[path = "bench_bank/case.rs"]
mod case;
#[allow(dead_code)]
#[path = "bench_bank/draw.rs"]
mod draw;
#[path = "bench_runs/execute.rs"]
mod execute;
#[path = "bench_runs/probe.rs"]
mod probe;
#[path = "bench_runs/report.rs"]
mod report;
#[allow(dead_code)]
#[path = "bench_bank/runner.rs"]
mod runner;
#[path = "bench_runs/runs.rs"]
mod runs;
#[path = "bench_runs/score.rs"]
mod score;
#[allow(dead_code)]
#[path = "bench_bank/simulate.rs"]
mod simulate;

use std::error::Error;
use std::path::PathBuf;
use std::process::Command;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::Instant;

use execute::{run_probe, Column, ProbeResult};

/// Command-line settings (`unlag` and `out` are what bench_bank's runner reads).
pub struct Settings {
    seed: u64,
    probes: usize,
    threads: usize,
    unlag: PathBuf,
    out: PathBuf,
    /// Keep every compensator output CSV (they are removed once scored).
    keep: bool,
    /// The binary knows `compensate --adapt-to-run`.
    adapt: bool,
}

/// The usage line.
const USAGE: &str = "cargo run --release --example bench_runs -- [--seed N] [--probes N] \
[--threads 1|2] [--unlag PATH] [--out DIR] [--keep]";

fn settings() -> Result<Settings, Box<dyn Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.iter().any(|a| a == "-h" || a == "--help") {
        println!("{USAGE}");
        std::process::exit(0);
    }
    let keep = args.iter().any(|a| a == "--keep");
    // Every other flag takes a value: `--flag value` pairs.
    let pairs: Vec<&String> = args.iter().filter(|a| *a != "--keep").collect();
    if pairs.len() % 2 == 1 {
        return Err(format!("{} needs a value ({USAGE})", pairs[pairs.len() - 1]).into());
    }
    let (mut seed, mut probes, mut threads) = (1001, 24, 2);
    let mut out = PathBuf::from("target/bench_runs");
    // By default the release binary of this checkout (or of CARGO_TARGET_DIR).
    let mut unlag = std::env::var_os("CARGO_TARGET_DIR")
        .map_or_else(|| PathBuf::from("target"), PathBuf::from)
        .join("release/unlag");
    for pair in pairs.chunks(2) {
        let (flag, value) = (pair[0].as_str(), pair[1].as_str());
        match flag {
            "--seed" => seed = value.parse()?,
            "--probes" => probes = value.parse()?,
            "--threads" => threads = value.parse::<usize>()?.clamp(1, 2),
            "--unlag" => unlag = PathBuf::from(value),
            "--out" => out = PathBuf::from(value),
            _ => return Err(format!("unknown argument {flag} ({USAGE})").into()),
        }
    }
    // The commands run inside each probe's folder: the binary's path must not be relative.
    let unlag = unlag.canonicalize().map_err(|e| {
        format!(
            "no unlag binary at {} ({e}): `cargo build --release --bin unlag`, or --unlag PATH",
            unlag.display()
        )
    })?;
    // The host's run-adapted design is a recent flag: asked of the binary's help.
    let help = Command::new(&unlag)
        .args(["compensate", "--help"])
        .output()?;
    let adapt = String::from_utf8_lossy(&help.stdout).contains("--adapt-to-run");
    Ok(Settings {
        seed,
        probes,
        threads,
        unlag,
        out,
        keep,
        adapt,
    })
}

fn main() -> Result<(), Box<dyn Error>> {
    let s = settings()?;
    std::fs::create_dir_all(&s.out)
        .map_err(|e| format!("cannot create {}: {e}", s.out.display()))?;
    let command: Vec<String> = std::env::args().collect();
    let header = format!(
        "## bench_runs, seed {}\n\n`{}` (seed {}, {} probes, {} threads, binary {})\n",
        s.seed,
        command.join(" "),
        s.seed,
        s.probes,
        s.threads,
        s.unlag.display()
    );
    print!("{header}");
    if !s.adapt {
        println!("\nThe binary has no `compensate --adapt-to-run`: that host column is skipped.");
    }
    let probes = probe::draw(s.seed, s.probes);
    let start = Instant::now();
    let next = AtomicUsize::new(0);
    let done = AtomicUsize::new(0);
    let results: Mutex<Vec<ProbeResult>> = Mutex::new(Vec::with_capacity(probes.len()));
    std::thread::scope(|scope| {
        for _ in 0..s.threads {
            scope.spawn(|| loop {
                let i = next.fetch_add(1, Ordering::SeqCst);
                let Some(p) = probes.get(i) else { break };
                let r = run_probe(p, &s);
                let k = done.fetch_add(1, Ordering::SeqCst) + 1;
                let what = match &r.failure {
                    Some(e) => format!("FAILED {e}"),
                    None => r
                        .runs
                        .iter()
                        .map(|x| {
                            let ratio = |c| {
                                x.output(c)
                                    .map_or("-".into(), |o| format!("{:.2}", x.raw.0 / o.error))
                            };
                            format!(
                                "{} {}/{}",
                                x.kind.name(),
                                ratio(Column::BoardF32),
                                ratio(Column::BoardFixed)
                            )
                        })
                        .collect::<Vec<_>>()
                        .join(", "),
                };
                eprintln!(
                    "[{k:2}/{}] probe-{:03} {} {}: {what} ({:.1} s)",
                    probes.len(),
                    p.id,
                    p.family.name(),
                    p.generator(),
                    r.seconds
                );
                if let Ok(mut all) = results.lock() {
                    all.push(r);
                }
            });
        }
    });
    let mut results = results.into_inner().map_err(|_| "poisoned lock")?;
    results.sort_by_key(|r| r.probe.id);
    let path = s.out.join("results.csv");
    report::write_csv(&path, &results)?;
    let text = report::report(&results, s.adapt, start.elapsed().as_secs_f64());
    print!("{text}");
    println!(
        "\nWrote {} and the probes' records in {}.",
        path.display(),
        s.out.display()
    );
    Ok(())
}
