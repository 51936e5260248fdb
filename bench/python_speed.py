"""The Python package against the command line on the same work: fit a
1e6-sample step test and compensate a 1e6-sample run, from the CSV files, both ways.

    python bench/python_speed.py [UNLAG_BINARY] [N] [REPEATS]

UNLAG_BINARY defaults to target/release/unlag; compare it with a package built the same way
(`pip install ./python` builds with the release profile, as `cargo build --release` does).
The data: the shipped step test's fitted model driven by a step (est.csv) and by another step
(run.csv), with noise, written once to target/bench-python/N/. Prints the wall times (best of
REPEATS, default 3) and the ratio Python / CLI.
"""

import os
import pathlib
import subprocess
import sys
import time

import numpy as np

import unlag

root = pathlib.Path(__file__).resolve().parents[1]
cli = sys.argv[1] if len(sys.argv) > 1 else str(root / "target" / "release" / "unlag")
n = int(float(sys.argv[2])) if len(sys.argv) > 2 else 1_000_000
repeats = int(sys.argv[3]) if len(sys.argv) > 3 else 3
out = root / "target" / "bench-python" / str(n)
out.mkdir(parents=True, exist_ok=True)
est_csv, run_csv = out / "est.csv", out / "run.csv"

if not run_csv.exists():
    u0, y0, fs = unlag.read_csv(root / "examples" / "data" / "step_test_1.csv")
    probe = unlag.fit(u0, y0, fs)
    rng = np.random.default_rng(65)
    for path, lo, hi, at in [(est_csv, 0.0, 1.0, 2000), (run_csv, 1.0, 0.3, 3000)]:
        u = np.full(n, lo)
        u[at:] = hi
        y = probe.simulate(u) + 1e-3 * rng.standard_normal(n)
        u = u + 3e-4 * rng.standard_normal(n)
        t = np.arange(n) / fs
        with open(path, "w") as f:
            f.write("t,u,y\n")
            np.savetxt(f, np.column_stack([t, u, y]), fmt="%.8g", delimiter=",")


def best(f):
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        f()
        times.append(time.perf_counter() - t0)
    return min(times)


def by_cli():
    # A fresh fit each time (an existing output model file would be continued).
    (out / "cli.toml").unlink(missing_ok=True)
    subprocess.run([cli, "fit", est_csv, "-o", out / "cli.toml"], check=True, capture_output=True)
    subprocess.run(
        [cli, "compensate", out / "cli.toml", run_csv, "-o", out / "cli_u_hat.csv", "--force"],
        check=True,
        capture_output=True,
    )


def by_python():
    u, y, fs = unlag.read_csv(est_csv)
    model = unlag.fit(u, y, fs)
    model.save(out / "py.toml")
    run = unlag.read_csv(run_csv)
    model.compensate(run.y)


def by_python_arrays(arrays):
    (u, y, fs), run_y = arrays
    unlag.fit(u, y, fs).compensate(run_y)


if os.path.exists(out / "cli_u_hat.csv"):
    os.remove(out / "cli_u_hat.csv")
t_cli = best(by_cli)
t_py = best(by_python)
arrays = (unlag.read_csv(est_csv), unlag.read_csv(run_csv).y)
t_arr = best(lambda: by_python_arrays(arrays))
print(f"rows {n}: CLI fit + compensate (CSV in, CSV out) {t_cli:.2f} s; "
      f"Python read_csv + fit + save + compensate {t_py:.2f} s (ratio {t_py / t_cli:.2f}); "
      f"Python fit + compensate from arrays {t_arr:.2f} s (ratio {t_arr / t_cli:.2f})")
