"""The analysis as a pipeline of stages (bayes_jackal.workflow): how results join, and a stage.

The stages run here on a short run without the grids and the report (the
analyse tests run the whole pipeline): the ingest, the one family, and the
residual table, whose rows are checked against the one-step residuals
computed anew (eq. 7-3) at the posterior median of the damping.
"""

from __future__ import annotations

import csv
import dataclasses
import re
import warnings

import numpy as np
import pytest

import bayes_jackal as bj
from bayes_jackal._runtime import printed
from bayes_jackal.inference import ProcessExecutor, SerialExecutor
from bayes_jackal.likelihood import LikelihoodOptions, channel_residuals, residual_times
from bayes_jackal.workflow import (
    PIPELINE,
    Analysis,
    RunContext,
    StageResult,
    background_jobs,
    run_pipeline,
)
from bayes_jackal.workflow.stages.family_comparison import families
from bayes_jackal.workflow.stages.ingestion import ingest
from bayes_jackal.workflow.stages.report_page import report, report_sections
from bayes_jackal.workflow.stages.residual_table import residual_table

ROBOT = bj.load_profile()


@pytest.fixture(scope="module")
def pipeline(tmp_path_factory):
    """Two 8 s runs ingested from CSV, white noise on yaw and vx (100 steps), the residuals."""
    folder = tmp_path_factory.mktemp("pipeline")
    short = bj.io.Series(0.3, 0.39, 8.0)
    runs = [
        bj.simulate_experiment(ROBOT, 110.0, 30.0, short, rng=seed, name=name)
        for seed, name in ((1, "a"), (2, "b"))
    ]
    context = RunContext(
        inputs=[bj.write_csv(run, folder / f"{run.name}.csv") for run in runs],
        out=folder / "out",
        executor=SerialExecutor(),
        families=("white",),
        likelihood_options=LikelihoodOptions(channels=("yaw", "vx")),
        settings=bj.SamplerSettings(max_steps=100, progress=False),
        seed=1,
    )
    with warnings.catch_warnings():  # 100 steps, on purpose: not converged
        warnings.simplefilter("ignore", bj.ConvergenceWarning)
        return run_pipeline(context, (ingest, families, residual_table))


def test_the_residual_table_holds_every_runs_one_step_residuals(pipeline):
    table = pipeline["residual_table"]
    with table.path.open(newline="") as file:
        rows = list(csv.DictReader(file))
    assert len(rows) == table.rows and pipeline.to_dict()["files"]["residuals"] == str(table.path)
    posterior = pipeline["families"].posterior
    median = {name: float(posterior.posterior[name].median()) for name in ("d_lat", "d_long")}
    for experiment in pipeline["ingest"].experiments:
        for channel, unit in (("yaw", "rad/s"), ("vx", "m/s")):
            mine = [r for r in rows if r["run"] == experiment.name and r["channel"] == channel]
            assert {r["unit"] for r in mine} == {unit}
            # Written with 9 significant digits and the times with 6 decimals.
            expected = channel_residuals(
                experiment, ROBOT, median["d_lat"], median["d_long"], channel
            )
            np.testing.assert_allclose(
                [float(r["residual"]) for r in mine], expected, rtol=1e-8, atol=1e-12
            )
            times = residual_times(experiment, channel)
            np.testing.assert_allclose([float(r["t"]) for r in mine], times, atol=5e-7)


def test_a_stages_result_joins_the_json_and_its_warnings_the_list(pipeline):
    @dataclasses.dataclass(frozen=True)
    class Counted(StageResult):
        runs: int

        def to_dict(self):
            return {"runs": self.runs, "warnings": [{"kind": "few-runs", "message": "2 runs"}]}

    def count(context, done):
        return Counted(len(done["ingest"].experiments))

    results = {**pipeline.results, "count": count(None, pipeline.results)}
    payload = Analysis(pipeline.folder, results).to_dict()
    before = pipeline.to_dict()
    assert list(payload) == [*list(before)[:-1], "runs", "files"]  # in the stages' order
    assert payload["warnings"] == [*before["warnings"], {"kind": "few-runs", "message": "2 runs"}]
    assert payload["files"] == before["files"]


def test_the_pipeline_lists_each_stage_once_the_report_after_its_sections():
    names = [stage.__name__ for stage in PIPELINE]
    assert len(set(names)) == len(names) and names[0] == "ingest"
    for sectioned in ("families", "state_estimation", "groups_population"):
        assert names.index("report") > names.index(sectioned)
    assert names.index("residual_table") > names.index("report")  # cannot cost the report


def _report_drawn(pipeline, out, executor, capsys) -> tuple[str, dict[str, bytes], str]:
    """The report of the pipeline's families, its sections drawn beside (or before) the page.

    Its text, its figure files and the lines it told, which must have waited for the page.
    """
    context = RunContext(inputs=["a.csv"], out=out, executor=executor)
    with printed("stdout"), background_jobs(context):
        done = {**pipeline.results, "report_sections": report_sections(context, pipeline.results)}
        if capsys.readouterr().out:
            raise AssertionError("the sections told something before the page was written")
        page = report(context, done).path
    figures = {path.name: path.read_bytes() for path in (out / "report_figures").iterdir()}
    text = re.sub(r"\d{4}-\d\d-\d\d \d\d:\d\d UTC", "(written)", page.read_text())  # its minute
    return text, figures, capsys.readouterr().out


def test_sections_drawn_in_a_worker_make_the_report_drawn_in_place(pipeline, tmp_path, capsys):
    # A process executor draws the families' sections in one more process
    # while the stages after them run; a serial one, in place. Same page.
    in_place = _report_drawn(pipeline, tmp_path / "serial", SerialExecutor(), capsys)
    beside = _report_drawn(pipeline, tmp_path / "processes", ProcessExecutor(2), capsys)
    assert beside[0] == in_place[0] and beside[1] == in_place[1] and len(beside[1]) >= 3
    assert beside[2] == in_place[2] and "report: white.nc (1 of 1)" in beside[2]


def test_a_stage_without_a_name_of_its_own_is_refused(pipeline):
    context = RunContext(inputs=["a.csv"], out="out", executor=SerialExecutor())
    for stages in ((ingest, ingest), (lambda context, done: None,)):
        with pytest.raises(bj.InputError, match="needs a name of its own"):
            run_pipeline(context, stages)


def test_an_unknown_figure_format_is_refused_before_a_log_is_read(tmp_path):
    with pytest.raises(bj.InputError, match=r"unknown figure formats \['eps'\]") as refused:
        RunContext(inputs=["a.csv"], out=tmp_path, executor=SerialExecutor(),
                   figure_formats=("png", "eps"))  # fmt: skip
    assert refused.value.field == "figure_formats" and not any(tmp_path.iterdir())
    context = RunContext(inputs=["a.csv"], out=tmp_path, executor=SerialExecutor())
    assert context.figure_formats == ("png",)  # SVG on request
