"""What the tests of the command line share (imported as tests/synthetic_posteriors.py is).

``CLI`` runs ``bayes-jackal`` as a subprocess of this interpreter;
:func:`strict_json` parses its JSON as every parser but Python's would.
How promptly a run stops after a signal is the CPU it spends after it
(:data:`STOP_CPU_SECONDS`), which the machine's load does not change; the
wall time it does (CI once saw a stop of 0.05 s CPU take 3 s on a busy
2-core machine).
"""

from __future__ import annotations

import json
import os
import resource
import sys
from pathlib import Path

#: ``bayes-jackal`` as a subprocess (the module form; the venv's interpreter).
CLI = [sys.executable, "-m", "bayes_jackal.cli"]

#: CPU seconds a run may spend after a signal, its processes' together: the
#: earlier wall-clock bound of "about a second". Measured: <= 0.08 s for
#: sample and analyse, up to 0.7 s for compare, whose workers' results are
#: criticised and written as they come (what finished is kept).
STOP_CPU_SECONDS = 2.0
#: A run that waits after a signal instead of working fails this wall-clock
#: bound [s] (15x the CPU one: load stretches work, not waiting).
STOP_WALL_SECONDS = 15 * STOP_CPU_SECONDS


def process_cpu_seconds(pid: int) -> float:
    """User and system CPU [s] of a live process and its live descendants so far (Linux)."""
    stats = {}
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rpartition(")")[2].split()
        except OSError:  # gone meanwhile
            continue
        stats[int(stat.parent.name)] = (int(fields[1]), sum(int(t) for t in fields[11:15]))
    family, grown = set(), {pid}
    while grown:  # the spawned workers of compare, and their children
        family |= grown
        grown = {child for child, (parent, _) in stats.items() if parent in grown}
    ticks = sum(stats[member][1] for member in family if member in stats)
    return ticks / os.sysconf("SC_CLK_TCK")


def children_cpu_seconds() -> float:
    """User and system CPU [s] of this process's reaped children (and theirs) so far."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def strict_json(text: str) -> object:
    """Parse JSON refusing NaN and Infinity (which json.loads accepts by default)."""

    def refuse(name: str):
        raise ValueError(f"not valid JSON: {name}")

    return json.loads(text, parse_constant=refuse)


def stored_steps(chain: Path) -> int:
    """Steps stored in a chain file while it is written (0 where it cannot be read yet).

    Read without HDF5's file lock, which would make the sampler's next write fail.
    """
    import h5py

    try:
        with h5py.File(chain, "r", locking=False) as stored:
            return int(stored["mcmc"].attrs["iteration"])
    except (OSError, KeyError):
        return 0
