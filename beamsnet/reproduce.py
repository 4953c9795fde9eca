"""``beamsnet reproduce paper-sim``: the paper's simulation experiment end to end.

Generate (or read) the paper's dataset, train BeamsNetV1 and V2 on each speed's mission as
the paper did (lr 0.01, 30 epochs, batch 4), evaluate every estimator on each mission's
test split, and write a report with the paper's Table 1 beside ours.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

from .evaluate import estimates, markdown, table
from .train import TrainConfig, file_identity, load, train

# The paper's Table 1: RMSE improvement over LS, %, per speed
# (../shared/reference/beamsnet-reference.md).
PAPER_TABLE_1 = {1: {"v1": 75.45, "v2": 66.72}, 2: {"v1": 82.45, "v2": 77.91},
                 3: {"v1": 86.76, "v2": 83.32}}


def paper_sim(experiment: str, *, data: Path | None, duration: float, epochs: int,
              out: Path, runs: Path = Path("runs"), progress: bool = True) -> Path:
    """Run the experiment; the report goes to ``out``, the trained models to ``runs``."""
    from auvsim.config import ScenarioConfig
    from auvsim.generate import generate
    from auvsim.presets import preset

    config = preset(experiment)
    config = dataclasses.replace(config, missions=tuple(
        dataclasses.replace(m, scenario=ScenarioConfig(
            **{**dataclasses.asdict(m.scenario), "duration": duration}))
        for m in config.missions))
    if data is None:
        data = Path("datasets") / f"{experiment}_{duration:g}s.h5"
        if not data.exists():
            generate(config, data, progress=progress)
    runs = runs / experiment
    sections, summary = [], []
    for mission in config.missions:
        speed = round(mission.scenario.speed)
        trained = []
        for model in ("v1", "v2"):
            run = runs / mission.name / model
            config = TrainConfig(model=model, epochs=epochs, missions=(mission.name,))
            if not _trained(run, config, data):
                train(data, config, run, progress=progress)
            trained.append(run)
        windows, predictions = estimates(trained, data, missions=[mission.name])
        rows = table(windows, predictions)
        sections.append(markdown(rows, f"{speed} m/s ({mission.name}), test split: "
                                       f"{len(windows.target)} pings"))
        by_model = {name.split(" ")[0]: row for name, row in rows.items()}
        summary.append((speed, by_model))
    report = out / f"{experiment}.md"
    out.mkdir(parents=True, exist_ok=True)
    report.write_text(_report(experiment, data, duration, epochs, summary, sections))
    _figure(summary, out / f"{experiment}.png")
    return report


def _trained(run: Path, config: TrainConfig, data: Path) -> bool:
    """Whether ``run`` already holds this config trained on this very file (re-running the
    report then re-evaluates without retraining)."""
    if not (run / "model.pt").exists():
        return False
    _, checkpoint = load(run)
    return (checkpoint["train_config"] == dataclasses.asdict(config)
            and checkpoint["dataset"]["sha256"] == file_identity(data)["sha256"])


def _report(experiment, data, duration, epochs, summary, sections) -> str:
    lines = [
        f"# {experiment}: the BeamsNet paper's simulation, reproduced",
        "",
        f"Made by `beamsnet reproduce {experiment}` (dataset `{data}`, {duration:g} s per "
        f"speed, {epochs} epochs). RMSE improvement over least squares on the speed, %, "
        "on each mission's test split (last 25 %):",
        "",
        "| speed | V1 ours | V1 paper | V2 ours | V2 paper | affine calibration | Kalman |",
        "|---|---|---|---|---|---|---|",
    ]
    for speed, rows in summary:
        paper = PAPER_TABLE_1.get(speed, {})
        lines.append(
            f"| {speed} m/s | {rows['BeamsNetV1']['improvement']:.2f} | "
            f"{paper.get('v1', float('nan')):.2f} | {rows['BeamsNetV2']['improvement']:.2f} | "
            f"{paper.get('v2', float('nan')):.2f} | "
            f"{rows['Affine']['improvement']:.2f} | {rows['KF']['improvement']:.2f} |")
    lines += [
        "",
        f"![improvement per speed]({experiment}.png)",
        "",
        "How to read it. Each mission is a straight line at constant speed, so the true DVL "
        "velocity barely changes and the test split (the last 25 % of the mission) has "
        "almost the velocity the training split had. An estimator fitted on the training "
        "split can therefore do well by learning that constant rather than by undoing the "
        "sensor errors: the affine calibration is such an estimator, and where it matches "
        "or beats BeamsNet the networks have no advantage on this data. Improvements far "
        "above the paper's say more about this constancy than about the networks. The "
        "manoeuvre stress test (`beamsnet stress`) is where the difference shows.",
        "",
        "## Full tables",
        "",
    ]
    return "\n".join(lines) + "\n" + "\n\n".join(sections) + "\n"


def _figure(summary, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    speeds = [s for s, _ in summary]
    series = {
        "V1 ours": [r["BeamsNetV1"]["improvement"] for _, r in summary],
        "V1 paper": [PAPER_TABLE_1.get(s, {}).get("v1", np.nan) for s in speeds],
        "V2 ours": [r["BeamsNetV2"]["improvement"] for _, r in summary],
        "V2 paper": [PAPER_TABLE_1.get(s, {}).get("v2", np.nan) for s in speeds],
        "affine": [r["Affine"]["improvement"] for _, r in summary],
        "Kalman": [r["KF"]["improvement"] for _, r in summary],
    }
    fig, ax = plt.subplots(figsize=(8, 4))
    width = 0.8 / len(series)
    for i, (name, values) in enumerate(series.items()):
        ax.bar(np.arange(len(speeds)) + i * width, values, width, label=name)
    ax.set_xticks(np.arange(len(speeds)) + 0.4 - width / 2, [f"{s} m/s" for s in speeds])
    ax.set_ylabel("RMSE improvement over LS, %")
    ax.set_ylim(0, 125)  # room for the legend above the bars
    ax.legend(ncol=6, fontsize=8, loc="upper center")
    ax.grid(axis="y", alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
