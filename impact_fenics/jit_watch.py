"""Which compiled kernels gained a signature: the check that nothing compiles in the loop.

A numba kernel compiles (or loads from its cache) once per signature, the first
time it is called with new argument types, e.g. an array view whose layout
differs from the one loaded at set-up. Inside the timed loop that costs
0.1-1 s once, which no median shows. :func:`signature_counts` counts the
signatures of every kernel of the package; the loop compares the counts before
and after and the summary names any kernel that gained one.
"""
from __future__ import annotations

import sys

import numpy as np


def signature_counts() -> dict[str, int]:
    """{module.kernel: number of compiled signatures} of every numba kernel in the loaded
    modules of impact_fenics (a few hundred microseconds)."""
    from numba.core.dispatcher import Dispatcher

    counts: dict[str, int] = {}
    for name, module in list(sys.modules.items()):
        if module is None or not name.startswith("impact_fenics"):
            continue
        for var, obj in list(vars(module).items()):
            if isinstance(obj, Dispatcher):  # by the name it is bound to: the kernels one
                # factory makes share a function name (contact.fused's face steps)
                counts[f"{obj.py_func.__module__}.{var}"] = len(obj.signatures)
    return counts


def gained(before: dict[str, int], after: dict[str, int]) -> list[str]:
    """Kernels with more signatures in ``after`` than in ``before`` (sorted names)."""
    return sorted(k for k, n in after.items() if n > before.get(k, 0))


def load(kernel, *args) -> None:
    """Compile (or load from the cache) numba ``kernel`` for the types of ``args`` now, at
    set-up, without running it: the loop's first call finds it ready."""
    from numba import typeof

    kernel.compile(tuple(typeof(a) for a in args))


def direct(kernel, *args):
    """The compiled entry of numba ``kernel`` for the types of ``args``, compiled (or loaded
    from the cache) now, without running it: callable with arguments of exactly those
    types, it skips the dispatcher's search by argument types (0.15-0.35 us a call) and
    still refuses an array of another type. The kernel itself where numba offers no such
    entry. For calls in the loop whose argument types are fixed for the run."""
    from numba import typeof

    sig = tuple(typeof(a) for a in args)
    kernel.compile(sig)
    entry = getattr(getattr(kernel, "overloads", {}).get(sig), "entry_point", None)
    return entry if callable(entry) else kernel


def contiguous_float64(a, ndim: int) -> bool:
    """Is ``a`` an aligned, writeable, C-contiguous float64 numpy array of ``ndim``
    dimensions, the type :func:`direct` entries are bound for here? (An entry refuses
    another dtype but takes another layout or ndim unchecked: check an array from
    elsewhere once before binding it.)"""
    return (isinstance(a, np.ndarray) and a.dtype == np.float64 and a.ndim == ndim
            and a.flags.c_contiguous and a.flags.aligned and a.flags.writeable)


def cold_share(kernels) -> float:
    """The share (0 to 1) of numba ``kernels`` that will compile rather than load from
    numba's on-disk cache: those whose cache index is absent (a first run) or holds
    nothing for their current source and numba (an edited module, another numba). Give
    the kernels every such run loads at set-up: their cache is then as fresh as the
    last run left it, so the share says what the next run compiles. Reads the index
    files only."""
    import os

    cold = total = 0
    for kernel in kernels:
        index = getattr(getattr(kernel, "_cache", None), "_cache_file", None)
        if index is None:  # (cache=False)
            continue
        total += 1
        try:
            cold += not (os.path.exists(index._index_path) and index._load_index())
        except Exception:  # another numba's cache layout: count it as compiled
            pass
    return cold / total if total else 0.0
