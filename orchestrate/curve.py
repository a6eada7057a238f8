"""The learning curve of a training run (`unips.train`'s log.jsonl): its records, a figure, a PNG; what
`orchestrate.gpu_session` brings back as learning_curve.png."""
from __future__ import annotations

import json
from pathlib import Path


def curve_records(log: Path) -> list[dict]:
    """The training records (step, loss) of a run's log.jsonl, in step order."""
    rows = [json.loads(line) for line in log.read_text().splitlines() if line.strip()] if log.is_file() else []
    return sorted((r for r in rows if "loss" in r and "val" not in r), key=lambda r: r["step"])


def curve_figure(records: list[dict], title: str):
    """Training loss against step, a matplotlib Figure (640 x 400 pixels; `scenes.report.charts`)."""
    from scenes.report.charts import new_figure

    fig = new_figure(640, 400, layout="constrained")
    ax = fig.subplots()
    ax.set_title(title, loc="left", fontsize=9)
    ax.plot([r["step"] for r in records], [r["loss"] for r in records], color="#1f77b4")
    ax.set(xlabel="step", ylabel="training loss")
    return fig


def plot_curve(records: list[dict], path: Path, title: str) -> None:
    """Write `curve_figure` as a PNG."""
    from scenes.report.charts import write_figure

    write_figure(path, curve_figure(records, title))
