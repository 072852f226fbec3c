"""Posterior of the damping and the noise parameters, sampled with emcee (DESIGN §4).

Priors: d_lat, d_long uniform on the profile's ranges; every kernel width,
sigma_c and sigma_n log-uniform. The sampler works in z = log(theta), where
the damping ridge d_lat / d_long ~ const is straight (see :class:`Prior`).

The run: the likelihood profiled over each noise group's parameters on a
design over the damping, local optimisations from the best profile points
to the maximum a posteriori (MAP), walkers drawn from the Laplace
approximation there, and emcee's ensemble with differential-evolution
moves until the
chain is longer than 50 integrated autocorrelation times and that estimate
changed by less than 1 % (emcee's monitoring recipe), or a step cap with a
:class:`ConvergenceWarning`. Every step is stored in an HDF5 file; a run
started again with the same file and settings resumes where it stopped.
"""

from __future__ import annotations

import hashlib
import json
import warnings
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import emcee
import h5py
import numpy as np
import scipy.optimize
import scipy.stats

from .errors import InputError
from .likelihood import ResidualLikelihood
from .noise_profile import profile_starts
from .posterior import az, build_inference_data
from .progress import Progress
from .robot import RobotProfile

__all__ = [
    "BufferedHDFBackend",
    "ConvergenceWarning",
    "LogPosterior",
    "Prior",
    "SamplerSettings",
    "find_map",
    "sample_posterior",
]


class ConvergenceWarning(UserWarning):
    """The chain hit its step cap before the convergence criterion held."""


@dataclass(frozen=True)
class Prior:
    """Independent uniform or log-uniform priors on a box.

    The sampler works in z = log(theta) for every parameter: the ridge of
    the damping, d_lat / d_long ~ const, is a straight line there, which
    affine-invariant moves cross easily. A prior uniform in theta has
    log-density z - log(high - low) in z; a log-uniform one is constant.

    Attributes
    ----------
    names : tuple of str
        Parameter names, as :attr:`ResidualLikelihood.parameter_names`.
    low, high : ndarray, shape (P,)
        Bounds in natural units.
    log_uniform : ndarray of bool, shape (P,)
        Log-uniform (True) or uniform (False) in natural units.
    """

    names: tuple[str, ...]
    low: np.ndarray
    high: np.ndarray
    log_uniform: np.ndarray

    @classmethod
    def for_likelihood(
        cls, likelihood: ResidualLikelihood, robot: RobotProfile, overrides: dict | None = None
    ) -> Prior:
        """Priors of every parameter of ``likelihood`` from the robot profile.

        ``overrides`` maps a base name (``d_lat``, ``d_long``, ``sigma_h``,
        ``sigma_c``, ``sigma_n``) to a (low, high) pair. Every noise family's
        width takes the ``sigma_h`` range.
        """
        ranges = {**robot.priors, **(overrides or {})}
        low, high, log_uniform = [], [], []
        for name in likelihood.parameter_names:
            base = name.split("[")[0]
            key = "sigma_h" if base == "width" else base
            lo, hi = (float(v) for v in ranges[key])
            if not (np.isfinite(lo) and np.isfinite(hi) and 0 < lo < hi):
                raise InputError(
                    f"prior range must satisfy 0 < low < high, got [{lo}, {hi}]: it excludes "
                    "every value",
                    field=f"priors.{key}",
                )
            low.append(lo)
            high.append(hi)
            log_uniform.append(base not in ("d_lat", "d_long"))
        return cls(
            tuple(likelihood.parameter_names), np.array(low), np.array(high), np.array(log_uniform)
        )

    @property
    def z_low(self) -> np.ndarray:
        """Lower bounds of z = log(theta)."""
        return np.log(self.low)

    @property
    def z_high(self) -> np.ndarray:
        """Upper bounds of z = log(theta)."""
        return np.log(self.high)

    def log_density(self, z: np.ndarray) -> np.ndarray:
        """Log prior density of z = log(theta) inside the box, shape (...)."""
        uniform = np.where(self.log_uniform, 0.0, z - np.log(self.high - self.low))
        log_uniform = np.where(self.log_uniform, -np.log(self.z_high - self.z_low), 0.0)
        return np.sum(uniform + log_uniform, axis=-1)

    @staticmethod
    def to_natural(z: np.ndarray) -> np.ndarray:
        """Natural units from sampling coordinates."""
        return np.exp(z)

    def inside(self, z: np.ndarray) -> np.ndarray:
        """Whether each point lies in the prior's support."""
        return np.all((z >= self.z_low) & (z <= self.z_high), axis=-1)

    def from_unit(self, u: np.ndarray) -> np.ndarray:
        """z of the prior quantiles ``u`` in [0, 1]^P: maps uniform draws to prior draws."""
        uniform = np.log(self.low + u * (self.high - self.low))
        return np.where(self.log_uniform, self.z_low + u * (self.z_high - self.z_low), uniform)

    def draw(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """``n`` prior draws in z from a scrambled Sobol design, shape (n, P)."""
        return self.from_unit(
            scipy.stats.qmc.Sobol(len(self.names), scramble=True, seed=rng).random(n)
        )


@dataclass(frozen=True)
class LogPosterior:
    """Vectorised log-posterior in sampling coordinates (for emcee, vectorize=True)."""

    likelihood: ResidualLikelihood
    prior: Prior

    def __call__(self, z: np.ndarray) -> np.ndarray:
        z = np.atleast_2d(z)
        out = np.full(len(z), -np.inf)
        inside = self.prior.inside(z)
        if inside.any():
            loglike = self.likelihood(self.prior.to_natural(z[inside]))
            out[inside] = loglike + self.prior.log_density(z[inside])
        return np.where(np.isnan(out), -np.inf, out)


@dataclass(frozen=True)
class SamplerSettings:
    """How long and how wide to sample.

    Attributes
    ----------
    walkers : int
        Ensemble size; 0 means max(32, 4 x parameters), rounded up to even.
    max_steps : int
        Step cap; reaching it without convergence warns loudly.
    check_every : int
        Steps between convergence checks.
    autocorr_multiple : float
        The chain must be longer than this many autocorrelation times (50).
    tau_rtol : float
        ... and the estimate must have changed by less than this (1 %).
    design_points : int
        Size of the MAP search's design: ``design_points / 16`` damping
        points, each crossed with every noise group's grid (:func:`find_map`).
    progress : bool
        Show the chain's progress on stderr: a bar on a terminal, a plain
        line every 10 s elsewhere (:class:`bayes_jackal.progress.Progress`).
    progress_label : str
        The bar's label.
    progress_line : int
        The bar's line on the terminal (one per process sampling at once).
    """

    walkers: int = 0
    max_steps: int = 20_000
    check_every: int = 100
    autocorr_multiple: float = 50.0
    tau_rtol: float = 0.01
    design_points: int = 1024
    progress: bool = False
    progress_label: str = "emcee"
    progress_line: int = 0

    def n_walkers(self, ndim: int) -> int:
        walkers = self.walkers or max(32, 4 * ndim)
        if walkers < 2 * ndim:
            raise InputError(f"need at least {2 * ndim} walkers, got {walkers}", field="walkers")
        return walkers + walkers % 2


#: Local searches of :func:`find_map`, from the best points of the profile.
_MAP_STARTS = 4


def find_map(
    log_posterior: LogPosterior, rng: np.random.Generator, design_points: int = 1024
) -> np.ndarray:
    """Maximum a posteriori point in sampling coordinates.

    The likelihood is a sum over noise groups, each depending on the damping
    and its own noise only, so its profile over each group's noise on a
    design over the damping (:func:`bayes_jackal.noise_profile.profile_starts`,
    ``design_points / 16`` damping points) finds the basin where every
    channel's noise is right at once, which a design over the whole prior
    box does not. Its best points start bounded quasi-Newton (L-BFGS-B)
    searches on a scan of the posterior that uses the exact spectral engine
    without its slow fallback (long-memory corners of the prior, e.g. a 1 s
    kernel over 1e-4 sensor noise, count as -inf there); line scans of the
    kernel widths move the best end point out of a local optimum's basin
    (:func:`_sweep_widths`) and a search starts again from there, and the
    result is polished on ``log_posterior`` itself.

    Parameters
    ----------
    log_posterior : LogPosterior
    rng : numpy.random.Generator
        Scrambles the damping design: same seed, same result.
    design_points : int
        Sixteen times the size of the damping design (at least 16 points).

    Returns
    -------
    ndarray, shape (P,)
        z = log(theta) of the MAP.

    Raises
    ------
    InputError
        When the log-posterior is -inf at every start.
    """
    prior = log_posterior.prior
    scan = replace(log_posterior.likelihood, engine="fast", fallback=False)
    scan_posterior = LogPosterior(scan, prior)
    # Noise far below the data's overflows the likelihood's terms: -inf, checked below.
    with np.errstate(over="ignore", divide="ignore"):
        theta, _ = profile_starts(
            log_posterior.likelihood,
            prior.low,
            prior.high,
            damping_points=max(16, design_points // 16),
            starts=_MAP_STARTS,
            rng=rng,
        )
        starts = np.log(theta)
        finite = np.isfinite(log_posterior(starts))
    if not finite.any():
        raise InputError(
            f"the log-posterior is -inf at every start of the MAP search (the best {len(starts)} "
            "points of the profile likelihood): the priors exclude every parameter value the "
            "data allow",
            field="priors",
        )
    bounds = list(zip(prior.z_low, prior.z_high, strict=True))

    def maximise(function: LogPosterior, start: np.ndarray) -> scipy.optimize.OptimizeResult:
        # Finite differences next to a -inf region subtract inf - inf there;
        # L-BFGS-B treats the NaN as a failed step and backs off.
        with np.errstate(invalid="ignore"):
            return scipy.optimize.minimize(
                _with_gradient(function, prior), start, method="L-BFGS-B", jac=True, bounds=bounds
            )

    best = max((maximise(scan_posterior, start) for start in starts), key=lambda r: -r.fun)
    for _ in range(3):
        swept = _sweep_widths(scan_posterior, best.x, prior)
        if np.array_equal(swept, best.x):
            break
        best = maximise(scan_posterior, swept)
    polished = maximise(log_posterior, best.x)
    return polished.x if np.isfinite(polished.fun) else best.x


def _with_gradient(function: LogPosterior, prior: Prior):
    """-function(z) and its forward-difference gradient from one vectorised call.

    The P + 1 points are evaluated as one batch (about half the cost of
    P + 1 single calls); steps point into the prior box, as scipy's own
    finite differences do at a bound.
    """

    def negative(z: np.ndarray) -> tuple[float, np.ndarray]:
        step = np.sqrt(np.finfo(float).eps) * np.maximum(1.0, np.abs(z))
        step = np.where(z + step > prior.z_high, -step, step)
        values = -function(np.vstack([z, z + np.diag(step)]))
        return values[0], (values[1:] - values[0]) / step

    return negative


def _sweep_widths(
    function: LogPosterior, z: np.ndarray, prior: Prior, points: int = 256
) -> np.ndarray:
    """Move each kernel width to the best of a grid over its prior range, the rest held.

    A kernel width can have separated optima: the moving-average family's
    likelihood in its width has local maxima at about half and 1.5 times
    the best width, hundreds of nats lower, and a local search started in
    their basins stays there. A line scan of each width finds the best basin.
    """
    for column, name in enumerate(prior.names):
        if not name.startswith(("sigma_h", "width")):
            continue
        candidates = np.repeat(z[None], points + 1, axis=0)
        candidates[1:, column] = np.linspace(prior.z_low[column], prior.z_high[column], points)
        z = candidates[np.argmax(function(candidates))]
    return z


def _laplace_walkers(
    log_posterior: LogPosterior, centre: np.ndarray, walkers: int, rng: np.random.Generator
) -> np.ndarray:
    """Walkers from the Laplace approximation at ``centre``, kept inside the prior.

    A MAP on the prior's boundary (the damping ridge can run into it) has no
    Laplace approximation; the walkers then start in a small ball.
    """
    prior = log_posterior.prior
    span = prior.z_high - prior.z_low
    step = 1e-4 * span
    centre = np.clip(centre, prior.z_low + 10 * step, prior.z_high - 10 * step)
    ndim = len(centre)
    # Central-difference Hessian from one vectorised call over the stencil.
    rows, cols = np.triu_indices(ndim)
    signs = np.array([[1, 1], [1, -1], [-1, 1], [-1, -1]])
    offsets = np.zeros((len(rows), 4, ndim))
    pairs = np.arange(len(rows))[:, None]
    offsets[pairs, np.arange(4), rows[:, None]] += signs[:, 0] * step[rows][:, None]
    offsets[pairs, np.arange(4), cols[:, None]] += signs[:, 1] * step[cols][:, None]
    values = log_posterior(centre + offsets.reshape(-1, ndim)).reshape(-1, 4)
    hessian = np.zeros((ndim, ndim))
    hessian[rows, cols] = values @ np.array([1, -1, -1, 1]) / (4 * step[rows] * step[cols])
    hessian[cols, rows] = hessian[rows, cols]
    ball = np.diag((1e-3 * span) ** 2)
    covariance = ball
    if np.all(np.isfinite(hessian)):
        try:
            covariance = np.linalg.inv(-hessian)
            np.linalg.cholesky(covariance)
        except np.linalg.LinAlgError:
            covariance = ball
    points = rng.multivariate_normal(centre, 0.25 * covariance, size=8 * walkers)
    points = points[prior.inside(points)]
    points = points[np.isfinite(log_posterior(points))]
    if len(points) < walkers:
        points = rng.multivariate_normal(centre, ball, size=8 * walkers)
        points = points[prior.inside(points)]
    return points[:walkers]


def _moves() -> list:
    """Differential-evolution moves with snooker updates (emcee's recommendation for
    curved targets): along the damping ridge the noise parameters bend with the
    damping scale, and these cut the autocorrelation time ~3x against the
    stretch move (measured: tau 88 vs 247 steps on a thesis-like experiment)."""
    return [(emcee.moves.DEMove(), 0.8), (emcee.moves.DESnookerMove(), 0.2)]


def _fingerprint(likelihood: ResidualLikelihood, prior: Prior, walkers: int, seed) -> str:
    """Hash of everything that defines a chain, to refuse resuming a different run."""
    digest = hashlib.sha256()
    for experiment in likelihood.experiments:
        for values in (experiment.t, experiment.yaw_rate, experiment.omega_r, experiment.omega_l):
            digest.update(np.ascontiguousarray(values).tobytes())
        for values in (experiment.vx, experiment.vy):
            if values is not None:
                digest.update(np.ascontiguousarray(values).tobytes())
    settings = {
        "family": likelihood.family,
        "channels": likelihood.channels,
        "shared_noise": likelihood.shared_noise,
        "sensor": likelihood.sensor,
        "engine": likelihood.engine,
        "steady": likelihood.steady,
        "low": prior.low.tolist(),
        "high": prior.high.tolist(),
        "walkers": walkers,
        "seed": seed,
    }
    digest.update(json.dumps(settings, sort_keys=True).encode())
    return digest.hexdigest()


class BufferedHDFBackend(emcee.backends.HDFBackend):
    """emcee's HDF5 backend, writing steps in batches.

    emcee's own backend opens the file for every step, which costs ~3 ms a
    step, more than the likelihood. This one keeps up to ``flush_every``
    steps in memory and writes them at once; the sampler flushes at every
    convergence check and on any exit, a KeyboardInterrupt included, so an
    interrupted run keeps every completed step (a hard kill can lose the
    steps since the last check).
    """

    def __init__(self, filename: str, flush_every: int):
        super().__init__(filename, name="mcmc")
        self.flush_every = flush_every
        self._pending: list[tuple] = []

    @property
    def iteration(self) -> int:
        return super().iteration + len(self._pending)

    @property
    def accepted(self) -> np.ndarray:
        self.flush()
        return super().accepted

    @property
    def random_state(self):
        self.flush()
        return super().random_state

    def get_value(self, name, flat=False, thin=1, discard=0):
        self.flush()
        return super().get_value(name, flat=flat, thin=thin, discard=discard)

    def save_step(self, state, accepted) -> None:
        self._pending.append(
            (state.coords.copy(), state.log_prob.copy(), accepted.copy(), state.random_state)
        )
        if len(self._pending) >= self.flush_every:
            self.flush()

    def flush(self) -> None:
        """Write the buffered steps to the file."""
        if not self._pending:
            return
        coords, log_prob, accepted, _ = zip(*self._pending, strict=True)
        with self.open("a") as stored:
            group = stored[self.name]
            start = int(group.attrs["iteration"])
            stop = start + len(coords)
            group["chain"][start:stop] = np.stack(coords)
            group["log_prob"][start:stop] = np.stack(log_prob)
            group["accepted"][:] += np.sum(accepted, axis=0)
            for i, value in enumerate(self._pending[-1][3]):
                group.attrs[f"random_state_{i}"] = value
            group.attrs["iteration"] = stop
        self._pending.clear()


def _backend(path: Path | None, fingerprint: str, walkers: int, ndim: int, flush_every: int):
    """emcee backend: in memory, or an HDF5 file that resumes a matching run."""
    if path is None:
        backend = emcee.backends.Backend()
        backend.reset(walkers, ndim)
        return backend
    backend = BufferedHDFBackend(str(path), flush_every)
    if path.exists():
        try:
            with h5py.File(path, "r") as stored:
                previous = stored.attrs.get("fingerprint")
        except OSError as exc:
            raise InputError(f"not a readable chain file ({exc})", source=str(path)) from None
        if previous == fingerprint and backend.iteration > 0:
            return backend
        if previous is not None and previous != fingerprint:
            raise InputError(
                "holds a chain of a different run (other data, model, priors, walkers or "
                "seed); remove it or choose another output",
                source=str(path),
            )
    backend.reset(walkers, ndim)
    with h5py.File(path, "a") as stored:
        stored.attrs["fingerprint"] = fingerprint
    return backend


def _run_until_converged(
    sampler: emcee.EnsembleSampler, start, settings: SamplerSettings
) -> tuple[bool, np.ndarray]:
    """Advance the chain until the autocorrelation criterion holds or the cap is reached."""
    previous_tau = np.full(sampler.ndim, np.inf)
    remaining = settings.max_steps - sampler.iteration
    tau = previous_tau
    if remaining > 0:
        with Progress(
            settings.max_steps,
            settings.progress_label,
            enabled=settings.progress,
            position=settings.progress_line,
            initial=sampler.iteration,
        ) as progress:
            for _ in sampler.sample(start, iterations=remaining):
                progress.update()
                if sampler.iteration % settings.check_every:
                    continue
                tau = sampler.get_autocorr_time(tol=0)
                progress.update(0, tau=f"{np.max(tau):.0f}")
                long_enough = np.all(tau * settings.autocorr_multiple < sampler.iteration)
                if long_enough and np.all(np.abs(previous_tau - tau) < settings.tau_rtol * tau):
                    return True, tau
                previous_tau = tau
    tau = sampler.get_autocorr_time(tol=0)
    converged = bool(np.all(tau * settings.autocorr_multiple < sampler.iteration))
    return converged, tau


def sample_posterior(
    likelihood: ResidualLikelihood,
    settings: SamplerSettings | None = None,
    seed: int | None = None,
    chain_file: str | Path | None = None,
    prior_overrides: dict | None = None,
) -> az.InferenceData:
    """Sample the posterior of a residual likelihood with emcee.

    Parameters
    ----------
    likelihood : ResidualLikelihood
        Experiments, channels, noise family, sensor model and engine.
    settings : SamplerSettings, optional
    seed : int, optional
        Seeds the design, the walkers and emcee's moves: same seed, same chain.
    chain_file : str or Path, optional
        HDF5 file of the chain; a run with the same file and settings resumes.
    prior_overrides : dict, optional
        (low, high) per base parameter name, over the profile's ranges.

    Returns
    -------
    arviz.InferenceData
        Groups ``posterior`` (parameters and derived ratio, Ad, Bd),
        ``sample_stats`` (lp, log_likelihood_total), ``observed_data`` (residuals at
        the posterior median), ``constant_data`` (the measured experiments);
        ``attrs`` hold convergence diagnostics and the settings.
    """
    settings = settings or SamplerSettings()
    robot = likelihood.robot
    prior = Prior.for_likelihood(likelihood, robot, prior_overrides)
    log_posterior = LogPosterior(likelihood, prior)
    ndim = len(prior.names)
    walkers = settings.n_walkers(ndim)
    rng = np.random.default_rng(seed)
    backend = _backend(
        None if chain_file is None else Path(chain_file),
        _fingerprint(likelihood, prior, walkers, seed),
        walkers,
        ndim,
        settings.check_every,
    )
    sampler = emcee.EnsembleSampler(
        walkers, ndim, log_posterior, vectorize=True, backend=backend, moves=_moves()
    )
    if backend.iteration == 0:
        centre = find_map(log_posterior, rng, settings.design_points)
        initial = _laplace_walkers(log_posterior, centre, walkers, rng)
        moves_state = np.random.RandomState(int(rng.integers(2**32))).get_state()
        start = emcee.State(initial, random_state=moves_state)
    else:
        start = sampler.get_last_sample()
    try:
        converged, tau = _run_until_converged(sampler, start, settings)
    finally:
        if isinstance(backend, BufferedHDFBackend):
            backend.flush()
    if not converged:
        warnings.warn(
            ConvergenceWarning(
                f"NOT CONVERGED: {sampler.iteration} steps are fewer than "
                f"{settings.autocorr_multiple:g} autocorrelation times (max tau "
                f"{np.max(tau):.0f} steps); raise max_steps or resume the run"
            ),
            stacklevel=2,
        )
    return _inference_data(sampler, log_posterior, tau, converged, settings, seed)


def _inference_data(sampler, log_posterior, tau, converged, settings, seed) -> az.InferenceData:
    """Keep the chain after 2 tau of burn-in, thinned by tau / 2, with its diagnostics."""
    names = log_posterior.prior.names
    discard = min(int(np.ceil(2 * np.max(tau))), sampler.iteration // 2)
    thin = max(1, int(np.min(tau) / 2))
    kept = sampler.iteration - discard
    diagnostics = {
        "converged": converged,
        "n_steps": int(sampler.iteration),
        "walkers": int(sampler.nwalkers),
        "discard": discard,
        "thin": thin,
        "autocorr_time": dict(zip(names, map(float, tau), strict=True)),
        "ess_autocorr": {
            n: float(sampler.nwalkers * kept / t) for n, t in zip(names, tau, strict=True)
        },
        "acceptance_fraction": float(np.mean(sampler.acceptance_fraction)),
        "seed": seed,
        "settings": asdict(settings),
    }
    return build_inference_data(
        log_posterior.likelihood,
        log_posterior.prior,
        sampler.get_chain(discard=discard, thin=thin),
        sampler.get_log_prob(discard=discard, thin=thin),
        diagnostics,
    )
