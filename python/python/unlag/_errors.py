"""The exceptions unlag raises: one base class, :class:`Error`, and a subclass per kind of
problem. Each message is the one the ``unlag`` command line prints for the same problem."""


class Error(Exception):
    """Any problem unlag reports. ``kind`` is the command line's ``--json`` error kind
    (``"invalid-argument"``, ``"no-step"``, ``"model"``, ...)."""

    def __init__(self, message: str, kind: str = "error") -> None:
        super().__init__(message)
        self.message = message
        self.kind = kind


class InvalidArgumentError(Error, ValueError):
    """An argument out of range or of the wrong kind: an order, a bandwidth, an array that is
    not a one-dimensional array of finite numbers."""


class DataError(Error, ValueError):
    """The recording cannot be used: no step in the reference, too short, another sample
    rate than the model's, a CSV file that cannot be read as one."""


class FileError(Error):
    """A file cannot be read or written."""


class ModelFileError(Error):
    """A model file that is not one (or not one this version reads)."""


class UnstableError(Error):
    """An unstable model or compensator (the pole or zero outside the unit circle named)."""


class BoardError(Error):
    """What the board cannot run (fixed point with nonlinear damping, a coefficient blob
    refused)."""
