"""Benchmark: the package's ``sample`` against a Kalman-filter + emcee peer (issue 39).

Run by hand: ``python benchmarks/bench_peer.py [--runs 38,300] [--workdir DIR]
[--seed N] [--family exponential] [--max-steps N] [--cases package,peer-lfilter,peer]``
(on 2 busy cores about an hour, 38 minutes of it the ``peer`` on the 300 s run).

The peer is what a user without this package would write: an independent
Kalman-filter likelihood of the measured channels (yaw rate, vx, vy), here
in numpy and vectorised over the walkers, sampled with emcee's default move
(the stretch move) under the package's priors and its stopping rule. It
calls none of the package's likelihood, discretisation or sampler code: it
takes only the run (read by the package's reader), the robot profile's
constants and prior ranges from the package.

- The model (thesis eq. 4-32 and 6-6): each channel is x[k+1] = a x[k] +
  b . u[k] + w[k], y[k] = x[k] + n[k], with the exact zero-order-hold pole
  a = exp(A dt) and input row b = B (a - 1) / A of the diagonal A; the
  sensor noise n is white of sd sigma_n; the process noise w is white
  (family ``white``) or AR(1) / Ornstein-Uhlenbeck of sd sigma_c and
  phi = exp(-dt / width) (``exponential``), carried as a second state, so
  that the filter is exact. The filter conditions on the first sample with
  the state diffuse before it (x[0] | y[0] ~ N(y[0], sigma_n^2)), which
  makes its likelihood that of the package's one-step residuals exactly.
  Its covariances do not depend on the data and reach a steady state
  within tens of steps; from there on the gains are held (to 1e-13) and
  only the means run, in a loop over time (``peer``) or, in a variant a
  user versed in signal processing could write, as the innovations'
  ARMA(2, 1) recursion by ``scipy.signal.lfilter`` for each walker and
  channel (``peer-lfilter``). The two agree to rounding; with the same seed
  their chains part after a while (rounding decides an acceptance), so
  they are two runs of the same sampler on the same posterior.
- The check: the peer's log-likelihood against the package's
  (``ResidualLikelihood``, default ``fast`` engine) at 8 points, with the
  largest difference in nats, for the family sampled and for ``white``.
- The chains, each case in a fresh process, one after the other: the
  package's ``bj.sample`` (its defaults: MAP search, its moves, the
  stopping rule, one seed), and each peer, started in a ball of 1e-3 in
  log coordinates around the MAP that L-BFGS-B finds on its own likelihood
  (from d = 100 N s/m and each channel's noise at a guess), with as many
  walkers as the package uses (max(32, 4 x parameters)) and the same rule:
  check every 100 steps, stop once the chain is longer than 50 integrated
  autocorrelation times (emcee's estimator) and arviz's bulk and tail ESS
  (walkers as chains) of every parameter after a burn-in of 2 tau are at
  least 400; the same step cap (20,000 unless ``--max-steps``).
- Every case in a process of its own with one BLAS thread (the package
  computes its likelihood with one; OpenBLAS's threads slowed the peer's
  long dot products 13-fold on 2 busy cores).
- Printed per run and sampler: wall and CPU time (from the data loaded to
  the chain finished, the MAP search included), peak RSS of the process,
  likelihood evaluations (parameter sets, the MAP search's included; the
  package's one-channel evaluations of its block moves count a third),
  steps, the largest integrated autocorrelation time, min ESS over the
  parameters (bulk and tail, after 2 tau of burn-in, computed the same way
  for both), ESS per second, evaluations per effective draw and the
  likelihood's time per evaluation; the posterior medians of the damping
  (and the peer's MAP); then the ratio package / peer of ESS per second
  (issue 39's targets, for ``peer``: at least 25 on the 38 s run, 100 on
  the 300 s run), and the growth of the time per evaluation and of the
  wall time from the first run to the last.

The runs are ``bench_long_runs.make_run``'s (72 Hz, truth d_lat 110,
d_long 30 N s/m, Gaussian process noise of sigma_h 0.047 s). The load
average is printed at the start and at the end.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from bench_long_runs import make_run
from timing import work_folder

CHANNELS = ("yaw", "vx", "vy")
#: The chains: the package's, the peer's lfilter variant, the peer (its filter in a loop).
CASES = ("package", "peer-lfilter", "peer")
#: The package's stopping rule (``bj.SamplerSettings``' defaults).
CHECK_EVERY, AUTOCORR_MULTIPLE, MIN_ESS, MAX_STEPS = 100, 50.0, 400, 20_000
#: Spread of the peer's walkers around its MAP in log coordinates.
BALL = 1e-3
#: Every case computes with one BLAS thread, as the package's likelihood does: OpenBLAS's
#: threads on the peer's 21,600-sample dot products made it 13 times slower on 2 cores.
ONE_THREAD = os.environ | {name: "1" for name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS")}
#: Issue 39's targets: package / peer ESS per second on the shortest and longest run.
TARGETS = {38.0: 25.0, 300.0: 100.0}


# --- The peer: the model as a user writes it from the thesis -------------------------------


@dataclass(frozen=True)
class Run:
    """One run's measured channels, wheel speeds and sample time."""

    y: np.ndarray  # (N, C): the channels of CHANNELS [rad/s, m/s]
    u: np.ndarray  # (N, 2): wheel speeds (right, left) [rad/s]
    dt: float  # [s]


@dataclass(frozen=True)
class Body:
    """The robot's constants [kg, kg m^2, m]."""

    mass: float
    inertia: float
    half_wheelbase: float
    half_track: float
    wheel_radius: float


def read_run(path: Path) -> tuple[Run, Body, dict[str, tuple[float, float]]]:
    """The run, the robot's constants and prior ranges, read with the package's reader."""
    import bayes_jackal as bj

    experiment = bj.load_experiments([path])[0]
    robot = bj.load_profile()
    y = np.column_stack([experiment.channel(channel) for channel in CHANNELS])
    body = Body(
        robot.mass, robot.yaw_inertia, robot.half_wheelbase, robot.half_track, robot.wheel_radius
    )
    return Run(y, np.asarray(experiment.inputs, float), float(experiment.dt)), body, robot.priors


def parameter_names(family: str) -> list[str]:
    """The parameters in the package's order: damping, then each channel's noise."""
    noise = ("sigma_c", "sigma_n") if family == "white" else ("width", "sigma_c", "sigma_n")
    return ["d_lat", "d_long"] + [f"{name}[{c}]" for c in CHANNELS for name in noise]


def prior_box(names: list[str], ranges: dict[str, tuple[float, float]]) -> np.ndarray:
    """Bounds (2, P) of the log-uniform priors, in z = log(theta)."""
    keys = [name.split("[")[0].replace("width", "sigma_h") for name in names]
    return np.log(np.array([ranges[key] for key in keys], float).T)


def continuous_poles(body: Body, d_lat: np.ndarray, d_long: np.ndarray) -> tuple:
    """A (B, C) and B (B, C, 2) of eq. 4-32's diagonal model, channels as CHANNELS."""
    a, b, m, inertia = body.half_wheelbase, body.half_track, body.mass, body.inertia
    poles = np.stack(
        [-4.0 / inertia * (b**2 * d_long + a**2 * d_lat), -4.0 * d_long / m, -4.0 * d_lat / m],
        axis=-1,
    )
    torque = 2.0 * b * d_long * body.wheel_radius / inertia
    force = 2.0 * d_long * body.wheel_radius / m
    zero = np.zeros_like(d_lat)
    rows = np.stack(
        [
            np.stack([torque, -torque], -1),
            np.stack([force, force], -1),
            np.stack([zero, zero], -1),
        ],
        axis=-2,
    )
    return poles, rows


def zero_order_hold(body: Body, d_lat: np.ndarray, d_long: np.ndarray, dt: float) -> tuple:
    """Exact discretisation of the diagonal model: a = exp(A dt), b = B (a - 1) / A."""
    poles, rows = continuous_poles(body, d_lat, d_long)
    a = np.exp(poles * dt)
    return a, rows * ((a - 1.0) / poles)[..., None]


def kalman_loglike(
    run: Run, body: Body, family: str, theta: np.ndarray, steady: str = "loop"
) -> np.ndarray:
    """Exact log-likelihood of y[1:] given y[0] of each row of ``theta`` (B, P).

    A two-state filter per channel (the velocity and the AR(1) noise),
    vectorised over the rows and the channels; white noise is phi = 0. The
    covariances do not depend on the data: once they stop changing (both
    gains within 1e-13 of their value 1 step before, a steady state reached
    geometrically) the gains are held, and the means run on in a loop over
    time (``steady="loop"``) or, as the innovations' ARMA(2, 1) recursion,
    by ``scipy.signal.lfilter`` for each row and channel (``"lfilter"``).
    """
    theta = np.atleast_2d(theta)
    a, b = zero_order_hold(body, theta[:, 0], theta[:, 1], run.dt)  # (B, C), (B, C, 2)
    noise = theta[:, 2:].reshape(len(theta), len(CHANNELS), -1)
    phi = np.zeros_like(a) if family == "white" else np.exp(-run.dt / noise[..., 0])
    var_w, var_n = noise[..., -2] ** 2, noise[..., -1] ** 2
    steps = len(run.y) - 1
    innovations = np.empty((steps, *a.shape))
    variances = np.empty((steps, *a.shape))
    # After y[0], the velocity diffuse before it: x | y[0] ~ N(y[0], var_n); w stationary.
    x, w = np.broadcast_to(run.y[0], a.shape).copy(), np.zeros_like(a)
    pxx, pxw, pww = var_n.copy(), np.zeros_like(a), var_w.copy()
    q, two_a, a2, phi2 = (1.0 - phi**2) * var_w, 2.0 * a, a * a, phi * phi
    previous = (a, a)
    k = 0
    while k < steps:
        # Predict x[k+1] and w[k+1], then update with y[k+1].
        x, w = a * x + b[..., 0] * run.u[k, 0] + b[..., 1] * run.u[k, 1] + w, phi * w
        pxx, pxw, pww = a2 * pxx + two_a * pxw + pww, phi * (a * pxw + pww), phi2 * pww + q
        s = pxx + var_n
        v = run.y[k + 1] - x
        innovations[k], variances[k] = v, s
        kx, kw = pxx / s, pxw / s
        x, w = x + kx * v, w + kw * v
        pww = pww - kw * pxw
        pxx, pxw = kx * var_n, kw * var_n
        k += 1
        if k % 8 == 7:
            previous = (kx, kw)
        elif k % 8 == 0 and all(
            np.all(np.abs(gain - last) <= 1e-13 * np.abs(gain))
            for gain, last in zip((kx, kw), previous, strict=True)
        ):
            break
    terms = np.log(variances[:k]) + innovations[:k] ** 2 / variances[:k]
    total = terms.sum(axis=0)
    if k < steps:
        if steady == "lfilter":
            squares = _held_lfilter(run, a, b, phi, (kx, kw), innovations[k - 1 : k - 3 : -1], k)
        else:
            squares = _held_loop(run, a, b, phi, (kx, kw), (x, w), k)
        total += (steps - k) * np.log(s) + squares / s
    return -0.5 * (total.sum(axis=1) + steps * len(CHANNELS) * np.log(2.0 * np.pi))


def _held_loop(run, a, b, phi, gains, state, k) -> np.ndarray:
    """Sum of the squared innovations from step k on, the gains held (B, C).

    p and r are the predicted means of x and w.
    """
    (kx, kw), (x, w) = gains, state
    drive = run.u[k:-1, None, None, 0] * b[..., 0] + run.u[k:-1, None, None, 1] * b[..., 1]
    innovations = np.empty_like(drive)
    p, r = a * x + w, phi * w
    g1, g2 = a * kx + kw, phi * kw
    for j in range(len(drive)):
        p += drive[j]
        v = np.subtract(run.y[k + j + 1], p, out=innovations[j])
        p = a * p + g1 * v + r
        r = phi * r + g2 * v
    return np.einsum("jbc,jbc->bc", innovations, innovations)


def _held_lfilter(run, a, b, phi, gains, past, k) -> np.ndarray:
    """The same by lfilter: with e[j] = y[j+1] - a y[j] - b . u[j] and c = a (1 - kx),
    v[j] = e[j] - phi e[j-1] + (c + phi - kw) v[j-1] - c phi v[j-2], started from
    the last two innovations ``past`` (2, B, C) of the filter and e[k-1]."""
    import scipy.signal

    kx, kw = gains
    c = a * (1.0 - kx)
    y, u = run.y.T[None], run.u.T  # (1, C, N), (2, N)
    drive = b[..., 0, None] * u[0, k - 1 : -1] + b[..., 1, None] * u[1, k - 1 : -1]
    e = y[..., k:] - a[..., None] * y[..., k - 1 : -1] - drive  # (B, C, T): e[k-1], e[k], ...
    sums = np.empty(a.shape)
    for row, channel in np.ndindex(a.shape):
        numerator = [1.0, -phi[row, channel]]
        denominator = [1.0, -(c + phi - kw)[row, channel], (c * phi)[row, channel]]
        series = e[row, channel]
        zi = scipy.signal.lfiltic(numerator, denominator, past[:, row, channel], series[:1])
        v = scipy.signal.lfilter(numerator, denominator, series[1:], zi=zi)[0]
        sums[row, channel] = v @ v
    return sums


@dataclass
class Counted:
    """A vectorised function that counts the rows it evaluates and the time it takes."""

    function: Callable[[np.ndarray], np.ndarray]
    rows: float = 0.0
    seconds: float = 0.0

    def __call__(self, theta: np.ndarray) -> np.ndarray:
        started = time.perf_counter()
        out = self.function(theta)
        self.seconds += time.perf_counter() - started
        self.rows += len(np.atleast_2d(theta))
        return out


def log_posterior(loglike: Counted, box: np.ndarray) -> Callable[[np.ndarray], np.ndarray]:
    """log p(z) up to a constant: the log-likelihood inside the prior box, -inf outside."""

    def density(z: np.ndarray) -> np.ndarray:
        z = np.atleast_2d(z)
        out = np.full(len(z), -np.inf)
        inside = np.all((z >= box[0]) & (z <= box[1]), axis=1)
        if inside.any():
            out[inside] = loglike(np.exp(z[inside]))
        return np.where(np.isnan(out), -np.inf, out)

    return density


def find_map(density: Callable, box: np.ndarray, guess: np.ndarray) -> np.ndarray:
    """L-BFGS-B from ``guess`` in z, its gradient by forward differences in one batch."""
    import scipy.optimize

    step = 1e-6

    def objective(z: np.ndarray) -> tuple[float, np.ndarray]:
        steps = np.where(z + step <= box[1], step, -step)  # inside the box
        values = density(np.vstack([z, z + np.diag(steps)]))
        if not np.all(np.isfinite(values)):
            return 1e300, np.zeros_like(z)
        return -float(values[0]), -(values[1:] - values[0]) / steps

    result = scipy.optimize.minimize(
        objective, guess, jac=True, method="L-BFGS-B", bounds=list(zip(*box, strict=True))
    )
    return result.x


def guess(family: str) -> np.ndarray:
    """A user's first guess: d = 100 N s/m, width 0.05 s, sigma_c and sigma_n 0.01."""
    noise = [0.01, 0.01] if family == "white" else [0.05, 0.01, 0.01]
    return np.log([100.0, 100.0, *noise * len(CHANNELS)])


def ess_after_burn_in(chain: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """arviz's bulk and tail ESS (2, P) after 2 tau of burn-in (at most half the chain)."""
    import arviz as az
    import xarray as xr

    discard = min(int(np.ceil(2.0 * np.max(tau))), len(chain) // 2)
    draws = np.swapaxes(chain[discard:], 0, 1)  # (walkers, draws, P): walkers as chains
    dataset = xr.Dataset({"z": (("chain", "draw", "parameter"), draws)})
    return np.array([az.ess(dataset, method=kind)["z"].values for kind in ("bulk", "tail")])


def integrated_time(chain: np.ndarray) -> np.ndarray:
    """emcee's integrated autocorrelation time of each parameter [steps], no tolerance."""
    import emcee

    return emcee.autocorr.integrated_time(chain, c=5, tol=0, quiet=True)


def converged(chain: np.ndarray) -> bool:
    """The stopping rule: longer than 50 tau, and every bulk and tail ESS >= 400."""
    tau = integrated_time(chain)
    if not np.all(np.isfinite(tau)) or not np.all(AUTOCORR_MULTIPLE * tau < len(chain)):
        return False
    return bool(np.all(ess_after_burn_in(chain, tau) >= MIN_ESS))


def run_peer(path: Path, family: str, seed: int, max_steps: int, steady: str) -> dict:
    """The Kalman-filter peer: MAP by L-BFGS-B, then emcee's stretch move to the rule."""
    import emcee

    run, body, ranges = read_run(path)
    names = parameter_names(family)
    box = prior_box(names, ranges)
    loglike = Counted(lambda theta: kalman_loglike(run, body, family, theta, steady))
    density = log_posterior(loglike, box)
    rng = np.random.default_rng(seed)
    wall, cpu = time.perf_counter(), time.process_time()
    centre = find_map(density, box, guess(family))
    walkers = max(32, 4 * len(names))  # the package's default ensemble
    start = np.clip(centre + BALL * rng.standard_normal((walkers, len(names))), *box)
    state = emcee.State(start, random_state=np.random.RandomState(seed).get_state())
    sampler = emcee.EnsembleSampler(walkers, len(names), density, vectorize=True)
    done = False
    for _ in sampler.sample(state, iterations=max_steps):
        if sampler.iteration % CHECK_EVERY == 0 and converged(sampler.get_chain()):
            done = True
            break
    return finish(sampler.get_chain(), loglike, wall, cpu, done) | {
        "map": np.exp(centre[:2]).tolist()
    }


def finish(chain: np.ndarray, loglike: Counted, wall: float, cpu: float, done: bool) -> dict:
    """A chain's result: times, evaluations, steps, tau and the smallest ESS."""
    seconds, cpu_seconds = time.perf_counter() - wall, time.process_time() - cpu
    tau = integrated_time(chain)
    ess = ess_after_burn_in(chain, tau)
    kept = chain[min(int(np.ceil(2.0 * np.max(tau))), len(chain) // 2) :]
    return {
        "seconds": seconds,
        "cpu": cpu_seconds,
        "evaluations": loglike.rows,
        "per_evaluation": loglike.seconds / max(loglike.rows, 1.0),
        "steps": len(chain),
        "walkers": chain.shape[1],
        "tau": float(np.max(tau)),
        "min_ess": float(np.min(ess)),
        "converged": done,
        "median": np.exp(np.median(kept[..., :2], axis=(0, 1))).tolist(),  # d_lat, d_long
        "peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
    }


# --- The package -----------------------------------------------------------------------------


def run_package(path: Path, family: str, seed: int, max_steps: int, folder: Path) -> dict:
    """``bj.sample`` with its defaults and a chain file; its likelihood's rows counted."""
    import h5py

    import bayes_jackal as bj
    from bayes_jackal.likelihood import ResidualLikelihood

    counter = Counted(lambda theta: theta)
    full, group = ResidualLikelihood.__call__, ResidualLikelihood.group_loglike

    def counted_full(self, theta):
        return _timed(counter, lambda: full(self, theta), len(np.atleast_2d(theta)))

    def counted_group(self, theta, index):
        share = len(np.atleast_2d(theta)) / len(self.layout.groups)
        return _timed(counter, lambda: group(self, theta, index), share)

    ResidualLikelihood.__call__, ResidualLikelihood.group_loglike = counted_full, counted_group
    experiments = bj.load_experiments([path])
    chain_file = folder / f"{path.stem}.{family}.seed{seed}.chain.h5"
    chain_file.unlink(missing_ok=True)  # a stored chain would resume, not sample
    wall, cpu = time.perf_counter(), time.process_time()
    posterior = bj.sample(
        experiments,
        family=family,
        seed=seed,
        max_steps=max_steps,
        progress=False,
        chain_file=chain_file,
    )
    done = bool(posterior.metadata.convergence.converged)
    seconds, cpu_seconds = time.perf_counter() - wall, time.process_time() - cpu
    with h5py.File(chain_file, "r") as stored:
        chain = stored["mcmc"]["chain"][: int(stored["mcmc"].attrs["iteration"])]
    result = finish(chain, counter, 0.0, 0.0, done)
    return result | {"seconds": seconds, "cpu": cpu_seconds}


def _timed(counter: Counted, call: Callable[[], np.ndarray], rows: float) -> np.ndarray:
    started = time.perf_counter()
    out = call()
    counter.seconds += time.perf_counter() - started
    counter.rows += rows
    return out


# --- The likelihood check, the cases in fresh processes and the table ------------------------


def check_likelihood(path: Path, family: str, points: int = 8) -> float:
    """Largest |peer - package| log-likelihood [nats] at ``points`` points; prints a line."""
    import bayes_jackal as bj
    from bayes_jackal.likelihood import ResidualLikelihood

    run, body, _ = read_run(path)
    experiments = bj.load_experiments([path])
    package = ResidualLikelihood(experiments, bj.load_profile(), family=family)
    names = parameter_names(family)
    if list(package.parameter_names) != names:
        raise RuntimeError(f"parameter order: package {package.parameter_names}, peer {names}")
    centre = np.log(
        [110.0, 30.0, *([0.01, 0.004] if family == "white" else [0.05, 0.01, 0.004]) * 3]
    )
    rng = np.random.default_rng(0)
    theta = np.exp(centre + 0.3 * rng.standard_normal((points, len(names))))
    theirs = package(theta)
    difference = np.max(
        [np.abs(kalman_loglike(run, body, family, theta, steady) - theirs)
         for steady in ("loop", "lfilter")],
        axis=0,
    )  # fmt: skip
    print(
        f"likelihood check, {path.name}, {family}: {points} points, log-likelihood "
        f"{theirs.min():.1f} .. {theirs.max():.1f}, max |peer - package| (both variants) "
        f"{difference.max():.2g} nats (relative {np.max(difference / np.abs(theirs)):.1g})"
    )
    return float(difference.max())


def check_discretisation(path: Path) -> float:
    """Largest difference of the peer's closed-form ZOH from scipy's expm of the block matrix."""
    import scipy.linalg

    run, body, _ = read_run(path)
    d_lat, d_long = np.array([110.0]), np.array([30.0])
    a, b = zero_order_hold(body, d_lat, d_long, run.dt)
    poles, rows = continuous_poles(body, d_lat, d_long)
    block = np.zeros((5, 5))
    block[:3, :3], block[:3, 3:] = np.diag(poles[0]), rows[0]
    exponential = scipy.linalg.expm(block * run.dt)
    return float(
        max(
            np.abs(np.diag(exponential[:3, :3]) - a[0]).max(),
            np.abs(exponential[:3, 3:] - b[0]).max(),
        )
    )


def run_case(case: str, path: Path, args: argparse.Namespace) -> dict:
    """One case in a fresh process (its own peak memory); its JSON result."""
    command = [sys.executable, __file__, "--worker", case, "--path", str(path),
               "--seed", str(args.seed), "--family", args.family,
               "--max-steps", str(args.max_steps), "--workdir", str(args.workdir)]  # fmt: skip
    done = subprocess.run(
        command, capture_output=True, text=True, cwd=Path(__file__).parent, env=ONE_THREAD
    )
    if done.returncode != 0:
        raise RuntimeError(f"{case} on {path.name} failed:\n{done.stderr[-3000:]}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def describe(label: str, result: dict) -> str:
    """One row of the table."""
    ess_rate = result["min_ess"] / result["seconds"]
    per_draw = result["evaluations"] / result["min_ess"]
    return (
        f"{label:<22s} {result['seconds']:8.1f} {result['cpu']:8.1f} {result['peak_mb']:6.0f} "
        f"{result['evaluations']:10.0f} {result['steps']:6d} {result['tau']:6.1f} "
        f"{result['min_ess']:7.0f} {ess_rate:8.2f} {per_draw:8.1f} "
        f"{1e3 * result['per_evaluation']:8.3f} {result['converged']!s:>5s}"
    )


HEADER = (
    f"{'run / sampler':<22s} {'wall s':>8s} {'CPU s':>8s} {'MB':>6s} {'evals':>10s} "
    f"{'steps':>6s} {'tau':>6s} {'minESS':>7s} {'ESS/s':>8s} {'ev/ESS':>8s} "
    f"{'ms/eval':>8s} {'conv':>5s}"
)


def load_average() -> str:
    return " ".join(f"{value:.2f}" for value in os.getloadavg())


def worker(args: argparse.Namespace) -> None:
    """A case's own process: prints its result as one JSON line."""
    path = Path(args.path)
    if args.worker == "package":
        result = run_package(path, args.family, args.seed, args.max_steps, Path(args.workdir))
    else:
        steady = "lfilter" if args.worker == "peer-lfilter" else "loop"
        result = run_peer(path, args.family, args.seed, args.max_steps, steady)
    print(json.dumps(result))


def summarise(results: dict[tuple[float, str], dict], runs: list[float], cases: list) -> None:
    """Package / peer ratios per run, and the growth of the time per evaluation."""
    for seconds in runs:
        if "package" not in cases:
            break
        package = results[(seconds, "package")]
        for case in (case for case in CASES[1:] if case in cases):
            peer = results[(seconds, case)]
            rate = (package["min_ess"] / package["seconds"]) / (peer["min_ess"] / peer["seconds"])
            target = TARGETS.get(seconds) if case == "peer" else None
            goal = (
                f" (target >= {target:g}: {'met' if rate >= target else 'NOT met'})"
                if target
                else ""
            )
            print(
                f"{seconds:g} s run, package / {case}: ESS per second {rate:.1f}{goal}; "
                "evaluations per effective draw "
                f"{package['evaluations'] / package['min_ess']:.1f} against "
                f"{peer['evaluations'] / peer['min_ess']:.1f}"
            )
    if len(runs) < 2:
        return
    first, last = runs[0], runs[-1]
    for case in cases:
        growth = results[(last, case)]["per_evaluation"] / results[(first, case)]["per_evaluation"]
        wall = results[(last, case)]["seconds"] / results[(first, case)]["seconds"]
        print(
            f"{case}: time per evaluation {last:g} s run / {first:g} s run: {growth:.2f}; "
            f"wall time {wall:.2f}"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", default="38,300", help="run lengths [s], comma-separated")
    parser.add_argument("--workdir", type=Path, default=None)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--family", default="exponential", choices=("exponential", "white"))
    parser.add_argument("--max-steps", type=int, default=MAX_STEPS, help="step cap of all chains")
    parser.add_argument("--cases", default=",".join(CASES), help="of " + ",".join(CASES))
    parser.add_argument("--worker", choices=CASES, help=argparse.SUPPRESS)
    parser.add_argument("--path", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.worker:
        worker(args)
        return
    args.workdir = work_folder(args.workdir, "bench_peer_")
    runs = [float(value) for value in args.runs.split(",")]
    print(f"load average at start: {load_average()}; files in {args.workdir}")
    paths = {seconds: make_run(args.workdir, seconds) for seconds in runs}
    print(
        f"peer ZOH against scipy expm: max difference {check_discretisation(paths[runs[0]]):.1g}"
    )
    for family in dict.fromkeys((args.family, "white")):
        for path in paths.values():
            check_likelihood(path, family)
    results: dict[tuple[float, str], dict] = {}
    print(HEADER)
    cases = args.cases.split(",")
    for seconds, path in paths.items():
        for case in sorted(cases, key=CASES.index):
            results[(seconds, case)] = run_case(case, path, args)
            print(describe(f"{seconds:g} s {case}", results[(seconds, case)]), flush=True)
    for (seconds, case), result in results.items():
        medians = ", ".join(f"{value:.1f}" for value in result["median"])
        start = result.get("map")
        start = f"; started at its MAP {start[0]:.1f}, {start[1]:.1f}" if start else ""
        print(f"{seconds:g} s {case}: posterior median d_lat, d_long {medians} N s/m{start}")
    summarise(results, runs, cases)
    print(f"load average at end: {load_average()}")


if __name__ == "__main__":
    main()
