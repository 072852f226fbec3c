"""``analyse`` of logs as labs record them: a pose dropout is used, a broken log is skipped.

Issue 36's Must show: three good motion-capture bags, one with a 2 s pose
dropout and one truncated (a crashed recorder's), simulated by
tests/lab_simulator.py. ``analyse`` must analyse four (the gapped one with a
note in its repairs), skip the truncated one naming its reason, write the
report and exit 2 (an input could not be used).
"""

from __future__ import annotations

import json

import lab_simulator as lab
import numpy as np
import pytest

from bayes_jackal.cli import main
from bayes_jackal.cli.exits import EXIT_BAD_INPUT
from bayes_jackal.io.experiment import read_netcdf
from bayes_jackal.posterior import load_posterior

#: Thesis circles (v [m/s], w [rad/s], duration [s]) of the three good bags.
CIRCLES = ((0.3, 0.3927, 38.0), (0.4, 0.5236, 26.0), (0.3, 0.3927, 38.0))


@pytest.mark.slow
@pytest.mark.xdist_group("lab_workflow")
def test_analyse_uses_a_gapped_log_and_skips_a_broken_one(tmp_path, capsys):
    rng = np.random.default_rng(36)
    bags = []
    for i, (v, w, duration) in enumerate((*CIRCLES, (0.4, 0.5236, 26.0), (0.3, 0.3927, 38.0))):
        sim = lab.simulate(lab.thesis_circle(v, w, duration), rng=rng)
        dropouts = [(12.0, 2.0)] if i == 3 else []
        bags.append(lab.write_lab_bag(tmp_path / f"run{i}.bag", sim, pose_dropouts=dropouts,
                                      rng=rng).path)  # fmt: skip
    broken = lab.truncate_bag(bags[4], 0.6, out=tmp_path / "crashed.bag")
    bags[4].unlink()
    code = main(["analyse", *map(str, bags[:4]), str(broken), "--out", str(tmp_path / "out"),
                 "--families", "gaussian", "--seed", "1", "--json"])  # fmt: skip
    result = json.loads(capsys.readouterr().out)
    assert code == EXIT_BAD_INPUT
    assert sorted(result["experiments"]) == ["run0", "run1", "run2", "run3"]
    assert list(result["failed"]) == [str(broken)]
    assert "cannot read bag" in result["failed"][str(broken)]  # its reason, not only its name
    gapped = read_netcdf(result["experiments"]["run3"]["file"])
    assert any("the poses are kept with their gap" in r for r in gapped.provenance["repairs"])
    assert (tmp_path / "out" / "report.html").stat().st_size > 0
    # One data set: each truth in the central 99.9 % interval (a 94 % HDI
    # misses one in 17 by design; tests/test_lab_calibration.py calibrates it).
    posterior = load_posterior(tmp_path / "out" / "posterior.nc").posterior
    for name, truth in (("d_lat", 110.0), ("d_long", 30.0)):
        low, high = np.quantile(posterior[name].values, [0.0005, 0.9995])
        assert low <= truth <= high, (name, low, high)
