"""Executors: the same results in this process, in local processes and on a Dask cluster.

The cluster tests start a real ``distributed.LocalCluster`` and, through the
console script, a real ``dask scheduler`` and ``dask worker`` on 127.0.0.1,
each stopped by its own process id. The runs are tiny (one v2 run of 26 s,
yaw channel, 200 steps): the point is the plumbing and the equality of the
numbers, not the posterior.
"""

from __future__ import annotations

import contextlib
import json
import logging
import multiprocessing
import os
import shutil
import signal
import socket
import struct
import subprocess
import sys
import threading
import time
import warnings
from pathlib import Path

import numpy as np
import pytest

import bayes_jackal
from bayes_jackal import load_profile
from bayes_jackal._runtime import printed
from bayes_jackal._runtime.errors import InputError
from bayes_jackal.inference import FitOptions
from bayes_jackal.inference.chains import SamplerSettings
from bayes_jackal.inference.comparison import compare_families
from bayes_jackal.inference.executors import (
    Background,
    DaskExecutor,
    ProcessExecutor,
    SerialExecutor,
)
from bayes_jackal.inference.sampler_warnings import ConvergenceWarning
from bayes_jackal.io.simulate import simulate_experiment
from bayes_jackal.likelihood import LikelihoodOptions

distributed = pytest.importorskip("distributed")

ROBOT = load_profile()
FAMILIES = ("white", "exponential")
#: Where the console scripts of this environment live.
BIN = Path(sys.executable).parent
#: A port nothing listens on: 1 is reserved (tcpmux) and unused on test machines.
DEAD_ADDRESS = "tcp://127.0.0.1:1"
# Without a dashboard, the scheduler's and workers' HTTP servers (health
# routes) still listen, by default on every interface and port 8787.
LOCAL_HTTP = ("--dashboard-address", "127.0.0.1:0")
#: Run first by the ``cli`` fixture's child (tests/conftest.py): the Dask check's
#: timeout at 1 s instead of DaskExecutor's default 5 s (which the CLI uses), for
#: the refusals that wait it out: unreachable, or no Dask handshake. They are
#: refused all the same, 4 s sooner; a command that waited for ever would still
#: meet the fixture's timeout, and be killed.
SHORT_TIMEOUT = (
    "from bayes_jackal.inference.executors import DaskExecutor\n"
    "DaskExecutor.__init__.__kwdefaults__['timeout'] = 1.0"
)
#: One simulated v2 run (26 s at 72 Hz), and flags of a quick comparison.
TINY_RUN = ["--v1", "0", "--v2", "1", "--seed", "1"]
QUICK = ["--families", ",".join(FAMILIES), "--seed", "3", "--max-steps", "200"]
QUICK += ["--channels", "yaw", "--json"]


def _compare(run, executor):
    settings = SamplerSettings(max_steps=200, progress=False)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)  # 200 steps do not converge
        options = FitOptions(
            robot=ROBOT,
            likelihood_options=LikelihoodOptions(channels=("yaw",)),
            settings=settings,
            seed=3,
        )
        return compare_families([run], options, families=FAMILIES, executor=executor)


@pytest.mark.slow  # ~40 s: three comparisons, process and cluster start-ups
def test_same_evidence_and_chains_on_every_executor():
    run = simulate_experiment(ROBOT, 110.0, 30.0, "v2", rng=1)
    serial = _compare(run, SerialExecutor())
    local = _compare(run, ProcessExecutor(2))
    with distributed.LocalCluster(
        n_workers=2,
        threads_per_worker=1,
        processes=True,
        host="127.0.0.1",
        # Not None: the scheduler's HTTP server would still listen, on
        # 0.0.0.0:8787, and another cluster there fails the start (a warning).
        dashboard_address="127.0.0.1:0",
    ) as cluster:
        clustered = _compare(run, DaskExecutor(cluster))
        assert cluster.status.name == "running"  # our client closed, the cluster not
    for family in FAMILIES:
        assert serial.evidence[family] == local.evidence[family] == clustered.evidence[family]
        for other in (local, clustered):
            np.testing.assert_array_equal(
                other.posteriors[family].posterior.d_lat.values,
                serial.posteriors[family].posterior.d_lat.values,
            )


def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def _start(command: list[str]) -> subprocess.Popen:
    return subprocess.Popen(
        command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True
    )


def _stop(process: subprocess.Popen) -> None:
    """Stop a process we started, by its own id (SIGTERM, then SIGKILL)."""
    if process.poll() is None:
        os.kill(process.pid, signal.SIGTERM)
        try:
            process.wait(timeout=10)
        except subprocess.TimeoutExpired:
            os.kill(process.pid, signal.SIGKILL)
            process.wait()


def _wait_for_worker(address: str, seconds: float = 60.0) -> None:
    with distributed.Client(address, timeout=seconds, set_as_default=False) as client:
        client.wait_for_workers(1, timeout=seconds)


@pytest.mark.slow  # ~30 s: a scheduler, a worker and three commands
def test_compare_on_a_dask_scheduler_through_the_console_script(tmp_path):
    subprocess.run(
        [BIN / "bayes-jackal", "simulate", "--out", tmp_path / "runs", *TINY_RUN],
        check=True,
        capture_output=True,
    )
    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    scheduler = _start(
        [
            BIN / "dask",
            "scheduler",
            "--host",
            "127.0.0.1",
            "--port",
            str(port),
            "--no-dashboard",
            *LOCAL_HTTP,
        ]
    )
    worker = None
    try:
        worker = _start(
            [
                BIN / "dask",
                "worker",
                address,
                "--nworkers",
                "1",
                "--nthreads",
                "1",
                "--no-dashboard",
                *LOCAL_HTTP,
                "--host",
                "127.0.0.1",
            ]
        )
        _wait_for_worker(address)
        command = [
            BIN / "bayes-jackal",
            "compare",
            tmp_path / "runs" / "v2_01.nc",
            *QUICK,
            "--out",
            tmp_path / "out",
            "--scheduler",
            address,
        ]
        done = subprocess.run(command, capture_output=True, text=True, timeout=300)
        # The finished families were saved as they came back: a rerun reuses them.
        rerun = subprocess.run(command, capture_output=True, text=True, timeout=300)
    finally:
        for process in (worker, scheduler):
            if process is not None:
                _stop(process)
    assert done.returncode == 0, done.stderr
    result = json.loads(done.stdout)
    assert set(result["families"]) == set(FAMILIES)
    for family in FAMILIES:  # each saved as it finished: a rerun reuses it
        assert (tmp_path / "out" / f"v2_01.{family}.nc").is_file()
    assert (tmp_path / "out" / "v2_01.compare.json").is_file()
    assert "\r" not in done.stderr  # no progress bars from the cluster
    assert rerun.returncode == 0, rerun.stderr
    for family in FAMILIES:
        assert f"reusing {family}" in rerun.stderr
    assert json.loads(rerun.stdout)["families"] == result["families"]


def test_unreachable_scheduler_is_bad_input_named_fast(tmp_path, cli):
    (tmp_path / "never-read.nc").touch()  # the scheduler is refused before any input is read
    start = time.perf_counter()
    argv = ["compare", str(tmp_path / "never-read.nc"), "--scheduler", DEAD_ADDRESS]
    done = cli(argv, tmp_path, timeout=60, setup=SHORT_TIMEOUT)
    assert done.code == 2, done.stderr
    assert DEAD_ADDRESS in done.stderr and "dask scheduler" in done.stderr
    assert "within 1 s" in done.stderr  # the shortened timeout, waited out
    assert time.perf_counter() - start < 30


def _listening(port: int, seconds: float = 30.0) -> None:
    """Wait until something accepts connections on 127.0.0.1:``port``."""
    deadline = time.monotonic() + seconds
    while True:
        with socket.socket() as probe:
            if probe.connect_ex(("127.0.0.1", port)) == 0:
                return
        if time.monotonic() > deadline:
            raise RuntimeError(f"nothing listens on port {port} after {seconds} s")
        time.sleep(0.1)


@pytest.mark.parametrize("command", ["sample", "analyse"])
def test_a_port_that_is_not_a_scheduler_is_refused_not_waited_on(tmp_path, cli, command):
    """Issue 24, item 2: a web server on the port hung ``sample`` and ``analyse`` for ever."""
    out = "p.nc" if command == "sample" else "out"
    port = _free_port()
    server = _start([sys.executable, "-m", "http.server", str(port), "--bind", "127.0.0.1"])
    try:
        _listening(port)
        address = f"tcp://127.0.0.1:{port}"
        (tmp_path / "never-read.nc").touch()  # refused before any input is read
        argv = [command, "never-read.nc", "--out", out, "--scheduler", address]
        # The Dask check's 1 s timeout, far from this on any load.
        done = cli(argv, tmp_path, timeout=120, setup=SHORT_TIMEOUT)
    finally:
        _stop(server)
    assert done.code == 2, done.stderr
    assert address in done.stderr and "no Dask handshake" in done.stderr
    assert "within 1 s" in done.stderr


@pytest.mark.parametrize(
    "reply",
    [b"\xff" * 64, struct.pack("<QQ", 1, 3 * 2**60) + b"x" * 48, b"HTTP/1.0 200 OK\r\n\r\n"],
    ids=["ones", "a frame of 3 EiB", "http"],
)
def test_a_peer_that_answers_the_handshake_with_garbage_is_refused_by_name(reply):
    """Issue 37, item 12: such a peer on 127.0.0.1 ended in MemoryError (3.07 EiB), exit 1."""
    server = socket.create_server(("127.0.0.1", 0))
    port = server.getsockname()[1]

    def answer() -> None:  # every connection gets the reply, until the test closes the server
        while True:
            try:
                connection, _ = server.accept()
            except OSError:
                return
            with connection, contextlib.suppress(OSError):
                connection.recv(65536)
                connection.sendall(reply)
                connection.recv(65536)

    threading.Thread(target=answer, daemon=True).start()
    try:
        with pytest.raises(InputError, match=f"Dask scheduler at 'tcp://127.0.0.1:{port}'"):
            DaskExecutor(f"tcp://127.0.0.1:{port}", timeout=2.0).__enter__()
    finally:
        server.close()


@pytest.mark.parametrize("address", ["not-an-address", "bogus://"])
def test_a_scheduler_address_that_is_garbage_gives_one_line(tmp_path, address):
    """Issue 24, item 7: the refusal was followed by a Client.__del__ traceback."""
    (tmp_path / "never-read.nc").touch()  # refused before any input is read
    done = subprocess.run(
        [BIN / "bayes-jackal", "sample", "never-read.nc", "--out", "p.nc", "--scheduler", address],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 2
    assert done.stderr.count("\n") == 1 and address in done.stderr, done.stderr


def test_dask_executor_without_a_scheduler_address_refused():
    with pytest.raises(InputError, match="cannot reach the Dask scheduler at 'nowhere'"):
        with DaskExecutor("nowhere", timeout=1.0):
            pass


def test_dask_executor_without_the_extra_names_it(monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)  # import distributed fails
    with pytest.raises(InputError, match=r"pip install 'bayes-jackal\[cluster\]'"):
        DaskExecutor(DEAD_ADDRESS)


def test_workers_run_one_blas_thread_for_more_jobs_than_cores():
    # In a fresh interpreter whose BLAS has two threads (this suite's
    # processes have one): the workers forked from the server process keep
    # its two, unless they are single-threaded (more jobs than processes).
    job = (
        "sorted({pool['num_threads'] for pool in __import__('threadpoolctl').threadpool_info()"
        " if pool['user_api'] == 'blas'})"
    )
    code = (
        "from bayes_jackal.inference.executors import in_processes\n"
        "for single in (False, True):\n"
        f"    with in_processes(eval, [{job!r}] * 2, workers=2, single_threaded=single) as done:\n"
        "        print(single, sorted(map(tuple, done)))\n"
    )
    threads = dict.fromkeys(("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"), "2")
    done = subprocess.run(
        [sys.executable, "-c", code], env=os.environ | threads, capture_output=True, text=True,
        timeout=120, check=True,
    )  # fmt: skip
    assert done.stdout.splitlines() == ["False [(2,), (2,)]", "True [(1,), (1,)]"]


def test_workers_run_the_package_this_process_imported(tmp_path):
    # A copy of the package found first on a sys.path changed at run time: a
    # fork server would have imported the installed one before the workers
    # got this sys.path; the workers must run the copy, as this process does.
    shutil.copytree(Path(bayes_jackal.__file__).parent, tmp_path / "bayes_jackal")
    code = (
        f"import sys; sys.path.insert(0, {str(tmp_path)!r})\n"
        "import bayes_jackal\n"
        "from bayes_jackal.inference.executors import in_processes\n"
        "job = \"__import__('bayes_jackal').__file__\"\n"
        "with in_processes(eval, [job] * 2, workers=2) as done:\n"
        "    print(sorted(set(done)) == [bayes_jackal.__file__], bayes_jackal.__file__)\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True
    )
    assert done.stdout.split() == ["True", str(tmp_path / "bayes_jackal" / "__init__.py")]


def _doubled_with_a_word(value: int, pid_file: Path | None = None) -> int:
    """A job that tells, warns and fails as the package's own do (or waits, named by pid)."""
    if pid_file is not None:
        pid_file.write_text(str(os.getpid()))
        time.sleep(600)
    if value < 0:
        raise InputError(f"must be >= 0, got {value}", field="value")
    logging.getLogger("bayes_jackal.workflow").info(f"doubling {value}")
    warnings.warn(ConvergenceWarning(f"NOT CONVERGED: doubling {value}"), stacklevel=2)
    return 2 * value


@pytest.mark.parametrize("local", [True, False], ids=["in-a-worker", "here"])
def test_a_background_job_tells_and_warns_once_where_its_result_is_taken(local, capsys):
    # The job of 4 is never taken: the block's end takes it, its line told last.
    with printed("stdout"), pytest.warns(ConvergenceWarning, match="doubling 4"):
        with Background(local=local) as background:
            pending, failing, _ = (background.submit(_doubled_with_a_word, v) for v in (21, -1, 4))
            assert capsys.readouterr().out == ""  # nothing told before a result is taken
            with pytest.warns(ConvergenceWarning, match="NOT CONVERGED: doubling 21"):
                assert pending.result() == 42
            assert pending.result() == 42  # taken again: told once only
            with pytest.raises(InputError, match="value: must be >= 0, got -1"):
                failing.result()
            assert capsys.readouterr().out == "doubling 21\n"
    assert capsys.readouterr().out == "doubling 4\n"


def test_a_background_job_is_stopped_when_its_block_fails(tmp_path):
    # The worker waits 600 s: leaving the block on an interrupt ends it at once.
    pid_file = tmp_path / "worker.pid"
    with pytest.raises(KeyboardInterrupt), Background(local=True) as background:
        background.submit(_doubled_with_a_word, 1, pid_file)
        while not pid_file.exists():
            time.sleep(0.05)
        raise KeyboardInterrupt
    worker = int(pid_file.read_text())
    assert worker not in {child.pid for child in multiprocessing.active_children()}
    with pytest.raises(ProcessLookupError):
        os.kill(worker, 0)
