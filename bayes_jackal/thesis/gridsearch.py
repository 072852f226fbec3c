"""The thesis' grid searches over (d_lat, d_long), vectorised.

Two criteria, both evaluated on every experiment and combined as the thesis
does: the MSE per experiment (eq. 5-1, 9-2), its mean per series of equal
commands (eq. 5-2) and the sum of the series means (eq. 5-3).

- ``"simulation"`` (ch. 5): simulate the channel from the measured initial
  state with the measured input and compare with the measurement.
- ``"onestep"`` (ch. 9-1-2): predict each next sample from the measured one
  (eq. 9-1). The residual x[k+1] - alpha x[k] - beta_r u_r[k] - beta_l u_l[k]
  is linear in the coefficient vector c = (1, -alpha, -beta_r, -beta_l), so
  its mean square is c^T G c with the 4 x 4 Gram matrix G of the data: O(N)
  once per experiment, then O(1) per grid point (docs/design.md §4).

The thesis' grids are linear (:func:`damping_grid`: 1..1000 step 1 and
10..1000 step 10 N s/m, the Jackal's). The default grids follow the robot:
log-spaced over the profile's prior range of each damping
(:func:`prior_grid`). A minimum on a grid's edge says the criterion may be
lower outside the grid: :meth:`GridResult.edges` names the edge and
:meth:`GridResult.edge_warnings` warns of it (kind ``grid-edge``).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import xarray as xr

from .._runtime import (
    DISCRETISATION,
    GRID_EDGE,
    GRID_METHODS,
    GRID_POINTS,
    METHOD,
    THESIS_CHANNEL,
    InputError,
    Phase,
    write_hdf5,
)
from ..io import UNLABELLED, Experiment
from ..likelihood import RateMeasurement
from ..model import DAMPING, Method, RobotProfile, channel_coefficients, prior_overrides, propagate

__all__ = [
    "GridResult",
    "damping_grid",
    "grid_search",
    "onestep_mse",
    "prior_grid",
    "simulation_mse",
]

#: Grid points simulated at once by the simulation criterion (bounds memory).
SIMULATION_CHUNK_ELEMENTS = 4_000_000


#: Most values on one damping axis: 4x the thesis' finest grid (1..1000 step 1).
#: Every experiment's surface holds (values)^2 MSEs: 4000^2 x 8 bytes = 128 MB,
#: and a grid of 1e9 values would only run out of memory after minutes.
MAX_GRID_VALUES = 4000


def damping_grid(start: float, stop: float, step: float, name: str = "d") -> np.ndarray:
    """Values start, start + step, ..., up to and including stop [N s/m].

    Raises
    ------
    InputError
        When a value is not finite, the range is not positive or empty, the
        step is not positive, or the grid has more than
        :data:`MAX_GRID_VALUES` values.

    Examples
    --------
    >>> from bayes_jackal.thesis import damping_grid
    >>> damping_grid(10.0, 50.0, 10.0).tolist()  # STOP included
    [10.0, 20.0, 30.0, 40.0, 50.0]
    >>> len(damping_grid(10.0, 1000.0, 10.0))  # the thesis' grid
    100
    >>> try:
    ...     damping_grid(1.0, 10_000.0, 1.0)
    ... except ValueError as error:
    ...     print(error)
    d: grid START=1.0 STOP=10000.0 STEP=1.0 has 10000 values, more than 4000;
    take a larger STEP
    """
    values = (start, stop, step)
    if not all(np.isfinite(values)) or start <= 0 or step <= 0 or stop < start:
        raise InputError(
            "grid needs finite 0 < START <= STOP and STEP > 0 [N s/m], "
            f"got START={start!r} STOP={stop!r} STEP={step!r}",
            field=name,
        )
    count = np.floor((stop - start) / step + 1e-9) + 1
    if count > MAX_GRID_VALUES:
        raise InputError(
            f"grid START={start!r} STOP={stop!r} STEP={step!r} has {count:.0f} values, more "
            f"than {MAX_GRID_VALUES}; take a larger STEP",
            field=name,
        )
    return start + step * np.arange(int(count))


def prior_grid(
    robot: RobotProfile,
    parameter: str,
    method: str = METHOD,
    priors: Mapping[str, Sequence[float]] | None = None,
) -> np.ndarray:
    """The default grid of one damping: log-spaced over the profile's prior range [N s/m].

    :data:`GRID_POINTS` ``[method]`` values from the prior's low to its high
    bound, both included, equally spaced in log d: 1000 for the one-step
    criterion, 100 for the simulation one, the thesis' counts (its grids
    1..1000 step 1 and 10..1000 step 10).

    Why log-spaced rather than linear: the damping's prior is log-uniform,
    and the model's poles are -4 d / m (eq. 4-29/30), so what the data pin
    down is the time constant m / d, to a relative precision. Equal ratios
    give every part of the range the same relative resolution: 0.46 %
    between the 1000 values over a mass-scaled prior's factor 100, 4.8 %
    between the 100. A linear step fine enough at the low end is wasted at
    the high end (the thesis' step 10 is 33 % at the Jackal's d_long = 30
    and 1 % at 1000), and over a wider range such as the Warthog's
    121-12104 N s/m a step of 1 would take 12,000 values per axis. The
    count, not the step, is fixed, so the cost is the same for every robot:
    10^6 one-step points per experiment, O(1) each, or 10^4 simulations.
    A linear grid, the thesis' own, is :func:`damping_grid` (``grid --d-lat
    1 1000 1``).

    Parameters
    ----------
    robot : RobotProfile
        Its ``priors[parameter]`` is the range.
    parameter : {"d_lat", "d_long"}
    method : {"onestep", "simulation"}
        The criterion, which sets the count.
    priors : mapping of str to (low, high), optional
        Prior ranges that replace the profile's (as ``--prior d_lat LOW
        HIGH`` does), validated by :func:`bayes_jackal.model.prior_overrides`.

    Returns
    -------
    ndarray, shape (GRID_POINTS[method],)
        Increasing values [N s/m]; the first and last are the range's bounds.

    Raises
    ------
    InputError
        For a parameter other than the damping, an unknown method, or a bad
        range in ``priors``.

    Examples
    --------
    The Jackal's prior is 10-1000 N s/m; the Warthog's, scaled to its
    200 kg body, 121.04-12104.34 N s/m:

    >>> import numpy as np
    >>> import bayes_jackal as bj
    >>> from bayes_jackal.thesis import prior_grid
    >>> grid = prior_grid(bj.load_profile(), "d_long", "simulation")
    >>> len(grid), grid[[0, -1]].tolist(), round(float(grid[1] / grid[0]), 4)
    (100, [10.0, 1000.0], 1.0476)
    >>> warthog = prior_grid(bj.load_profile("warthog"), "d_lat")
    >>> len(warthog), [round(float(value), 2) for value in warthog[[0, -1]]]
    (1000, [121.04, 12104.34])
    >>> prior_grid(bj.load_profile(), "d_lat", priors={"d_lat": (50, 500)})[[0, -1]].tolist()
    [50.0, 500.0]
    """
    if parameter not in DAMPING:
        raise InputError(
            f"a grid spans a damping, {list(DAMPING)}, got {parameter!r}", field="parameter"
        )
    if method not in GRID_POINTS:
        raise InputError(f"unknown method {method!r}; use one of {GRID_METHODS}", field="method")
    low, high = {**robot.priors, **prior_overrides(priors)}[parameter]
    return np.geomspace(low, high, GRID_POINTS[method])


def onestep_mse(
    experiment: Experiment,
    robot: RobotProfile,
    d_lat: np.ndarray,
    d_long: np.ndarray,
    channel: str = "yaw",
    discretisation: Method = "zoh",
) -> np.ndarray:
    """One-step prediction MSE (eq. 9-2) on a (d_lat, d_long) grid.

    Parameters
    ----------
    experiment : Experiment
    robot : RobotProfile
    d_lat : ndarray, shape (L,)
    d_long : ndarray, shape (M,)
        Grid values [N s/m].
    channel : {"yaw", "vx", "vy"}
        The thesis' method takes a measured state: vx and vy recorded as
        poses are taken as the velocities derived from them, as the thesis'
        were (the posterior models the poses: docs/design.md §2.2).
    discretisation : {"zoh", "euler"}

    Returns
    -------
    ndarray, shape (L, M)
        Mean squared one-step residual [channel unit^2].

    Examples
    --------
    The mean square of the one-step residuals (eq. 7-3) over the whole run,
    at every grid point:

    >>> import numpy as np
    >>> import bayes_jackal as bj
    >>> from bayes_jackal.thesis import damping_grid, onestep_mse
    >>> from bayes_jackal.likelihood import channel_residuals
    >>> robot = bj.load_profile()
    >>> run = bj.simulate_experiment(robot, 110.0, 30.0, "v1", rng=1)
    >>> d_lat, d_long = damping_grid(100.0, 120.0, 10.0), damping_grid(30.0, 40.0, 10.0)
    >>> mse = onestep_mse(run, robot, d_lat, d_long)
    >>> mse.shape
    (3, 2)
    >>> w = channel_residuals(run, robot, 110.0, 40.0, steady=False)
    >>> bool(np.isclose(mse[1, 1], np.mean(w**2)))
    True
    """
    regressors = RateMeasurement().series(experiment, channel).regressors
    gram = regressors.T @ regressors / len(regressors)
    alpha, input_row = channel_coefficients(
        robot, d_lat[:, None], d_long[None, :], channel, experiment.dt, discretisation
    )
    coefficients = np.concatenate(
        [np.ones((*alpha.shape, 1)), -alpha[..., None], -input_row], axis=-1
    )
    return np.einsum("...i,...i->...", coefficients @ gram, coefficients)


def simulation_mse(
    experiment: Experiment,
    robot: RobotProfile,
    d_lat: np.ndarray,
    d_long: np.ndarray,
    channel: str = "yaw",
    discretisation: Method = "zoh",
) -> np.ndarray:
    """MSE between the simulated and the measured channel (eq. 5-1).

    The simulation starts from the first measured sample and is driven by the
    measured wheel speeds. Grid points are simulated in chunks, each fully
    vectorised.

    Parameters and return value as :func:`onestep_mse`.

    Examples
    --------
    The simulated yaw rate, started from the first measured state and driven
    by the measured wheel speeds (:func:`bayes_jackal.model.simulate`),
    against the measured one:

    >>> import numpy as np
    >>> import bayes_jackal as bj
    >>> from bayes_jackal.thesis import damping_grid, simulation_mse
    >>> from bayes_jackal.model import simulate
    >>> robot = bj.load_profile()
    >>> run = bj.simulate_experiment(robot, 110.0, 30.0, "v1", rng=1)
    >>> d_lat, d_long = damping_grid(100.0, 120.0, 10.0), damping_grid(30.0, 40.0, 10.0)
    >>> mse = simulation_mse(run, robot, d_lat, d_long)
    >>> x0 = [run.channel(c)[0] for c in ("vx", "vy", "yaw")]
    >>> yaw = simulate(robot, 120.0, 30.0, run.inputs, x0, dt=run.dt)[:, 2]
    >>> bool(np.isclose(mse[2, 0], np.mean((yaw - run.channel("yaw")) ** 2)))
    True
    """
    y = experiment.channel(channel)
    alpha, input_row = channel_coefficients(
        robot, d_lat[:, None], d_long[None, :], channel, experiment.dt, discretisation
    )
    alpha, input_row = alpha.ravel(), input_row.reshape(-1, 2)
    chunk = max(1, SIMULATION_CHUNK_ELEMENTS // len(y))
    mse = np.concatenate(
        [
            np.mean(
                (
                    propagate(
                        alpha[i : i + chunk], input_row[i : i + chunk] @ experiment.inputs.T, y[0]
                    )
                    - y
                )
                ** 2,
                axis=-1,
            )
            for i in range(0, len(alpha), chunk)
        ]
    )
    return mse.reshape(len(d_lat), len(d_long))


_CRITERIA = {"onestep": onestep_mse, "simulation": simulation_mse}


@dataclass(frozen=True)
class GridResult:
    """MSE surfaces of a grid search.

    Attributes
    ----------
    method : {"onestep", "simulation"}
    channel : str
    d_lat : ndarray, shape (L,)
    d_long : ndarray, shape (M,)
        Grid values [N s/m].
    experiment_mse : dict of str to ndarray, shape (L, M)
        MSE per experiment (eq. 5-1 or 9-2).
    series_mse : dict of str to ndarray, shape (L, M)
        Mean MSE of the experiments of each series (eq. 5-2).
    series_members : dict of str to list of str
        Experiment names of each series.
    mse : ndarray, shape (L, M)
        Sum of the series means (eq. 5-3); the mean when there is one series.

    Examples
    --------
    A result holds each experiment's surface, each series' mean and the
    total; :meth:`summary` is what ``bayes-jackal grid --json`` prints:

    >>> import tempfile
    >>> from pathlib import Path
    >>> import bayes_jackal as bj
    >>> from bayes_jackal.thesis import damping_grid, grid_search
    >>> robot = bj.load_profile()
    >>> runs = [bj.simulate_experiment(robot, 110.0, 30.0, s, rng=1) for s in ("v1", "v2")]
    >>> d_lat, d_long = damping_grid(50.0, 200.0, 10.0), damping_grid(10.0, 60.0, 5.0)
    >>> result = grid_search(runs, robot, d_lat, d_long)
    >>> result.mse.shape, sorted(result.experiment_mse)
    ((16, 11), ['v1', 'v2'])
    >>> sorted(result.summary())
    ['channel', 'd_lat', 'd_long', 'edge', 'experiments', 'grid', 'method', 'mse', 'ratio',
     'series', 'warnings']
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     print(result.to_netcdf(Path(folder) / "grid.nc").name)
    grid.nc
    """

    method: str
    channel: str
    d_lat: np.ndarray
    d_long: np.ndarray
    experiment_mse: dict[str, np.ndarray]
    series_mse: dict[str, np.ndarray]
    series_members: dict[str, list[str]] = field(default_factory=dict)

    @property
    def mse(self) -> np.ndarray:
        """Total surface, eq. 5-3."""
        return np.sum(list(self.series_mse.values()), axis=0)

    def _index(self, surface: np.ndarray | None) -> tuple[np.ndarray, int, int]:
        surface = self.mse if surface is None else surface
        i, j = np.unravel_index(np.argmin(surface), surface.shape)
        return surface, int(i), int(j)

    @property
    def caveat(self) -> str | None:
        """What the criterion's minimum is not, in words (the one-step grid's), else None.

        Examples
        --------
        >>> import numpy as np
        >>> from bayes_jackal.thesis import GridResult
        >>> grid = GridResult("onestep", "yaw", np.ones(2), np.ones(2), {}, {})
        >>> grid.caveat.startswith("the one-step minimum is not the damping's estimate")
        True
        """
        if self.method != "onestep":
            return None
        return (
            "the one-step minimum is not the damping's estimate: each prediction starts from "
            "the measured, noisy sample, which biases it (the thesis, 9-1-2, found 40/10 N s/m "
            "where the simulation grid found 110/30; only their ratio agreed); the posterior "
            "(bayes-jackal sample) is the estimate"
        )

    def argmin(self, surface: np.ndarray | None = None) -> tuple[float, float, float]:
        """(d_lat, d_long, mse) at the minimum of ``surface`` (the total by default).

        A minimum on the grid's edge may not be the criterion's: :meth:`edges`
        says which edge.
        """
        surface, i, j = self._index(surface)
        return float(self.d_lat[i]), float(self.d_long[j]), float(surface[i, j])

    def edges(self, surface: np.ndarray | None = None) -> dict[str, str]:
        """The edges of the grid the minimum of ``surface`` (the total by default) lies on.

        Returns
        -------
        dict of str to str
            ``"d_lat"`` and/or ``"d_long"`` -> ``"low"`` (the axis' first
            value) or ``"high"`` (its last); empty when the minimum is inside
            on both axes. An axis of one value is no search and has no edge;
            a minimum tied with its neighbour inside the grid lies inside too
            (the vx channel's MSE does not depend on d_lat, eq. 4-29: the
            whole d_lat axis ties).

        Examples
        --------
        A run of truth (110, 30) N s/m on a grid whose d_lat stops at 90: the
        minimum is at its high edge, below the truth's d_lat.

        >>> import bayes_jackal as bj
        >>> from bayes_jackal.thesis import damping_grid, grid_search
        >>> robot = bj.load_profile()
        >>> run = bj.simulate_experiment(robot, 110.0, 30.0, "v1", rng=1)
        >>> result = grid_search(
        ...     [run], robot, damping_grid(50.0, 90.0, 10.0), damping_grid(10.0, 60.0, 5.0),
        ...     method="simulation",
        ... )
        >>> result.argmin()[:2], result.edges()
        ((90.0, 25.0), {'d_lat': 'high'})
        """
        surface, i, j = self._index(surface)
        found = {}
        for name, line, index in (("d_lat", surface[:, j], i), ("d_long", surface[i, :], j)):
            last = len(line) - 1
            if last and index == 0 and line[0] < line[1]:
                found[name] = "low"
            elif last and index == last and line[last] < line[last - 1]:
                found[name] = "high"
        return found

    def edge_warnings(self) -> list[dict]:
        """A ``grid-edge`` warning for each edge of the grid the total minimum lies on.

        Returns
        -------
        list of dict
            ``kind`` (``"grid-edge"``), ``message``, ``method``,
            ``parameter`` (``"d_lat"`` or ``"d_long"``), ``side`` (``"low"``
            or ``"high"``) and ``value``, the minimum's value of that damping,
            the grid's first or last [N s/m].

        Examples
        --------
        >>> import bayes_jackal as bj
        >>> from bayes_jackal.thesis import damping_grid, grid_search
        >>> robot = bj.load_profile()
        >>> run = bj.simulate_experiment(robot, 110.0, 30.0, "v1", rng=1)
        >>> result = grid_search(
        ...     [run], robot, damping_grid(50.0, 90.0, 10.0), damping_grid(10.0, 60.0, 5.0),
        ...     method="simulation",
        ... )
        >>> (warning,) = result.edge_warnings()
        >>> warning["parameter"], warning["side"], warning["value"]
        ('d_lat', 'high', 90.0)
        >>> print(warning["message"])
        simulation grid: the minimum (d_lat = 90, d_long = 25 N s/m) lies on the high edge
        of the d_lat grid (50-90 N s/m): the MSE may be lower above d_lat = 90 N s/m,
        outside the grid; widen the grid
        """
        d_lat, d_long, _ = self.argmin()
        at = {"d_lat": d_lat, "d_long": d_long}
        warnings = []
        for name, side in self.edges().items():
            values = getattr(self, name)
            span = f"{values[0]:g}-{values[-1]:g} N s/m"
            where = "below" if side == "low" else "above"
            message = (
                f"{self.method} grid: the minimum (d_lat = {d_lat:g}, d_long = {d_long:g} N s/m) "
                f"lies on the {side} edge of the {name} grid ({span}): the MSE may be lower "
                f"{where} {name} = {at[name]:g} N s/m, outside the grid; widen the grid"
            )
            warnings.append(
                {
                    "kind": GRID_EDGE,
                    "message": message,
                    "method": self.method,
                    "parameter": name,
                    "side": side,
                    "value": at[name],
                }
            )
        return warnings

    def summary(self) -> dict:
        """JSON-ready summary: the total argmin at top level, then per series and experiment.

        Each minimum has its ``edge`` (:meth:`edges`: ``{}`` inside the
        grid); ``warnings`` holds the total minimum's :meth:`edge_warnings`.
        """
        d_lat, d_long, mse = self.argmin()

        def best(surface: np.ndarray) -> dict:
            found = dict(zip(("d_lat", "d_long", "mse"), self.argmin(surface), strict=True))
            return {**found, "edge": self.edges(surface)}

        return {
            "d_lat": d_lat,
            "d_long": d_long,
            "mse": mse,
            "ratio": d_lat / d_long,
            "edge": self.edges(),
            "method": self.method,
            "channel": self.channel,
            "grid": {
                "d_lat": [float(self.d_lat[0]), float(self.d_lat[-1]), len(self.d_lat)],
                "d_long": [float(self.d_long[0]), float(self.d_long[-1]), len(self.d_long)],
            },
            "series": {
                label: {**best(surface), "experiments": self.series_members.get(label, [])}
                for label, surface in self.series_mse.items()
            },
            "experiments": {name: best(s) for name, s in self.experiment_mse.items()},
            "warnings": self.edge_warnings(),
        }

    def to_netcdf(self, path: str | Path) -> Path:
        """Save all surfaces as NetCDF (atomically)."""
        names = list(self.experiment_mse)
        labels = list(self.series_mse)
        dataset = xr.Dataset(
            {
                "mse": (("d_lat", "d_long"), self.mse),
                "experiment_mse": (
                    ("experiment", "d_lat", "d_long"),
                    np.stack([self.experiment_mse[n] for n in names]),
                ),
                "series_mse": (
                    ("series", "d_lat", "d_long"),
                    np.stack([self.series_mse[s] for s in labels]),
                ),
            },
            coords={
                "d_lat": self.d_lat,
                "d_long": self.d_long,
                "experiment": names,
                "series": labels,
            },
            attrs={"method": self.method, "channel": self.channel},
        )
        return write_hdf5(dataset, path)


def grid_search(
    experiments: list[Experiment],
    robot: RobotProfile,
    d_lat: np.ndarray,
    d_long: np.ndarray,
    method: str = METHOD,
    channel: str = THESIS_CHANNEL,
    discretisation: Method = DISCRETISATION,
    *,
    progress: bool = False,
) -> GridResult:
    """Evaluate a grid-search criterion on every experiment and combine them.

    Parameters
    ----------
    experiments : list of Experiment
        Experiments without a series label form one series, ``"unlabelled"``.
    robot : RobotProfile
    d_lat, d_long : ndarray
        Grid values [N s/m], e.g. from :func:`damping_grid`.
    method : {"onestep", "simulation"}
    channel : {"yaw", "vx", "vy"}
    discretisation : {"zoh", "euler"}
    progress : bool
        Show the search while it runs on stderr (a ticking line on a
        terminal, one line elsewhere; :class:`bayes_jackal._runtime.progress.Phase`).

    Returns
    -------
    GridResult

    Examples
    --------
    The thesis' simulation criterion (ch. 5) on two simulated runs, one per
    series (truth d_lat = 110, d_long = 30 N s/m):

    >>> import bayes_jackal as bj
    >>> from bayes_jackal.thesis import damping_grid, grid_search
    >>> robot = bj.load_profile()
    >>> runs = [bj.simulate_experiment(robot, 110.0, 30.0, s, rng=1) for s in ("v1", "v2")]
    >>> d_lat, d_long = damping_grid(50.0, 200.0, 10.0), damping_grid(10.0, 60.0, 5.0)
    >>> result = grid_search(runs, robot, d_lat, d_long, method="simulation")
    >>> d_lat_best, d_long_best, mse = result.argmin()
    >>> d_lat_best, d_long_best, f"{mse:.2e}"
    (150.0, 40.0, '2.49e-03')

    The yaw rate identifies the ratio d_lat / d_long (3.75 here, 3.67 true),
    not the scale: the posterior's ``damping-scale-not-identified`` check
    (:func:`bayes_jackal.posterior.damping_scale`) says so.
    """
    if method not in _CRITERIA:
        raise InputError(f"unknown method {method!r}; use one of {GRID_METHODS}", field="method")
    if not experiments:
        raise InputError("no experiments given", field="experiments")
    d_lat, d_long = np.asarray(d_lat, float), np.asarray(d_long, float)
    criterion = _CRITERIA[method]
    label = f"  {method} MSE grid of the {channel} channel ({d_lat.size} x {d_long.size} points)"
    with Phase(label, enabled=progress):
        surfaces = {
            e.name: criterion(e, robot, d_lat, d_long, channel, discretisation)
            for e in experiments
        }
    members: dict[str, list[str]] = {}
    for e in experiments:
        members.setdefault(e.series or UNLABELLED, []).append(e.name)
    series_mse = {
        label: np.mean([surfaces[n] for n in names], axis=0) for label, names in members.items()
    }
    return GridResult(method, channel, d_lat, d_long, surfaces, series_mse, members)
