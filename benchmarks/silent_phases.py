"""Benchmark: the longest silent phase of a command on a terminal (issue 37).

Run by hand: ``python benchmarks/silent_phases.py [--threshold 5] [--cwd DIR] -- CMD ...``,
e.g. ``python benchmarks/silent_phases.py -- .venv/bin/bayes-jackal demo --out /tmp/demo``.

Issue 37 asks that no phase of the demo or of ``analyse`` stay silent on a
terminal for more than 5 s. The command runs here on a pseudo-terminal (so
that it draws its progress bars as it would for a user, 120 columns wide);
every chunk it writes is stamped as it arrives (``--transcript FILE`` keeps
each chunk's stamp and last line). It prints the wall time, the
peak resident memory of the largest process, the number of chunks, and each
silence longer than ``--threshold`` seconds with the last line shown before
it (the phase that was silent) — the longest first. Its baseline is the
threshold itself: the ratio longest silence / threshold must stay below 1.
Exit code: the command's, or 3 if a silence was longer than the threshold.
"""

from __future__ import annotations

import argparse
import codecs
import fcntl
import os
import pty
import re
import resource
import select
import struct
import subprocess
import sys
import termios
import time

#: ANSI escape sequences (tqdm's cursor moves), removed from the lines shown.
_ANSI = re.compile(r"\x1b\[[0-9;?]*[A-Za-z]")


def _last_line(text: str) -> str:
    """The last non-empty line a terminal showed at the end of ``text``."""
    lines = [line.strip() for line in re.split(r"[\r\n]", _ANSI.sub("", text))]
    shown = [line for line in lines if line]
    return shown[-1] if shown else "(nothing yet)"


def record(command: list[str], cwd: str | None) -> tuple[int, float, list[tuple[float, str]]]:
    """Run ``command`` on a pseudo-terminal: (exit code, wall s, [(seconds, text), ...])."""
    master, slave = pty.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 40, 120, 0, 0))
    start = time.monotonic()
    process = subprocess.Popen(
        command, stdin=subprocess.DEVNULL, stdout=slave, stderr=slave, cwd=cwd, close_fds=True
    )
    os.close(slave)
    chunks: list[tuple[float, str]] = []
    decoder = codecs.getincrementaldecoder("utf-8")("replace")  # a character split by a read
    while True:
        ready, _, _ = select.select([master], [], [], 1.0)
        if not ready:
            continue
        try:
            data = os.read(master, 65536)
        except OSError:  # EIO: every writer closed the terminal
            break
        if not data:
            break
        chunks.append((time.monotonic() - start, decoder.decode(data)))
    os.close(master)
    code = process.wait()
    return code, time.monotonic() - start, chunks


def silences(chunks: list[tuple[float, str]], wall: float) -> list[tuple[float, float, str]]:
    """Every gap between what was written: (length s, start s, the line shown before it)."""
    gaps, shown, last = [], "", 0.0
    for stamp, text in chunks:
        gaps.append((stamp - last, last, _last_line(shown)))
        shown, last = shown[-4000:] + text, stamp
    gaps.append((wall - last, last, _last_line(shown)))
    return sorted(gaps, reverse=True)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--threshold", type=float, default=5.0, help="seconds (default 5)")
    parser.add_argument("--cwd", help="folder to run the command in")
    parser.add_argument("--transcript", help="write each chunk's stamp and last line here")
    parser.add_argument("command", nargs=argparse.REMAINDER)
    args = parser.parse_args()
    command = args.command[1:] if args.command[:1] == ["--"] else args.command
    if not command:
        parser.error("give the command after --")
    code, wall, chunks = record(command, args.cwd)
    peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
    gaps = silences(chunks, wall)
    if args.transcript:
        with open(args.transcript, "w") as file:
            file.writelines(f"{stamp:8.2f} {_last_line(text)}\n" for stamp, text in chunks)
    load = os.getloadavg()[0]
    print(f"{' '.join(command)}\n  exit {code}, {wall:.1f} s wall, peak RSS {peak:.0f} MB, ")
    print(f"  {len(chunks)} chunks written, load {load:.1f} at the end")
    longest = gaps[0][0]
    print(
        f"  longest silence {longest:.1f} s; ratio to the {args.threshold:g} s threshold "
        f"{longest / args.threshold:.2f}"
    )
    for length, begin, line in (gap for gap in gaps if gap[0] > args.threshold):
        print(f"  silent {length:6.1f} s from {begin:7.1f} s after: {line[:100]}")
    return code if code else (3 if longest > args.threshold else 0)


if __name__ == "__main__":
    sys.exit(main())
