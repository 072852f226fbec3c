"""What every chain of an analysis shares: one object instead of five arguments."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass, field

from .._runtime import InputError
from ..likelihood import LikelihoodOptions
from ..model import RobotProfile, as_profile, prior_overrides
from .chains import SamplerSettings

__all__ = ["FitOptions"]

#: The verbs' flat keywords (``bj.sample``, ``bj.compare``, ``bj.population``)
#: that are fields of the likelihood options, and of the sampler settings.
_LIKELIHOOD_KEYWORDS = ("channels", "noise", "sensor", "engine", "steady", "damping")
_SAMPLER_KEYWORDS = ("walkers", "max_steps", "progress")


@dataclass(frozen=True, kw_only=True)
class FitOptions:
    """What a posterior's numbers depend on besides its data and noise family.

    The robot, the likelihood options, the priors, the sampler settings
    and the seed: :func:`bayes_jackal.inference.compare_groups`, the
    population's units and the runs left out of a prior all take one, and
    the analysis' :class:`~bayes_jackal.workflow.RunContext` is one. Where
    the chains run (the executor) is not part of it: it changes no number.

    Parameters
    ----------
    robot : RobotProfile, str or Path, optional
        A profile, or a packaged profile's name or a TOML file
        (:func:`bayes_jackal.load_profile`); default: the Jackal's.
    likelihood_options : LikelihoodOptions, optional
        The channels, the noise sharing, sensor model, engine, window and
        damping model (default: the defaults').
    prior_overrides : mapping, optional
        Prior ranges (low, high) by base parameter name [natural units],
        over the profile's (:func:`bayes_jackal.model.prior_overrides`).
    settings : SamplerSettings, optional
        Every chain's walkers, step cap and progress display.
    seed : int, optional
        Seeds every chain and the draws made from them: same seed, same
        result, whichever executor ran them. None: fresh entropy.

    Raises
    ------
    InputError
        For a prior range of an unknown parameter or not 0 < low < high.
    ProfileError
        For a robot profile that cannot be read.

    Examples
    --------
    >>> import bayes_jackal as bj
    >>> from bayes_jackal.inference import FitOptions, SamplerSettings
    >>> options = FitOptions(robot="husky", settings=SamplerSettings(max_steps=500), seed=1)
    >>> options.robot.name, options.settings.max_steps, options.likelihood_options.noise
    ('husky', 500, 'shared')
    >>> try:
    ...     FitOptions(prior_overrides={"d_latt": (50, 500)})
    ... except bj.InputError as error:
    ...     print(error.field)
    prior_overrides
    """

    robot: RobotProfile = field(default_factory=lambda: as_profile(None))
    likelihood_options: LikelihoodOptions = field(default_factory=LikelihoodOptions)
    prior_overrides: Mapping[str, tuple[float, float]] | None = None
    settings: SamplerSettings = field(default_factory=SamplerSettings)
    seed: int | None = None

    def __post_init__(self) -> None:
        set_field = object.__setattr__  # normalised once, as the frozen fields they are
        set_field(self, "robot", as_profile(self.robot))
        set_field(self, "likelihood_options", LikelihoodOptions.of(self.likelihood_options))
        set_field(self, "settings", self.settings or SamplerSettings())
        # Validated here (names and 0 < low < high), not when the first chain starts.
        set_field(self, "prior_overrides", prior_overrides(self.prior_overrides) or None)

    @classmethod
    def of(cls, options: FitOptions | None) -> FitOptions:
        """``options``' own fields alone (a RunContext's), or the defaults for None.

        What a job sends to a worker: none of a larger context's other fields.
        """
        if options is None:
            return cls()
        if not isinstance(options, FitOptions):  # e.g. a robot where the options go
            raise InputError(
                f"must be a FitOptions (e.g. FitOptions(robot=...)), got a "
                f"{type(options).__name__}",
                field="options",
            )
        if type(options) is cls:
            return options
        return cls(**{f.name: getattr(options, f.name) for f in dataclasses.fields(cls)})

    @classmethod
    def of_keywords(cls, keywords: Mapping[str, object]) -> FitOptions:
        """The options the verbs' flat keywords give (``robot``, ``priors``, ``seed``, ...).

        ``keywords`` holds at least the likelihood's (``channels``, ``noise``,
        ``sensor``, ``engine``, ``steady``, ``damping``) and the sampler's
        (``walkers``, ``max_steps``, ``progress``) under the verbs' names;
        other keys are not read.

        Examples
        --------
        >>> from bayes_jackal.inference import FitOptions
        >>> keywords = dict(robot=None, priors=None, seed=1, channels=["yaw"], noise="shared",
        ...                 sensor="ma1", engine="fast", steady=False, damping="constant",
        ...                 walkers=0, max_steps=200, progress=False, family="white")
        >>> options = FitOptions.of_keywords(keywords)
        >>> options.likelihood_options.channels, options.settings.max_steps, options.seed
        (('yaw',), 200, 1)
        """
        return cls(
            robot=keywords["robot"],
            likelihood_options=LikelihoodOptions(**{k: keywords[k] for k in _LIKELIHOOD_KEYWORDS}),
            prior_overrides=keywords["priors"],
            settings=SamplerSettings(**{k: keywords[k] for k in _SAMPLER_KEYWORDS}),
            seed=keywords["seed"],
        )

    def with_settings(self, **changes) -> FitOptions:
        """The same options, the sampler settings changed (e.g. ``progress=False``)."""
        return dataclasses.replace(self, settings=dataclasses.replace(self.settings, **changes))
