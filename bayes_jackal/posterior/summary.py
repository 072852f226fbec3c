"""The summary of a posterior: arviz's table of each parameter, convergence and criticism.

What ``sample --json`` prints and the report tabulates (docs/design.md §6).
"""

from __future__ import annotations

import numpy as np

from .._runtime import az
from .criticism import criticise
from .posterior import Posterior

__all__ = ["INTERVAL_FIELDS", "THESIS_RATIO", "Summary", "interval", "summarize"]


#: The thesis' ridge ratio d_lat / d_long (ch. 5-2-2).
THESIS_RATIO = 11.0 / 3.0


_SUMMARY_FIELDS = ("mean", "sd", "hdi_3%", "hdi_97%", "ess_bulk", "ess_tail", "r_hat")


#: The fields of a summary row that describe the posterior itself.
INTERVAL_FIELDS = _SUMMARY_FIELDS[:4]


class Summary(dict):
    """The JSON of a posterior's summary (a dict), printed (``str``) as a table.

    Each parameter's row (and the ratio's) is a dict of arviz's fields;
    ``to_dict()`` is the plain dict ``sample --json`` prints.

    Examples
    --------
    >>> from bayes_jackal.posterior import Summary
    >>> row = {"mean": 110.2, "sd": 4.1, "hdi_3%": 102.6, "hdi_97%": 117.9, "ess_autocorr": 812.0}
    >>> print(Summary(family="white", n_steps=4000, converged=True, d_lat=row))
    white posterior, 4000 steps, converged
                           mean         sd     hdi_3%    hdi_97%  ess_autocorr
    d_lat                 110.2        4.1      102.6      117.9           812
    """

    _COLUMNS = (*INTERVAL_FIELDS, "ess_autocorr")

    def to_dict(self) -> dict:
        return dict(self)

    def __str__(self) -> str:
        state = "converged" if self.get("converged") else "NOT CONVERGED"
        lines = [f"{self.get('family')} posterior, {self.get('n_steps')} steps, {state}"]
        lines.append(f"{'':16s}" + "".join(f"{column:>11s}" for column in self._COLUMNS[:4])
                     + f"{self._COLUMNS[4]:>14s}")  # fmt: skip
        for name, row in self.items():
            if isinstance(row, dict) and "mean" in row:
                cells = "".join(f"{row.get(c, float('nan')):11.4g}" for c in self._COLUMNS[:4])
                lines.append(f"{name:16s}{cells}{row.get('ess_autocorr', float('nan')):14.0f}")
        return "\n".join(lines)


def interval(row: dict) -> dict:
    """Mean, sd and 94 % HDI of a :func:`summarize` row.

    Examples
    --------
    The ratio d_lat / d_long, which the yaw rate alone identifies (truth
    110 / 30 = 3.67). The 20-step chain is short on purpose:

    >>> import bayes_jackal as bj
    >>> from bayes_jackal.posterior import interval
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1)
    >>> posterior = bj.sample([run], family="white", channels=["yaw"], max_steps=20, seed=1)
    >>> row = interval(bj.summarize(posterior)["ratio"])
    >>> sorted(row), row["hdi_3%"] < 110 / 30 < row["hdi_97%"]
    (['hdi_3%', 'hdi_97%', 'mean', 'sd'], True)
    """
    return {key: row[key] for key in INTERVAL_FIELDS}


def summarize(idata: az.InferenceData) -> Summary:
    """JSON-ready summary of a posterior (docs/design.md §6 ``sample --json``), printed as a table.

    One key per parameter and for the derived ``ratio``, each with arviz's
    ``mean``, ``sd``, ``hdi_3%``, ``hdi_97%``, ``ess_bulk``, ``ess_tail``,
    ``r_hat`` (walkers as chains: a secondary check only) and
    ``ess_autocorr``, the ESS implied by the integrated autocorrelation time
    (the primary one for emcee); plus ``corr_d_lat_d_long``,
    ``autocorr_time``, ``n_steps``, ``converged``, and under ``ratio`` the
    thesis' 3 2/3. ``warnings`` lists the model-criticism warnings (dicts
    with ``kind`` and ``message``) and ``criticism`` their numbers
    (:func:`bayes_jackal.posterior.criticise`).

    Examples
    --------
    The summary of a white-noise fit to one run's yaw rate. The 20-step chain
    is short on purpose:

    >>> import bayes_jackal as bj
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1)
    >>> posterior = bj.sample([run], family="white", channels=["yaw"], max_steps=20, seed=1)
    >>> summary = bj.summarize(posterior)
    >>> summary["family"], summary["n_steps"], summary["converged"]
    ('white', 20, False)
    >>> round(summary["ratio"]["mean"], 1), round(summary["ratio"]["thesis"], 2)
    (3.6, 3.67)

    The criticism warns: yaw alone does not identify the damping's scale, and
    the residuals are coloured (the simulated noise is Gaussian-filtered):

    >>> sorted({warning["kind"] for warning in summary["warnings"]})
    ['damping-scale-not-identified', 'predictive-acf', 'prior-boundary']
    """
    fitted = Posterior.of(idata)
    metadata = fitted.metadata
    convergence = metadata.convergence
    summary = Summary()
    for label, row in fitted.table(round_to="none").iterrows():
        summary[label] = {key: float(row[key]) for key in _SUMMARY_FIELDS}
        if label in convergence.ess_autocorr:
            summary[label]["ess_autocorr"] = convergence.ess_autocorr[label]
    posterior = idata.posterior
    d_lat, d_long = posterior["d_lat"].values.ravel(), posterior["d_long"].values.ravel()
    summary["ratio"]["thesis"] = THESIS_RATIO
    summary["corr_d_lat_d_long"] = float(np.corrcoef(d_lat, d_long)[0, 1])
    summary["autocorr_time"] = convergence.autocorr_time
    summary["n_steps"] = convergence.n_steps
    summary["converged"] = convergence.converged
    summary["family"] = metadata.family
    summary["channels"] = list(metadata.channels)
    summary.update(criticise(idata))
    return summary
