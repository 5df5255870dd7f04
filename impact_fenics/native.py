"""C functions that a compiled kernel calls by address: PETSc's MatMultAdd and VecAXPY,
MPI's Allgatherv and Allreduce, and the monotonic clock.

A kernel that runs many steps in one call (:mod:`.step_block`) cannot go through
petsc4py, so it calls the PETSc library that petsc4py loaded into this process
(found in ``/proc/self/maps``) by the functions' addresses, with the objects'
handles (``Mat.handle``, ``Vec.handle``) as integers: the same C functions on the
same objects as ``A.multAdd(u, v, v)`` and ``u.axpy(dt, v)``, so the same numbers
bit for bit, without petsc4py's ~0.2 us a call. The addresses are arguments of the
kernel, not constants compiled into it, so numba caches the kernel across runs.

MPI is called the same way, from the library mpi4py loaded, with mpi4py's handles
of the communicator, MPI_DOUBLE, MPI_MAX and MPI_SUM: pointers in Open MPI, ``int`` in
MPICH (:func:`mpi_addresses` says which; the kernels call the matching form).

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
# mpi_addresses(): MPI_Allgatherv, MPI_Allreduce, handles 64-bit (1) or 32-bit (0), and the
# handles of the communicator, MPI_DOUBLE, MPI_MAX and MPI_SUM
M_ALLGATHERV, M_ALLREDUCE, M_WIDE, M_COMM, M_DOUBLE, M_MAX, M_SUM = range(7)


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


def _allgatherv_call(wide: bool):
    """An intrinsic calling MPI_Allgatherv(send, count, dtype, recv, counts, displs, dtype,
    comm) at an address, the handles (dtype, comm) passed 64-bit if ``wide`` else 32-bit."""

    @intrinsic
    def call(typingctx, address, send, count, dtype, recv, counts, displs, comm):
        sig = types.int32(types.int64, types.int64, types.int32, types.int64, types.int64,
                          types.int64, types.int64, types.int64)

        def codegen(context, builder, signature, args):
            i32, i64 = ir.IntType(32), ir.IntType(64)
            h = i64 if wide else i32
            fnty = ir.FunctionType(i32, [i64, i32, h, i64, i64, i64, h, h])
            fn = builder.inttoptr(args[0], fnty.as_pointer())
            send_, count_, dtype_, recv_, counts_, displs_, comm_ = args[1:]
            if not wide:
                dtype_, comm_ = builder.trunc(dtype_, i32), builder.trunc(comm_, i32)
            return builder.call(fn, [send_, count_, dtype_, recv_, counts_, displs_, dtype_,
                                     comm_])
        return sig, codegen
    return call


def _allreduce_call(wide: bool):
    """An intrinsic calling MPI_Allreduce(send, recv, count, dtype, op, comm) at an address,
    the handles passed 64-bit if ``wide`` else 32-bit."""

    @intrinsic
    def call(typingctx, address, send, recv, count, dtype, op, comm):
        sig = types.int32(types.int64, types.int64, types.int64, types.int32, types.int64,
                          types.int64, types.int64)

        def codegen(context, builder, signature, args):
            i32, i64 = ir.IntType(32), ir.IntType(64)
            h = i64 if wide else i32
            fnty = ir.FunctionType(i32, [i64, i64, i32, h, h, h])
            fn = builder.inttoptr(args[0], fnty.as_pointer())
            send_, recv_, count_, dtype_, op_, comm_ = args[1:]
            if not wide:
                dtype_, op_, comm_ = (builder.trunc(dtype_, i32), builder.trunc(op_, i32),
                                      builder.trunc(comm_, i32))
            return builder.call(fn, [send_, recv_, count_, dtype_, op_, comm_])
        return sig, codegen
    return call


_allgatherv_64, _allgatherv_32 = _allgatherv_call(True), _allgatherv_call(False)
_allreduce_64, _allreduce_32 = _allreduce_call(True), _allreduce_call(False)


@njit(cache=True)
def allgatherv(mpi, send, recv, counts, displs) -> int:
    """MPI_Allgatherv of the doubles ``send`` into ``recv`` (``counts``, ``displs``: int32
    arrays) over the communicator of ``mpi`` (:func:`mpi_addresses`' layout)."""
    if mpi[M_WIDE] != 0:
        return _allgatherv_64(mpi[M_ALLGATHERV], send.ctypes.data, np.int32(send.size),
                              mpi[M_DOUBLE], recv.ctypes.data, counts.ctypes.data,
                              displs.ctypes.data, mpi[M_COMM])
    return _allgatherv_32(mpi[M_ALLGATHERV], send.ctypes.data, np.int32(send.size),
                          mpi[M_DOUBLE], recv.ctypes.data, counts.ctypes.data,
                          displs.ctypes.data, mpi[M_COMM])


@njit(cache=True)
def allreduce(mpi, send, recv, op: int) -> int:
    """MPI_Allreduce of the doubles ``send`` into ``recv`` by the operation in ``mpi[op]``
    (``op``: M_MAX or M_SUM)."""
    if mpi[M_WIDE] != 0:
        return _allreduce_64(mpi[M_ALLREDUCE], send.ctypes.data, recv.ctypes.data,
                             np.int32(send.size), mpi[M_DOUBLE], mpi[op], mpi[M_COMM])
    return _allreduce_32(mpi[M_ALLREDUCE], send.ctypes.data, recv.ctypes.data,
                         np.int32(send.size), mpi[M_DOUBLE], mpi[op], mpi[M_COMM])


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


def _functions(stem: str | None, names) -> list[int] | None:
    """The addresses of the functions ``names`` in the shared library ``stem``* mapped into
    this process (None: the process itself, libc's), or None where one cannot be had."""
    path = None if stem is None else _loaded(stem)
    if stem is not None and path is None:
        return None
    try:
        lib = ctypes.CDLL(path)
        return [_address(getattr(lib, name)) for name in names]
    except (OSError, AttributeError):
        return None


@functools.lru_cache(maxsize=None)
def _addresses() -> tuple | None:
    from petsc4py import PETSc

    if np.dtype(PETSc.ScalarType) != np.float64:
        return None
    petsc = _functions("libpetsc", ("MatMultAdd", "VecAXPY"))
    clock = _functions(None, ("clock_gettime",))
    return None if petsc is None or clock is None else (*petsc, *clock)


def addresses() -> np.ndarray | None:
    """int64 [MatMultAdd, VecAXPY, clock_gettime] of this process, or None where they
    cannot be had (no /proc, a PETSc whose scalars are not real doubles): the caller
    then stays with petsc4py. Looked up once per process."""
    found = _addresses()
    return None if found is None else np.array(found, dtype=np.int64)


def _signed(handle: int, bits: int) -> int:
    """An MPI handle as mpi4py gives it (unsigned) as the signed integer of its width."""
    handle &= (1 << bits) - 1
    return handle - (1 << bits) if handle >= 1 << (bits - 1) else handle


def mpi_addresses(comm) -> np.ndarray | None:
    """int64 [MPI_Allgatherv, MPI_Allreduce, wide, comm, MPI_DOUBLE, MPI_MAX, MPI_SUM] for ``comm``
    (layout M_*), or None where they cannot be had (the caller then stays with mpi4py)."""
    from mpi4py import MPI

    bits = 8 * MPI._sizeof(MPI.Comm)
    if bits not in (32, 64) or {8 * MPI._sizeof(t) for t in (MPI.Datatype, MPI.Op)} != {bits}:
        return None
    functions = _functions("libmpi.so", ("MPI_Allgatherv", "MPI_Allreduce"))
    if functions is None:
        return None
    handles = [_signed(MPI._handleof(h), bits) for h in (comm, MPI.DOUBLE, MPI.MAX, MPI.SUM)]
    return np.array(functions + [bits == 64] + handles, dtype=np.int64)
