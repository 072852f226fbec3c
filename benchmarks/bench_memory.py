"""Benchmark: wall time and peak memory of a posterior's post-processing on long runs (issue 12).

Run by hand: ``python benchmarks/bench_memory.py [--hour] [--steps load,report] [--workdir DIR]``.

For each run length (38 s, the baseline; 300 s; with ``--hour`` one hour,
259,200 samples at 72 Hz) it simulates a thesis-like experiment
(``simulate_experiment(robot, 110, 30, Series(0.3, 22.5 deg/s, duration),
rng=1)``: Gaussian process noise, channels yaw, vx and vy) and builds its
posterior from a short synthetic chain: 200 draws of 32 walkers scattered
by 1 % around the truth in log coordinates. That posterior is what the
post-processing reads (the point here is its memory, not the sampler's: the
chain's cost is the likelihood's, measured by ``bench_posterior.py``); the
likelihood it stores uses the package's default engine (``--engine``).

Each step then runs in a fresh subprocess that loads the posterior file,
so that its peak resident memory (``VmHWM`` of ``/proc/self/status``: a
high-water mark never resets) is that step's alone:

- ``load``: read the file and rebuild its likelihood, the floor of every step;
- ``criticise``: :func:`bayes_jackal.posterior.criticise` (the
  posterior-predictive p-values of 200 replicated series per channel);
- ``predictive``: the autocorrelation and spectrum figures of every channel
  with their posterior-predictive bands, rendered to PNG;
- ``model``: the model-fit and residual figures, rendered to PNG;
- ``report``: the whole HTML report (:func:`bayes_jackal.report.write_report`).

Printed per run length and step: wall time [s] and peak RSS [MB], and their
ratios to the 38 s run's in the same invocation. The issue's target: every
step of the one-hour run under 2 GB. To measure another copy of the package
(e.g. before a change), put it first on ``PYTHONPATH``: the subprocesses
inherit the environment.
"""

from __future__ import annotations

import argparse
import io
import json
import subprocess
import sys
import tempfile
import time
from dataclasses import asdict
from pathlib import Path

import numpy as np

DURATIONS = {"38 s": 38.0, "300 s": 300.0}
HOUR = {"1 h": 3600.0}
STEPS = ("load", "criticise", "predictive", "model", "report")
#: Synthetic chain: kept draws, walkers, and the scatter in log coordinates.
CHAIN_DRAWS, CHAIN_WALKERS, CHAIN_SCATTER = 200, 32, 0.01


def _peak_mb() -> float:
    """This process' peak resident memory (VmHWM) [MB]."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) / 1024.0
    raise RuntimeError("no VmHWM in /proc/self/status (Linux only)")


def _truth_vector(names: list[str], truth: dict) -> np.ndarray:
    """The parameter vector of a simulated truth, in ``names`` order."""
    values = []
    for name in names:
        base, _, group = name.partition("[")
        value = truth["width"] if base in ("width", "sigma_h") else truth[base]
        values.append(value[group.rstrip("]")] if isinstance(value, dict) else value)
    return np.array(values, float)


def build(seconds: float, engine: str | None, out: Path) -> None:
    """Simulate a run of ``seconds``, build its posterior from a synthetic chain, save it."""
    from bayes_jackal import load_profile
    from bayes_jackal.inference.chains import SamplerSettings
    from bayes_jackal.io.simulate import Series, simulate_experiment
    from bayes_jackal.likelihood.priors import Prior
    from bayes_jackal.likelihood.residual_likelihood import ResidualLikelihood
    from bayes_jackal.posterior.posterior import (
        build_inference_data,
        save_posterior,
    )

    robot = load_profile()
    experiment = simulate_experiment(robot, 110, 30, Series(0.3, np.deg2rad(22.5), seconds), rng=1)
    options = {} if engine is None else {"engine": engine}
    likelihood = ResidualLikelihood([experiment], robot, **options)
    prior = Prior.for_likelihood(likelihood, robot)
    centre = np.log(_truth_vector(list(prior.names), experiment.truth))
    rng = np.random.default_rng(1)
    chain = centre + CHAIN_SCATTER * rng.standard_normal((CHAIN_DRAWS, CHAIN_WALKERS, len(centre)))
    names = list(prior.names)
    diagnostics = {
        "converged": True,
        "n_steps": 2 * CHAIN_DRAWS,
        "walkers": CHAIN_WALKERS,
        "discard": CHAIN_DRAWS,
        "thin": 1,
        "autocorr_time": dict.fromkeys(names, 1.0),
        "ess_autocorr": dict.fromkeys(names, float(CHAIN_DRAWS * CHAIN_WALKERS)),
        "acceptance_fraction": 0.3,
        "seed": 1,
        "settings": asdict(SamplerSettings()),
    }
    idata = build_inference_data(likelihood, prior, chain, prior.log_density(chain), diagnostics)
    save_posterior(idata, out)


def _render(draw) -> None:
    fig, _ = draw()
    fig.savefig(io.BytesIO(), format="png", dpi=130)


def run_step(step: str, path: Path) -> None:
    """One post-processing step on the posterior file ``path``."""
    from bayes_jackal.posterior import Posterior, load_posterior
    from bayes_jackal.posterior.criticism import criticise
    from bayes_jackal.report import plots
    from bayes_jackal.report.page import write_report

    idata = load_posterior(path)
    channels = Posterior.of(idata).metadata.channels
    if step == "load":
        Posterior.of(idata).likelihood()
    elif step == "criticise":
        criticise(idata)
    elif step == "predictive":
        for channel in channels:
            _render(lambda c=channel: plots.plot_autocorrelation(idata, 0, c))
            _render(lambda c=channel: plots.plot_spectrum(idata, 0, c))
    elif step == "model":
        _render(lambda: plots.plot_model_fit(idata, 0))
        _render(lambda: plots.plot_residuals(idata, 0))
    else:
        with tempfile.TemporaryDirectory() as folder:
            write_report([path], Path(folder) / "report.html", formats=("png",))


def _child(arguments: list[str]) -> dict:
    """Run this script on ``arguments`` in a fresh process; its JSON line."""
    result = subprocess.run(
        [sys.executable, __file__, *arguments], capture_output=True, text=True, check=False
    )
    if result.returncode != 0:
        return {"error": result.stderr.strip().splitlines()[-1:] or ["killed"]}
    return json.loads(result.stdout.strip().splitlines()[-1])


def _measured(action) -> dict:
    start = time.perf_counter()
    action()
    return {"seconds": time.perf_counter() - start, "peak_mb": _peak_mb()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--hour", action="store_true", help="also one hour at 72 Hz")
    parser.add_argument("--steps", default=",".join(STEPS), help="comma-separated steps")
    parser.add_argument("--engine", default=None, help="engine stored in the posterior")
    parser.add_argument("--workdir", type=Path, default=None, help="keep the posteriors here")
    parser.add_argument("--child", nargs=2, metavar=("STEP", "PATH"), help=argparse.SUPPRESS)
    parser.add_argument("--seconds", type=float, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        step, path = args.child[0], Path(args.child[1])
        action = (
            (lambda: build(args.seconds, args.engine, path))
            if step == "build"
            else (lambda: run_step(step, path))
        )
        print(json.dumps(_measured(action)))
        return
    steps = args.steps.split(",")
    durations = DURATIONS | (HOUR if args.hour else {})
    with tempfile.TemporaryDirectory() as temporary:
        folder = args.workdir or Path(temporary)
        folder.mkdir(parents=True, exist_ok=True)
        baseline: dict[str, dict] = {}
        print(
            f"{'run':>6s} {'step':>10s} {'time [s]':>9s} {'x 38 s':>7s} "
            f"{'peak [MB]':>10s} {'x 38 s':>7s}",
            flush=True,
        )
        for label, seconds in durations.items():
            path = folder / f"posterior_{int(seconds)}s.nc"
            if not path.exists():
                extra = [] if args.engine is None else ["--engine", args.engine]
                made = _child(["--child", "build", str(path), "--seconds", str(seconds), *extra])
                seconds_taken = made.get("seconds", float("nan"))
                print(f"{label:>6s} {'(build)':>10s} {seconds_taken:9.1f}", flush=True)
            for step in steps:
                result = _child(["--child", step, str(path)])
                if "error" in result:
                    print(f"{label:>6s} {step:>10s} failed: {result['error']}", flush=True)
                    continue
                base = baseline.setdefault(step, result)
                print(
                    f"{label:>6s} {step:>10s} {result['seconds']:9.2f} "
                    f"{result['seconds'] / base['seconds']:7.2f} {result['peak_mb']:10.0f} "
                    f"{result['peak_mb'] / base['peak_mb']:7.2f}",
                    flush=True,
                )


if __name__ == "__main__":
    main()
