"""Default flags on runs the package did not generate: every channel, every truth held.

The runs come from the independent thesis-like simulator of tests/conftest.py
(its own eq. 4-32 discretisation, eq. 7-5 filter and wheel-speed ripple),
written to CSV and read back by ``bayes-jackal sample`` as a user's log
would be. Without ``--channels`` the command uses yaw, vx and vy, which
identify the damping's scale; yaw alone identifies only d_lat / d_long.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.stats

from bayes_jackal import load_profile
from bayes_jackal.cli import main
from bayes_jackal.io.tables import write_csv
from bayes_jackal.posterior.posterior import load_posterior
from bayes_jackal.posterior.summary import summarize

ROBOT = load_profile()
#: (d_lat [N s/m], d_long [N s/m], sigma_h [s]) of the issue: the thesis'
#: values and a stiffer, smoother robot.
TRUTHS = {"thesis": (110.0, 30.0, 0.047), "stiff": (300.0, 60.0, 0.1)}
#: Process-noise sd per step and sensor-noise sd (m/s for vx, vy; rad/s for yaw).
SIGMA_C = {"vx": 0.005, "vy": 0.005, "yaw": 0.02}
SIGMA_N = {"vx": 0.003, "vy": 0.003, "yaw": 0.004}
#: Chains capped at 600 steps (15-25 autocorrelation times of walkers started
#: from the Laplace approximation at the MAP): 40-60 s for three channels on
#: one idle core, short of the 50 tau of convergence, so the run warns.
QUICK = ["--max-steps", "600", "--seed", "1", "--no-progress"]


@pytest.fixture(scope="module")
def posteriors(thesis_like_simulator, tmp_path_factory) -> dict[str, dict]:
    """Per truth: the run's truth and the summaries of ``sample`` by default and yaw alone."""
    folder = tmp_path_factory.mktemp("real")
    results = {}
    for seed, (label, (d_lat, d_long, sigma_h)) in enumerate(TRUTHS.items(), start=11):
        run = thesis_like_simulator(
            ROBOT,
            d_lat=d_lat,
            d_long=d_long,
            sigma_h=sigma_h,
            sigma_c=SIGMA_C,
            sigma_n=SIGMA_N,
            rng=np.random.default_rng(seed),
            name=label,
        )
        path = write_csv(run, folder / f"{label}.csv")
        results[label] = {"truth": run.truth}
        for mode, extra in (("default", []), ("yaw", ["--channels", "yaw"])):
            out = folder / f"{label}.{mode}.nc"
            assert main(["sample", str(path), "--out", str(out), *QUICK, *extra]) == 0
            results[label][mode] = summarize(load_posterior(out))
    return results


def _truth_of(label: str, truth: dict) -> float:
    """The true value of a summary row such as ``d_lat`` or ``sigma_c[vx]``."""
    base, _, channel = label.rstrip("]").partition("[")
    value = truth[base]
    return value[channel or "yaw"] if isinstance(value, dict) else value


@pytest.mark.slow
@pytest.mark.xdist_group("real")
def test_default_hdis_hold_every_truth_within_the_binomial_tolerance(posteriors):
    misses, count = [], 0
    for label, result in posteriors.items():
        summary = result["default"]
        assert summary["channels"] == ["yaw", "vx", "vy"]
        for name in summary["autocorr_time"]:  # every sampled parameter
            count += 1
            value, row = _truth_of(name, result["truth"]), summary[name]
            if not row["hdi_3%"] <= value <= row["hdi_97%"]:
                misses.append((label, name, value, row["hdi_3%"], row["hdi_97%"]))
    # A calibrated 94 % HDI misses its truth with probability 0.06. Were the
    # HDIs independent, the misses among `count` would be Binomial(count,
    # 0.06); allow the fewest k that X exceeds with probability below 1e-3
    # (22 HDIs: at most 6 misses). The HDIs of one run are not independent
    # (a damping error moves the noise parameters with it), so this count
    # alone could pass a default biased on a few parameters at once; the
    # damping, the quantity the yaw-only default got wrong, must therefore
    # hold its truth in every run.
    allowed = int(scipy.stats.binom.isf(1e-3, count, 0.06))
    assert count == 22
    assert len(misses) <= allowed, (allowed, misses)
    damping = [miss for miss in misses if miss[1] in ("d_lat", "d_long")]
    assert not damping, damping


@pytest.mark.slow
@pytest.mark.xdist_group("real")
def test_vx_and_vy_narrow_the_d_lat_hdi_to_below_40_percent_of_yaw_alone(posteriors):
    # On the thesis truth the vx and vy poles (4 d / m: 7.3 and 26.6 1/s) lie
    # inside the band of the sigma_h = 0.047 s noise, so their channels pin
    # the damping's scale (measured: HDI width 59 against 720, 8 %). On the
    # stiff truth (poles 14.5 and 72.6 1/s, noise of sigma_h = 0.1 s, about
    # 1.6 Hz wide) the states follow the smooth noise quasi-statically and a
    # change of scale is absorbed by sigma_c: with every other parameter
    # maximised, the log-likelihood varies by 1.5 nats over d_lat 150..1000.
    # No channel can narrow that; the HDI test above shows the default
    # still holds the truth there, where yaw alone ([496, 1000]) excludes it.
    result = posteriors["thesis"]
    widths = {
        mode: result[mode]["d_lat"]["hdi_97%"] - result[mode]["d_lat"]["hdi_3%"]
        for mode in ("default", "yaw")
    }
    assert widths["default"] < 0.4 * widths["yaw"], widths
