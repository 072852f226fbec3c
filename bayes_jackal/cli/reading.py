"""How the commands read their inputs: the robot profile and the logs, each on its own or all."""

from __future__ import annotations

import argparse
import contextlib
from collections.abc import Callable, Iterable
from contextlib import AbstractContextManager
from pathlib import Path
from typing import Any

from .._runtime import InputError, describe, each_input
from ..io import Experiment, ReadOptions, check_column_roles, load_experiments, read_logs
from ..model import RobotProfile, load_profile
from .output import Failures, Reporter
from .paths import check_named_outputs


def robot_profile(args: argparse.Namespace) -> RobotProfile:
    return load_profile(args.robot)


def robot_with_topics(args: argparse.Namespace) -> RobotProfile:
    """The profile with ``--topic ROLE NAME`` overrides applied."""
    robot = robot_profile(args)
    unknown = [role for role, _ in args.topic if role not in robot.topics]
    if unknown:
        raise InputError(
            f"unknown topic role(s) {unknown}; use {sorted(robot.topics)}", field="--topic"
        )
    return robot.replace(topics={**robot.topics, **dict(args.topic)})


def each_experiment(
    args: argparse.Namespace,
    out: Reporter,
    work: Callable[[Experiment], Any],
    outputs: Callable[[Experiment], list[Path]] | None = None,
    *,
    results: Callable[..., AbstractContextManager[Iterable[tuple[str, Any]]]] | None = None,
) -> tuple[list[tuple[Experiment, Any]], dict[str, str], int]:
    """Without pooling: read and process each experiment on its own.

    A bad input is reported on stderr as it is met, and the others finish.
    ``outputs`` gives the files an experiment's work writes: they are checked
    for every experiment before any work (:func:`.paths.check_named_outputs`).
    ``results(loaded, fail)``: the experiments' jobs (e.g. all at once on an
    executor), a context holding (input, value) pairs as each input's jobs
    finish; ``loaded`` maps input -> Experiment, and ``fail(input,
    exception)`` reports an input whose jobs failed. ``work`` is then
    called as ``work(experiment, value)`` in this process; without
    ``results``, as ``work(experiment)`` on each in turn.

    Returns
    -------
    done : list of (Experiment, result)
    failed : dict of str to str
        Input -> reason.
    code : int
        The exit code: 2 when an input was bad, 1 when one failed otherwise.
    """
    failures = Failures(args.debug)
    loaded, failed = read_logs(args.experiments, **log_options(args), on_failure=failures)
    if outputs is not None:
        checked, refused = each_input(
            loaded,
            lambda given: check_named_outputs(args, outputs(loaded[given])),
            on_failure=failures,
        )
        loaded, failed = {given: loaded[given] for given in checked}, failed | refused

    def fail(given: str, exc: Exception) -> None:
        failed[given] = describe(exc, given)
        failures(given, exc)

    done: dict[str, Any] = {}
    in_turn = contextlib.nullcontext((given, None) for given in loaded)
    with in_turn if results is None else results(loaded, fail) as finished:
        for given, value in finished:  # in the order they finish
            inputs = (loaded[given],) if results is None else (loaded[given], value)
            result, crashed = each_input(
                [given], lambda _, i=inputs: work(*i), catch=Exception, on_failure=failures
            )
            done |= result
            failed |= crashed
    done = {given: done[given] for given in loaded if given in done}
    if failed:
        total = len(args.experiments)
        out.say(f"{len(done)} of {total} experiments done; failed: {', '.join(failed)}")
    return [(loaded[given], result) for given, result in done.items()], failed, failures.code


def read_options(args: argparse.Namespace) -> ReadOptions:
    """The flags of reading logs: window, longest gap, column roles, rate, velocities.

    A role given twice is refused: the later would silently win.
    """
    names: dict[str, list[str]] = {}
    for role, name in args.column:
        names.setdefault(role, []).append(name)
    twice = {role: given for role, given in names.items() if len(given) > 1}
    if twice:
        role, given = next(iter(twice.items()))
        raise InputError(f"role {role!r} is given {len(given)} times: {given}", field="--column")
    return ReadOptions(
        window=args.window,
        max_gap=args.max_gap,
        columns=check_column_roles(dict(args.column), field="--column"),
        rate=args.rate,
        velocities=args.velocities,
    )


def log_options(args: argparse.Namespace) -> dict:
    """Keywords of :func:`~bayes_jackal.io.load_experiments` from the flags of reading logs.

    Those of experiment files, and of bags (``--window``, ``--max-gap``,
    ``--topic``); ``--robot``: topics and wheels of bags, the rate of files.
    """
    options = read_options(args)
    return {
        "robot": robot_with_topics(args),
        "window": options.window,
        "max_gap": options.max_gap,
        **options.table_keywords,
    }


def load_logs(args: argparse.Namespace) -> list:
    """The logs named on the command line, read as the library reads them (all or none)."""
    return load_experiments(args.experiments, **log_options(args))
