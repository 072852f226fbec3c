"""The exported Active Inference prior as a typed value: :class:`ActiveInferencePrior`.

:func:`bayes_jackal.dem.export_prior` returns one, :func:`bayes_jackal.dem.write_prior`
writes its JSON (``prior.json``, format ``bayes_jackal.prior/1``, unchanged) and
:func:`bayes_jackal.dem.read_prior` reads it back. Its fields are the file's
top-level keys (docs/guide/prior.md, "The file"); the filters
(:mod:`bayes_jackal.filters`) take it, or a plain mapping of the same JSON
through :meth:`ActiveInferencePrior.from_json`.
"""

from __future__ import annotations

import copy
import dataclasses
from collections.abc import Iterator, Mapping
from functools import cached_property
from typing import Any

from .._runtime import InputError
from .prior_fields import PRIOR_FORMAT, check_prior_fields

__all__ = ["ActiveInferencePrior"]

#: The top-level keys every prior holds (:func:`~bayes_jackal.dem.check_prior_fields`
#: refuses a prior without one); the other fields only some filter reads, or none.
_REQUIRED = ("format", "robot", "dt", "model", "damping", "noise")


@dataclasses.dataclass(frozen=True, eq=False, kw_only=True)
class ActiveInferencePrior(Mapping[str, Any]):
    """The Active Inference (DEM) prior of a posterior: the content of ``prior.json``.

    One field per top-level key of the file (format ``bayes_jackal.prior/1``,
    docs/guide/prior.md, "The file"), in the file's order. The sections
    hold what the file holds, as JSON values: dicts, lists of numbers
    (a matrix is a list of rows; ``numpy.asarray`` makes it an array),
    text, numbers, None for null. So :meth:`to_json` gives the file's
    content exactly, and a file read and written again is unchanged.

    Every prior is checked when it is made: the fields the filters read,
    with their types (:func:`~bayes_jackal.dem.check_prior_fields`), and
    an :class:`~bayes_jackal._runtime.errors.InputError` names the field
    and the value. The prior is frozen; its sections are the prior's own
    and are not to be edited in place (:meth:`to_json` gives a copy to
    edit, :meth:`from_json` makes a prior of it, ``dataclasses.replace``
    one with a field replaced).

    It is also a read-only mapping of its JSON: ``prior["noise"]["family"]``
    is ``prior.noise["family"]``, ``dict(prior)`` holds the keys and
    values of :meth:`to_json` (not copied), and ``prior | {"dt": 0.01}`` is
    a dict of the JSON with that key replaced. Until this class, the export
    was that dict, and code written for it, the package's tests among them,
    indexes a prior so; the readers of single fields,
    :func:`~bayes_jackal.dem.prior_field` and the filters' helpers
    (:func:`~bayes_jackal.filters.filter_models`,
    :func:`~bayes_jackal.filters.noise_parameters`...), read a prior and a
    mapping built by hand alike. Two priors, or a prior and a mapping, are
    equal when their JSON is.

    Parameters
    ----------
    format : str
        :data:`~bayes_jackal.dem.PRIOR_FORMAT`, ``"bayes_jackal.prior/1"``.
    bayes_jackal_version : str or None
        The version of the package that exported the prior.
    source : str or None
        Where the posterior was read from; None when it was in memory.
    converged : bool or None
        Whether the posterior's chain converged.
    experiments : list of str or None
        The names of the experiments the posterior was sampled on.
    robot : dict
        The robot's constants: ``name`` and ``conversion`` text, ``mass``
        [kg], ``inertia`` [kg m^2], lengths [m], ``rate`` [Hz]
        (:data:`~bayes_jackal.posterior.ROBOT_CONSTANTS`), ``source``.
    dt : float
        The sample time [s].
    states, inputs : list of str or None
        ``["vx", "vy", "yaw"]`` [m/s, m/s, rad/s] and ``["omega_r", "omega_l"]``
        [rad/s].
    model : dict
        At the posterior mean of the damping: ``A`` [1/s] and ``B`` [state
        units / s per rad/s] of dx/dt = A x + B u, ``C`` = I, ``Ad`` and ``Bd``
        per step (x[k+1] = Ad x[k] + Bd u[k]), ``A_bins``, ``B_bins`` = A dt, B dt.
    damping : dict
        ``mean`` [N s/m] and ``covariance`` [(N s/m)^2] of (d_lat, d_long),
        their and their ratio's moments and HDIs, ``matrix_prior``.
    noise : dict
        ``family``, ``channels``, ``sensor``, ``shared_width``,
        ``pose_channels``, ``pose_samples``, ``sigma_c_is`` and
        ``parameters``: each noise parameter's posterior mean, sd and HDI
        [s for a width, channel units for an sd], ``process_sd_continuous``
        [channel units / s].
    generalised_coordinates : dict or None
        The embedding ``order`` P and, averaged over the draws, V
        [s^-(i+j)], inv(V), the precision Pi ((P + 1) x channels square,
        derivative-major) in seconds and in time bins.
    draws : dict or None
        ``count`` and one list of posterior draws per parameter (at most
        1000, evenly thinned).
    sensor_noise : dict or None
        The sensor noise's precision Pi_z in generalised coordinates and its
        smoothness [bins, s]; None (null) when the noise fit has one total sd.
    smoothness : dict or None
        Per channel the Gaussian smoothness [s, bins], and one shared by
        the channels; its values are None for a family whose noise has no
        derivative.
    log_precision : dict or None
        Moments of log(1 / sd^2) per channel, for hyperpriors.
    operating_point : dict or None
        Per experiment and pooled: the mean inputs [rad/s] and outputs.
    extra : dict
        Top-level keys this version does not know (a file edited by hand
        may add some): written after the others, read by no filter.
    absent : frozenset of str
        The fields a prior built by hand leaves out (None and not in its
        JSON): those only some filter reads, which then refuses the prior,
        naming the field. Empty for an exported prior; :meth:`from_json`
        names the fields its mapping lacks. (A field not named here is in
        the JSON, None as null: a null ``sensor_noise`` says that the noise
        fit has one total sd, an absent one nothing.)

    Raises
    ------
    InputError
        For a field the filters read that is missing or of the wrong type
        (:func:`~bayes_jackal.dem.check_prior_fields`), an ``absent`` field
        that is required or not None, or an ``extra`` key that is a field.

    Examples
    --------
    A prior built by hand (``bj.export_prior`` makes one from a posterior):
    white noise on the yaw rate, with none of the fields only some filter
    reads:

    >>> from bayes_jackal.dem import ActiveInferencePrior
    >>> prior = ActiveInferencePrior.from_json({
    ...     "format": "bayes_jackal.prior/1", "robot": {"name": "jackal"}, "dt": 0.0125,
    ...     "model": {}, "damping": {"mean": [110.0, 30.0]},
    ...     "noise": {"family": "white", "channels": ["yaw"],
    ...               "parameters": {"sigma_c": {"mean": 0.01}, "sigma_n": {"mean": 0.005}}}})
    >>> prior
    ActiveInferencePrior(family='white', channels=('yaw',), order=None, dt=0.0125, source=None)
    >>> prior.dt, prior["noise"]["channels"], prior.draws, "draws" in prior
    (0.0125, ['yaw'], None, False)
    >>> list(prior.to_json()) == list(prior), prior.to_json() == prior
    (True, True)

    A field of the wrong type is refused, naming it (and the file when given):

    >>> try:
    ...     ActiveInferencePrior.from_json({**prior, "dt": "fast"}, source="prior.json")
    ... except ValueError as error:
    ...     print(error)
    prior.json: dt: expected a positive number of seconds, got 'fast'
    """

    format: str = PRIOR_FORMAT
    bayes_jackal_version: str | None = None
    source: str | None = None
    converged: bool | None = None
    experiments: list[str] | None = None
    robot: dict[str, Any]
    dt: float
    states: list[str] | None = None
    inputs: list[str] | None = None
    model: dict[str, Any]
    damping: dict[str, Any]
    noise: dict[str, Any]
    generalised_coordinates: dict[str, Any] | None = None
    draws: dict[str, Any] | None = None
    sensor_noise: dict[str, Any] | None = None
    smoothness: dict[str, Any] | None = None
    log_precision: dict[str, Any] | None = None
    operating_point: dict[str, Any] | None = None
    extra: dict[str, Any] = dataclasses.field(default_factory=dict)
    absent: frozenset[str] = frozenset()

    def __post_init__(self) -> None:
        absent = frozenset(self.absent)
        object.__setattr__(self, "absent", absent)
        unknown = sorted(absent - set(_KEYS))
        if unknown:
            raise InputError(f"{unknown[0]!r} is no field of a prior", field="absent")
        for key in sorted(absent):
            if key in _REQUIRED or getattr(self, key) is not None:
                why = "every prior holds it" if key in _REQUIRED else "it holds a value"
                raise InputError(f"{key!r} cannot be absent: {why}", field="absent")
        if not isinstance(self.extra, Mapping):
            raise InputError(f"expected an object of named fields, got {self.extra!r:.80}",
                             field="extra")  # fmt: skip
        for key in self.extra:
            if not isinstance(key, str) or key in _KEYS:
                why = "a field of the prior" if key in _KEYS else "no text"
                raise InputError(f"the key {key!r} is {why}", field="extra")
        check_prior_fields(self)

    @classmethod
    def from_json(
        cls, mapping: Mapping[str, Any], *, source: str | None = None
    ) -> ActiveInferencePrior:
        """The prior of a JSON object (``json.load`` of a ``prior.json``), checked.

        Parameters
        ----------
        mapping : mapping
            The file's JSON: every field the filters read, with its type
            (:func:`~bayes_jackal.dem.check_prior_fields`). Its values are
            copied; keys this version does not know go to ``extra``, and the
            optional ones it lacks to ``absent``. A prior is returned as it is.
        source : str, optional
            Where it was read from: an error is then a DataError naming it.

        Returns
        -------
        ActiveInferencePrior

        Raises
        ------
        InputError
            For a mapping of another format, or a field the filters read
            that is missing or of the wrong type, naming the field and the
            value (a DataError naming ``source`` too when given).

        Examples
        --------
        >>> from bayes_jackal.dem import ActiveInferencePrior
        >>> try:
        ...     ActiveInferencePrior.from_json({"format": "bayes_jackal.noise_prior/1"})
        ... except ValueError as error:
        ...     print(error)
        format: not a prior this version reads: 'bayes_jackal.noise_prior/1' (expected
        bayes_jackal.prior/1)
        """
        if isinstance(mapping, cls):
            return mapping
        check_prior_fields(mapping, source=source)
        values = copy.deepcopy(dict(mapping))
        return cls(
            **{key: values[key] for key in _KEYS if key in values},
            extra={key: value for key, value in values.items() if key not in _KEYS},
            absent=frozenset(key for key in _KEYS if key not in values),
        )

    def to_json(self) -> dict[str, Any]:
        """The prior as the JSON object ``prior.json`` holds: a new dict, the caller's to edit.

        The keys in the order :func:`~bayes_jackal.dem.export_prior` writes
        them (those ``absent`` left out), then the ``extra`` ones.
        :func:`~bayes_jackal.dem.write_prior` writes it (a number that is
        not finite, which an export does not hold, as null).

        Examples
        --------
        A prior built by hand without the optional fields, and an edited copy:

        >>> from bayes_jackal.dem import ActiveInferencePrior
        >>> prior = ActiveInferencePrior.from_json({
        ...     "format": "bayes_jackal.prior/1", "robot": {"name": "jackal"}, "dt": 0.0125,
        ...     "model": {}, "damping": {"mean": [110.0, 30.0]},
        ...     "noise": {"family": "white", "channels": ["vx"],
        ...               "parameters": {"sigma_c": {"mean": 0.01}, "sigma_n": {"mean": 0.005}}}})
        >>> edited = prior.to_json()
        >>> list(edited)
        ['format', 'robot', 'dt', 'model', 'damping', 'noise']
        >>> edited["noise"]["channels"] = ["vy"]
        >>> ActiveInferencePrior.from_json(edited).channels, prior.channels
        (('vy',), ('vx',))
        """
        return copy.deepcopy(self._json)

    @cached_property
    def _json(self) -> dict[str, Any]:
        """The JSON object of the prior, its values the prior's own (the mapping's view)."""
        fields = {key: getattr(self, key) for key in _KEYS if key not in self.absent}
        return fields | dict(self.extra)

    def __getitem__(self, key: str) -> Any:
        return self._json[key]

    def __iter__(self) -> Iterator[str]:
        return iter(self._json)

    def __len__(self) -> int:
        return len(self._json)

    def __or__(self, other: object) -> dict[str, Any]:
        """``prior | {"dt": 0.01}``: a dict of the JSON with those keys replaced."""
        if not isinstance(other, Mapping):
            return NotImplemented
        return self.to_json() | dict(other)

    def __ror__(self, other: object) -> dict[str, Any]:
        if not isinstance(other, Mapping):
            return NotImplemented
        return dict(other) | self.to_json()

    def __repr__(self) -> str:
        return (
            f"{type(self).__name__}(family={self.family!r}, channels={self.channels!r}, "
            f"order={self.order!r}, dt={self.dt!r}, source={self.source!r})"
        )

    @property
    def family(self) -> str:
        """The noise family (``noise.family``), one of :data:`~bayes_jackal.model.FAMILIES`."""
        return self.noise["family"]

    @property
    def channels(self) -> tuple[str, ...]:
        """The channels of the prior's noise (``noise.channels``), in its order."""
        return tuple(self.noise["channels"])

    @property
    def order(self) -> int | None:
        """The embedding order P (``generalised_coordinates.order``); None when absent."""
        coordinates = self.generalised_coordinates
        return None if coordinates is None else coordinates.get("order")


#: The fields that are keys of the file, in its order (``extra`` and ``absent`` are not).
_KEYS = tuple(
    f.name for f in dataclasses.fields(ActiveInferencePrior) if f.name not in ("extra", "absent")
)
