"""The output directory of a run: what may be written, replaced or removed, and the lock.

The rule: a run never removes a file it did not write.

* A run writes only into ``DIR.partial``, its staging directory, which it creates with
  one atomic ``mkdir``: that directory is the lock, and its lock file names the run
  (pid, host, start time).
* When the run ends, the marker file of the staging directory gets the run's manifest
  (every file the run wrote, with its size in bytes, and the run's status), and the
  staging directory becomes DIR.
* An existing DIR is replaced only if it is a run directory: empty, or carrying the
  marker with every file in it listed in the manifest at its listed size. A directory
  holding anything else (a user's notes, a post-processing folder, a run file the user
  changed) is refused before the run, in one line that names the first such file.
* A replaced run is renamed aside, the new one moved in, and then only the files of
  the old run's manifest are deleted: an interruption leaves the old run or the new one,
  never neither, and a file that appeared in the meantime is kept.
* A run that did not complete (interrupted, diverged) never replaces a completed run:
  it is published beside it, as ``DIR.interrupted`` or ``DIR.diverged``.
* A lock left by a run that died (its pid no longer exists on this host) is taken over,
  with a warning: the dead run's own files (the names a run writes, :data:`RUN_FILE`)
  are removed; a staging directory that also holds other files is refused, naming one.
* ``~`` in a path is the user's home directory.

Only rank 0 touches the file system; errors reach every rank (InputError).
"""
from __future__ import annotations

import json
import os
import re
import socket
import sys
import time

from mpi4py import MPI

from .errors import InputError

# A run directory carries MARKER (written first into the staging directory; at the end
# it holds the manifest); the staging directory DIR.partial carries LOCK while a run owns it.
MARKER = ".impact_fenics_run"
LOCK = ".impact_fenics_lock"
# every name a run (or ``impact-fenics plot``) writes into its directory: the files a
# dead run may have left in its staging directory, and those of a run directory written
# by a version without the manifest
RUN_FILE = re.compile(r"^(summary\.json|shpb\.csv|shpb_\w+\.png|fields\.xdmf|fields(_p\d+)?\.h5|history\.csv|energy\.csv|"
                      r"contact_pairs(_\d+)?\.h5|history\.png|energy\.png|scene\.\w+|"
                      r"\w+_t\d\.\d{6}e[-+]\d+\.png|\.impact_fenics_run(\.tmp)?|\.impact_fenics_lock)$")
# where a run that did not complete goes when DIR holds a completed run
_BESIDE = {"interrupted": ".interrupted", "diverged": ".diverged"}


def expand(path: str) -> str:
    """The absolute path of ``path``, with ``~`` the user's home directory."""
    return os.path.abspath(os.path.expanduser(path))


def read_marker(path: str) -> dict | None:
    """The marker of directory ``path``: its manifest ("files": name -> bytes, "status"),
    ``{}`` for a marker without one (a run not finished, or an older version's), or None."""
    try:
        with open(os.path.join(path, MARKER)) as f:
            text = f.read()
    except OSError:
        return None
    try:
        marker = json.loads(text)
    except ValueError:
        return {}
    return marker if isinstance(marker, dict) else {}


def _files(path: str) -> list[str]:
    """Every entry below ``path`` that is not a directory (relative, sorted), and every
    empty directory (with a trailing separator)."""
    found = []
    for root, dirs, names in os.walk(path):
        dirs.sort()
        rel = os.path.relpath(root, path)
        for name in sorted(names) + [d for d in dirs if os.path.islink(os.path.join(root, d))]:
            found.append(os.path.normpath(os.path.join(rel, name)))
        if root != path and not names and not dirs:
            found.append(rel + os.sep)
    return sorted(found)


def foreign_file(path: str) -> str | None:
    """The first file in run directory ``path`` that its run did not write, said as
    "'name' (why)", or None. With a manifest: any file not in it, or not at its size.
    Without one (a run not finished, or an older version's): any file whose name is not
    one a run writes (:data:`RUN_FILE`), and anything in a subdirectory."""
    marker = read_marker(path) or {}
    listed = marker.get("files")
    for name in _files(path):
        if name == MARKER:
            continue
        if not isinstance(listed, dict):
            if os.sep in name or not RUN_FILE.match(name):
                return f"'{name}' (no run wrote it)"
        elif name not in listed:
            return f"'{name}' (no run wrote it)"
        elif os.path.getsize(os.path.join(path, name)) != listed[name]:
            return f"'{name}' (changed since its run wrote it)"
    return None


def is_run_directory(path: str) -> bool:
    """True if ``path`` is a directory this package may replace: empty, or carrying the
    run marker and nothing its run did not write (:func:`foreign_file`)."""
    if not os.path.isdir(path) or os.path.islink(path):
        return False
    if not os.listdir(path):
        return True
    return read_marker(path) is not None and foreign_file(path) is None


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
    full = expand(path)
    staging = full + ".partial"
    here = os.path.abspath(os.getcwd())
    if full == here or here.startswith(full.rstrip(os.sep) + os.sep):
        return f"'{full}' is the working directory or one of its parents"
    if os.path.lexists(full) and not os.path.isdir(full):
        return f"'{full}' exists and is not a directory"
    if os.path.isdir(full) and not is_run_directory(full):
        if read_marker(full) is None:
            return (f"'{full}' exists and is not a run directory (it has no {MARKER}): a run "
                    "never replaces it; choose a new directory")
        return (f"'{full}' is a run directory that also holds {foreign_file(full)}: a run "
                "never removes a file it did not write; move that out or choose a new "
                "directory")
    if os.path.lexists(staging):
        lock = _read_lock(staging) if os.path.isdir(staging) else None
        if lock is None:
            return (f"'{staging}' exists and is not the staging directory of a run (no "
                    f"{LOCK}): remove or rename it")
        if not _lock_is_stale(lock):
            return f"another run is writing it ({_lock_owner(lock)}; lock {staging})"
        other = foreign_file(staging)
        if other is not None:
            return (f"'{staging}' was left by a run that died ({_lock_owner(lock)}) and also "
                    f"holds {other}: move that out, and the dead run's files are replaced")
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


def _remove_run(path: str) -> list[str]:
    """Delete the files of run directory ``path`` that its run wrote (its manifest, or
    without one the names a run writes), then the directories left empty. Returns what
    was kept (a file that appeared meanwhile), relative to ``path``."""
    marker = read_marker(path) or {}
    listed = marker.get("files")
    for name in _files(path):
        own = (name in listed) if isinstance(listed, dict) else (
            os.sep not in name and RUN_FILE.match(name) is not None)
        if own or name == MARKER:
            os.remove(os.path.join(path, name))
    for root, _, _ in sorted(os.walk(path), key=lambda w: -len(w[0])):
        try:
            os.rmdir(root)  # only if empty
        except OSError:
            pass
    return _files(path) if os.path.isdir(path) else []


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
            if lock is None or not _lock_is_stale(lock) or foreign_file(staging) is not None:
                raise
            aside = _unused(staging + f".stale-{os.getpid()}")
            os.rename(staging, aside)  # atomic: of two runs taking over, one wins
            kept = _remove_run(aside)   # the dead run's files only
            note = (f"warning: took over the output of a run that died ({_lock_owner(lock)}); "
                    "its partial files were removed")
            if kept:
                note += f"; '{kept[0]}', saved there meanwhile, is kept in '{aside}'"
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
    staging = expand(path) + ".partial"
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
                _write_marker(staging, {"impact_fenics": _version(), "started": started,
                                        "status": "running"})
            except OSError as exc:
                _remove_run(staging)
                error = f"cannot be written: {exc.strerror or exc}"
        if note:
            print(note, file=sys.stderr, flush=True)
    error = comm.bcast(error, root=0)
    if error:
        raise InputError(f"output directory '{path}': {error}")
    return staging


def _write_marker(path: str, marker: dict) -> None:
    """Write the marker of ``path`` whole or not at all (a temporary file renamed)."""
    tmp = os.path.join(path, MARKER + ".tmp")
    with open(tmp, "w") as f:
        json.dump(marker, f, indent=1, sort_keys=True)
        f.write("\n")
    os.replace(tmp, os.path.join(path, MARKER))


def abandon_directory(staging: str, comm: MPI.Comm) -> None:
    """Remove a staging directory this run created (set-up failed before any result):
    the files this run wrote, nothing else."""
    comm.barrier()
    if comm.rank == 0 and os.path.isfile(os.path.join(staging, LOCK)):
        _remove_run(staging)
    comm.barrier()


def finalize_directory(staging: str, path: str, comm: MPI.Comm,
                       status: str = "completed") -> str:
    """Publish the finished staging directory as ``path`` and return where it went.

    The marker gets the manifest (the files written, ``status``). An older run in
    ``path`` is renamed aside, the new one moved in, then the old one's files deleted:
    an interruption at any point leaves the old or the new run (or both). A run whose
    ``status`` is not "completed..." goes to ``path.interrupted`` (or ``.diverged``)
    when ``path`` holds a completed run or anything else worth keeping. A ``path`` that
    is no run directory (changed meanwhile) is never touched: the run then goes to
    ``path-<time>`` and a warning says so."""
    comm.barrier()
    where = error = None
    if comm.rank == 0:
        try:
            where = _publish(staging, expand(path), status)
        except OSError as exc:
            error = (f"the finished run could not be moved to '{path}': {exc.strerror or exc}; "
                     f"its files are in '{staging}'")
    where, error = comm.bcast((where, error), root=0)
    if error:
        raise InputError(error)
    return where


def _completed(path: str) -> bool:
    """Whether ``path`` holds anything but an unfinished run (a run that did not
    complete, or nothing): a completed run, a run of unknown status, a user's files."""
    if not os.path.isdir(path) or not os.listdir(path):
        return False
    marker = read_marker(path)
    status = marker.get("status") if marker else None
    return not (isinstance(status, str) and status.split()[0] in _BESIDE
                and is_run_directory(path))


def _publish(staging: str, final: str, status: str = "completed") -> str:
    os.remove(os.path.join(staging, LOCK))
    marker = read_marker(staging) or {}
    marker.update(status=status, finished=time.strftime("%Y-%m-%dT%H:%M:%S%z"),
                  files={name: os.path.getsize(os.path.join(staging, name))
                         for name in _files(staging) if name != MARKER})
    _write_marker(staging, marker)
    kind = status.split()[0] if status else ""
    if kind in _BESIDE and _completed(final):
        final += _BESIDE[kind]
    aside = None
    if os.path.lexists(final) and not is_run_directory(final):
        moved = _unused(final + time.strftime("-%Y%m%d-%H%M%S"))
        print(f"warning: '{final}' changed during the run and is no longer only a run's "
              f"directory; the run is in '{moved}'", file=sys.stderr, flush=True)
        final = moved
    elif os.path.lexists(final):
        aside = _unused(final + f".old-{os.getpid()}")
        os.rename(final, aside)
    os.rename(staging, final)
    if aside is not None:
        kept = _remove_run(aside)  # the old run's files, as its manifest lists them
        if kept:
            print(f"warning: '{kept[0]}' appeared in '{final}' while it was replaced; it is "
                  f"kept in '{aside}'", file=sys.stderr, flush=True)
    return final


def record_files(run_dir: str, paths: list[str]) -> None:
    """Add files written into a finished run directory (``impact-fenics plot``'s
    pictures) to its manifest, so that a later run may replace them with the rest."""
    marker = read_marker(run_dir)
    if not marker or not isinstance(marker.get("files"), dict):
        return
    for p in paths:
        name = os.path.relpath(os.path.abspath(p), os.path.abspath(run_dir))
        if not name.startswith(os.pardir) and os.path.isfile(p):
            marker["files"][name] = os.path.getsize(p)
    _write_marker(run_dir, marker)
