"""The typed records of a posterior file's metadata: experiments, convergence, the whole.

:attr:`bayes_jackal.posterior.Posterior.metadata`, read from the file's
attributes, fills them.
"""

from __future__ import annotations

from dataclasses import dataclass

from .._runtime import CHANNELS
from ..likelihood import Prior
from ..model import ParameterLayout, RobotProfile

__all__ = ["Convergence", "Evidence", "ExperimentRecord", "PosteriorMetadata"]


@dataclass(frozen=True)
class ExperimentRecord:
    """What a posterior file says of one experiment (its arrays are in ``constant_data``).

    Attributes
    ----------
    name : str
    source : str or None
        The file it was read from.
    series : str or None
        Its series label (``v1``...).
    steady_window : (float, float) or None
        Start and stop of the steady window [s].
    dt : float
        Sample time [s].
    truth : dict or None
        The simulator's parameters, for simulated data.
    provenance : dict
        Time base and repairs (docs/design.md §2).
    channels : tuple of str
        The model channels (``vx``, ``vy``, ``yaw``) it measured: those
        whose arrays the file stores.
    pose_samples : int
        The recorded poses averaged into each sample of its pose channels in
        the likelihood's window (1 where it has none;
        :func:`bayes_jackal.io.tick_poses`).
    pose_clock : (int, float) or None
        Its pose channels' clock, every m samples at a phase [s] ((1, 0): a
        pose per sample); None where they are observed at their own stamps
        (the irregular engine, :mod:`bayes_jackal.likelihood.irregular`).
    segments : tuple of int, optional
        The first sample of each of its segments (command steps;
        :attr:`bayes_jackal.io.Experiment.segments`); None: one.

    Examples
    --------
    Each experiment of a posterior, as its file records it. The 20-step chain
    is short on purpose:

    >>> import bayes_jackal as bj
    >>> from bayes_jackal.posterior import Posterior
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1)
    >>> posterior = bj.sample([run], family="white", channels=["yaw"], max_steps=20, seed=1)
    >>> [record] = posterior.metadata.experiments
    >>> record.name, record.series, record.steady_window, round(1 / record.dt)
    ('v1', 'v1', (3.0, 36.0), 72)
    >>> record.channels, record.truth["d_lat"]
    (('vx', 'vy', 'yaw'), 110.0)
    """

    name: str
    source: str | None
    series: str | None
    steady_window: tuple[float, float] | None
    dt: float
    truth: dict | None
    provenance: dict
    channels: tuple[str, ...] = ()
    pose_samples: int = 1
    segments: tuple[int, ...] | None = None
    pose_clock: tuple[int, float] | None = (1, 0.0)


@dataclass(frozen=True)
class Convergence:
    """The sampler's convergence diagnostics and settings.

    Attributes
    ----------
    converged : bool
        Whether the autocorrelation criterion held.
    n_steps : int
        Steps run.
    autocorr_time : dict of str to float
        Integrated autocorrelation time per parameter [steps].
    ess_autocorr : dict of str to float
        The effective sample size it implies, per parameter.
    walkers, discard, thin : int or None
        Walkers; steps discarded as burn-in; thinning of the kept draws.
    acceptance_fraction : float or None
        Mean over walkers.
    seed : int or None
    settings : dict or None
        The :class:`~bayes_jackal.inference.SamplerSettings`, as a dict.

    Examples
    --------
    The diagnostics of a chain of 20 steps, far too short on purpose; real use
    takes the default step cap:

    >>> import bayes_jackal as bj
    >>> from bayes_jackal.posterior import Posterior
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1)
    >>> posterior = bj.sample([run], family="white", channels=["yaw"], max_steps=20, seed=1)
    >>> convergence = posterior.metadata.convergence
    >>> convergence.converged, convergence.n_steps, convergence.walkers, convergence.seed
    (False, 20, 32, 1)
    >>> sorted(convergence.autocorr_time)
    ['d_lat', 'd_long', 'sigma_c', 'sigma_n']
    """

    converged: bool
    n_steps: int
    autocorr_time: dict[str, float]
    ess_autocorr: dict[str, float]
    walkers: int | None = None
    discard: int | None = None
    thin: int | None = None
    acceptance_fraction: float | None = None
    seed: int | None = None
    settings: dict | None = None


@dataclass(frozen=True)
class PosteriorMetadata:
    """Everything a posterior file says besides its draws (:attr:`Posterior.metadata`).

    Attributes
    ----------
    format : str
        The file format, e.g. ``bayes_jackal.posterior/1``.
    version : str
        The bayes_jackal version that wrote it.
    layout : ParameterLayout
        Parameter names, noise groups and columns; the family, sensor term,
        channels and pooling.
    engine : str
        Likelihood engine.
    steady : bool
        Whether the likelihood used the steady windows.
    prior : Prior
        The priors sampled under.
    robot : RobotProfile
        The robot profile sampled with (for files that stored only the body
        constants, the installed default profile's other fields).
    experiments : tuple of ExperimentRecord
    convergence : Convergence
    evidence, evidence_nested : Evidence or None
        Bridge-sampling and nested-sampling evidence (:func:`store_comparison`).
    convergence_messages : tuple of str
        The sampler's convergence warnings, kept by :func:`store_comparison`.
    task : dict or None
        What defined a comparison's result (:func:`store_comparison`).
    criticism : dict or None
        :func:`bayes_jackal.posterior.criticise`'s result (:func:`store_criticism`).
    reweighting : dict or None
        For a posterior made by reweighting another's draws instead of
        sampling (:func:`store_reweighting`): ``method`` (``psis``), ``of``
        (the posterior reweighted), its ``experiments``, the ``left_out``
        run, ``pareto_k``, ``weights_ess``, ``draws``,
        ``relative_efficiency`` and ``task`` (what defined it, for reuse).
        None for a sampled posterior.

    Examples
    --------
    What a posterior says besides its draws. The 20-step chain is short on
    purpose:

    >>> import bayes_jackal as bj
    >>> from bayes_jackal.posterior import Posterior
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1)
    >>> posterior = bj.sample([run], family="white", channels=["yaw"], max_steps=20, seed=1)
    >>> metadata = posterior.metadata
    >>> metadata.family, metadata.channels, metadata.engine, metadata.robot.name
    ('white', ('yaw',), 'fast', 'jackal')
    >>> metadata.layout.names
    ('d_lat', 'd_long', 'sigma_c', 'sigma_n')

    The run measured every channel; only yaw was used:

    >>> metadata.measured_channels
    ('vx', 'vy', 'yaw')
    """

    format: str
    version: str
    layout: ParameterLayout
    engine: str
    steady: bool
    prior: Prior
    robot: RobotProfile
    experiments: tuple[ExperimentRecord, ...]
    convergence: Convergence
    evidence: Evidence | None = None
    evidence_nested: Evidence | None = None
    convergence_messages: tuple[str, ...] = ()
    task: dict | None = None
    criticism: dict | None = None
    reweighting: dict | None = None

    @property
    def family(self) -> str:
        """The noise family."""
        return self.layout.family

    @property
    def channels(self) -> tuple[str, ...]:
        """The channels, in likelihood order."""
        return self.layout.channels

    @property
    def truth(self) -> dict | None:
        """The shared truth of simulated experiments, when every one has it."""
        truths = [e.truth for e in self.experiments]
        return truths[0] if truths and all(truths) else None

    @property
    def measured_channels(self) -> tuple[str, ...]:
        """The model channels every experiment measured (``vx``, ``vy``, ``yaw`` order)."""
        return tuple(c for c in CHANNELS if all(c in e.channels for e in self.experiments))


@dataclass(frozen=True)
class Evidence:
    """A log-evidence estimate.

    Attributes
    ----------
    log_evidence : float
        log Z [nats].
    error : float
        Its standard error [nats].
    method : str
        The estimator.

    Examples
    --------
    >>> from bayes_jackal.posterior import Evidence
    >>> evidence = Evidence(-12.5, 0.03, "bridge sampling")
    >>> evidence.to_dict()
    {'log_evidence': -12.5, 'log_evidence_err': 0.03, 'method': 'bridge sampling'}
    >>> Evidence.from_dict(evidence.to_dict()) == evidence
    True
    """

    log_evidence: float
    error: float
    method: str

    def to_dict(self) -> dict:
        """JSON-ready fields (the keys of ``compare --json``)."""
        return {
            "log_evidence": self.log_evidence,
            "log_evidence_err": self.error,
            "method": self.method,
        }

    @classmethod
    def from_dict(cls, fields: dict) -> Evidence:
        """The inverse of :meth:`to_dict`."""
        return cls(fields["log_evidence"], fields["log_evidence_err"], fields["method"])
