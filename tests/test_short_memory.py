"""``analyse`` on a 1 kHz physics-engine log whose noise has a short memory (issue 37, item 14).

A simulator that logs every physics step (Gazebo at 1 kHz) leaves process
noise of a few samples' memory, not the Gaussian kernel of tens of ms the
thesis found on the real Jackal. The log here is written by this module, not
by the package: a thesis circle (tests/mocap_simulator.py's command and
model, models/jackal.toml's constants, truth d_lat 110, d_long 30 N s/m),
the yaw rate driven by AR(1) process noise, whose autocorrelation is the
exponential exp(-|tau| / memory) sampled at the log's rate, and read by a
gyro with white noise. The wheel speeds are exact.

``analyse`` must answer "is the noise coloured?" from families that could
say yes: where white beats gaussian, whose kernel is too smooth for colour of
a few samples, it compares the exponential family too.
"""

from __future__ import annotations

import json
from pathlib import Path

import mocap_simulator as mocap
import numpy as np
import pytest
import scipy.signal

from bayes_jackal.cli import main

RATE = 1000.0
#: sd of the process noise [rad/s per step] and of the gyro's noise [rad/s].
SIGMA_C, SIGMA_N = 0.002, 0.001


def physics_engine_log(path: Path, seed: int, memory: float, duration: float = 20.0) -> Path:
    """A CSV (t, yaw_rate, omega_r, omega_l) at 1 kHz; process noise of memory ``memory`` [s]."""
    rng = np.random.default_rng(seed)
    dt = 1.0 / RATE
    t = np.arange(round(duration * RATE)) * dt
    poles, B = mocap.model_matrices(110.0, 30.0)
    command = mocap.command_profile(t, 0.3, 0.3927, duration)
    wheels = mocap.wheel_speeds(command[:, 0], command[:, 1])
    decay = np.exp(poles[2] * dt)  # the yaw rate's exact discretisation over one step
    gain = (decay - 1) / poles[2] * B[2]
    phi = np.exp(-dt / memory)  # AR(1): autocorrelation phi^|k| = exp(-|k dt| / memory)
    shocks = rng.normal(0.0, SIGMA_C * np.sqrt(1 - phi**2), t.size)
    noise, _ = scipy.signal.lfilter([1.0], [1.0, -phi], shocks, zi=[phi * rng.normal(0, SIGMA_C)])
    # r[k] = decay r[k-1] + gain u[k-1] + w[k-1], from rest
    yaw = scipy.signal.lfilter([0.0, 1.0], [1.0, -decay], wheels @ gain + noise)
    table = np.column_stack([t, yaw + rng.normal(0.0, SIGMA_N, t.size), wheels])
    header = "t,yaw_rate,omega_r,omega_l"
    np.savetxt(path, table, delimiter=",", header=header, comments="", fmt="%.10g")
    return path


def analyse(log: Path, out: Path, capsys) -> tuple[dict, str]:
    """``analyse`` with its default families: the result's JSON and stderr."""
    code = main(["analyse", str(log), "--out", str(out), "--rate", "1000", "--seed", "1",
                 "--no-progress", "--json"])  # fmt: skip
    captured = capsys.readouterr()
    assert code == 0, captured.err
    return json.loads(captured.out), captured.err


@pytest.mark.slow
def test_a_physics_engine_log_of_short_memory_noise_is_coloured(tmp_path, capsys):
    """5 ms of memory (5 samples): coloured, by gaussian or exponential, never white."""
    result, _ = analyse(physics_engine_log(tmp_path / "gazebo.csv", 1, 0.005), tmp_path / "a",
                        capsys)  # fmt: skip
    verdict = json.loads((tmp_path / "a" / "compare.json").read_text())["verdict"]
    assert verdict == "coloured" and result["best"] != "white", result["comparison"]


@pytest.mark.slow
def test_white_beating_gaussian_brings_in_the_short_memory_family(tmp_path, capsys):
    """On white noise white beats gaussian: exponential is compared too, unless families are given.

    The run is the package's own simulation with white process noise: this
    checks which families ``analyse`` compares, not a statistical claim.
    """
    assert main(["simulate", "--out", str(tmp_path / "runs"), "--seed", "1", "--v1", "1",
                 "--v2", "0", "--family", "white"]) == 0  # fmt: skip
    run = tmp_path / "runs" / "v1_01.nc"
    quick = ["--channels", "yaw", "--max-steps", "300", "--no-progress", "--seed", "1", "--json"]
    capsys.readouterr()
    cases = (([], ["white", "gaussian", "exponential"]),
             (["--families", "white,gaussian"], ["white", "gaussian"]))  # fmt: skip
    for given, compared in cases:
        out = tmp_path / f"a{len(given)}"
        code = main(["analyse", str(run), "--out", str(out), *quick, *given])
        captured = capsys.readouterr()
        assert code == 0, captured.err
        result = json.loads(captured.out)
        assert list(result["comparison"]["families"]) == compared and result["best"] == "white"
        assert ("white beat gaussian: exponential" in captured.err) == (not given)
        assert sorted(p.name for p in (out / "posteriors").iterdir()) == sorted(
            f"{family}.nc" for family in compared
        )


@pytest.mark.slow
def test_memory_shorter_than_the_width_floor_is_not_read_as_white(tmp_path, capsys):
    """0.5 ms of memory (lag-1 correlation 0.135) at 1 kHz, where the width prior starts at 1 ms.

    The exponential width piles at its floor (e^-1 = 0.37 at lag 1, too
    coloured) and white wins by ln B ~ -39: on the old code "not coloured".
    The verdict must say that shorter memory was not tried, and how to try it.
    """
    log = physics_engine_log(tmp_path / "gazebo.csv", 1, 0.0005, duration=10.0)
    code = main(["compare", str(log), "--rate", "1000", "--seed", "1", "--channels", "yaw",
                 "--families", "white,exponential", "--no-progress", "--json"])  # fmt: skip
    captured = capsys.readouterr()
    assert code == 0, captured.err
    comparison = json.loads(captured.out)
    comparison = comparison.get("comparison", comparison)
    assert comparison["best"] == "white"
    assert comparison["verdict"] == "inconclusive", comparison["verdict_text"]
    assert "exponential's at 0.001 s" in comparison["verdict_text"]
