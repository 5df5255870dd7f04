"""SIGINT and SIGTERM: stop at once while nothing is written, at a step boundary after.

A main calls :func:`install` first of all (before dolfinx is imported). Until a
run has its output directory, a signal raises :class:`Interrupted` where the
program is (serial), or, under MPI where the other ranks may sit in a
collective call, prints one line and ends every rank with MPI_Abort (Open MPI
adds its own notice). Inside :func:`deferred` (the run: loop, plots, moving
the directory into place) a signal only sets a flag: the loop reads it every
step and the ranks agree on it every :data:`AGREE_EVERY` steps and after the
last step, so the run stops with a complete directory.

Exit code of an interrupted program: 128 + the signal number (130 SIGINT, 143
SIGTERM). Only this module knows how a signal arrived.
"""
from __future__ import annotations

import os
import signal
import sys
from contextlib import contextmanager
from typing import Iterator

SIGNALS = (signal.SIGINT, signal.SIGTERM)
AGREE_EVERY = 64  # steps between the collective checks of the flag under MPI


class Interrupted(BaseException):
    """A signal stopped the program before a run had written anything (a BaseException,
    like KeyboardInterrupt, so that no ``except Exception`` swallows it)."""

    def __init__(self, signum: int, when: str = "during set-up"):
        self.signum = signum
        self.name = signal.Signals(signum).name
        self.exit_code = 128 + signum
        super().__init__(f"interrupted by {self.name} {when}; nothing was written")


class _State:
    signum = 0       # the last signal caught (0: none)
    deferred = 0     # depth of deferred() blocks
    installed = False


STATE = _State()


def _world():
    """mpi4py's COMM_WORLD if MPI is up (not while mpi4py is being imported), else None."""
    mpi = sys.modules.get("mpi4py.MPI")
    world = getattr(mpi, "COMM_WORLD", None)
    try:
        return world if world is not None and mpi.Is_initialized() and not mpi.Is_finalized() \
            else None
    except Exception:  # a partly imported module
        return None


def _world_size() -> int:
    for key in ("OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_SIZE"):
        if os.environ.get(key, "").isdigit():
            return int(os.environ[key])
    world = _world()
    return world.size if world is not None else 1


def _handler(signum, frame) -> None:
    STATE.signum = signum
    if STATE.deferred:
        return
    if _world_size() > 1:
        # another rank may wait in a collective call for this one: end them all
        sys.stderr.write(f"stopped: {Interrupted(signum)}\n")
        sys.stderr.flush()
        world = _world()
        if world is not None:
            world.Abort(128 + signum)
        os._exit(128 + signum)
    raise Interrupted(signum)


def install() -> None:
    """Catch SIGINT and SIGTERM from now on (call it first in a main)."""
    for sig in SIGNALS:
        signal.signal(sig, _handler)
    STATE.installed = True


@contextmanager
def deferred() -> Iterator[None]:
    """Within this block a signal only sets the flag (:func:`pending`). Installs the
    handlers for its duration if no main did (library use), restoring the old ones."""
    old = {}
    if not STATE.installed:
        for sig in SIGNALS:
            try:
                old[sig] = signal.signal(sig, _handler)
            except ValueError:  # not the main thread: signals stay with their owner
                pass
    STATE.deferred += 1
    try:
        yield
    finally:
        STATE.deferred -= 1
        for sig, handler in old.items():
            signal.signal(sig, handler)


@contextmanager
def whole() -> Iterator[None]:
    """Run the block whole (the imports of compiled modules): a signal inside it only sets
    the flag, and is acted on as :func:`install`'s handler would (one line, stop) when
    the block ends. An exception raised by the handler inside a compiled module's
    initialisation would come out as that module's ImportError, with a traceback."""
    before = STATE.signum
    STATE.deferred += 1
    try:
        yield
    finally:
        STATE.deferred -= 1
    if STATE.installed and not STATE.deferred and STATE.signum and STATE.signum != before:
        _handler(STATE.signum, None)


@contextmanager
def kept() -> Iterator[None]:
    """Keep the SIGINT/SIGTERM handlers across a block: importing gmsh's module sets
    SIGINT to SIG_DFL (so that Ctrl-C kills its GUI) and its finalize() sets it back.
    Inside the block those calls are no-ops, so no signal ever meets SIG_DFL there
    (blocking the signals would not do: MPI's threads would take them). Newer gmsh's
    initialize() also resets SIGTERM (and SIGHUP) to the default action in C, below
    Python's record of the handler: on leaving the block, the handlers Python has on
    record are installed again, so a SIGTERM still reaches ours."""
    real = signal.signal

    def unchanged(sig, handler):
        if sig in SIGNALS:
            return signal.getsignal(sig)
        return real(sig, handler)

    signal.signal = unchanged
    try:
        yield
    finally:
        signal.signal = real
        for sig in SIGNALS:
            handler = signal.getsignal(sig)
            if handler is not None:  # None: set outside Python, not ours to touch
                try:
                    real(sig, handler)
                except ValueError:  # not the main thread
                    pass


@contextmanager
def masked() -> Iterator[None]:
    """SIGINT and SIGTERM blocked in the calling thread for the block, pending until it
    ends: around a library call that resets their action in C (newer gmsh's initialize()
    sets SIGTERM to the default, which would end the process silently). Put it outside
    :func:`kept`, so that the handlers are back before a pending signal is let through.
    A signal sent to the process goes to a thread that does not block it: the threads
    started during :func:`held_at_start` (MPI's) block these signals for good, so it
    waits for this one; a thread started otherwise could take it meanwhile."""
    old = signal.pthread_sigmask(signal.SIG_BLOCK, SIGNALS)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


@contextmanager
def held_at_start() -> Iterator[None]:
    """Around the package's first imports (MPI start-up, before any main could call
    :func:`install`): a SIGINT/SIGTERM arriving there ends the program with one line
    and exit 128 + signum, as :func:`install` would, instead of a traceback; where the
    program had its own handler already, the signal goes to it after the block."""
    caught: list[int] = []
    old = {}
    for sig in SIGNALS:
        try:
            old[sig] = signal.signal(sig, lambda signum, frame: caught.append(signum))
        except ValueError:  # not the main thread: leave the handlers alone
            old.pop(sig, None)
    # blocked meanwhile: the threads the imports start (MPI's) inherit the block, so a
    # signal to the process always reaches this thread, never a thread where a library
    # may have reset its action (masked); unblocked below, a pending one is caught
    mask = signal.pthread_sigmask(signal.SIG_BLOCK, SIGNALS) if old else None
    try:
        yield
    finally:
        if mask is not None:
            signal.pthread_sigmask(signal.SIG_SETMASK, mask)  # runs the handler of a pending one
        for sig, handler in old.items():
            signal.signal(sig, handler)
        if caught:
            signum = caught[0]
            default = old.get(signum) in (signal.default_int_handler, signal.SIG_DFL)
            if default or STATE.installed:
                sys.stderr.write(f"stopped: {Interrupted(signum, 'during start-up')}\n")
                sys.stderr.flush()
                os._exit(128 + signum)
            signal.raise_signal(signum)


def pending() -> int:
    """The signal caught on this rank (0: none). Cheap: read it every step."""
    return STATE.signum


def agree(comm) -> int:
    """The signal caught on any rank (collective; every rank returns the same number)."""
    from mpi4py import MPI

    signum = comm.allreduce(STATE.signum, op=MPI.MAX) if comm.size > 1 else STATE.signum
    # a signal may arrive on this rank while it waits in the reduction (its handler can run
    # before the reduction returns, after this rank's flag was read): the flag is raised to
    # what the ranks agreed, never lowered, so such a signal is agreed on the next time
    if signum:
        STATE.signum = signum
    return signum


def clear() -> None:
    """Forget a caught signal (a new run in the same process starts clean)."""
    STATE.signum = 0


def name(signum: int) -> str:
    return signal.Signals(signum).name
