"""SIGINT and SIGTERM: one line, exit 130 / 143, nothing lost; resumed = uninterrupted."""

from __future__ import annotations

import contextlib
import gc
import io
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import emcee
import numpy as np
import pytest
import xarray as xr
from cli_helpers import (
    CLI,
    STOP_CPU_SECONDS,
    STOP_WALL_SECONDS,
    children_cpu_seconds,
    process_cpu_seconds,
    stored_steps,
)

from bayes_jackal._runtime import interrupt
from bayes_jackal.cli import main
from bayes_jackal.inference.chains import (
    BufferedHDFBackend,
    SamplerSettings,
    _run_until_converged,
)

#: The console script's entry point, run in a fresh interpreter.
#: One experiment, short chains, two families: the cheapest runs of every command.
QUICK = ["--seed", "3", "--max-steps", "200", "--channels", "yaw", "--no-progress", "--json"]
FAMILIES = ["--families", "white,exponential"]


@pytest.fixture
def handlers():
    """The package's handlers installed for one test, the previous ones restored after."""
    previous = interrupt.install_interrupts()
    yield
    interrupt.restore_interrupts(previous)


def test_interrupted_knows_its_signal_and_exit_code():
    for signum, code in ((signal.SIGINT, 130), (signal.SIGTERM, 143)):
        stop = interrupt.Interrupted(signum)
        assert isinstance(stop, KeyboardInterrupt)
        assert (stop.signum, stop.exit_code) == (signum, code)


def test_a_signal_raises_at_once_outside_deferred(handlers):
    with pytest.raises(interrupt.Interrupted) as stop:
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(1)  # the handler runs at the next bytecode: never reached
    assert stop.value.exit_code == 143


def test_restore_forgets_a_stop_so_later_work_in_the_process_runs():
    # A stop raised under the handlers stays pending until check(); once they
    # are restored (the command ended), later code calling check() must run.
    previous = interrupt.install_interrupts()
    try:
        with pytest.raises(interrupt.Interrupted):
            os.kill(os.getpid(), signal.SIGTERM)
            time.sleep(1)
    finally:
        interrupt.restore_interrupts(previous)
    assert interrupt.interrupt_pending() is None
    interrupt.check_interrupt()


def test_deferred_holds_a_signal_until_check_and_a_second_one_raises(handlers):
    with interrupt.interrupts_deferred():
        os.kill(os.getpid(), signal.SIGINT)
        reached = True  # recorded, not raised
        with pytest.raises(interrupt.Interrupted) as stop:
            interrupt.check_interrupt()
        assert stop.value.signum == signal.SIGINT
        interrupt.check_interrupt()  # raised once only
        os.kill(os.getpid(), signal.SIGINT)
        with pytest.raises(interrupt.Interrupted):
            os.kill(os.getpid(), signal.SIGTERM)  # the second one: at once
        # ... and it stays pending, in case the code it landed in swallows it.
        assert interrupt.interrupt_pending() == signal.SIGTERM
        with pytest.raises(interrupt.Interrupted):
            interrupt.check_interrupt()  # raised where nothing swallows it: no longer pending
    assert reached
    with pytest.raises(interrupt.Interrupted) as stop, interrupt.interrupts_deferred():
        os.kill(os.getpid(), signal.SIGTERM)
    assert stop.value.signum == signal.SIGTERM  # leaving the block raises what is pending


class _SignalOnAccess(tuple):
    """A 'random state' that sends SIGINT when emcee's setter reads it (inside its bare except)."""

    def __getitem__(self, index):
        os.kill(os.getpid(), signal.SIGINT)
        return super().__getitem__(index)


def _gaussian(x: np.ndarray) -> np.ndarray:
    return -0.5 * np.sum(x**2, axis=1)


def _sampler(log_prob, backend=None) -> emcee.EnsembleSampler:
    return emcee.EnsembleSampler(8, 2, log_prob, vectorize=True, backend=backend)


def test_emcee_swallows_an_interrupt_in_its_random_state_setter(handlers):
    """The hazard the deferral exists for: `except: pass` around set_state."""
    _sampler(_gaussian).random_state = _SignalOnAccess((1, 2))  # raised, and lost ...
    with pytest.raises(interrupt.Interrupted):
        interrupt.check_interrupt()  # ... but still pending: the next check (or the CLI) stops


class _RaisesWhenCollected:
    def __del__(self):
        os.kill(os.getpid(), signal.SIGINT)  # raised in a finaliser: Python cannot propagate it


def test_a_stop_raised_where_python_cannot_propagate_it_is_silent_and_sent_again(handlers, capsys):
    started = time.monotonic()
    with pytest.raises(interrupt.Interrupted) as stop:
        _RaisesWhenCollected()  # collected at once: "Exception ignored in ..." without the hook
        time.sleep(5)  # the stop is sent again once the finaliser has returned: never reached
    # RESEND_DELAY is 0.01 s; 1 s leaves room for a loaded machine.
    assert time.monotonic() - started < 1.0
    assert stop.value.signum == signal.SIGINT
    assert capsys.readouterr().err == ""


class _CutShort:
    """Stopped in its constructor before the attribute its finaliser reads (h5netcdf's File)."""

    def __init__(self):
        os.kill(os.getpid(), signal.SIGTERM)
        self._closed = False

    def __del__(self):
        if not self._closed:  # AttributeError: "Exception ignored in ..." without the hook
            self._closed = True


def test_the_finaliser_of_what_a_stop_cut_short_fails_quietly(handlers, capsys):
    with pytest.raises(interrupt.Interrupted) as stop:
        _CutShort()
    del stop  # its traceback held the half-built object
    gc.collect()
    assert capsys.readouterr().err == ""


def test_a_finaliser_failing_before_any_stop_is_still_reported(handlers, monkeypatch):
    shown = []
    monkeypatch.setitem(interrupt._previous_hooks, "unraisablehook", shown.append)
    _CutShort.__new__(_CutShort)  # never constructed, and no stop: a real fault
    gc.collect()
    assert [type(hook.exc_value) for hook in shown] == [AttributeError]


def test_a_swallowed_stop_sent_again_inside_deferred_is_held_as_the_first(handlers):
    _RaisesWhenCollected()
    with interrupt.interrupts_deferred():
        time.sleep(0.5)  # sent again here: held (a second signal would raise at once)
        assert interrupt.interrupt_pending() == signal.SIGINT
        with pytest.raises(interrupt.Interrupted):
            interrupt.check_interrupt()
        time.sleep(0.1)
    interrupt.check_interrupt()  # nothing left


def test_a_swallowed_stop_raised_by_check_is_not_sent_again(handlers):
    _RaisesWhenCollected()
    with pytest.raises(interrupt.Interrupted):
        interrupt.check_interrupt()  # before the resend's 0.01 s
    time.sleep(0.2)  # no second stop: nothing raised
    assert interrupt.interrupt_pending() is None


def test_emcee_catch_alls_neither_swallow_nor_print_an_interrupt(handlers, capsys):
    settings = SamplerSettings(max_steps=50, check_every=10)
    coords = np.random.default_rng(1).normal(size=(8, 2))
    # Inside the setter's `except: pass`: held, raised after the first step.
    sampler = _sampler(_gaussian)
    with pytest.raises(interrupt.Interrupted):
        _run_until_converged(
            sampler,
            emcee.State(coords, random_state=_SignalOnAccess((1,))),
            settings,
            ("a", "b"),
        )
    assert sampler.iteration == 1
    calls = []

    def signal_on_fifth_call(x):  # inside emcee's `except:` that prints the walkers
        calls.append(1)
        if len(calls) == 5:
            os.kill(os.getpid(), signal.SIGTERM)
        return _gaussian(x)

    # One call for the start, two a step (each half of the ensemble): the
    # fifth is step 2's second half, which finishes; then the stop.
    sampler = _sampler(signal_on_fifth_call)
    with pytest.raises(interrupt.Interrupted) as stop:
        _run_until_converged(sampler, emcee.State(coords), settings, ("a", "b"))
    assert stop.value.exit_code == 143
    assert sampler.iteration == 2
    assert capsys.readouterr().out == ""


def _chain(path: Path, settings: SamplerSettings, stop_at: int | None = None):
    """Run (or resume) a toy chain in ``path``; SIGINT on the ``stop_at``-th evaluation."""
    calls = []

    def log_prob(x):
        calls.append(1)
        if len(calls) == stop_at:
            os.kill(os.getpid(), signal.SIGINT)
        return _gaussian(x)

    backend = BufferedHDFBackend(str(path), settings.check_every)
    if not path.exists():
        backend.reset(8, 2)
    sampler = _sampler(log_prob, backend)
    start = (
        sampler.get_last_sample()
        if backend.iteration
        else emcee.State(
            np.random.default_rng(1).normal(size=(8, 2)),
            random_state=np.random.RandomState(2).get_state(),
        )
    )
    try:
        shortfall, tau = _run_until_converged(sampler, start, settings, ("a", "b"))
    finally:
        backend.flush()
    return shortfall is None, tau, sampler.get_chain()


def test_resumed_chain_equals_the_uninterrupted_one_at_every_stop(handlers, tmp_path):
    # The ESS rule decides (the 5-tau rule alone would stop at step 20 on a poor tau).
    settings = SamplerSettings(max_steps=3000, check_every=20, autocorr_multiple=5, min_ess=100)
    converged, tau, chain = _chain(tmp_path / "reference.h5", settings)
    assert converged and len(chain) < settings.max_steps  # it stopped on the criterion
    # Evaluation k > 0 belongs to step (k + 1) // 2 (one for the start, two a
    # step): stops in steps 2, 19, 20 (a check), 48, and the last (then a rerun).
    for stop_at in (3, 38, 40, 95, 2 * len(chain)):
        path = tmp_path / f"stopped_{stop_at}.h5"
        try:
            _chain(path, settings, stop_at)
        except interrupt.Interrupted:
            pass
        resumed = _chain(path, settings)
        assert resumed[0] == converged
        np.testing.assert_array_equal(resumed[1], tau)
        np.testing.assert_array_equal(resumed[2], chain)
        rerun = _chain(path, settings)  # a converged chain takes no more steps
        np.testing.assert_array_equal(rerun[2], chain)


@pytest.fixture(scope="module")
def experiment(tmp_path_factory) -> str:
    # Written in this process: a fresh interpreter's imports would cost ~2 s more.
    folder = tmp_path_factory.mktemp("experiment")
    args = ["simulate", "--out", str(folder), "--seed", "1", "--v1", "1", "--v2", "0"]
    with contextlib.redirect_stdout(io.StringIO()):
        assert main(args) == 0
    return str(folder / "v1_01.nc")


def _interrupt(
    args: list[str],
    delay: float,
    signum: int,
    *,
    after: str = "",
    until: Callable[[], bool] | None = None,
):
    """Signal the CLI ``delay`` s after ``after`` is on stderr (and ``until()`` holds).

    Returns (code, CPU s after the signal, out, err). How promptly a run
    stops is the CPU it spends after the signal (tests/cli_helpers.py,
    :data:`STOP_CPU_SECONDS`).
    """
    before = children_cpu_seconds()
    process = subprocess.Popen(
        [*CLI, *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    err = ""
    while after and after not in err:
        err += process.stderr.readline()
    while until is not None and not until() and process.poll() is None:
        time.sleep(0.02)
    time.sleep(delay)
    at_signal = process_cpu_seconds(process.pid)
    sent = time.monotonic()
    process.send_signal(signum)
    out, rest = process.communicate(timeout=60)
    assert time.monotonic() - sent < STOP_WALL_SECONDS, "waited after the signal"
    return process.returncode, children_cpu_seconds() - before - at_signal, out, err + rest


def _assert_clean_stop(code, cpu_after, out, err, signum):
    assert code == 128 + signum, err
    assert cpu_after < STOP_CPU_SECONDS
    assert out == ""  # stdout may carry --json
    assert "Traceback" not in err and "emcee:" not in err, err
    assert err.strip().splitlines()[-1].startswith("bayes-jackal: interrupted")


_KILLED_WHILE_CREATING = """
import os, signal, sys
from pathlib import Path
import h5py
from bayes_jackal.inference.chains import _backend
create_dataset = h5py.Group.create_dataset
def dying(self, *args, **kwargs):  # the first dataset written, then a hard kill
    create_dataset(self, *args, **kwargs)
    self.file.flush()
    os.kill(os.getpid(), signal.SIGKILL)
h5py.Group.create_dataset = dying
_backend(Path(sys.argv[1]), "run", 8, 2, 10)
"""


def test_a_chain_file_appears_only_whole(tmp_path):
    # CI once SIGKILLed `sample` while HDF5 was writing the new chain file's
    # header: the rerun refused the file as unreadable (exit 2), and could
    # not know it for its own. The file is now built beside its name and
    # moved into place whole, so a kill while creating it leaves none (only
    # the temporary, ".p.chain.h5.*.part"), and the rerun starts afresh.
    path = tmp_path / "p.chain.h5"
    killed = subprocess.run(
        [sys.executable, "-c", _KILLED_WHILE_CREATING, str(path)], capture_output=True
    )
    assert killed.returncode == -signal.SIGKILL, killed.stderr
    assert not path.exists()
    assert [p.name.endswith(".part") for p in tmp_path.iterdir()] == [True]


def test_sample_stops_cleanly_inside_emcee_and_says_it_resumes(experiment, tmp_path):
    # The signal once the chain has stored steps (written every 100), however
    # long the MAP search took; with all three channels the chain needs
    # thousands of steps, so it is still running then.
    chain = tmp_path / "p.chain.h5"
    args = ["sample", experiment, "--out", str(tmp_path / "p.nc"), "--seed", "3"]
    args += ["--no-progress", "--json", "--max-steps", "20000"]
    result = _interrupt(args, 0.0, signal.SIGINT, until=lambda: stored_steps(chain) > 0)
    _assert_clean_stop(*result, signal.SIGINT)
    steps = stored_steps(chain)
    assert steps > 0  # stopped inside emcee
    code, cpu_after, out, err = _interrupt(args, 0.0, signal.SIGTERM, after="resuming")
    _assert_clean_stop(code, cpu_after, out, err, signal.SIGTERM)
    assert f"resuming {chain} at step {steps}" in err


_STOPPED_AS_IT_EXITS = """
import os, signal, sys
from bayes_jackal import cli
command = cli.main
def main(*args, **kwargs):  # the command's work done, its last line printed: then a SIGTERM
    code = command(*args, **kwargs)
    os.kill(os.getpid(), signal.SIGTERM)
    return code
cli.main = main
cli.console(["--version"])
"""


def test_a_signal_as_the_command_exits_is_its_exit_code_not_swallowed():
    # compare exited 0 on a SIGTERM in its last second (issue 37, item 7): the
    # signals were ignored once the command's last line was out. They are
    # recorded, and the process exits 143, saying its outputs are whole.
    done = subprocess.run([sys.executable, "-c", _STOPPED_AS_IT_EXITS], capture_output=True,
                          text=True, timeout=60)  # fmt: skip
    assert done.returncode == 143, done.stderr
    assert done.stdout.startswith("bayes-jackal ")  # the command's own output, kept
    assert done.stderr.strip() == (
        "bayes-jackal: interrupted by SIGTERM as it exited, after everything it was to write "
        "had been written"
    )


def test_a_signal_during_the_imports_gives_one_line(experiment, tmp_path):
    args = ["sample", experiment, "--out", str(tmp_path / "p.nc"), *QUICK]
    code, cpu_after, out, err = _interrupt(args, 0.3, signal.SIGINT)  # imports take ~2 s
    _assert_clean_stop(code, cpu_after, out, err, signal.SIGINT)
    assert len(err.strip().splitlines()) == 1


@pytest.mark.parametrize("where", ["parsing", "command"])
def test_a_signal_an_extension_turns_into_an_import_error_is_a_stop(
    where, monkeypatch, tmp_path, capsys
):
    # CI: SIGINT landed while scipy's HiGHS extension initialised (imported by
    # the parser's family check), which raised "ImportError: initialization
    # failed" from the stop: exit 1 and a traceback. The same chain of
    # exceptions, raised where the parser and where a command import.
    from bayes_jackal.cli import commands, main, parser_types

    def failing_import(*args, **kwargs):
        try:
            raise interrupt.Interrupted(signal.SIGINT)
        except interrupt.Interrupted as stop:
            raise ImportError("initialization failed") from stop

    if where == "parsing":
        monkeypatch.setattr(parser_types, "registered_families", failing_import)
    else:
        monkeypatch.setattr(commands, "cmd_simulate", failing_import)
    argv = ["sample", str(tmp_path / "a.nc"), "--family", "white"]
    if where == "command":
        argv = ["simulate", "--out", str(tmp_path / "runs"), "--v1", "1", "--v2", "0"]
    assert main(argv) == 130
    err = capsys.readouterr().err
    assert err.strip().splitlines() == [
        "bayes-jackal: interrupted by SIGINT; what had finished is kept, and the same "
        "command resumes"
    ]


def _results(folder: Path, out: str) -> dict:
    """Every posterior array under ``folder``, and the command's JSON (evidence included)."""
    arrays = {}
    for path in sorted(folder.rglob("*.nc")):
        if path.parent.name == "experiments":
            continue
        for group in ("posterior", "sample_stats"):
            with xr.open_dataset(path, group=group) as data:
                for name, values in data.data_vars.items():
                    arrays[f"{path.relative_to(folder)}:{group}/{name}"] = values.values
    return {"arrays": arrays, "json": json.loads(out)}


def _assert_equal(results: dict, reference: dict) -> None:
    assert results["json"] == reference["json"]
    assert results["arrays"].keys() == reference["arrays"].keys()
    for name, values in reference["arrays"].items():
        np.testing.assert_array_equal(results["arrays"][name], values, err_msg=name)


COMMANDS = {
    "sample": ["sample", "{exp}", "--out", "{out}/p.nc", *QUICK],
    "compare": ["compare", "{exp}", "--out", "{out}", *QUICK, *FAMILIES, "--processes", "2"],
    "analyse": ["analyse", "{exp}", "--out", "{out}", *QUICK, *FAMILIES, "--processes", "1"],
}


@pytest.mark.slow
@pytest.mark.parametrize("command", list(COMMANDS))
def test_random_interrupts_resume_to_the_uninterrupted_results(experiment, tmp_path, command):
    """20 signals at random moments (SIGINT and SIGTERM in turn) on one command.

    ``BAYES_JACKAL_INTERRUPTS`` sets another count: CI runs 4 to stay within
    its time (.ci/run); the issue's 20 per command take ~6 min on 2 cores.

    Runs follow each other in one output folder: each is stopped at a random
    moment of a whole run, or finishes, resuming what the stopped ones kept;
    a finished run's results must equal the uninterrupted run's bit for bit,
    and the folder starts afresh.
    """
    template = COMMANDS[command]
    out = tmp_path / "out"
    args = [a.format(exp=experiment, out=out) for a in template]
    started = time.monotonic()
    reference = subprocess.run([*CLI, *args], capture_output=True, text=True, check=True)
    duration = time.monotonic() - started
    expected = _results(out, reference.stdout)
    shutil.rmtree(out)
    rng = np.random.default_rng(20)
    signals = [signal.SIGINT, signal.SIGTERM]
    interrupted = 0
    while interrupted < int(os.environ.get("BAYES_JACKAL_INTERRUPTS", "20")):
        signum = signals[interrupted % 2]
        code, cpu_after, stdout, err = _interrupt(args, rng.uniform(0.5, duration), signum)
        # Done before the signal (or the signal came as the interpreter exited,
        # its handlers reset: killed, quietly, with the output complete): the
        # run must have resumed to the same results.
        late = code == 128 + signum and "as it exited" in err  # after its last line
        if code == 0 or (code == -signum and stdout) or late:
            assert "Traceback" not in err, err
            _assert_equal(_results(out, stdout), expected)
            shutil.rmtree(out)
            continue
        _assert_clean_stop(code, cpu_after, stdout, err, signum)
        interrupted += 1
    # The last stop's leftovers, resumed: the same results as the uninterrupted run.
    rerun = subprocess.run([*CLI, *args], capture_output=True, text=True, check=True)
    _assert_equal(_results(out, rerun.stdout), expected)
