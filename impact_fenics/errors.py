"""Errors a user can act on, and the one-line exit that reports them.

Input checks are collective: every rank sees the same data (or reduces it) and
raises the same :class:`InputError`, so every rank can leave with the same exit
code without a hang. Anything unexpected aborts all ranks.
"""
from __future__ import annotations

import errno
import functools
import logging
import os
import re
import sys
from typing import Callable, TypeVar

F = TypeVar("F", bound=Callable)

EXIT_INPUT = 2
EXIT_UNSTABLE = 3
EXIT_OUTPUT = 4

# why a finite-strain body is refused on triangles (the scene reader,
# DeformableModel): one reason, one wording
FINITE_STRAIN_NEEDS_QUADRILATERALS = ("finite strain needs quadrilaterals: constant-strain "
                                      "triangles lock under isochoric plastic flow")


class InputError(ValueError):
    """Bad input: the message names the field and the problem in one line."""


class UnstableRunError(RuntimeError):
    """The run diverged (NaN or energy growth); the message gives step and stable dt."""


class OutputError(OSError):
    """Writing the run's results failed (disk full, I/O error): the message names the file
    and the cause in one line. It may come on one rank only."""


# OSErrors a user acts on as on an OutputError: disk full, quota, I/O error, read-only
# file system, file too large
_OUTPUT_ERRNOS = {errno.ENOSPC, errno.EDQUOT, errno.EIO, errno.EROFS, errno.EFBIG}


def _print_rank0(message: str) -> None:
    from mpi4py import MPI

    sys.stdout.flush()
    if MPI.COMM_WORLD.rank == 0:
        print(message, file=sys.stderr, flush=True)


def _abort_on_unexpected(exc_type, exc, tb) -> None:
    """Excepthook: print the traceback, then take every rank down (never hang)."""
    sys.__excepthook__(exc_type, exc, tb)
    from mpi4py import MPI

    if MPI.COMM_WORLD.size > 1:
        MPI.COMM_WORLD.Abort(1)


def quiet_compiler_logs() -> None:
    """Show warnings only on the console: the form compiler's C builds (setuptools)
    log at INFO through the root logger and lower its level while they run, so
    the console handler itself filters below WARNING."""
    root = logging.getLogger()
    if not root.handlers:
        handler = logging.StreamHandler()
        handler.setFormatter(logging.Formatter("%(levelname)s: %(message)s"))
        root.addHandler(handler)
    for handler in root.handlers:
        if type(handler) is logging.StreamHandler:
            handler.setLevel(logging.WARNING)


def user_errors(func: F) -> F:
    """Decorate a ``main()``: InputError exits 2, UnstableRunError exits 3, OutputError (or
    an OSError of a full disk, an I/O error, ...: _OUTPUT_ERRNOS) 4 (said by the rank that
    met it, every rank stopped) and a signal before the run 128
    + its number, one line each; the form compiler's INFO lines stay off the console.
    SIGINT and SIGTERM are caught from the first line on."""

    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        from . import interrupts

        interrupts.install()
        sys.excepthook = _abort_on_unexpected
        quiet_compiler_logs()
        try:
            return func(*args, **kwargs)
        except InputError as exc:
            _print_rank0(f"error: {exc}")
            raise SystemExit(EXIT_INPUT)
        except UnstableRunError as exc:
            _print_rank0(f"error: {exc}")
            raise SystemExit(EXIT_UNSTABLE)
        except OSError as exc:
            if not (isinstance(exc, OutputError) or exc.errno in _OUTPUT_ERRNOS):
                raise
            _stop_on_output(exc)
            raise SystemExit(EXIT_OUTPUT)
        except interrupts.Interrupted as exc:
            _print_rank0(f"stopped: {exc}")
            raise SystemExit(exc.exit_code)

    return wrapper  # type: ignore[return-value]


def file_system_failure(exc: BaseException) -> str | None:
    """The cause (e.g. 'No space left on device') if ``exc`` is a failed write for a
    reason in _OUTPUT_ERRNOS, also as HDF5 reports it through h5py (its message carries
    'errno = N, error message = ...'); else None."""
    code = getattr(exc, "errno", None)
    if code in _OUTPUT_ERRNOS:
        return os.strerror(code)
    found = re.search(r"errno = (\d+)", str(exc))
    if found and int(found.group(1)) in _OUTPUT_ERRNOS:
        return os.strerror(int(found.group(1)))
    return None


def _stop_on_output(exc: OSError) -> None:
    """Print ``exc``'s line on this rank (the rank that met it); under MPI abort every rank
    with exit 4 (the others may be waiting in a collective call this rank will not make)."""
    from mpi4py import MPI

    sys.stdout.flush()
    print(f"error: {exc}", file=sys.stderr, flush=True)
    if MPI.COMM_WORLD.size > 1:
        MPI.COMM_WORLD.Abort(EXIT_OUTPUT)


def output_failed(exc: OutputError) -> None:
    """Stop on a failed write of the results met on this rank only (a rank-0 file): raise
    ``exc`` on one rank (user_errors says it); under MPI say it and abort every rank."""
    from mpi4py import MPI

    if MPI.COMM_WORLD.size > 1:
        _stop_on_output(exc)
    raise exc


def require(condition: bool, message: str) -> None:
    """Raise :class:`InputError` with ``message`` unless ``condition`` holds."""
    if not condition:
        raise InputError(message)
