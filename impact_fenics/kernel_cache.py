"""numba's on-disk cache of the package's kernels, valid only for the sources that compiled it.

numba keys a cached kernel by its own source file (time and size) and its own
code. Two things it does not see:

- **what the kernel took from other modules:** the kernels it calls (compiled
  into it) and the constants it imports (frozen into its code). After an edit
  of ``contact/state.py`` a cached ``contact_step`` would keep running the old
  layout; after a ``git pull`` the same.
- **the names of closures from another process:** a kernel made by a factory
  has one qualified name for every closure the factory makes, told apart inside
  one process by a counter. Two cached kernels compiled by two processes can
  then each hold a different closure under the same symbol, and the process
  that loads both links one to the other's body: a run of the wrong method,
  silently. The package therefore gives each factory's closure a name of its
  own (contact.fused's face steps), and the tests check that no two cached
  kernels share one.

:func:`sweep` settles the first: the package's sources are hashed (SHA-256 of
every ``.py`` file under it, path and bytes); each directory where numba keeps
the package's cache holds the hash that filled it; where it differs, numba's
files of the package's modules there are deleted before anything loads, and
the new hash is written. A file lock makes ranks that import at once sweep
once. Files that are not numba's cache of the package's own modules are never
touched.
"""
from __future__ import annotations

import hashlib
import os

STAMP = "impact_fenics.sources"  # the hash that filled the directory's cache
CACHE_SUFFIXES = (".nbi", ".nbc")  # numba's index and data files


def sources_digest(package_dir: str) -> str:
    """SHA-256 (hex) of every ``.py`` file under ``package_dir``: its path relative to
    the package and its bytes, in sorted order."""
    digest = hashlib.sha256()
    for path in sorted(_sources(package_dir)):
        digest.update(os.path.relpath(path, package_dir).encode())
        digest.update(b"\0")
        with open(path, "rb") as handle:
            digest.update(handle.read())
        digest.update(b"\0")
    return digest.hexdigest()


def _sources(package_dir: str) -> list[str]:
    found = []
    for root, dirs, files in os.walk(package_dir):
        dirs[:] = [d for d in dirs if d != "__pycache__" and not d.startswith(".")]
        found += [os.path.join(root, f) for f in files if f.endswith(".py")]
    return found


def numba_cache_dir(source_file: str) -> str | None:
    """Where numba keeps the cache of the kernels of ``source_file``: the first of its
    locators that accepts the file (NUMBA_CACHE_DIR, the ``__pycache__`` beside it if
    writable, the user's cache directory). None if numba finds none."""
    try:
        from numba.core.caching import CacheImpl

        stand_in = _function_of(source_file)
        for locator in CacheImpl._locator_classes:
            found = locator.from_function(stand_in, source_file)
            if found is not None:
                return found.get_cache_path()
    except Exception:  # another numba's internals: numba's own default
        pass
    return None


def _function_of(source_file: str):
    """A function whose code says it comes from ``source_file`` (what a locator reads)."""
    import types

    code = compile("def kernel():\n    pass\n", source_file, "exec").co_consts[0]
    return types.FunctionType(code, {})


def sweep(package_dir: str) -> int:
    """Delete numba's cache of the package's modules wherever it was filled by other
    sources than the package's present ones; returns the number of files deleted."""
    digest = sources_digest(package_dir)
    by_source_dir: dict[str, list[str]] = {}
    for path in _sources(package_dir):
        by_source_dir.setdefault(os.path.dirname(path), []).append(path)
    deleted = 0
    for paths in by_source_dir.values():  # (numba's place depends on the directory only)
        where = numba_cache_dir(paths[0])
        if where is not None:
            stems = {os.path.splitext(os.path.basename(p))[0] for p in paths}
            deleted += _sweep_dir(where, stems, digest)
    return deleted


def _sweep_dir(where: str, stems: set[str], digest: str) -> int:
    """In cache directory ``where``: if its stamp is not ``digest``, delete numba's files
    of modules ``stems`` (named ``stem.kernel-line.pyXY[.n].nb[ic]``) and stamp it."""
    try:
        handle = open(os.path.join(where, STAMP), "a+")
    except OSError:  # (numba found it writable a moment ago; leave it to numba)
        return 0
    with handle:
        _lock(handle)
        handle.seek(0)
        if handle.read().strip() == digest:
            return 0
        deleted = 0
        for name in os.listdir(where):
            if name.endswith(CACHE_SUFFIXES) and name.split(".", 1)[0] in stems:
                try:
                    os.remove(os.path.join(where, name))
                    deleted += 1
                except OSError:
                    pass
        handle.seek(0)
        handle.truncate()
        handle.write(digest + "\n")
        handle.flush()
        return deleted  # (the lock goes with the file's closing)


def _lock(handle) -> None:
    """An exclusive lock on ``handle`` until it closes (where the platform has one)."""
    try:
        import fcntl
    except ImportError:
        return
    fcntl.flock(handle.fileno(), fcntl.LOCK_EX)
