"""The evaluation's episodes: the suites (the env set-ups and seeds every policy meets), the
policies (:class:`PolicySpec`: the scripted planner, trained models, RLlib checkpoints, a
random policy) and one episode of a policy on a suite (:func:`run_episode`), as
``agents.evaluate`` runs them."""

from __future__ import annotations

import functools
import math
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")

import gymnasium as gym
import numpy as np

from agents.models import MODEL_DIR, TEST_TIMES, load_agent, network_action, seed_sampling
from grasp_env.envs.shapes import WIDE_SHAPE_RANGES

#: First seed of the held-out shapes. Training seeds its envs with ``seed + rank`` and its
#: evaluation env with ``seed + 1000`` (small seeds); these streams never meet them.
HELDOUT_SEED = 1_000_000
#: Seeds that training data must not use: the held-out suites' (``agents.evaluate``,
#: 1,000,000 on) and the learning curves' validation episodes (2,000,000 on).
RESERVED_SEEDS = range(1_000_000, 3_000_000)


def seed_problem(seed: int, count: int) -> str | None:
    """Why seeds ``seed .. seed + count - 1`` cannot be training seeds, or None."""
    first, last = seed, seed + count - 1
    if seed < 0:
        return f"--seed must be >= 0, got {seed}"
    if first <= RESERVED_SEEDS[-1] and last >= RESERVED_SEEDS[0]:
        return (
            f"--seed {seed}: the training seeds {first}..{last} meet the held-out and "
            f"validation seeds {RESERVED_SEEDS[0]}..{RESERVED_SEEDS[-1]}"
        )
    return None


#: Env kwargs of the held-out suite: fig13's hand, a new random shape per seed, the hand
#: starting where the scene puts it (the "from anywhere" task).
HELDOUT_KWARGS = {"scene": "fig13", "shape_randomizer": True, "start": "scene"}
#: Env kwargs of the wide held-out suite: the same with the randomizer's wider ranges
#: (``grasp_env.envs.shapes.WIDE_SHAPE_RANGES``: 3-12 vertices, aspect to 1:5).
WIDE_KWARGS = {"scene": "fig13", "shape_randomizer": dict(WIDE_SHAPE_RANGES), "start": "scene"}
#: Env kwargs of the lifting suite: the held-out shapes, the hand starting at the planner's
#: first pre-liftoff placement for each (``start="placement"``, the task of
#: ``FrictionlessGraspLift-v0``).
LIFT_KWARGS = {"scene": "fig13", "shape_randomizer": True, "start": "placement"}
#: Env kwargs of the perturbed-start suite: fig13 from the ``"random"`` start (the pre-liftoff
#: placement perturbed in palm pose and finger angles), one draw per seed.
PERTURBED_KWARGS = {"scene": "fig13", "start": "random"}
#: Env kwargs of the seeded suites, by suite name (every policy meets the same draws).
SHAPE_SUITES = {
    "heldout": HELDOUT_KWARGS,
    "wide": WIDE_KWARGS,
    "lift": LIFT_KWARGS,
    "perturbed": PERTURBED_KWARGS,
}
#: Env set-up of the scripted planner (``agents.scripted.ScriptedPolicy``, which plans from
#: the env's state at every reset with exact knowledge of the scene, as the paper assumes):
#: the scene's start with palm actions, so that where lifting with the palm fixed fails (as
#: in the paper's set-up) it can drive the hand to the whole planner's placement, tilted palm
#: included. On fig13 it never moves the palm.
SCRIPTED_KWARGS = {"palm_control": True, "start": "scene"}
#: Env set-up of the random policy: the paper's (palm fixed where the scene puts it).
RANDOM_KWARGS = {"palm_control": False, "start": "scene"}
#: Env kwargs that a suite or a sweep's level sets and a policy's own set-up must not override
#: (a model trained with ``uncertainty`` or ``friction`` meets every level of the sweep).
SUITE_KEYS = (
    "scene", "shape_randomizer", "start", "time_limit", "shape_pool", "friction", "uncertainty",
)  # fmt: skip
GIF_SCENE, GIF_SIZE, GIF_EVERY = "fig13", (320, 240), 2
#: What each kind of policy calls at test time (``agents.models.TEST_TIMES``); a ``"ppo"``
#: model's is its training entry's (``agents.models.entry_test_time``). An RLlib checkpoint
#: plays on its env id alone.
KIND_TEST_TIMES = {
    "scripted": "planner", "scripted_in_place": "planner", "random": "network",
    "rllib": "network",
}  # fmt: skip
#: The planner kinds: ``"scripted"`` with all its fallbacks; ``"scripted_in_place"`` lifting
#: only from where the env puts the hand (``ScriptedPolicy(fallbacks=False)``: no
#: re-placement, no exploratory lifting), which tells the part of the planner's success that
#: needs a better placement than the start's.
SCRIPTED_KINDS = ("scripted", "scripted_in_place")


# ---------------------------------------------------------------------- policies
@dataclass(frozen=True)
class PolicySpec:
    """A policy to evaluate: ``kind`` is "scripted" or "scripted_in_place"
    (:data:`SCRIPTED_KINDS`), "random", "ppo" (with ``model_dir``) or
    "rllib" (``model_dir`` is an RLlib checkpoint, see ``agents.rllib_policy``); ``wrapper``:
    the wrapper class and arguments of a model that plays beside the planner
    (``agents.planner_base.planner_wrapper``); ``test_time``: what the policy calls at test
    time (``agents.models.TEST_TIMES``; by default its kind's, ``KIND_TEST_TIMES``, and for
    a "ppo" model its wrapper's declaration, ``PlannerAgent.test_time_of``, or ``"network"``
    without one: as ``agents.models.entry_test_time`` reads its entry); ``sampled``: a
    "ppo" model plays actions drawn from its policy's distribution, seeded with the
    episode's seed, instead of the distribution's mean (``agents.models.network_action``)."""

    name: str
    kind: str
    env_kwargs: dict = field(default_factory=dict)
    model_dir: str | None = None
    wrapper: tuple[type[gym.Wrapper], dict] | None = None
    test_time: str = ""
    sampled: bool = False

    def __post_init__(self) -> None:
        if not self.test_time:
            if self.kind == "ppo":  # the network, and what the wrapper it plays through calls
                cls, kwargs = self.wrapper or (None, {})
                test_time = "network" if cls is None else cls.test_time_of(kwargs)
            elif self.kind in KIND_TEST_TIMES:
                test_time = KIND_TEST_TIMES[self.kind]
            else:
                raise ValueError(f"policy {self.name!r}: a {self.kind!r} policy needs test_time")
            object.__setattr__(self, "test_time", test_time)
        if self.test_time not in TEST_TIMES:
            raise ValueError(f"policy {self.name!r}: test_time must be one of {TEST_TIMES}")
        if self.sampled and self.kind != "ppo":
            raise ValueError(f"policy {self.name!r}: only a 'ppo' model plays sampled actions")


def ppo_spec(model_dir: str | os.PathLike, sampled: bool = False) -> PolicySpec:
    """The spec of a trained model directory: its training env set-up (palm control, start,
    the wrapper that plays it beside the planner) from its saved config, with the env's
    default reward weights like every other policy; with ``sampled``, the model playing
    draws from its policy's distribution, named ``ppo_<name>_sampled``."""
    from agents.planner_base import planner_wrapper

    _, _, name, entry = load_agent(model_dir)
    kwargs = {
        k: v
        for k, v in entry.get("env_kwargs", {}).items()
        if k not in SUITE_KEYS and not k.startswith("reward_")  # one return for all policies
    }
    return PolicySpec(
        f"ppo_{name}{'_sampled' if sampled else ''}", "ppo", kwargs, str(model_dir),
        planner_wrapper(entry), sampled=sampled,
    )  # fmt: skip


def rllib_spec(path: str | os.PathLike) -> PolicySpec:
    """The spec of an ``agents.train_rllib`` run directory or checkpoint: the set-up of the
    env id it trained on (the id's registered kwargs and the config's, from the config saved
    beside the checkpoint), less the suite's keys and reward weights as in :func:`ppo_spec`."""
    from agents.rllib_policy import load_run

    checkpoint, env_id, entry = load_run(path)
    set_up = {**gym.spec(env_id).kwargs, **(entry.get("env_kwargs") or {})}
    kwargs = {
        k: v for k, v in set_up.items() if k not in SUITE_KEYS and not k.startswith("reward_")
    }
    return PolicySpec(f"rllib_{env_id}", "rllib", kwargs, str(checkpoint))


def default_policies(
    model_dirs: list[str] | None, rllib_checkpoints: Sequence[str] = (),
    sampled_dirs: Sequence[str] = (), in_place: bool = False,
) -> list[PolicySpec]:  # fmt: skip
    """Scripted (when ``agents.scripted`` exists; with ``in_place`` also the planner lifting
    from where the env puts the hand, ``scripted_in_place``), the models, the models of
    ``sampled_dirs`` playing sampled actions, the RLlib checkpoints, random."""
    if model_dirs is None:
        model_dirs = [str(p.parent) for p in sorted(MODEL_DIR.glob("*/model.zip"))]
    specs = []
    try:
        import agents.scripted  # noqa: F401
    except ImportError:
        print("agents.scripted is not available: the scripted policy is left out")
    else:
        specs.append(PolicySpec("scripted", "scripted", SCRIPTED_KWARGS))
        if in_place:
            specs.append(PolicySpec("scripted_in_place", "scripted_in_place", SCRIPTED_KWARGS))
    specs += [ppo_spec(d) for d in model_dirs]
    specs += [ppo_spec(d, sampled=True) for d in sampled_dirs]
    specs += [rllib_spec(c) for c in rllib_checkpoints]
    specs.append(PolicySpec("random", "random", RANDOM_KWARGS))
    return specs


def make_policy(spec: PolicySpec, env: gym.Env) -> tuple[Callable, Callable]:
    """``(reset(obs, info, seed), act(obs))`` for a spec on an env."""
    if spec.kind in SCRIPTED_KINDS:
        from agents.scripted import ScriptedPolicy

        policy = ScriptedPolicy(env, fallbacks=spec.kind == "scripted")
        return (lambda obs, info, seed: policy.reset(obs, info)), policy.act
    if spec.kind == "random":
        box = env.action_space
        state = {}

        def reset(obs, info, seed):
            state["rng"] = np.random.default_rng(seed)

        def act(obs):
            return state["rng"].uniform(box.low, box.high).astype(np.float32)

        return reset, act
    if spec.kind == "rllib":
        return (lambda obs, info, seed: None), _load_rllib(spec.model_dir).act
    model, norm, _, _ = _load_agent(spec.model_dir)

    def reset(obs, info, seed):
        if spec.sampled:
            seed_sampling(seed)

    return reset, lambda obs: network_action(model, norm, obs, spec.sampled)


_load_agent = functools.cache(load_agent)  # once per model and process


@functools.cache
def _load_rllib(checkpoint: str):
    from agents.rllib_policy import RLlibPolicy

    return RLlibPolicy(checkpoint)


# ---------------------------------------------------------------------- episodes
@dataclass
class Episode:
    """One evaluated episode; ``grip`` is y* and ``grip_W`` is y* / object weight."""

    suite: str
    scene: str
    policy: str
    seed: int
    steps: int = 0
    ret: float = 0.0
    success: bool = False
    reached: bool = False
    steps_to_closure: float = math.nan
    grip: float = math.nan
    grip_W: float = math.nan
    dropped: bool = False
    jammed: bool = False
    error: str = ""
    friction: float = 0.0
    uncertainty: float = 0.0


def make_env(spec: PolicySpec, suite_kwargs: dict, max_steps: int | None, **extra) -> gym.Env:
    kwargs = {**spec.env_kwargs, **suite_kwargs, **extra}
    if max_steps is not None:
        kwargs["time_limit"] = max_steps
    env = gym.make("FrictionlessGrasp-v0", **kwargs)
    if spec.wrapper is None:
        return env
    cls, wrapper_kwargs = spec.wrapper
    return cls(env, **wrapper_kwargs)


def run_episode(
    spec: PolicySpec, suite: str, scene: str, seed: int, max_steps: int | None, frames=None,
    friction: float = 0.0, uncertainty: float = 0.0,
) -> Episode:  # fmt: skip
    """Run one episode to its end, with Coulomb ``friction`` at every contact (the env's
    ``friction``) and the object's vertices perturbed by ``uncertainty`` palm widths (the
    env's ``uncertainty``); appends rendered frames to ``frames`` if given."""
    suite_kwargs = SHAPE_SUITES.get(suite, {"scene": scene})
    extra: dict = {"friction": friction} if friction else {}
    if uncertainty:
        extra["uncertainty"] = uncertainty
    if frames is not None:
        extra |= {"render_mode": "rgb_array", "render_width": GIF_SIZE[0]}
        extra["render_height"] = GIF_SIZE[1]
    env = make_env(spec, suite_kwargs, max_steps, **extra)
    ep = Episode(suite, scene, spec.name, seed, friction=friction, uncertainty=uncertainty)
    try:
        reset, act = make_policy(spec, env)
        obs, info = env.reset(seed=seed)
        reset(obs, info, seed)
        while True:
            if frames is not None and ep.steps % GIF_EVERY == 0:
                frames.append(env.render())
            obs, reward, terminated, truncated, info = env.step(act(obs))
            ep.steps += 1
            ep.ret += float(reward)
            if info["is_success"] and not ep.reached:
                ep.reached, ep.steps_to_closure = True, ep.steps
            ep.dropped |= info["dropped"]
            ep.jammed |= info["jammed"] and not info["form_closure"]
            if "sim_error" in info:
                ep.error = info["sim_error"]
            if terminated or truncated:
                break
    except Exception as exc:  # a failing policy fails its episode, not the evaluation
        ep.error = f"{type(exc).__name__}: {exc}"
        print(f"{spec.name} on {scene} (seed {seed}): {ep.error}")
        env.close()
        return ep
    if frames is not None:
        frames.append(env.render())
    ep.success = bool(info["is_success"])
    if ep.success:
        ep.grip = float(info["grip_force"])
        ep.grip_W = ep.grip / env.unwrapped.scene.object_weight
    env.close()
    return ep


def run_job(job: tuple) -> Episode:
    return run_episode(*job)
