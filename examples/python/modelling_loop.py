# %% [markdown]
# # The modelling loop from Python
#
# A notebook-style walk (run it whole with `python examples/python/modelling_loop.py`, or
# cell by cell in VS Code, Spyder or Jupyter with jupytext): a model too simple for the probe,
# the diagnosis that names what it misses, the refit that adds it, and the held-out error
# falling to the noise floor. The same loop as README's `unlag fit`, `unlag diagnose`,
# `unlag compare`.

# %%
import pathlib

import unlag

data = pathlib.Path(__file__).resolve().parents[2] / "examples" / "data"
est = unlag.read_csv(data / "step_test_1.csv")
val = unlag.read_csv(data / "step_test_2.csv")

# %% [markdown]
# ## 1. A second-order model
# One resonance: the probe's line has two modes, so this model misses one.

# %%
model = unlag.fit(est.u, est.y, est.fs, validation=[val], order=2)
print(model)

# %% [markdown]
# ## 2. What does it miss?
# `diagnose` refits the model with each candidate effect and ranks them by how much they
# lower the held-out error; `change` is the command-line wording of the refit.

# %%
candidates = unlag.diagnose(model, [est, val])
for c in candidates[:3]:
    print(f"{c.kind:<18} score {c.score:7.3f}  margin {c.margin:6.3f}  {c.reading}")
best = candidates[0]
print("best:", best.kind, "->", best.change)

# %% [markdown]
# ## 3. Add it and refit
# Passing `model=` continues the loop: its effects and history carry over.

# %%
better = unlag.fit(est.u, est.y, est.fs, validation=[val], order=2, add=[best.kind], model=model)
print(better)

# %% [markdown]
# ## 4. Watch the error fall
# `compare` returns the evidence per test and the loop's history: each fit's held-out error.

# %%
report = unlag.compare(better, [est, val])
for row in report["history"]:
    errors = ", ".join(f"{t['role']} {100 * t['nrmse']:.4f} %" for t in row["tests"])
    print(f"order {row['order']}, delay {row['delay']}, effects {row['effects']}: {errors}")
for t in report["tests"]:
    print(f"{t['file']}: nrmse {100 * t['nrmse']:.4f} %, noise floor {100 * t['noise_floor']:.4f} %")
