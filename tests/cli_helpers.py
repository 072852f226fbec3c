"""What the tests of the command line share (imported as tests/synthetic_posteriors.py is).

``CLI`` runs ``bayes-jackal`` as a subprocess of this interpreter;
:func:`strict_json` parses its JSON as every parser but Python's would.
:class:`Zygote` runs it in a child forked from a process that has imported
the package, without a fresh interpreter's ~2 s of imports (the reliability
suite's and the write-error tests' commands, through the ``cli`` fixture of
tests/conftest.py).
How promptly a run stops after a signal is the CPU it spends after it
(:data:`STOP_CPU_SECONDS`), which the machine's load does not change; the
wall time it does (CI once saw a stop of 0.05 s CPU take 3 s on a busy
2-core machine).
"""

from __future__ import annotations

import fcntl
import json
import os
import pkgutil
import resource
import select
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
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


# --------------------------------------------------------------- the zygote

ENV = os.environ | {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
EXEC_ALL = os.environ.get("BAYES_JACKAL_RELIABILITY_EXEC") == "1"
SCRIPT = [str(Path(sys.executable).with_name("bayes-jackal"))]


def warm_modules() -> list[str]:
    """Modules the zygote imports before it forks, which the CLI imports on first use.

    Every module of the package (but the CLI's ``__main__``, which would run
    it) and of the libraries the commands load, Dask's too (xarray and arviz
    load it where it is installed). A child that imported them itself spent
    up to 0.7 s of CPU on it (compare's Dask).
    """
    import bayes_jackal

    package = [
        module.name
        for module in pkgutil.walk_packages(bayes_jackal.__path__, "bayes_jackal.")
        if not module.name.endswith(".__main__")
    ]
    return [
        *package,
        "bayes_jackal.models",
        "arviz",
        "dask.array",
        "distributed",
        "h5netcdf.legacyapi",
        "h5py",
        "emcee",
        "matplotlib.pyplot",
        "matplotlib.backends.backend_agg",
        "PIL.PngImagePlugin",
    ]


#: The zygote's program; its argument is the JSON list of modules to import first.
ZYGOTE = r"""
import atexit, gc, importlib, json, os, resource, signal, sys, threading
from bayes_jackal.cli import console
for name in json.loads(sys.argv[1]):  # what a run imports lazily, imported once here
    try:
        importlib.import_module(name)
    except ImportError:
        pass
gc.freeze()  # the children's collections skip what the zygote loaded
os.write(1, b"ready\n")
while True:
    line = sys.stdin.readline()
    if not line:
        os._exit(0)
    request = json.loads(line)
    pid = os.fork()
    if pid == 0:
        break
    os.write(1, f"{pid}\n".encode())
    _, status = os.waitpid(pid, 0)
    os.write(1, f"{os.waitstatus_to_exitcode(status)}\n".encode())
os.setpgid(0, 0)
os.chdir(request["cwd"])
for fd, name, mode in ((0, os.devnull, os.O_RDONLY), (1, request["stdout"], os.O_WRONLY),
                       (2, request["stderr"], os.O_WRONLY)):
    handle = os.open(name, mode | (os.O_CREAT | os.O_TRUNC if fd else 0), 0o644)
    os.dup2(handle, fd)
    os.close(handle)
if request["fsize"]:
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    resource.setrlimit(resource.RLIMIT_FSIZE, (request["fsize"], request["fsize"]))
sys.argv = ["bayes-jackal", *request["argv"]]
exec(request["setup"], {})
try:
    console(request["argv"])
    code = 0
except SystemExit as stop:
    code = stop.code if isinstance(stop.code, int) else 0 if stop.code is None else 1
    if not isinstance(stop.code, (int, type(None))):
        print(stop.code, file=sys.stderr)
except BaseException:
    sys.excepthook(*sys.exc_info())
    code = 1
# What the interpreter's exit does before its teardown: wait for the threads,
# run the atexit functions, flush. The teardown itself is skipped: releasing
# every object inherited from the zygote copies its pages (~0.1 s a child).
threading._shutdown()
atexit._run_exitfuncs()
for stream in (sys.stdout, sys.stderr):
    stream.flush()
os._exit(code)
"""


@dataclass
class Result:
    code: int
    stdout: str
    stderr: str
    seconds: float


class Zygote:
    """A Python process with the CLI imported that forks one child per command."""

    def __init__(self):
        self.process = subprocess.Popen(
            [sys.executable, "-c", ZYGOTE, json.dumps(warm_modules())],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            env=ENV,
        )
        self.buffer = b""
        assert self._line(120) == "ready"

    def _line(self, timeout: float) -> str:
        deadline = time.monotonic() + timeout
        fd = self.process.stdout.fileno()
        while b"\n" not in self.buffer:
            left = deadline - time.monotonic()
            if left <= 0 or not select.select([fd], [], [], left)[0]:
                raise TimeoutError
            chunk = os.read(fd, 4096)
            if not chunk:
                raise RuntimeError("the zygote died")
            self.buffer += chunk
        line, self.buffer = self.buffer.split(b"\n", 1)
        return line.decode()

    def run(
        self, argv: list[str], cwd: Path, *, fsize: int, timeout: float, setup: str = ""
    ) -> Result:
        out, err = cwd.parent / f"{cwd.name}.stdout", cwd.parent / f"{cwd.name}.stderr"
        request = {"argv": argv, "cwd": str(cwd), "stdout": str(out), "stderr": str(err)}
        request |= {"fsize": fsize, "setup": setup}
        self.process.stdin.write((json.dumps(request) + "\n").encode())
        self.process.stdin.flush()
        start = time.monotonic()
        pid = int(self._line(30))
        try:
            code = int(self._line(timeout))
        except TimeoutError:
            os.killpg(pid, signal.SIGKILL)
            code = int(self._line(30))
            err.write_text(err.read_text() + f"\n[test: killed after the {timeout:g} s timeout]")
        return Result(code, out.read_text(), err.read_text(), time.monotonic() - start)

    def close(self):
        self.process.stdin.close()
        self.process.wait(10)
        self.process.stdout.close()


def built_once(tmp_path_factory, name: str, build: Callable[[Path], None]) -> Path:
    """The folder ``name`` that ``build(folder)`` fills, once per test run.

    Under xdist the first worker that asks builds it, in the run's temporary
    folder that the workers share; another waits on a lock meanwhile, then
    reads it. A folder is used once its build has returned (a marker file
    says so); one left by a build that failed is built again. It is built
    where it stays, so paths written into its files remain valid.
    """
    base = tmp_path_factory.getbasetemp()
    shared = base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base
    folder, done = shared / name, shared / f"{name}.done"
    with (shared / f"{name}.lock").open("w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # released when the file closes
        if not done.exists():
            shutil.rmtree(folder, ignore_errors=True)
            folder.mkdir()
            build(folder)
            done.touch()
    return folder


def _limit_fsize(limit: int):
    def preexec():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    return preexec if limit else None


def start(argv: list[str], cwd: Path, *, script: bool = False, fsize: int = 0, setup: str = ""):
    """A fresh interpreter running the CLI, in its own process group (like a shell job).

    ``setup``: Python code run first (then the console script's entry point).
    """
    out, err = cwd.parent / f"{cwd.name}.stdout", cwd.parent / f"{cwd.name}.stderr"
    command = (SCRIPT if script else CLI) + argv
    if setup:
        entry = "import sys\nfrom bayes_jackal.cli import console\nconsole(sys.argv[1:])"
        command = [sys.executable, "-c", f"{setup}\n{entry}", *argv]
    with out.open("wb") as stdout, err.open("wb") as stderr:
        process = subprocess.Popen(
            command,
            cwd=cwd,
            stdin=subprocess.DEVNULL,
            stdout=stdout,
            stderr=stderr,
            env=ENV,
            start_new_session=True,
            preexec_fn=_limit_fsize(fsize),
        )
    process.outputs = (out, err)
    process.started = time.monotonic()
    return process


def finish(process, timeout: float) -> Result:
    try:
        process.wait(timeout)
    except subprocess.TimeoutExpired:
        os.killpg(process.pid, signal.SIGKILL)
        process.wait()
    out, err = process.outputs
    return Result(process.returncode, out.read_text(), err.read_text(), 0.0)


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
