//! A bank of drawn step tests, run through the `unlag` binary as a new user would: a bank
//! that is not the generator's echo.
//!
//! This example owns the bank: it draws at least 120 cases from a seed (three probe families,
//! every hidden-effect kind and none, two generators), writes each case's estimation and
//! validation tests and its true model into `target/bank/case-NNN/`, runs `unlag fit`,
//! `unlag compensate`, and the oracle (`unlag invert` on the true model, then
//! `unlag compensate`), and prints per family and per kind how much better than the raw probe
//! the compensated signal is, and how close to the oracle. `target/bank/results.csv` has one
//! row per case with every drawn parameter and every error.
//!
//! The files beside it in `bench_bank/`: `case.rs` (what a case is), `draw.rs` (drawing the
//! cases), `simulate.rs` (their tests and true models), `runner.rs` (one case through the
//! binary), `report.rs` (the summary and `results.csv`) and `modelling_loop.rs` (`--loop`).
//! This file owns the flags and runs the cases on its threads.
//!
//! ```sh
//! cargo build --release --bin unlag
//! cargo run --release --example bench_bank                 # --seed N --cases N --unlag PATH
//! ```
//!
//! * Families: (a) pneumatic lines at 5-10 kHz, 20-150 Hz, damping 0.1-1.5; (b) flush or
//!   recessed sensors (hole and cavity) at 1 MHz, 30-120 kHz; (c) overdamped capillaries.
//! * Generators: a lumped second-order line with the effect's stages, simulated by RK4 with
//!   the input held between samples, whose true model is the exact zero-order-hold
//!   discretisation (matrix exponential; nonlinear damping: its linear part; a diaphragm on
//!   both channels cancels from reference to probe); or the physics module's Bergh-Tijdeman
//!   lines and cavities, whose "true" model is what `unlag fit` finds on a long noise-free
//!   estimation test (written by the CLI).
//! * Both channels carry white noise (0.1-0.5 % of the step) and a 16-bit ADC over 2.5 steps
//!   (wider only where a ringing probe or a drift would clip, as an experimenter would set it).
//!   The estimation test is a step; the validation test another step, a balloon, a valve or a
//!   wake traverse with a tunnel oscillation.
//! * A command that fails is a row with its first stderr line, counted, never dropped.

#[path = "bench_bank/case.rs"]
mod case;
#[path = "bench_bank/coverage.rs"]
mod coverage;
#[path = "bench_bank/draw.rs"]
mod draw;
#[path = "bench_bank/loop_report.rs"]
mod loop_report;
#[path = "bench_bank/modelling_loop.rs"]
mod modelling_loop;
#[path = "bench_bank/report.rs"]
mod report;
#[path = "bench_bank/runner.rs"]
mod runner;
#[path = "bench_bank/simulate.rs"]
mod simulate;

use std::error::Error;
use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::Instant;

use case::{Case, Effect, Kind};
use runner::{make_files, run_case, Outcome};

/// Command-line settings.
struct Settings {
    seed: u64,
    cases: usize,
    threads: usize,
    unlag: PathBuf,
    out: PathBuf,
    /// The modelling loop instead of the reconstruction.
    modelling_loop: bool,
}

fn settings() -> Result<Settings, Box<dyn Error>> {
    let mut seed = 13;
    let mut cases = 126;
    let mut threads = 2;
    let mut unlag = None;
    let mut out = PathBuf::from("target/bank");
    let mut modelling_loop = false;
    let mut args = std::env::args().skip(1);
    while let Some(flag) = args.next() {
        let mut value = || args.next().ok_or_else(|| format!("{flag} needs a value"));
        match flag.as_str() {
            "--seed" => seed = value()?.parse()?,
            "--cases" => cases = value()?.parse()?,
            "--threads" => threads = value()?.parse::<usize>()?.clamp(1, 2),
            "--unlag" => unlag = Some(PathBuf::from(value()?)),
            "--out" => out = PathBuf::from(value()?),
            "--loop" => modelling_loop = true,
            "-h" | "--help" => {
                println!("cargo run --release --example bench_bank -- [--seed N] [--cases N] [--threads 1|2] [--unlag PATH] [--out DIR] [--loop]");
                std::process::exit(0);
            }
            other => return Err(format!("unknown argument {other} (try --help)").into()),
        }
    }
    let unlag = match unlag {
        Some(p) => p,
        None => {
            let target = std::env::var_os("CARGO_TARGET_DIR")
                .map_or_else(|| PathBuf::from("target"), PathBuf::from);
            target.join("release").join("unlag")
        }
    };
    if !unlag.is_file() {
        return Err(format!(
            "no unlag binary at {}: run `cargo build --release --bin unlag` or pass --unlag PATH",
            unlag.display()
        )
        .into());
    }
    // The commands run inside each case's folder: the binary's path must not be relative.
    let unlag = unlag.canonicalize()?;
    Ok(Settings {
        seed,
        cases,
        threads,
        unlag,
        out,
        modelling_loop,
    })
}

fn main() -> Result<(), Box<dyn Error>> {
    let s = settings()?;
    std::fs::create_dir_all(&s.out)
        .map_err(|e| format!("cannot create {}: {e}", s.out.display()))?;
    let cases = draw::draw(s.seed, s.cases);
    if s.modelling_loop {
        return run_loop(&cases, &s);
    }
    let start = Instant::now();
    let next = AtomicUsize::new(0);
    let done = AtomicUsize::new(0);
    let results: Mutex<Vec<(Case, Outcome)>> = Mutex::new(Vec::with_capacity(cases.len()));
    std::thread::scope(|scope| {
        for _ in 0..s.threads {
            scope.spawn(|| loop {
                let i = next.fetch_add(1, Ordering::SeqCst);
                let Some(case) = cases.get(i) else { break };
                let o = run_case(case, &s);
                let k = done.fetch_add(1, Ordering::SeqCst) + 1;
                let what = match (&o.failure, o.raw.zip(o.comp)) {
                    (Some(e), _) => format!("FAILED {e}"),
                    (None, Some((r, e))) => format!(
                        "raw/comp {:.2}{}",
                        r / e,
                        o.oracle
                            .map_or(String::new(), |q| format!(", comp/oracle {:.2}", e / q))
                    ),
                    _ => "no errors".into(),
                };
                eprintln!(
                    "[{k:3}/{}] case-{:03} {} {} {}: {what} ({:.1} s)",
                    cases.len(),
                    case.id,
                    case.family.name(),
                    case.generator_name(),
                    case.kind.name(),
                    o.seconds
                );
                if let Ok(mut r) = results.lock() {
                    r.push((case.clone(), o));
                }
            });
        }
    });
    let mut rows = results.into_inner().map_err(|_| "poisoned lock")?;
    rows.sort_by_key(|(c, _)| c.id);
    let path = s.out.join("results.csv");
    report::write_results(&path, &rows)?;
    print!(
        "{}",
        report::report(&rows, &s, start.elapsed().as_secs_f64())
    );
    println!(
        "\nWrote {} and the cases in {}.",
        path.display(),
        s.out.display()
    );
    Ok(())
}

/// `--loop`: the modelling loop on every case, two at a time.
fn run_loop(cases: &[Case], s: &Settings) -> Result<(), Box<dyn Error>> {
    let start = Instant::now();
    let next = AtomicUsize::new(0);
    let rows: Mutex<Vec<(Case, modelling_loop::LoopOutcome)>> = Mutex::new(Vec::new());
    std::thread::scope(|scope| {
        for _ in 0..s.threads {
            scope.spawn(|| loop {
                let i = next.fetch_add(1, Ordering::SeqCst);
                let Some(case) = cases.get(i) else { break };
                let dir = s.out.join(format!("case-{:03}", case.id));
                let mut ignored = Outcome::default();
                // The same probe without the hidden effect, on the same noise (`bare/`): the
                // oracle for what its own dynamics show beyond the second-order start.
                let bare = Case {
                    kind: Kind::None,
                    effect: Effect::None,
                    ..case.clone()
                };
                let made = make_files(case, &dir, &s.unlag, &mut ignored).and_then(|_| {
                    make_files(&bare, &dir.join("bare"), &s.unlag, &mut Outcome::default())
                });
                let o = match made {
                    Ok(_) => modelling_loop::run(&s.unlag, &dir, case),
                    Err(e) => modelling_loop::LoopOutcome {
                        failure: Some(format!("simulation: {e}")),
                        ..Default::default()
                    },
                };
                eprintln!(
                    "case-{:03} {} {}: named {} ({})",
                    case.id,
                    case.family.name(),
                    case.kind.name(),
                    o.named.join(", "),
                    if o.right_or_carried(case.kind) {
                        "right"
                    } else {
                        "wrong"
                    }
                );
                if let Ok(mut r) = rows.lock() {
                    r.push((case.clone(), o));
                }
            });
        }
    });
    let mut rows = rows.into_inner().map_err(|_| "poisoned lock")?;
    rows.sort_by_key(|(c, _)| c.id);
    print!("{}", loop_report::report(&rows));
    print!("{}", coverage::report(&rows));
    println!(
        "\n{} cases in {:.0} s on {} threads, seed {}, {}.",
        rows.len(),
        start.elapsed().as_secs_f64(),
        s.threads,
        s.seed,
        s.unlag.display()
    );
    Ok(())
}
