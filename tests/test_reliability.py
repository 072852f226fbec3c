"""The reliability suite of issue 11: the table of tests/reliability_cases.py, run for real.

Every case runs ``bayes-jackal`` in a subprocess, in a fresh folder, and must
give the expected exit code and words on stderr, with no traceback, every
input byte-identical and untouched (sha256 and mtime), no ``.part`` file
left, and stdout empty or strict JSON (no NaN, no Infinity) with ``--json``.

Starting Python and importing the package takes ~2 s, more than most cases
need, so plain cases run in a child forked from a "zygote": a Python process
started once per test session (per xdist worker) that has imported the
package and the libraries its commands load (tests/cli_helpers.py, through
the ``cli`` fixture of tests/conftest.py). Each child chdirs to the case's
folder, points fds 0-2 at /dev/null and files, and runs ``console(argv)``:
the same entry point as the console script and ``python -m
bayes_jackal.cli``. It then exits as the interpreter would (threads joined,
atexit functions run, streams flushed) but without the teardown that frees
every object (most of a plain case's CPU time, spent copying the zygote's
pages). Signal, lock-holder and full-disk cases, and everything when
``BAYES_JACKAL_RELIABILITY_EXEC=1``, exec a fresh interpreter instead, where
the interpreter's whole exit is checked too.
"""

from __future__ import annotations

import hashlib
import os
import shlex
import shutil
import signal
import subprocess
import time
from pathlib import Path

import pytest
from cli_helpers import CLI as MODULE
from cli_helpers import (
    ENV,
    STOP_CPU_SECONDS,
    STOP_WALL_SECONDS,
    Result,
    built_once,
    children_cpu_seconds,
    finish,
    process_cpu_seconds,
    start,
    stored_steps,
    strict_json,
)
from reliability_cases import CASES, Case, Library, mat, words_missing

INTERRUPT_LINE = r"interrupt|signal|sigint|sigterm|stopp|terminat"


@pytest.fixture(scope="session")
def library(cli, tmp_path_factory) -> Library:
    """One tiny simulated run as .nc, .csv, .mat, .bag, .mcap, and two short posteriors.

    Built once per test run: under xdist by the first worker that needs it, in
    the run's temporary folder that the workers share (another waits on a lock
    meanwhile, then reads it). The cases only copy from it.
    """
    commands = [
        "simulate --out runs --seed 1 --v1 1 --v2 0 --bag ros2",
        "simulate --out csv --seed 1 --v1 1 --v2 0 --format csv --bag ros1",
        "sample runs/v1_01.nc --out post/gaussian.nc --family gaussian --channels yaw "
        "--max-steps 200 --walkers 32 --seed 1 --no-progress",
        "sample runs/v1_01.nc --out post/white.nc --family white --channels yaw "
        "--max-steps 200 --walkers 32 --seed 1 --no-progress",
    ]

    def build(folder: Path) -> None:
        for command in commands:
            result = cli(shlex.split(command), folder)
            if result.code != 0:
                pytest.fail(f"could not build the library ({command}): {result.stderr}")
        mat()(_library(folder), _library(folder).mat)

    root = built_once(tmp_path_factory, "reliability-library", build)
    return _library(root)


def _library(root: Path) -> Library:
    return Library(
        root=root,
        nc=root / "runs/v1_01.nc",
        csv=root / "csv/v1_01.csv",
        mat=root / "v1_01.mat",
        bag=root / "csv/v1_01.bag",
        mcap=root / "runs/v1_01.mcap",
        posterior=root / "post/gaussian.nc",
        white_posterior=root / "post/white.nc",
    )


def _snapshot(folder: Path, mutable: tuple[str, ...]) -> dict[Path, tuple]:
    """sha256, size and mtime of every file under ``folder``."""
    skip = {folder / name for name in mutable}
    return {
        path: (hashlib.sha256(path.read_bytes()).hexdigest(), path.stat().st_mtime_ns)
        for path in sorted(folder.rglob("*"))
        if path.is_file() and not path.is_symlink() and path not in skip
    }


def _build(case: Case, library: Library, folder: Path) -> dict[Path, tuple]:
    folder.mkdir()
    for name, builder in case.files.items():
        path = folder / name
        path.parent.mkdir(parents=True, exist_ok=True)
        builder(library, path)
    return _snapshot(folder, case.mutable)


def _check(
    case: Case,
    result: Result,
    folder: Path,
    inputs: dict,
    *,
    exit=None,
    words=None,
) -> None:
    """What every case must satisfy, and the case's own checks.

    A rerun's ``words`` (it resumed, it reused a family) are looked for on
    both streams: a run's progress lines go to stdout, or to stderr with
    ``--json``.
    """
    argv = shlex.split(case.argv)
    expected = case.exit if exit is None else exit
    expected = expected if isinstance(expected, tuple) else (expected,)
    said = f"\n--- stderr ---\n{result.stderr[-3000:]}\n--- stdout ---\n{result.stdout[-1500:]}"
    assert result.code in expected, f"exit {result.code}, expected {expected}{said}"
    told = result.stderr if words is None else result.stderr + result.stdout
    missing = words_missing(case, told, words)
    assert not missing, f"the command did not say {missing}{said}"
    if "--debug" not in argv:
        assert "Traceback" not in result.stderr, f"a traceback reached the user{said}"
    if "--json" in argv:
        # Nothing, or one whole document (a signal may land after it was written).
        if result.stdout.strip() or result.code == 0:
            try:
                strict_json(result.stdout)
            except ValueError as exc:
                pytest.fail(f"stdout is not strict JSON ({exc}){said}")
    for text in case.stdout_lacks:
        assert text not in result.stdout, f"stdout holds {text!r}{said}"
    after = _snapshot(folder, case.mutable)
    changed = [str(p.relative_to(folder)) for p, state in inputs.items() if after.get(p) != state]
    assert not changed, f"inputs changed or touched: {changed}{said}"
    parts = [str(p.relative_to(folder)) for p in folder.rglob("*.part")]
    assert not parts, f"half-written files left: {parts}{said}"
    for pattern in case.exists:
        assert list(folder.glob(pattern)), f"{pattern} was not written{said}"
    for pattern in case.absent:
        found = [str(p.relative_to(folder)) for p in folder.glob(pattern)]
        assert not found, f"{found} should not exist{said}"
    for pattern, count in case.count.items():
        found = sorted(str(p.relative_to(folder)) for p in folder.glob(pattern))
        assert len(found) == count, f"{pattern}: {found}, expected {count} files{said}"
    for name in case.json_files:
        try:
            strict_json((folder / name).read_text())
        except (OSError, ValueError) as exc:
            pytest.fail(f"{name} is not strict JSON ({exc}){said}")


def _wait_for(folder: Path, pattern: str, process, timeout: float) -> bool:
    """Until a file matches ``pattern``; a chain file (``*.chain.h5``) once it holds steps.

    A chain file is made before the MAP search: a signal then would leave
    nothing to resume.
    """

    def there() -> bool:
        found = list(folder.glob(pattern))
        if pattern.endswith(".chain.h5"):
            return any(stored_steps(path) > 0 for path in found)
        return bool(found)

    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline and process.poll() is None:
        if there():
            return True
        time.sleep(0.05)
    return there()


def _run_signal(case: Case, folder: Path, inputs: dict, cli) -> None:
    argv = shlex.split(case.argv)
    before = children_cpu_seconds()
    process = start(argv, folder, script=case.script)
    if case.trigger:
        assert _wait_for(folder, case.trigger, process, case.timeout), (
            f"{case.trigger} never appeared (exit {process.poll()})"
        )
    else:
        time.sleep(case.delay)
    assert process.poll() is None, "the command ended before the signal"
    at_signal = process_cpu_seconds(process.pid)
    sent = time.monotonic()
    # Ctrl-C reaches the terminal's whole process group; kill(1) one process.
    if case.signum == signal.SIGINT:
        os.killpg(process.pid, case.signum)
    else:
        os.kill(process.pid, case.signum)
    result = finish(process, 30)
    waited = time.monotonic() - sent
    stopping = children_cpu_seconds() - before - at_signal
    if case.signum != signal.SIGKILL:
        _check(case, result, folder, inputs)
        assert stopping <= STOP_CPU_SECONDS, f"{stopping:.2f} s of CPU after the signal"
        assert waited <= STOP_WALL_SECONDS, f"stopped {waited:.1f} s after the signal"
        lines = [line for line in result.stderr.splitlines() if line.strip()]
        said = [line for line in lines if __import__("re").search(INTERRUPT_LINE, line, 2)]
        assert len(said) == 1, f"expected one line about the signal: {lines[-10:]}"
        if case.delay:  # during the imports: that line and nothing else
            assert len(lines) <= 2, lines
    else:
        assert result.code == case.exit
    if case.rerun:
        code, words = case.rerun
        again = cli(argv, folder, timeout=case.timeout)
        _check(case, again, folder, inputs, exit=code, words=words)


def _run_lock(case: Case, folder: Path, inputs: dict, cli) -> None:
    argv = shlex.split(case.argv)
    holder = start(argv, folder)
    try:
        assert _wait_for(folder, "**/*.lock", holder, 60), (
            f"no lock file appeared (holder exit {holder.poll()})"
        )
        assert _wait_for(folder, case.trigger, holder, 60)
        second = cli(argv, folder, timeout=30)
        _check(case, second, folder, inputs, words=(*case.words, str(holder.pid)))
        assert holder.poll() is None, "the holder ended while the second run was refused"
    finally:
        if holder.poll() is None:
            holder.send_signal(signal.SIGTERM)
        first = finish(holder, 30)
    assert first.code in (130, 143), f"holder exit {first.code}: {first.stderr[-2000:]}"
    assert "Traceback" not in first.stderr, first.stderr


def _run_tmpfs(case: Case, folder: Path, inputs: dict, cli) -> None:
    """The output folder ``disk`` on a 4 MB tmpfs with ``limit`` bytes free (0: 1 MB)."""
    if shutil.which("unshare") is None:
        pytest.skip("no unshare(1) to mount a private tmpfs")
    disk, saved = folder / "disk", folder.parent / f"{folder.name}.saved"
    disk.mkdir()
    saved.mkdir()
    command = shlex.join(MODULE + shlex.split(case.argv))
    fill = (4 << 20) - (case.limit or 1 << 20)
    script = "\n".join(
        [
            "mount -t tmpfs -o size=4m tmpfs disk || exit 97",
            f"head -c {fill} /dev/zero > disk/.filler 2>/dev/null",
            f"{command} > ../{folder.name}.stdout 2> ../{folder.name}.stderr",
            f"echo $? > ../{folder.name}.code",
            "rm -f disk/.filler",
            f"{command} > ../{folder.name}.stdout2 2> ../{folder.name}.stderr2"
            if case.rerun
            else "",
            f"echo $? > ../{folder.name}.code2",
            f"cp -a disk/. {shlex.quote(str(saved))}/",
        ]
    )
    status = subprocess.run(
        ["unshare", "-rm", "sh", "-c", script], cwd=folder, env=ENV, timeout=180, check=False
    ).returncode
    if status == 97 or not (folder.parent / f"{folder.name}.code").exists():
        pytest.skip(f"cannot mount a tmpfs in a user namespace here (unshare exit {status})")
    shutil.copytree(saved, disk, dirs_exist_ok=True)

    def outcome(suffix: str) -> Result:
        read = lambda kind: (folder.parent / f"{folder.name}.{kind}{suffix}").read_text()  # noqa: E731
        return Result(int(read("code")), read("stdout"), read("stderr"), 0.0)

    _check(case, outcome(""), folder, inputs)
    if case.rerun:
        code, words = case.rerun
        _check(case, outcome("2"), folder, inputs, exit=code, words=words)


def _run(case: Case, folder: Path, inputs: dict, cli) -> None:
    argv = shlex.split(case.argv)
    result = cli(
        argv, folder, fsize=case.limit if case.kind == "fsize" else 0, timeout=case.timeout
    )
    _check(case, result, folder, inputs)
    if case.rerun:
        code, words = case.rerun
        again = cli(argv, folder, timeout=case.timeout)
        _check(case, again, folder, inputs, exit=code, words=words)


RUNNERS = {
    "run": _run,
    "fsize": _run,
    "signal": _run_signal,
    "lock": _run_lock,
    "tmpfs": _run_tmpfs,
}


def test_table_has_150_distinct_cases():
    ids = [case.id for case in CASES]
    assert len(ids) == len(set(ids)), sorted({i for i in ids if ids.count(i) > 1})
    assert len(CASES) >= 150
    assert {case.kind for case in CASES} == set(RUNNERS)


@pytest.mark.parametrize("case", CASES, ids=[case.id for case in CASES])
def test_reliability(case: Case, library: Library, cli, tmp_path: Path) -> None:
    folder = tmp_path / "case"
    inputs = _build(case, library, folder)
    RUNNERS[case.kind](case, folder, inputs, cli)
