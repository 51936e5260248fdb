"""unlag: give pressure probes back the bandwidth their tubing, holes and cavities take away.

The same fit, compensator and modelling loop as the ``unlag`` command line, on numpy arrays:

>>> import unlag
>>> u, y, fs = unlag.read_csv("examples/data/step_test_1.csv")
>>> u2, y2, _ = unlag.read_csv("examples/data/step_test_2.csv")
>>> model = unlag.fit(u, y, fs, validation=[(u2, y2)])  # the probe's model and compensator
>>> u_hat = model.compensate(y2)                      # what the board computes (f32 by default)
>>> model.save("model.toml")                          # the CLI's model file
>>> header = model.export("c")                        # coefficients for the board
>>> unlag.diagnose(model, [(u, y), (u2, y2)])[0]      # the missing physics, best first

Arrays go in as any one-dimensional array of real numbers (a float64 C-contiguous array is
used without a copy) and come out as float64 numpy arrays. Problems raise :class:`Error` (and
its subclasses) with the command line's message; the long work releases the GIL.
"""

from __future__ import annotations

import json
import os
import warnings
from dataclasses import dataclass, field
from typing import Any, Dict, Iterable, List, NamedTuple, Optional, Sequence, Tuple, Union

import numpy as np

from . import _unlag
from ._errors import (
    BoardError,
    DataError,
    Error,
    FileError,
    InvalidArgumentError,
    ModelFileError,
    UnstableError,
)

__version__ = _unlag.__version__

__all__ = [
    "BoardError",
    "Candidate",
    "DataError",
    "Error",
    "FileError",
    "InvalidArgumentError",
    "Model",
    "ModelFileError",
    "Recording",
    "ReferenceError",
    "SimulatedTest",
    "UnstableError",
    "compare",
    "diagnose",
    "fit",
    "load",
    "loads",
    "predict",
    "read_csv",
    "simulate_test",
]

PathLike = Union[str, "os.PathLike[str]"]


class Recording(NamedTuple):
    """A recording read by :func:`read_csv`: unpacks as ``u, y, fs``."""

    u: Optional[np.ndarray]
    """The reference pressure (None when the file has no reference column)."""
    y: np.ndarray
    """The probe output."""
    fs: float
    """The sample rate in Hz."""


class SimulatedTest(NamedTuple):
    """A step test simulated by :func:`simulate_test`: unpacks as ``t, u, y``, the columns of
    the CSV file ``unlag simulate-test`` writes."""

    t: np.ndarray
    """The sample times in s from the record's start."""
    u: np.ndarray
    """The reference channel in Pa (relative to the level before the event)."""
    y: np.ndarray
    """The probe channel in Pa."""


class ReferenceError(NamedTuple):
    """The error of a compensated signal against a recorded reference, beside the raw
    probe's (:meth:`Model.reference_error`): RMS over the reference's range (0.01 is 1 %),
    each at its best whole-sample alignment."""

    u_hat: float
    """``u_hat``'s error."""
    raw: float
    """The raw probe's error."""
    lag: int
    """The lag of ``u_hat`` behind the reference at its best alignment (samples)."""

    @property
    def improvement(self) -> float:
        """How many times smaller ``u_hat``'s error is than the raw probe's (above 1: better)."""
        return self.raw / self.u_hat if self.u_hat > 0 else float("inf")


def _vector(x: Any, name: str) -> np.ndarray:
    """``x`` as a one-dimensional C-contiguous float64 array of finite numbers (no copy when it
    is one already), or :class:`InvalidArgumentError` saying what is wrong with it."""
    if isinstance(x, np.ndarray) and np.iscomplexobj(x):
        raise InvalidArgumentError(f"{name} must hold real numbers, got dtype {x.dtype}", "invalid-argument")
    try:
        a = np.asarray(x, dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise InvalidArgumentError(
            f"{name} must be a one-dimensional array of numbers ({e})", "invalid-argument"
        ) from None
    if a.ndim != 1:
        raise InvalidArgumentError(
            f"{name} must be one-dimensional, got an array of shape {a.shape}", "invalid-argument"
        )
    if a.size == 0:
        raise InvalidArgumentError(f"{name} is empty", "invalid-argument")
    a = np.ascontiguousarray(a)
    finite = np.isfinite(a)
    if not finite.all():
        k = int(np.argmin(finite))
        raise InvalidArgumentError(
            f"{name}[{k}] is {a[k]}: every sample must be a finite number", "invalid-argument"
        )
    return a


def _pair(test: Any, name: str) -> Tuple[np.ndarray, np.ndarray, Optional[float]]:
    """A test given as ``(u, y)``, ``(u, y, fs)`` or a :class:`Recording`."""
    try:
        items = tuple(test)
    except TypeError:
        items = ()
    if len(items) not in (2, 3):
        raise InvalidArgumentError(
            f"{name} must be a pair (u, y) or a recording (u, y, fs)", "invalid-argument"
        )
    if items[0] is None:
        raise DataError(f"{name} has no reference u (a step test needs one)", "missing-column")
    u = _vector(items[0], f"{name}: u")
    y = _vector(items[1], f"{name}: y")
    if u.shape != y.shape:
        raise InvalidArgumentError(
            f"{name}: u and y must be as long as each other, got {u.size} and {y.size} samples",
            "invalid-argument",
        )
    fs = None if len(items) == 2 or items[2] is None else float(items[2])
    return u, y, fs


def _flag(flags: List[str], name: str, value: Any) -> None:
    """Appends ``--name value`` unless ``value`` is None."""
    if value is not None and value is not False:
        flags.append(f"--{name}")
        if value is not True:
            flags.append(str(value))


def _text(x: Any) -> str:
    """A flag's value as the command line reads it: a float as the shortest text that reads
    back to it, anything else as its text."""
    if isinstance(x, (bool, np.bool_)):
        return str(x).lower()
    if isinstance(x, (int, np.integer)):
        return str(int(x))
    if isinstance(x, (float, np.floating)):
        return repr(float(x))
    return os.fspath(x) if isinstance(x, os.PathLike) else str(x)


def _options(options: Dict[str, Any]) -> List[str]:
    """The command line's flags for keyword arguments: ``name=value`` is ``--name value``
    (``_`` read as ``-``), ``True`` the bare flag, ``None`` and ``False`` nothing; a pair
    such as ``(0.5, 1e-3)`` is ``0.5,0.001``, and a list of values (strings or pairs) repeats
    the flag."""
    flags: List[str] = []
    for key, value in options.items():
        name = "--" + key.replace("_", "-")
        if value is None or value is False:
            continue
        if value is True:
            flags.append(name)
            continue
        if isinstance(value, (str, os.PathLike)) or not isinstance(value, Iterable):
            values = [value]
        else:
            items = list(value)
            scalar = lambda v: not isinstance(v, Iterable) or isinstance(v, (str, os.PathLike))
            # A list of numbers is one pair; a list of pairs or strings, one flag each.
            if items and all(scalar(v) and not isinstance(v, str) for v in items):
                values = [items]
            else:
                values = items
        for v in values:
            if not isinstance(v, (str, os.PathLike)) and isinstance(v, Iterable):
                v = ",".join(_text(x) for x in v)
            flags += [name, _text(v)]
    return flags


def _compensator_flags(
    bandwidth: Any,
    max_latency: Any,
    max_band: Any,
    signal: Any,
    lowpass: str,
    lowpass_order: int,
    direct: bool,
    full_scale: Optional[float],
    board: Optional[str],
    fixed_form: str,
) -> List[str]:
    """The compensator's flags, as :func:`fit` and :meth:`Model.invert` share them (``signal``
    one path or a sequence of paths)."""
    flags: List[str] = []
    _flag(flags, "bandwidth", bandwidth)
    _flag(flags, "max-latency", max_latency)
    _flag(flags, "max-band", max_band)
    for path in [signal] if isinstance(signal, (str, os.PathLike)) else signal:
        flags += ["--signal", os.fspath(path)]
    flags += ["--lowpass", str(lowpass), "--lowpass-order", str(lowpass_order)]
    _flag(flags, "direct", direct)
    _flag(flags, "full-scale", full_scale)
    _flag(flags, "board", board)
    flags += ["--fixed-form", str(fixed_form)]
    return flags


def _warn(messages: Iterable[str]) -> None:
    for m in messages:
        warnings.warn(m, RuntimeWarning, stacklevel=3)


def read_csv(
    path: PathLike,
    *,
    t: str = "t",
    u: str = "u",
    y: str = "y",
    fs: Optional[float] = None,
    delimiter: str = ",",
    decimal_comma: bool = False,
) -> Recording:
    """Read a recording from a CSV file, as the command line reads it.

    Parameters
    ----------
    path : str or os.PathLike
        The CSV file (a step test, or a run recorded by the probe alone).
    t, u, y : str
        The names of the time, reference and probe columns (the CLI's ``--t``, ``--u``, ``--y``).
    fs : float, optional
        The sample rate in Hz, for a file without a time column.
    delimiter : str
        The field separator (one character, or ``"tab"``).
    decimal_comma : bool
        Numbers written with a decimal comma (``1,5``).

    Returns
    -------
    Recording
        ``(u, y, fs)``: float64 arrays (``u`` is None without a reference column) and the
        sample rate in Hz.
    """
    flags = ["--t", t, "--u", u, "--y", y, "--delimiter", delimiter]
    _flag(flags, "fs", fs)
    _flag(flags, "decimal-comma", decimal_comma)
    ref, probe, rate, _sha = _unlag.read_csv(os.fspath(path), flags)
    return Recording(ref, probe, rate)


def fit(
    u: Any,
    y: Any,
    fs: float,
    *,
    order: Union[int, str] = "auto",
    max_order: int = 6,
    method: str = "bj",
    delay: Optional[int] = None,
    validation: Sequence[Any] = (),
    also: Sequence[Any] = (),
    add: Sequence[str] = (),
    model: Optional["Model"] = None,
    fresh: bool = False,
    bandwidth: Union[None, float, str] = None,
    max_latency: Union[None, int, str] = None,
    max_band: Optional[float] = None,
    signal: Union[PathLike, Sequence[PathLike]] = (),
    lowpass: str = "bessel",
    lowpass_order: int = 4,
    direct: bool = False,
    full_scale: Optional[float] = None,
    board: Optional[str] = None,
    fixed_form: str = "normal",
) -> "Model":
    """Fit a probe's model to a step test and design its compensator (``unlag fit``).

    Parameters
    ----------
    u, y : array_like
        The reference pressure and the probe output of the estimation step test (1-D, as long
        as each other).
    fs : float
        The sample rate in Hz.
    order : int or "auto"
        The model order, or ``"auto"`` to choose it (up to ``max_order``).
    max_order : int
        The largest order ``order="auto"`` tries.
    method : {"bj", "oe", "sm", "arx"}
        Box-Jenkins (default), output error, Steiglitz-McBride, or the paper's least squares.
    delay : int, optional
        A known delay in samples (skips the delay search).
    validation : sequence of (u, y) or (u, y, fs)
        Held-out step tests: the order is chosen and the compensator judged on them.
    also : sequence of (u, y) or (u, y, fs)
        Other estimation tests fitted together with the first.
    add : sequence of str
        Physical effects to add (the CLI's ``--add``): ``"mode"``, ``"leak"``, ``"offset"``,
        ``"drift"``, ``"coloured-noise"``, ``"nonlinear-damping"``, ``"delay"``,
        ``"sensor-resonance"``, ``"temperature"``, ... (see :func:`diagnose`).
    model : Model, optional
        The model this fit continues (the modelling loop): its effects and history carry over,
        as when ``unlag fit -o`` names an existing model file.
    fresh : bool
        With ``model``, start afresh: only its probe geometry is kept.
    bandwidth : float or "auto", optional
        Instead of the noise-aware optimum, a stable inverse times a low-pass at this corner
        (Hz), or ``"auto"`` for the corner that reconstructs the tests best.
    max_latency : int or str, optional
        The longest latency the optimum may take: samples, or ``"3ms"``, ``"250us"``.
    max_band : float, optional
        The largest -3 dB band (Hz) the optimum may take.
    signal : path or sequence of paths
        CSV runs of the kind the board will compensate (the prior is learnt from them).
    lowpass : {"bessel", "butterworth"}
        The band limit's low-pass family; ``lowpass_order`` its order.
    direct : bool
        The paper's direct inverse A/B instead of the stable one.
    full_scale : float, optional
        The ADC's range in the probe's units (the fixed-point plan is made for it).
    board : {"f32", "fixed"}, optional
        The board's arithmetic, stored in the model (the default of :meth:`Model.compensate`).
    fixed_form : {"normal", "direct"}
        The fixed-point form.

    Returns
    -------
    Model
        The fitted model with its compensator. A compensator that cannot be designed is a
        ``RuntimeWarning`` (the model stands on its own).

    Raises
    ------
    InvalidArgumentError
        An argument out of range, or arrays that are not 1-D finite numbers of equal length.
    DataError
        A test without a step, or tests at different sample rates.
    """
    u, y = _vector(u, "u"), _vector(y, "y")
    if u.shape != y.shape:
        raise InvalidArgumentError(
            f"u and y must be as long as each other, got {u.size} and {y.size} samples",
            "invalid-argument",
        )
    try:
        fs = float(fs)
    except (TypeError, ValueError):
        raise InvalidArgumentError(f"fs must be a number of Hz, got {fs!r}", "invalid-argument") from None
    extra = [(_pair(t, f"also[{k}]"), f"also[{k}]") for k, t in enumerate(also)]
    held = [(_pair(t, f"validation[{k}]"), f"validation[{k}]") for k, t in enumerate(validation)]
    tests = [("estimation test", u, y)]
    rates = [fs]
    for (tu, ty, tfs), name in extra + held:
        tests.append((name, tu, ty))
        rates.append(fs if tfs is None else tfs)
    if isinstance(add, str):
        add = [add]
    flags = ["--order", str(order), "--max-order", str(max_order), "--method", str(method)]
    _flag(flags, "delay", delay)
    for a in add:
        flags += ["--add", str(a)]
    flags += _compensator_flags(
        bandwidth, max_latency, max_band, signal, lowpass, lowpass_order, direct, full_scale, board, fixed_form
    )
    native, warns = _unlag.fit(
        tests,
        1 + len(extra),
        rates,
        flags,
        None if model is None else model._native,
        bool(fresh),
    )
    _warn(warns)
    return Model(native)


def load(path: PathLike) -> "Model":
    """Load a model file (TOML) written by ``unlag fit`` or :meth:`Model.save`."""
    return Model(_unlag.load(os.fspath(path)))


def loads(text: str, name: str = "model") -> "Model":
    """A model from the text of a model file (``name`` is what messages call it)."""
    return Model(_unlag.loads(text, name))


class Model:
    """A probe's model, its effects and its compensator: the content of a model file.

    Made by :func:`fit`, :func:`load` or :func:`loads`.
    """

    def __init__(self, native: Any) -> None:
        self._native = native
        self._json: Optional[Dict[str, Any]] = None

    def _dict(self) -> Dict[str, Any]:
        if self._json is None:
            self._json = json.loads(self._native.to_json())
        return self._json

    @property
    def fs(self) -> float:
        """The sample rate in Hz."""
        return float(self._dict()["fs"])

    @property
    def delay(self) -> int:
        """The delay in samples."""
        return int(self._dict()["delay"])

    @property
    def a(self) -> np.ndarray:
        """The denominator ``A(q) = 1 + a1 q^-1 + ...`` without its leading 1."""
        return np.asarray(self._dict()["a"], dtype=np.float64)

    @property
    def b(self) -> np.ndarray:
        """The numerator ``B(q) = b0 + b1 q^-1 + ...`` (after the delay)."""
        return np.asarray(self._dict()["b"], dtype=np.float64)

    @property
    def order(self) -> int:
        """The model order (the length of ``a``)."""
        return len(self._dict()["a"])

    @property
    def effects(self) -> List[Dict[str, Any]]:
        """The model's physical effects, as the model file stores them."""
        return list(self._dict().get("effects", []))

    @property
    def latency(self) -> Optional[float]:
        """The compensator's latency behind the true pressure in samples (None without one)."""
        inv = self._dict().get("inverse")
        return None if inv is None else float(inv["latency_samples"])

    def to_dict(self) -> Dict[str, Any]:
        """The model file as a dict (as ``unlag fit --json`` writes it)."""
        return json.loads(self._native.to_json())

    def to_toml(self) -> str:
        """The model file's text (TOML)."""
        return self._native.to_toml()

    def save(self, path: PathLike) -> None:
        """Write the model file (TOML), as ``unlag fit -o`` does: the command line reads it."""
        self._native.save(os.fspath(path))

    def __reduce__(self) -> Tuple[Any, Tuple[str]]:
        """Pickled (and copied) as the text of its model file, which :func:`loads` reads back:
        a model sent to another process (``multiprocessing``, ``concurrent.futures``) is the
        same model, its compensator included."""
        return (loads, (self.to_toml(),))

    def compensate(
        self,
        y: Any,
        arithmetic: Optional[str] = None,
        *,
        direct: bool = False,
        offline: bool = False,
        adapt_to_run: bool = False,
        temperature: Optional[float] = None,
    ) -> np.ndarray:
        """Compensate a probe signal: the pressure ``u_hat`` as the board computes it
        (``unlag compensate``).

        Parameters
        ----------
        y : array_like
            The probe output, sampled at :attr:`fs`.
        arithmetic : {"f32", "f64", "fixed"}, optional
            32-bit float (a Cortex-M4F), 64-bit float, or 32-bit fixed point bit for bit as a
            board without an FPU. Default: the board's, stored in the model (f32 unless
            fitted with ``board="fixed"``).
        direct : bool
            The paper's direct inverse (eq. 7) even when the model has a compensator.
        offline : bool
            Host only: the non-causal optimum on the whole record (no latency).
        adapt_to_run : bool
            Host only: a design predicted better for this run when the stored one is not.
        temperature : float, optional
            The gas temperature (K) for a model with a temperature effect.

        Returns
        -------
        numpy.ndarray
            ``u_hat``, one sample per sample of ``y``; it lags the pressure by
            :attr:`latency` samples.
        """
        u_hat, _error = self._compensate(y, None, arithmetic, direct, offline, adapt_to_run, temperature)
        return u_hat

    def reference_error(
        self,
        u: Any,
        y: Any,
        arithmetic: Optional[str] = None,
        *,
        direct: bool = False,
        offline: bool = False,
        adapt_to_run: bool = False,
        temperature: Optional[float] = None,
    ) -> Optional["ReferenceError"]:
        """The error of :meth:`compensate`'s ``u_hat`` against a recorded reference ``u``,
        beside the raw probe's, as ``unlag compensate`` reports it for a file with a reference
        column (its ``nrmse_u_hat``, ``nrmse_raw`` and ``alignment_samples``).

        Parameters
        ----------
        u : array_like
            The recorded reference pressure, one sample per sample of ``y``.
        y : array_like
            The probe output, sampled at :attr:`fs`.
        arithmetic, direct, offline, adapt_to_run, temperature
            As for :meth:`compensate`.

        Returns
        -------
        ReferenceError or None
            Each RMS error over the reference's range at its own best alignment, or None (with
            a ``RuntimeWarning``) when the reference does not move above its noise.
        """
        u = _vector(u, "u")
        if u.size != np.size(y):
            raise InvalidArgumentError(
                f"u and y must have the same length, got {u.size} and {np.size(y)}", "invalid-argument"
            )
        _u_hat, error = self._compensate(y, u, arithmetic, direct, offline, adapt_to_run, temperature)
        return None if error is None else ReferenceError(*error)

    def _compensate(
        self,
        y: Any,
        reference: Optional[np.ndarray],
        arithmetic: Optional[str],
        direct: bool,
        offline: bool,
        adapt_to_run: bool,
        temperature: Optional[float],
    ) -> Tuple[np.ndarray, Optional[Tuple[float, float, int]]]:
        """:meth:`compensate`, and the error against ``reference`` when one is given."""
        y = _vector(y, "y")
        if sum(map(bool, (direct, offline, adapt_to_run))) > 1:
            raise InvalidArgumentError(
                "give at most one of direct, offline and adapt_to_run", "invalid-argument"
            )
        if (offline or adapt_to_run) and arithmetic is not None:
            raise InvalidArgumentError(
                "offline and adapt_to_run run in f64 on the host: give no arithmetic",
                "invalid-argument",
            )
        how = "direct" if direct else "offline" if offline else "adapt" if adapt_to_run else "designed"
        u_hat, _latency, warns, error = self._native.compensate(y, arithmetic, how, temperature, reference)
        _warn(warns)
        return u_hat, error

    def simulate(self, u: Any, y: Any = None, *, temperature: Optional[float] = None) -> np.ndarray:
        """The probe's output for the reference ``u`` (``unlag simulate``): the model's
        dynamics and effects. With the recorded probe ``y``, the effects that are the
        recording's own (an offset, a drift) are estimated on it."""
        u = _vector(u, "u")
        if y is not None:
            y = _vector(y, "y")
            if y.shape != u.shape:
                raise InvalidArgumentError(
                    f"u and y must be as long as each other, got {u.size} and {y.size} samples",
                    "invalid-argument",
                )
        y_model, _nrmse = self._native.simulate(u, y, temperature)
        return y_model

    def inspect(self) -> Dict[str, Any]:
        """What the model says about the probe (``unlag inspect``).

        Returns a dict with ``poles`` and ``zeros`` (complex arrays, largest magnitude first),
        ``resonances`` (a list of ``{"frequency_hz", "damping"}``), ``dc_gain``,
        ``delay_samples``, ``delay_s``, ``latency_samples`` and ``latency_s`` (the
        compensator's, None without one), ``stable`` and ``stability`` (None, or why the model
        cannot be used), ``minimum_phase``, ``modes``, ``continuous`` (the continuous-time
        equivalent, None when it has none) and ``analysis`` (everything ``unlag inspect
        --json`` says).
        """
        text, unstable = self._native.inspect([])
        v = json.loads(text)
        a = v["analysis"]
        roots = lambda rs: np.array([complex(r["re"], r["im"]) for r in rs], dtype=np.complex128)
        latency = self.latency
        return {
            "poles": roots(a["poles"]),
            "zeros": roots(a["zeros"]),
            "resonances": [{"frequency_hz": f, "damping": d} for f, d in v["resonances"]],
            "dc_gain": a["dc_gain"],
            "delay_samples": a["delay_samples"],
            "delay_s": a["delay_s"],
            "latency_samples": latency,
            "latency_s": None if latency is None else latency / self.fs,
            "stable": a["stable"],
            "stability": unstable,
            "minimum_phase": a["minimum_phase"],
            "modes": a["modes"],
            "continuous": v["continuous"],
            "analysis": a,
        }

    def frequency_response(self, f: Any = None) -> Tuple[np.ndarray, np.ndarray]:
        """The model's frequency response, delay included (as ``scipy.signal.freqz``).

        Parameters
        ----------
        f : array_like, optional
            Frequencies in Hz. Default: ``unlag inspect``'s grid (0 Hz, then four points a
            decade from fs/1000 to fs/2).

        Returns
        -------
        f : numpy.ndarray
            The frequencies (Hz).
        h : numpy.ndarray
            The complex response at each.
        """
        f = self._native.default_frequencies() if f is None else _vector(f, "f")
        magnitude, phase = self._native.response(f)
        return f, magnitude * np.exp(1j * phase)

    def invert(
        self,
        tests: Sequence[Any] = (),
        *,
        names: Optional[Sequence[str]] = None,
        bandwidth: Union[None, float, str] = None,
        max_latency: Union[None, int, str] = None,
        max_band: Optional[float] = None,
        signal: Union[PathLike, Sequence[PathLike]] = (),
        lowpass: str = "bessel",
        lowpass_order: int = 4,
        direct: bool = False,
        full_scale: Optional[float] = None,
        unit: Optional[str] = None,
        board: Optional[str] = None,
        fixed_form: str = "normal",
    ) -> "Model":
        """The model with its compensator designed anew (``unlag invert``).

        The model, its effects and its history are kept; the compensator is replaced. The
        options are :func:`fit`'s compensator options.

        Parameters
        ----------
        tests : sequence of (u, y) or (u, y, fs)
            Step tests at the model's rate, to choose the bandwidth on and to judge the
            compensator on (the CLI's ``TEST.csv`` files).
        names : sequence of str, optional
            What the model file's report calls each test (default ``tests[0]``, ...; the
            command line names them by their paths).
        bandwidth : float or "auto", optional
            Instead of the noise-aware optimum, a stable inverse times a low-pass at this corner
            (Hz), or ``"auto"`` for the corner that reconstructs the tests best.
        max_latency : int or str, optional
            The longest latency the optimum may take: samples, or ``"3ms"``, ``"250us"``.
        max_band : float, optional
            The largest -3 dB band (Hz) the optimum may take.
        signal : path or sequence of paths
            CSV runs of the kind the board will compensate (the prior is learnt from them).
        lowpass : {"bessel", "butterworth"}
            The band limit's low-pass family; ``lowpass_order`` its order.
        direct : bool
            The paper's direct inverse A/B instead of the stable one.
        full_scale : float, optional
            The ADC's range in the probe's units (the fixed-point plan is made for it).
        unit : str, optional
            The probe's pressure unit (``"Pa"``, ``"kPa"``, ``"mbar"``, ...), stored in the
            model.
        board : {"f32", "fixed"}, optional
            The board's arithmetic, stored in the model. Default: the model's.
        fixed_form : {"normal", "direct"}
            The fixed-point form.

        Returns
        -------
        Model
            A new model (this one is unchanged). A fixed-point plan that cannot be made is a
            ``RuntimeWarning`` (the f32 compensator stands).

        Raises
        ------
        InvalidArgumentError
            An option out of range (the command line's message), or arrays that are not 1-D
            finite numbers of equal length.
        DataError
            A test without a step, or at another rate than the model's.
        Error
            No compensator can be designed for the model (an :class:`UnstableError` for a
            direct inverse of a non-minimum-phase model).
        """
        named, rates = [], []
        if names is not None and len(names) != len(tests):
            raise InvalidArgumentError(
                f"give one name a test: {len(names)} names for {len(tests)} tests",
                "invalid-argument",
            )
        for k, t in enumerate(tests):
            name = f"tests[{k}]" if names is None else str(names[k])
            u, y, fs = _pair(t, name)
            named.append((name, u, y))
            rates.append(self.fs if fs is None else fs)
        flags = _compensator_flags(
            bandwidth, max_latency, max_band, signal, lowpass, lowpass_order, direct, full_scale, board, fixed_form
        )
        _flag(flags, "unit", unit)
        native, warns = self._native.invert(named, rates, flags)
        _warn(warns)
        return Model(native)

    def resample(self, fs: float) -> "Model":
        """The model at another sample rate (``unlag resample``).

        The model is re-discretised step invariant through its continuous-time equivalent, the
        delay included; its effects, fit report and history are kept.

        Parameters
        ----------
        fs : float
            The new sample rate in Hz.

        Returns
        -------
        Model
            A new model, without a compensator (the old one's coefficients belong to the old
            rate): design one with :meth:`invert`. What the new rate cannot hold (a resonance
            above its Nyquist frequency) is a ``RuntimeWarning``.

        Raises
        ------
        InvalidArgumentError
            ``fs`` not a sample rate (the command line's message).
        ModelFileError
            A model without a continuous-time equivalent (the pole named).
        """
        native, warns = self._native.resample(_text(fs))
        _warn(warns)
        return Model(native)

    def export(
        self,
        format: str = "c",
        *,
        number_format: Optional[str] = None,
        full_scale: Optional[float] = None,
        fixed_form: Optional[str] = None,
        temperature: Optional[float] = None,
        temperatures: Optional[str] = None,
        force: bool = False,
    ) -> Union[str, bytes]:
        """The board's coefficients (``unlag export``).

        Parameters
        ----------
        format : {"c", "rust", "bin"}
            A C header, a Rust module, or the binary blob a board loads.
        number_format : {"f32", "fixed"}, optional
            Default: the board's arithmetic stored in the model.
        full_scale, fixed_form :
            For fixed point: the ADC's range, and ``"normal"`` or ``"direct"``.
        temperature : float, optional
            The set at one gas temperature (K); ``temperatures="FROM:TO:STEP"`` a bank.
        force : bool
            Export a compensator whose check found it no better than the raw probe.

        Returns
        -------
        str or bytes
            The text of the header or module, or the blob's bytes.
        """
        flags = ["--format", str(format)]
        _flag(flags, "number-format", number_format)
        _flag(flags, "full-scale", full_scale)
        _flag(flags, "fixed-form", fixed_form)
        _flag(flags, "temperature", temperature)
        _flag(flags, "temperatures", temperatures)
        _flag(flags, "force", force)
        data = self._native.export(flags)
        return data if format == "bin" else data.decode("utf-8")

    def __repr__(self) -> str:
        m = self._dict()
        lat = self.latency
        comp = "no compensator" if lat is None else f"compensator latency {lat:.2f} samples"
        return f"<unlag.Model order {len(m['a'])}, delay {m['delay']} samples, fs {m['fs']} Hz, {comp}>"


@dataclass
class Candidate:
    """A missing effect :func:`diagnose` proposes, best first."""

    kind: str
    """What it names: the effect as ``fit(add=[...])`` takes it (``"leak"``, ``"mode"``, ...),
    or ``"none"`` or ``"unexplained"``."""
    score: float
    """``ln(error before / error after)`` of its trial refit, less a penalty per parameter."""
    margin: float
    """How far ahead of the next candidate it is (score difference)."""
    reading: str
    """What it means physically."""
    change: str
    """The change that adds it, as the command line words it (``unlag fit ... --add leak``)."""
    nrmse_before: float
    """The held-out error before the trial."""
    nrmse_after: float
    """The held-out error after it."""
    details: Dict[str, Any] = field(default_factory=dict, repr=False)
    """Everything ``unlag diagnose --json`` says of it."""


def _loop_tests(model: Model, tests: Sequence[Any]) -> Tuple[list, list]:
    if not isinstance(model, Model):
        raise InvalidArgumentError("model must be an unlag.Model", "invalid-argument")
    if len(tests) == 0:
        raise InvalidArgumentError("give at least one step test", "invalid-argument")
    named, rates = [], []
    for k, t in enumerate(tests):
        u, y, fs = _pair(t, f"tests[{k}]")
        named.append((f"tests[{k}]", u, y))
        rates.append(model.fs if fs is None else fs)
    return named, rates


def diagnose(model: Model, tests: Sequence[Any]) -> List[Candidate]:
    """Rank the missing physics of ``model`` on its step tests (``unlag diagnose``).

    Parameters
    ----------
    model : Model
    tests : sequence of (u, y) or (u, y, fs)
        The step tests, the estimation test first (the trial refits are fitted on it), the
        held-out ones after.

    Returns
    -------
    list of Candidate
        Best first. Add the first one's ``kind`` with ``fit(..., add=[kind], model=model)``
        and watch the held-out error fall.
    """
    named, rates = _loop_tests(model, tests)
    candidates, _tests = _unlag.diagnose(model._native, named, rates)
    return [
        Candidate(
            kind=str(c["kind"]),
            score=float(c["score"]),
            margin=float(c["margin"]),
            reading=str(c["reading"]),
            change=str(c["change"]),
            nrmse_before=float(c["nrmse_before"]),
            nrmse_after=float(c["nrmse_after"]),
            details=c,
        )
        for c in json.loads(candidates)
    ]


def compare(model: Model, tests: Sequence[Any]) -> Dict[str, Any]:
    """The model against each step test, and the residual evidence (``unlag compare``).

    Returns a dict (as ``unlag compare --json``): ``tests`` (the evidence per test: errors,
    noise floor, residual spectra and correlations), ``across_tests`` (the structure fitted to
    each test alone), ``amplitude_signature`` and ``history`` (the modelling loop's fits).
    """
    named, rates = _loop_tests(model, tests)
    return json.loads(_unlag.compare(model._native, named, rates))


def simulate_test(fs: float, excitation: str, *, volume: float, **options: Any) -> SimulatedTest:
    """A step test of a physical probe, simulated (``unlag simulate-test``).

    The keyword arguments are the command line's flags: ``name=value`` is ``--name value``
    (``_`` for ``-``), ``True`` a bare flag, a pair ``(a, b)`` the CLI's ``A,B`` and a list of
    pairs a repeated flag. The same arguments give the same samples as the CSV file the
    command line writes.

    Parameters
    ----------
    fs : float
        The acquisition's sample rate in Hz.
    excitation : {"shock", "balloon", "valve", "wake"}
        The facility.
    volume : float
        The volume at the closed end (transducer volume or sensor cavity) in m^3.
    **options
        The probe (lengths and diameters in m, temperature in K, pressures in Pa):
        ``line=[(L, D), ...]`` the tubes in series from the measuring point on,
        ``hole=(L, D)`` a recessed hole, ``hole_end``, ``temperature``, ``pressure``,
        ``sigma``, ``cavity_k``, ``cavity_radius``, ``leak``, ``minor_loss``, ``amplitude``
        (the step in Pa), ``diaphragm=(FN, ZETA)``. The test: ``duration`` (s),
        ``event_at`` (s), ``rise`` (s), ``chamber=(HZ, FRACTION)``, ``wake_hz``,
        ``wake_width``, ``tunnel_hz``, ``tunnel_amplitude``, ``noise`` and
        ``reference_noise`` (Pa), ``adc_bits``, ``adc_range=(MIN, MAX)``, ``skew`` (s),
        ``reference_sensor=(FN, ZETA)``, ``anti_alias=(HZ, ORDER)``, ``oversample``,
        ``seed``, ``gain_error``, ``hum=(PA, HZ)``, ``drift`` (Pa/s). ``unlag simulate-test
        --help`` says each.

    Returns
    -------
    SimulatedTest
        ``(t, u, y)``: float64 arrays of the sample times (s), the reference and the probe
        (Pa). ``unlag.fit(u, y, fs)`` fits them. Where the simulation fell short of what was
        asked (a reduced internal rate, a resonance above the simulated band) is a
        ``RuntimeWarning``.

    Raises
    ------
    InvalidArgumentError
        A flag unknown or out of range (the command line's message).
    """
    flags = _options({"fs": fs, "excitation": excitation, "volume": volume, **options})
    t, u, y, notes = _unlag.simulate_test(flags)
    _warn(notes)
    return SimulatedTest(t, u, y)


def predict(*, volume: float, model: Union[None, Model, PathLike] = None, **options: Any) -> Dict[str, Any]:
    """What a physical probe's geometry predicts (``unlag predict --json``): its exact first
    modes, front delay, lumped approximation and DC gain, compared with a fitted model when
    given.

    Parameters
    ----------
    volume : float
        The volume at the closed end in m^3.
    model : Model or path, optional
        A fitted model to compare the prediction with (the CLI's ``--model``).
    **options
        The probe, as :func:`simulate_test` takes it (``line=[(L, D), ...]``, ``hole=(L, D)``,
        ``temperature``, ``diaphragm=(FN, ZETA)``, ...), and ``modes``, the number of exact
        modes to report (default 3).

    Returns
    -------
    dict
        The object ``unlag predict --json`` prints: ``modes`` (each ``natural_frequency_hz``,
        ``damping``, ``damped_frequency_hz``, ``overdamped``), ``real_poles_rad_s``,
        ``delay_s``, ``lumped``, ``dc_gain``, ``gas``, ``helmholtz``, ``diaphragm``,
        ``minor_loss_resistance_pa_s_per_m3``, and with a model ``comparison``.

    Raises
    ------
    InvalidArgumentError
        A flag unknown or out of range (the command line's message).
    """
    if model is not None and not isinstance(model, Model):
        model = load(model)
    flags = _options({"volume": volume, **options})
    return json.loads(_unlag.predict(flags, None if model is None else model._native))
