#!/usr/bin/env python3
"""The fit-speed benchmark's data and its baseline, numpy/scipy only.

    python bench/fit_baseline.py gen N DIR
        Writes DIR/est.csv (a step 0 -> 1) and DIR/val.csv (a falling step 1 -> 0.3 of another
        size), N rows each, columns t,u,y: a 4th-order probe (10 kHz; modes 112 Hz / 0.32 and
        362 Hz / 0.16, zero-order hold; delay 17 samples), white noise on both channels
        (3e-4 on u, 1e-3 on y) and a 16-bit ADC over 2.5 steps.

    python bench/fit_baseline.py fit DIR MODEL.toml
        Reads DIR/est.csv and DIR/val.csv, times an independent Steiglitz-McBride + output-error
        fit (numpy lstsq, scipy lfilter, scipy least_squares 'lm' with the analytic Jacobian)
        of the order and delay in MODEL.toml (unlag's fit), and prints `RESULT name value`
        lines: its time (reading the file included, as unlag's wall time includes it) and the
        validation errors of both models, computed by the same code here.

The baseline is given unlag's order and delay: it does no order or delay search, so it is
the cheaper job of the two.
"""

import sys
import time
import tomllib
from pathlib import Path

import numpy as np
from scipy import optimize, signal

FS = 10_000.0


def probe():
    """The 4th-order probe as a discrete ZOH model (b, a) in z^-1 and its delay."""
    modes = [(112.0, 0.32), (362.0, 0.16)]
    den = np.array([1.0])
    for f, z in modes:
        w = 2 * np.pi * f
        den = np.polymul(den, [1.0, 2 * z * w, w * w])
    num = [den[-1]]
    bd, ad, _ = signal.cont2discrete((num, den), 1.0 / FS, method="zoh")
    return np.ravel(bd), np.ravel(ad), 17


def quantise(x, full_scale):
    lsb = full_scale / 65536.0
    return np.round(x / lsb) * lsb


def gen(n, out):
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    b, a, d = probe()
    rng = np.random.default_rng(16)
    for name, lo, hi, at in [("est", 0.0, 1.0, 2000), ("val", 1.0, 0.3, 3000)]:
        u = np.full(n, lo)
        u[at:] = hi
        y = signal.lfilter(b, a, np.concatenate([np.full(d, lo), u[:-d]]), zi=signal.lfilter_zi(b, a) * lo)[0]
        un = quantise(u + 3e-4 * rng.standard_normal(n), 2.5)
        yn = quantise(y + 1e-3 * rng.standard_normal(n), 2.5)
        t = np.arange(n) / FS
        with open(out / f"{name}.csv", "w") as f:
            f.write("t,u,y\n")
            np.savetxt(f, np.column_stack([t, un, yn]), fmt="%.8g", delimiter=",")


def read(path):
    x = np.loadtxt(path, delimiter=",", skiprows=1)
    return x[:, 1], x[:, 2]


def prepare(u, y):
    """Deviations from the resting levels before the step (the first 90 % of the quiet part)."""
    mid = 0.5 * (u[:100].mean() + u[-100:].mean())
    onset = int(np.argmax(np.abs(u - u[:100].mean()) > abs(mid - u[:100].mean())))
    q = max(onset - 10, 10)
    return u - u[:q].mean(), y - y[:q].mean()


def delayed(x, d):
    return np.concatenate([np.zeros(d), x[: len(x) - d]])


def arx(u, y, m, d):
    n = len(y)
    k0 = m + d
    cols = [-y[k0 - i - 1 : n - i - 1] for i in range(m)]
    cols += [u[k0 - d - i : n - d - i] for i in range(m + 1)]
    x = np.column_stack(cols)
    theta = np.linalg.lstsq(x, y[k0:], rcond=None)[0]
    return theta[:m], theta[m:]


def sim(a, b, d, u):
    return signal.lfilter(b, np.concatenate([[1.0], a]), delayed(u, d))


def stable(a):
    return np.all(np.abs(np.roots(np.concatenate([[1.0], a]))) < 1.0)


def steiglitz_mcbride(u, y, m, d, iterations=20):
    a, b = arx(u, y, m, d)
    best = (np.inf, a, b)
    for _ in range(iterations):
        if not stable(a):
            break
        den = np.concatenate([[1.0], a])
        a, b = arx(signal.lfilter([1.0], den, u), signal.lfilter([1.0], den, y), m, d)
        if stable(a):
            loss = np.sum((y - sim(a, b, d, u)) ** 2)
            if loss < best[0]:
                best = (loss, a, b)
    return best[1], best[2]


def output_error(u, y, a, b, d):
    m = len(a)
    ud = delayed(u, d)

    def split(p):
        return p[:m], p[m:]

    def residual(p):
        a, b = split(p)
        return y - signal.lfilter(b, np.concatenate([[1.0], a]), ud)

    def jacobian(p):
        a, b = split(p)
        den = np.concatenate([[1.0], a])
        yh = signal.lfilter(b, den, ud)
        w = signal.lfilter([1.0], den, ud)
        v = signal.lfilter([1.0], den, yh)
        j = np.empty((len(y), len(p)))
        for i in range(m):
            j[:, i] = delayed(v, i + 1)
        for i in range(len(b)):
            j[:, m + i] = -delayed(w, i)
        return j

    r = optimize.least_squares(residual, np.concatenate([a, b]), jac=jacobian, method="lm")
    return split(r.x)


def nrmse(a, b, d, u, y):
    u, y = prepare(u, y)
    e = y - sim(a, b, d, u)
    return np.sqrt(np.mean(e * e)) / (y.max() - y.min())


def fit(directory, model_path):
    directory = Path(directory)
    model = tomllib.loads(Path(model_path).read_text())
    a_u, b_u, d = np.array(model["a"]), np.array(model["b"]), int(model["delay"])
    m = len(a_u)
    t0 = time.perf_counter()
    u, y = read(directory / "est.csv")
    t_read = time.perf_counter() - t0
    up, yp = prepare(u, y)
    a, b = steiglitz_mcbride(up, yp, m, d)
    a, b = output_error(up, yp, a, b, d)
    seconds = time.perf_counter() - t0
    uv, yv = read(directory / "val.csv")
    print(f"RESULT baseline_seconds {seconds:.4f}")
    print(f"RESULT baseline_read_seconds {t_read:.4f}")
    print(f"RESULT order {m}")
    print(f"RESULT delay {d}")
    print(f"RESULT baseline_val_nrmse {nrmse(a, b, d, uv, yv):.6e}")
    print(f"RESULT unlag_val_nrmse {nrmse(a_u, b_u, d, uv, yv):.6e}")
    print(f"RESULT baseline_est_nrmse {nrmse(a, b, d, u, y):.6e}")
    print(f"RESULT unlag_est_nrmse {nrmse(a_u, b_u, d, u, y):.6e}")


if __name__ == "__main__":
    if len(sys.argv) == 4 and sys.argv[1] == "gen":
        gen(int(float(sys.argv[2])), sys.argv[3])
    elif len(sys.argv) == 4 and sys.argv[1] == "fit":
        fit(sys.argv[2], sys.argv[3])
    else:
        sys.exit(__doc__)
