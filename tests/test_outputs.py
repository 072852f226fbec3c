"""Outputs never replace inputs, one run per output, write errors and a full disk (issue 11).

Through the real command line: in-process (:func:`bayes_jackal.cli.main`)
where one process is enough, in another process for a second run and a
file-size limit (RLIMIT_FSIZE, SIGXFSZ ignored: the portable simulated write
error), forked by the ``cli`` fixture (tests/conftest.py) from a process that
has the package imported, and in a fresh interpreter on a real full file
system (a 1 MB tmpfs in a private mount namespace, where ``unshare -rm``
works; skipped with the reason elsewhere).
"""

from __future__ import annotations

import json
import os
import re
import shlex
import shutil
import signal
import stat
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import pytest
from cli_helpers import CLI

from bayes_jackal._runtime.errors import InputError, OutputError
from bayes_jackal._runtime.files import write_json
from bayes_jackal._runtime.output_safety import (
    Output,
    OutputLock,
    OutputLockedError,
    check_outputs,
    protected,
)
from bayes_jackal.cli import main

#: A cheap chain: white noise, 200 steps (two flushes of 100).
CHEAP = ["--family", "white", "--max-steps", "200", "--no-progress", "--seed", "1"]


@pytest.fixture(scope="module")
def runs(tmp_path_factory) -> Path:
    """``simulate --out runs --seed 1 --v1 2 --v2 0``: runs/v1_01.nc and runs/v1_02.nc."""
    folder = tmp_path_factory.mktemp("outputs")
    assert (
        main(["simulate", "--out", str(folder / "runs"), "--seed", "1", "--v1", "2", "--v2", "0"])
        == 0
    )
    return folder / "runs"


def _hidden(folder: Path) -> list[str]:
    """Temporaries and lock files left anywhere under ``folder``."""
    return sorted(p.name for p in folder.rglob(".*") if p.suffix in (".part", ".lock"))


# --------------------------------------------------------------------------- before any work


@pytest.mark.parametrize(
    "command",
    [
        ["sample", "{exp}", "--out", "{exp}"],
        ["grid", "{exp}", "--out", "{exp}"],
        ["export-prior", "{exp}", "--out", "{exp}"],
        ["report", "{exp}", "--out", "{exp}"],
        ["sample", "{exp}", "--out", "{link}"],  # the same file by inode
        ["grid", "{exp}", "--out", "{symlink}"],
        ["ingest", "{exp}", "--out", "{exp}"],
    ],
)
def test_an_output_that_is_an_input_is_refused_before_any_work(runs, tmp_path, capsys, command):
    experiment = tmp_path / "v1_01.nc"
    shutil.copy(runs / "v1_01.nc", experiment)
    link, symlink = tmp_path / "link.nc", tmp_path / "symlink.nc"
    os.link(experiment, link)
    symlink.symlink_to(experiment)
    before = experiment.read_bytes()
    names = {"exp": experiment, "link": link, "symlink": symlink}
    code = main([part.format(**names) for part in command])
    err = capsys.readouterr().err
    assert code == 2, err
    assert f"is the input {experiment}" in err and "never replaces an input" in err
    assert experiment.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["link.nc", "symlink.nc", "v1_01.nc"]


@pytest.mark.parametrize(
    ("command", "words"),
    [
        (["sample", "{exp}", "--out", "{folder}"], "is an existing folder; give a file name"),
        (["compare", "{exp}", "--out", "{file}"], "is an existing file; give a folder"),
        (["simulate", "--out", "{file}"], "is an existing file; give a folder"),
        (["grid", "{exp}", "--plot", "{tmp}/x.xyz"], "'.xyz' is not a known suffix; use .png"),
        (["grid", "{exp}", "--out", "{tmp}/g.png"], "'.png' is not a known suffix; use .nc"),
        (["sample", "{exp}", "--out", "{tmp}/p"], "no suffix is not a known suffix; use .nc"),
        (["export-prior", "{exp}", "--out", "{tmp}/p.txt"], "use .json"),
        (["report", "{exp}", "--out", "{tmp}/r.pdf"], "use .html"),
    ],
)
def test_a_bad_output_is_refused_fast_with_exit_2(runs, tmp_path, capsys, command, words):
    (tmp_path / "folder").mkdir()
    (tmp_path / "file").write_text("keep me")
    names = {"exp": runs / "v1_01.nc", "folder": tmp_path / "folder", "file": tmp_path / "file"}
    argv = [part.format(tmp=tmp_path, **names) for part in command]
    code = main(argv)
    err = capsys.readouterr().err
    assert code == 2 and words in err, err
    assert sorted(p.name for p in tmp_path.rglob("*")) == ["file", "folder"]  # no chain, no lock
    assert (tmp_path / "file").read_text() == "keep me"
    # Refused before the command's imports (numpy, scipy: seconds on a busy
    # machine), let alone reading or sampling (issue 37, item 8).
    assert _refusal_in_a_fresh_process(argv) == (2, False)


def _refusal_in_a_fresh_process(argv: list[str]) -> tuple[int, bool]:
    """main(argv)'s exit code in a new interpreter, and whether numpy was loaded by then."""
    script = (
        "import sys; from bayes_jackal.cli import main; "
        f"code = main({argv!r}); print(code, 'numpy' in sys.modules)"
    )
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True)
    code, loaded = done.stdout.split()
    return int(code), loaded == "True"


def test_a_second_run_on_a_held_output_is_refused_before_the_imports(runs, tmp_path):
    # A run in progress holds p.nc: the second is refused at once, naming it.
    out = tmp_path / "p.nc"
    argv = ["sample", str(runs / "v1_01.nc"), "--out", str(out)]
    with OutputLock(out):
        assert _refusal_in_a_fresh_process(argv) == (2, False)


@pytest.mark.parametrize(
    ("command", "absent"),
    [
        (["sample", "{tmp}/nothere.bag", "--out", "{tmp}/p.nc"], ["nothere.bag"]),
        (["analyse", "{tmp}/a.bag", "{tmp}/b.bag", "--out", "{tmp}/analysis"], ["a.bag", "b.bag"]),
        (["report", "{tmp}/absent.nc", "--out", "{tmp}/r.html"], ["absent.nc"]),
        (["export-prior", "{tmp}/absent.nc", "--out", "{tmp}/prior.json"], ["absent.nc"]),
    ],
    ids=["sample", "analyse-two", "report", "export-prior"],
)
def test_a_command_none_of_whose_inputs_exists_is_refused_before_the_imports(
    command, absent, tmp_path, capsys
):
    # Where some inputs exist, the command runs and names the absent ones
    # (tests/test_cli.py: ..._finishes_the_good_inputs_and_names_the_bad_one).
    argv = [part.format(tmp=tmp_path) for part in command]
    assert _refusal_in_a_fresh_process(argv) == (2, False)
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert all(f"{tmp_path / name}: no such file" in err for name in absent), err
    assert list(tmp_path.iterdir()) == []  # no folder, chain or lock left


@pytest.mark.parametrize(
    "command",
    [
        ["sample", "{exp}", "--out", "{fifo}"],
        ["filter", "{exp}", "--prior", "{exp}", "--out", "{fifo}"],
        ["export-prior", "{exp}", "--out", "{fifo}"],
        ["report", "{exp}", "--out", "{fifo}"],
    ],
)
def test_a_named_pipe_given_as_the_output_is_refused_not_replaced(runs, tmp_path, capsys, command):
    # Written in place (a temporary renamed over it), the pipe a user's
    # reader listens on would become a regular file, exit 0.
    suffix = {"sample": ".nc", "filter": ".csv", "export-prior": ".json", "report": ".html"}
    fifo = tmp_path / f"out{suffix[command[0]]}"
    os.mkfifo(fifo)
    code = main([part.format(exp=runs / "v1_01.nc", fifo=fifo) for part in command])
    err = capsys.readouterr().err
    assert code == 2 and f"--out {fifo}: is a named pipe, not a file" in err, err
    assert stat.S_ISFIFO(os.stat(fifo).st_mode)
    assert sorted(p.name for p in tmp_path.iterdir()) == [fifo.name]


def test_an_output_folder_1400_levels_deep_is_made(tmp_path, capsys):
    # pathlib's mkdir(parents=True) recursed per missing level past Python's
    # stack: exit 1 with a RecursionError. (2,799 characters: inside Linux's
    # 4,096. Removed level by level: pytest's own clean-up recurses too.)
    deep = Path(tmp_path, *["d"] * 1400)
    try:
        code = main(["simulate", "--out", str(deep), "--seed", "3", "--v1", "1", "--v2", "0"])
        assert code == 0, capsys.readouterr().err
        assert (deep / "v1_01.nc").is_file()
    finally:
        for path in deep.glob("*"):
            path.unlink()
        while deep != tmp_path:
            deep.rmdir()
            deep = deep.parent


def test_two_outputs_of_one_command_never_share_a_path(tmp_path):
    shared = tmp_path / "a" / ".." / "x.nc"
    outputs = [Output(tmp_path / "x.nc"), Output(shared, flag="--plot")]
    with pytest.raises(InputError, match=r"--plot .*x\.nc: is also --out; two outputs cannot"):
        check_outputs(outputs, inputs=[])


def test_a_computed_name_never_replaces_an_input(tmp_path):
    # sample --out p.nc writes p.<experiment>.nc: checked where it is written.
    given = tmp_path / "p.v1_01.nc"
    given.write_bytes(b"field recording")
    with protected([given]), pytest.raises(InputError, match="would replace the input"):
        write_json(tmp_path / "p.v1_01.nc", {"a": 1})
    assert given.read_bytes() == b"field recording" and _hidden(tmp_path) == []
    write_json(given, {"a": 1})  # outside the command's run it is a plain file


def test_sample_creates_the_output_folder_and_a_second_run_is_refused_naming_the_holder(
    runs, tmp_path, cli
):
    out = tmp_path / "new" / "dir" / "p.nc"
    assert main(["sample", str(runs / "v1_01.nc"), "--out", str(out), *CHEAP]) == 0
    chain = out.with_suffix(".chain.h5")
    before = chain.read_bytes(), out.read_bytes()
    assert _hidden(tmp_path) == []  # the lock file went with the run
    with OutputLock(out) as held:
        holder = json.loads(held.lock_file.read_text())
        assert holder["pid"] == os.getpid()
        started = time.perf_counter()
        result = cli(["sample", str(runs / "v1_01.nc"), "--out", str(out), *CHEAP], tmp_path)
        seconds = time.perf_counter() - started
        with pytest.raises(OutputLockedError, match=f"pid {os.getpid()} on "):
            OutputLock(out).__enter__()
    assert result.code == 2, result.stderr
    assert f"is in use by another run (pid {os.getpid()} on " in result.stderr
    assert seconds < 30.0  # at once: no MAP search, no step
    assert (chain.read_bytes(), out.read_bytes()) == before  # never spliced


def test_a_killed_holder_never_blocks_the_next_run(tmp_path):
    out = tmp_path / "p.nc"
    holder = subprocess.Popen(
        [
            sys.executable,
            "-c",
            "import sys, time; from bayes_jackal._runtime.output_safety import OutputLock\n"
            f"with OutputLock({str(out)!r}):\n    print('held', flush=True); time.sleep(60)",
        ],
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert holder.stdout.readline() == "held\n"
        with pytest.raises(OutputLockedError, match=f"pid {holder.pid} "):
            OutputLock(out).__enter__()
    finally:
        holder.send_signal(signal.SIGKILL)
        holder.wait()
        holder.stdout.close()
    assert (tmp_path / ".p.nc.lock").exists()  # left by the killed run, but unlocked
    with OutputLock(out):
        pass
    assert _hidden(tmp_path) == []


# --------------------------------------------------------------------------- write errors


def test_a_write_error_names_the_users_path_and_leaves_nothing(runs, tmp_path, cli):
    grid = ["--d-lat", "100", "120", "10", "--d-long", "20", "40", "10"]
    plot = tmp_path / "out" / "grid.svg"
    result = cli(
        ["grid", str(runs / "v1_01.nc"), *grid, "--plot", str(plot)], tmp_path, fsize=4096
    )
    assert result.code == 1, result.stderr
    assert f"{plot}: cannot write: file too large" in result.stderr
    assert ".part" not in result.stderr and "Traceback" not in result.stderr
    assert not (tmp_path / "out").exists()  # made for the plot, left empty: removed


def test_a_file_size_limit_leaves_the_chain_resumable(runs, tmp_path, capsys, cli):
    out = tmp_path / "p.nc"
    chain = out.with_suffix(".chain.h5")
    args = ["sample", str(runs / "v1_01.nc"), "--out", str(out), *CHEAP]
    # 800 kB: the first flush (100 steps) needs 0.61 MB with the margins (32 walkers, 8
    # parameters, chunks of 128 steps: 0.27 MB, + 25 % + 0.26 MB); the second does not fit
    # beside the 0.32 MB file.
    limited = cli(args, tmp_path, fsize=800_000)
    assert limited.code == 1, limited.stderr
    assert f"{chain}: cannot write: file too large for the file-size limit" in limited.stderr
    assert "resumes: free some space and run the same command again" in limited.stderr
    assert ".part" not in limited.stderr and not out.exists() and _hidden(tmp_path) == []
    with h5py.File(chain, "r") as stored:
        kept = int(stored["mcmc"].attrs["iteration"])
        prefix = stored["mcmc/chain"][:kept]
    assert kept == 100
    # Resumed without the limit, in this process.
    capsys.readouterr()
    code = main(args)
    said = capsys.readouterr()
    assert code == 0, said.err
    assert f"resuming {chain} at step 100" in said.out + said.err
    with h5py.File(chain, "r") as stored:
        assert stored["mcmc"].attrs["iteration"] == 200
        np.testing.assert_array_equal(stored["mcmc/chain"][:kept], prefix)


# --------------------------------------------------------------------------- a full disk


def _tiny_tmpfs(tmp_path: Path) -> Path:
    """A folder to mount a 1 MB tmpfs on with ``unshare -rm``; skip where that is refused."""
    mount = tmp_path / "disk"
    mount.mkdir()
    probe = ["unshare", "-rm", "sh", "-c", f"mount -t tmpfs -o size=1m tmpfs {mount}"]
    try:
        works = subprocess.run(probe, capture_output=True, timeout=30).returncode == 0
    except (OSError, subprocess.TimeoutExpired):
        works = False
    if not works:
        pytest.skip("no tiny tmpfs: unshare -rm (user and mount namespaces) is not allowed here")
    return mount


def _on_tiny_disk(mount: Path, script: str) -> subprocess.CompletedProcess:
    """Run shell ``script`` in ``mount``, a fresh 1 MB tmpfs ($BJ: the command line)."""
    cli = shlex.join(CLI)
    setup = f"mount -t tmpfs -o size=1m tmpfs {mount} && cd {mount} && BJ={shlex.quote(cli)}"
    env = {**os.environ, "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}
    return subprocess.run(
        ["unshare", "-rm", "sh", "-c", f"{setup} && {script}"],
        capture_output=True,
        text=True,
        env=env,
        timeout=300,
    )


def test_simulate_on_a_full_disk_names_the_file_and_never_crashes(tmp_path):
    mount = _tiny_tmpfs(tmp_path)
    # Four 0.28 MB experiments on 1 MB: the third would not fit with its margin.
    result = _on_tiny_disk(
        mount, "eval $BJ simulate --out sim --seed 1 --v1 4 --v2 0; echo exit=$?; ls -a sim"
    )
    assert "exit=1" in result.stdout, result.stderr  # was a segmentation fault (139)
    assert "sim/v1_03.nc: cannot write: no space left on device (" in result.stderr
    assert ".part" not in result.stdout + result.stderr and "Traceback" not in result.stderr
    assert result.stdout.split()[-2:] == ["v1_01.nc", "v1_02.nc"]


@pytest.mark.slow
def test_sample_on_a_full_disk_keeps_a_chain_that_resumes_bit_for_bit(runs, tmp_path):
    mount = _tiny_tmpfs(tmp_path)
    sample = f"eval $BJ sample {runs / 'v1_01.nc'} --out p.nc {' '.join(CHEAP[:2])} "
    sample += f"--max-steps 400 {' '.join(CHEAP[4:])}"
    script = (
        f'{sample}; echo "exit=$?"; echo "files:" $(ls -A); '
        # free space (a bigger file system), then the same command resumes
        f'mount -o remount,size=8m {mount} && {sample}; echo "exit=$?"; cp p.chain.h5 {tmp_path}'
    )
    result = _on_tiny_disk(mount, script)
    codes = re.findall(r"^exit=(\d+)$", result.stdout, flags=re.MULTILINE)
    files = re.findall(r"^files: (.*)$", result.stdout, flags=re.MULTILINE)
    assert codes == ["1", "0"], result.stderr  # the first was a segmentation fault (139)
    assert "p.chain.h5: cannot write: no space left on device" in result.stderr
    assert "the chain file keeps the steps stored so far and resumes" in result.stderr
    assert files == ["p.chain.h5"]  # no .part, no half posterior, no lock
    fresh = tmp_path / "fresh" / "p.nc"
    assert main(["sample", str(runs / "v1_01.nc"), "--out", str(fresh), *CHEAP[:2], "--max-steps",
                 "400", *CHEAP[4:]]) == 0  # fmt: skip
    with (
        h5py.File(tmp_path / "p.chain.h5") as resumed,
        h5py.File(fresh.with_suffix(".chain.h5")) as once,
    ):
        assert resumed["mcmc"].attrs["iteration"] == once["mcmc"].attrs["iteration"] == 400
        np.testing.assert_array_equal(resumed["mcmc/chain"][:], once["mcmc/chain"][:])


def test_an_output_error_is_an_os_error_naming_the_path():
    error = OutputError("runs/p.nc", "no space left on device", code=28)
    assert isinstance(error, OSError) and error.errno == 28
    assert str(error) == "runs/p.nc: cannot write: no space left on device"
