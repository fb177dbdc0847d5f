"""The paper's planner as a policy for the env (:class:`ScriptedPolicy`).

Policy::

    policy = ScriptedPolicy(env)
    obs, info = env.reset()
    policy.reset(obs, info)
    action = policy.act(obs)

plans from the env's current state with the planner's lifting and grip-adjustment phases
(palm fixed, so it works with ``palm_control`` False or True) and replays the plan as scaled
env actions, splitting increments larger than one action into several steps. With
``palm_control`` True, when that fails, it moves the palm to the whole planner's placement
(tilted, for square, heavy_square and triangle) and lifts from there; where no placement
lifts the object (tall_rectangle), it runs the planner's exploratory lifting with palm
motion on the env's own step function and replays it exactly. With the env's
``uncertainty`` it plans on the nominal scene and plays the plan open loop.
"""

from __future__ import annotations

import math

import numpy as np

from grasp_env import planning
from grasp_env.core.state import State
from grasp_env.envs.checks import placement_problem
from grasp_env.errors import ComputationError
from grasp_env.simulator import Simulator

#: Object pose deviation (relative to the object's size) from the plan that makes the
#: policy re-plan from the env's state.
REPLAN_TOL = 1e-4
#: Re-plans allowed per episode (a plan that gets stuck is replayed as it is). Lifting from
#: a tilted-palm placement crosses tipping bifurcations where the env's float32 actions
#: (round-off of 1e-10 rad in the fingers) change the outcome: square and heavy_square need 5
#: re-plans, triangle 1-3. Each costs one lifting plan (about a second of CPU).
MAX_REPLANS = 10
#: Finger actions at most to close the fingers onto the object before exploring.
CLOSE_STEPS = 64
#: Finger opening (rad) a step, and steps at most, that clear the hand of the nominal object
#: where the env's hand overlaps it (:attr:`ScriptedPolicy.open_loop`).
OPEN_STEP, OPEN_STEPS = 0.005, 40
#: Whole-planner plans kept (per scene) by :class:`ScriptedPolicy` with palm control.
PLAN_CACHE_SIZE = 16
_PLAN_CACHE: dict[tuple, planning.Plan] = {}


# ---------------------------------------------------------------------- env policy
class ScriptedPolicy:
    """The paper's planner as a policy acting only through ``FrictionlessGrasp-v0`` actions.

    At :meth:`reset` it plans from the env's current state (exact knowledge of the scene and
    state, as the paper assumes): close the fingers until both touch, then the planner's
    lifting and grip-adjustment phases, all with the palm fixed where the env put it. It then
    replays the planned hand configurations as scaled actions, splitting an increment larger
    than one action (``max_finger_step``) over several steps, and re-plans from the env's
    state (at most ``MAX_REPLANS`` times an episode) whenever the object is not where the
    plan expects it. Once the plan is done it
    holds still (zero actions).

    Works with ``palm_control`` False or True (the palm actions stay zero) from the
    ``"scene"`` start when the scene's palm is over the object (as in every bundled scene),
    and from the ``"preliftoff"`` and ``"placement"`` starts, on scenes that lift from there.

    With ``palm_control`` True, if lifting from the env's placement fails and the object still
    rests at its scene pose, it runs :func:`grasp_env.planning.plan_grasp` on the env's scene
    (cached per scene in the process: the placement search can take a minute of CPU), drives
    the hand to the plan's pre-liftoff placement along a collision-free
    :func:`grasp_env.planning.approach_path` (palm actions included), and there plans lifting
    and grip adjustment again from the env's own state. Scenes whose only plans start with a
    tilted palm (square, heavy_square, triangle) need ``palm_control`` True; the approach
    takes most of the steps (about 90-150 at the default step sizes). Where no placement
    lifts the object (tall_rectangle), it plans the planner's exploratory lifting with palm
    motion (:mod:`grasp_env.planning.regrasp`) from the env's state on the env's own step function
    (``simulate_action``), so the env follows it exactly.

    With the env's ``uncertainty`` (``env.unwrapped.nominal_scene`` is not ``.scene``) it
    knows only the nominal object: it plans on a simulator of the nominal scene from the
    nominal object at rest at its placement with the hand where the env's is (the fingers
    opened where they would overlap it; where no opening clears it, the policy holds
    still), plays the plan open loop
    (:attr:`open_loop`: no re-plans, no planning at the re-placed hand, no exploration on
    the env's step function, which would use the simulated object), and so fails where the
    simulated object does not follow the nominal one's plan.

    It reads the env only through its public accessors (``env.unwrapped.state``,
    ``.simulator``, ``.scene``, ``.nominal_scene``, ``.simulate_action`` and the action
    settings).

    Args:
        env: a ``FrictionlessGraspEnv``, possibly wrapped.
        dq: finger increment of the lifting phase (rad).
        fallbacks: with ``palm_control``, re-place the hand or explore where lifting from the
            env's placement fails; False keeps to lifting from where the hand is (cheap: no
            placement search), as a base policy in training does.

    Attributes:
        on_fallback: the episode follows a re-placement or an exploratory path (replayed
            exactly past tipping bifurcations) rather than lifting from the env's placement.
        open_loop: the episode plays a plan of the nominal scene without re-planning (the
            env's ``uncertainty``).
    """

    def __init__(self, env, dq: float = 0.02, fallbacks: bool = True) -> None:
        self.env = env
        self.dq = dq
        self.fallbacks = fallbacks
        self.on_fallback = False
        self.open_loop = False
        self.plan: planning.Plan | None = None
        self._ready = False  # reset() has planned
        self._transit_left = -1  # waypoints left before the planned placement (-1: none)
        # (hand, object pose, hand increment or None: the difference of the hands)
        self._waypoints: list[tuple[np.ndarray, np.ndarray, np.ndarray | None]] = []
        self._chunk: list[np.ndarray] = []  # actions left to reach the current waypoint
        self._expected: np.ndarray | None = None  # object pose planned at that waypoint
        self._replans = 0
        self._explored = False

    def reset(self, obs=None, info=None) -> None:
        """Plan from the env's current state (call after every ``env.reset``).

        Raises:
            RuntimeError: the env has not been reset yet.
        """
        if self.env.unwrapped.state is None:
            raise RuntimeError("reset the env (env.reset()) before ScriptedPolicy.reset()")
        base = self.env.unwrapped
        self._replans = 0
        self._explored = False
        self.on_fallback = False
        self.open_loop = base.nominal_scene is not base.scene
        self._transit_left = -1
        self._replan()
        self._ready = True

    def _replan(self, palm_moves: bool = True) -> None:
        base = self.env.unwrapped
        sim, state = self._model()
        if state is None:  # nothing to plan from: hold still
            self._use(planning.Plan(message="the hand overlaps the nominal object"), [])
            return
        plan = self._fixed_palm_plan(sim, state)
        self._use(plan, [])
        if not plan.success and palm_moves and self.fallbacks and base.palm_control:
            if not self._replan_with_palm(sim, state) and not self.open_loop:
                self._explore(state)

    def _model(self) -> tuple[Simulator, State | None]:
        """The simulator and state the policy plans on: the env's, or in :attr:`open_loop`
        a simulator of the nominal scene with its object at rest at its placement and the
        hand where the env's is, the fingers opened by the least multiples of ``OPEN_STEP``
        (up to ``OPEN_STEPS`` each) that clear the hand of the nominal object there; no state
        where none does (the hand is wedged between the simulated object and the support
        where the nominal object sticks out).
        """
        base = self.env.unwrapped
        if not self.open_loop:
            return base.simulator, base.state
        sim = Simulator(base.nominal_scene, contact_tol=base.contact_tol)
        pose, hand = sim.scene.object.start_pose, base.state.hand
        low, high = sim.scene.joint_limits.T
        for total in range(2 * OPEN_STEPS + 1):  # the least opening first
            for k in range(max(0, total - OPEN_STEPS), min(total, OPEN_STEPS) + 1):
                opened = hand.copy()  # finger 1 opens as q1 falls, finger 2 as q2 rises
                opened[3:] = np.clip(hand[3:] + OPEN_STEP * np.array([-k, total - k]), low, high)
                if placement_problem(sim.scene, pose, opened, base.contact_tol) is None:
                    return sim, sim.settle(pose, opened)
        return sim, None

    def _fixed_palm_plan(self, sim: Simulator, state) -> planning.Plan:
        """Close until both fingers touch, lift and adjust the grip, the palm where it is."""
        plan = planning.Plan()
        plan.steps.append(planning.PlanStep("pre-liftoff", state, math.nan, "env state"))
        if not planning.both_fingers_touch(state):
            state = planning.close_until_touch(sim, state)
            plan.steps.append(planning.PlanStep("pre-liftoff", state, math.nan, "closing"))
        state = plan.add(planning.lift(sim, state, self.dq))
        if plan.success:
            plan.add(planning.adjust_grip(sim, state))
        return plan

    def _use(
        self,
        plan: planning.Plan,
        transit: list[np.ndarray],
        increments: list[np.ndarray] | None = None,
    ) -> None:
        """Follow ``transit`` (hand configurations, the object at rest), then ``plan``; its
        first steps by ``increments`` if given (the hand increments they were planned with)."""
        self.plan = plan
        rest = self.env.unwrapped.state.object_pose.copy()
        self._waypoints = [(h, rest, None) for h in transit]
        incs = list(increments or [])
        for k, st in enumerate(plan.steps[1:]):
            dh = incs[k] if k < len(incs) else None
            self._waypoints.append((st.state.hand, st.state.object_pose, dh))
        self._transit_left = len(transit) if transit else -1
        self._chunk, self._expected = [], None

    def _replan_with_palm(self, sim: Simulator, state) -> bool:
        """With palm control, when lifting from the env's hand placement fails: the whole
        planner's grasp (any of its placements, tilted palm included), reached from the env's
        state along :func:`grasp_env.planning.approach_path`. Only while the object still rests
        at its scene pose (the plan starts there), to within ``REPLAN_TOL`` (closing the
        fingers on it at the pre-liftoff start can move it by round-off). At the placement,
        lifting is planned anew from the env's state (:meth:`act`): the planned squeeze can
        cross a tipping bifurcation, where round-off in the env's hand (float32 actions)
        changes the outcome."""
        scene = sim.scene
        if np.abs(state.object_pose - scene.object.start_pose).max() > REPLAN_TOL * sim.size:
            return False
        plan = self._full_plan(sim)
        if not plan.success:
            return False
        path = planning.approach_path(sim, state, plan.steps[0].state.hand)
        if path is None:
            return False
        self._use(plan, path)
        self.on_fallback = True
        return True

    def _explore(self, state) -> None:
        """With palm control, when no placement lifts the object: the planner's exploratory
        lifting with palm motion (:mod:`grasp_env.planning.regrasp`) from the env's state, then
        grip adjustment; at most once an episode, with the planner's budget
        (``grasp_env.planning.EXPLORE_MOVES`` simulated moves). The search simulates the very
        actions the policy will send (``simulate_action``, the env's own step), so the env
        follows the path exactly, past every tipping bifurcation."""
        base = self.env.unwrapped
        if self._explored:
            return
        self._explored = True

        def move(st, dh: np.ndarray):
            try:
                for a in self._actions(dh):
                    new = base.simulate_action(st, a)
                    if new.on_support and not st.on_support:
                        return None  # a drop: the env would end the episode
                    st = new
            except ComputationError:
                return None
            return st

        # Like the planner, explore from the fingers closed until both touch the object (one
        # finger action at a time, each finger stopping once it touches).
        states, increments = [state], []
        for _ in range(CLOSE_STEPS):
            touching = planning.touching_bodies(states[-1])
            dh = np.zeros(5)
            dh[3:] = base.max_finger_step * np.array(
                [f"finger{i}" not in touching for i in (1, 2)], float
            )
            dh[4] = -dh[4]  # finger 2 closes as q2 falls
            new = move(states[-1], dh) if dh.any() else None
            if new is None or new.jammed or np.array_equal(new.hand, states[-1].hand):
                break
            states.append(new)
            increments.append(dh)
        plan = planning.Plan()
        plan.steps.append(planning.PlanStep("pre-liftoff", state, math.nan, "env state"))
        phase, increments, _ = planning.explore(
            base.simulator, [(states, increments)], planning.EXPLORE_MOVES, move
        )
        end = plan.add(phase)
        if not plan.success:
            return
        plan.add(planning.adjust_grip(base.simulator, end))
        self._use(plan, [], increments)
        self.on_fallback = True

    def _full_plan(self, sim: Simulator) -> planning.Plan:
        """:func:`grasp_env.planning.plan_grasp` on the env's scene, cached per scene (the
        search over placements can take a minute)."""
        scene = sim.scene
        key = (repr(scene), self.dq)
        if key not in _PLAN_CACHE:
            if len(_PLAN_CACHE) >= PLAN_CACHE_SIZE:
                _PLAN_CACHE.pop(next(iter(_PLAN_CACHE)))
            # no exploratory lifting here: the policy explores from the env's own state
            _PLAN_CACHE[key] = planning.plan_grasp(scene, sim=sim, dq=self.dq, explore_moves=0)
        return _PLAN_CACHE[key]

    @property
    def done(self) -> bool:
        """The plan has been played to its end (the policy holds still until a re-plan)."""
        return self._ready and not self._chunk and not self._waypoints

    def act(self, obs=None) -> np.ndarray:
        """The next action, float32 in [-1, 1], of the env's action shape.

        Raises:
            RuntimeError: :meth:`reset` has not been called (it plans the episode).
        """
        if not self._ready:
            raise RuntimeError(
                "call ScriptedPolicy.reset() after env.reset() and before act(): "
                "reset() plans the episode from the env's state"
            )
        base = self.env.unwrapped
        if not self._chunk:
            state = base.state
            if self._expected is not None and not self.open_loop:
                off = np.abs(state.object_pose - self._expected).max()
                self._expected = None
                if off > REPLAN_TOL * base.simulator.size and self._replans < MAX_REPLANS:
                    self._replans += 1
                    self._replan()
            placed = self._transit_left == 0 and self.plan is not None and self._waypoints
            if placed and not self.open_loop:
                self._transit_left = -1  # at the placement: lift from the env's own state
                plan = self._fixed_palm_plan(base.simulator, state)
                if plan.success:
                    self._use(plan, [])
            if self._waypoints:
                hand, self._expected, dh = self._waypoints.pop(0)
                self._transit_left -= 1
                self._chunk = self._actions(hand - state.hand if dh is None else dh)
        if not self._chunk:
            return np.zeros(base.action_space.shape, np.float32)
        return self._chunk.pop(0)

    def _actions(self, dh: np.ndarray) -> list[np.ndarray]:
        """Equal actions that together move the hand by ``dh`` (shape (5,))."""
        base = self.env.unwrapped
        w = base.scene.palm.width
        a = np.zeros(5)
        a[0] = dh[3] / base.max_finger_step
        a[1] = -dh[4] / base.max_finger_step
        a[2:] = dh[:3] / (base.max_palm_step * np.array([w, w, 1.0]))
        if not base.palm_control:
            a = a[:2]
        n = max(1, math.ceil(float(np.abs(a).max()) - 1e-9))
        return [(a / n).astype(np.float32) for _ in range(n)]
