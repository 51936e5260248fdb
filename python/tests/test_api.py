"""The Python API against the command line: the same model, the same u_hat bit for bit, the
same model files and the same messages; and bad input refused with an exception."""

import csv
import json
import threading

import numpy as np
import pytest

import unlag
from conftest import DATA


def u_hat_of(path):
    """The u_hat column of a CSV file the command line wrote, as float64 (it writes the
    shortest text that reads back to the same value)."""
    with open(path, newline="") as f:
        return np.array([float(r["u_hat"]) for r in csv.DictReader(f)], dtype=np.float64)


def cli_error(p):
    """The message of the command line's `error: ...` line."""
    assert p.returncode != 0, p.stdout
    lines = [l for l in p.stderr.splitlines() if l.startswith("error: ")]
    assert lines, p.stderr
    return lines[-1][len("error: "):]


# --- reading -------------------------------------------------------------------------------


def test_read_csv_reads_the_shipped_test(tests):
    est, _ = tests
    u, y, fs = est
    assert fs == 10_000.0
    assert u.dtype == np.float64 and y.dtype == np.float64
    assert u.shape == y.shape == (4000,)
    # The file's first row: t,u,y = 0.000000000,0.561,-0.0282
    assert u[0] == 0.561 and y[0] == -0.0282


def test_read_csv_of_a_missing_file_is_a_file_error(tmp_path, cli):
    missing = tmp_path / "missing.csv"
    with pytest.raises(unlag.FileError) as e:
        unlag.read_csv(missing)
    p = cli("fit", missing, "-o", tmp_path / "m.toml")
    assert str(e.value) == cli_error(p)


# --- the fit against the command line's ---------------------------------------------------


def test_fit_is_the_command_lines_fit(model, cli_model):
    cli = unlag.load(cli_model)
    assert model.delay == cli.delay
    assert np.array_equal(model.a, cli.a)
    assert np.array_equal(model.b, cli.b)
    assert model.latency == cli.latency
    assert model.fs == 10_000.0 and model.order == len(model.a) >= 1


@pytest.mark.parametrize("arithmetic", ["f32", "fixed", "f64"])
def test_compensate_is_the_command_lines_u_hat_bit_for_bit(cli, cli_model, tests, tmp_path, arithmetic):
    out = tmp_path / f"u_hat_{arithmetic}.csv"
    p = cli("compensate", cli_model, DATA / "step_test_2.csv", "--arithmetic", arithmetic, "-o", out)
    assert p.returncode == 0, p.stderr
    expected = u_hat_of(out)
    got = unlag.load(cli_model).compensate(tests[1].y, arithmetic)
    assert got.dtype == np.float64 and got.shape == expected.shape
    assert np.array_equal(got, expected), np.flatnonzero(got != expected)[:5]


def test_compensate_brings_the_probe_closer_to_the_reference(model, tests):
    val = tests[1]
    u_hat = model.compensate(val.y)
    lag = int(round(model.latency))
    err = lambda x: np.sqrt(np.mean((x[lag:] - val.u[: val.u.size - lag]) ** 2))
    raw = lambda x: min(np.sqrt(np.mean((x[d:] - val.u[: val.u.size - d]) ** 2)) for d in range(0, 60))
    assert err(u_hat) < raw(val.y)


@pytest.mark.parametrize("arithmetic", ["f32", "fixed"])
def test_reference_error_is_the_command_lines(cli, cli_model, tests, tmp_path, arithmetic):
    out = tmp_path / "u_hat.csv"
    p = cli("compensate", cli_model, DATA / "step_test_2.csv", "--arithmetic", arithmetic, "-o", out, "--json")
    assert p.returncode == 0, p.stderr
    expected = json.loads(p.stdout)
    got = unlag.load(cli_model).reference_error(tests[1].u, tests[1].y, arithmetic)
    assert got.u_hat == expected["nrmse_u_hat"]
    assert got.raw == expected["nrmse_raw"]
    assert got.lag == expected["alignment_samples"]
    assert got.improvement > 1.0


def test_reference_error_refuses_a_reference_of_another_length(model, tests):
    with pytest.raises(unlag.InvalidArgumentError, match="same length"):
        model.reference_error(tests[1].u[:-1], tests[1].y)


def test_the_default_arithmetic_is_the_boards(model, tests):
    y = tests[1].y
    assert np.array_equal(model.compensate(y), model.compensate(y, "f32"))


# --- model files --------------------------------------------------------------------------


def test_a_saved_model_is_what_the_command_line_reads(model, cli, tmp_path, tests):
    path = tmp_path / "py.toml"
    model.save(path)
    again = unlag.load(path)
    assert again.to_toml() == model.to_toml()
    p = cli("inspect", path, "--json")
    assert p.returncode == 0, p.stderr
    out = tmp_path / "cli_u_hat.csv"
    p = cli("compensate", path, DATA / "step_test_2.csv", "-o", out)
    assert p.returncode == 0, p.stderr
    assert np.array_equal(u_hat_of(out), model.compensate(tests[1].y))


def test_loads_reads_the_text_of_a_model_file(model):
    assert unlag.loads(model.to_toml()).to_toml() == model.to_toml()


def test_a_model_pickles_and_copies_as_its_model_file(model, tests):
    import copy
    import pickle

    for again in (pickle.loads(pickle.dumps(model)), copy.deepcopy(model), copy.copy(model)):
        assert isinstance(again, unlag.Model)
        assert again.to_toml() == model.to_toml()
        assert np.array_equal(again.compensate(tests[1].y), model.compensate(tests[1].y))


def test_a_broken_model_file_is_the_command_lines_error(tmp_path, cli):
    path = tmp_path / "broken.toml"
    path.write_text("[model]\nfs = 'fast'\n")
    with pytest.raises(unlag.ModelFileError) as e:
        unlag.load(path)
    assert str(e.value) == cli_error(cli("inspect", path))


# --- simulate, inspect, frequency response, export -----------------------------------------


def test_simulate_is_the_command_lines(cli, cli_model, tests, tmp_path):
    out = tmp_path / "sim.csv"
    p = cli("simulate", cli_model, DATA / "step_test_2.csv", "-o", out)
    assert p.returncode == 0, p.stderr
    with open(out, newline="") as f:
        expected = np.array([float(r["y_model"]) for r in csv.DictReader(f)])
    val = tests[1]
    assert np.array_equal(unlag.load(cli_model).simulate(val.u, val.y), expected)
    # Without the recorded probe: the dynamics alone, as long as u.
    assert unlag.load(cli_model).simulate(val.u).shape == val.u.shape


def test_inspect_names_poles_zeros_gain_and_latency(model):
    i = model.inspect()
    assert i["poles"].dtype == np.complex128 and i["poles"].size == model.order
    # The DC gain is sum(b) / (1 + sum(a)).
    assert i["dc_gain"] == pytest.approx(model.b.sum() / (1 + model.a.sum()), rel=1e-12)
    assert i["delay_samples"] == model.delay
    assert i["latency_samples"] == model.latency
    assert i["stable"] and i["stability"] is None
    assert all(np.abs(i["poles"]) < 1)
    for r in i["resonances"]:
        assert r["frequency_hz"] > 0 and 0 < r["damping"] < 1


def test_frequency_response_is_the_models_transfer_function(model):
    f = np.array([0.0, 10.0, 250.0, 1000.0])
    f_out, h = model.frequency_response(f)
    assert np.array_equal(f_out, f)
    z = np.exp(1j * 2 * np.pi * f / model.fs)
    a = np.concatenate([[1.0], model.a])
    num = np.polyval(model.b[::-1], 1 / z) * z ** (-model.delay)
    den = np.polyval(a[::-1], 1 / z)
    np.testing.assert_allclose(h, num / den, rtol=1e-9)
    f_grid, h_grid = model.frequency_response()
    assert f_grid[0] == 0.0 and f_grid.size == h_grid.size > 10


def test_export_is_the_command_lines(model, cli, tmp_path):
    path = tmp_path / "m.toml"
    model.save(path)
    for fmt, name in [("c", "m.h"), ("rust", "m.rs"), ("bin", "m.bin")]:
        out = tmp_path / name
        p = cli("export", path, "--format", fmt, "-o", out)
        assert p.returncode == 0, p.stderr
        got = unlag.load(path).export(fmt)
        if fmt == "bin":
            assert isinstance(got, bytes) and got == out.read_bytes()
        else:
            assert isinstance(got, str) and got == out.read_text()


def test_export_refuses_what_the_command_line_refuses(model, cli, tmp_path):
    path = tmp_path / "m.toml"
    model.save(path)
    with pytest.raises(unlag.InvalidArgumentError) as e:
        unlag.load(path).export("c", number_format="f32", full_scale=2.0)
    p = cli("export", path, "--format", "c", "--number-format", "f32", "--full-scale", "2", "-o", tmp_path / "x.h")
    assert str(e.value) == cli_error(p)
    with pytest.raises(unlag.InvalidArgumentError):
        model.export("pdf")


# --- bad input: exceptions, never a crash --------------------------------------------------


@pytest.mark.parametrize(
    "bad, what",
    [
        (np.array([0.0, np.nan, 1.0] * 100), "nan"),
        (np.array([0.0, np.inf] * 100), "inf"),
        (np.zeros((10, 2)), "shape"),
        (np.array([], dtype=np.float64), "empty"),
        (np.array(["a", "b"]), "numbers"),
        ([None, 1.0], "nan"),  # numpy reads None as NaN
        (np.array([1 + 1j, 2.0]), "real"),
    ],
)
def test_bad_arrays_raise_invalid_argument(model, tests, bad, what):
    est = tests[0]
    with pytest.raises(unlag.InvalidArgumentError, match=what):
        model.compensate(bad)
    with pytest.raises(unlag.InvalidArgumentError, match=what):
        unlag.fit(bad, est.y, est.fs)
    with pytest.raises(unlag.InvalidArgumentError, match=what):
        model.simulate(bad)


def test_other_dtypes_and_layouts_are_accepted(model, tests):
    y = tests[1].y
    expected = model.compensate(y, "f64")
    assert np.array_equal(model.compensate(list(y), "f64"), expected)
    strided = np.repeat(y, 2)[::2]
    assert not strided.flags.c_contiguous
    assert np.array_equal(model.compensate(strided, "f64"), expected)
    big_endian = y.astype(">f8")
    assert np.array_equal(model.compensate(big_endian, "f64"), expected)
    as_f32 = model.compensate(y.astype(np.float32), "f64")
    assert as_f32.shape == y.shape


def test_unequal_lengths_and_no_step_are_refused(tests):
    est = tests[0]
    with pytest.raises(unlag.InvalidArgumentError, match="as long as"):
        unlag.fit(est.u[:-1], est.y, est.fs)
    with pytest.raises(unlag.DataError) as e:
        unlag.fit(np.ones(4000), est.y, est.fs)
    assert e.value.kind == "no-step"
    with pytest.raises(unlag.InvalidArgumentError):
        unlag.fit(est.u, est.y, -1.0)
    with pytest.raises(unlag.InvalidArgumentError):
        unlag.fit(est.u, est.y, float("nan"))


def test_fit_options_are_checked_as_the_command_line_checks_them(tests, cli, tmp_path):
    est = tests[0]
    with pytest.raises(unlag.InvalidArgumentError) as e:
        unlag.fit(est.u, est.y, est.fs, order=0)
    p = cli("fit", DATA / "step_test_1.csv", "--order", "0", "-o", tmp_path / "m.toml")
    assert str(e.value) == cli_error(p)
    with pytest.raises(unlag.InvalidArgumentError, match="method"):
        unlag.fit(est.u, est.y, est.fs, method="magic")
    with pytest.raises(unlag.InvalidArgumentError):
        unlag.fit(est.u, est.y, est.fs, add=["gremlins"])
    assert issubclass(unlag.InvalidArgumentError, ValueError)
    assert issubclass(unlag.InvalidArgumentError, unlag.Error)


def test_unknown_arithmetic_is_refused(model, tests):
    with pytest.raises(unlag.InvalidArgumentError, match="arithmetic"):
        model.compensate(tests[1].y, "f16")


def test_compensation_releases_the_gil(model, tests):
    """Two threads compensating at once both finish with the same answer (the native work
    runs without the GIL; a deadlock would hang here)."""
    y = np.tile(tests[1].y, 20)
    results = [None, None]

    def work(k):
        results[k] = model.compensate(y)

    threads = [threading.Thread(target=work, args=(k,)) for k in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert np.array_equal(results[0], results[1])


# --- the modelling loop --------------------------------------------------------------------


def test_diagnose_is_the_command_lines(model, cli, cli_model, tests):
    import json

    candidates = unlag.diagnose(unlag.load(cli_model), list(tests))
    p = cli("diagnose", cli_model, DATA / "step_test_1.csv", DATA / "step_test_2.csv", "--json")
    assert p.returncode == 0, p.stderr
    expected = json.loads(p.stdout)["candidates"]
    assert [c.kind for c in candidates] == [c["kind"] for c in expected]
    assert [c.score for c in candidates] == [c["score"] for c in expected]
    assert [c.change for c in candidates] == [c["change"] for c in expected]
    best = candidates[0]
    assert isinstance(best, unlag.Candidate) and best.reading


def test_compare_reports_each_test(model, tests):
    c = unlag.compare(model, list(tests))
    assert len(c["tests"]) == 2
    assert len(c["history"]) >= 1


def test_the_loop_continues_a_model(model, tests):
    est, val = tests
    again = unlag.fit(est.u, est.y, est.fs, validation=[val], add=["offset"], model=model)
    assert len(again.to_dict()["history"]) == len(model.to_dict()["history"]) + 1
    assert any(e.get("kind") == "offset" for e in again.effects)


def test_help_reads_well():
    assert "step test" in unlag.fit.__doc__
    assert "Parameters" in unlag.Model.compensate.__doc__


# --- the examples --------------------------------------------------------------------------


@pytest.mark.parametrize("script, says", [("quickstart.py", "unlag_coeffs.h"), ("modelling_loop.py", "best: mode")])
def test_the_examples_run(script, says):
    import subprocess
    import sys

    from conftest import ROOT

    p = subprocess.run(
        [sys.executable, str(ROOT / "examples" / "python" / script)], capture_output=True, text=True
    )
    assert p.returncode == 0, p.stderr
    assert says in p.stdout, p.stdout


# --- invert, resample, simulate-test, predict ----------------------------------------------


def test_invert_is_the_command_lines(cli, cli_model, tests, tmp_path):
    """The compensator designed anew: the same model file as `unlag invert` writes."""
    out = tmp_path / "inverted.toml"
    p = cli("invert", cli_model, "step_test_2.csv", "--bandwidth", "auto", "-o", out, cwd=DATA)
    assert p.returncode == 0, p.stderr
    model = unlag.load(cli_model)
    got = model.invert([tests[1]], names=["step_test_2.csv"], bandwidth="auto")
    assert isinstance(got, unlag.Model)
    assert got.to_toml() == out.read_text()
    assert model.to_toml() == unlag.load(cli_model).to_toml()  # the model itself unchanged


def test_invert_refuses_what_the_command_line_refuses(cli, cli_model, tests, tmp_path):
    with pytest.raises(unlag.InvalidArgumentError) as e:
        unlag.load(cli_model).invert([tests[1]], bandwidth="fast")
    p = cli("invert", cli_model, DATA / "step_test_2.csv", "--bandwidth", "fast", "-o", tmp_path / "x.toml")
    assert str(e.value) == cli_error(p)
    # A test at another rate than the model's.
    val = tests[1]
    with pytest.raises(unlag.DataError):
        unlag.load(cli_model).invert([(val.u, val.y, 20_000.0)])


def test_resample_is_the_command_lines(cli, cli_model, tmp_path):
    out = tmp_path / "resampled.toml"
    p = cli("resample", cli_model, "--fs", "20000", "-o", out)
    assert p.returncode == 0, p.stderr
    got = unlag.load(cli_model).resample(20_000)
    assert got.to_toml() == out.read_text()
    assert got.fs == 20_000.0 and got.latency is None


def test_resample_refuses_what_the_command_line_refuses(cli, cli_model, tmp_path):
    with pytest.raises(unlag.InvalidArgumentError) as e:
        unlag.load(cli_model).resample(-1)
    p = cli("resample", cli_model, "--fs", "-1", "-o", tmp_path / "x.toml")
    assert str(e.value) == cli_error(p)


SIMULATED = dict(fs=20_000, excitation="shock", volume=2e-7, line=[(0.3, 1e-3)], duration=0.02, noise=0.5, seed=7)


def test_simulate_test_is_the_command_lines(cli, tmp_path):
    out = tmp_path / "sim.csv"
    p = cli(
        "simulate-test", "--fs", "20000", "--excitation", "shock", "--volume", "2e-7",
        "--line", "0.3,0.001", "--duration", "0.02", "--noise", "0.5", "--seed", "7", "-o", out,
    )
    assert p.returncode == 0, p.stderr
    with open(out, newline="") as f:
        rows = list(csv.DictReader(f))
    t, u, y = unlag.simulate_test(**SIMULATED)
    assert t.dtype == u.dtype == y.dtype == np.float64 and t.shape == u.shape == y.shape == (len(rows),)
    # u and y are written as the shortest text that reads back to them, t to the nanosecond.
    assert np.array_equal(u, [float(r["u"]) for r in rows])
    assert np.array_equal(y, [float(r["y"]) for r in rows])
    assert [f"{x:.9f}" for x in t] == [r["t"] for r in rows]


def test_simulate_test_refuses_what_the_command_line_refuses(cli, tmp_path):
    bad = {**SIMULATED, "line": "0.3"}
    with pytest.raises(unlag.InvalidArgumentError) as e:
        unlag.simulate_test(**bad)
    p = cli("simulate-test", "--fs", "20000", "--excitation", "shock", "--volume", "2e-7", "--line", "0.3", "-o", tmp_path / "x.csv")
    assert str(e.value) == cli_error(p)
    with pytest.raises(unlag.InvalidArgumentError, match="--gremlins"):
        unlag.simulate_test(**SIMULATED, gremlins=1)


def test_predict_is_the_command_lines(cli):
    import json

    p = cli("predict", "--line", "0.3,0.001", "--volume", "2e-7", "--modes", "2", "--json")
    assert p.returncode == 0, p.stderr
    expected = json.loads(p.stdout)
    got = unlag.predict(line=[(0.3, 1e-3)], volume=2e-7, modes=2)
    assert got["modes"] == expected["modes"] and len(got["modes"]) == 2
    assert got == expected


def test_predict_compares_with_a_model_as_the_command_line(cli, cli_model):
    import json

    p = cli("predict", "--line", "0.3,0.001", "--volume", "2e-7", "--model", cli_model, "--json")
    assert p.returncode == 0, p.stderr
    expected = json.loads(p.stdout)["comparison"]
    assert unlag.predict(line=[(0.3, 1e-3)], volume=2e-7, model=unlag.load(cli_model))["comparison"] == expected
    assert unlag.predict(line=[(0.3, 1e-3)], volume=2e-7, model=cli_model)["comparison"] == expected


def test_predict_refuses_what_the_command_line_refuses(cli):
    with pytest.raises(unlag.InvalidArgumentError) as e:
        unlag.predict(line=[(0.3, 1e-3)], volume=2e-7, modes=0)
    p = cli("predict", "--line", "0.3,0.001", "--volume", "2e-7", "--modes", "0")
    assert str(e.value) == cli_error(p)


def test_one_signal_path_is_a_list_of_one(tests):
    run = str(DATA / "step_test_2.csv")
    one = unlag.fit(tests[0].u, tests[0].y, tests[0].fs, order=2, signal=run)
    listed = unlag.fit(tests[0].u, tests[0].y, tests[0].fs, order=2, signal=[run])
    assert one.to_toml() == listed.to_toml()
