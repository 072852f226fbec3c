"""Reproduce thesis ch. 7 step by step: residuals, their spectrum, the sigma_h fit, table 7-1.

Run: ``python examples/thesis_chapter_7.py [--quick] [--out DIR]``.

The thesis' own bags are not public, so the analysis runs on simulated
thesis-like experiments (10 x v1, 5 x v2) with Gaussian-coloured process
noise of known width sigma_h = 0.047 s, the value of the thesis' table 7-1.
The model is the thesis' optimum, d_lat = 110, d_long = 30 N s/m.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from bayes_jackal import load_profile
from bayes_jackal.io.simulate import NoiseSettings, simulate_series
from bayes_jackal.likelihood.residuals import channel_residuals
from bayes_jackal.model.kernels import get_family
from bayes_jackal.posterior.series_statistics import (
    autocorrelation_bounds,
    sample_autocorrelation,
    spectrum,
)
from bayes_jackal.thesis.residual_analysis import analyse, fit_sigma_h

THESIS_TABLE_7_1 = {"v1": 0.051, "v2": 0.041, "all": 0.047}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="3 runs instead of 15")
    parser.add_argument("--out", default=".", help="folder for the figure")
    args = parser.parse_args()
    robot = load_profile()
    counts = {"v1": 2, "v2": 1} if args.quick else {"v1": 10, "v2": 5}
    runs = simulate_series(robot, 110.0, 30.0, counts, rng=2026)

    # Eq. 7-3: one-step residuals of the yaw rate on the steady window; the
    # Ljung-Box test rejects white noise (thesis figs. 7-10..7-12).
    result = analyse(runs, robot, 110.0, 30.0)
    first = runs[0].name
    yaw = result["experiments"][first]["yaw"]
    print(
        f"{first}: {yaw['n']} yaw residuals, sd {yaw['sd']:.4f} rad/s, Ljung-Box "
        f"Q = {yaw['ljung_box_q']:.0f} (p = {yaw['ljung_box_p']:.2g}); r[1..3] = "
        + ", ".join(f"{r:.2f}" for r in yaw["autocorrelation"][:3])
        + f" against the white-noise bound {yaw['bound']:.3f}"
    )

    # Eq. 7-6 and table 7-1: sigma_h by least squares between autocorrelations.
    print("table 7-1 (sigma_h [s]): this run / thesis")
    for label, thesis in THESIS_TABLE_7_1.items():
        print(f"  {label:4s} {result['sigma_h'][label]:.4f} / {thesis:.3f}")
    truth = NoiseSettings().width
    print(
        f"truth {truth} s: the fit is biased low, since the sensor noise's MA(1) "
        "footprint lowers the lag-1 autocorrelation"
    )

    # Figure: the residual ACF with the fitted filter's, and the Welch PSD.
    residuals = channel_residuals(runs[0], robot, 110.0, 30.0, "yaw")
    dt = runs[0].dt
    sigma_h, _ = fit_sigma_h(residuals, dt)
    lags = np.arange(31)
    fig = Figure(figsize=(10, 3.8), layout="constrained")
    acf_ax, psd_ax = fig.subplots(1, 2)
    bound = autocorrelation_bounds(len(residuals))
    acf_ax.axhspan(-bound, bound, color="tab:blue", alpha=0.15, label="95 % white-noise bounds")
    acf_ax.plot(lags, sample_autocorrelation(residuals, 30), "o-", ms=3, label="residuals")
    fitted = get_family("gaussian").autocorrelation(float(sigma_h), dt, 31)
    acf_ax.plot(lags, np.ravel(fitted), label=f"Gaussian filter, sigma_h = {float(sigma_h):.3f} s")
    acf_ax.set(xlabel="lag [samples]", ylabel="autocorrelation", title="thesis fig. 7-12")
    acf_ax.legend(fontsize="small")
    frequency, psd = spectrum(residuals, dt)
    psd_ax.loglog(frequency[1:], psd[1:])
    psd_ax.set(xlabel="frequency [Hz]", ylabel="PSD [(rad/s)^2/Hz]", title="thesis figs. 7-7..7-9")
    path = Path(args.out) / "thesis_chapter_7.png"
    fig.savefig(path, dpi=120)
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
