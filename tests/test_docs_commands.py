"""Every shell command and Python block of README.md and the docs' pages runs as written.

A reader follows a page from its top: each page runs in a fresh folder that
holds only the files a reader brings (:func:`reader_files`: their logs, a
gyro series, a standstill bag, a robot profile), its blocks in order, each
``sh`` block by bash with the installed console script on the ``PATH``
(``.venv`` in the folder is this interpreter's environment), the ``python``
blocks between two ``sh`` blocks as one script (a block guarded by
``if __name__ == "__main__":`` as a script of its own). A block must exit 0.

An HTML comment on the line before a fence marks a block:

- ``<!-- not-run: REASON -->``: not run; the reason says why (an install, a
  server that outlives the block, a test that runs it elsewhere);
- ``<!-- synopsis -->``: a command's usage: every ``--flag`` it names must be
  one its parser has;
- ``<!-- file: NAME -->``: a ``text`` block written to NAME before the
  page's blocks run (a groups CSV, say).

The settings are made small (:data:`SMALL`, :data:`PYTHON_SMALL`) so that
the pages run in minutes: every chain is capped at a few hundred steps and
analyse skips the leave-one-out state estimation; each rewrite must apply
somewhere, so the table cannot outlive the docs it shortens.
"""

from __future__ import annotations

import os
import re
import shlex
import shutil
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
import scipy.signal
from mocap_simulator import imu_message, write_ros1

from bayes_jackal.cli.parser import build_parser
from bayes_jackal.model import default_profile_path
from bayes_jackal.workflow import demo_folder

ROOT = Path(__file__).resolve().parent.parent
#: The pages in the order a reader meets them: the README, then the guide's nav.
PAGES = ["README.md", "docs/index.md"] + [
    f"docs/{name}.md"
    for name in (
        "guide/getting-started", "guide/commands", "guide/data", "guide/robots", "guide/model",
        "families", "guide/evidence", "guide/population", "guide/criticism", "guide/prior",
        "active_inference", "guide/state-estimation", "guide/noise", "guide/reports",
        "guide/python", "guide/clusters", "guide/safety", "guide/thesis", "guide/development",
    )
]  # fmt: skip
#: Flags that keep each command's chains short, put at the end of its line.
SMALL = {
    "analyse": "--max-steps 200 --no-state-estimation --no-progress",
    "compare": "--max-steps 200 --no-progress",
    "sample": "--max-steps 200 --no-progress",
    "population": "--max-steps 200 --no-progress",
    "noise": "--max-steps 300 --no-progress",
}
#: The same for the Python API: text -> its replacement, in Python blocks (one
#: pass, the longest text first, so that a replacement is not rewritten again).
PYTHON_SMALL = {
    "seed=1": "seed=1, max_steps=200",
    '"analysis", seed=1)': '"analysis", seed=1, settings=SHORT, state_estimation=False)',
    "load_profile(), seed=1)": "load_profile(), seed=1, settings=SHORT)",
    "characterise_noise(series)": "characterise_noise(series, settings=SHORT)",
    "executor=bj.inference.ProcessExecutor(2),": (
        "executor=bj.inference.ProcessExecutor(2), settings=SHORT, state_estimation=False,"
    ),
}
#: A block guarded by this runs as a script of its own: its worker processes
#: import its file, and would run the page's other blocks again.
MAIN = 'if __name__ == "__main__":'
#: The settings ``SHORT`` of :data:`PYTHON_SMALL`'s rewrites.
SHORT = "SHORT = __import__('bayes_jackal').SamplerSettings(max_steps=200)\n"
PYTHON_TEXT = re.compile(
    "|".join(re.escape(old) for old in sorted(PYTHON_SMALL, key=len, reverse=True)) + r"(?!\d)"
)
#: The README's install before a command: the package is installed here already.
INSTALL = "python3 -m venv .venv && .venv/bin/pip install . && "
FENCE = re.compile(
    r"^(?P<marks>(?:<!-- [^>]*? -->\n)*)```(?P<lang>\w*)\n(?P<text>.*?)^```", re.M | re.S
)
#: The marks of this test; other comments (README's ``<!-- test-command -->``, say) are not.
MARK = re.compile(r"<!-- ((?:not-run|synopsis|file)\b[^>]*?) -->")
COMMAND = re.compile(
    r"^(?P<head>(?:\.venv/bin/)?bayes-jackal (?P<verb>[a-z-]+)\b[^#\n]*?)(?P<tail>\s*(?:#.*)?)$",
    re.M,
)


@dataclass(frozen=True)
class Block:
    """A fenced block of a page: its language, text, mark and first line."""

    page: str
    line: int
    lang: str
    text: str
    mark: str

    @property
    def where(self) -> str:
        return f"{self.page}:{self.line}"


def page_blocks(page: str) -> list[Block]:
    """The ``sh``, ``python`` and marked blocks of a page, in order."""
    text = (ROOT / page).read_text(encoding="utf-8")
    blocks = []
    for match in FENCE.finditer(text):
        line = text.count("\n", 0, match.start("lang")) + 1
        marks = MARK.findall(match["marks"])
        block = Block(page, line, match["lang"], match["text"], marks[0] if marks else "")
        if block.lang in ("sh", "python") or block.mark:
            blocks.append(block)
    return blocks


def small(block: Block, applied: set[str]) -> str:
    """The block's text with :data:`SMALL`'s flags or :data:`PYTHON_SMALL`'s rewrites."""
    if block.lang == "python":

        def rewrite(match: re.Match) -> str:
            applied.add(match[0])
            return PYTHON_SMALL[match[0]]

        return PYTHON_TEXT.sub(rewrite, block.text)

    def shorten(match: re.Match) -> str:
        flags = SMALL.get(match["verb"])
        if flags is None:
            return match[0]
        applied.add(match["verb"])
        return f"{match['head']} {flags}{match['tail']}"

    return COMMAND.sub(shorten, block.text.replace(INSTALL, ""))


def reader_files(folder: Path) -> None:
    """What a reader brings: two logs, a gyro series, a standstill bag and a robot profile.

    The logs are the demo's bags under the names the pages use; the gyro
    series and the standstill bag hold an AR(1) yaw rate (coefficient 0.9,
    sd 0.01 rad/s, 100 Hz, 60 s and 20 s: a coloured sensor) made here; the
    profile is the Jackal's, as a lab would start from it.
    """
    logs = folder / "logs"
    logs.mkdir()
    shutil.copy(demo_folder() / "v1_01.bag", logs / "run1.bag")
    shutil.copy(demo_folder() / "v2_01.bag", logs / "run2.bag")
    rng = np.random.default_rng(37)
    gyro = _ar1(rng, 6000)
    table = np.column_stack([np.arange(gyro.size) / 100.0, gyro])
    np.savetxt(folder / "gyro.csv", table, delimiter=",", header="t,gyro_z", comments="")
    still = _ar1(rng, 2000)
    stamps = 1_700_000_000 * 10**9 + np.arange(still.size) * 10**7
    rows = [(int(s) + 10**6, "imu", imu_message(k, int(s), 0.0, float(z)))
            for k, (s, z) in enumerate(zip(stamps, still, strict=True))]  # fmt: skip
    write_ros1(folder / "standstill.bag", rows, {"imu": ("/imu/data", "sensor_msgs/msg/Imu")})
    shutil.copy(default_profile_path(), folder / "my_robot.toml")


def _ar1(rng: np.random.Generator, n: int, phi: float = 0.9, sd: float = 0.01) -> np.ndarray:
    """A stationary AR(1) series of ``n`` samples, marginal sd ``sd``."""
    shocks = rng.normal(0.0, sd * np.sqrt(1 - phi**2), n)
    start = [phi * rng.normal(0.0, sd)]  # the state before the first sample: stationary
    return scipy.signal.lfilter([1.0], [1.0, -phi], shocks, zi=start)[0]


def _environment(folder: Path) -> dict[str, str]:
    """The reader's shell: this environment's console script first on the PATH."""
    (folder / ".venv").symlink_to(sys.prefix, target_is_directory=True)
    bin_folder = str(Path(sys.executable).parent)
    return os.environ | {"PATH": f"{bin_folder}{os.pathsep}{os.environ['PATH']}"}


def _run(command: list[str], folder: Path, env: dict, block: Block) -> None:
    result = subprocess.run(command, cwd=folder, env=env, capture_output=True, text=True,
                            timeout=900)  # fmt: skip
    if result.returncode != 0:
        pytest.fail(
            f"{block.where} ({block.lang}) exited {result.returncode}:\n{command[-1]}\n"
            f"--- stderr ---\n{result.stderr[-4000:]}\n--- stdout ---\n{result.stdout[-2000:]}"
        )


def _check_synopsis(block: Block) -> None:
    """Every --flag of a usage line is one the command's parser has."""
    verbs = build_parser()._subparsers._group_actions[0].choices
    for line in block.text.replace("\\\n", " ").splitlines():
        words = shlex.split(line.replace("[", " ").replace("]", " ").replace("|", " "))
        if words[:1] != ["bayes-jackal"]:
            continue
        known = {o for action in verbs[words[1]]._actions for o in action.option_strings}
        unknown = [w for w in words[2:] if w.startswith("--") and w not in known]
        assert not unknown, f"{block.where}: {words[1]} has no {unknown}"


def runnable(page: str) -> list[Block]:
    """The page's blocks that run: unmarked ``sh`` and ``python`` blocks and synopses."""
    return [
        b for b in page_blocks(page) if b.mark in ("", "synopsis") and b.lang in ("sh", "python")
    ]


def test_every_block_is_runnable_or_marked_with_a_reason():
    """A mark is one of the three, a not-run says why, a file mark sits on a text block."""
    for page in PAGES:
        for block in page_blocks(page):
            kind, _, rest = block.mark.partition(":")
            assert kind in ("", "not-run", "synopsis", "file"), f"{block.where}: {block.mark}"
            if kind == "not-run":
                assert len(rest.split()) >= 3, f"{block.where}: say why it does not run"
            if kind == "file":
                assert block.lang == "text" and rest.strip(), block.where


def test_every_small_setting_shortens_a_block():
    """A rewrite no block uses would hide a page whose commands changed."""
    applied: set[str] = set()
    for page in PAGES:
        for block in runnable(page):
            small(block, applied)
    assert applied == set(SMALL) | set(PYTHON_SMALL)


@pytest.mark.slow
@pytest.mark.parametrize("page", [page for page in PAGES if runnable(page)])
def test_the_page_runs_as_written(page, tmp_path):
    """The page's blocks in order, in a folder holding the reader's files only."""
    folder = tmp_path / "reader"
    folder.mkdir()
    reader_files(folder)
    env = _environment(folder)
    for block in page_blocks(page):
        if block.mark.startswith("file:"):
            (folder / block.mark.partition(":")[2].strip()).write_text(block.text)
    script: list[Block] = []
    for block in [*runnable(page), None]:
        if block is not None and block.lang == "python" and MAIN not in block.text:
            script.append(block)
            continue
        if script and (block is None or block.lang == "sh"):
            _run_python(script, folder, env)
            script = []
        if block is None:
            break
        if block.mark == "synopsis":
            _check_synopsis(block)
        elif block.lang == "python":
            _run_python([block], folder, env)
        else:
            _run(["bash", "-e", "-o", "pipefail", "-c", small(block, set())], folder, env, block)


def _run_python(blocks: list[Block], folder: Path, env: dict) -> None:
    """Python blocks as one script, ``page.py``, with :data:`SHORT` defined."""
    (folder / "page.py").write_text(SHORT + "\n".join(small(b, set()) for b in blocks))
    _run([sys.executable, "page.py"], folder, env, blocks[0])


def test_every_page_with_commands_is_listed():
    """A new page's commands run too: every page under docs/ with a block is in PAGES."""
    pages = {
        str(path.relative_to(ROOT))
        for path in (ROOT / "docs").rglob("*.md")
        if any(
            block.lang in ("sh", "python") for block in page_blocks(str(path.relative_to(ROOT)))
        )
    }
    assert pages <= set(PAGES), pages - set(PAGES)
