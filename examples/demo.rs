//! The README's first command: the whole job on the shipped example data.
//!
//! ```sh
//! cargo run --release --example demo
//! ```
//!
//! It runs exactly what a user would type, through the same code as the `unlag` binary:
//!
//! 1. `unlag fit examples/data/step_test_1.csv examples/data/step_test_2.csv --fresh -o target/demo/model.toml --report target/demo/report.html`
//!    (fit on the first test, validate on the second, print the model and its errors, and write
//!    the HTML report: traces, residuals, spectra, Bode and pole-zero plots, the diagnosis);
//! 2. `unlag compensate target/demo/model.toml examples/data/step_test_2.csv -o target/demo/compensated.csv`
//!    (reconstruct the reference of the second test with the board's f32 compensator).

use std::process::ExitCode;

use clap::Parser;
use unlag::cli::{run, Cli};

fn main() -> ExitCode {
    // Paths relative to the repository, as a user would type them (and as the model file
    // records them).
    let root = env!("CARGO_MANIFEST_DIR");
    if let Err(e) =
        std::env::set_current_dir(root).and_then(|()| std::fs::create_dir_all("target/demo"))
    {
        eprintln!("error: {root}/target/demo: {e}");
        return ExitCode::FAILURE;
    }
    let (t1, t2) = (
        "examples/data/step_test_1.csv",
        "examples/data/step_test_2.csv",
    );
    let (model, compensated, report) = (
        "target/demo/model.toml",
        "target/demo/compensated.csv",
        "target/demo/report.html",
    );
    let steps: [Vec<&str>; 2] = [
        // --fresh: a rerun starts over instead of extending the model file's history.
        vec![
            "unlag", "fit", t1, t2, "--fresh", "-o", model, "--report", report,
        ],
        vec!["unlag", "compensate", model, t2, "-o", compensated],
    ];
    for argv in steps {
        println!("\n$ {}", argv.join(" "));
        if let Err(e) = run(Cli::parse_from(argv)) {
            eprintln!("error: {e}");
            return ExitCode::FAILURE;
        }
    }
    if let Err(e) = unlag::cli::console::finish() {
        eprintln!("error: cannot write to standard output: {e}");
        return ExitCode::FAILURE;
    }
    println!("\nthe report: open {root}/{report} in a browser");
    ExitCode::SUCCESS
}
