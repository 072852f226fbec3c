"""Robot profiles: the constants of a skid-steer robot, read from TOML.

A profile holds the body constants of the thesis' model (ch. 4), the
diff-drive settings that turn a velocity command into wheel speeds, the
sampling rate, prior ranges and the ROS topic names. ``models/jackal.toml``
is the default; any path can be passed instead.
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

from .._runtime.defaults import CONVERSIONS
from .._runtime.errors import ProfileError
from .._runtime.files import require_file

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - exercised on Python 3.10 only
    import tomli as tomllib

__all__ = ["DEFAULT_PRIORS", "RobotProfile", "as_profile", "default_profile_path", "load_profile"]


_BODY_KEYS = ("mass", "yaw_inertia", "half_wheelbase", "half_track", "wheel_radius")
_DIFF_DRIVE_KEYS = ("wheel_separation", "wheel_separation_multiplier")
#: The profile schema this version reads (``schema_version``, optional).
SCHEMA_VERSION = 1
_PRIOR_KEYS = ("d_lat", "d_long", "sigma_h", "sigma_c", "sigma_n", "sigma_p")
_WHEEL_SIDES = ("right", "left")
#: Prior ranges, all log-uniform (docs/design.md §4): the damping [N s/m],
#: the kernel width [s] and the noise standard deviations [channel units];
#: sigma_n is kept away from zero. sigma_p, the motion-capture
#: position noise per recorded pose [m], spans 1 um to 1 cm: its log-centre,
#: 0.1 mm, is the specification of lab systems (OptiTrack, Vicon: 0.1-0.5 mm),
#: and its floor keeps the pose channels' covariance away from singular as
#: sigma_n's does (docs/design.md §2.2).
DEFAULT_PRIORS = {
    "d_lat": (10.0, 1000.0),
    "d_long": (10.0, 1000.0),
    "sigma_h": (0.001, 1.0),
    "sigma_c": (1e-5, 1.0),
    "sigma_n": (1e-4, 1.0),
    "sigma_p": (1e-6, 1e-2),
}
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
        vx, vy recorded as poses).
    topics : dict of str to str
        ROS topic names (``imu``, ``joint_states``, ``cmd_vel``, ``pose``).
    wheels : dict of str to list of str
        Joint names of the ``right`` and ``left`` wheels.
    source : str
        Where the profile was read from.

    Examples
    --------
    The packaged Jackal, and a copy with one constant changed, validated as a
    file would be:

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
    priors: dict[str, tuple[float, float]] = field(default_factory=lambda: dict(DEFAULT_PRIORS))
    topics: dict[str, str] = field(default_factory=lambda: dict(_DEFAULT_TOPICS))
    wheels: dict[str, list[str]] = field(default_factory=dict)
    source: str = "<memory>"

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


def default_profile_path() -> Path:
    """Path of the packaged Jackal profile (``models/jackal.toml``).

    Examples
    --------
    >>> from bayes_jackal.model import default_profile_path
    >>> default_profile_path().name
    'jackal.toml'
    """
    return Path(str(resources.files("bayes_jackal.models") / "jackal.toml"))


def load_profile(path: str | Path | None = None) -> RobotProfile:
    """Read and validate a robot profile.

    Parameters
    ----------
    path : str or Path, optional
        TOML file; the packaged Jackal profile when omitted.

    Returns
    -------
    RobotProfile

    Raises
    ------
    ProfileError
        When the file cannot be read or parsed, a key is unknown, a value has
        the wrong type, a constant is missing, not a number, not finite or
        not positive, or a prior range is empty.

    Examples
    --------
    A profile of your own: here the packaged one with another mass.

    >>> import tempfile
    >>> from pathlib import Path
    >>> from bayes_jackal.model import default_profile_path, load_profile
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
    """
    path = Path(path) if path is not None else default_profile_path()
    source = str(path)
    require_file(path, source, error=ProfileError)
    try:
        with open(path, "rb") as stream:
            doc = tomllib.load(stream)
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
    values = {key: _number(body, "body", key, source) for key in _BODY_KEYS}
    values |= {key: _number(diff_drive, "diff_drive", key, source) for key in _DIFF_DRIVE_KEYS}
    profile = RobotProfile(
        name=_text(doc, "", "name", source, path.stem),
        conversion=_text(diff_drive, "diff_drive", "conversion", source, "ros"),
        rate=_number(sampling, "sampling", "rate", source) if "rate" in sampling else 72.0,
        priors=_priors(_table(doc, "priors", source, required=False), source),
        topics=_topics(_table(doc, "topics", source, required=False), source),
        wheels=_wheels(_table(doc, "wheels", source, required=False), source),
        source=source,
        **values,
    )
    _validate(profile)
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
    priors = dict(DEFAULT_PRIORS)
    for key, value in table.items():
        if not (isinstance(value, list) and len(value) == 2):
            raise ProfileError(
                f"expected [low, high], got {value!r}", source=source, field=f"priors.{key}"
            )
        priors[key] = tuple(_number({key: v}, "priors", key, source) for v in value)
    return priors


def _validate(profile: RobotProfile) -> None:
    source = profile.source
    qualified = {key: f"body.{key}" for key in _BODY_KEYS}
    qualified |= {key: f"diff_drive.{key}" for key in _DIFF_DRIVE_KEYS} | {"rate": "sampling.rate"}
    for key, name in qualified.items():
        value = getattr(profile, key)
        if not (math.isfinite(value) and value > 0):
            raise ProfileError(
                f"must be a positive finite number, got {value!r}", source=source, field=name
            )
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
    """A robot profile as given, or read from its TOML file (None: the Jackal's).

    Examples
    --------
    >>> from bayes_jackal.model import as_profile, default_profile_path, load_profile
    >>> jackal = load_profile()
    >>> as_profile(jackal) is jackal, as_profile(None).name
    (True, 'jackal')
    >>> as_profile(default_profile_path()) == jackal
    True
    """
    return robot if isinstance(robot, RobotProfile) else load_profile(robot)
