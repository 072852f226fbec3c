"""Benchmark: ingesting a 10-minute bag (issue 4 target: under 10 s on 2 cores).

Run by hand: ``python benchmarks/bench_ingest.py``. A 600 s simulated run is
written as a ROS1 bag and a ROS2 (.mcap) bag at the thesis' rates: 72 Hz IMU,
360 Hz motion capture, joint_states and cmd_vel. ``read_bag`` is timed
against the floor of any reader in the same process: rosbags' AnyReader
deserialising every message of the same topics and doing nothing else.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

from rosbags.highlevel import AnyReader

from bayes_jackal import load_profile
from bayes_jackal.io.bag_reading import typestore
from bayes_jackal.io.bag_writer import write_bag
from bayes_jackal.io.bags import read_bag
from bayes_jackal.io.simulate import Series, simulate_experiment

DURATION = 600.0


def deserialise_only(path: Path, topics: list[str], format: str) -> int:
    """The baseline: read and deserialise every message of ``topics``."""
    count = 0
    with AnyReader([path], default_typestore=typestore(format)) as reader:
        connections = [c for c in reader.connections if c.topic in topics]
        for connection, _, raw in reader.messages(connections=connections):
            reader.deserialize(raw, connection.msgtype)
            count += 1
    return count


def main() -> None:
    robot = load_profile()
    experiment = simulate_experiment(robot, 110.0, 30.0, Series(0.3, 0.3927, DURATION), rng=1)
    topics = list(robot.topics.values())
    with tempfile.TemporaryDirectory() as folder:
        for format, suffix in (("ros1", ".bag"), ("ros2", ".mcap")):
            path = write_bag(experiment, Path(folder) / f"run{suffix}", robot, format, rng=2)
            start = time.perf_counter()
            count = deserialise_only(path, topics, format)
            floor = time.perf_counter() - start
            start = time.perf_counter()
            ingested = read_bag(path, robot)
            seconds = time.perf_counter() - start
            print(
                f"{format} {suffix}: {DURATION:.0f} s run, {count} messages, "
                f"{path.stat().st_size / 1e6:.0f} MB: read_bag {seconds:5.2f} s "
                f"(target < 10 s); deserialise-only baseline {floor:5.2f} s; "
                f"ratio {seconds / floor:.2f}; {len(ingested.t)} samples out"
            )


if __name__ == "__main__":
    main()
