"""The training page of an ``agents.imitation`` run: its expert data and, per round, the
samples, the losses and the network's success in the DAgger episodes."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np

from agents.provenance import generated_header


def training_page(run: Path, command: str, date: str, commit: str) -> str:
    """The training page of a run folder (its ``train_stats.json`` and ``progress.csv``):
    the expert data, and per round the samples, the losses and the network's success in the
    DAgger episodes (training seeds, the network alone playing)."""
    stats = json.loads((run / "train_stats.json").read_text())
    with open(run / "progress.csv", newline="") as f:
        rounds = list(csv.DictReader(f))
    run_args = stats.get("args", {})
    played, grasped = stats["expert_episodes"], stats["expert_success"]
    seeds, source = "-", "collected by this run"
    if (run / "expert.npz").is_file():  # the data's own record, also where it came by --data
        with np.load(run / "expert.npz") as d:
            if "seeds" in d.files and len(d["seeds"]):
                played, grasped = len(d["seeds"]), int(d["seed_success"].sum())
                seeds = f"{d['seeds'].min()}..{d['seeds'].max()}"
    if run_args.get("data"):
        source = f"from `{run_args['data']}`"
        unused = ("episodes", "lift_episodes", "hold_steps", "keep_failures", "collect_minutes")
        run_args = {k: v for k, v in run_args.items() if k not in unused}
    lines = [
        f"# Imitation of the scripted planner: training of `{run.as_posix()}`",
        "",
        *generated_header("python -m agents.imitation --report", command, date, commit),
        f"The run: `{stats.get('command', 'python -m agents.imitation')}` with "
        + ", ".join(f"`{k}={v}`" for k, v in run_args.items() if v is not None)
        + (f"; run at commit `{stats['commit']}`, {stats['date']}" if "commit" in stats else "")
        + f"; {stats.get('wall_minutes', math.nan):.0f} minutes of wall time.",
        "",
        f"Expert episodes: {grasped} of {played} grasped by the planner (training seeds "
        f"{seeds}, both starts; {source}); samples after the last round: {stats['samples']}.",
        "",
        "Round 0 is behaviour cloning on the expert's episodes; round k >= 1 adds the expert's "
        "labels of the states the round k-1 network visited. Network success in row k: the "
        "round k-1 network alone, deterministic, in round k's DAgger episodes (training "
        "seeds, both starts); the last round's network is measured by agents.evaluate.",
        "",
        "| round | samples | train loss | validation loss | DAgger episodes "
        "| network success | expert queries | unlabelled | minutes |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- |",
    ]

    def num(text: str, fmt: str) -> str:
        return format(float(text), fmt) if text not in ("", None) else "-"

    for r in rounds:
        lines.append(
            f"| {r['round']} | {r['samples']} | {num(r['train_loss'], '.4f')} "
            f"| {num(r['val_loss'], '.4f')} | {r['episodes'] or '-'} "
            f"| {num(r['network_success'], '.2f')} | {r['queries'] or '-'} "
            f"| {r['unlabelled'] or '-'} | {num(r['minutes'], '.0f')} |"
        )
    return "\n".join(lines) + "\n"
