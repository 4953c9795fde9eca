"""How well ``auvsim serve --dvl a50`` keeps time (target: within 5 ms of the mission clock
at 1x, and at least 100x real time when asked).

It generates one mission with the ``navigator`` preset's sensors pinging at ``--rate`` Hz
(or takes ``--dataset``), then runs the command in a fresh interpreter with
``--wait-for-client`` and reads its reports over TCP from this process, three times:

- at ``--speed 1`` for ``--seconds`` of mission: each velocity report's lateness, as the
  server stamps it (``time_of_transmission - time_of_validity``: written minus due, both
  Unix microseconds, the due time on the mission clock from the start) and as this client
  receives it (the wall clock at the line's arrival minus ``time_of_validity``);
- at ``--speed 100`` and ``--speed 10000`` over the whole mission: the mission time the
  reports span over the wall time between the first and the last one received (the
  speed achieved).

Figures: the median, 95th and 99th percentiles and the largest lateness in ms, and the
share of reports within 5 ms. The machine's load shows in them: run it on an idle one.

    .venv/bin/python benchmarks/serve.py [--seconds 30] [--rate 10] [--dataset FILE]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]


def make_dataset(path: Path, seconds: float, rate: float) -> None:
    sys.path.insert(0, str(REPO))
    from auvsim.config import MissionConfig, ScenarioConfig
    from auvsim.runs.generate import generate
    from auvsim.runs.presets import preset

    base = preset("navigator")
    config = dataclasses.replace(
        base, dvl=dataclasses.replace(base.dvl, rate_hz=rate),
        missions=(MissionConfig(name="bench", seed=1,
                                scenario=ScenarioConfig(duration=seconds)),))
    generate(config, path, workers=1, progress=False)


def play(dataset: Path, speed: float) -> tuple[list[dict], np.ndarray]:
    """The velocity reports of one run at ``speed``, and the wall-clock time (Unix s) at
    which each line arrived."""
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    server = subprocess.Popen(
        [sys.executable, "-m", "auvsim", "serve", str(dataset), "--dvl", "a50", "--port",
         "0", "--speed", repr(speed), "--wait-for-client"],
        env=env, stdout=subprocess.PIPE, text=True)
    try:
        port = int(server.stdout.readline().split("127.0.0.1:")[1].split(":")[0])
        reports, arrived = [], []
        with socket.create_connection(("127.0.0.1", port)) as client:
            client.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            stream = client.makefile("rb")
            for line in stream:
                now = time.time()
                report = json.loads(line)
                if report.get("type") == "velocity":
                    reports.append(report)
                    arrived.append(now)
        server.wait(timeout=60)
    finally:
        server.kill()
        server.wait()
    return reports, np.asarray(arrived)


def lateness_line(name: str, late_ms: np.ndarray) -> str:
    p50, p95, p99 = np.percentile(late_ms, [50, 95, 99])
    return (f"  {name:34s} median {p50:6.2f}  p95 {p95:6.2f}  p99 {p99:6.2f}  max "
            f"{late_ms.max():6.2f} ms; within 5 ms: {100 * np.mean(late_ms <= 5):5.1f} %")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=30.0,
                        help="mission length, s (the 1x run takes that long)")
    parser.add_argument("--rate", type=float, default=10.0, help="ping rate, Hz")
    parser.add_argument("--dataset", type=Path, help="a dataset to play (default: made)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        dataset = args.dataset
        if dataset is None:
            dataset = Path(tmp) / "serve-bench.h5"
            make_dataset(dataset, args.seconds, args.rate)
        reports, arrived = play(dataset, 1.0)
        validity = np.array([r["time_of_validity"] for r in reports]) / 1e6
        sent = np.array([r["time_of_transmission"] for r in reports]) / 1e6
        print(f"auvsim serve --dvl a50 --speed 1: {len(reports)} velocity reports over "
              f"{validity[-1] - validity[0]:.1f} s")
        print(lateness_line("written - due (server's stamps)", 1e3 * (sent - validity)))
        print(lateness_line("received - due (this client)", 1e3 * (arrived - validity)))
        for speed in (100.0, 10000.0):
            reports, arrived = play(dataset, speed)
            span = (reports[-1]["time_of_validity"] - reports[0]["time_of_validity"]) / 1e6
            wall = arrived[-1] - arrived[0]
            print(f"auvsim serve --dvl a50 --speed {speed:g}: {len(reports)} reports, "
                  f"{span:.1f} s of mission in {wall:.3f} s: {span / wall:.1f}x real time")
    return 0


if __name__ == "__main__":
    sys.exit(main())
