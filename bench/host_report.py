#!/usr/bin/env python3
"""Writes the host-benchmark section of BENCHMARKS.md from the outputs of the Rust example
(`bench_host`) and of `bench/host_baseline.py`, both `RESULT name value unit` lines.

    python bench/host_report.py --rust R.txt --python P.txt --md BENCHMARKS.md \
        --command "bash bench/run-host.sh" [--info "key: value"]...

Only the text between `<!-- host-bench:start -->` and `<!-- host-bench:end -->` is replaced;
the file is created with a short introduction if it does not exist, and the section is
appended if the markers are missing. Standard library only.
"""

import argparse
import os
import re
import sys
import tempfile
from pathlib import Path

START = "<!-- host-bench:start -->"
END = "<!-- host-bench:end -->"

INTRO = """# Benchmarks

Figures measured on the development machine, not tests: nothing here passes or fails CI.
Each section is produced by one script, in one run, and says which command that is;
the script replaces only its own section (between its HTML comment markers), so the
figures in a section always come from the same run on the same machine.

"""


def parse(path):
    """`RESULT name value unit` lines as {name: (value, unit)}, and the other lines."""
    results, other = {}, []
    for line in Path(path).read_text().splitlines():
        parts = line.split()
        if len(parts) == 4 and parts[0] == "RESULT":
            results[parts[1]] = (float(parts[2]), parts[3])
        elif line.strip():
            other.append(line)
    return results, other


def fmt_time(s):
    if s >= 1.0:
        return f"{s:.2f} s"
    return f"{s * 1e3:.1f} ms"


def fmt_rate(r):
    return f"{r / 1e6:.0f} M samples/s"


def cell(results, name, kind):
    """`best (median m)` for a figure, or None when it is missing."""
    best = results.get(f"{name}_best")
    median = results.get(f"{name}_median")
    reps = results.get(f"{name}_reps")
    if best is None or median is None:
        return None
    f = fmt_time if kind == "time" else fmt_rate
    n = f", {int(reps[0])} runs" if reps else ""
    return f"{f(best[0])} (median {f(median[0])}{n})"


def ratio(rust, py, ours, theirs, kind):
    a = rust.get(f"{ours}_best")
    b = py.get(f"{theirs}_best")
    if a is None or b is None:
        return "—"
    return f"{a[0] / b[0]:.2f}"


def section(rust, rust_other, py, py_other, command, info):
    n = int(rust["n"][0])
    fit_n = int(rust.get("fit_oe_n", (n, ""))[0])
    shape = f"{int(rust['arx_rows'][0]):,} x {int(rust['arx_cols'][0])}" if "arx_rows" in rust else "?"
    rows = [
        # (figure, unlag name, baseline text, baseline name, kind)
        (
            f"ARX regression matrix build ({shape})",
            "arx_build",
            "numpy slicing into a column-major array",
            "np_build",
            "time",
        ),
        (
            "least-squares solve: unlag `fit::arx::lstsq` (faer column-pivoted QR)",
            "arx_solve",
            "`numpy.linalg.lstsq` (LAPACK gelsd, SVD)",
            "np_lstsq",
            "time",
        ),
        (
            "**fit time: build + solve**",
            "arx_total",
            "numpy build + `numpy.linalg.lstsq`",
            "np_total",
            "time",
        ),
        (
            "for information: the same solve against LAPACK's pivoted QR",
            "arx_solve",
            "`scipy.linalg.lstsq(driver='gelsy')`",
            "sp_gelsy",
            "time",
        ),
        (
            "**compensation, f32**: `InverseCoefficients<f32, 4>::process_in_place`",
            "comp_f32_inplace",
            "`scipy.signal.lfilter`, float32",
            "lfilter_f32",
            "rate",
        ),
        (
            "compensation, f64: `InverseCoefficients<f64, 4>::process_in_place`",
            "comp_f64_inplace",
            "`scipy.signal.lfilter`, float64",
            "lfilter_f64",
            "rate",
        ),
        (
            "**stable compensator, f32** (what `unlag compensate` runs): "
            "`CascadeCoefficients<f32, 4>::process_in_place`, 4 sections",
            "sos_f32_inplace",
            "`scipy.signal.sosfilt`, float32",
            "sosfilt_f32",
            "rate",
        ),
        (
            "stable compensator, f64: `CascadeCoefficients<f64, 4>::process_in_place`",
            "sos_f64_inplace",
            "`scipy.signal.sosfilt`, float64",
            "sosfilt_f64",
            "rate",
        ),
        (
            "the direct inverse as the CLI runs it without a designed compensator: `Model::compensate::<f32>` (f64 `Vec` in and out)",
            "comp_model_f32",
            "`scipy.signal.lfilter`, float32",
            "lfilter_f32",
            "rate",
        ),
    ]
    out = [START, "", "## Host: ARX fit time and compensation throughput", ""]
    out += [
        f"Data: a step test of N = {n:,} samples from a 4th-order probe (10 kHz; modes 112 Hz / 0.32 "
        "and 362 Hz / 0.16; delay 17; noise 3e-4 on u, 1e-3 on y), written by `examples/bench_host.rs` "
        "so that numpy and scipy read the same bytes in the same run. Fit: the ARX regression of "
        "order 4 (9 columns), built and solved by least squares. Compensation: the inverse "
        "`A(z)/B(z)` (against `lfilter`) and the stable compensator unlag designs for it (4 "
        "second-order sections, the same `sos` given to `sosfilt`). Cells: best wall time or "
        "throughput (median in brackets); ratio unlag / baseline of the best: for times **below 1 "
        "is faster**, for throughputs **above 1 is faster**.",
        "",
        "| figure | unlag | baseline | unlag / baseline |",
        "|---|---|---|---|",
    ]
    for figure, ours, base_text, theirs, kind in rows:
        a = cell(rust, ours, kind) or "—"
        b = cell(py, theirs, kind)
        b = f"{base_text}: {b}" if b else "—"
        better = "time" if kind == "time" else "throughput"
        r = ratio(rust, py, ours, theirs, kind)
        out.append(f"| {figure} | {a} | {b} | {r} ({better}) |")
    fit = cell(rust, "fit_oe", "time") or "—"
    out.append(
        f"| for information: the whole default fit `fit::fit` (output error, order 4, "
        f"delay given) on {fit_n:,} samples | {fit} | no baseline | — |"
    )
    checks = [l.split() for l in py_other if l.startswith("CHECK ")]
    if checks:
        failed = [c[1] for c in checks if c[4] != "ok"]
        out += ["", f"Checks of `bench/host_baseline.py` in the same run: {len(checks) - len(failed)} of "
                f"{len(checks)} passed" + (f" (failed: {', '.join(failed)})" if failed else "")
                + " (" + "; ".join(f"{c[1]} {c[2]}" for c in checks) + ")."]
    out += ["", "; ".join(info + [f"command: `{command}`"]) + ".", "", END]
    return "\n".join(out) + "\n"


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--rust", required=True)
    p.add_argument("--python", required=True)
    p.add_argument("--md", required=True, type=Path)
    p.add_argument("--command", required=True)
    p.add_argument("--info", action="append", default=[])
    args = p.parse_args()
    rust, rust_other = parse(args.rust)
    py, py_other = parse(args.python)
    if "n" not in rust:
        sys.exit(f"{args.rust}: no `RESULT n` line: did the Rust example run?")
    new = section(rust, rust_other, py, py_other, args.command, args.info)
    text = args.md.read_text() if args.md.exists() else INTRO
    pattern = re.compile(re.escape(START) + r".*?" + re.escape(END) + r"\n?", re.S)
    if pattern.search(text):
        text = pattern.sub(lambda _: new, text, count=1)
    else:
        text = text.rstrip("\n") + "\n\n" + new
    # Write next to the target and rename: never a half-written file.
    fd, tmp = tempfile.mkstemp(dir=args.md.parent, prefix=".BENCHMARKS.", suffix=".tmp")
    with os.fdopen(fd, "w") as f:
        f.write(text)
    os.replace(tmp, args.md)
    print(f"wrote the host-bench section of {args.md}")


if __name__ == "__main__":
    main()
