"""Imitation of the scripted planner: a network-only policy cloned from its actions.

    python -m agents.imitation [--episodes N] [--lift-episodes N] [--dagger-iters K]
        [--out DIR] [--workers 2]

1. **Expert data.** :class:`agents.scripted.ScriptedPolicy` plays random shapes of the
   training distribution, the env set-up it is evaluated in (``agents.evaluate``'s
   ``SCRIPTED_KWARGS``: the scene's start, palm control; ``--episodes``) and from the
   planner's placement (the lifting task, ``--lift-episodes``), with the observation's hand
   features, on seeds ``--seed + k``, refused where they meet the held-out and validation
   seeds (1,000,000 to 2,999,999). Every step records ``(observation, expert action)``; the
   expert's actions are float32 in the env's ``Box(-1, 1)`` (checked). Once the expert's plan
   is played, ``--hold-steps`` steps of holding still are kept and the episode ends, so that
   the long holds do not outweigh the motion. Episodes the planner does not grasp are left
   out unless ``--keep-failures``.
2. **Behaviour cloning** into a stable-baselines3 PPO policy (``MlpPolicy``): the actor's
   mean is fitted to the expert's actions by mean squared error (Adam, ``--epochs``), on
   observations normalized as ``VecNormalize`` does, with the data's mean and variance
   (saved as ``vecnormalize.pkl``).
3. **DAgger** (``--dagger-iters`` rounds): the current network plays ``--dagger-episodes``
   new training episodes (both starts, in the proportion of step 1); at every
   ``--query-every``-th step the expert is asked for its action at the visited state: a
   fresh ``ScriptedPolicy`` planned from that state (``agents.expert.expert_action``; its
   exploratory search, seconds of simulation, is left out, and a state from which it has
   no plan gets no label). The labels join the data and the network is trained again from
   the previous weights.

Writes into ``--out`` a model directory that ``agents.evaluate --models`` and
``agents.train_ppo -i`` read (``model.zip``, ``vecnormalize.pkl``, ``config.yml``: the entry
of ``FrictionlessGraspRandomShapes-v0`` with ``hand_features``, ``train_stats.json``), the
data (``expert.npz``), ``round_<k>/`` (the model after each round), ``progress.csv`` (one
row per round: samples, losses, the network's success in the DAgger episodes) and
``training.md``, the training page (``--page`` elsewhere; ``--report RUN`` writes it again
for a finished run). ``--dagger-weight`` weighs each DAgger label in the loss. At test
time the model is its network alone on the env's observation: no planner, no simulator
calls. The recipe and results: ``docs/imitation.md``. The expert and its episodes:
``agents.expert``; behaviour cloning and the model directory: ``agents.cloning``; the
training page: ``agents.imitation_page``.
"""

from __future__ import annotations

import argparse
import csv
import math
import os
import platform
import shlex
import sys
import time
import zipfile
from pathlib import Path

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")

import numpy as np

from agents.cloning import (
    behaviour_clone,
    mse,
    new_model,
    sample_weights,
    save_model,
    set_normalization,
)
from agents.episodes import seed_problem
from agents.expert import (
    ENV_ID,
    STARTS,
    check_actions,
    dagger_episode,
    expert_episode,
    interleave,
    make_env,
    run_jobs,
    stack_samples,
)
from agents.imitation_page import training_page
from agents.provenance import git_commit, utc_now
from grasp_env.cli import (
    HelpFormatter,
    existing_file,
    nonnegative_int,
    out_dir_problem,
    positive_float,
    positive_int,
    seed_int,
    workers,
)


def _net_arch(text: str) -> list[int]:
    try:
        sizes = [int(s) for s in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected sizes like 256,256, got {text!r}") from None
    if not sizes or min(sizes) < 1:
        raise argparse.ArgumentTypeError(f"expected positive sizes, got {text!r}")
    return sizes


# ---------------------------------------------------------------------- main
#: The expert data's numbers: flag, type, default, help.
EXPERT_OPTIONS = (
    ("--episodes", nonnegative_int, 300, "expert episodes from the scene's start"),
    ("--lift-episodes", nonnegative_int, 150, "expert episodes from the planner's placement"),
    ("--seed", seed_int, 0, "first training seed (default: 0)"),
    ("--hold-steps", nonnegative_int, 10, "steps kept after the expert's plan is played"),
)
#: Cloning's, DAgger's and the run's numbers: flag, type, default (None: unset), help.
TRAINING_OPTIONS = (
    ("--dagger-iters", nonnegative_int, 2, "DAgger rounds"),
    ("--dagger-episodes", positive_int, 60, "network episodes per round"),
    ("--query-every", positive_int, 4, "the expert labels every this many visited states"),
    ("--epochs", positive_int, 30, "BC epochs (first fit)"),
    ("--dagger-weight", positive_float, 1.0,
     "weight of a DAgger label in the loss, against 1 for an expert episode's sample"),
    ("--dagger-epochs", positive_int, 15, "BC epochs after each round"),
    ("--batch-size", positive_int, 256, "BC batch size"),
    ("--lr", positive_float, 1e-3, "BC learning rate (Adam)"),
    ("--net-arch", _net_arch, "256,256", "hidden sizes, e.g. 256,256"),
    ("--workers", workers, 2, "processes for episodes"),
    ("--collect-minutes", positive_float, None,
     "stop starting expert episodes after this wall time (default: none)"),
    ("--max-minutes", positive_float, None,
     "start no DAgger episode or round after this wall time (default: none)"),
    ("--threads", positive_int, 1, "torch threads for BC"),
)  # fmt: skip


#: The arrays of the expert data (``expert.npz``) that cloning reads, one row per sample.
DATA_KEYS = ("obs", "act", "round")


def read_data(path: Path) -> dict[str, np.ndarray]:
    """The expert data of an earlier run (``expert.npz``), checked before any work: every
    array of :data:`DATA_KEYS`, at least one sample, as many of each, observations as wide as
    the env's and actions in its action space; a one-line ``ValueError`` naming the file."""
    try:
        with np.load(path) as npz:  # no pickles: allow_pickle is off
            data = {k: npz[k] for k in npz.files}
    except (OSError, ValueError, EOFError, TypeError, zipfile.BadZipFile) as exc:
        reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise ValueError(f"{str(path)!r} is not an .npz file of arrays ({reason})") from None
    if missing := [k for k in DATA_KEYS if k not in data]:
        raise ValueError(f"{str(path)!r} has no {', '.join(missing)}: not an expert.npz")
    env = make_env("scene")
    samples = len(data["act"])
    shapes = {
        "obs": (samples, env.observation_space.shape[0]),
        "act": (samples, env.action_space.shape[0]),
        "round": (samples,),
    }
    if samples == 0:
        raise ValueError(f"{str(path)!r} holds no samples")
    for key, shape in shapes.items():
        if data[key].shape != shape:
            raise ValueError(f"{str(path)!r}: {key} of shape {data[key].shape}, expected {shape}")
    try:
        check_actions(data["act"], env.action_space)
    except ValueError as exc:
        raise ValueError(f"{str(path)!r}: {exc}") from None
    return data


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m agents.imitation",
        description="Clone the scripted planner into a network-only PPO policy: expert data "
        "on training shapes, behaviour cloning, DAgger rounds. Writes a model directory "
        "(model.zip, vecnormalize.pkl, config.yml, train_stats.json), expert.npz and "
        "progress.csv into --out; see docs/imitation.md.",
        formatter_class=HelpFormatter,
    )
    p.add_argument("--out", type=Path, default=Path("runs/imitation"), help="output directory")
    for flag, kind, default, text in EXPERT_OPTIONS:
        p.add_argument(flag, type=kind, default=default, help=text)
    p.add_argument(
        "--keep-failures", action="store_true", help="also keep the episodes the planner fails"
    )
    p.add_argument(
        "--data",
        type=existing_file,
        help="expert data (expert.npz of an earlier run) instead of step 1",
    )
    for flag, kind, default, text in TRAINING_OPTIONS:
        p.add_argument(flag, type=kind, default=default, help=text)
    p.add_argument(
        "--report",
        type=Path,
        metavar="RUN",
        help="only write the training page of a finished run folder (to --page) and exit",
    )
    p.add_argument(
        "--page",
        type=Path,
        help="the training page's path (default: RUN/training.md; runs write OUT/training.md)",
    )
    return p


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    parser = build_parser()
    args = parser.parse_args(argv)
    command = shlex.join(["python", "-m", "agents.imitation", *argv])
    if args.report is not None:
        for name in ("train_stats.json", "progress.csv"):
            if not (args.report / name).is_file():
                parser.error(f"--report {str(args.report)!r} has no {name} (not a finished run)")
        page = args.page or args.report / "training.md"
        if page.is_dir() or not page.parent.is_dir():
            parser.error(f"--page {str(page)!r}: not a file in an existing folder")
        page.write_text(training_page(args.report, command, utc_now(), git_commit()))
        print(f"wrote {page}")
        return 0
    n_collect = 0 if args.data else args.episodes + args.lift_episodes
    n_dagger = args.dagger_iters * args.dagger_episodes
    if problem := seed_problem(args.seed, n_collect + n_dagger):
        parser.error(problem)
    if args.data is not None:
        try:
            data = read_data(args.data)
        except ValueError as exc:
            parser.error(f"--data {exc}")
    if (args.out / "model.zip").exists():
        parser.error(f"--out {args.out} already holds a model.zip")
    if problem := out_dir_problem(args.out):
        parser.error(f"--out {problem}")
    if args.data is None and n_collect == 0:
        parser.error("--episodes 0 and --lift-episodes 0: no expert data (or give --data)")

    import torch

    torch.set_num_threads(args.threads)
    t_start = time.monotonic()
    deadline = t_start + 60 * args.max_minutes if args.max_minutes else None
    collect_deadline = t_start + 60 * args.collect_minutes if args.collect_minutes else None
    if deadline is not None:
        collect_deadline = min(deadline, collect_deadline or deadline)

    def log(msg: str) -> None:
        print(f"[{time.monotonic() - t_start:7.0f} s] {msg}", file=sys.stderr, flush=True)

    # 1. expert data
    width_obs = make_env("scene").observation_space.shape[0]
    if args.data is not None:
        log(f"expert data from {args.data}: {len(data['act'])} samples")
        collected: list[dict] = []
    else:
        jobs = interleave(
            [("scene", args.seed + k, args.hold_steps) for k in range(args.episodes)],
            [
                ("placement", args.seed + args.episodes + k, args.hold_steps)
                for k in range(args.lift_episodes)
            ],
        )
        log(f"collecting {len(jobs)} expert episodes ({args.workers} workers)")
        collected = run_jobs(expert_episode, jobs, args.workers, collect_deadline, "expert")
        kept = [e for e in collected if e["success"] or args.keep_failures]
        data = {
            "obs": stack_samples(kept, "obs", width_obs),
            "act": stack_samples(kept, "act", 5),
            "round": np.zeros(sum(len(e["act"]) for e in kept), np.int16),
            "seeds": np.array([e["seed"] for e in collected]),
            "seed_success": np.array([e["success"] for e in collected]),
        }
        np.savez_compressed(args.out / "expert.npz", **data)
        log(
            f"expert: {sum(e['success'] for e in collected)}/{len(collected)} grasped, "
            f"{len(kept)} episodes kept, {len(data['act'])} samples -> {args.out}/expert.npz"
        )
    space = make_env("scene").action_space
    check_actions(data["act"], space)

    # 2. behaviour cloning
    model, venv = new_model(args.net_arch, seed=args.seed)
    norm = venv
    set_normalization(norm, data["obs"])
    log(f"behaviour cloning on {len(data['act'])} samples, {args.epochs} epochs")
    history = behaviour_clone(
        model, norm, data["obs"], data["act"], args.epochs, args.batch_size, args.lr,
        args.seed, log=log, weights=sample_weights(data, args.dagger_weight),
    )  # fmt: skip
    progress = [
        {
            "round": 0,
            "samples": len(data["act"]),
            "train_loss": history[-1]["train_loss"],
            "val_loss": history[-1]["val_loss"],
            "episodes": "",
            "network_success": "",
            "queries": "",
            "unlabelled": "",
            "minutes": (time.monotonic() - t_start) / 60,
        }
    ]
    stats = {
        "command": command,
        "date": utc_now(),
        "commit": git_commit(),
        "method": "behaviour cloning of agents.scripted.ScriptedPolicy, then DAgger",
        "env_id": ENV_ID,
        "starts": list(STARTS),
        "expert_episodes": len(collected),
        "expert_success": sum(e["success"] for e in collected),
        "args": {k: (str(v) if isinstance(v, Path) else v) for k, v in vars(args).items()},
        "python": platform.python_version(),
        "torch": torch.__version__,
    }
    ckpt = args.out / "round_0"
    save_model(model, norm, ckpt, {**stats, "rounds": progress}, args.net_arch)

    # 3. DAgger
    seed = args.seed + n_collect
    n_scene = args.episodes if args.data is None else 1
    share = n_scene / max(1, n_scene + (args.lift_episodes if args.data is None else 1))
    for it in range(1, args.dagger_iters + 1):
        if deadline is not None and time.monotonic() > deadline:
            log("time is up: no more DAgger rounds")
            break
        k_scene = round(args.dagger_episodes * share)
        jobs = interleave(
            [(str(ckpt), "scene", seed + k, args.query_every, it) for k in range(k_scene)],
            [
                (str(ckpt), "placement", seed + k, args.query_every, it)
                for k in range(k_scene, args.dagger_episodes)
            ],
        )
        seed += args.dagger_episodes
        log(f"DAgger round {it}: {len(jobs)} network episodes, expert every {args.query_every}")
        episodes = run_jobs(dagger_episode, jobs, args.workers, deadline, f"dagger {it}")
        new_obs = stack_samples(episodes, "obs", width_obs)
        new_act = stack_samples(episodes, "act", 5)
        before = mse(model, norm, new_obs, new_act) if len(new_act) else math.nan
        data["obs"] = np.concatenate([data["obs"], new_obs])
        data["act"] = np.concatenate([data["act"], new_act])
        data["round"] = np.concatenate([data["round"], np.full(len(new_act), it, np.int16)])
        np.savez_compressed(args.out / "expert.npz", **data)
        ok = sum(e["success"] for e in episodes)
        log(
            f"round {it}: network grasped {ok}/{len(episodes)}; {len(new_act)} labels "
            f"(loss on them {before:.4f}); retraining on {len(data['act'])} samples"
        )
        history = behaviour_clone(
            model, norm, data["obs"], data["act"], args.dagger_epochs, args.batch_size,
            args.lr, args.seed + it, log=log, weights=sample_weights(data, args.dagger_weight),
        )  # fmt: skip
        progress.append(
            {
                "round": it,
                "samples": len(data["act"]),
                "train_loss": history[-1]["train_loss"],
                "val_loss": history[-1]["val_loss"],
                "episodes": len(episodes),
                "network_success": ok / max(1, len(episodes)),
                "queries": sum(e["queries"] for e in episodes),
                "unlabelled": sum(e["unlabelled"] for e in episodes),
                "minutes": (time.monotonic() - t_start) / 60,
            }
        )
        ckpt = args.out / f"round_{it}"
        save_model(model, norm, ckpt, {**stats, "rounds": progress}, args.net_arch)

    stats["rounds"] = progress
    stats["samples"] = len(data["act"])
    stats["wall_minutes"] = (time.monotonic() - t_start) / 60
    save_model(model, norm, args.out, stats, args.net_arch)
    with open(args.out / "progress.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(progress[0]))
        writer.writeheader()
        writer.writerows(progress)
    page = args.page or args.out / "training.md"
    page.write_text(training_page(args.out, command, utc_now(), git_commit()))
    log(
        f"wrote {args.out}/: model.zip vecnormalize.pkl config.yml train_stats.json "
        f"progress.csv, and {page}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
