"""Exception classes raised by :mod:`foldmatch_rs`.

Every error raised by the Rust core is an instance of :class:`FoldMatchError` and also of
the built-in class a caller would expect (``ValueError`` for bad input or parameters,
``OSError`` for unreadable files, ``RuntimeError`` for numerical or internal failures).
"""

from __future__ import annotations


class FoldMatchError(Exception):
    """Base class of every error raised by foldmatch_rs."""


class InvalidInputError(FoldMatchError, ValueError):
    """An input array is empty, has the wrong shape, holds NaN/Inf, or a face index is out of
    range; or the template lies far from the scan."""


class InvalidParameterError(FoldMatchError, ValueError):
    """A fit parameter is out of range or unknown."""


class MeshFileError(FoldMatchError, OSError):
    """A mesh file could not be opened, read or written."""


class MeshFormatError(FoldMatchError, ValueError):
    """A mesh file was read but is malformed (names the file and line)."""


class NumericalError(FoldMatchError, RuntimeError):
    """The computation diverged (non-finite positions)."""


class FitCancelled(FoldMatchError, RuntimeError):
    """The fit was cancelled."""


class RunSetupError(FoldMatchError, ValueError):
    """A batch or sequence could not start: the template is unreadable, no scan was found, a
    parameter is invalid or the output folder cannot be written (the message says which)."""


class OutOfMemoryError(FoldMatchError, MemoryError):
    """Memory for a size the input announced could not be allocated (the sizes are checked
    against the input and the documented limits first: the machine has less memory than the
    input needs)."""


class InternalError(FoldMatchError, RuntimeError):
    """A bug inside foldmatch_rs (a caught Rust panic). Please report it."""


__all__ = [
    "FoldMatchError",
    "InvalidInputError",
    "InvalidParameterError",
    "MeshFileError",
    "MeshFormatError",
    "NumericalError",
    "FitCancelled",
    "RunSetupError",
    "OutOfMemoryError",
    "InternalError",
]
