"""Collision-free motion: OMPL plans in joint space, MuJoCo checks, toppra times the path.

`MotionPlanner.plan(goal)` finds a path from the robot's joint positions (or `start`) to a
joint vector or a TCP pose with one of OMPL's geometric planners, every state checked by a
`CollisionChecker` (MuJoCo's collision detection with `margin` clearance) and every edge at
`resolution` radians. The path is shortened with OMPL's simplifier, timed with toppra under
velocity and acceleration limits, and the timed trajectory is checked once more, finely next
to obstacles (the spline through the waypoints may cut a corner). `plan_cartesian(pose)`
follows a straight TCP line instead, through IK at every `step`. docs/motion.md has the
details and the figures.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from typing import Any

import numpy as np
import pinocchio as pin

from ..control.cartesian import _number, _vector
from ..errors import PlanningError, SpecError, SpecTypeError
from ..robot import Robot
from .collision import CollisionChecker
from .trajectory import JointTrajectory, TimeParametrizer

# Datasheet joint limits of the arms mjkdl's examples use, recognised by their Menagerie body
# names (the MJCF files carry none). Franka: the FCI documentation's "Limits for Panda";
# Kinova Gen3 (7 DoF): the user guide's joint speeds and the 8.6 rad/s² ros2_kortex's MoveIt
# configuration uses.
DATASHEET_LIMITS: dict[tuple[str, ...], tuple[tuple[float, ...], tuple[float, ...]]] = {
    ("link1", "link2", "link3", "link4", "link5", "link6", "link7"): (
        (2.175, 2.175, 2.175, 2.175, 2.61, 2.61, 2.61),
        (15.0, 7.5, 10.0, 12.5, 15.0, 20.0, 20.0),
    ),
    (
        "shoulder_link",
        "half_arm_1_link",
        "half_arm_2_link",
        "forearm_link",
        "spherical_wrist_1_link",
        "spherical_wrist_2_link",
        "bracelet_link",
    ): ((1.3963,) * 4 + (1.2218,) * 3, (8.6,) * 7),
}
# OMPL's geometric planners selectable by name.
PLANNERS = (
    "RRTConnect",
    "RRT",
    "RRTstar",
    "InformedRRTstar",
    "PRM",
    "PRMstar",
    "KPIECE1",
    "BKPIECE1",
    "LBKPIECE1",
    "BITstar",
    "FMT",
    "AORRTC",
)
# The longest edge (rad, joint-space distance) RRT-family planners grow at once: OMPL's default,
# a fifth of the space's diagonal (2.6-3.3 rad here), gives the Gen3's clutter queries a heavy
# tail (one in a hundred needed 15-20k checks); 2 rad cuts it to about 3k.
RANGE = 2.0
# Within this distance (rad, any joint) of the start or goal the search needs only `margin`.
ESCAPE = 0.2
# Clearance (m) beyond the margin the timed trajectory keeps away from its ends: followed in
# POSITION mode, the arm comes up to 0.4 mm closer to things than the plan (Panda, 100 of the
# benchmark's trajectories, at each one's closest approach).
TRACKING = 0.001
# The timed trajectory is checked every CHECK_STEP (rad, any joint), and this many times more
# finely next to obstacles: finer than the search's edges, which are only proposals.
CHECK_STEP = 0.05
FINE = 4
# OMPL's cheap simplification passes (simplifyMax shortens paths ~25% at 5x the cost).
SIMPLIFY = ("reduceVertices", "collapseCloseVertices")
# Joints without position limits are planned within this range (rad).
UNLIMITED_RANGE = 2.0 * math.pi
# A model velocity limit at or above this stands for none (Pinocchio's inf or largest double).
_NO_LIMIT = 1e6


class MotionPlanner:
    """Collision-free joint trajectories for `robot`'s arm, through OMPL and toppra.

    `margin`: the clearance (m) every geom the arm moves keeps from everything else and from
    the arm's other links. `planner`: the name of an OMPL geometric planner (`PLANNERS`).
    `velocity_limits`, `acceleration_limits`: one positive value per joint; by default the
    model's, else the datasheet's for the Franka Panda and Kinova Gen3 (`DATASHEET_LIMITS`).
    `allowed_contacts`: pairs of body names whose contacts do not count. `resolution`: the
    joint-space distance (rad) between two checks along a search edge (the timed
    trajectory is checked every `CHECK_STEP`, finer next to obstacles). `padding` (m): the search
    keeps `margin + padding` clear where it can (away from the start and goal), so the motion
    between checked states and the timed spline keep `margin`. `ik_attempts`: seeds tried
    for a pose goal, drawn from `seed` (OMPL's own sampling is seeded process-wide:
    `ompl.util.RNG.setSeed`). Everything the arm does not move is taken where it is when
    `plan` starts.
    """

    def __init__(
        self,
        robot: Robot,
        *,
        margin: float = 0.005,
        planner: str = "RRTConnect",
        velocity_limits: Sequence[float] | None = None,
        acceleration_limits: Sequence[float] | None = None,
        allowed_contacts: Sequence[tuple[str, str]] = (),
        resolution: float = 0.1,
        padding: float = 0.005,
        ik_attempts: int = 20,
        seed: int = 0,
    ) -> None:
        if not isinstance(robot, Robot):
            raise SpecTypeError(f"MotionPlanner: robot must be a Robot, got {robot!r}")
        self._robot = robot
        self._n = robot.n_joints
        self._margin = _number(margin, "margin")
        self._resolution = _number(resolution, "resolution", positive=True)
        self._padding = _number(padding, "padding")
        if not isinstance(planner, str) or planner not in PLANNERS:
            raise SpecError(f"planner must be one of OMPL's {', '.join(PLANNERS)}; got {planner!r}")
        self._planner_name = planner
        if isinstance(ik_attempts, bool) or not isinstance(ik_attempts, int) or ik_attempts < 1:
            raise SpecError(f"ik_attempts must be a positive integer, got {ik_attempts!r}")
        self._ik_attempts = ik_attempts
        self._vmax, self._amax = self._limits(velocity_limits, acceleration_limits)
        self._timing = TimeParametrizer(self._vmax, self._amax)
        self._checker = CollisionChecker(
            robot,
            self._margin,
            allowed_contacts,
            reach=self._margin + self._padding,
        )
        self._rng = np.random.default_rng(seed)
        limits = robot.joint_limits
        self._lower = np.where(np.isfinite(limits[:, 0]), limits[:, 0], -UNLIMITED_RANGE)
        self._upper = np.where(np.isfinite(limits[:, 1]), limits[:, 1], UNLIMITED_RANGE)
        self._ends = np.zeros((2, self._n))  # start and goal of the search under way
        self.checks = 0  # validity checks since the planner was made
        # Seconds the last plan spent searching and simplifying (0 for a straight line).
        self.last_stats: dict[str, float] = {"search": 0.0, "simplify": 0.0}
        self._unlimited = ~np.isfinite(limits).all(axis=1)
        self._space_info = self._ompl_space(self._lower, self._upper)

    # ------------------------------------------------------------------ setup

    def _limits(
        self, velocity: Sequence[float] | None, acceleration: Sequence[float] | None
    ) -> tuple[np.ndarray, np.ndarray]:
        n = self._n
        sheet = _datasheet(self._link_names())
        model = self._robot.model
        joints = [model.getJointId(name) for name in self._robot.joint_names]
        own = np.array([model.velocityLimit[model.joints[j].idx_v] for j in joints])
        out = []
        for given, field, index in (
            (velocity, "velocity_limits", 0),
            (acceleration, "acceleration_limits", 1),
        ):
            if given is not None:
                arr = _vector(given, n, field)
                bad = np.flatnonzero(arr <= 0)
                if len(bad):
                    i = int(bad[0])
                    raise SpecError(
                        f"{field}[{i}] (joint {self._robot.joint_names[i]!r}) must be "
                        f"positive, got {arr[i]:g}"
                    )
                out.append(arr)
                continue
            if index == 0 and np.all((own > 0) & (own < _NO_LIMIT)):
                out.append(own.astype(float))
            elif sheet is not None:
                out.append(np.array(sheet[index], dtype=float))
            else:
                raise SpecError(
                    f"{field}: the model has none for joints "
                    f"{', '.join(self._robot.joint_names)} and they are not a Franka Panda's "
                    f"or a Kinova Gen3's; pass {field}=[...] ({n} values)"
                )
        return out[0], out[1]

    def _link_names(self) -> list[str]:
        """The bodies the arm's joints turn."""
        model = self._robot.scene.model
        return [model.body(model.joint(j).bodyid[0]).name for j in self._robot.joint_names]

    def _ompl_space(self, lower: np.ndarray, upper: np.ndarray) -> Any:
        """OMPL's space information: joint positions within [lower, upper], our checks."""
        from ompl import base as ob

        space = ob.RealVectorStateSpace(self._n)
        bounds = ob.RealVectorBounds(self._n)
        for i in range(self._n):
            bounds.setLow(i, float(lower[i]))
            bounds.setHigh(i, float(upper[i]))
        space.setBounds(bounds)
        si = ob.SpaceInformation(space)
        n, search_valid = self._n, self._search_valid

        def valid(state: Any) -> bool:
            return search_valid(state[0:n])

        si.setStateValidityChecker(valid)
        si.setStateValidityCheckingResolution(self._resolution / space.getMaximumExtent())
        si.setup()
        self._valid_fn = valid  # OMPL keeps a reference; so does the planner
        return si

    # ------------------------------------------------------------------ public

    @property
    def robot(self) -> Robot:
        """The robot this planner plans for."""
        return self._robot

    @property
    def margin(self) -> float:
        """Clearance (m) the arm keeps from everything."""
        return self._margin

    @property
    def velocity_limits(self) -> np.ndarray:
        """Per-joint velocity limits the trajectories respect (rad/s or m/s)."""
        return self._vmax.copy()

    @property
    def acceleration_limits(self) -> np.ndarray:
        """Per-joint acceleration limits the trajectories respect (rad/s² or m/s²)."""
        return self._amax.copy()

    @property
    def checker(self) -> CollisionChecker:
        """The collision checker the planner uses."""
        return self._checker

    def contacts(self, q: Sequence[float]) -> list[tuple[str, str, float]]:
        """Pairs of bodies closer than the margin with the arm at `q` (nearest first)."""
        self._checker.sync()
        return self._checker.contacts(_vector(q, self._n, "q"))

    def plan(
        self,
        goal: Sequence[float] | np.ndarray | pin.SE3,
        *,
        start: Sequence[float] | None = None,
        timeout: float = 1.0,
        carry: str | None = None,
    ) -> JointTrajectory:
        """A collision-free, timed trajectory from `start` (default: the measured joint
        positions) to `goal`, a joint vector or a TCP pose (`pinocchio.SE3`).

        `timeout` bounds the search (s). `carry`: a free body held by the tool, moved with
        the tip (it keeps its present pose relative to the tip).
        """
        budget = _number(timeout, "timeout", positive=True)
        began = time.perf_counter()
        self._checker.sync()
        self._checker.carry(carry)
        try:
            q0 = self._start(start)
            q1 = self._goal(goal, q0)
            straight = True
            while True:  # a path whose timing cuts into the margin is searched again
                waypoints = self._search(q0, q1, budget, began, straight)
                trajectory = self._timed(waypoints)
                if trajectory is not None:
                    return trajectory
                straight = False
                if time.perf_counter() - began > budget:
                    raise PlanningError(
                        f"{self._planner_name}: every path found within {budget:g} s came "
                        "closer than the margin once timed; raise the timeout or the padding"
                    )
        finally:
            if carry is not None:
                self._checker.carry(None)

    def plan_cartesian(
        self,
        pose: pin.SE3,
        *,
        step: float = 0.005,
        start: Sequence[float] | None = None,
        max_joint_step: float = 0.1,
        carry: str | None = None,
    ) -> JointTrajectory:
        """A timed trajectory along the straight TCP line to `pose` (rotation by slerp).

        IK at every `step` metres (or 0.05 rad of rotation), each seeded with the previous
        solution; a joint moving more than `max_joint_step` (rad) between two steps (a
        branch change) or a pose in collision raises `PlanningError` naming where.
        """
        if not isinstance(pose, pin.SE3):
            raise SpecTypeError(f"plan_cartesian: pose must be a pinocchio.SE3, got {pose!r}")
        if not (np.isfinite(pose.translation).all() and np.isfinite(pose.rotation).all()):
            raise SpecError(f"plan_cartesian: pose must be finite, got {pose}")
        step = _number(step, "step", positive=True)
        jump = _number(max_joint_step, "max_joint_step", positive=True)
        self._checker.sync()
        self._checker.carry(carry)
        try:
            q = self._start(start)
            begin = self._robot.fk_frame(q)
            delta = pin.log6(begin.inverse() * pose)
            count = max(
                1,
                math.ceil(np.linalg.norm(pose.translation - begin.translation) / step),
                math.ceil(np.linalg.norm(delta.angular) / 0.05),
            )
            waypoints = [q]
            for k in range(1, count + 1):
                target = _interpolate(begin, pose, k / count)
                result = self._robot.ik(target, q)
                where = f"at {k / count:.0%} of the line to {pose.translation.round(4).tolist()}"
                if not result.success:
                    raise PlanningError(
                        f"plan_cartesian: no IK solution {where} (position error "
                        f"{result.position_error:.2g} m)"
                    )
                moved = np.abs(result.q - q)
                if moved.max() > jump:
                    i = int(moved.argmax())
                    raise PlanningError(
                        f"plan_cartesian: joint {self._robot.joint_names[i]!r} jumps "
                        f"{moved[i]:.3f} rad {where} (more than max_joint_step={jump:g}): the "
                        "IK changed branch or the line passes a singularity"
                    )
                q = result.q
                self._in_collision(q, f"plan_cartesian: the pose {where}")
                waypoints.append(q)
            trajectory = self._timed(np.array(waypoints))
            if trajectory is None:
                raise PlanningError(
                    "plan_cartesian: the timed line comes closer than the margin between its "
                    "IK steps; lower `step` or the margin"
                )
            return trajectory
        finally:
            if carry is not None:
                self._checker.carry(None)

    # ------------------------------------------------------------------ steps

    def _start(self, start: Sequence[float] | None) -> np.ndarray:
        q = self._robot.jnt_pos_msr.copy() if start is None else _vector(start, self._n, "start")
        self._inside(q, "start")
        self._in_collision(q, "the start")
        return q

    def _inside(self, q: np.ndarray, what: str) -> None:
        outside = np.flatnonzero((q < self._lower - 1e-9) | (q > self._upper + 1e-9))
        if len(outside):
            i = int(outside[0])
            raise PlanningError(
                f"{what}: joint {self._robot.joint_names[i]!r} at {q[i]:g} is outside "
                f"[{self._lower[i]:g}, {self._upper[i]:g}]"
                + (
                    " (unlimited joints are planned within ±2π)"
                    if self._upper[i] == UNLIMITED_RANGE
                    else ""
                )
            )

    def _in_collision(self, q: np.ndarray, what: str) -> None:
        if self._checker.valid(q):
            return
        a, b, d = self._checker.contacts(q)[0]
        raise PlanningError(
            f"{what} is in collision: bodies {a!r} and {b!r} are {d * 1000:.1f} mm apart "
            f"(margin {self._margin * 1000:g} mm; negative: penetrating)"
        )

    def _goal(self, goal: object, q0: np.ndarray) -> np.ndarray:
        if isinstance(goal, pin.SE3):
            return self._ik(goal, q0)
        q = _vector(goal, self._n, "goal")
        self._inside(q, "goal")
        self._in_collision(q, "the goal")
        return q

    def _ik(self, pose: pin.SE3, q0: np.ndarray) -> np.ndarray:
        """The collision-free IK solution nearest to `q0` among those found from
        `ik_attempts` seeds (`q0` first, then random ones inside the limits)."""
        if not (np.isfinite(pose.translation).all() and np.isfinite(pose.rotation).all()):
            raise SpecError(f"goal pose must be finite, got {pose}")
        seeds = [q0, *self._rng.uniform(self._lower, self._upper, (self._ik_attempts - 1, self._n))]
        found: list[np.ndarray] = []
        clash: tuple[str, str, float] | None = None
        best_error = math.inf
        for seed in seeds:
            result = self._robot.ik(pose, seed)
            if not result.success:
                best_error = min(best_error, result.position_error)
                continue
            if not self._checker.valid(result.q):
                clash = clash or self._checker.contacts(result.q)[0]
                continue
            found.append(result.q)
            if len(found) >= 3:
                break
        if found:
            return min(found, key=lambda q: float(np.abs(q - q0).sum()))
        where = f"the goal pose at {pose.translation.round(4).tolist()}"
        if clash is not None:
            a, b, d = clash
            raise PlanningError(
                f"{where}: every IK solution is in collision (e.g. bodies {a!r} and {b!r} "
                f"{d * 1000:.1f} mm apart, margin {self._margin * 1000:g} mm)"
            )
        raise PlanningError(
            f"{where} is unreachable: no IK solution from {len(seeds)} seeds (best position "
            f"error {best_error:.3g} m)"
        )

    def _search(
        self, q0: np.ndarray, q1: np.ndarray, budget: float, began: float, straight: bool = True
    ) -> np.ndarray:
        """OMPL's path from q0 to q1, simplified, as waypoints (k×n); `budget` seconds from
        `began` (a `perf_counter` time). `straight`: try the straight segment first."""
        from ompl import geometric as og
        from ompl import util as ou

        si = self._space_info
        if self._unlimited.any():
            # An unlimited joint is searched within half a turn beyond the start and goal,
            # not over the whole ±2π: a quarter of the volume per joint, or less.
            lower, upper = self._lower.copy(), self._upper.copy()
            free = self._unlimited
            lower[free] = np.minimum(q0, q1)[free] - math.pi
            upper[free] = np.maximum(q0, q1)[free] + math.pi
            si = self._ompl_space(lower, upper)
        self._ends[0], self._ends[1] = q0, q1
        self.last_stats.update(search=0.0, simplify=0.0)
        if straight and self._straight(q0, q1):
            return np.array([q0, q1])
        setup = og.SimpleSetup(si)
        planner = getattr(og, self._planner_name)(si)
        if hasattr(planner, "setRange"):
            planner.setRange(RANGE)
        setup.setPlanner(planner)
        start, goal = si.allocState(), si.allocState()
        for i in range(self._n):
            start[i], goal[i] = float(q0[i]), float(q1[i])
        setup.setStartAndGoalStates(start, goal)
        checks = self.checks
        level = ou.getLogLevel()
        ou.setLogLevel(ou.LOG_NONE)
        try:
            status = setup.solve(max(budget - (time.perf_counter() - began), 1e-3))
            solved = setup.haveExactSolutionPath()
            t_simplify = time.perf_counter()
            if solved:
                path = setup.getSolutionPath()
                simplifier = og.PathSimplifier(si)
                for name in SIMPLIFY:
                    getattr(simplifier, name)(path)
            t_simplify = time.perf_counter() - t_simplify
        finally:
            ou.setLogLevel(level)
        if not solved:
            raise PlanningError(
                f"{self._planner_name} found no collision-free path within {budget:.3g} s "
                f"({self.checks - checks} states checked, status {status.asString()}, margin "
                f"{self._margin * 1000:g} mm): raise the timeout, try another planner, or "
                "check that the goal can be reached"
            )
        self.last_stats["search"] = setup.getLastPlanComputationTime()
        self.last_stats["simplify"] = t_simplify
        n = self._n
        return np.array([state[0:n] for state in path.getStates()])

    def _search_valid(self, q: np.ndarray | list[float]) -> bool:
        """The search's test: `margin + padding` clear, or `margin` within `ESCAPE` of the
        start or goal (which may themselves be closer than the padding to something)."""
        self.checks += 1
        d = self._checker.clearance(q)
        if d >= self._checker.reach:
            return True
        if d < self._margin:
            return False
        return bool(np.abs(self._ends - np.asarray(q)).max(axis=1).min() < ESCAPE)

    def _straight(self, q0: np.ndarray, q1: np.ndarray) -> bool:
        """Whether the straight joint-space segment q0 -> q1 passes the search's test."""
        count = max(1, math.ceil(float(np.linalg.norm(q1 - q0)) / self._resolution))
        return all(self._search_valid(q0 + (q1 - q0) * (k / count)) for k in range(1, count))

    def _timed(self, waypoints: np.ndarray) -> JointTrajectory | None:
        """toppra's timing of the path, checked; when the spline cuts a corner into a
        collision, the path is subdivided (the spline then hugs it) and timed again. None
        when that does not help: the path itself grazes the margin between its checks."""
        for _ in range(3):
            trajectory = self._timing(waypoints)
            if self._trajectory_ok(trajectory):
                return trajectory
            waypoints = _subdivide(waypoints)
        return None

    def _trajectory_ok(self, trajectory: JointTrajectory) -> bool:
        """Whether the trajectory keeps the margin (+ `TRACKING` beyond `ESCAPE` of its
        ends): checked every `CHECK_STEP` (rad, any joint) and, on both sides of a state closer
        than `margin + padding` to something, every `FINE`th of it."""
        fine = CHECK_STEP / FINE
        times, positions = trajectory.times, trajectory.positions
        # A time grid whose steps move no joint more than `fine`.
        splits = np.maximum(1, np.ceil(np.abs(np.diff(positions, axis=0)).max(axis=1) / fine))
        counts = splits.astype(int)
        start = np.repeat(times[:-1], counts)
        frac = np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts)
        grid = np.append(start + np.repeat(np.diff(times) / splits, counts) * frac, times[-1])
        q = trajectory.positions_at(grid)
        travelled = np.concatenate([[0.0], np.cumsum(np.abs(np.diff(q, axis=0)).max(axis=1))])
        marks = np.floor(travelled / CHECK_STEP)
        coarse = np.flatnonzero(np.diff(marks, prepend=-1.0) > 0).tolist()
        if coarse[-1] != len(grid) - 1:
            coarse.append(len(grid) - 1)
        clearance, reach = self._checker.clearance, self._checker.reach
        # Away from the start and goal (where the arm is slow) the executed arm strays from
        # the plan: it must keep TRACKING more than the margin there.
        ends = np.minimum(np.abs(q - q[0]).max(axis=1), np.abs(q - q[-1]).max(axis=1))
        need = np.where(ends < ESCAPE, self._margin, self._margin + TRACKING).tolist()
        near = []
        for k in coarse:
            d = clearance(q[k])
            if d < need[k]:
                return False
            near.append(d < reach)
        self.checks += len(coarse)
        for j in range(len(coarse) - 1):
            if near[j] or near[j + 1]:
                between = range(coarse[j] + 1, coarse[j + 1])
                self.checks += len(between)
                if any(clearance(q[k]) < need[k] for k in between):
                    return False
        return True


def _subdivide(points: np.ndarray) -> np.ndarray:
    """The polyline with a point added in the middle of every segment."""
    mids = 0.5 * (points[:-1] + points[1:])
    out = np.empty((2 * len(points) - 1, points.shape[1]))
    out[0::2], out[1::2] = points, mids
    return out


def _interpolate(a: pin.SE3, b: pin.SE3, s: float) -> pin.SE3:
    """The pose a fraction `s` of the way from `a` to `b`: straight line, slerp rotation."""
    rotation = a.rotation @ pin.exp3(s * pin.log3(a.rotation.T @ b.rotation))
    return pin.SE3(rotation, a.translation + s * (b.translation - a.translation))


def _datasheet(links: list[str]) -> tuple[tuple[float, ...], tuple[float, ...]] | None:
    """The datasheet limits of the arm whose links are named `links` (any prefix)."""
    for names, limits in DATASHEET_LIMITS.items():
        if len(names) == len(links) and all(
            a.endswith(b) for a, b in zip(links, names, strict=True)
        ):
            return limits
    return None
