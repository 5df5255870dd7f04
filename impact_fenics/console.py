"""Whether the user watches this run on a terminal (for the progress line).

A process started by hand asks its own stdout. A rank started by an MPI
launcher cannot: OpenMPI's ``mpirun`` gives its local ranks a pseudo-terminal
even when its own output goes to a file (so a rank sees a terminal, and a
redirected log would fill with carriage-return lines), and MPICH's Hydra
``mpiexec`` gives them a pipe even when it runs in a terminal (so a user at a
terminal would see no progress). The launcher's own stdout is what the user
sees: on Linux this module finds the launcher among the process's ancestors and
asks what its file descriptor 1 is. Where it cannot (no /proc, a rank on
another host than the launcher), the rank's own stdout decides.
"""
from __future__ import annotations

import os
import sys

# names (as the kernel reports them, at most 15 characters) of MPI launchers
LAUNCHERS = ("mpirun", "mpiexec", "orterun", "prterun", "mpiexec.hydra", "mpirun.openmpi",
             "mpiexec.openmpi", "mpirun.mpich", "mpiexec.mpich", "srun")
# environment variables set in the ranks by OpenMPI, MPICH's Hydra and Slurm
_RANK_VARIABLES = ("OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMI_RANK", "SLURM_PROCID")


def _parent(pid: int) -> int | None:
    try:
        with open(f"/proc/{pid}/stat") as f:
            stat = f.read()
        return int(stat[stat.rindex(")") + 2:].split()[1])
    except (OSError, ValueError, IndexError):
        return None


def _name(pid: int) -> str:
    try:
        with open(f"/proc/{pid}/comm") as f:
            return f.read().strip()
    except OSError:
        return ""


def _is_terminal(path: str) -> bool:
    return path.startswith(("/dev/pts/", "/dev/tty")) or path == "/dev/console"


def launcher_pid(max_depth: int = 6) -> int | None:
    """The pid of the MPI launcher this process descends from, if found within
    ``max_depth`` generations (None when not launched by one, or not visible)."""
    if not any(v in os.environ for v in _RANK_VARIABLES):
        return None
    pid = os.getpid()
    for _ in range(max_depth):
        pid = _parent(pid)
        if pid is None or pid <= 1:
            return None
        if _name(pid) in LAUNCHERS:
            return pid
    return None


def on_terminal() -> bool:
    """True when this process's output reaches a terminal: its launcher's stdout when an
    MPI launcher started it, else its own."""
    launcher = launcher_pid()
    if launcher is not None:
        try:
            return _is_terminal(os.readlink(f"/proc/{launcher}/fd/1"))
        except OSError:
            pass
    try:
        return sys.stdout.isatty()
    except (AttributeError, ValueError):  # replaced or closed stdout
        return False
