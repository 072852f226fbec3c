"""Running an emcee chain to convergence: stored step by step, resumed, kept after burn-in.

The ensemble moves with differential evolution, and with independent
draws from an approximation of the posterior where the start gives one
(its Laplace approximation, moments or a mixture along its ridge:
:mod:`bayes_jackal.inference.moves`), until the answer is known:
the chain is longer than 50 integrated autocorrelation times (emcee's
advice, so that tau itself is estimated reliably) and every parameter has
an effective sample size of at least 400 in the bulk and in the tails
(arviz's rank-normalised ``ess``, walkers as chains, on the draws kept
after burn-in; Vehtari et al. 2021), or a step cap with a
:class:`~bayes_jackal.inference.ConvergenceWarning`. Every step is
stored in an HDF5 file; a run started again with the same file and
fingerprint resumes where it stopped. The posteriors of the robot model
(:mod:`bayes_jackal.inference.sampling`) and of a bare noise series run on it.
"""

from __future__ import annotations

import contextlib
import logging
import math
import warnings
from collections.abc import Callable
from dataclasses import asdict, dataclass, fields
from pathlib import Path

import emcee
import h5py
import numpy as np
import scipy.fft
import xarray as xr

from .._runtime import (
    AUTOCORR_MULTIPLE,
    BRIDGE_MIN_DRAWS,
    MAX_STEPS,
    MIN_ESS,
    MIN_EVIDENCE_STEPS,
    WALKERS,
    InputError,
    OutputError,
    OutputLock,
    Phase,
    Progress,
    atomic_path,
    az,
    check_interrupt,
    check_space,
    interrupts_deferred,
    one_blas_thread,
    refuse_link,
)
from .moves import (
    Approximation,
    BlockT,
    BoundedLaplace,
    GroupGrid,
    LaplaceApproximation,
    MixtureApproximation,
    Start,
    ensemble_moves,
)
from .sampler_warnings import ConvergenceWarning

__all__ = [
    "BufferedHDFBackend",
    "Chain",
    "SamplerSettings",
    "autocorrelation_time",
    "effective_sizes",
    "run_chain",
]

#: The stage's messages (INFO): :mod:`bayes_jackal._runtime.messages`.
_log = logging.getLogger(__package__)

#: A mixture approximation's fields, each a dataset ``mixture_<field>`` of a chain file.
MIXTURE_FIELDS = ("weights", "centres", "covariances")
#: A bounded Laplace approximation's, each a dataset ``bounded_<field>``.
BOUNDED_FIELDS = tuple(field.name for field in fields(BoundedLaplace))
#: The fields of each kind of block proposal kept in a chain file, in its class's order.
BLOCK_FIELDS = {
    "grid": (
        GroupGrid,
        (
            "columns",
            "low",
            "high",
            "log_probability",
            "points",
            "box_low",
            "box_high",
            "conditional_columns",
            "conditional_mean",
            "conditional_covariance",
        ),
    ),
    "t": (BlockT, ("columns", "centre", "covariance")),
}
#: The approximations kept as datasets: their prefix in a chain file, and their fields.
_KIND = {
    MixtureApproximation: ("mixture", MIXTURE_FIELDS),
    BoundedLaplace: ("bounded", BOUNDED_FIELDS),
}


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
    min_ess : int
        ... and have at least this bulk and tail effective sample size for
        every parameter after burn-in (400; 0 leaves the 50-tau rule alone).
    design_points : int
        Size of the MAP search's design: ``design_points / 16`` damping
        points, each crossed with every noise group's grid
        (:func:`bayes_jackal.inference.find_map`).
    progress : bool
        Show the chain's progress on stderr: a bar on a terminal, a plain
        line every 10 s elsewhere (:class:`bayes_jackal._runtime.progress.Progress`).
    progress_label : str
        The bar's label.
    progress_line : int
        The bar's line on the terminal (one per process sampling at once).

    Examples
    --------
    A step cap of 5000; the default ensemble has max(32, 4 x parameters)
    walkers:

    >>> import bayes_jackal as bj
    >>> settings = bj.SamplerSettings(max_steps=5000)
    >>> settings.max_steps, settings.n_walkers(4), settings.n_walkers(10)
    (5000, 32, 40)
    >>> try:
    ...     bj.SamplerSettings(max_steps=0)
    ... except bj.InputError as error:
    ...     print(error)
    max_steps: must be an integer >= 1, got 0
    """

    walkers: int = WALKERS
    max_steps: int = MAX_STEPS
    check_every: int = 100
    autocorr_multiple: float = AUTOCORR_MULTIPLE
    min_ess: int = MIN_ESS
    design_points: int = 1024
    progress: bool = False
    progress_label: str = "emcee"
    progress_line: int = 0

    def __post_init__(self) -> None:
        counts = {
            "walkers": (self.walkers, 0),
            "max_steps": (self.max_steps, 1),
            "check_every": (self.check_every, 1),
            "design_points": (self.design_points, 16),  # design_points / 16 damping points
            "min_ess": (self.min_ess, 0),
        }
        for name, (value, least) in counts.items():
            if isinstance(value, bool) or not isinstance(value, int) or value < least:
                raise InputError(f"must be an integer >= {least}, got {value!r}", field=name)
        value = self.autocorr_multiple
        if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
            raise InputError(
                f"must be a finite number > 0, got {value!r}", field="autocorr_multiple"
            )

    def check_evidence_steps(self) -> None:
        """Refuse a step cap too short for bridge sampling (before any sampling).

        Raises
        ------
        InputError
            For ``max_steps`` < :data:`bayes_jackal._runtime.defaults.MIN_EVIDENCE_STEPS`.

        Examples
        --------
        >>> import bayes_jackal as bj
        >>> try:
        ...     bj.SamplerSettings(max_steps=10).check_evidence_steps()
        ... except bj.InputError as error:
        ...     print(error)
        max_steps: must be at least 16 to estimate the evidence (bridge sampling needs 8 draws
        from the chain's second half), got 10
        """
        if self.max_steps < MIN_EVIDENCE_STEPS:
            raise InputError(
                f"must be at least {MIN_EVIDENCE_STEPS} to estimate the evidence (bridge sampling "
                f"needs {BRIDGE_MIN_DRAWS} draws from the chain's second half), got "
                f"{self.max_steps}",
                field="max_steps",
            )

    def n_walkers(self, ndim: int) -> int:
        walkers = self.walkers or max(32, 4 * ndim)
        if walkers < 2 * ndim:
            raise InputError(f"need at least {2 * ndim} walkers, got {walkers}", field="walkers")
        return walkers + walkers % 2


class BufferedHDFBackend(emcee.backends.HDFBackend):
    """emcee's HDF5 backend, writing steps in batches.

    emcee's own backend opens the file for every step, which costs ~3 ms a
    step, more than the likelihood. This one keeps up to ``flush_every``
    steps in memory and writes them at once; the sampler flushes at every
    convergence check and on any exit, a KeyboardInterrupt included, so an
    interrupted run keeps every completed step (a hard kill can lose the
    steps since the last check).

    A full disk never reaches HDF5, which cannot recover from a failed
    write: each write is first checked against the free space and the
    file-size limit (:func:`bayes_jackal._runtime.files.check_space`) and refused
    with an :class:`~bayes_jackal._runtime.errors.OutputError` naming the chain file,
    which is left as it was: the steps stored so far resume. The refused
    batch (at most ``flush_every`` steps) is dropped.

    Examples
    --------
    The chain file of a run, read back: every one of its 20 steps is stored.
    The 20-step chain is short on purpose (the doctests skip it, as it writes
    a file; tests/test_outputs.py reads chain files back):

    >>> import tempfile
    >>> from pathlib import Path
    >>> import bayes_jackal as bj
    >>> from bayes_jackal.inference import BufferedHDFBackend
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1)
    >>> with tempfile.TemporaryDirectory() as folder:  # doctest: +SKIP
    ...     chain = Path(folder) / "posterior.chain.h5"
    ...     posterior = bj.sample(
    ...         [run], family="white", channels=["yaw"], max_steps=20, seed=1, chain_file=chain
    ...     )
    ...     backend = BufferedHDFBackend(str(chain), flush_every=100)
    ...     int(backend.iteration), backend.get_chain().shape
    (20, (20, 32, 4))
    """

    def __init__(self, filename: str, flush_every: int):
        super().__init__(filename, name="mcmc")
        self.flush_every = flush_every
        self._pending: list[tuple] = []
        self._chunk_bytes: dict[str, tuple[int, int]] = {}
        self._stored: int | None = None  # steps in the file, read once

    @contextlib.contextmanager
    def writing(self, steps: int = 0):
        """Check the room for ``steps`` more steps; make a failed write an OutputError."""
        path = Path(self.filename)
        advice = (
            "; the chain file keeps the steps stored so far and resumes: free some space "
            "and run the same command again"
        )
        check_space(path, self._bytes_needed(steps), grows=True, advice=advice)
        try:
            yield
        except OSError as exc:
            if isinstance(exc, OutputError):
                raise
            raise OutputError.from_os_error(path, exc, advice=advice) from None

    def _bytes_needed(self, steps: int) -> int:
        """The bytes ``steps`` more steps add: the chunks they allocate, whole."""
        if not steps:
            return 0
        with self.open("r") as stored:
            start = int(stored[self.name].attrs["iteration"])
            if not self._chunk_bytes:
                for name in ("chain", "log_prob"):
                    dataset = stored[self.name][name]
                    chunks = dataset.chunks or dataset.shape
                    across = np.prod(np.ceil(np.divide(dataset.shape[1:], chunks[1:])))
                    chunk = dataset.dtype.itemsize * int(np.prod(chunks))
                    self._chunk_bytes[name] = (chunks[0], int(across) * chunk)
        return sum(
            (-(-(start + steps) // rows) - -(-start // rows)) * band
            for rows, band in self._chunk_bytes.values()
        )

    def grow(self, ngrow, blobs) -> None:
        with self.writing():
            super().grow(ngrow, blobs)

    def reset(self, nwalkers, ndim) -> None:
        super().reset(nwalkers, ndim)
        self._stored = None

    @property
    def iteration(self) -> int:
        # emcee asks every step; reading the file each time cost ~1 ms a step.
        if self._stored is None:
            self._stored = super().iteration
        return self._stored + len(self._pending)

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
        pending, self._pending = self._pending, []  # dropped if refused: the file stays as it was
        coords, log_prob, accepted, _ = zip(*pending, strict=True)
        with self.writing(len(pending)), self.open("a") as stored:
            group = stored[self.name]
            start = int(group.attrs["iteration"])
            stop = start + len(coords)
            group["chain"][start:stop] = np.stack(coords)
            group["log_prob"][start:stop] = np.stack(log_prob)
            group["accepted"][:] += np.sum(accepted, axis=0)
            for i, value in enumerate(pending[-1][3]):
                group.attrs[f"random_state_{i}"] = value
            group.attrs["iteration"] = stop
        self._stored = stop


def _backend(path: Path | None, fingerprint: str, walkers: int, ndim: int, flush_every: int):
    """emcee backend: in memory, or an HDF5 file that resumes a matching run."""
    if path is None:
        backend = emcee.backends.Backend()
        backend.reset(walkers, ndim)
        return backend
    refuse_link(path)  # a link planted at the chain's name is never written through
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
    # Built beside it and moved into place whole: a run killed while creating
    # it (SIGKILL, a full disk) leaves no half-written file that its rerun
    # could neither read nor, not knowing it for its own, replace.
    # Errors name the chain file (backend.writing), never the temporary.
    with backend.writing(), atomic_path(path) as fresh:
        h5py.File(fresh, "w").close()
        created = BufferedHDFBackend(str(fresh), flush_every)
        created.reset(walkers, ndim)
        with h5py.File(fresh, "a") as stored:
            stored.attrs["fingerprint"] = fingerprint
    return backend


def autocorrelation_time(chain: np.ndarray, c: float = 5.0) -> np.ndarray:
    """Integrated autocorrelation time of each parameter of an ensemble's chain [steps].

    emcee's estimator (``emcee.autocorr.integrated_time`` with ``tol=0``):
    the walkers' normalised autocorrelation functions averaged, summed up to
    Sokal's automatic window (the first lag M with M >= c tau(M)). All the
    walkers of a parameter in one transform instead of one per walker.

    Parameters
    ----------
    chain : ndarray, shape (steps, walkers, k)
    c : float
        The window's multiple of tau.

    Returns
    -------
    ndarray, shape (k,)

    Examples
    --------
    An AR(1) chain of coefficient 0.5 has tau = (1 + 0.5) / (1 - 0.5) = 3:

    >>> import numpy as np
    >>> import scipy.signal
    >>> from bayes_jackal.inference import autocorrelation_time
    >>> noise = np.random.default_rng(1).standard_normal((20000, 8, 1))
    >>> chain = scipy.signal.lfilter([1.0], [1.0, -0.5], noise, axis=0)
    >>> round(float(autocorrelation_time(chain)[0]), 1)
    3.0
    """
    steps = len(chain)
    size = 2 * 2 ** int(np.ceil(np.log2(max(steps, 1))))  # emcee's zero padding
    tau = np.empty(chain.shape[2])
    for k in range(chain.shape[2]):  # one parameter's walkers at a time: bounded memory
        deviations = chain[:, :, k] - chain[:, :, k].mean(axis=0)
        power = np.abs(scipy.fft.rfft(deviations, size, axis=0)) ** 2
        acf = scipy.fft.irfft(power, size, axis=0)[:steps]
        with np.errstate(invalid="ignore", divide="ignore"):  # a stuck walker: NaN, as emcee
            taus = 2.0 * np.cumsum(np.mean(acf / acf[0], axis=1)) - 1.0
        inside = np.arange(steps) < c * taus
        tau[k] = taus[np.argmin(inside) if np.any(inside) else steps - 1]
    return tau


def effective_sizes(draws: np.ndarray) -> np.ndarray:
    """arviz's bulk and tail effective sample sizes of each parameter, shape (2, k).

    ``draws`` (steps, walkers, k), the walkers taken as chains.

    Examples
    --------
    Independent draws: as many effective draws as draws, in the bulk and the tails:

    >>> import numpy as np
    >>> from bayes_jackal.inference import effective_sizes
    >>> sizes = effective_sizes(np.random.default_rng(4).standard_normal((1000, 8, 2)))
    >>> sizes.shape, bool(np.all(np.abs(sizes / 8000 - 1) < 0.1))
    ((2, 2), True)
    """
    dataset = xr.Dataset({"z": (("chain", "draw", "parameter"), np.swapaxes(draws, 0, 1))})
    return np.array([az.ess(dataset, method=method)["z"].values for method in ("bulk", "tail")])


def _shortfall(
    chain: np.ndarray, tau: np.ndarray, settings: SamplerSettings, names: tuple
) -> str | None:
    """What ``chain`` (steps, walkers, k) of ``tau`` lacks by the stopping rule, or None."""
    steps = len(chain)
    if not np.all(tau * settings.autocorr_multiple < steps):
        return (
            f"{steps} steps are fewer than {settings.autocorr_multiple:g} autocorrelation "
            f"times (max tau {np.max(tau):.0f} steps)"
        )
    if not settings.min_ess:
        return None
    discard, _ = _burn_in_and_thinning(steps, tau)
    sizes = effective_sizes(chain[discard:])
    if np.all(sizes >= settings.min_ess):
        return None
    kind, k = np.unravel_index(np.argmin(np.nan_to_num(sizes, nan=-1.0)), sizes.shape)
    return (
        f"the {('bulk', 'tail')[kind]} effective sample size of {names[k]} is "
        f"{sizes[kind, k]:.0f} after {steps} steps, fewer than {settings.min_ess}"
    )


def _expected_steps(tau: np.ndarray, steps: int, walkers: int, settings: SamplerSettings) -> int:
    """The steps the rule will need, as tau stands, at a check after this one.

    The multiple of tau, or the burn-in plus the steps whose walkers hold
    ``min_ess`` independent draws at this tau, whichever is longer; the cap
    while a tau is not known (NaN: a parameter that has not moved yet).
    """
    longest = float(np.max(tau))
    if not np.isfinite(longest):
        return settings.max_steps
    needed = max(
        longest * settings.autocorr_multiple,
        2 * longest + settings.min_ess * longest / walkers,
        steps + settings.check_every,
    )
    return int(np.ceil(needed / settings.check_every) * settings.check_every)


def _replay(sampler: emcee.EnsembleSampler, settings: SamplerSettings, names: tuple) -> bool:
    """Whether the rule held at the last check of a stored chain.

    It follows from the chain itself, so a resumed run continues the
    uninterrupted one's test bit for bit, wherever it was stopped.
    """
    last = sampler.iteration - sampler.iteration % settings.check_every
    if not last:
        return False
    chain = sampler.get_chain()[:last]
    return _shortfall(chain, autocorrelation_time(chain), settings, names) is None


def _run_until_converged(
    sampler: emcee.EnsembleSampler, start, settings: SamplerSettings, names: tuple
) -> tuple[str | None, np.ndarray]:
    """Advance the chain until the stopping rule holds or the cap is reached.

    Returns what the chain still lacks (None once the rule holds) and tau.
    emcee steps inside :func:`bayes_jackal._runtime.interrupt.interrupts_deferred` (its catch-all
    handlers must not see an interrupt); a signal stops the run between steps.
    """
    converged = _replay(sampler, settings, names)
    remaining = settings.max_steps - sampler.iteration
    if remaining > 0 and not converged:
        with (
            Progress(
                settings.max_steps,
                settings.progress_label,
                enabled=settings.progress,
                position=settings.progress_line,
                initial=sampler.iteration,
            ) as progress,
            interrupts_deferred(),
        ):
            for _ in sampler.sample(start, iterations=remaining):
                check_interrupt()
                progress.update()
                if sampler.iteration % settings.check_every:
                    continue
                chain = sampler.get_chain()
                tau = autocorrelation_time(chain)
                progress.update(0, tau=f"{np.max(tau):.0f}")
                progress.expect(
                    _expected_steps(tau, sampler.iteration, sampler.nwalkers, settings)
                )
                if _shortfall(chain, tau, settings, names) is None:
                    return None, tau
    chain = sampler.get_chain()
    tau = autocorrelation_time(chain)
    if converged:
        return None, tau
    return _shortfall(chain, tau, settings, names), tau


@dataclass(frozen=True)
class Chain:
    """A finished chain after burn-in and thinning (:func:`run_chain`).

    Attributes
    ----------
    samples : ndarray, shape (draws, walkers, k)
        The walkers' positions z = log(theta) (the sampler's coordinates;
        ``prior.to_natural`` gives theta).
    log_prob : ndarray, shape (draws, walkers)
        The log-posterior at each.
    diagnostics : dict
        ``converged``, ``n_steps``, ``walkers``, ``discard``, ``thin``,
        ``autocorr_time`` and ``ess_autocorr`` per parameter,
        ``acceptance_fraction``, ``seed`` and ``settings``.

    Examples
    --------
    >>> import numpy as np
    >>> from bayes_jackal.inference import Chain
    >>> chain = Chain(np.zeros((5, 8, 2)), np.zeros((5, 8)), {"converged": False})
    >>> chain.samples.reshape(-1, 2).shape
    (40, 2)
    """

    samples: np.ndarray
    log_prob: np.ndarray
    diagnostics: dict


@one_blas_thread()
def run_chain(
    log_posterior: Callable[[np.ndarray], np.ndarray],
    initial: Callable[[np.random.Generator, int], np.ndarray],
    *,
    settings: SamplerSettings,
    seed: int | list[int] | None,
    fingerprint: str = "",
    chain_file: str | Path | None = None,
) -> Chain:
    """Run emcee on a log-posterior until it converges (module docstring) or hits the cap.

    Parameters
    ----------
    log_posterior : callable
        Vectorised over rows of z, with ``prior.names`` (a
        :class:`~bayes_jackal.likelihood.LogPosterior` or one of the same shape).
    initial : callable
        ``initial(rng, walkers)``: the walkers' starting points (walkers, k),
        drawn with ``rng``, or a :class:`~bayes_jackal.inference.Start` that
        also gives the Laplace approximation the independence moves propose
        from (:func:`~bayes_jackal.inference.moves.ensemble_moves`; kept in the chain
        file); called only when the chain starts afresh.
    settings : SamplerSettings
    seed : int or list of int, optional
        Seeds ``initial`` and emcee's moves (numpy's seed: an entropy list
        too): same seed, same chain.
    fingerprint : str
        What defines the chain: a stored chain with another is not resumed
        (needed with a ``chain_file``).
    chain_file : str or Path, optional
        HDF5 file of the chain; a run with the same file and fingerprint resumes.

    Returns
    -------
    Chain
        After 2 tau of burn-in (at most half), thinned by tau / 2 (at most
        so far that :data:`~bayes_jackal._runtime.defaults.BRIDGE_MIN_DRAWS` draws of
        each walker remain); a chain that did not converge warns
        (:class:`ConvergenceWarning`).

    Examples
    --------
    A standard normal in two dimensions, started near the origin (the
    doctests skip the chain; tests/test_inference.py runs one):

    >>> import numpy as np
    >>> from bayes_jackal.inference import SamplerSettings, run_chain
    >>> from bayes_jackal.likelihood import Prior
    >>> prior = Prior(("a", "b"), np.full(2, 1e-3), np.full(2, 1e3), np.array([True, True]))
    >>> def log_posterior(z):
    ...     return -0.5 * np.sum(np.atleast_2d(z) ** 2, axis=-1)
    >>> log_posterior.prior = prior
    >>> def initial(rng, walkers):
    ...     return 0.1 * rng.standard_normal((walkers, 2))
    >>> settings = SamplerSettings(max_steps=3000, progress=False)
    >>> chain = run_chain(log_posterior, initial, settings=settings, seed=1)  # doctest: +SKIP
    >>> sd = chain.samples.reshape(-1, 2).std(axis=0)  # doctest: +SKIP
    >>> chain.diagnostics["converged"], bool(np.all(np.abs(sd - 1) < 0.1))  # doctest: +SKIP
    (True, True)
    """
    prior = log_posterior.prior
    names = prior.names
    ndim = len(names)
    walkers = settings.n_walkers(ndim)
    rng = np.random.default_rng(seed)
    # One run per chain: a second on the same file is refused, naming this one.
    lock = contextlib.nullcontext() if chain_file is None else OutputLock(chain_file)
    with lock:
        backend = _backend(
            None if chain_file is None else Path(chain_file),
            fingerprint,
            walkers,
            ndim,
            settings.check_every,
        )
        if backend.iteration == 0:
            with Phase(
                f"{settings.progress_label.strip()}: "
                "finding the chain's start (the posterior's peak)",
                enabled=settings.progress,
                position=settings.progress_line,
            ):
                begun = initial(rng, walkers)
            begun = begun if isinstance(begun, Start) else Start(np.asarray(begun))
            moves_state = np.random.RandomState(int(rng.integers(2**32))).get_state()
            start = emcee.State(begun.walkers, random_state=moves_state)
            approximation, groups, joint = begun.approximation, begun.groups, begun.joint
            _store_approximation(backend, approximation, groups, joint)
        else:
            start = backend.get_last_sample()
            approximation, groups, joint = _stored_approximation(backend)
            _log.info(f"resuming {chain_file} at step {backend.iteration}")
        sampler = emcee.EnsembleSampler(
            walkers,
            ndim,
            log_posterior,
            vectorize=True,
            backend=backend,
            moves=ensemble_moves(
                approximation, box=(prior.z_low, prior.z_high), groups=groups, joint=joint
            ),
        )
        try:
            shortfall, tau = _run_until_converged(sampler, start, settings, tuple(names))
        finally:
            if isinstance(backend, BufferedHDFBackend):
                with interrupts_deferred():  # a batch is written whole or not at all
                    backend.flush()
        if shortfall is not None:
            warnings.warn(
                ConvergenceWarning(
                    f"NOT CONVERGED: {shortfall}; raise max_steps or resume the run"
                ),
                stacklevel=3,
            )
        return _kept(sampler, names, tau, shortfall is None, settings, seed)


def _store_approximation(
    backend,
    approximation: Approximation | None,
    groups: tuple[BlockT | GroupGrid, ...] = (),
    joint: float = 0.0,
) -> None:
    """Keep the moves' approximation in a chain file, so that a resumed chain moves alike.

    A Laplace approximation as ``laplace_centre`` and ``laplace_covariance``
    attributes of the chain's group; a mixture as its datasets
    ``mixture_weights``, ``mixture_centres`` and ``mixture_covariances``
    (16 covariances of 23 parameters would pass HDF5's 64 KiB limit of an
    attribute), a bounded Laplace approximation as ``bounded_<field>``; the
    blocks' proposals as datasets ``block_<i>_<field>`` with their kind in
    the attribute ``block_<i>``, the share of walkers that draw them all at
    once as ``block_joint``.
    """
    if not isinstance(backend, BufferedHDFBackend) or (approximation is None and not groups):
        return
    with backend.writing(), backend.open("a") as stored:
        group = stored[backend.name]
        group.attrs["block_joint"] = joint
        for i, block in enumerate(groups):
            kind = "grid" if isinstance(block, GroupGrid) else "t"
            group.attrs[f"block_{i}"] = kind
            for key in BLOCK_FIELDS[kind][1]:
                group.create_dataset(f"block_{i}_{key}", data=getattr(block, key))
        if approximation is None:
            return
        if isinstance(approximation, MixtureApproximation | BoundedLaplace):
            prefix, keys = _KIND[type(approximation)]
            for key in keys:
                group.create_dataset(f"{prefix}_{key}", data=getattr(approximation, key))
        else:
            group.attrs["laplace_centre"] = approximation.centre
            group.attrs["laplace_covariance"] = approximation.covariance


def _stored_approximation(
    backend,
) -> tuple[Approximation | None, tuple[BlockT | GroupGrid, ...], float]:
    """The approximation, grids and joint share a stored chain's moves used (None, (), 0:
    DE alone; a file from before the joint share: 0)."""
    if not isinstance(backend, BufferedHDFBackend):
        return None, (), 0.0
    with backend.open("r") as stored:
        group = stored[backend.name]
        joint = float(group.attrs.get("block_joint", 0.0))
        grids = []
        while f"block_{len(grids)}" in group.attrs:
            i = len(grids)
            kind, fields = BLOCK_FIELDS[str(group.attrs[f"block_{i}"])]
            stored_fields = {  # a grid stored before its conditional columns had none
                key: group[f"block_{i}_{key}"][()] for key in fields if f"block_{i}_{key}" in group
            }
            grids.append(kind(**stored_fields))
        for kind, (prefix, keys) in _KIND.items():
            if f"{prefix}_{keys[0]}" in group:
                values = (group[f"{prefix}_{key}"][()] for key in keys)
                return kind(*values), tuple(grids), joint
        if "laplace_centre" not in group.attrs:
            return None, tuple(grids), joint
        return (
            LaplaceApproximation(
                np.array(group.attrs["laplace_centre"]),
                np.array(group.attrs["laplace_covariance"]),
            ),
            tuple(grids),
            joint,
        )


def _burn_in_and_thinning(steps: int, tau: np.ndarray) -> tuple[int, int]:
    """The steps discarded (2 tau, at most half) and the thinning (tau / 2) of a chain.

    The thinning is capped so that :data:`~bayes_jackal._runtime.defaults.BRIDGE_MIN_DRAWS`
    draws of each walker remain from a chain of at least
    :data:`~bayes_jackal._runtime.defaults.MIN_EVIDENCE_STEPS` steps, whatever tau was
    estimated (emcee's window bounds it by steps / 5, where tau / 2 would leave
    6 draws); the cap does not bind on a converged chain (steps > 50 tau). A
    chain too short to estimate tau (NaN) keeps its second half, unthinned.
    """
    estimated = bool(np.all(np.isfinite(tau)))
    half = steps // 2
    discard = min(int(np.ceil(2 * np.max(tau))), half) if estimated else half
    thin = max(1, int(np.min(tau) / 2)) if estimated else 1
    return discard, max(1, min(thin, (steps - discard) // BRIDGE_MIN_DRAWS))


def _kept(sampler, names, tau, converged, settings, seed) -> Chain:
    """Keep the chain after 2 tau of burn-in, thinned by tau / 2, with its diagnostics."""
    discard, thin = _burn_in_and_thinning(sampler.iteration, tau)
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
    return Chain(
        sampler.get_chain(discard=discard, thin=thin),
        sampler.get_log_prob(discard=discard, thin=thin),
        diagnostics,
    )
