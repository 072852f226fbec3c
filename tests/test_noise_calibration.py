"""Calibration of bj.characterise_noise on simulated series (issue 15's Must show).

Each coloured family's noise, simulated here by the kernels of the thesis
(ch. 7: the Gaussian filter of eq. 7-5; the first-order low-pass, the
triangular and the moving-average filters it names as alternatives) and
written in this file, independently of :mod:`bayes_jackal.kernels`, over a
white floor, at widths from 0.6 to 20 samples: the true family must win
(ln B - 3 se > 3 against every other family) and the true width must lie
inside its 94 % HDI within the binomial tolerance over seeds. On white
noise the verdict must be "not coloured" or "inconclusive".

``BAYES_JACKAL_CALIBRATION_SEEDS`` sets the number of seeds per case (the
full form, run by hand: 5, several hours: the cases of 20 samples and the
white ones take over 5 min each per seed); CI runs 1 (.ci/run) with the
cases of :data:`CI_CASES` only, to stay within its time.
"""

from __future__ import annotations

import os
import time

import numpy as np
import pytest
import scipy.signal
import scipy.stats

import bayes_jackal as bj
from bayes_jackal.chains import SamplerSettings
from bayes_jackal.defaults import NOISE_MAX_STEPS

DT = 0.01  # [s]; the widths below are in samples
SAMPLES = 4000
FLOOR = 0.3  # the white floor's sd; the coloured part has unit sd
WIDTHS = (0.6, 2.0, 6.0, 20.0)  # [samples]
COLOURED = ("gaussian", "exponential", "triangular", "moving-average")
FAMILIES = ("white", *COLOURED)
SETTINGS = SamplerSettings(design_points=256, max_steps=NOISE_MAX_STEPS)  # the command's cap
HDI_PROB = 0.94
#: ln B - 3 se above this against every other family: the true family wins.
WIN_LOG_BF = 3.0


def taps(family: str, width: float) -> np.ndarray:
    """The thesis' filters at t = k dt for a width in samples (any scale).

    - gaussian (eq. 7-5): exp(-t^2 / (2 w^2)) for |t| <= 3 w;
    - triangular: 1 - |t| / w for |t| < w;
    - moving-average: a boxcar of duration w: floor(w) unit taps and one of
      the fraction left (one tap for w <= 1: a boxcar shorter than a sample
      is white at this rate).
    """
    if family == "gaussian":
        k = np.arange(-np.floor(3 * width), np.floor(3 * width) + 1)
        return np.exp(-(k**2) / (2 * width**2))
    if family == "triangular":
        k = np.arange(-np.ceil(width), np.ceil(width) + 1)
        return np.clip(1 - np.abs(k) / width, 0, None)
    if family == "moving-average":
        whole = int(max(width, 1.0))
        return np.append(np.ones(whole), max(width, 1.0) - whole)
    raise ValueError(family)


def simulate(family: str, width: float, seed: int, samples: int = SAMPLES) -> np.ndarray:
    """Unit-sd noise of one family and width [samples] plus a white floor of sd FLOOR."""
    rng = np.random.default_rng(seed)
    if family == "white":
        return rng.standard_normal(samples) * np.hypot(1.0, FLOOR)
    if family == "exponential":
        # AR(1), phi = exp(-dt / tau), started in its stationary distribution.
        phi = np.exp(-1 / width)
        white = rng.standard_normal(samples)
        coloured = scipy.signal.lfilter([np.sqrt(1 - phi**2)], [1, -phi], white[1:],
                                        zi=[phi * white[0]])[0]  # fmt: skip
        coloured = np.append(white[0], coloured)
    else:
        h = taps(family, width)
        h = h / np.linalg.norm(h)
        coloured = np.convolve(rng.standard_normal(samples + len(h) - 1), h, "valid")
    return coloured + FLOOR * rng.standard_normal(samples)


#: Cases where the noise is white at this rate: the truth cannot win, its
#: width is not identified, and the verdict must not be "coloured".
WHITE_AT_THIS_RATE = {
    ("triangular", 0.6): "1 - |k| / 0.6 is 0 for every k != 0: one tap, white noise",
    ("moving-average", 0.6): "a boxcar of 0.6 samples is one tap: white noise",
}
#: Cases where short kernels look alike (measured, SAMPLES samples; the
#: numbers in :func:`test_true_family_wins_and_its_width_is_calibrated`):
#: the truth cannot win by ln B - 3 se > 3, so it must only not be beaten so.
ALIKE = {
    ("gaussian", 0.6): "taps exp(-1 / 0.72) = 0.25, 1, 0.25: ln Z - ln Z_white 368.0, "
    "triangular 367.9, moving-average 364.6",
    ("gaussian", 2.0): "ln Z - ln Z_white 2795.6, triangular 2796.0",
    ("exponential", 0.6): "phi = 0.19: ln Z - ln Z_white 40.1, gaussian 38.6",
    ("triangular", 2.0): "taps 0.5, 1, 0.5: ln Z - ln Z_white 1174.1, moving-average 1173.2, "
    "gaussian 1172.2",
}
#: Cases whose simulated noise is not in the model, so their HDI is not
#: counted (the evidence checks still apply).
OUTSIDE_THE_MODEL = {
    ("gaussian", 0.6): "the thesis' hard truncation at 3 w = 1.8 samples drops the taps at "
    "+-2 that the package's continuous truncation keeps (0.8 exp(-4 / 0.72) = 0.0031): "
    "the HDI 0.56-0.60 sits just below the truth",
}
CASES = [(family, width) for family in COLOURED for width in WIDTHS]
#: The reduced form's cases: the AR(1) path of the fast engine and the
#: banded fallback's family (CI: ~75 s of one core; 39 s and 36 s measured alone).
CI_CASES = [("exponential", 6.0), ("moving-average", 6.0)]


def seeds() -> range:
    """``BAYES_JACKAL_CALIBRATION_SEEDS`` seeds per case (5)."""
    count = int(os.environ.get("BAYES_JACKAL_CALIBRATION_SEEDS", "5"))
    if count < 1:
        raise ValueError(f"BAYES_JACKAL_CALIBRATION_SEEDS must be >= 1, got {count}")
    return range(count)


def least_inside(cases: int) -> float:
    """The 0.1 % quantile of Binomial(cases, 0.94): a calibrated 94 % HDI holds
    the truth in fewer of ``cases`` independent cases once in a thousand."""
    return scipy.stats.binom.ppf(0.001, cases, HDI_PROB)


def characterise(values: np.ndarray, seed: int) -> bj.NoiseCharacterisation:
    return bj.characterise_noise(values, dt=DT, families=FAMILIES, settings=SETTINGS, seed=seed)


def margin(result: bj.NoiseCharacterisation, family: str, rival: str) -> float:
    """ln B - 3 se of ``family`` against ``rival`` [nats]."""
    mine, theirs = result.fits[family].evidence, result.fits[rival].evidence
    error = np.hypot(mine.error, theirs.error)
    return mine.log_evidence - theirs.log_evidence - 3 * error


@pytest.mark.slow
@pytest.mark.xdist_group("noise_calibration")
def test_true_family_wins_and_its_width_is_calibrated():
    """Simulated series of each family (SAMPLES samples, floor FLOOR) at widths WIDTHS.

    The truth must win by ln B - 3 se > 3 against every other family,
    except where the noise is white (:data:`WHITE_AT_THIS_RATE`: then not
    "coloured") or short kernels look alike (:data:`ALIKE`: then not beaten
    by that margin). With one seed (CI) only :data:`CI_CASES` run.

    Measured, seed 0, 4000 samples, 3000 steps, one core at load 1-4:
    family, width [samples], ln B - 3 se of the truth against its closest
    rival [nats], the 94 % HDI [samples], time.

    ============== ===== ========== ============= ======
    gaussian         0.6   0.0 alike  0.56-0.60 out  46 s
    gaussian         2    -0.5 alike  1.93-2.06      43 s
    gaussian         6     8.9        5.65-6.15     114 s
    exponential      0.6   1.0 alike  0.44-0.65      50 s
    exponential      2    11.7        1.60-2.14      29 s
    exponential      6    59.4        4.85-6.41      39 s
    triangular       2     0.7 alike  1.80-2.01      26 s
    triangular       6     8.5        5.79-6.12      41 s
    moving-average   2    38.3        1.61-1.91 out  24 s
    moving-average   6   166.6        5.92-6.03      36 s
    ============== ===== ========== ============= ======

    Not measured (stopped after 4.5 to 6 min each): the widths of 20
    samples (the wide kernels cost 50 ms to 3 s per step of 32 walkers)
    and the white cases of 0.6 samples (every coloured chain runs to its
    cap on white noise). The moving-average chain of 2 samples did not
    converge in the 3000 steps of that measurement (its HDI missed the
    truth); the test now runs at the command's cap, NOISE_MAX_STEPS.

    The HDIs are checked per case over its seeds and pooled, each against
    the 0.1 % quantile of Binomial(N, 0.94); with one seed that quantile
    is 0, so the reduced form asserts each case's (fixed-seed) hit instead.
    """
    cases = CI_CASES if len(seeds()) == 1 else CASES
    rows, inside, failures = [], {}, []
    for family, width in cases:
        for seed in seeds():
            start = time.perf_counter()
            result = characterise(simulate(family, width, seed=100 + seed), seed=seed)
            rivals = [name for name in FAMILIES if name != family]
            closest = min(margin(result, family, rival) for rival in rivals)
            hdi = result.fits[family].width()["bins"]
            hit = hdi["hdi_3%"] <= width <= hdi["hdi_97%"]
            verdict = result.verdict()[0]
            rows.append((family, width, seed, closest, result.best, hit, verdict,
                         time.perf_counter() - start))  # fmt: skip
            print("{:15} {:5.1f} {} {:8.1f} {:15} {!s:5} {:13} {:5.1f} s".format(*rows[-1]))
            if (family, width) in WHITE_AT_THIS_RATE:
                if verdict == "coloured":
                    failures.append(("white at this rate, called coloured", family, width, seed))
                continue
            if (family, width) not in OUTSIDE_THE_MODEL:
                inside.setdefault((family, width), []).append(hit)
            if (family, width) in ALIKE:
                beaten = max(margin(result, rival, family) for rival in rivals)
                if beaten > WIN_LOG_BF:
                    failures.append(("beaten", family, width, seed, beaten, result.best))
            elif closest <= WIN_LOG_BF:
                failures.append(("did not win", family, width, seed, closest, result.best))
    for case, hits in inside.items():
        least = len(hits) if len(hits) == 1 else least_inside(len(hits))
        if sum(hits) < least:
            failures.append(("HDI misses the truth", case, sum(hits), len(hits)))
    pooled = [hit for hits in inside.values() for hit in hits]
    if sum(pooled) < least_inside(len(pooled)):
        failures.append(("HDIs pooled", sum(pooled), len(pooled)))
    assert not failures, failures


@pytest.mark.slow
@pytest.mark.xdist_group("noise_calibration")
def test_white_noise_is_never_called_coloured():
    """White noise (1000 samples: a coloured family's width is unidentified
    there and its chain runs to its cap): "not coloured" or "inconclusive".
    Only in the full form (the fast suite's
    test_noise_characterisation.py::test_white_noise_is_not_called_coloured
    checks one seed against the Gaussian family)."""
    if len(seeds()) == 1:
        pytest.skip("the full form only (BAYES_JACKAL_CALIBRATION_SEEDS > 1)")
    for seed in seeds():
        result = characterise(simulate("white", 0.0, seed=200 + seed, samples=1000), seed=seed)
        assert result.verdict()[0] in ("not coloured", "inconclusive"), result.verdict()
