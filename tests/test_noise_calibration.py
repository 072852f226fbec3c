"""Calibration of bj.characterise_noise on simulated series (issue 15's Must show).

Each coloured family's noise, simulated here by the kernels of the thesis
(ch. 7: the Gaussian filter of eq. 7-5; the first-order low-pass, the
triangular and the moving-average filters it names as alternatives) and
written in this file, independently of :mod:`bayes_jackal.model.kernels`, over a
white floor, at widths from 0.6 to 20 samples: the true family must win
(ln B - 3 se > 3 against every other family) and the true width must lie
inside its 94 % HDI within the binomial tolerance over seeds. On white
noise the verdict must be "not coloured" or "inconclusive".

``BAYES_JACKAL_CALIBRATION_SEEDS`` sets the number of seeds per case (the
full form, run by hand: 5, about five hours of one core;
``BAYES_JACKAL_CALIBRATION_PROCESSES=2`` runs the series in two worker
processes); CI runs 1 (.ci/run) with the cases of :data:`CI_CASES` only, to
stay within its time.
"""

from __future__ import annotations

import time

import numpy as np
import pytest
import scipy.signal
from calibration import least_inside, map_rows, seeds

import bayes_jackal as bj
from bayes_jackal._runtime.defaults import NOISE_MAX_STEPS
from bayes_jackal.inference.chains import SamplerSettings

DT = 0.01  # [s]; the widths below are in samples
SAMPLES = 4000
FLOOR = 0.3  # the white floor's sd; the coloured part has unit sd
WIDTHS = (0.6, 2.0, 6.0, 20.0)  # [samples]
COLOURED = ("gaussian", "exponential", "triangular", "moving-average")
FAMILIES = ("white", *COLOURED)
SETTINGS = SamplerSettings(design_points=256, max_steps=NOISE_MAX_STEPS)  # the command's cap
#: Seeds per case of the full form (``BAYES_JACKAL_CALIBRATION_SEEDS``, tests/calibration.py).
FULL_SEEDS = 5
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
#: Cases whose width the data cannot identify, so their HDI is not counted
#: (the evidence checks still apply).
NOT_IDENTIFIED = {
    ("moving-average", 2.0): "taps 1, w - 1 for 1 < w <= 2: an MA(1) process plus white noise "
    "is an MA(1) process, so (w, sigma_c, sigma_n) lie on a ridge of equal likelihood "
    "(measured, seed 100: the profile is -5109.82 from w = 1.65 to 2.00, sigma_n 0.05 to "
    "0.31); the truth is at its end, and the HDI covers the ridge as the prior weighs it",
}
#: Cases simulated on a longer record, in samples: the Gaussian and
#: triangular kernels differ most in their spectra's tails, which the white
#: floor buries, so telling them apart at 20 samples takes a record of
#: ~1000 widths. Measured on SAMPLES samples (200 widths), seeds 0-4: ln B -
#: 3 se of the truth over its closest rival -0.5 to 13.7 (Gaussian) and 2.9
#: to 15.2 (triangular), below 3 once each; on 20,000 samples those two
#: seeds give 53.6 and 63.9.
LONG_RECORDS = {("gaussian", 20.0): 20_000, ("triangular", 20.0): 20_000}
CASES = [(family, width) for family in COLOURED for width in WIDTHS]
#: The reduced form's cases: the AR(1) path of the fast engine and the
#: banded fallback's family (CI: ~75 s of one core; 39 s and 36 s measured alone).
CI_CASES = [("exponential", 6.0), ("moving-average", 6.0)]


def characterise(values: np.ndarray, seed: int) -> bj.NoiseCharacterisation:
    return bj.characterise_noise(values, dt=DT, families=FAMILIES, settings=SETTINGS, seed=seed)


def margin(result: bj.NoiseCharacterisation, family: str, rival: str) -> float:
    """ln B - 3 se of ``family`` against ``rival`` [nats]."""
    mine, theirs = result.fits[family].evidence, result.fits[rival].evidence
    error = np.hypot(mine.error, theirs.error)
    return mine.log_evidence - theirs.log_evidence - 3 * error


def calibration_row(case: tuple[str, float, int]) -> dict:
    """One simulated series of ``case`` = (family, width [samples], seed), characterised.

    Returns the truth's closest margin (ln B - 3 se against its closest
    rival), the largest margin of a rival against it, the best family,
    whether the truth's 94 % HDI holds the true width, the verdict and the
    time; the row is printed as it comes.
    """
    family, width, seed = case
    start = time.perf_counter()
    samples = LONG_RECORDS.get((family, width), SAMPLES)
    result = characterise(simulate(family, width, seed=100 + seed, samples=samples), seed=seed)
    rivals = [name for name in FAMILIES if name != family]
    hdi = result.fits[family].width()["bins"]
    row = {
        "family": family,
        "width": width,
        "seed": seed,
        "closest": min(margin(result, family, rival) for rival in rivals),
        "beaten": max(margin(result, rival, family) for rival in rivals),
        "best": result.best,
        "hdi": (hdi["hdi_3%"], hdi["hdi_97%"]),
        "hit": bool(hdi["hdi_3%"] <= width <= hdi["hdi_97%"]),
        "verdict": result.verdict()[0],
        "seconds": time.perf_counter() - start,
    }
    print("{family:15} {width:5.1f} {seed} {closest:8.1f} {beaten:8.1f} {best:15} {hit!s:5} "
          "{verdict:13} {hdi[0]:6.2f}-{hdi[1]:6.2f} {seconds:5.1f} s".format(**row),
          flush=True)  # fmt: skip
    return row


def calibration_failures(rows: list[dict]) -> list[tuple]:
    """The Must show's checks over the rows (the test's docstring): empty when all hold."""
    inside, failures = {}, []
    for row in rows:
        case = (row["family"], row["width"])
        if case in WHITE_AT_THIS_RATE:
            if row["verdict"] == "coloured":
                failures.append(("white at this rate, called coloured", *case, row["seed"]))
            continue
        if case not in OUTSIDE_THE_MODEL and case not in NOT_IDENTIFIED:
            inside.setdefault(case, []).append(row["hit"])
        if case in ALIKE:
            if row["beaten"] > WIN_LOG_BF:
                failures.append(("beaten", *case, row["seed"], row["beaten"], row["best"]))
        elif row["closest"] <= WIN_LOG_BF:
            failures.append(("did not win", *case, row["seed"], row["closest"], row["best"]))
    for case, hits in inside.items():
        least = len(hits) if len(hits) == 1 else least_inside(len(hits))
        if sum(hits) < least:
            failures.append(("HDI misses the truth", case, sum(hits), len(hits)))
    pooled = [hit for hits in inside.values() for hit in hits]
    if sum(pooled) < least_inside(len(pooled)):
        failures.append(("HDIs pooled", sum(pooled), len(pooled)))
    return failures


@pytest.mark.slow
@pytest.mark.xdist_group("noise_calibration")
def test_true_family_wins_and_its_width_is_calibrated():
    """Simulated series of each family (SAMPLES samples, floor FLOOR) at widths WIDTHS.

    The truth must win by ln B - 3 se > 3 against every other family,
    except where the noise is white (:data:`WHITE_AT_THIS_RATE`: then not
    "coloured") or short kernels look alike (:data:`ALIKE`: then not beaten
    by that margin). With one seed (CI) only :data:`CI_CASES` run.

    Measured, the full form (seeds 0-4, NOISE_MAX_STEPS, two processes at
    load 2): family, width [samples], HDI hits of 5, ln B - 3 se of the
    truth against its closest rival over the seeds [nats], the median 94 %
    HDI [samples] and the median time of one series.

    ============== ===== ====== ================ ============= ======
    gaussian         0.6  2 out   -0.2..0.1 alike  0.56-0.60      40 s
    gaussian         2    5       -0.5..5.7 alike  1.92-2.04      35 s
    gaussian         6    5        8.8..12.3       5.78-6.28      83 s
    gaussian        20    5       31.9..66.0      19.78-20.83    381 s
    exponential      0.6  5       -1.5..0.9 alike  0.50-0.64      54 s
    exponential      2    3       11.1..17.6       1.57-2.04      30 s
    exponential      6    5       59.4..97.3       5.02-6.61      30 s
    exponential     20    5      132.0..185.5     16.02-24.63     56 s
    triangular       0.6  white   -1.9..-0.8     inconclusive    919 s
    triangular       2    5       -0.4..0.7 alike  1.88-2.03      23 s
    triangular       6    5        4.5..8.5        5.74-6.06      49 s
    triangular      20    5       46.4..71.9      19.62-20.19    155 s
    moving-average   0.6  white   -0.8           inconclusive    513 s
    moving-average   2    0 unid  22.9..53.9       1.63-1.91      37 s
    moving-average   6    4      130.1..195.0      5.92-6.03      34 s
    moving-average  20    5      157.1..182.2     19.89-20.12    110 s
    ============== ===== ====== ================ ============= ======

    Pooled, the HDIs hold the truth in 57 of 60 series (the bound is 50).
    The Gaussian and triangular cases of 20 samples ran on LONG_RECORDS;
    the white-at-this-rate cases ran 2 seeds (triangular) and 1 (boxcar),
    every coloured chain running to its cap there (8 to 17 min a series).
    The full form takes about 5 h of one core.

    The HDIs are checked per case over its seeds and pooled, each against
    the 0.1 % quantile of Binomial(N, 0.94); with one seed that quantile
    is 0, so the reduced form asserts each case's (fixed-seed) hit instead.
    Cases outside the model (:data:`OUTSIDE_THE_MODEL`) or whose width is
    not identified (:data:`NOT_IDENTIFIED`) are not counted.
    """
    cases = CI_CASES if len(seeds(FULL_SEEDS)) == 1 else CASES
    rows = map_rows(
        calibration_row,
        [(family, width, seed) for family, width in cases for seed in seeds(FULL_SEEDS)],
    )
    failures = calibration_failures(rows)
    assert not failures, failures


@pytest.mark.slow
@pytest.mark.xdist_group("noise_calibration")
def test_white_noise_is_never_called_coloured():
    """White noise (1000 samples: a coloured family's width is unidentified
    there and its chain runs to its cap): "not coloured" or "inconclusive".
    Only in the full form (the fast suite's
    test_noise_characterisation.py::test_white_noise_is_not_called_coloured
    checks one seed against the Gaussian family)."""
    if len(seeds(FULL_SEEDS)) == 1:
        pytest.skip("the full form only (BAYES_JACKAL_CALIBRATION_SEEDS > 1)")
    verdicts = map_rows(white_verdict, list(seeds(FULL_SEEDS)))
    assert all(verdict in ("not coloured", "inconclusive") for verdict in verdicts), verdicts


def white_verdict(seed: int) -> str:
    """The verdict on white noise of 1000 samples (seed 200 + ``seed``), printed."""
    start = time.perf_counter()
    result = characterise(simulate("white", 0.0, seed=200 + seed, samples=1000), seed=seed)
    print(f"white {seed} {result.best:15} {result.verdict()[0]:13} "
          f"{time.perf_counter() - start:5.1f} s", flush=True)  # fmt: skip
    return result.verdict()[0]
