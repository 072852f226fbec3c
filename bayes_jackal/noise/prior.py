"""The DEM prior of a sensor's noise series, from its characterisation (issue 15).

A DEM (Active Inference) filter of a sensor y = g(x) + z needs the
precision of the sensor noise z in generalised coordinates
(z, z', ..., z^(P)). :func:`bayes_jackal.characterise_noise` models a
series as z = c + n: coloured noise c of one family (sd sigma_c,
autocorrelation rho of width w) and a white floor n (sd sigma_n). For the
coloured part, as for the robot's process noise (:mod:`bayes_jackal.dem.export`),

    cov(c^(i), c^(j)) = sigma_c^2 V[i, j],   V[i, j] = (-1)^i rho^(i+j)(0)
                                              (zero when i + j is odd),

    Pi    = E[inv(V) / sigma_c^2]          (``precision``),
    Pi_mc = inv(E[sigma_c^2 V])            (``precision_mean_covariance``),

with E the mean over the posterior draws; rho is the continuous-time
autocorrelation whose samples are the sampled kernel's (exactly so as
dt -> 0). V exists up to the order P at which rho has 2P derivatives at 0:
every order for ``gaussian`` (bounded by Pi's condition number in seconds
and in bins, :data:`~bayes_jackal.dem.MAX_CONDITION`), 1 for
``triangular``, 0 for ``exponential``, ``moving-average`` and ``white``.

**No continuous-time conversion.** sigma_c is already the sd of the sampled
stationary noise: the sd of c(t) at any t, in series units. The robot's
process noise is different: its sigma_c is the sd of an increment per step,
which :func:`~bayes_jackal.dem.export_prior` turns into the sd of a rate
(s_c = sigma_c a / (alpha - 1)); nothing of the kind applies here.

**Time bins.** DEM codes count time in samples, k = t / dt. Derivative i
in bins is dt^i times the one in seconds, so

    V_bins[i, j]  = dt^(i+j) V[i, j]     (V at the width w / dt),
    Pi_bins[i, j] = Pi[i, j] / dt^(i+j),

and sigma_c is unchanged: the noise is not a rate (the process noise's sd
in bins is dt s_c). For the Gaussian family inv(V_bins) is SPM's
``spm_DEM_R(P + 1, sigma_h / dt)``.

**The white floor** has no derivatives. Its precision E[1/sigma_n^2] is
the part a DEM user adds to Pi_z at order 0 (SPM gives it a small
smoothness, 0.5 bins: :mod:`bayes_jackal.dem.consumer_keys`) or treats as
white. The ``white`` family has one sd, ``sigma``: all of the noise, so
``sigma_c_is`` is ``"total"``, the order 0, there is no floor, and
``log_precision.coloured`` holds the moments of log(1 / sigma^2).

The file's schema is ``bayes_jackal.noise_prior/1`` (docs/active_inference.md,
"A sensor's noise series"); :func:`~bayes_jackal.dem.write_prior` writes it.
"""

from __future__ import annotations

import numpy as np

from .. import __version__
from .._runtime import InputError, thinned_indices
from ..dem import (
    MAX_DRAWS,
    channel_moments,
    checked_precision,
    gaussian_smoothness,
    generalised_precision,
    log_precision_moments,
    mean_covariance_precision,
    temporal_covariance,
)
from ..likelihood import WHITE_SD
from ..model import get_family
from .characterisation import FamilyFit, NoiseCharacterisation

__all__ = ["NOISE_PRIOR_FORMAT", "export_noise_prior"]

NOISE_PRIOR_FORMAT = "bayes_jackal.noise_prior/1"


def _noise_draws(fit: FamilyFit) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """(width [s], sigma_c, sigma_n) per draw; white: (1, sigma, None)."""
    column = dict(zip(fit.names, fit.draws.T, strict=True))
    width_name = get_family(fit.family).width_name
    if width_name is None:
        return np.ones(len(fit.draws)), column[WHITE_SD], None
    return column[width_name], column["sigma_c"], column["sigma_n"]


def _moments(values: np.ndarray) -> dict:
    """Mean and sd over the draws of one quantity."""
    return channel_moments(values[:, None], ["value"])["value"]


def _log_precision(sd: np.ndarray) -> dict:
    """Mean and variance over the draws of log(1 / sd^2) (SPM's ``hE``, ``hC``)."""
    moments = log_precision_moments(sd[:, None])
    return {"mean": moments["mean"][0], "variance": moments["variance"][0]}


def _coordinates(
    family: str,
    width: np.ndarray,
    sigma_c: np.ndarray,
    dt: float,
    order: int | None,
    source: str | None,
) -> dict:
    """V, inv(V) and Pi of the coloured part, in seconds and in bins (module docstring)."""
    sd = sigma_c[:, None]  # (draws, 1): one channel
    order, V, S = checked_precision(family, width[:, None], sd, order, dt=dt, source=source)
    V_bins = temporal_covariance(family, width[:, None] / dt, order)
    S_bins = np.linalg.inv(V_bins)
    precision = generalised_precision(S, sd)
    precision_bins = generalised_precision(S_bins, sd)
    return {
        "order": order,
        "layout": "row i is derivative i of the noise of sd sigma_c, i = 0 .. order",
        "temporal_covariance": V.mean(axis=0)[0].tolist(),
        "temporal_precision": S.mean(axis=0)[0].tolist(),
        "precision": precision.tolist(),
        "precision_mean_covariance": mean_covariance_precision(V, sd).tolist(),
        "condition": float(np.linalg.cond(precision)),
        "temporal_covariance_bins": V_bins.mean(axis=0)[0].tolist(),
        "temporal_precision_bins": S_bins.mean(axis=0)[0].tolist(),
        "precision_bins": precision_bins.tolist(),
        "precision_mean_covariance_bins": mean_covariance_precision(V_bins, sd).tolist(),
        "condition_bins": float(np.linalg.cond(precision_bins)),
    }


def _white_floor(sigma_c: np.ndarray, sigma_n: np.ndarray | None) -> dict | None:
    """The white floor's sd, precision 1 / sigma_n^2 and share of the variance."""
    if sigma_n is None:
        return None
    return {
        "sd": _moments(sigma_n),
        "precision": _moments(1.0 / sigma_n**2),
        "variance_fraction": _moments(sigma_n**2 / (sigma_c**2 + sigma_n**2)),
    }


def _smoothness(family: str, width: np.ndarray, dt: float) -> dict | None:
    """The Gaussian smoothness in seconds and bins; None for noise without a derivative."""
    s = gaussian_smoothness(family, width)
    return None if s is None else {"seconds": _moments(s), "bins": _moments(s / dt)}


def export_noise_prior(
    result: NoiseCharacterisation,
    *,
    family: str | None = None,
    order: int | None = None,
    source: str | None = None,
) -> dict:
    """The DEM prior of a characterised noise series, as a JSON-ready dict.

    Parameters
    ----------
    result : NoiseCharacterisation
        From :func:`bayes_jackal.characterise_noise`.
    family : str, optional
        One of ``result.fits``; by default the best by evidence (``result.best``).
    order : int or None
        Embedding order P (P + 1 generalised coordinates). None (the
        default, as ``noise --order``): :data:`~bayes_jackal._runtime.defaults.AUTO_ORDER`
        (2), or the highest order the family allows at these draws if lower
        (:func:`~bayes_jackal.dem.allowed_orders`: 0 for white noise).
    source : str, optional
        Where the series was read from (written into the prior and named in errors).

    Returns
    -------
    dict
        Schema ``bayes_jackal.noise_prior/1`` (module docstring): ``format``,
        ``bayes_jackal_version``, ``source``, ``series`` (name, source,
        samples), ``dt`` [s], ``family``, ``best``, ``verdict``,
        ``converged``, ``fit`` (the family's entry of ``noise --json``: log
        evidence, ln B against white, the width in seconds and bins, the
        parameters' moments, warnings), ``sigma_c_is``,
        ``generalised_coordinates`` (V, inv(V), Pi and Pi_mc in seconds and
        bins), ``white_floor``, ``smoothness``, ``log_precision`` and the
        thinned ``draws``.

    Raises
    ------
    InputError
        For a family without a fit, or an order the family cannot give (its
        noise has too few derivatives, or the precision's condition number in
        seconds or in bins is above :data:`~bayes_jackal.dem.MAX_CONDITION`),
        naming ``order`` and the allowed orders.

    Examples
    --------
    A Gaussian fit of width 3 bins, from draws made up here (no sampling). In
    bins the derivative's variance is -rho''(0) = 1 / (2 * 3^2), and the
    smoothness is the width:

    >>> import numpy as np
    >>> from bayes_jackal.posterior import Evidence
    >>> from bayes_jackal.noise import FamilyFit, NoiseCharacterisation
    >>> from bayes_jackal.noise import export_noise_prior
    >>> from bayes_jackal.noise import NoiseSeries
    >>> rng = np.random.default_rng(0)
    >>> draws = np.column_stack([np.full(50, 0.03), rng.uniform(0.9, 1.1, 50), np.full(50, 0.3)])
    >>> fit = FamilyFit(family="gaussian", names=("sigma_h", "sigma_c", "sigma_n"), draws=draws,
    ...                 evidence=Evidence(-950.0, 0.1, "bridge sampling"),
    ...                 diagnostics={"converged": True}, warnings=[], dt=0.01)
    >>> series = NoiseSeries(values=rng.standard_normal(100), dt=0.01, name="gyro")
    >>> result = NoiseCharacterisation(series=series, fits={"gaussian": fit},
    ...                                acf_least_squares={}, thesis_fit=0.03)
    >>> prior = export_noise_prior(result, order=1)
    >>> prior["format"], prior["family"], prior["generalised_coordinates"]["order"]
    ('bayes_jackal.noise_prior/1', 'gaussian', 1)
    >>> V_bins = prior["generalised_coordinates"]["temporal_covariance_bins"]
    >>> bool(np.allclose(V_bins, [[1.0, 0.0], [0.0, 1 / 18]]))
    True
    >>> round(prior["white_floor"]["precision"]["mean"], 6), prior["smoothness"]["bins"]["mean"]
    (11.111111, 3.0)
    >>> try:
    ...     export_noise_prior(result, order=3, family="white")
    ... except ValueError as error:
    ...     print(error)
    family: no 'white' fit in this characterisation; it has ['gaussian']
    """
    family = result.best if family is None else family
    if family not in result.fits:
        raise InputError(
            f"no {family!r} fit in this characterisation; it has {list(result.fits)}",
            source=source,
            field="family",
        )
    fit, series = result.fits[family], result.series
    width, sigma_c, sigma_n = _noise_draws(fit)
    summary = result.to_dict()
    kept = thinned_indices(len(fit.draws), MAX_DRAWS)
    return {
        "format": NOISE_PRIOR_FORMAT,
        "bayes_jackal_version": __version__,
        "source": source,
        "series": {
            "name": series.name,
            "source": series.source,
            "samples": len(series.values),
        },
        "dt": fit.dt,
        "family": family,
        "best": summary["best"],
        "verdict": summary["verdict"],
        "converged": bool(fit.diagnostics["converged"]),
        "fit": summary["families"][family],
        "sigma_c_is": "total" if sigma_n is None else "coloured",
        "generalised_coordinates": _coordinates(family, width, sigma_c, fit.dt, order, source),
        "white_floor": _white_floor(sigma_c, sigma_n),
        "smoothness": _smoothness(family, width, fit.dt),
        "log_precision": {
            "coloured": _log_precision(sigma_c),
            "white_floor": None if sigma_n is None else _log_precision(sigma_n),
        },
        "draws": {
            "count": len(kept),
            **{
                name: column[kept].tolist()
                for name, column in zip(fit.names, fit.draws.T, strict=True)
            },
        },
    }
