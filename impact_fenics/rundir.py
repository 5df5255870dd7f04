"""The output directory of a run: what may be written, replaced or removed, and the lock.

The rule. A run writes only into ``DIR.partial``, its staging directory, which it
creates with one atomic ``mkdir``: that directory is the lock, and its lock file
names the run (pid, host, start time). When the run ends the staging directory
becomes DIR. An existing DIR is replaced only if it is a run directory (it
carries the marker file written into every staging directory, or it is empty);
anything else is refused before the run, and nothing outside the run's own
directories is ever removed. A replaced run is first renamed aside, the new one
moved in, and only then the old one deleted, so an interruption leaves the old
run or the new one, never neither. A lock left by a run that died (its pid no
longer exists on this host) is taken over, with a warning.

Only rank 0 touches the file system; errors reach every rank (InputError).
"""
from __future__ import annotations

import json
import os
import re
import shutil
import socket
import sys
import time

from mpi4py import MPI

from .errors import InputError

# A run directory carries MARKER (written first into the staging directory, kept);
# the staging directory DIR.partial carries LOCK while a run owns it.
MARKER = ".impact_fenics_run"
LOCK = ".impact_fenics_lock"
# what a run directory written before the marker existed may hold (and nothing else)
_LEGACY_FILES = re.compile(r"^(summary\.json|fields\.(xdmf|h5)|history\.csv|energy\.csv|"
                           r"contact_pairs(_\d+)?\.csv|[\w.+-]+\.png)$")


def is_run_directory(path: str) -> bool:
    """True if ``path`` is a directory this package may replace: it carries the run
    marker, is empty, or (an older run) holds summary.json and only run files."""
    if not os.path.isdir(path) or os.path.islink(path):
        return False
    names = os.listdir(path)
    if MARKER in names or not names:
        return True
    return "summary.json" in names and all(
        _LEGACY_FILES.match(n) and os.path.isfile(os.path.join(path, n)) for n in names)


def _read_lock(staging: str) -> dict | None:
    try:
        with open(os.path.join(staging, LOCK)) as f:
            lock = json.load(f)
        return lock if isinstance(lock, dict) else None
    except (OSError, ValueError):
        return None


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _lock_owner(lock: dict) -> str:
    return (f"pid {lock.get('pid')} on {lock.get('host')}, started {lock.get('started')}")


def _lock_is_stale(lock: dict) -> bool:
    """A lock taken on this host by a process that no longer exists."""
    pid = lock.get("pid")
    return (lock.get("host") == socket.gethostname() and isinstance(pid, int)
            and not _pid_alive(pid))


def directory_problem(path: str) -> str | None:
    """Why a run may not write to ``path`` (rank-local, changes nothing), or None.

    The rule: a run writes only into ``path.partial`` (its staging directory, created
    atomically: the lock) and replaces ``path`` only if that is a run directory
    (:func:`is_run_directory`). Anything else is refused."""
    if not path or not path.strip():
        return "the output directory name is empty"
    full = os.path.abspath(path)
    staging = full + ".partial"
    here = os.path.abspath(os.getcwd())
    if full == here or here.startswith(full.rstrip(os.sep) + os.sep):
        return f"'{full}' is the working directory or one of its parents"
    if os.path.lexists(full) and not os.path.isdir(full):
        return f"'{full}' exists and is not a directory"
    if os.path.isdir(full) and not is_run_directory(full):
        return (f"'{full}' exists and is not a run directory (it has no {MARKER}): a run "
                "never replaces it; choose a new directory")
    if os.path.lexists(staging):
        lock = _read_lock(staging) if os.path.isdir(staging) else None
        if lock is None:
            return (f"'{staging}' exists and is not the staging directory of a run (no "
                    f"{LOCK}): remove or rename it")
        if not _lock_is_stale(lock):
            return f"another run is writing it ({_lock_owner(lock)}; lock {staging})"
    parent = os.path.dirname(full)
    while not os.path.exists(parent):
        parent = os.path.dirname(parent)
    if not os.path.isdir(parent):
        return f"'{parent}' is a file, not a directory"
    if not os.access(parent, os.W_OK | os.X_OK):
        return f"no permission to write in '{parent}'"
    return None


def _version() -> str:
    try:
        from importlib.metadata import version

        return version("impact_fenics")
    except Exception:  # not installed as a distribution
        return "unknown"


def _take_lock(staging: str) -> str | None:
    """Create ``staging`` atomically (the lock); take over a dead run's. Returns a note."""
    note = None
    os.makedirs(os.path.dirname(staging), exist_ok=True)
    for _ in range(3):
        try:
            os.mkdir(staging)
            return note
        except FileExistsError:
            lock = _read_lock(staging)
            if lock is None or not _lock_is_stale(lock):
                raise
            aside = _unused(staging + f".stale-{os.getpid()}")
            os.rename(staging, aside)  # atomic: of two runs taking over, one wins
            shutil.rmtree(aside)       # a dead run's staging directory: ours to remove
            note = (f"warning: took over the output of a run that died ({_lock_owner(lock)}); "
                    "its partial files were removed")
    os.mkdir(staging)
    return note


def _unused(path: str) -> str:
    k, candidate = 0, path
    while os.path.lexists(candidate):
        k += 1
        candidate = f"{path}.{k}"
    return candidate


def prepare_directory(path: str, comm: MPI.Comm) -> str:
    """Create the staging directory ``path.partial``, lock it and return it.

    Refused (InputError on every rank, nothing changed) when :func:`directory_problem`
    objects, when another run holds the lock, or when the location cannot be written."""
    full = os.path.abspath(path)
    staging = full + ".partial"
    error = note = None
    if comm.rank == 0:
        error = directory_problem(path)
        if error is None:
            try:
                note = _take_lock(staging)
            except FileExistsError:
                error = directory_problem(path) or f"'{staging}' appeared meanwhile"
            except OSError as exc:
                error = f"cannot be written: {exc.strerror or exc}"
        if error is None:
            try:
                started = time.strftime("%Y-%m-%dT%H:%M:%S%z")
                with open(os.path.join(staging, LOCK), "w") as f:
                    json.dump({"pid": os.getpid(), "host": socket.gethostname(),
                               "started": started, "ranks": comm.size}, f)
                with open(os.path.join(staging, MARKER), "w") as f:
                    f.write(f"impact_fenics {_version()} run directory, started {started}\n")
            except OSError as exc:
                shutil.rmtree(staging, ignore_errors=True)
                error = f"cannot be written: {exc.strerror or exc}"
        if note:
            print(note, file=sys.stderr, flush=True)
    error = comm.bcast(error, root=0)
    if error:
        raise InputError(f"output directory '{path}': {error}")
    return staging


def abandon_directory(staging: str, comm: MPI.Comm) -> None:
    """Remove a staging directory this run created (set-up failed before any result)."""
    comm.barrier()
    if comm.rank == 0 and os.path.isfile(os.path.join(staging, LOCK)):
        shutil.rmtree(staging, ignore_errors=True)
    comm.barrier()


def finalize_directory(staging: str, path: str, comm: MPI.Comm) -> str:
    """Publish the finished staging directory as ``path`` and return where it went.

    An older run in ``path`` is renamed aside, the new one moved in, then the old one
    deleted: an interruption at any point leaves the old or the new run (or both).
    A ``path`` that is no run directory (created meanwhile) is never touched: the
    run then goes to ``path-<time>`` and a warning says so."""
    comm.barrier()
    where = error = None
    if comm.rank == 0:
        try:
            where = _publish(staging, os.path.abspath(path))
        except OSError as exc:
            error = (f"the finished run could not be moved to '{path}': {exc.strerror or exc}; "
                     f"its files are in '{staging}'")
    where, error = comm.bcast((where, error), root=0)
    if error:
        raise InputError(error)
    return where


def _publish(staging: str, final: str) -> str:
    os.remove(os.path.join(staging, LOCK))
    aside = None
    if os.path.lexists(final) and not is_run_directory(final):
        moved = _unused(final + time.strftime("-%Y%m%d-%H%M%S"))
        print(f"warning: '{final}' appeared during the run and is not a run directory; "
              f"the run is in '{moved}'", file=sys.stderr, flush=True)
        final = moved
    elif os.path.lexists(final):
        aside = _unused(final + f".old-{os.getpid()}")
        os.rename(final, aside)
    os.rename(staging, final)
    if aside is not None:
        shutil.rmtree(aside)  # the old run: a run directory, renamed aside above
    return final
