"""C functions that a compiled kernel calls by address: PETSc's MatMultAdd and VecAXPY, and
the monotonic clock.

A kernel that runs many steps in one call (:mod:`.step_block`) cannot go through
petsc4py, so it calls the PETSc library that petsc4py loaded into this process
(found in ``/proc/self/maps``) by the functions' addresses, with the objects'
handles (``Mat.handle``, ``Vec.handle``) as integers: the same C functions on the
same objects as ``A.multAdd(u, v, v)`` and ``u.axpy(dt, v)``, so the same numbers
bit for bit, without petsc4py's ~0.2 us a call. The addresses are arguments of the
kernel, not constants compiled into it, so numba caches the kernel across runs.

:func:`now` reads CLOCK_MONOTONIC, the clock of ``time.perf_counter`` on Linux
(s; ~25 ns a read).
"""
from __future__ import annotations

import ctypes
import functools
import re

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic

CLOCK_MONOTONIC = 1  # Linux <time.h>


@intrinsic
def _call_4p(typingctx, address, a, b, c, d):
    """int f(void*, void*, void*, void*) at ``address`` (the pointers as integers)."""
    sig = types.int32(types.int64, types.int64, types.int64, types.int64, types.int64)

    def codegen(context, builder, signature, args):
        fnty = ir.FunctionType(ir.IntType(32), [ir.IntType(64)] * 4)
        fn = builder.inttoptr(args[0], fnty.as_pointer())
        return builder.call(fn, args[1:])
    return sig, codegen


@intrinsic
def _call_pdp(typingctx, address, a, x, b):
    """int f(void*, double, void*) at ``address``."""
    sig = types.int32(types.int64, types.int64, types.float64, types.int64)

    def codegen(context, builder, signature, args):
        fnty = ir.FunctionType(ir.IntType(32), [ir.IntType(64), ir.DoubleType(), ir.IntType(64)])
        fn = builder.inttoptr(args[0], fnty.as_pointer())
        return builder.call(fn, args[1:])
    return sig, codegen


@intrinsic
def _call_ip(typingctx, address, i, p):
    """int f(int, void*) at ``address``."""
    sig = types.int32(types.int64, types.int32, types.int64)

    def codegen(context, builder, signature, args):
        fnty = ir.FunctionType(ir.IntType(32), [ir.IntType(32), ir.IntType(64)])
        fn = builder.inttoptr(args[0], fnty.as_pointer())
        return builder.call(fn, args[1:])
    return sig, codegen


@njit(cache=True)
def mat_mult_add(address: int, A: int, x: int, y: int, z: int) -> int:
    """MatMultAdd(A, x, y, z): z = A x + y; returns PETSc's error code (0: none)."""
    return _call_4p(address, A, x, y, z)


@njit(cache=True)
def vec_axpy(address: int, y: int, alpha: float, x: int) -> int:
    """VecAXPY(y, alpha, x): y += alpha x; returns PETSc's error code (0: none)."""
    return _call_pdp(address, y, alpha, x)


@njit(cache=True)
def now(address: int, timespec: np.ndarray) -> float:
    """CLOCK_MONOTONIC (s) by clock_gettime at ``address``, through ``timespec`` (int64[2])."""
    _call_ip(address, np.int32(CLOCK_MONOTONIC), timespec.ctypes.data)
    return timespec[0] + 1e-9 * timespec[1]


def _loaded(stem: str) -> str | None:
    """Path of the shared library named ``stem``* mapped into this process, if any."""
    try:
        with open("/proc/self/maps") as maps:
            found = re.search(r"(/\S*/" + re.escape(stem) + r"[^/\s]*)$", maps.read(), re.M)
    except OSError:
        return None
    return found.group(1) if found else None


def _address(fn) -> int:
    return ctypes.cast(fn, ctypes.c_void_p).value


@functools.lru_cache(maxsize=None)
def _addresses() -> tuple | None:
    from petsc4py import PETSc

    if np.dtype(PETSc.ScalarType) != np.float64:
        return None
    path = _loaded("libpetsc")
    if path is None:
        return None
    try:
        petsc = ctypes.CDLL(path)
        libc = ctypes.CDLL(None)
        return (_address(petsc.MatMultAdd), _address(petsc.VecAXPY),
                _address(libc.clock_gettime))
    except (OSError, AttributeError):
        return None


def addresses() -> np.ndarray | None:
    """int64 [MatMultAdd, VecAXPY, clock_gettime] of this process, or None where they
    cannot be had (no /proc, a PETSc whose scalars are not real doubles): the caller
    then stays with petsc4py. Looked up once per process."""
    found = _addresses()
    return None if found is None else np.array(found, dtype=np.int64)
