"""unlag from Python in one page: fit the shipped step test, compensate the second one, plot
them (with matplotlib, if installed) and export the compensator for the board.

    pip install ./python          # once, from the repository's root
    python examples/python/quickstart.py

Writes target/python-quickstart/: model.toml (the command line reads it too), unlag_coeffs.h
(the board's coefficients) and, with matplotlib, compensated.png.
"""

import pathlib

import numpy as np

import unlag

root = pathlib.Path(__file__).resolve().parents[2]
data = root / "examples" / "data"
out = root / "target" / "python-quickstart"
out.mkdir(parents=True, exist_ok=True)

# 1. The step tests: the reference pressure u, the probe's output y, the sample rate.
u1, y1, fs = unlag.read_csv(data / "step_test_1.csv")
val = unlag.read_csv(data / "step_test_2.csv")

# 2. The probe's model and its compensator, the second test held out.
model = unlag.fit(u1, y1, fs, validation=[val])
print(model)
info = model.inspect()
print(f"DC gain {info['dc_gain']:.4f}, delay {info['delay_samples']} samples, "
      f"compensator latency {info['latency_samples']:.2f} samples")
for r in info["resonances"]:
    print(f"resonance at {r['frequency_hz']:.1f} Hz, damping {r['damping']:.3f}")

# 3. The second test compensated as the board computes it (f32), and its error.
u_hat = model.compensate(val.y)
lag = int(round(model.latency))
rms = lambda e: float(np.sqrt(np.mean(e**2)))
print(f"RMS error against the reference: raw probe {rms(val.y[model.delay:] - val.u[:val.u.size - model.delay]):.4f}, "
      f"u_hat {rms(u_hat[lag:] - val.u[:val.u.size - lag]):.4f} (each at its own lag)")

# 4. Plot, if matplotlib is there.
try:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
except ImportError:
    print("matplotlib is not installed: no plot (pip install matplotlib)")
else:
    t = np.arange(val.y.size) / fs * 1e3
    fig, ax = plt.subplots(figsize=(8, 4))
    ax.plot(t, val.u, "k", lw=1, label="reference u")
    ax.plot(t, val.y, "C0", lw=1, label="probe y")
    ax.plot(t, u_hat, "C2", lw=1, label="compensated u_hat")
    ax.set_xlabel("time [ms]")
    ax.legend()
    fig.savefig(out / "compensated.png", dpi=120)
    print(f"wrote {out / 'compensated.png'}")

# 5. The model file and the board's coefficients.
model.save(out / "model.toml")
(out / "unlag_coeffs.h").write_text(model.export("c"))
print(f"wrote {out / 'model.toml'} and {out / 'unlag_coeffs.h'}")
