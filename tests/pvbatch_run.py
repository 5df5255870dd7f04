"""ParaView's default reader on a run's fields.xdmf: pvbatch runs tests/pvbatch_fields.py
and prints what it read as JSON.

pvbatch needs a display: off-screen rendering where ParaView was built with it, else a
virtual X server (xvfb-run). ``xvfb-run -a`` takes the first display number without a
lock file, which races with other X servers starting at the same moment and picks a
number whose lock a dead server left, or whose socket another namespace holds (pvbatch
then aborts with "bad X server connection" or in creating its window). So each try
names its own display (-n), a number no lock file claims, drawn from a wide range, and
a failure to reach the display is tried again on another number.
"""
from __future__ import annotations

import json
import os
import random
import shutil
import subprocess

from conftest import clean_mpi_env

SCRIPT = os.path.join(os.path.dirname(__file__), "pvbatch_fields.py")
X_FAILURES = ("bad X server connection", "CreateAWindow", "Could not open display",
              "xvfb-run: error")


def _free_display(rng: random.Random) -> int:
    while True:
        n = rng.randrange(200, 2000)
        if not os.path.exists(f"/tmp/.X{n}-lock") and not os.path.exists(f"/tmp/.X11-unix/X{n}"):
            return n


def pvbatch_json(xdmf: str, tries: int = 5, field: str = "sigma_zz") -> dict | None:
    """tests/pvbatch_fields.py's JSON on ``xdmf`` (coloured by ``field``), or None without
    pvbatch."""
    if not shutil.which("pvbatch"):
        return None
    tried = []
    proc = subprocess.run(["pvbatch", "--force-offscreen-rendering", SCRIPT, xdmf, field],
                          capture_output=True, text=True, timeout=300, env=clean_mpi_env())
    if proc.returncode == 0:
        return json.loads(proc.stdout.strip().splitlines()[-1])
    tried.append(f"off-screen: {proc.stderr[-300:]}")
    if not shutil.which("xvfb-run"):
        raise AssertionError("pvbatch failed: " + " | ".join(tried))
    rng = random.Random(os.getpid())
    for _ in range(tries):
        display = _free_display(rng)
        proc = subprocess.run(["xvfb-run", "-n", str(display), "-s", "-screen 0 1280x1024x24",
                               "pvbatch", SCRIPT, xdmf, field], capture_output=True, text=True,
                              timeout=300, env=clean_mpi_env())
        if proc.returncode == 0:
            return json.loads(proc.stdout.strip().splitlines()[-1])
        tried.append(f"xvfb-run -n {display}: {proc.stderr[-300:]}")
        if not any(x in proc.stderr for x in X_FAILURES):
            break  # ParaView itself failed: no other display will help
    raise AssertionError("pvbatch failed: " + " | ".join(tried))
