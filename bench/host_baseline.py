#!/usr/bin/env python3
"""Baseline of the host benchmark: numpy's lstsq and scipy's lfilter on the data
that `cargo run --release --example bench_host` wrote, in the same run.

    python bench/host_baseline.py DIR

DIR holds `meta.json`, `u.f64`, `y.f64` (the step test), and the Rust results to check
against: `theta.f64` (ARX least-squares solution), `comp_f32.f32` and `comp_f64.f64`
(compensator output from a zero state). All binaries are little-endian, no header.

Prints one line per figure, `RESULT name value unit`, and one per check,
`CHECK name value tolerance ok|FAIL`; exits with status 1 if a check fails.
"""

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

import numpy as np
import scipy
import scipy.linalg
import scipy.signal


def timed(fn, reps):
    """Best and median wall time of `reps` runs of `fn`, and the first run's result."""
    seconds = []
    first = None
    for i in range(max(reps, 1)):
        t0 = time.perf_counter()
        r = fn()
        seconds.append(time.perf_counter() - t0)
        if i == 0:
            first = r
        del r  # freed outside the timed region
    return min(seconds), statistics.median(seconds), len(seconds), first


def result_time(name, best, median, reps):
    print(f"RESULT {name}_best {best:.6e} s")
    print(f"RESULT {name}_median {median:.6e} s")
    print(f"RESULT {name}_reps {reps} count")


def result_throughput(name, n, best, median, reps):
    print(f"RESULT {name}_best {n / best:.6e} samples/s")
    print(f"RESULT {name}_median {n / median:.6e} samples/s")
    print(f"RESULT {name}_reps {reps} count")


FAILED = []


def check(name, value, tolerance):
    ok = bool(value <= tolerance)
    print(f"CHECK {name} {value:.3e} {tolerance:.1e} {'ok' if ok else 'FAIL'}")
    if not ok:
        FAILED.append(name)


def regression(u, y, m, nb, d):
    """The ARX regression of `unlag::fit::arx::regression` for one data set: rows
    k = max(m, nb - 1) + d .. n - 1, columns -y[k-1..k-m], then u[k-d..k-d-nb+1]; target y[k].
    Column-major, as LAPACK wants it."""
    n = min(len(u), len(y))
    start = max(m, nb - 1) + d
    x = np.empty((n - start, m + nb), order="F")
    for c in range(m):
        np.negative(y[start - 1 - c : n - 1 - c], out=x[:, c])
    for j in range(nb):
        x[:, m + j] = u[start - d - j : n - d - j]
    return x, y[start:n].copy()


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("dir", type=Path, help="directory written by the bench_host example")
    parser.add_argument("--reps", type=int, default=7, help="repetitions of the fit figures")
    parser.add_argument(
        "--filter-reps", type=int, default=51, help="repetitions of the filter figures"
    )
    args = parser.parse_args()
    meta = json.loads((args.dir / "meta.json").read_text())
    files = meta["files"]
    n, m, nb, d = meta["n"], meta["m"], meta["nb"], meta["d"]
    a = np.array(meta["a"], dtype=np.float64)
    b = np.array(meta["b"], dtype=np.float64)

    def load(key, dtype):
        x = np.fromfile(args.dir / files[key], dtype=dtype)
        return x

    u = load("u", "<f8")
    y = load("y", "<f8")
    theta_rust = load("theta", "<f8")
    comp_f32_rust = load("comp_f32", "<f4")
    comp_f64_rust = load("comp_f64", "<f8")
    if not (len(u) == len(y) == len(comp_f32_rust) == len(comp_f64_rust) == n):
        sys.exit(f"{args.dir}: the signal files do not hold n = {n} samples each")
    if len(theta_rust) != m + nb:
        sys.exit(f"{args.dir}/{files['theta']}: {len(theta_rust)} values, expected {m + nb}")
    print(f"INFO numpy {np.__version__} scipy {scipy.__version__} python {sys.version.split()[0]}")

    # Least squares.
    best, med, reps, (x, t) = timed(lambda: regression(u, y, m, nb, d), args.reps)
    print(f"INFO regression matrix {x.shape[0]} x {x.shape[1]}")
    result_time("np_build", best, med, reps)
    best, med, reps, sol = timed(lambda: np.linalg.lstsq(x, t, rcond=None), args.reps)
    theta_np = sol[0]
    result_time("np_lstsq", best, med, reps)

    def build_and_solve():
        xx, tt = regression(u, y, m, nb, d)
        return np.linalg.lstsq(xx, tt, rcond=None)[0]

    best, med, reps, _ = timed(build_and_solve, args.reps)
    result_time("np_total", best, med, reps)
    # For information: LAPACK's column-pivoted QR driver, the algorithm unlag uses.
    best, med, reps, sol = timed(
        lambda: scipy.linalg.lstsq(x, t, lapack_driver="gelsy", check_finite=False),
        args.reps,
    )
    theta_gelsy = sol[0]
    result_time("sp_gelsy", best, med, reps)
    print(f"INFO numpy theta={theta_np.tolist()}")
    rel = np.abs(theta_rust - theta_np) / np.abs(theta_np)
    # The regression is ill conditioned (one step in 1e6 samples): agreement is bounded by
    # cond(X) * eps, not by eps.
    cond = np.linalg.cond(x)
    print(f"INFO cond(X) = {cond:.3e}")
    check("theta_max_rel_diff_vs_numpy", float(rel.max()), 1e-6)
    rel_gelsy = np.abs(theta_rust - theta_gelsy) / np.abs(theta_gelsy)
    check("theta_max_rel_diff_vs_gelsy", float(rel_gelsy.max()), 1e-6)
    del x, t

    # Compensation: the inverse A(z)/B(z) applied to y from a zero state, with the
    # coefficients pre-divided by b0 as the Rust compensator does (1/b0 computed once).
    g = 1.0 / b[0]
    num64 = np.concatenate(([g], a * g))
    den64 = np.concatenate(([1.0], b[1:] * g))
    num32, den32 = num64.astype(np.float32), den64.astype(np.float32)
    y32 = y.astype(np.float32)
    best, med, reps, out32 = timed(
        lambda: scipy.signal.lfilter(num32, den32, y32), args.filter_reps
    )
    if out32.dtype != np.float32:
        sys.exit(f"lfilter returned {out32.dtype} for float32 input")
    result_throughput("lfilter_f32", n, best, med, reps)
    best, med, reps, out64 = timed(
        lambda: scipy.signal.lfilter(num64, den64, y), args.filter_reps
    )
    result_throughput("lfilter_f64", n, best, med, reps)

    scale = float(np.max(np.abs(out64)))
    print(f"INFO compensated output: max |u_hat| = {scale:.3e}")
    check(
        "comp_f64_max_diff_vs_lfilter_rel",
        float(np.max(np.abs(comp_f64_rust - out64))) / scale,
        1e-9,
    )
    # In f32 both filters round differently (direct form I against lfilter's transposed
    # direct form II); compare each with the f64 result, and the two with each other.
    err_rust32 = float(np.max(np.abs(comp_f32_rust.astype(np.float64) - out64))) / scale
    err_scipy32 = float(np.max(np.abs(out32.astype(np.float64) - out64))) / scale
    print(f"INFO f32 error relative to max |u_hat|: unlag {err_rust32:.3e}, lfilter {err_scipy32:.3e}")
    check(
        "comp_f32_max_diff_vs_lfilter_rel",
        float(np.max(np.abs(comp_f32_rust.astype(np.float64) - out32))) / scale,
        1e-3,
    )
    check("comp_f32_max_err_vs_f64_rel", err_rust32, 1e-3)

    # The stable band-limited compensator in second-order sections against sosfilt.
    sos64 = np.array(meta["sos"], dtype=np.float64)
    sos64[0, :3] *= meta["sos_gain"]
    sos32 = sos64.astype(np.float32)
    sos_rust32 = load("sos_f32", "<f4")
    sos_rust64 = load("sos_f64", "<f8")
    best, med, reps, s32 = timed(lambda: scipy.signal.sosfilt(sos32, y32), args.filter_reps)
    if s32.dtype != np.float32:
        sys.exit(f"sosfilt returned {s32.dtype} for float32 input")
    result_throughput("sosfilt_f32", n, best, med, reps)
    best, med, reps, s64 = timed(lambda: scipy.signal.sosfilt(sos64, y), args.filter_reps)
    result_throughput("sosfilt_f64", n, best, med, reps)
    scale = float(np.max(np.abs(s64)))
    check(
        "sos_f64_max_diff_vs_sosfilt_rel",
        float(np.max(np.abs(sos_rust64 - s64))) / scale,
        1e-9,
    )
    check(
        "sos_f32_max_err_vs_f64_rel",
        float(np.max(np.abs(sos_rust32.astype(np.float64) - s64))) / scale,
        1e-3,
    )
    print(
        "INFO sos f32 error relative to max |u_hat|: unlag "
        f"{float(np.max(np.abs(sos_rust32.astype(np.float64) - s64))) / scale:.3e}, sosfilt "
        f"{float(np.max(np.abs(s32.astype(np.float64) - s64))) / scale:.3e}"
    )

    if FAILED:
        sys.exit(f"checks failed: {', '.join(FAILED)}")


if __name__ == "__main__":
    main()
