"""Calibration of the default posterior on motion-capture bags (issue 23's Must show).

Bags simulated by tests/mocap_simulator.py, written independently of the
package's simulator, bag writer and model code: the linear model driven by
a continuous coloured force, an IMU at 72 Hz, motion capture on its own
clock with white pose noise, wheel encoders at 50 Hz, stamps jittered,
poses duplicated and dropped. Each case is a v1 and a v2 run of one truth,
read with ``read_bag`` and sampled pooled with ``bj.sample``'s defaults (the
channels yaw, vx, vy; the Gaussian family). d_lat, d_long, their ratio,
every channel's sigma_h and the pose noise sigma_p of vx and vy must hold
their truth in the 94 % HDI within the binomial tolerance over seeds: per configuration
and pooled over them, against the 0.1 % quantile of Binomial(N, 0.94)
(tests/calibration.py).

The configurations: pose noise 0.1 and 1 mm, motion capture at 120 and
360 Hz, truths (d_lat, d_long, sigma_h) = (110, 30, 0.047) and (300, 60,
0.1), 10 seeds each (``BAYES_JACKAL_CALIBRATION_SEEDS``; the full form,
run by hand, takes about 4.5 h of one core,
``BAYES_JACKAL_CALIBRATION_PROCESSES=2`` halves it). With one seed (CI) only
:data:`CI_CONFIGS` run, and each parameter's truth must lie in its central
99.9 % interval (a calibrated posterior misses it once in a thousand; one
seed's 94 % HDI misses a truth in 6 % of cases, too often to assert on 7
intervals).

Under the stiff truth the runs do not identify the damping's scale, and no
posterior can hold a fixed truth there at the nominal rate. The poles (time
constants of 14-69 ms) are fast against the noise's 0.1 s width, the states follow
the noise quasi-statically, and the profile log-posterior of d_lat (every
other parameter at its best) changes by only 3-6 nats between 300 and
1000 N s/m on three pairs, rising towards 1000 on one; runs five times as
long leave it within 3 nats. Under the thesis truth it falls by 21 nats over
the same factor from 110. Where on that plateau the truth lies is then
the prior's to say. So for the stiff truth the parameters on the ridge
(:data:`RIDGE`: d_lat, d_long, and sigma_h[vx], which moves along it by more
than its HDI's half-width) are recorded, not asserted. The ratio d_lat /
d_long and the other parameters are asserted as for the thesis truth, and
the posterior must say that the scale is not identified
(``damping-scale-not-identified``, or ``prior-boundary`` on the damping) in
at least 90 % of the stiff truth's rows and at most 10 % of the thesis
truth's (:data:`SCALE_WARNED`). At the truth the likelihood is right: over
200 pairs of each thesis configuration with 1 mm noise, the score's mean
moves the maximum-likelihood log d_lat by -0.02 to -0.03 (0.13-0.22 of its
sd; first order).

Measured in the full form (80 rows, 3.5 h of row time, 2026-11-27): the
thesis truth held d_lat 35/40 (1 mm at 120 Hz: 6/10, the bound), d_long
36/40, every other parameter 35-37/40; the stiff truth held the ratio
37/40, sigma_h[yaw] 35/40, sigma_h[vy] 36/40, sigma_p 37-38/40, and warned
in 38/40 rows (the thesis truth in none); d_lat held 300 in 30/40. NIS in
its band: yaw 77/80, vx 75/80, vy 79/80 (all three at once 71/80); the
smoother beat the derived velocities in 160/160 (RMSE ratio 0.23-0.77).

``BAYES_JACKAL_POSE_BASELINE=1`` also samples each case with the
poses dropped, vx and vy then the reader's derived velocities under the rate
model, as before issue 23, and prints its rows (not asserted: it fails).

The same cases test the prior on a run it has not seen: a third run (v1's
command, its own seed) is filtered with the posterior's exported prior.
``kalman-coloured``'s NIS must lie in its 95 % band on every channel in at
least 90 % of the runs (the issue's bar), channel by channel: with the true
parameters each channel's NIS is in its chi-square band with probability
0.95, all three at once only 0.86 (measured at the truth over 20 left-out
runs: 93 % of channels, 80 % of runs). The band allows for the identified
parameters' uncertainty (:func:`bayes_jackal.filters.nis_band`):
two runs leave sigma_c and sigma_p a few percent uncertain, which moves the
NIS of a 38 s run by a log-sd of ~0.02 against the chi-square band's 0.027
(measured over 8 posterior draws); the chi-square band alone held vx in
14 of 20 runs. The Kalman smoother's vx and vy must be closer to the true
velocities than the reader's Savitzky-Golay ones in every run (both are
centred smoothers; measured: ~1.5x closer).
"""

from __future__ import annotations

import dataclasses
import os
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np
import pytest
from calibration import least_inside, map_rows, seeds
from mocap_simulator import POSE_JITTER, THESIS_COMMANDS, write_mocap_bag, write_mocap_pair

import bayes_jackal as bj
from bayes_jackal.filters.state_estimation import DERIVED
from bayes_jackal.io.bags import read_bag

ROBOT = bj.load_profile()
#: (d_lat [N s/m], d_long [N s/m], sigma_h [s]) of each truth.
TRUTHS = {"thesis": (110.0, 30.0, 0.047), "stiff": (300.0, 60.0, 0.1)}
#: The parameters each truth's runs leave to the prior, recorded but not
#: asserted (module docstring): under the stiff truth steady circles fix the
#: ratio d_lat / d_long and a lower bound on the damping, not its scale, and
#: sigma_h[vx] moves along that ridge by more than its HDI's half-width.
RIDGE = {"thesis": (), "stiff": ("d_lat", "d_long", "sigma_h[vx]")}
#: The most of the thesis truth's rows that may warn that the damping scale is
#: not identified, and the least of the stiff truth's that must.
SCALE_WARNED = {"thesis": (0.0, 0.1), "stiff": (0.9, 1.0)}
#: (truth, pose noise sd [m], motion-capture rate [Hz]).
CONFIGS = [
    (truth, pose_sd, rate)
    for truth in TRUTHS
    for pose_sd in (1e-4, 1e-3)
    for rate in (120.0, 360.0)
]
#: The reduced form's configuration: the thesis' robot under a lab's usual
#: motion capture (CI: ~80 s of one core; the stiff truth's cases take twice that).
CI_CONFIGS = [("thesis", 1e-4, 360.0)]
#: Seeds per configuration of the full form (issue 23: at least 10).
FULL_SEEDS = 10
#: The central interval of the reduced form.
WIDE = 0.999
#: The share of left-out runs whose kalman-coloured NIS must be consistent, per channel.
NIS_RUNS = 0.9
CHANNELS = ("yaw", "vx", "vy")


def truth_by_name(truth: str, pose_sd: float) -> dict[str, float]:
    """The parameters checked and their true values.

    The motion capture's stamps are jittered (POSE_JITTER, the driver's):
    a pose stamped tau late lies v tau along the path from where its stamp
    says, so along the direction of motion the poses carry that too. The
    longitudinal channel's pose noise is sqrt(sd^2 + POSE_JITTER^2 v^2),
    v^2 the mean square of the runs' speeds (1.5 % above sd at 0.1 mm, 0.01 %
    at 1 mm); the lateral one's is sd (vy ~ 0).
    """
    d_lat, d_long, sigma_h = TRUTHS[truth]
    speed = np.mean([v**2 for v, _, _ in THESIS_COMMANDS.values()])
    return {
        "d_lat": d_lat,
        "d_long": d_long,
        "ratio": d_lat / d_long,
        **{f"sigma_h[{c}]": sigma_h for c in CHANNELS},
        "sigma_p[vx]": float(np.sqrt(pose_sd**2 + POSE_JITTER**2 * speed)),
        "sigma_p[vy]": pose_sd,
    }


def calibration_row(case: tuple[str, float, float, int, bool]) -> dict:
    """One pair of bags of ``case`` = (truth, pose sd, rate, seed, derived), sampled.

    ``derived``: the poses dropped (the model before issue 23). Returns, per
    parameter, the 94 % HDI, the central 99.9 % interval and the hits; the
    row is printed as it comes.
    """
    truth, pose_sd, rate, seed, derived = case
    # Each configuration's data have seeds of their own: rows of one seed
    # are independent across configurations, as the pooled bound assumes.
    configuration = CONFIGS.index((truth, pose_sd, rate))
    d_lat, d_long, sigma_h = TRUTHS[truth]
    start = time.perf_counter()
    options = {"d_lat": d_lat, "d_long": d_long, "sigma_h": sigma_h, "pose_sd": pose_sd,
               "pose_rate": rate}  # fmt: skip
    with tempfile.TemporaryDirectory() as folder:
        runs = write_mocap_pair(folder, seed=[1000 + seed, configuration], **options)
        experiments = [read_bag(run.path, ROBOT) for run in runs]
        left_out = _left_out(Path(folder) / "left_out.bag", [5000 + seed, configuration], options)
    if derived:
        experiments, left_out = [dataclasses.replace(e, pose=None) for e in experiments], None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # the baseline piles at bounds
        posterior = bj.sample(experiments, seed=seed)
    summary = bj.summarize(posterior)
    draws = posterior.posterior
    tail = (1 - WIDE) / 2
    rows = {}
    for name, value in truth_by_name(truth, pose_sd).items():
        if name not in summary:  # the baseline has sigma_n for vx, vy
            continue
        wide = np.quantile(_draws(draws, name), [tail, 1 - tail])
        hdi = (summary[name]["hdi_3%"], summary[name]["hdi_97%"])
        rows[name] = {
            "truth": value,
            "hdi": hdi,
            "hit": bool(hdi[0] <= value <= hdi[1]),
            "wide": bool(wide[0] <= value <= wide[1]),
            "mean": summary[name]["mean"],
        }
    row = {
        "case": (truth, pose_sd, rate),
        "seed": seed,
        "model": "derived" if derived else "poses",
        "parameters": rows,
        "steps": summary["n_steps"],
        "warnings": sorted({w["kind"] for w in summary["warnings"]}),
        "scale_warned": any(
            w["kind"] == "damping-scale-not-identified"
            or (w["kind"] == "prior-boundary" and w["parameter"] in ("d_lat", "d_long"))
            for w in summary["warnings"]
        ),
        "prior_shift": summary["criticism"]["damping_scale"]["prior_shift"],
        "estimation": None if left_out is None else _estimation(posterior, left_out),
        "seconds": time.perf_counter() - start,
    }
    missed = [f"{n} [{r['hdi'][0]:.4g}, {r['hdi'][1]:.4g}]" for n, r in rows.items()
              if not r["hit"]]  # fmt: skip
    estimation = row["estimation"]
    filtered = "" if estimation is None else (
        " NIS " + " ".join(f"{v:.3f}" for v in estimation["nis"].values())
        + " smoothed/derived " + " ".join(
            f"{estimation['smoothed'][c] / estimation['derived'][c]:.2f}" for c in ("vx", "vy"))
    )  # fmt: skip
    print(f"{truth:6} {pose_sd:7.1e} {rate:5.0f} {seed:2d} {row['model']:7} "
          f"{sum(r['hit'] for r in rows.values())}/{len(rows)} hits {row['steps']:5d} steps "
          f"{row['seconds']:5.0f} s{filtered} prior shift {row['prior_shift']['d_lat']:.2f}"
          f"  missed: {', '.join(missed) or '-'}"
          f"  warnings: {', '.join(row['warnings']) or '-'}", flush=True)  # fmt: skip
    return row


def _draws(draws, name: str) -> np.ndarray:
    """The flat draws of a parameter named as in the summary (``ratio``: d_lat / d_long)."""
    if name == "ratio":
        return (draws["d_lat"] / draws["d_long"]).values.ravel()
    base, _, group = name.partition("[")
    variable = draws[base]
    if group:
        variable = variable.sel({variable.dims[-1]: group.rstrip("]")})
    return variable.values.ravel()


def _left_out(path: Path, seed: list[int], options: dict) -> bj.Experiment:
    """A v1 run of its own seed, read back, with the true states on its samples."""
    v, w, duration = THESIS_COMMANDS["v1"]
    rng = np.random.default_rng(seed)
    run = write_mocap_bag(path, v=v, w=w, duration=duration, rng=rng, **options)
    experiment = read_bag(run.path, ROBOT)
    states = {f"{c}_state": np.interp(experiment.t, run.imu_t, run.states[:, i])
              for i, c in enumerate(("vx", "vy", "yaw"))}  # fmt: skip
    return dataclasses.replace(experiment, truth_arrays=states)


def _estimation(posterior, experiment: bj.Experiment) -> dict:
    """kalman-coloured's NIS verdict per channel and the smoothed and derived vx, vy RMSEs."""
    prior = bj.export_prior(posterior)
    scores = bj.score_estimates(experiment, bj.estimate_states(experiment, prior))
    coloured = scores["kalman-coloured"]
    return {
        "nis": {c: coloured["nis"][c]["mean"] for c in CHANNELS},
        "consistent": {c: coloured["nis"][c]["consistent"] for c in CHANNELS},
        "band": {c: coloured["nis"][c]["band"] for c in CHANNELS},
        "smoothed": {c: coloured["smoothed_state_rmse"][c] for c in ("vx", "vy")},
        "derived": scores[DERIVED]["smoothed_state_rmse"],
    }


def calibration_failures(rows: list[dict]) -> list[tuple]:
    """The Must show's checks over the pose model's rows: empty when all hold."""
    rows = [row for row in rows if row["model"] == "poses"]
    failures = [
        ("the smoother is not closer than the derived velocity", row["case"], row["seed"], c)
        for row in rows
        for c in ("vx", "vy")
        if not row["estimation"]["smoothed"][c] < row["estimation"]["derived"][c]
    ]
    for c in CHANNELS:
        consistent = sum(row["estimation"]["consistent"][c] for row in rows)
        if consistent < NIS_RUNS * len(rows):
            failures.append(("kalman-coloured's NIS out of its band", c, consistent, len(rows)))
    for truth, (least, most) in SCALE_WARNED.items():
        warned = [row["scale_warned"] for row in rows if row["case"][0] == truth]
        if warned and not least <= np.mean(warned) <= most:
            failures.append(("damping-scale warnings", truth, sum(warned), len(warned)))
    if len({row["seed"] for row in rows}) == 1:  # the reduced form
        return failures + [
            ("truth outside the 99.9 % interval", row["case"], name, result["hdi"])
            for row in rows
            for name, result in row["parameters"].items()
            if not result["wide"] and name not in RIDGE[row["case"][0]]
        ]
    hits: dict[tuple, list[bool]] = {}
    for row in rows:
        for name, result in row["parameters"].items():
            if name not in RIDGE[row["case"][0]]:
                hits.setdefault((row["case"], name), []).append(result["hit"])
    failures += [
        ("HDI misses the truth", case, name, sum(found), len(found))
        for (case, name), found in hits.items()
        if sum(found) < least_inside(len(found))
    ]
    for name in {name for _, name in hits}:
        pooled = [hit for (_, other), found in hits.items() if other == name for hit in found]
        if sum(pooled) < least_inside(len(pooled)):
            failures.append(("HDIs pooled miss the truth", name, sum(pooled), len(pooled)))
    return failures


@pytest.mark.slow
@pytest.mark.xdist_group("pose_calibration")
def test_the_default_posterior_on_motion_capture_bags_holds_the_truth():
    """The module docstring's check; measured numbers in the closing note of issue 23."""
    configs = CI_CONFIGS if len(seeds(FULL_SEEDS)) == 1 else CONFIGS
    baseline = os.environ.get("BAYES_JACKAL_POSE_BASELINE") == "1"
    models = (False, True) if baseline else (False,)
    work = [(*config, seed, derived) for config in configs for seed in seeds(FULL_SEEDS)
            for derived in models]  # fmt: skip
    rows = map_rows(calibration_row, work)
    failures = calibration_failures(rows)
    assert not failures, failures
