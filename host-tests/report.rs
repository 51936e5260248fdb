//! `unlag report` checked in a real browser: a report of a model that misses the shipped
//! probe's second mode is written and opened in headless Chromium. Every plot must be present
//! with data drawn in it, the page must load without a console error, a screenshot must be
//! taken, and the page's text must carry the diagnosed effect and the error numbers that
//! `unlag diagnose --json` and `unlag compare --json` report, and each compensated signal's
//! errors as `unlag compensate --json` reports them.
//!
//! Chromium (Debian package `chromium`) is required in CI (`CI=true`, or
//! `UNLAG_REQUIRE_CHROMIUM=1` as `.ci/run` sets): the test fails there without it. Elsewhere it
//! prints a notice and skips the browser part.

// Test code: a failed unwrap is a failed test, with its location.
#![allow(clippy::unwrap_used)]

mod common;
use common::unlag;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use serde_json::Value;

fn ok(args: &[&str]) -> String {
    let o = unlag(args);
    let (out, err) = (
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    );
    assert!(o.status.success(), "unlag {args:?} failed:\n{out}\n{err}");
    out
}

fn example(name: &str) -> String {
    format!("{}/examples/data/{name}", env!("CARGO_MANIFEST_DIR"))
}

fn tmp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("unlag-report-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

/// Whether a missing browser fails the test: in CI (`CI` set and not `false`) and under
/// `.ci/run` (`UNLAG_REQUIRE_CHROMIUM=1`).
fn required() -> bool {
    std::env::var("CI").is_ok_and(|v| !v.is_empty() && v != "false" && v != "0")
        || std::env::var("UNLAG_REQUIRE_CHROMIUM").is_ok_and(|v| v == "1")
}

/// The browser, or `None` (after a notice) where a missing browser may skip the test.
fn chromium() -> Option<String> {
    let found = ["chromium", "chromium-browser", "google-chrome"]
        .into_iter()
        .find(|c| {
            Command::new(c)
                .arg("--version")
                .output()
                .is_ok_and(|o| o.status.success())
        });
    match found {
        Some(c) => Some(c.to_string()),
        None if required() => panic!(
            "headless Chromium is required in CI to check the HTML report and was not found: \
             apt-get install -y chromium (.ci/run installs it)"
        ),
        None => {
            eprintln!(
                "NOTICE: chromium not found: the report was written but not checked in a \
                 browser (apt-get install -y chromium to run this part)"
            );
            None
        }
    }
}

/// Runs headless Chromium with a private profile, at most two minutes.
fn browse(browser: &str, profile: &Path, args: &[&str], page: &Path) -> Output {
    let url = format!("file://{}", page.display());
    Command::new("timeout")
        .arg("120")
        .arg(browser)
        .args([
            "--headless",
            "--disable-gpu",
            "--no-sandbox",
            "--hide-scrollbars",
            "--no-first-run",
            "--enable-logging=stderr",
            "--v=0",
        ])
        .arg(format!("--user-data-dir={}", profile.display()))
        .args(args)
        .arg(url)
        .output()
        .expect("run chromium")
}

/// The data colours of the report's plots (the axes, grids and guides are black and grey).
const PALETTE: [&str; 5] = ["#0072B2", "#E69F00", "#D55E00", "#009E73", "#CC79A7"];

fn attribute<'a>(element: &'a str, name: &str) -> Option<&'a str> {
    let key = format!(" {name}=\"");
    let start = element.find(&key)? + key.len();
    let len = element[start..].find('"')?;
    Some(&element[start..start + len])
}

/// What a figure draws: `(polylines of 3 or more points, marks in the data colours)`. Axes,
/// ticks, guides and legend samples are 2-point lines and grid lines are grey, so a chart with
/// nothing but its frame and legend scores `(0, one mark per legend entry)`.
fn data_marks(figure: &str) -> (usize, usize) {
    let (mut lines, mut marks) = (0, 0);
    for tag in ["<polyline", "<circle", "<line", "<path", "<rect"] {
        for (i, _) in figure.match_indices(tag) {
            let end = figure[i..].find('>').map_or(figure.len(), |e| i + e);
            let element = &figure[i..end];
            let stroke = attribute(element, "stroke")
                .or_else(|| attribute(element, "fill"))
                .unwrap_or("")
                .to_ascii_uppercase();
            let points = attribute(element, "points").map_or(0, |p| p.split_whitespace().count());
            if tag == "<polyline" && points >= 3 {
                lines += 1;
            } else if PALETTE.contains(&stroke.as_str()) {
                marks += 1;
            }
        }
    }
    (lines, marks)
}

/// The page's text: tags removed, entities decoded, white space collapsed.
fn text_of(html: &str) -> String {
    let mut out = String::new();
    let mut in_tag = false;
    for c in html.chars() {
        match c {
            '<' => {
                in_tag = true;
                out.push(' ');
            }
            '>' => in_tag = false,
            _ if !in_tag => out.push(c),
            _ => {}
        }
    }
    let out = out
        .replace("&nbsp;", " ")
        .replace("&lt;", "<")
        .replace("&gt;", ">")
        .replace("&quot;", "\"")
        .replace("&#39;", "'")
        .replace("&amp;", "&");
    out.split_whitespace().collect::<Vec<_>>().join(" ")
}

fn pct(x: f64) -> String {
    format!("{:.3} %", 100.0 * x)
}

#[test]
fn report_of_a_model_missing_a_mode_opens_in_chromium() {
    let (t1, t2) = (example("step_test_1.csv"), example("step_test_2.csv"));
    let model = tmp("probe.toml");
    let model = model.to_str().unwrap();
    let fit_report = tmp("fit-report.html");
    // Order 2 misses the shipped probe's second line mode: the hidden effect.
    ok(&[
        "fit",
        &t1,
        &t2,
        "--order",
        "2",
        "--fresh",
        "-o",
        model,
        "--report",
        fit_report.to_str().unwrap(),
    ]);
    assert!(
        std::fs::read_to_string(&fit_report)
            .unwrap()
            .contains("id=\"bode\""),
        "`unlag fit --report` wrote no report"
    );
    let report = tmp("report.html");
    let json: Value = serde_json::from_str(&ok(&[
        "report",
        model,
        &t1,
        &t2,
        "-o",
        report.to_str().unwrap(),
        "--json",
    ]))
    .unwrap();
    let html = std::fs::read_to_string(&report).unwrap();
    assert_eq!(json["bytes"].as_u64(), Some(html.len() as u64));
    // Self-contained: nothing to fetch, nothing to run.
    for banned in ["<script", "<link", "<img", "@import", "url(", "https://"] {
        assert!(!html.contains(banned), "the report contains {banned}");
    }
    assert!(html.len() < 2_000_000, "{} bytes", html.len());
    // The modes table carries the fit's stated deviations, and says where the noise was read.
    let file: toml::Value = std::fs::read_to_string(model).unwrap().parse().unwrap();
    let stated = &file["fit"]["uncertainty"]["resonances"][0];
    let (f, sf) = (
        stated["natural_frequency_hz"].as_float().unwrap(),
        stated["natural_frequency_std_hz"].as_float().unwrap(),
    );
    let cell = "resonance (pole pair)</td><td class=\"num\">";
    let row = &html[html.find(cell).expect("no resonance in the modes table") + cell.len()..];
    let shown: Vec<f64> = row[..row.find(" Hz").unwrap()]
        .split(" &plusmn; ")
        .map(|x| x.parse().unwrap())
        .collect();
    assert!(
        shown.len() == 2 && (shown[0] - f).abs() <= sf && (shown[1] / sf - 1.0).abs() < 0.05,
        "the modes table shows {shown:?} for {f} +/- {sf} Hz"
    );
    assert!(
        html.contains("one standard deviation as the fit states it, from both channels' noise"),
        "no note of where the noise was read"
    );

    let compare: Value =
        serde_json::from_str(&ok(&["compare", model, &t1, &t2, "--json"])).unwrap();
    let diagnose: Value =
        serde_json::from_str(&ok(&["diagnose", model, &t1, &t2, "--json"])).unwrap();
    let top = &diagnose["candidates"][0];
    let effect = top["kind"].as_str().unwrap();
    assert_ne!(effect, "none", "the missing mode went undiagnosed: {top}");

    // The compensated signal of each test is what `unlag compensate` gives on it: its errors
    // and alignment in the figure's caption and the summary table.
    for (i, t) in [&t1, &t2].into_iter().enumerate() {
        let out = tmp(&format!("compensated-{}.csv", i + 1));
        let c: Value = serde_json::from_str(&ok(&[
            "compensate",
            model,
            t,
            "-o",
            out.to_str().unwrap(),
            "--json",
        ]))
        .unwrap();
        let id = format!("id=\"compensated-{}\"", i + 1);
        let figure = &html[html.find(&id).expect("no compensated figure")..];
        let caption =
            &figure[figure.find("<figcaption>").unwrap()..figure.find("</figure>").unwrap()];
        let (u_hat, raw) = (
            pct(c["nrmse_u_hat"].as_f64().unwrap()),
            pct(c["nrmse_raw"].as_f64().unwrap()),
        );
        assert!(
            caption.contains(&format!(
                "Error against the reference {u_hat} (raw probe at its best alignment: {raw})"
            )),
            "`unlag compensate` says {c}; the report: {caption}"
        );
        let lag = c["alignment_samples"].as_u64().unwrap();
        assert!(
            caption.contains(&format!("advanced by {lag} samples")),
            "{caption}"
        );
        assert!(
            caption.contains(c["compensator"].as_str().unwrap()),
            "{c}: {caption}"
        );
        assert!(html.contains(&format!("{u_hat} / {raw}")), "summary table");
    }

    let Some(browser) = chromium() else { return };
    let profile = tmp("chromium-profile");
    let dom = browse(&browser, &profile, &["--dump-dom"], &report);
    let (stdout, stderr) = (
        String::from_utf8_lossy(&dom.stdout).into_owned(),
        String::from_utf8_lossy(&dom.stderr).into_owned(),
    );
    assert!(dom.status.success(), "chromium failed: {stderr}");
    for bad in ["Uncaught", "ERROR:CONSOLE", "Failed to load resource"] {
        assert!(
            !stderr.contains(bad),
            "console error in the report: {stderr}"
        );
    }
    assert!(stdout.contains("</html>"), "no DOM dumped: {stderr}");

    // Every plot is present and has data drawn in it.
    let ids = unlag::report::plot_ids(2, true);
    assert_eq!(
        stdout.matches("<figure class=\"plot\"").count(),
        ids.len(),
        "plots in the page"
    );
    assert!(stdout.matches("<svg").count() >= ids.len());
    for id in &ids {
        let open = format!("<figure class=\"plot\" id=\"{id}\">");
        let start = stdout
            .find(&open)
            .unwrap_or_else(|| panic!("plot {id} missing"));
        let end = start + stdout[start..].find("</figure>").unwrap();
        let figure = &stdout[start..end];
        assert!(figure.contains("<svg"), "plot {id} has no SVG");
        let (lines, marks) = data_marks(figure);
        assert!(
            lines >= 1 || marks >= 6,
            "plot {id} draws no data: {lines} data lines, {marks} marks"
        );
    }

    // The page says what the diagnosis says, and the errors that compare reports.
    let text = text_of(&stdout);
    assert!(
        text.contains(&format!("Diagnosis: {effect}")),
        "diagnosed effect {effect} not in the verdict"
    );
    let reading = top["reading"].as_str().unwrap();
    assert!(
        text.contains(reading),
        "the reading is not on the page: {reading}"
    );
    for t in compare["tests"].as_array().unwrap() {
        for key in ["nrmse", "noise_floor"] {
            let number = pct(t[key].as_f64().unwrap());
            assert!(
                text.contains(&number),
                "{key} {number} of {} not on the page",
                t["file"]
            );
        }
    }
    // The peaks of the residual spectrum are labelled with the diagnosed effect.
    let spectrum = &stdout[stdout.find("id=\"spectrum-1\"").unwrap()..];
    let spectrum = &spectrum[..spectrum.find("</figure>").unwrap()];
    assert!(
        spectrum.contains(&format!("Hz: {effect}")),
        "no spectral peak labelled {effect}"
    );

    // A screenshot, and not a blank one (a white page compresses to a few kB).
    let shot = tmp("report.png");
    let _ = std::fs::remove_file(&shot);
    let o = browse(
        &browser,
        &profile,
        &[
            &format!("--screenshot={}", shot.display()),
            "--window-size=1200,4000",
        ],
        &report,
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let png = std::fs::read(&shot).expect("no screenshot written");
    assert!(png.starts_with(b"\x89PNG\r\n\x1a\n"), "not a PNG");
    assert!(
        png.len() > 50_000,
        "screenshot of {} bytes: blank?",
        png.len()
    );
}

#[test]
fn bad_input_writes_no_report() {
    let model = tmp("bad-probe.toml");
    let model = model.to_str().unwrap();
    let t1 = example("step_test_1.csv");
    ok(&["fit", &t1, "--order", "2", "--fresh", "-o", model]);
    for (args, expect) in [
        (vec!["report", model, "no-such.csv"], "no-such.csv"),
        (vec!["report", "no-such.toml", t1.as_str()], "no-such.toml"),
    ] {
        let out = tmp("bad.html");
        let mut args = args;
        let out_s = out.to_str().unwrap().to_string();
        args.extend(["-o", out_s.as_str()]);
        let o = unlag(&args);
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{stderr}");
        assert_eq!(stderr.lines().count(), 1, "one line expected: {stderr}");
        assert!(
            stderr.starts_with("error: ") && stderr.contains(expect),
            "{stderr}"
        );
        assert!(!stderr.contains("panicked"));
        assert!(!out.exists(), "a report was written from bad input");
    }
    // An output directory that does not exist: a clear error, nothing left behind.
    let out = tmp("no-such-dir").join("r.html");
    let o = unlag(&["report", model, &t1, "-o", out.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("cannot write"), "{stderr}");
    assert!(!out.exists());
}

/// The "data drawn" check can fail: a chart with its axes, guides and legend but no data
/// does not pass it, and the same chart with data does.
#[test]
fn an_empty_chart_fails_the_data_check() {
    use unlag::report::plot::{colour, figure, Panel, Series, Style};
    let empty = Panel::new(
        "nothing",
        "time (s)",
        "pressure",
        vec![
            Series::with("probe", Vec::new(), colour::PROBE, Style::Line(2)),
            Series::with("stems", Vec::new(), colour::RESIDUAL, Style::Stems),
        ],
    )
    .guides(vec![(0.5, "band".into()), (-0.5, String::new())]);
    let svg = figure("empty", &[empty.clone(), empty], 300, 2).unwrap();
    let (lines, marks) = data_marks(&svg);
    assert!(
        lines == 0 && marks < 6,
        "an empty chart passed: {lines}, {marks}"
    );
    let trace: Vec<(f64, f64)> = (0..50).map(|k| (f64::from(k), f64::from(k % 7))).collect();
    let full = Panel::new(
        "data",
        "time (s)",
        "pressure",
        vec![Series::line("probe", &trace, colour::PROBE, 2)],
    );
    let (lines, _) = data_marks(&figure("full", &[full], 300, 1).unwrap());
    assert!(lines >= 1);
    let stems: Vec<(f64, f64)> = (1..=30).map(|k| (f64::from(k), 0.1)).collect();
    let acf = Panel::new(
        "stems",
        "lag",
        "rho",
        vec![Series::with("rho", stems, colour::PROBE, Style::Stems)],
    );
    let (_, marks) = data_marks(&figure("stems", &[acf], 300, 1).unwrap());
    assert!(marks >= 6, "{marks}");
}
