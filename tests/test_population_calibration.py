"""Calibration of bj.population on simulated campaigns (issue 27's Must show).

The runs come from :func:`conftest.simulate_thesis_like`, this suite's own
simulator, not the package's: a steady circle at 72 Hz for 38 s, measured
vx, vy and yaw rate, process noise of width 5 ms (white at this rate, so
every unit is sampled with the white family, the fast one).

- **Calibration and shrinkage**: 3 floors x 5 runs, each floor's log
  damping drawn around the population mean log(110, 30) with sd 0.03 per
  damping, close to a floor's own posterior sd (0.023), where borrowing
  strength shows; each floor's runs pooled (noise shared within the floor).
  Over the seeds, each floor's 94 % HDI of the hierarchical model holds its
  truth, and the population mean's holds log(110, 30), within the binomial
  bound. Shrinkage: the floors' intervals are narrower than their fits
  alone on average, and their errors smaller on average. Not each floor's
  interval is narrower: an outlying floor's is up to 8 % wider, because how
  far it is pulled depends on the spread, which three floors leave
  uncertain (the law of total variance: Var E[a_g | tau] is added);
  ``test_population.py::test_stage_2_is_calibrated_and_shrinks_on_normal_units``
  measures these figures on stage 2 alone.
- **Evidence**: 3 floors of 3 runs. Equal floors are not split (no
  structure beats pooled by ln B > 3); floors 30 % apart are (hierarchical
  or independent beats pooled by ln B > 3).
- **Speed**: two floors, each driven at three speeds (0.2, 0.4 and 0.6 m/s),
  one run each, sampled alone (noise per run). A damping 50 % higher at the top speed is
  detected (slope HDI excludes 0, ln B > 3 over the best constant
  structure); a constant one is not flagged.

``BAYES_JACKAL_CALIBRATION_SEEDS`` sets the seeds of the calibration
(:data:`FULL_SEEDS` by default; CI runs 1).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from calibration import least_inside, map_rows, seeds
from conftest import simulate_thesis_like

import bayes_jackal as bj
from bayes_jackal.inference import FitOptions, SamplerSettings, population_posterior
from bayes_jackal.inference.executors import ProcessExecutor
from bayes_jackal.likelihood import LikelihoodOptions

pytestmark = pytest.mark.slow

#: Seeds of the full form of the calibration (the issue asks for 10 at least).
FULL_SEEDS = 10
#: Seeds from which the averages of the shrinkage are checked (CI's one seed has 3 floors).
MIN_SHRINKAGE_SEEDS = 5
#: The population mean (d_lat, d_long) [N s/m] and the spread of each log damping.
MEAN, SPREAD = np.array([110.0, 30.0]), 0.03
#: White process noise (a 5 ms kernel at 72 Hz) and sensor noise per channel.
NOISE = {
    "sigma_h": 0.005,
    "sigma_c": {"vx": 1e-3, "vy": 1e-3, "yaw": 5e-3},
    "sigma_n": {"vx": 1e-3, "vy": 1e-3, "yaw": 2e-3},
}
RUNS_PER_FLOOR = 5


def campaign(
    floors: dict[str, np.ndarray], rng: np.random.Generator, speeds=(0.3,), runs=RUNS_PER_FLOOR
) -> list:
    """``runs`` runs of each floor (its truth (d_lat, d_long), or a function of the speed),
    cycling through ``speeds``; group and speed in their provenance."""
    robot = bj.load_profile()
    campaign_runs = []
    for label, dampings in floors.items():
        for i in range(runs):
            speed = speeds[i % len(speeds)]
            d_lat, d_long = dampings(speed) if callable(dampings) else dampings
            run = simulate_thesis_like(
                robot,
                d_lat=d_lat,
                d_long=d_long,
                rng=rng,
                name=f"{label}_{i}",
                v=speed,
                w=0.75 * speed,
                **NOISE,
            )
            run.provenance.update(group=label, covariates={"speed": speed})
            campaign_runs.append(run)
    return campaign_runs


#: The chains stop at 12 autocorrelation times instead of 50: these units' tau is about
#: 100 steps, so 12 tau is 1200 steps, and the sampler's own floor of 400 effective draws
#: (32 walkers x 1250 steps / 100) still holds, in 4 times fewer steps.
SETTINGS = SamplerSettings(autocorr_multiple=12)


def _fit(runs: list, seed: int, noise: str = "shared") -> bj.inference.Population:
    with ProcessExecutor(2) as executor:
        options = FitOptions(
            likelihood_options=LikelihoodOptions(noise=noise), settings=SETTINGS, seed=seed
        )
        return population_posterior(runs, options, family="white", executor=executor)


def _inside(summary: dict, truth: float) -> bool:
    return summary["hdi_3%"] <= truth <= summary["hdi_97%"]


def _calibration_row(seed: int) -> dict:
    rng = np.random.default_rng([27, seed])
    floors = {
        label: MEAN * np.exp(SPREAD * rng.standard_normal(2))
        for label in ("tiles", "carpet", "lino")
    }
    result = _fit(campaign(floors, rng), seed)
    model = result.group_summaries()
    alone = result.group_summaries("independent")
    population = result.population_summary()
    row = {"floors": [], "mean": []}
    for label, truth in floors.items():
        for i, name in enumerate(("d_lat", "d_long")):
            hier, own = model[label][name], alone[label][name]
            row["floors"].append(
                {
                    "inside": _inside(hier, truth[i]),
                    # widths and errors on the log scale, where the spread lives
                    "width": math.log(hier["hdi_97%"] / hier["hdi_3%"]),
                    "width_alone": math.log(own["hdi_97%"] / own["hdi_3%"]),
                    "error": abs(math.log(hier["mean"] / truth[i])),
                    "error_alone": abs(math.log(own["mean"] / truth[i])),
                }
            )
    for i, name in enumerate(("d_lat", "d_long")):
        row["mean"].append(_inside(population[name]["mean"]["log"], math.log(MEAN[i])))
    return row


def test_hierarchical_posterior_is_calibrated_and_shrinks():
    rows = map_rows(_calibration_row, list(seeds(FULL_SEEDS)))
    floors = [floor for row in rows for floor in row["floors"]]
    # d_lat and d_long of one floor move together (their posteriors correlate at 0.99):
    # count the floors, not the pairs, as the independent cases of the binomial bound.
    cases = len(floors) // 2
    assert sum(f["inside"] for f in floors) / 2 >= least_inside(cases)
    means = [inside for row in rows for inside in row["mean"]]
    assert sum(means) / 2 >= least_inside(len(means) // 2)
    # Shrinkage (module text). No floor's interval more than 8 % wider than alone, plus 3 %
    # for the Monte Carlo error of two HDI widths from 4000 draws each (1.5 % each).
    ratios = [f["width"] / f["width_alone"] for f in floors]
    assert max(ratios) <= 1.11
    if len(rows) >= MIN_SHRINKAGE_SEEDS:
        # Stage 2 alone on this design (test_population.py): mean width ratio 0.89, mean
        # error ratio 0.84; the error ratio of 30 floors stayed below 0.99 in 40 batches
        # of 40.
        assert np.mean(ratios) < 1
        errors = np.mean([f["error"] for f in floors]) / np.mean(
            [f["error_alone"] for f in floors]
        )
        assert errors < 1


@pytest.mark.parametrize(
    ("apart", "split"), [(1.0, False), (1.3, True)], ids=["equal floors", "30 % apart"]
)
def test_evidence_splits_floors_that_differ_and_only_those(apart, split):
    rng = np.random.default_rng([27, 100, int(apart * 10)])
    floors = {label: MEAN * apart**k for k, label in enumerate(("tiles", "carpet", "lino"))}
    result = _fit(campaign(floors, rng, runs=3), 1)  # 3 runs a floor: the calibration has 5
    beaten = max(
        result.log_bayes_factor(name, "pooled")[0] for name in ("hierarchical", "independent")
    )
    assert (beaten > 3) is split, result.verdict()


def _speed_dependence(ratio: float) -> dict:
    rng = np.random.default_rng([27, 200, int(ratio * 10)])
    speeds = (0.2, 0.4, 0.6)
    # log d linear in the speed: ratio times the damping at 0.6 m/s as at 0.2 m/s
    floors = {
        label: (lambda v, k=k: k * MEAN * ratio ** ((v - 0.2) / 0.4))
        for label, k in (("tiles", 1.0), ("carpet", 1.15))
    }
    result = _fit(campaign(floors, rng, speeds, runs=len(speeds)), 1, noise="per-experiment")
    return result.to_dict()["speed_dependence"]


def test_a_true_speed_dependence_is_detected():
    dependence = _speed_dependence(1.5)
    assert dependence["detected"], dependence["verdict"]
    assert dependence["log_bayes_factor"] > 3
    for name in ("d_lat", "d_long"):
        slope = dependence["slope"][name]
        assert slope["log_per_unit"]["hdi_3%"] > 0
        assert _inside(slope["ratio_across_range"], 1.5)


def test_a_constant_damping_is_not_flagged():
    dependence = _speed_dependence(1.0)
    assert not dependence["detected"], dependence["verdict"]
    assert dependence["log_bayes_factor"] < 3
