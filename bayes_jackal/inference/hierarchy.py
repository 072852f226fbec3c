"""The damping across groups of runs: a collapsed linear-Gaussian hierarchy.

Stage 2 of :func:`bayes_jackal.population` (docs/guide/population.md).
Stage 1 sampled each *unit* (one run, or a group's runs pooled with their
noise shared) alone with emcee.
On the log scale, theta = (log d_lat, log d_long), a unit's prior is uniform
on the robot's box of prior ranges, of area ``W = W_lat W_long``, so its
likelihood of theta with the noise integrated out is exactly

    L_u(theta) = Z_u W p_u(theta | y_u)

(Z_u its evidence, p_u its damping posterior). Summarising p_u by a normal
N(m_u, S_u) (checked: :attr:`UnitPosterior.coverage`) makes every
structure a linear-Gaussian model of the units' means:

    theta_u = a_g(u) + b z_u,   m_u ~ N(theta_u, S_u)

with z_u the unit's covariate (the operating point, standardised to
[-1/2, 1/2] across the campaign; b = 0 without state dependence) and

- **pooled**: a_g = mu for every group, one damping;
- **hierarchical**: a_g ~ N(mu, T), the population, its two spreads tau
  those of the scale (log of the geometric mean of d_lat and d_long) and of
  the ratio log(d_lat / d_long) (:data:`TO_SCALE_RATIO`): a floor scales
  both dampings, and one run pins their ratio far better than their scale;
- **independent**: each a_g uniform on the box.

The group dampings a_g, the population mean mu and the slope b enter
linearly and are integrated out in closed form (generalised least squares),
so the sampler never sees the funnel between a_g and tau: the two spreads
tau are integrated on a grid in log tau, where their log-uniform prior is
flat. The draws are exact given the normal summaries: tau from the grid,
then (mu, b) and each a_g from their normal conditionals.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.special
import scipy.stats

from .._runtime import HDI_PROB, InputError, as_rng, chunks

__all__ = [
    "DAMPING_NAMES",
    "FROM_SCALE_RATIO",
    "POPULATION_STRUCTURES",
    "SLOPE_SD",
    "TAU_RANGE",
    "TO_SCALE_RATIO",
    "Hierarchy",
    "UnitPosterior",
    "unit_posterior",
]

#: The damping parameters the population describes, in this order [N s/m].
DAMPING_NAMES = ("d_lat", "d_long")
#: How the groups' dampings relate: one for all, drawn from a population, or free.
POPULATION_STRUCTURES = ("pooled", "hierarchical", "independent")
#: Each structure's name (its key in the evidence and the JSON) -> how the
#: groups relate and whether log d has a slope in the covariate.
STRUCTURE_PARTS = {
    **{kind: (kind, False) for kind in POPULATION_STRUCTURES},
    **{f"{kind} + slope": (kind, True) for kind in POPULATION_STRUCTURES},
}
#: Log-uniform prior range of the population spread tau of log d [-]: from
#: 1 % (below what a campaign of runs resolves) to a factor e per sd. Its
#: log-uniform form is Jeffreys' prior of a scale, under which the
#: population mean's interval is the calibrated Student-t interval.
TAU_RANGE = (0.01, 1.0)
#: Standard deviation of the normal prior of each slope b, of the scale and of
#: the ratio [log d per covariate span]: the damping changes by less than a
#: factor 10 either way between the campaign's lowest and highest operating
#: points with 95 % prior probability (ln 10 is 2 sd). Normal, not uniform:
#: a slope the data cannot see (a covariate constant within every group,
#: beside the groups' own levels) then integrates to its prior, and costs
#: nothing, instead of leaving the evidence's integral unbounded.
SLOPE_SD = math.log(10.0) / 2
#: (log d_lat, log d_long) -> (scale, ratio): s = (log d_lat + log d_long) / 2, the log of
#: their geometric mean, and rho = log(d_lat / d_long). A floor scales both dampings, and
#: one run's yaw rate pins their ratio far better than their scale (thesis ch. 7), so the
#: population's two spreads are those of s and rho. The map has determinant -1: areas,
#: and so the box's prior density, are kept.
TO_SCALE_RATIO = np.array([[0.5, 0.5], [1.0, -1.0]])
FROM_SCALE_RATIO = np.linalg.inv(TO_SCALE_RATIO)
#: Grid points per axis of log tau (cell width ln(100) / 80 = 0.058).
TAU_GRID = 80
#: Elements of the largest work array per chunk of grid points or draws.
_BUDGET = 2_000_000
#: Squared Mahalanobis radius of a bivariate normal's 94 % ellipse: -2 ln(1 - 0.94).
_ELLIPSE = -2.0 * math.log(1.0 - HDI_PROB)


@dataclass(frozen=True)
class UnitPosterior:
    """One unit's damping posterior on the log scale, summarised by a normal.

    Attributes
    ----------
    name : str
        The unit: a run, or a group's runs pooled.
    group : str
        Its group's label.
    runs : tuple of str
        The runs it holds.
    mean : ndarray, shape (2,)
        Posterior mean of (log d_lat, log d_long) [log N s/m].
    cov : ndarray, shape (2, 2)
        Their posterior covariance.
    covariate : float or None
        The unit's operating point (e.g. speed [m/s]), when given.
    log_evidence, evidence_error : float
        Stage 1's log evidence of the unit and its error [nats] (NaN: unknown).
    ess : float
        Effective sample size of the draws (the smaller of the two dampings').
    coverage : float
        Fraction of the draws inside the normal's 94 % ellipse (0.94 when
        the normal summary holds).
    skewness : float
        The larger absolute skewness of the two log-dampings' draws (0 when
        the normal summary holds).
    at_bound : tuple of str
        The dampings whose draws reach the edge of the prior range.

    Examples
    --------
    A run's summary as :func:`unit_posterior` makes it from its draws, here
    written by hand (log-dampings of a posterior correlated at 0.9):

    >>> import numpy as np
    >>> from bayes_jackal.inference import UnitPosterior
    >>> cov = 0.05**2 * np.array([[1.0, 0.9], [0.9, 1.0]])
    >>> unit = UnitPosterior("v1_01", "tiles", ("v1_01",), np.log([110.0, 30.0]), cov)
    >>> np.exp(unit.mean).round(1).tolist(), unit.covariate
    ([110.0, 30.0], None)
    """

    name: str
    group: str
    runs: tuple[str, ...]
    mean: np.ndarray
    cov: np.ndarray
    covariate: float | None = None
    log_evidence: float = math.nan
    evidence_error: float = math.nan
    ess: float = math.inf
    coverage: float = HDI_PROB
    skewness: float = 0.0
    at_bound: tuple[str, ...] = ()


def unit_posterior(
    name: str,
    group: str,
    draws: np.ndarray,
    bounds: np.ndarray,
    *,
    runs: Sequence[str] = (),
    covariate: float | None = None,
    log_evidence: float = math.nan,
    evidence_error: float = math.nan,
    ess: float = math.inf,
) -> UnitPosterior:
    """The normal summary of a unit's damping draws, with its checks.

    Parameters
    ----------
    name, group : str
    draws : ndarray, shape (n, 2)
        Posterior draws of (d_lat, d_long) [N s/m].
    bounds : ndarray, shape (2, 2)
        Prior range (low, high) of d_lat and d_long [N s/m].
    runs : sequence of str
        The runs the unit holds (default: its name).
    covariate : float, optional
    log_evidence, evidence_error : float
    ess : float
        Effective sample size of the draws.

    Returns
    -------
    UnitPosterior

    Examples
    --------
    Draws from a log-normal posterior: the summary recovers its mean and
    covariance, and 94 % of the draws lie in its 94 % ellipse:

    >>> import numpy as np
    >>> from bayes_jackal.inference import unit_posterior
    >>> rng = np.random.default_rng(1)
    >>> draws = np.exp(rng.multivariate_normal([4.7, 3.4], [[0.01, 0.009], [0.009, 0.01]], 4000))
    >>> unit = unit_posterior("v1_01", "floor A", draws, np.array([[10, 1000], [10, 1000]]))
    >>> np.round(unit.mean, 2).tolist(), round(unit.coverage, 2), unit.at_bound
    ([4.7, 3.4], 0.94, ())
    >>> bool(unit.skewness < 0.1)
    True
    """
    log_draws = np.log(np.asarray(draws, float))
    mean = log_draws.mean(axis=0)
    cov = np.cov(log_draws.T)
    centred = log_draws - mean
    distance = np.einsum("ni,ij,nj->n", centred, np.linalg.inv(cov), centred)
    log_bounds = np.log(np.asarray(bounds, float))
    # Draws within 1 % of the log range from an edge: the likelihood is cut there.
    margin = 0.01 * (log_bounds[:, 1] - log_bounds[:, 0])
    near = (log_draws < log_bounds[:, 0] + margin) | (log_draws > log_bounds[:, 1] - margin)
    return UnitPosterior(
        name=name,
        group=group,
        runs=tuple(runs) or (name,),
        mean=mean,
        cov=cov,
        covariate=covariate,
        log_evidence=float(log_evidence),
        evidence_error=float(evidence_error),
        ess=float(ess),
        coverage=float(np.mean(distance <= _ELLIPSE)),
        skewness=float(np.max(np.abs(scipy.stats.skew(log_draws, axis=0)))),
        at_bound=tuple(np.array(DAMPING_NAMES)[near.mean(axis=0) > 0.01].tolist()),
    )


class Hierarchy:
    """The pooled, hierarchical and independent structures of a campaign's units.

    Parameters
    ----------
    units : sequence of UnitPosterior
        Every unit of every group; all with a covariate, or none.
    bounds : ndarray, shape (2, 2)
        The units' prior range (low, high) of d_lat and d_long [N s/m]; the
        population mean's prior is uniform on the same box (log scale).
    tau_range : (float, float)
        Log-uniform prior range of each population spread [log d].
    slope_sd : float
        Standard deviation of each slope's normal prior [log d per covariate span].

    Examples
    --------
    Three groups, one unit each, whose dampings differ by 30 %: the
    independent and hierarchical structures beat one pooled damping.

    >>> import numpy as np
    >>> from bayes_jackal.inference import Hierarchy, UnitPosterior
    >>> cov = np.diag([0.03, 0.03]) ** 2
    >>> means = {"A": np.log([88.0, 24.0]), "B": np.log([110.0, 30.0]), "C": np.log([143.0, 39.0])}
    >>> units = [UnitPosterior(g, g, (g,), mean, cov) for g, mean in means.items()]
    >>> model = Hierarchy(units, np.array([[10.0, 1000.0], [10.0, 1000.0]]))
    >>> model.structures
    ('pooled', 'hierarchical', 'independent')
    >>> evidence = {s: model.log_integral(s) for s in model.structures}
    >>> evidence["hierarchical"] - evidence["pooled"] > 3
    True
    >>> evidence["independent"] - evidence["pooled"] > 3
    True
    >>> draws = model.draws("hierarchical", 2000, rng=1)
    >>> sorted(draws), draws["groups"].shape
    (['groups', 'mu', 'new_group', 'slope', 'tau'], (2000, 3, 2))
    """

    def __init__(
        self,
        units: Sequence[UnitPosterior],
        bounds: np.ndarray,
        *,
        tau_range: tuple[float, float] = TAU_RANGE,
        slope_sd: float = SLOPE_SD,
    ) -> None:
        self.units = tuple(units)
        if not self.units:
            raise InputError("a population needs at least one unit", field="units")
        self.groups = tuple(dict.fromkeys(unit.group for unit in self.units))
        self.tau_range = tuple(float(v) for v in tau_range)
        if not 0 < self.tau_range[0] < self.tau_range[1]:
            raise InputError(
                f"tau_range must satisfy 0 < low < high, got {list(tau_range)}",
                field="tau_range",
            )
        self.slope_sd = float(slope_sd)
        self.bounds = np.asarray(bounds, float)
        log_bounds = np.log(self.bounds)
        #: Log area of the box of (log d_lat, log d_long) [log of log-units^2].
        self.log_box = float(np.sum(np.log(log_bounds[:, 1] - log_bounds[:, 0])))
        self.covariates = self._standardised_covariates()
        # The units in (scale, ratio) coordinates, where the population's spreads live.
        self._means = np.concatenate([TO_SCALE_RATIO @ unit.mean for unit in self.units])
        self._covs = [TO_SCALE_RATIO @ unit.cov @ TO_SCALE_RATIO.T for unit in self.units]
        self._members = [
            np.flatnonzero([unit.group == group for unit in self.units]) for group in self.groups
        ]

    def _standardised_covariates(self) -> np.ndarray | None:
        """z_u = (x_u - centre) / span, the campaign's range on [-1/2, 1/2]; None without one."""
        given = [unit.covariate is not None for unit in self.units]
        if not any(given):
            return None
        if not all(given):
            missing = next(unit.name for unit in self.units if unit.covariate is None)
            raise InputError(
                f"every unit needs a covariate when one has one; unit {missing!r} has none",
                field="covariate",
            )
        values = np.array([unit.covariate for unit in self.units], float)
        low, high = values.min(), values.max()
        if not np.all(np.isfinite(values)) or high == low:
            raise InputError(
                "the covariate must take two finite values at least, got "
                f"{sorted(set(values.tolist()))}",
                field="covariate",
            )
        span, centre = float(high) - float(low), float(high) / 2 + float(low) / 2
        if not math.isfinite(span):  # Python floats: inf without numpy's overflow warning
            raise InputError(
                f"the covariate's values {low:g} .. {high:g} span more than a float holds",
                field="covariate",
            )
        self.covariate_span, self.covariate_centre = span, centre
        return (values - self.covariate_centre) / self.covariate_span

    @property
    def structures(self) -> tuple[str, ...]:
        """The structures, and with a covariate each with a slope (``"pooled + slope"``)."""
        with_slope = self.covariates is not None
        return tuple(
            name for name, (_, slope) in STRUCTURE_PARTS.items() if with_slope or not slope
        )

    def _parse(self, structure: str) -> tuple[str, bool]:
        if structure not in self.structures:
            raise InputError(
                f"unknown structure {structure!r}; choose from {list(self.structures)}",
                field="structure",
            )
        return STRUCTURE_PARTS[structure]

    def _design(self, kind: str, slope: bool) -> np.ndarray:
        """X of theta = X beta, rows (unit, damping), columns (mu or each a_g, then b)."""
        levels = len(self.groups) if kind == "independent" else 1
        n = len(self.units)
        X = np.zeros((n, 2, 2 * levels + 2 * slope))
        for u, unit in enumerate(self.units):
            g = self.groups.index(unit.group) if kind == "independent" else 0
            X[u, :, 2 * g : 2 * g + 2] = np.eye(2)
            if slope:
                X[u, :, 2 * levels :] = self.covariates[u] * np.eye(2)
        return X.reshape(2 * n, -1)

    def _prior_precision(self, X: np.ndarray, slope: bool) -> np.ndarray:
        """Lambda_0 of beta: 0 for the means (flat on the box), 1 / SLOPE_SD^2 for each slope."""
        precision = np.zeros(X.shape[1])
        if slope:
            precision[-2:] = 1.0 / self.slope_sd**2
        return np.diag(precision)

    def _log_prior_normalisation(self, kind: str, slope: bool) -> float:
        """log of beta's prior density factors: 1 / W per mean (mu, or each a_g), and the
        slopes' normal normalisation, (2 pi)^-1 / SLOPE_SD^2."""
        levels = len(self.groups) if kind == "independent" else 1
        return -levels * self.log_box - slope * 2 * math.log(
            math.sqrt(2 * math.pi) * self.slope_sd
        )

    def _posterior_of_beta(self, kind: str, slope: bool, tau2: np.ndarray) -> tuple:
        """beta's normal posterior given tau: precision A + Lambda_0, its c, m'C^-1 m, log|C|."""
        X = self._design(kind, slope)
        A, c, quadratic, log_det = self._generalised_least_squares(X, tau2)
        return A + self._prior_precision(X, slope), c, quadratic, log_det, X.shape[0]

    def _generalised_least_squares(self, X: np.ndarray, tau2: np.ndarray) -> tuple:
        """Per tau^2 row: A = X'C^-1 X, c = X'C^-1 m, m'C^-1 m and log|C|, group by group.

        C is block-diagonal by group: each unit's S_u, plus tau^2 between
        every two units of a group (their shared a_g integrated out).
        """
        K, k = len(tau2), X.shape[1]
        A, c = np.zeros((K, k, k)), np.zeros((K, k))
        quadratic, log_det = np.zeros(K), np.zeros(K)
        for members in self._members:
            rows = (2 * members[:, None] + np.arange(2)).ravel()
            size = len(rows)
            S = np.zeros((size, size))
            for i, u in enumerate(members):
                S[2 * i : 2 * i + 2, 2 * i : 2 * i + 2] = self._covs[u]
            # J (x) diag(tau^2): tau_scale^2 between the scale rows of every two units,
            # tau_ratio^2 between their ratio rows.
            together = np.ones((len(members), len(members)))
            scale, ratio = (np.kron(together, np.diag(e)) for e in np.eye(2))
            for part in chunks(K, size * (size + k + 1), budget=_BUDGET):
                C = S + tau2[part, 0, None, None] * scale + tau2[part, 1, None, None] * ratio
                rhs = np.concatenate([X[rows], self._means[rows, None]], axis=1)
                solved = np.linalg.solve(C, np.broadcast_to(rhs, (len(C), size, k + 1)))
                A[part] += np.einsum("ia,kib->kab", X[rows], solved[..., :k])
                c[part] += np.einsum("ia,ki->ka", X[rows], solved[..., k])
                quadratic[part] += np.einsum("i,ki->k", self._means[rows], solved[..., k])
                log_det[part] += np.linalg.slogdet(C)[1]
        return A, c, quadratic, log_det

    def _log_integrand(self, kind: str, slope: bool, tau2: np.ndarray) -> np.ndarray:
        """log of the integral over beta of prod_u N(m_u | X beta, C(tau)) p(beta), per tau^2.

        With P = A + Lambda_0: (2 pi)^((k - n) / 2) |C|^-1/2 |P|^-1/2
        exp(-(m'C^-1 m - c'P^-1 c) / 2) times beta's prior normalisation.
        """
        P, c, quadratic, log_det, n = self._posterior_of_beta(kind, slope, tau2)
        k = P.shape[-1]
        explained = np.einsum("ka,ka->k", c, np.linalg.solve(P, c[..., None])[..., 0])
        return (
            -0.5 * (n - k) * math.log(2 * math.pi)
            - 0.5 * log_det
            - 0.5 * np.linalg.slogdet(P)[1]
            - 0.5 * (quadratic - explained)
            + self._log_prior_normalisation(kind, slope)
        )

    def _tau_grid(self) -> tuple[np.ndarray, float]:
        """Cell centres (TAU_GRID^2, 2) of log tau, and the cell width."""
        low, high = np.log(self.tau_range)
        width = (high - low) / TAU_GRID
        axis = low + width * (np.arange(TAU_GRID) + 0.5)
        return np.stack(np.meshgrid(axis, axis, indexing="ij"), axis=-1).reshape(-1, 2), width

    def log_integral(self, structure: str) -> float:
        """log of the integral over the structure's parameters of prod_u N(m_u | theta_u, S_u).

        The log evidence of the structure is this plus the sum over units
        of (log Z_u + log W) (:meth:`log_evidence`); Bayes factors between
        structures are differences of it.
        """
        kind, slope = self._parse(structure)
        if kind != "hierarchical":
            return float(self._log_integrand(kind, slope, np.zeros((1, 2)))[0])
        log_tau, _ = self._tau_grid()
        values = self._log_integrand(kind, slope, np.exp(2 * log_tau))
        # Midpoint rule: each cell holds 1 / TAU_GRID^2 of the log-uniform prior.
        return float(scipy.special.logsumexp(values) - 2 * math.log(TAU_GRID))

    def log_evidence(self, structure: str) -> tuple[float, float]:
        """(log evidence, error) [nats]: stage 1's units' plus :meth:`log_integral`.

        The error combines the units' bridge-sampling errors; they are the
        same in every structure, so a Bayes factor between two structures
        does not carry them.
        """
        offset = sum(unit.log_evidence + self.log_box for unit in self.units)
        error = math.sqrt(sum(unit.evidence_error**2 for unit in self.units))
        return offset + self.log_integral(structure), error

    def log_integral_replicas(self, *, rng=None, repeats: int = 40) -> dict[str, np.ndarray]:
        """:meth:`log_integral` of every structure, each unit's mean redrawn ``repeats`` times.

        Each replica draws every unit's mean from N(m_u, S_u / ESS_u), its
        Monte Carlo error; the spread of a difference of two structures'
        replicas is the error of their ln B (the part of the units' evidence
        common to both cancels). Empty arrays when a unit's ESS is unknown.
        """
        rng = as_rng(rng)
        if not all(math.isfinite(unit.ess) for unit in self.units):
            return {structure: np.array([]) for structure in self.structures}
        replicas = {structure: [] for structure in self.structures}
        for _ in range(repeats):
            units = [
                dataclasses.replace(
                    unit, mean=rng.multivariate_normal(unit.mean, unit.cov / unit.ess)
                )
                for unit in self.units
            ]
            again = Hierarchy(units, self.bounds, tau_range=self.tau_range, slope_sd=self.slope_sd)
            for structure in self.structures:
                replicas[structure].append(again.log_integral(structure))
        return {structure: np.array(values) for structure, values in replicas.items()}

    def draws(self, structure: str, count: int, rng=None) -> dict[str, np.ndarray | None]:
        """Posterior draws of the structure's parameters, on the log scale.

        Returns
        -------
        dict
            ``mu`` (count, 2): the population mean of (log d_lat, log d_long)
            (pooled: the one damping; independent: None); ``tau`` (count, 2):
            the population's spreads of the scale and of the ratio
            (:data:`TO_SCALE_RATIO`; hierarchical only); ``new_group``
            (count, 2): a new group's (log d_lat, log d_long) at the
            reference covariate (hierarchical only); ``slope`` (count, 2):
            of (log d_lat, log d_long) per covariate span (with a slope);
            ``groups`` (count, G, 2): each group's (log d_lat, log d_long) at
            its units' mean covariate.
        """
        kind, slope = self._parse(structure)
        rng = as_rng(rng)
        tau2 = np.zeros((count, 2))
        if kind == "hierarchical":
            log_tau, width = self._tau_grid()
            weights = self._log_integrand(kind, slope, np.exp(2 * log_tau))
            cells = rng.choice(len(log_tau), count, p=scipy.special.softmax(weights))
            tau2 = np.exp(2 * (log_tau[cells] + width * rng.uniform(-0.5, 0.5, (count, 2))))
        P, c, _, _, _ = self._posterior_of_beta(kind, slope, tau2)
        beta = _normal_draws(np.linalg.solve(P, c[..., None])[..., 0], P, rng)
        b = beta[:, -2:] if slope else np.zeros((count, 2))
        if kind == "independent":
            levels = beta[:, : 2 * len(self.groups)].reshape(count, -1, 2)
        elif kind == "pooled":
            levels = np.repeat(beta[:, None, :2], len(self.groups), axis=1)
        else:
            levels = self._group_levels(beta[:, :2], b, tau2, rng)
        z = np.zeros(len(self.units)) if self.covariates is None else self.covariates
        at_own = np.array([z[members].mean() for members in self._members])
        back = FROM_SCALE_RATIO.T  # row vectors of (scale, ratio) -> (log d_lat, log d_long)
        new_group = beta[:, :2] + np.sqrt(tau2) * rng.standard_normal((count, 2))
        return {
            "mu": None if kind == "independent" else beta[:, :2] @ back,
            "tau": np.sqrt(tau2) if kind == "hierarchical" else None,
            "new_group": new_group @ back if kind == "hierarchical" else None,
            "slope": b @ back if slope else None,
            "groups": (levels + at_own[None, :, None] * b[:, None, :]) @ back,
        }

    def _group_levels(
        self, mu: np.ndarray, b: np.ndarray, tau2: np.ndarray, rng: np.random.Generator
    ) -> np.ndarray:
        """a_g given (mu, b, tau): N(mu, T) times each unit's N(m_u - b z_u, S_u)."""
        z = np.zeros(len(self.units)) if self.covariates is None else self.covariates
        levels = []
        for members in self._members:
            precision = np.zeros((len(mu), 2, 2)) + _diagonal(1.0 / tau2)
            shift = mu / tau2
            for u in members:
                unit_precision = np.linalg.inv(self._covs[u])
                precision += unit_precision
                shift += (self._means[2 * u : 2 * u + 2] - z[u] * b) @ unit_precision
            mean = np.linalg.solve(precision, shift[..., None])[..., 0]
            levels.append(_normal_draws(mean, precision, rng))
        return np.stack(levels, axis=1)


def _diagonal(values: np.ndarray) -> np.ndarray:
    """(K, 2) -> (K, 2, 2) diagonal matrices."""
    return values[:, :, None] * np.eye(2)


def _normal_draws(mean: np.ndarray, precision: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """One draw per row of N(mean, precision^-1): mean + L^-T e, with precision = L L'."""
    lower = np.linalg.cholesky(precision)
    noise = rng.standard_normal(mean.shape)
    return mean + np.linalg.solve(np.swapaxes(lower, -1, -2), noise[..., None])[..., 0]
