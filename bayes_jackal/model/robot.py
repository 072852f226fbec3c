"""Robot profiles: the constants of a skid-steer robot, read from TOML.

A profile holds the body constants of the thesis' model (ch. 4), the
diff-drive settings that turn a velocity command into wheel speeds, the
sampling rate, prior ranges and the ROS topic names. The package ships
profiles of Clearpath's Jackal (the default, ``models/jackal.toml``), Husky
and Warthog (:func:`packaged_profiles`), each loaded by its name; any path
can be passed instead. A profile that gives no damping priors gets the
Jackal's scaled to its mass (:func:`mass_scaled_priors`), and the thesis'
Jackal damping scaled the same way is a robot's default true damping
(:func:`mass_scaled_damping`).
"""

from __future__ import annotations

import math
import sys
from collections.abc import Mapping
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

from .._runtime import CONVERSIONS, D_LAT, D_LONG, InputError, ProfileError, require_file

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - exercised on Python 3.10 only
    import tomli as tomllib

__all__ = [
    "DEFAULT_PRIORS",
    "PRIOR_REFERENCE_MASS",
    "RobotProfile",
    "as_profile",
    "default_profile_path",
    "load_profile",
    "mass_scaled_damping",
    "mass_scaled_priors",
    "packaged_profiles",
]


_BODY_KEYS = ("mass", "yaw_inertia", "half_wheelbase", "half_track", "wheel_radius")
_DIFF_DRIVE_KEYS = ("wheel_separation", "wheel_separation_multiplier")
#: The profile schema this version reads (``schema_version``, optional).
SCHEMA_VERSION = 1
_PRIOR_KEYS = ("d_lat", "d_long", "sigma_h", "sigma_c", "sigma_n", "sigma_p")
_WHEEL_SIDES = ("right", "left")
#: Prior ranges, all log-uniform (docs/design.md §4): the damping [N s/m],
#: the kernel width [s] and the noise standard deviations [channel units];
#: sigma_n is kept away from zero. sigma_p, the position noise per recorded
#: pose [m], spans 1 um to 10 cm: motion capture (OptiTrack, Vicon: 0.1-0.5
#: mm) and lidar odometry (ICP: 1-5 cm) alike; its floor keeps the pose
#: channels' covariance away from singular as sigma_n's does (docs/design.md
#: §2.2). The damping ranges are the Jackal's,
#: a robot of :data:`PRIOR_REFERENCE_MASS`; :func:`mass_scaled_priors` gives
#: another robot's.
DEFAULT_PRIORS = {
    "d_lat": (10.0, 1000.0),
    "d_long": (10.0, 1000.0),
    "sigma_h": (0.001, 1.0),
    "sigma_c": (1e-5, 1.0),
    "sigma_n": (1e-4, 1.0),
    "sigma_p": (1e-6, 0.1),
}
#: The body mass [kg] the damping ranges of :data:`DEFAULT_PRIORS` are set
#: for: the Jackal's (models/jackal.toml, as the thesis' eq. 6-7 uses it).
PRIOR_REFERENCE_MASS = 16.523
_DEFAULT_TOPICS = {
    "imu": "/imu/data",
    "joint_states": "/joint_states",
    "cmd_vel": "/cmd_vel",
    "pose": "/mocap_node/Jackal/pose",
}
#: The keys a profile may hold: top level, then per table. Anything else is
#: refused, so that a misspelt key (``d_latt``) is not silently ignored.
_TOP_KEYS = ("schema_version", "name", "description")
_TABLE_KEYS = {
    "body": _BODY_KEYS,
    "diff_drive": (*_DIFF_DRIVE_KEYS, "conversion"),
    "sampling": ("rate",),
    "priors": _PRIOR_KEYS,
    "topics": tuple(_DEFAULT_TOPICS),
    "wheels": _WHEEL_SIDES,
}
#: The packaged profile read when none is named.
_DEFAULT_PROFILE = "jackal"
#: Where each constant lives in a profile file, as errors name it.
_FIELDS = {key: f"body.{key}" for key in _BODY_KEYS}
_FIELDS |= {key: f"diff_drive.{key}" for key in _DIFF_DRIVE_KEYS} | {"rate": "sampling.rate"}

# The bounds of the impossibility check (_check_constants; docs/guide/robots.md).
#: Radius of gyration sqrt(I/m) over the footprint's half-diagonal sqrt(a^2 + b^2).
#: Above: mass placed at the corners of a rectangle of half-sides (A, B) gives
#: the largest sqrt(I/m) of any body in it, sqrt(A^2 + B^2), and a skid-steer's
#: body overhangs its wheels by less than they are apart (the Husky: 0.99 m
#: long on a 0.512 m wheelbase, A = 1.93 a), so A < 2a, B < 2b. Below: the
#: four wheels alone, at the corners (at least b/2 out, as a wheel is narrower
#: than the track), give more than 0.05 sqrt(a^2 + b^2) as soon as each weighs
#: 1/400 of the body (the Jackal's 1/35, the Husky's 1/17, the Warthog's 1/13;
#: I counts the wheels, eq. 3-1). The three packaged robots lie at 0.65-0.82.
_GYRATION_RATIO = (0.05, 2.0)
#: wheel_separation over the track 2b. s is the distance of the wheels' centre
#: planes, 2b adds a wheel's width (a wheel is narrower than the track, so
#: s <= 2b < 2s); a controller's effective track may exceed the geometric one
#: (the Warthog's ROS 2 control.yaml: 1.5 m on a 1.136 m track). The packaged
#: profiles lie at 0.78-0.90.
_SEPARATION_RATIO = (0.5, 2.0)
#: wheel_separation_multiplier k: a skid-steer's wheels scrub sideways in a
#: turn, which only slows it, so its effective track s k is no narrower than
#: the wheels are apart (k >= 1, ROS' default); k = 10 would turn it at a
#: tenth of the rate its wheels command. Clearpath's values: 1.0 (Warthog,
#: ROS 1), 1.5 (Jackal), 1.875 (Husky).
_MULTIPLIER = (1.0, 10.0)
#: The least wheel radius over the half track b: a wheel under 1/20 of it (5 mm
#: under the Jackal's 0.21 m) rolls over no floor's joints, and its wheel
#: speeds would be a thousand times a real robot's (a radius in m written in
#: mm, or 1e-300); the upper bound is b itself (:func:`_check_constants`). The
#: packaged profiles lie at 0.43-0.48.
_LEAST_WHEEL_RATIO = 0.05
#: Sample rates [Hz] of a profile's IMU: those of sensor logs,
#: :data:`bayes_jackal.io.PLAUSIBLE_RATES` (a layer above the model, so its
#: value is repeated here; a test keeps the two equal). Outside is a unit slip.
_RATES = (1.0, 10_000.0)


@dataclass(frozen=True)
class RobotProfile:
    """Constants of a skid-steer robot.

    Attributes
    ----------
    name : str
        Short name of the profile.
    mass : float
        Body mass m [kg].
    yaw_inertia : float
        Yaw moment of inertia I [kg m^2].
    half_wheelbase : float
        a [m], lever arm of the lateral wheel forces (thesis fig. 4-1).
    half_track : float
        b [m], lever arm of the longitudinal wheel forces.
    wheel_radius : float
        r_w [m].
    wheel_separation : float
        s [m], ROS diff_drive_controller's wheel separation.
    wheel_separation_multiplier : float
        k [-], ROS diff_drive_controller's separation multiplier.
    conversion : {"ros", "thesis"}
        Default command-to-wheel-speed conversion.
    rate : float
        Sampling rate of the measured state (IMU) [Hz].
    priors : dict of str to (float, float)
        Prior ranges, each log-uniform: ``d_lat``, ``d_long`` [N s/m],
        ``sigma_h`` [s] (the width of every noise family), ``sigma_c`` and
        ``sigma_n`` [channel units] and ``sigma_p`` [m] (the pose noise of
        vx, vy recorded as poses). Omitted (or empty): the defaults for the
        robot's mass, :func:`mass_scaled_priors`.
    topics : dict of str to str
        ROS topic names (``imu``, ``joint_states``, ``cmd_vel``, ``pose``).
    wheels : dict of str to list of str
        Joint names of the ``right`` and ``left`` wheels.
    source : str
        Where the profile was read from.

    Examples
    --------
    The packaged Jackal, and a copy with one constant changed, validated as a
    file would be (its priors are kept as they are):

    >>> from bayes_jackal.model import load_profile
    >>> robot = load_profile()
    >>> robot.name, robot.mass, robot.rate, round(robot.dt, 5)
    ('jackal', 16.523, 72.0, 0.01389)
    >>> robot.priors["d_lat"]
    (10.0, 1000.0)
    >>> robot.replace(mass=20.0).mass
    20.0
    >>> try:
    ...     robot.replace(mass=-1.0)
    ... except ValueError as error:
    ...     print(type(error).__name__)
    ProfileError

    A profile built in code without priors gets those of its mass: the
    Jackal's damping range, twice as wide for a robot twice as heavy.

    >>> from bayes_jackal.model import RobotProfile
    >>> twice = RobotProfile("twice", 2 * 16.523, 1.097, 0.131, 0.2078, 0.098, 0.37559, 1.5)
    >>> twice.priors["d_lat"], twice.priors["sigma_h"]
    ((20.0, 2000.0), (0.001, 1.0))
    """

    name: str
    mass: float
    yaw_inertia: float
    half_wheelbase: float
    half_track: float
    wheel_radius: float
    wheel_separation: float
    wheel_separation_multiplier: float
    conversion: str = "ros"
    rate: float = 72.0
    priors: dict[str, tuple[float, float]] = field(default_factory=dict)
    topics: dict[str, str] = field(default_factory=lambda: dict(_DEFAULT_TOPICS))
    wheels: dict[str, list[str]] = field(default_factory=dict)
    source: str = "<memory>"

    def __post_init__(self) -> None:
        if not self.priors:
            object.__setattr__(self, "priors", mass_scaled_priors(self.mass))

    @property
    def dt(self) -> float:
        """Sample time 1/rate [s]."""
        return 1.0 / self.rate

    def replace(self, **changes: object) -> RobotProfile:
        """Return a copy with some constants changed, validated like a file."""
        values = {**self.__dict__, **changes}
        profile = RobotProfile(**values)
        _validate(profile)
        return profile


def mass_scaled_priors(mass: float) -> dict[str, tuple[float, float]]:
    """The default prior ranges of a robot of this mass.

    :data:`DEFAULT_PRIORS` with the damping ranges (``d_lat``, ``d_long``)
    times mass / :data:`PRIOR_REFERENCE_MASS`: the same range of time
    constants m / d as the Jackal's [10, 1000] N s/m (the model's poles are
    -4 d / m, thesis eq. 4-29/30). The noise ranges are in the channels'
    units and do not scale. A profile without ``[priors] d_lat`` or
    ``d_long`` gets these.

    Parameters
    ----------
    mass : float
        Body mass m [kg], as the profile's ``[body] mass``.

    Returns
    -------
    dict of str to (float, float)
        Every prior range, keyed as :data:`DEFAULT_PRIORS`.

    Raises
    ------
    InputError
        When the mass is not a positive finite number.

    Examples
    --------
    The Jackal's own ranges, and a Husky's (46.034 kg: x 2.786):

    >>> from bayes_jackal.model import mass_scaled_priors
    >>> mass_scaled_priors(16.523)["d_lat"]
    (10.0, 1000.0)
    >>> [round(value, 2) for value in mass_scaled_priors(46.034)["d_long"]]
    [27.86, 2786.06]
    >>> mass_scaled_priors(46.034)["sigma_c"]
    (1e-05, 1.0)
    """
    scale = _mass_scale(mass)
    priors = dict(DEFAULT_PRIORS)
    for key in ("d_lat", "d_long"):  # the damping (model.DAMPING; that module imports this one)
        low, high = DEFAULT_PRIORS[key]
        priors[key] = (low * scale, high * scale)
    return priors


def mass_scaled_damping(mass: float) -> tuple[float, float]:
    """The thesis' Jackal damping in a body of this mass: (d_lat, d_long) [N s/m].

    The thesis' (110, 30) N s/m times mass / :data:`PRIOR_REFERENCE_MASS`:
    the Jackal's time constants m / d, as :func:`mass_scaled_priors` scales
    the prior, so the result lies inside the mass-scaled prior. It is the
    true damping ``bayes-jackal simulate`` simulates and the model
    ``bayes-jackal residuals`` analyses when no ``--d-lat``, ``--d-long``
    is given.

    Parameters
    ----------
    mass : float
        Body mass m [kg], as the profile's ``[body] mass``.

    Returns
    -------
    (float, float)
        d_lat, d_long [N s/m].

    Raises
    ------
    InputError
        When the mass is not a positive finite number.

    Examples
    --------
    The Jackal's own, and the Warthog's (200 kg: x 12.10), inside its
    prior of 121.04-12104.34 N s/m:

    >>> from bayes_jackal.model import mass_scaled_damping
    >>> mass_scaled_damping(16.523)
    (110.0, 30.0)
    >>> [round(value, 1) for value in mass_scaled_damping(200.0)]
    [1331.5, 363.1]
    """
    scale = _mass_scale(mass)
    return D_LAT * scale, D_LONG * scale


def _mass_scale(mass: float) -> float:
    """mass / :data:`PRIOR_REFERENCE_MASS`, for a positive finite mass [kg]."""
    try:
        value = float(mass)
    except (TypeError, ValueError):
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise InputError(f"must be a positive finite number [kg], got {mass!r}", field="mass")
    return value / PRIOR_REFERENCE_MASS


def packaged_profiles() -> dict[str, Path]:
    """The profiles shipped with the package, by name: their TOML files.

    A name (the file's stem: ``"jackal"``, ``"husky"``, ``"warthog"``) is
    what :func:`load_profile` and the command line's ``--robot`` take
    instead of a path.

    Returns
    -------
    dict of str to Path
        Name -> file, sorted by name.

    Examples
    --------
    >>> from bayes_jackal.model import default_profile_path, packaged_profiles
    >>> profiles = packaged_profiles()
    >>> profiles["jackal"] == default_profile_path()
    True
    >>> all(path.suffix == ".toml" for path in profiles.values())
    True
    """
    return {path.stem: path for path in sorted(_packaged_folder().glob("*.toml"))}


def default_profile_path() -> Path:
    """Path of the packaged Jackal profile (``models/jackal.toml``).

    Examples
    --------
    >>> from bayes_jackal.model import default_profile_path
    >>> default_profile_path().name
    'jackal.toml'
    """
    return _packaged_folder() / f"{_DEFAULT_PROFILE}.toml"


def _packaged_folder() -> Path:
    """The folder of the packaged profiles (``models/``, installed as ``bayes_jackal.models``)."""
    return Path(str(resources.files("bayes_jackal.models")))


def _profile_file(profile: str | Path | None) -> Path:
    """The file of a profile given by name, path or nothing (the Jackal's).

    A string without a path separator and without the ``.toml`` suffix is a
    packaged profile's name when one has it; anything else is a path.
    """
    if profile is None:
        return default_profile_path()
    if isinstance(profile, str) and not profile.strip():  # Path("") is the working folder
        raise ProfileError(
            f"an empty profile name; give one of {sorted(packaged_profiles())} or a TOML file",
            source=repr(profile),
            field="robot",
        )
    is_name = isinstance(profile, str) and Path(profile).name == profile
    if not is_name or profile.endswith(".toml"):
        return Path(profile)
    packaged = packaged_profiles()
    if profile in packaged:
        return packaged[profile]
    if not Path(profile).exists():
        raise ProfileError(
            f"no such file, nor a packaged profile of that name (those are {sorted(packaged)})",
            source=profile,
        )
    return Path(profile)


def load_profile(path: str | Path | None = None) -> RobotProfile:
    """Read and validate a robot profile.

    Parameters
    ----------
    path : str or Path, optional
        A packaged profile's name (``"jackal"``, ``"husky"``, ``"warthog"``:
        :func:`packaged_profiles`; a string without a path separator and
        without the ``.toml`` suffix), or a TOML file (``"./husky"`` for a
        file of a packaged profile's name); the packaged Jackal profile when
        omitted.

    Returns
    -------
    RobotProfile

    Raises
    ------
    ProfileError
        When the file cannot be read or parsed, a key is unknown, a value has
        the wrong type, a constant is missing, not a number, not finite or
        not positive, the constants cannot belong to one robot (the
        impossibility check of docs/guide/robots.md), or a prior range is
        empty.

    Examples
    --------
    A packaged profile by its name:

    >>> from bayes_jackal.model import load_profile
    >>> load_profile("jackal") == load_profile()
    True

    A profile of your own: here the packaged one with another mass.

    >>> import tempfile
    >>> from pathlib import Path
    >>> from bayes_jackal.model import default_profile_path
    >>> text = default_profile_path().read_text()
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     path = Path(folder) / "heavy.toml"
    ...     _ = path.write_text(text.replace("mass = 16.523", "mass = 20.0"))
    ...     robot = load_profile(path)
    >>> robot.mass, robot.rate, robot.conversion
    (20.0, 72.0, 'ros')

    A misspelt key is refused, naming it and the keys allowed:

    >>> with tempfile.TemporaryDirectory() as folder:
    ...     path = Path(folder) / "heavy.toml"
    ...     _ = path.write_text(text.replace("mass =", "mas ="))
    ...     try:
    ...         load_profile(path)
    ...     except ValueError as error:
    ...         print(error.field, "-", str(error).split("body.mas: ")[1])
    body.mas - unknown key 'mas'; the keys allowed here are
    ['mass', 'yaw_inertia', 'half_wheelbase', 'half_track', 'wheel_radius']

    So are constants no robot can have: wheels larger than half the wheelbase
    would overlap.

    >>> with tempfile.TemporaryDirectory() as folder:
    ...     path = Path(folder) / "big_wheels.toml"
    ...     _ = path.write_text(text.replace("wheel_radius = 0.098", "wheel_radius = 0.2"))
    ...     try:
    ...         load_profile(path)
    ...     except ValueError as error:
    ...         print(error.field, "-", str(error).split("wheel_radius: ")[1])
    body.wheel_radius - 0.2 m is not smaller than the half wheelbase a = 0.131 m:
    the front and rear wheels of a side would touch or overlap
    """
    path = _profile_file(path)
    source = str(path)
    require_file(path, source, error=ProfileError)
    try:
        with open(path, "rb") as stream:  # a byte-order mark (a Windows editor's) dropped
            doc = tomllib.loads(stream.read().decode("utf-8-sig"))
    except OSError as exc:
        raise ProfileError(f"cannot read profile ({exc.strerror})", source=source) from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise ProfileError(f"not a valid TOML text file ({exc})", source=source) from None

    _known_keys(doc, (*_TOP_KEYS, *_TABLE_KEYS), "", source)
    _text(doc, "", "description", source, "-")
    if doc.get("schema_version", SCHEMA_VERSION) != SCHEMA_VERSION:
        raise ProfileError(
            f"this version reads schema {SCHEMA_VERSION}, got {doc['schema_version']!r}",
            source=source,
            field="schema_version",
        )
    body = _table(doc, "body", source)
    diff_drive = _table(doc, "diff_drive", source)
    sampling = _table(doc, "sampling", source, required=False)
    name = _text(doc, "", "name", source, path.stem)
    values = {key: _number(body, "body", key, source) for key in _BODY_KEYS}
    values |= {key: _number(diff_drive, "diff_drive", key, source) for key in _DIFF_DRIVE_KEYS}
    values["rate"] = _number(sampling, "sampling", "rate", source) if "rate" in sampling else 72.0
    conversion = _text(diff_drive, "diff_drive", "conversion", source, "ros")
    priors = _priors(_table(doc, "priors", source, required=False), source)
    topics = _topics(_table(doc, "topics", source, required=False), source)
    wheels = _wheels(_table(doc, "wheels", source, required=False), source)
    _check_constants(values, source)
    profile = RobotProfile(
        name=name,
        conversion=conversion,
        priors=mass_scaled_priors(values["mass"]) | priors,
        topics=topics,
        wheels=wheels,
        source=source,
        **values,
    )
    _check_settings(profile)
    return profile


def _known_keys(table: dict, allowed: tuple[str, ...], where: str, source: str) -> None:
    """Refuse a key not in ``allowed``, naming it and listing the allowed ones."""
    unknown = [key for key in table if key not in allowed]
    if unknown:
        raise ProfileError(
            f"unknown key {unknown[0]!r}; the keys allowed here are {list(allowed)}",
            source=source,
            field=f"{where}.{unknown[0]}" if where else unknown[0],
        )


def _table(doc: dict, name: str, source: str, required: bool = True) -> dict:
    if name not in doc and not required:
        return {}
    if name not in doc:
        raise ProfileError(f"missing table [{name}]", source=source, field=name)
    if not isinstance(doc[name], dict):
        raise ProfileError(
            f"expected a table [{name}], got {doc[name]!r}", source=source, field=name
        )
    _known_keys(doc[name], _TABLE_KEYS[name], name, source)
    return doc[name]


def _text(table: dict, table_name: str, key: str, source: str, default: str) -> str:
    """A non-empty string value, or ``default`` when the key is absent."""
    value = table.get(key, default)
    if not (isinstance(value, str) and value):
        raise ProfileError(
            f"expected a non-empty string, got {value!r}",
            source=source,
            field=f"{table_name}.{key}" if table_name else key,
        )
    return value


def _topics(table: dict, source: str) -> dict[str, str]:
    return {
        role: _text(table, "topics", role, source, default)
        for role, default in _DEFAULT_TOPICS.items()
    }


def _wheels(table: dict, source: str) -> dict[str, list[str]]:
    for side, names in table.items():
        if not (isinstance(names, list) and all(isinstance(n, str) for n in names)):
            raise ProfileError(
                f"expected a list of joint names, got {names!r}",
                source=source,
                field=f"wheels.{side}",
            )
    return {side: list(names) for side, names in table.items()}


def _number(table: dict, table_name: str, key: str, source: str) -> float:
    where = f"{table_name}.{key}"
    if key not in table:
        raise ProfileError("missing constant", source=source, field=where)
    value = table[key]
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ProfileError(f"expected a number, got {value!r}", source=source, field=where)
    return float(value)


def _priors(table: dict, source: str) -> dict[str, tuple[float, float]]:
    """The prior ranges a profile's ``[priors]`` table gives (the others are defaults)."""
    priors = {}
    for key, value in table.items():
        if not (isinstance(value, list) and len(value) == 2):
            raise ProfileError(
                f"expected [low, high], got {value!r}", source=source, field=f"priors.{key}"
            )
        priors[key] = tuple(_number({key: v}, "priors", key, source) for v in value)
    return priors


def _validate(profile: RobotProfile) -> None:
    """Refuse a profile's impossible constants, unknown conversion or empty priors."""
    _check_constants({key: getattr(profile, key) for key in _FIELDS}, profile.source)
    _check_settings(profile)


def _check_constants(values: Mapping[str, float], source: str) -> None:
    """Refuse constants that are not positive and finite, or that no robot can have.

    Each bound is argued where it is defined (:data:`_GYRATION_RATIO`,
    :data:`_SEPARATION_RATIO`, :data:`_MULTIPLIER`, :data:`_RATES`) and in
    docs/guide/robots.md; the packaged profiles lie well inside them. The
    wheel radius must be smaller than both lever arms: the front and rear
    wheels of a side are 2a apart, and a robot whose wheels are as tall as
    its track is wide (r_w >= b, the centre of mass at least r_w high) tips
    over in a skid turn on a grippy floor before its wheels slide sideways.

    Raises
    ------
    ProfileError
        Naming ``source``, the field (``body.wheel_radius``) and its value.
    """
    for key, name in _FIELDS.items():
        value = values[key]
        if not (math.isfinite(value) and value > 0):
            raise ProfileError(
                f"must be a positive finite number, got {value!r}", source=source, field=name
            )
    a, b, r_w = values["half_wheelbase"], values["half_track"], values["wheel_radius"]
    for lever, named, why in (
        (a, "half wheelbase a", "the front and rear wheels of a side would touch or overlap"),
        (b, "half track b", "a robot with wheels that tall rolls over in a skid turn"),
    ):
        if r_w >= lever:
            raise ProfileError(
                f"{r_w:g} m is not smaller than the {named} = {lever:g} m: {why}",
                source=source,
                field=_FIELDS["wheel_radius"],
            )
    if r_w < _LEAST_WHEEL_RATIO * b:
        raise ProfileError(
            f"{r_w:g} m is less than {_LEAST_WHEEL_RATIO:g} x the half track b = {b:g} m: no "
            "ground robot's wheel (is r_w in m?)",
            source=source,
            field=_FIELDS["wheel_radius"],
        )
    inertia, mass = values["yaw_inertia"], values["mass"]
    gyration, half_diagonal = math.sqrt(inertia / mass), math.hypot(a, b)
    _check_bounds(
        gyration / half_diagonal,
        _GYRATION_RATIO,
        f"{inertia:g} kg m^2 at {mass:g} kg: a radius of gyration sqrt(I/m) = {gyration:.3g} m, "
        f"{gyration / half_diagonal:.3g} x the footprint's half-diagonal sqrt(a^2 + b^2) = "
        f"{half_diagonal:.3g} m",
        "is I in kg m^2 and m in kg?",
        source,
        "yaw_inertia",
    )
    separation = values["wheel_separation"]
    _check_bounds(
        separation / (2 * b),
        _SEPARATION_RATIO,
        f"{separation:g} m: {separation / (2 * b):.3g} x the track 2b = {2 * b:.4g} m",
        "the distance of the left and right wheels (a diameter for a radius?)",
        source,
        "wheel_separation",
    )
    multiplier = values["wheel_separation_multiplier"]
    _check_bounds(
        multiplier,
        _MULTIPLIER,
        f"{multiplier:g}",
        "a skid-steer turns no faster than its wheels command (k >= 1), nor ten times slower",
        source,
        "wheel_separation_multiplier",
    )
    rate = values["rate"]
    _check_bounds(rate, _RATES, f"{rate:g} Hz", "the rates of sensor logs, in Hz", source, "rate")


def _check_bounds(
    value: float, bounds: tuple[float, float], said: str, why: str, source: str, key: str
) -> None:
    """Refuse ``value`` outside ``bounds`` (inclusive): ``<said>, outside [low, high]: <why>``."""
    low, high = bounds
    if not low <= value <= high:
        raise ProfileError(
            f"{said}, outside [{low:g}, {high:g}]: {why}", source=source, field=_FIELDS[key]
        )


def _check_settings(profile: RobotProfile) -> None:
    """Refuse an unknown conversion and a missing or empty prior range."""
    source = profile.source
    if profile.conversion not in CONVERSIONS:
        raise ProfileError(
            f"must be one of {CONVERSIONS}, got {profile.conversion!r}",
            source=source,
            field="diff_drive.conversion",
        )
    for key, (low, high) in profile.priors.items():
        if not (math.isfinite(low) and math.isfinite(high) and 0 < low < high):
            raise ProfileError(
                f"prior range must satisfy 0 < low < high, got [{low}, {high}]",
                source=source,
                field=f"priors.{key}",
            )
    missing = [key for key in _PRIOR_KEYS if key not in profile.priors]
    if missing:
        raise ProfileError(f"missing prior ranges {missing}", source=source, field="priors")


def as_profile(robot: RobotProfile | str | Path | None) -> RobotProfile:
    """A robot profile as given, or read from its TOML file or name (None: the Jackal's).

    Examples
    --------
    >>> from bayes_jackal.model import as_profile, default_profile_path, load_profile
    >>> jackal = load_profile()
    >>> as_profile(jackal) is jackal, as_profile(None).name, as_profile("jackal").name
    (True, 'jackal', 'jackal')
    >>> as_profile(default_profile_path()) == jackal
    True
    """
    return robot if isinstance(robot, RobotProfile) else load_profile(robot)
