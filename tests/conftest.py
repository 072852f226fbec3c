"""Shared fixtures: a thesis-like simulator written independently of the package.

``simulate_thesis_like`` builds experiments the way a reader of the thesis
would, without bayes_jackal.io.simulate, .physics or .kernels: the linear model
x' = A x + B u (eq. 4-32) discretised by its own matrix exponential, the
Gaussian filter of eq. 7-5 with its own normalisation and +-3 sigma_h
truncation applied by numpy.convolve, wheel speeds of a steady circle with a
small ripple, and white sensor noise, sampled at the Jackal IMU's 72 Hz for
38 s (thesis ch. 7-3-1). Only the robot's constants come from the package's
profile. Tests that pass on these runs pass on data the package did not
generate.

Also shared: ``thesis_discrete_model`` (the same model's (Ad, Bd), for
checks of residuals and model curves), ``simulated`` (two small runs
written by ``bayes-jackal simulate``, for the tests of the command line),
``compared`` (one ``bayes-jackal compare`` of the first, for the tests of
its output and of the report's evidence table) and ``yaw_vx_posterior`` (a
short chain's posterior, for the tests of the export and of the report).
The last three are computed once per test session (per xdist worker;
``compared`` once per run, shared by the workers); the tests only read the
first two's files (checked when the session ends) and
each module gets a copy of the posterior. ``cli`` runs the command line in
a child forked from a process that has the package imported
(tests/cli_helpers.py), for the reliability suite and the write-error tests.
"""

from __future__ import annotations

import os

# One BLAS/OpenMP thread per test process, set before numpy is first imported
# (pytest imports this file before any test module, in each xdist worker too,
# and the CLI's subprocesses inherit it). `pytest -n 2` runs a process per
# core: OpenBLAS's own two threads in each oversubscribed a 2-core machine
# and its spinning threads starved each other (a 120-step chain: 1.7 s with
# one thread, 18 s with two, two chains at once). CI's slow pass says so on
# its command line; executors.in_processes does it for workers (threadpoolctl).
# An explicit setting in the environment is kept.
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")

import contextlib
import copy
import gc
import hashlib
import io
import json
import logging
import time
import warnings
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pytest
from cli_helpers import EXEC_ALL, Result, Zygote, built_once, finish, start

from bayes_jackal.cli import main

# The rest is imported where it is used: xdist's controller process loads this
# file too, and has no use for scipy and the package (~1.5 s before the
# workers start).
if TYPE_CHECKING:
    from bayes_jackal.io.experiment import Experiment
    from bayes_jackal.model.robot import RobotProfile


def pytest_collection_finish(session):
    """Keep the garbage collector off what the imports made, in each test process.

    The test modules import the package and its libraries (numpy, scipy,
    xarray, arviz, matplotlib, dask): millions of objects that live as long as
    the process. Python's full collections traversed them all, ~0.3 s each and
    a few dozen times per worker (a tenth of the suite's CPU time). Frozen
    after collection, they are skipped; collections of the young generation
    come every 7,000 allocations instead of 700, which also makes fewer full
    ones. Garbage is still collected, later (tests that need it at once call
    gc.collect()).
    """
    gc.collect()
    gc.freeze()
    gc.set_threshold(7000, 10, 10)


#: Sample rate of the Jackal's IMU [Hz] and length of a v1 run [s] (ch. 7-3-1).
THESIS_RATE = 72.0
THESIS_DURATION = 38.0
#: Channels in the order of the model's state (vx, vy, yaw rate).
STATE = ("vx", "vy", "yaw")
#: Seconds simulated before the record starts, so the noise is stationary.
BURN_IN = 3.0


class _Collected(logging.Handler):
    def __init__(self, lines: list[str], on_line: Callable[[str], None] | None):
        super().__init__(logging.INFO)
        self.lines, self.on_line = lines, on_line

    def emit(self, record: logging.LogRecord) -> None:
        self.lines.append(record.getMessage())
        if self.on_line is not None:
            self.on_line(self.lines[-1])  # may raise: the test's way to stop a run there


@contextlib.contextmanager
def messages(on_line: Callable[[str], None] | None = None) -> Iterator[list[str]]:
    """The package's messages (its loggers' INFO records) while the block runs, in order.

    A library user's way (``logging``); ``on_line(line)`` sees each as it comes.
    """
    logger, lines = logging.getLogger("bayes_jackal"), []
    handler, level = _Collected(lines, on_line), logger.level
    logger.addHandler(handler)
    logger.setLevel(logging.INFO)
    try:
        yield lines
    finally:
        logger.removeHandler(handler)
        logger.setLevel(level)


def thesis_matrices(robot: RobotProfile, d_lat: float, d_long: float):
    """Continuous A [1/s] and B of eq. 4-32 (state vx, vy, r; input omega_r, omega_l)."""
    m, inertia = robot.mass, robot.yaw_inertia
    a, b, r = robot.half_wheelbase, robot.half_track, robot.wheel_radius
    A = np.diag([-4 * d_long / m, -4 * d_lat / m, -4 * (b**2 * d_long + a**2 * d_lat) / inertia])
    B = np.array(
        [
            [2 * d_long * r / m, 2 * d_long * r / m],
            [0.0, 0.0],
            [2 * b * d_long * r / inertia, -2 * b * d_long * r / inertia],
        ]
    )
    return A, B


def zero_order_hold(A: np.ndarray, B: np.ndarray, dt: float):
    """(Ad, Bd) from expm([[A, B], [0, 0]] dt) (the input held over each step)."""
    import scipy.linalg

    n, k = B.shape
    block = np.zeros((n + k, n + k))
    block[:n, :n], block[:n, n:] = A, B
    exponential = scipy.linalg.expm(block * dt)
    return exponential[:n, :n], exponential[:n, n:]


def thesis_gaussian_filter(sigma_h: float, dt: float) -> np.ndarray:
    """Eq. 7-5: h(t) = sqrt(dT / (sigma_h sqrt(pi))) exp(-t^2 / (2 sigma_h^2)), |t| <= 3 sigma_h.

    Its energy sum(h^2) is a Riemann sum of the unit integral of
    exp(-t^2 / sigma_h^2) / (sigma_h sqrt(pi)): 1 within 1e-4 for
    sigma_h >= 2 dt, so filtered unit white noise has unit variance.
    """
    reach = int(np.floor(3 * sigma_h / dt))
    t = dt * np.arange(-reach, reach + 1)
    return np.sqrt(dt / (sigma_h * np.sqrt(np.pi))) * np.exp(-(t**2) / (2 * sigma_h**2))


def simulate_thesis_like(
    robot: RobotProfile,
    *,
    d_lat: float,
    d_long: float,
    sigma_h: float,
    sigma_c: dict[str, float],
    sigma_n: dict[str, float],
    rng: np.random.Generator,
    v: float = 0.3,
    w: float = float(np.deg2rad(22.5)),
    ripple: float = 0.01,
    name: str = "thesis_like",
) -> Experiment:
    """One steady circle at 72 Hz for 38 s with Gaussian-coloured process noise.

    x[k+1] = Ad x[k] + Bd u[k] + sigma_c h * e[k] per channel (e white, h of
    eq. 7-5); measured y = x + sigma_n n. Wheel speeds (v +- w b) / r_w of
    the command (v [m/s], w [rad/s]; thesis v1 by default) carry a ripple,
    independent per wheel, of relative sd about ``ripple`` / 2: two
    sinusoids and low-pass jitter. The record starts at t = 12.5 s, as a log
    cut from a longer session would.

    Returns
    -------
    Experiment
        vx, vy, yaw rate and wheel speeds; ``truth`` in the layout of the
        package's simulator (d_lat, d_long, width, sigma_h, sigma_c and
        sigma_n per channel).
    """
    import scipy.signal

    from bayes_jackal.io.experiment import Experiment

    dt = 1.0 / THESIS_RATE
    burn = round(BURN_IN / dt)
    n = round(THESIS_DURATION / dt) + 1 + burn
    time = dt * np.arange(n)[:, None]
    # Each wheel's own controller: sinusoids near the wheel's turning rate
    # (0.5 Hz) and at 2.3 Hz with random phases, and jitter low-passed over
    # 0.5 s (a moving average of 36 unit normals, scaled to unit sd).
    phases = rng.uniform(0, 2 * np.pi, (2, 2))
    jitter = scipy.signal.lfilter(np.ones(36) / 6.0, 1.0, rng.standard_normal((n + 35, 2)), axis=0)
    wobble = (
        0.5 * np.sin(2 * np.pi * 0.49 * time + phases[0])
        + 0.3 * np.sin(2 * np.pi * 2.3 * time + phases[1])
        + jitter[35:]
    )
    level = np.array([v + w * robot.half_track, v - w * robot.half_track]) / robot.wheel_radius
    inputs = level * (1.0 + ripple / 2 * wobble)
    A, B = thesis_matrices(robot, d_lat, d_long)
    Ad, Bd = zero_order_hold(A, B, dt)
    steady = np.linalg.solve(np.eye(3) - Ad, Bd @ level)
    h = thesis_gaussian_filter(sigma_h, dt)
    states = np.empty((n, 3))
    for i, channel in enumerate(STATE):
        noise = sigma_c[channel] * np.convolve(rng.standard_normal(n + len(h) - 1), h, "valid")
        drive = Bd[i] @ (inputs - level).T + noise
        # Deviation from the steady state: d[k+1] = Ad[i, i] d[k] + drive[k], d[0] = 0.
        states[:, i] = steady[i] + scipy.signal.lfilter([0.0, 1.0], [1.0, -Ad[i, i]], drive)
    measured = states + np.array([sigma_n[c] for c in STATE]) * rng.standard_normal(states.shape)
    keep = slice(burn, None)
    return Experiment(
        t=12.5 + dt * np.arange(n - burn),
        vx=measured[keep, 0],
        vy=measured[keep, 1],
        yaw_rate=measured[keep, 2],
        omega_r=inputs[keep, 0],
        omega_l=inputs[keep, 1],
        name=name,
        truth={
            "d_lat": d_lat,
            "d_long": d_long,
            "family": "gaussian",
            "width": sigma_h,
            "sigma_h": sigma_h,
            "sigma_c": dict(sigma_c),
            "sigma_n": dict(sigma_n),
        },
        truth_arrays={f"{c}_state": states[keep, i] for i, c in enumerate(STATE)},
        provenance={"simulated": True, "simulator": "tests/conftest.py (independent)"},
    )


@pytest.fixture(scope="session")
def thesis_like_simulator():
    """The independent simulator :func:`simulate_thesis_like`."""
    return simulate_thesis_like


@pytest.fixture(scope="session")
def thesis_discrete_model():
    """``(Ad, Bd) = model(robot, d_lat, d_long, dt)``: eq. 4-32 held over dt, as above."""
    return lambda robot, d_lat, d_long, dt: zero_order_hold(
        *thesis_matrices(robot, d_lat, d_long), dt
    )


def _digests(folder: Path) -> dict[str, str]:
    """sha256 of every file under ``folder``, by relative path."""
    return {
        str(path.relative_to(folder)): hashlib.sha256(path.read_bytes()).hexdigest()
        for path in sorted(folder.rglob("*"))
        if path.is_file()
    }


@pytest.fixture(scope="session")
def simulated(tmp_path_factory) -> Iterator[list[str]]:
    """Two simulated NetCDF experiments (v1_01, v2_01) written by the CLI, once per session.

    Shared by every test that asks for it: a test that would write into
    their folder copies them first (the session's end checks that none did).
    tests/test_bags.py and tests/test_criticism.py define their own
    ``simulated`` (one Experiment in memory), which overrides this one there.
    """
    folder = tmp_path_factory.mktemp("simulated")
    assert main(["simulate", "--out", str(folder), "--seed", "1", "--v1", "1", "--v2", "1"]) == 0
    before = _digests(folder)
    yield [str(folder / "v1_01.nc"), str(folder / "v2_01.nc")]
    assert _digests(folder) == before, f"a test changed the shared runs in {folder}"


@dataclass(frozen=True)
class Compared:
    """What ``bayes-jackal compare ... --out FOLDER --json`` returned, printed and wrote."""

    code: int
    out: str
    err: str
    folder: Path


#: The flags of ``compared``: yaw alone (three channels take ~3x the time),
#: the two default families, a short chain (300 steps, not converged).
QUICK_COMPARE = ["--channels", "yaw", "--families", "white,gaussian", "--max-steps", "300"]
QUICK_COMPARE += ["--seed", "2", "--no-progress"]


@pytest.fixture(scope="session")
def compared(simulated, tmp_path_factory) -> Iterator[Compared]:
    """``compare`` of the simulated v1_01 with QUICK_COMPARE, ``--out`` and ``--json``.

    Run once per test run, with the command's default processes, for the
    tests of compare's output (tests/test_cli.py) and of the report's
    evidence table (tests/test_report.py); they only read its folder. Under
    xdist the first worker that needs it runs it (``built_once``; the
    workers' ``simulated`` runs are the same: same seed), and keeps its exit
    code, stdout and stderr beside the folder for the other.
    """

    def build(shared: Path) -> None:
        out, err = io.StringIO(), io.StringIO()
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            code = main(
                [
                    "compare",
                    simulated[0],
                    *QUICK_COMPARE,
                    "--out",
                    str(shared / "compare"),
                    "--json",
                ]
            )
        printed = {"code": code, "out": out.getvalue(), "err": err.getvalue()}
        (shared / "printed.json").write_text(json.dumps(printed))

    shared = built_once(tmp_path_factory, "compared", build)
    printed = json.loads((shared / "printed.json").read_text())
    folder = shared / "compare"
    before = _digests(folder)
    yield Compared(printed["code"], printed["out"], printed["err"], folder)
    assert _digests(folder) == before, f"a test changed the shared comparison in {folder}"


def _posterior_digest(idata) -> str:
    """sha256 of a posterior's draws and attributes (what a test could change in place)."""
    digest = hashlib.sha256(repr(sorted(idata.posterior.attrs.items())).encode())
    for name, values in sorted(idata.posterior.data_vars.items()):
        digest.update(name.encode())
        digest.update(np.ascontiguousarray(values.values).tobytes())
    return digest.hexdigest()


@pytest.fixture(scope="session")
def _yaw_vx_sampled():
    """The chain of ``yaw_vx_posterior``, sampled once per session and never handed out."""
    from bayes_jackal.inference.chains import SamplerSettings
    from bayes_jackal.inference.sampler_warnings import ConvergenceWarning
    from bayes_jackal.inference.sampling import sample_posterior
    from bayes_jackal.io.simulate import simulate_experiment
    from bayes_jackal.likelihood.residual_likelihood import ResidualLikelihood
    from bayes_jackal.model.robot import load_profile

    run = simulate_experiment(load_profile(), 110.0, 30.0, "v2", rng=3)
    likelihood = ResidualLikelihood([run], load_profile(), channels=("yaw", "vx"))
    settings = SamplerSettings(max_steps=120, check_every=40, design_points=256)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        idata = sample_posterior(likelihood, settings, seed=1)
    before = _posterior_digest(idata)
    yield idata
    assert _posterior_digest(idata) == before, "the session's yaw_vx chain was changed"


@pytest.fixture(scope="module")
def yaw_vx_posterior(_yaw_vx_sampled):
    """A short chain (120 steps, not converged) on yaw and vx of a simulated v2 run (seed 3).

    For tests/test_export.py and tests/test_report.py: sampled once per
    session, each module gets a copy of its own (export_prior caches the
    criticism in the posterior's attributes, which another module must not see).
    """
    return copy.deepcopy(_yaw_vx_sampled)


@pytest.fixture(scope="session")
def cli():
    """Run the CLI in a forked child: ``cli(argv, cwd, fsize=0, timeout=90, setup="")``.

    Returns a :class:`cli_helpers.Result`. One :class:`cli_helpers.Zygote` per
    session (per xdist worker), started at first use;
    ``BAYES_JACKAL_RELIABILITY_EXEC=1`` runs each command in a fresh
    interpreter instead. stdout and stderr go to files beside ``cwd``
    (``<cwd>.stdout``, ``<cwd>.stderr``); ``fsize`` sets RLIMIT_FSIZE [bytes];
    ``setup`` is Python code the child runs before the command.
    """
    zygote = None if EXEC_ALL else Zygote()

    def run(
        argv: list[str], cwd: Path, *, fsize: int = 0, timeout: float = 90.0, setup: str = ""
    ) -> Result:
        if zygote is None:
            process = start(argv, cwd, fsize=fsize, setup=setup)
            result = finish(process, timeout)
            result.seconds = time.monotonic() - process.started
            return result
        return zygote.run(argv, cwd, fsize=fsize, timeout=timeout, setup=setup)

    yield run
    if zygote is not None:
        zygote.close()
