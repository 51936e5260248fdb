"""Shared fixtures: the shipped step tests, the command line to compare with, and one fit."""

import os
import pathlib
import subprocess

import pytest

import unlag

ROOT = pathlib.Path(__file__).resolve().parents[2]
DATA = ROOT / "examples" / "data"


def cli_path():
    """The `unlag` binary: $UNLAG_CLI (set by host-tests/python.rs), else a built one."""
    env = os.environ.get("UNLAG_CLI")
    if env:
        return env
    for profile in ("debug", "release"):
        p = ROOT / "target" / profile / "unlag"
        if p.exists():
            return str(p)
    return None


@pytest.fixture(scope="session")
def cli():
    """Runs the command line; returns the completed process (never raises on failure)."""
    path = cli_path()
    if path is None:
        pytest.skip("no unlag binary: set UNLAG_CLI or run `cargo build` first")

    def run(*args, cwd=None):
        return subprocess.run(
            [path, *map(str, args)], capture_output=True, text=True, cwd=cwd
        )

    return run


@pytest.fixture(scope="session")
def tests():
    """The two shipped step tests, as read_csv reads them."""
    return (
        unlag.read_csv(DATA / "step_test_1.csv"),
        unlag.read_csv(DATA / "step_test_2.csv"),
    )


@pytest.fixture(scope="session")
def model(tests):
    """The shipped estimation test fitted with the validation test held out."""
    est, val = tests
    return unlag.fit(est.u, est.y, est.fs, validation=[val])


@pytest.fixture(scope="session")
def cli_model(cli, tmp_path_factory):
    """The same fit by the command line: the model file's path."""
    out = tmp_path_factory.mktemp("cli") / "cli.toml"
    p = cli("fit", DATA / "step_test_1.csv", DATA / "step_test_2.csv", "-o", out)
    assert p.returncode == 0, p.stderr
    return out
