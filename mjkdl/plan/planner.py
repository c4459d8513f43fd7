"""Collision-free motion: OMPL plans in joint space, MuJoCo checks, TOPP-RA times the path.

`MotionPlanner.plan(goal)` finds a path from the robot's joint positions (or `start`) to a
joint vector or a TCP pose with one of OMPL's geometric planners, every state checked by a
`CollisionChecker` (MuJoCo's collision detection with `margin` clearance) and every edge at
`resolution` radians. The path is shortened with OMPL's simplifier, timed (TOPP-RA) under
velocity and acceleration limits, and the timed trajectory is checked once more, finely next
to obstacles (the spline through the waypoints may cut a corner). `plan_cartesian(pose)`
follows a straight TCP line instead, through IK at every `step`. docs/motion.md has the
details and the figures.
"""

from __future__ import annotations

import itertools
import math
import time
import zlib
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from ..control.cartesian import _number, _vector
from ..errors import (
    InfeasibleError,
    PlanningError,
    PlanningTimeout,
    SpecError,
    SpecTypeError,
    unknown_name,
)
from ..robot import Robot
from .acm import ALLOW, SAMPLES, AllowedCollisionMatrix, compute_acm
from .collision import CollisionChecker
from .constraints import OrientationConstraint
from .limits import RobotLimits, resolve_limits
from .srdf import Srdf
from .trajectory import JerkLimitedParametrizer, JointTrajectory, TimeParametrizer

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
# The pocket test (`MotionPlanner._pocket`): a start or goal from which a random tree of
# collision-free motions never gets POCKET_RADIUS (rad, any joint) away in POCKET_CHECKS
# validity checks sits in a pocket of free space: the query is infeasible. Its extensions head
# in turn for a random state within 2 * POCKET_RADIUS (at the search's resolution) and for a
# random TCP position within POCKET_REACH (m, each axis), the tool held, POCKET_STEP (m) a
# step, at most POCKET_STEPS steps. A Panda hand in a box, its way out under a lip: straight
# random rays alone (100) called it a pocket with 13 of 200 planner seeds; the tree gets out
# with each of them, within 371 checks (median 56). A real pocket costs the 1000 checks.
POCKET_RADIUS = 0.25
POCKET_CHECKS = 1000
POCKET_REACH = 0.2
POCKET_STEP = 0.005
POCKET_STEPS = 80
# The steps of a plan whose seconds `last_stats` holds: the start and goal checks (IK and the
# pocket test included), the search, OMPL's simplification, the projection onto a path
# constraint, the timing, the final check.
_STEPS = ("ends", "search", "simplify", "project", "timing", "check")
# Seconds to full acceleration: the jerk limits by default (datasheets rarely give any).
JERK_RAMP = 0.1
# A constrained plan's search keeps the constrained axis within this cone (rad) of its
# direction, so the projection has little to turn (45°: about 15 % of random states).
SEARCH_CONE = math.radians(45.0)
# Spacing (rad, any joint) of the states a constrained path is projected at.
PROJECTION_STEP = 0.02
# How far (rad) a measured start may be past a bound and be clipped back into it.
START_SLACK = 0.005
# The wall test (`MotionPlanner._wall`): after WALL_CHECKS validity checks without a path
# (or WALL_AFTER of the timeout on a slow machine: then the trees, and the verdict, may
# differ), RRTConnect's two trees are examined for a joint value neither has crossed; slices of it
# every WALL_STEP (rad) are sampled up to WALL_SAMPLES times (stopping at the first free
# configuration), and a slice without one divides the free space: the query is infeasible.
# 200 samples called a UR10's wrist slice a wall where 1.5 % of the configurations are free;
# 2000 miss such a passage with a probability of 1e-13, and say so in the verdict.
WALL_CHECKS = 2000
WALL_AFTER = 0.8
WALL_STEP = 0.05
WALL_SAMPLES = 2000
# Random goal states drawn within a goal tolerance when the exact goal is in collision.
TOLERANCE_SAMPLES = 50
# The ends of a constrained query (`MotionPlanner._approach`): up to APPROACH_SAMPLES states
# within PROJECTION_STEP (rad, any joint) of the start and of each goal are projected onto the
# constraint, as a path's first and last steps are; where none lands collision-free inside the
# bounds (from the start: within the 3 * PROJECTION_STEP a projected step may move), every
# path fails its projection there and the query fails before searching. Where an end breaks
# the constraint, up to CONSTRAINT_SEEDS random configurations inside the bounds are projected
# to tell whether the constraint can be met there at all.
APPROACH_SAMPLES = 50
CONSTRAINT_SEEDS = 200
# After every this many paths of one query failed their projection, the joint values between
# the start and the goal are sampled on the constraint for a wall (`_manifold_wall`), for at
# most MANIFOLD_SHARE of the time left (then the search goes on: on the Panda's upright
# queries across the wall, after 3 and without a limit, it cost 7 of 100 solutions at 1 s).
MANIFOLD_AFTER = 8
MANIFOLD_SHARE = 0.25
# Configurations a slice of the constraint's wall test projects (each costs up to
# PROJECTION_ITERATIONS Jacobians: a tenth of a millisecond to a few on the shared machine).
MANIFOLD_SAMPLES = 500
# The boxed-in test of a constrained query's ends (`MotionPlanner._boxed`): a random tree of
# projected steps (at most PROJECTION_STEP, any joint, each projected as a path's states are)
# grows from the end for BOX_TRIES extensions, in turn toward a random state within
# BOX_SPREAD rad and toward a random TCP position (BOX_STEP m a step); once its TCP gets
# BOX_REACH (m) from the end's, the end is open (in free space the first extension gets
# there). Else, on spheres around the end's TCP every BOX_GAP beyond the farthest the tree
# got (up to BOX_REACH), BOX_SAMPLES states within SHELL_NEAR or SHELL_SPREAD (rad, any
# joint, in turn) of the tree's are projected onto the constraint with the TCP on the
# sphere: where none is collision-free (and at least BOX_LANDED landed inside the bounds),
# every path on the axis out of the sphere crosses a collision: the end is boxed in, and
# only ends inside can be reached. The test gives up (no verdict) after BOX_SHARE of the
# timeout: a boxed end's search could only time out.
BOX_TRIES = 60
BOX_SPREAD = 0.5
SHELL_SPREAD = 1.0
SHELL_NEAR = 0.05
BOX_REACH = 0.1
BOX_GAP = 0.02
BOX_STEP = 0.005
BOX_SAMPLES = 500
BOX_LANDED = 100
BOX_SHARE = 0.5
# What the constrained verdicts are about: the projected paths, not every path the tolerance
# allows (one tilted within it all along, under something the level tool hits, is not searched).
_ON_AXIS = "paths are projected onto the axis; the tolerance is slack for the ends and the timing"


class MotionPlanner:
    """Collision-free joint trajectories for `robot`'s arm, through OMPL and toppra.

    `margin`: the clearance (m) every geom the arm moves keeps from everything else and from
    the arm's other links. `planner`: the name of an OMPL geometric planner (`PLANNERS`).
    `velocity_limits`, `acceleration_limits`: one positive value per joint; else per joint
    `limits` (a `RobotLimits`, or the path of a MoveIt `joint_limits.yaml`), the model's, or
    the published figures of an arm recognised by its names and kinematics
    (`mjkdl.plan.DATASHEETS`); `limits_source` says where each comes from, and one error
    lists every limit still missing (see `mjkdl.plan.limits`). Joint torque limits
    (`limits.effort`, else the model's: a URDF's efforts) are kept through the inverse
    dynamics by the default timing (`torque_limits`). `allowed_contacts`: pairs of body
    names whose contacts do not count, on top of the allowed-collision matrix `acm`, sampled
    on first use from `acm_samples` poses (`acm=False`: none; `acm_allow`: the reasons that
    allow a pair, default adjacent and always; see `mjkdl.plan.acm`). `srdf`: a MoveIt SRDF
    (an `Srdf` or its path) whose disabled collision pairs are allowed too (reason "srdf").
    `resolution`: the joint-space distance (rad) between two checks along a search edge (the timed
    trajectory is checked every `CHECK_STEP`, finer next to obstacles). `padding` (m): the search
    keeps `margin + padding` clear where it can (away from the start and goal), so the motion
    between checked states and the timed spline keep `margin`; `link_padding` ({body: m})
    sets it per body the arm moves (two of them keep the smaller of theirs), and pairs the
    matrix finds always closer than that keep the margin alone (`acm.unpadded`); an
    RRTConnect search unsolved after its wall test goes on with the margin alone
    (`padding_dropped`).
    `ik_attempts`: seeds tried for a pose goal, drawn from `seed` (OMPL's own sampling is
    seeded process-wide:
    `ompl.util.RNG.setSeed`). Everything the arm does not move is taken where it is when
    `plan` starts: obstacles added, moved or removed between calls are seen.
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
        link_padding: dict[str, float] | None = None,
        ik_attempts: int = 20,
        seed: int = 0,
        acm: bool = True,
        acm_samples: int = SAMPLES,
        acm_allow: tuple[str, ...] = ALLOW,
        jerk_limits: Sequence[float] | None = None,
        limits: RobotLimits | str | Path | None = None,
        srdf: Srdf | str | Path | None = None,
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
        self._vmax, self._amax, self.limits_source = self._limits(
            velocity_limits, acceleration_limits, limits
        )
        if jerk_limits is None:
            self._jmax = self._amax / JERK_RAMP
        else:
            self._jmax = _vector(jerk_limits, self._n, "jerk_limits")
            if np.any(self._jmax <= 0):
                raise SpecError(f"jerk_limits must be positive, got {self._jmax.tolist()}")
        self._timers: dict[tuple[float, float, str], Any] = {}
        self._checker = CollisionChecker(
            robot,
            self._margin,
            allowed_contacts,
            padding=self._padding,
            link_padding=link_padding,
        )
        self._allowed_user = list(self._checker._allowed_names)
        self._seed = seed
        self._rng = np.random.default_rng(seed)
        ranges = robot.joint_limits
        self._lower = np.where(np.isfinite(ranges[:, 0]), ranges[:, 0], -UNLIMITED_RANGE)
        self._upper = np.where(np.isfinite(ranges[:, 1]), ranges[:, 1], UNLIMITED_RANGE)
        self._ends = np.zeros((2, self._n))  # start and goal of the search under way
        self._cone: OrientationConstraint | None = None  # the search's loose constraint
        self._open_slices: set[tuple[int, float]] = set()  # `_manifold_wall`'s, for one plan
        # Leaving a jiggled start: the clearance it needs, how far (rad) that holds.
        self._start_need: tuple[float, float] | None = None
        self.checks = 0  # validity checks since the planner was made
        # The search's invalid states: how many, and per geom pair the distances in those it
        # was the least clear pair of.
        self._invalid = 0
        self._blockers: dict[tuple[int, int], list[float]] = {}
        # Of those, the states only the padding refused; once the wall test has found no
        # wall, `_padded` goes False and the search keeps the margin alone.
        self._padding_only = 0
        self._padded = True
        self.padding_dropped = False  # whether the last plan's search dropped the padding
        # Seconds the last plan spent in each step (0 for a step it skipped).
        self.last_stats: dict[str, float] = dict.fromkeys(_STEPS, 0.0)
        self._unlimited = ~np.isfinite(ranges).all(axis=1)
        self._space_info = self._ompl_space(self._lower, self._upper)
        if not isinstance(acm, bool):
            raise SpecTypeError(f"acm must be True or False, got {acm!r}")
        self._acm: AllowedCollisionMatrix | None = None
        self._acm_version = -1
        if acm:
            began = time.perf_counter()
            sample_low = np.where(np.isfinite(ranges[:, 0]), ranges[:, 0], -math.pi)
            sample_high = np.where(np.isfinite(ranges[:, 1]), ranges[:, 1], math.pi)
            self._acm = compute_acm(
                robot,
                self._margin,
                sample_low,
                sample_high,
                samples=acm_samples,
                seed=seed,
                allow=acm_allow,
                padding=self._padding,
                link_padding=link_padding,
            )
            self._checker.unpad(self._acm.unpadded)
            self.acm_seconds = time.perf_counter() - began
        if srdf is not None:
            self._srdf_pairs(srdf)
        self._apply_acm()

    # ------------------------------------------------------------------ setup

    def _srdf_pairs(self, srdf: Srdf | str | Path) -> None:
        """Allow the SRDF's disabled pairs: in the matrix (reason "srdf"), or with
        `acm=False` next to `allowed_contacts`."""
        if isinstance(srdf, (str, Path)):
            srdf = Srdf.load(srdf)
        elif not isinstance(srdf, Srdf):
            raise SpecTypeError(f"srdf must be an Srdf or the path of an SRDF file, got {srdf!r}")
        model = self._robot.scene.model
        bodies = [model.body(b).name for b in range(model.nbody)]
        pairs = []
        for k, (first, second, _reason) in enumerate(srdf.disabled):
            names = []
            for link in (first, second):
                hits = [
                    b
                    for b in bodies
                    if b == link or (b.endswith(link) and b[-len(link) - 1] in "/_:")
                ]
                if len(hits) != 1:
                    where = f"SRDF file {srdf.source!r}, disable_collisions {k} ({first}, {second})"
                    raise unknown_name("body", link, bodies, where)
                names.append(hits[0])
            pairs.append((names[0], names[1]))
        if self._acm is None:
            self._allowed_user.extend(pairs)
            self._checker.set_allowed(self._allowed_user)
            return
        for a, b in pairs:
            if a != b and self._acm.reason(a, b) is None:
                self._acm.allow(a, b, reason="srdf")

    def _apply_acm(self) -> None:
        """Hand the matrix's pairs (as edited) and `allowed_contacts` to the checker."""
        acm = self._acm
        if acm is None or acm.version == self._acm_version:
            return
        self._checker.set_allowed([*self._allowed_user, *acm.pairs])
        self._acm_version = acm.version

    def _limits(
        self,
        velocity: Sequence[float] | None,
        acceleration: Sequence[float] | None,
        limits: RobotLimits | str | Path | None,
    ) -> tuple[np.ndarray, np.ndarray, str]:
        names = self._robot.joint_names
        given = {}
        for quantity, value in (("velocity", velocity), ("acceleration", acceleration)):
            field = f"{quantity}_limits"
            arr = None if value is None else _vector(value, self._n, field)
            if arr is not None and np.any(arr <= 0):
                i = int(np.flatnonzero(arr <= 0)[0])
                raise SpecError(
                    f"{field}[{i}] (joint {names[i]!r}) must be positive, got {arr[i]:g}"
                )
            given[quantity] = arr
        if isinstance(limits, (str, Path)):
            limits = RobotLimits.load(limits)
        elif limits is not None and not isinstance(limits, RobotLimits):
            raise SpecTypeError(
                f"limits must be a RobotLimits or the path of a joint_limits.yaml, got {limits!r}"
            )
        model = self._robot.model
        joints = [model.getJointId(name) for name in names]
        own = np.array([model.velocityLimit[model.joints[j].idx_v] for j in joints])
        effort = np.array([model.effortLimit[model.joints[j].idx_v] for j in joints])
        found = resolve_limits(self._robot.scene.model, names, given, limits, own, effort)
        self._torque = found.torque
        return found.velocity, found.acceleration, found.source

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
    def torque_limits(self) -> np.ndarray | None:
        """Per-joint torque limits (N·m or N; inf: none) toppra's timing keeps through the
        dynamics (`limits.effort`, else the model's); None when no joint has one."""
        return None if self._torque is None else self._torque.copy()

    @property
    def jerk_limits(self) -> np.ndarray:
        """Per-joint jerk limits of `timing="ruckig"` (default: acceleration / `JERK_RAMP`)."""
        return self._jmax.copy()

    @property
    def checker(self) -> CollisionChecker:
        """The collision checker the planner uses."""
        return self._checker

    @property
    def acm(self) -> AllowedCollisionMatrix | None:
        """The allowed-collision matrix (inspect and edit it; None when built with acm=False)."""
        return self._acm

    def contacts(self, q: Sequence[float]) -> list[tuple[str, str, float]]:
        """Pairs of bodies closer than the margin with the arm at `q` (nearest first)."""
        self._apply_acm()
        self._checker.sync()
        return self._checker.contacts(_vector(q, self._n, "q"))

    def plan(
        self,
        goal: Any,
        *,
        start: Sequence[float] | None = None,
        timeout: float = 1.0,
        carry: str | None = None,
        bounds: tuple[Sequence[float], Sequence[float]] | None = None,
        goal_tolerance: float = 0.0,
        position_tolerance: float | None = None,
        orientation_tolerance: float | None = None,
        velocity_scaling: float = 1.0,
        acceleration_scaling: float = 1.0,
        start_jiggle: float = 0.0,
        constraint: OrientationConstraint | None = None,
        timing: str = "toppra",
    ) -> JointTrajectory:
        """A collision-free, timed trajectory from `start` (default: the measured joint
        positions) to `goal`: a joint vector, a TCP pose (`pinocchio.SE3`), or a goal set (a
        list of either, or a k×n array): the path ends at whichever it reaches.

        `timeout` bounds the search (s). `carry`: a free body held by the tool, moved with
        the tip. `bounds`: (lower, upper) joint bounds for this call, inside the joint limits.
        `goal_tolerance` (rad, any joint): a joint goal in collision may be reached at a
        collision-free state this close to it. `position_tolerance` (m),
        `orientation_tolerance` (rad): how far from a pose goal the TCP may end.
        `velocity_scaling`, `acceleration_scaling` in (0, 1]: fractions of the limits.
        `start_jiggle` (rad, any joint): a start in collision (an arm a watching follower
        stopped on a contact) is left first, straight, for the nearest collision-free state
        this close, going no deeper into what it touches (MoveIt's FixStartStateCollision).
        `constraint`: an `OrientationConstraint` the TCP keeps along the whole timed path
        (the path is projected onto it; see `mjkdl.plan.constraints`). `timing`: "toppra"
        (time-optimal under velocity and acceleration limits, through a spline) or "ruckig"
        (jerk-limited too, at rest at every waypoint, on the checked polyline).

        Raises `InfeasibleError` (with a `reason`) when the query cannot be solved, before
        searching: a start or goal in collision or outside the bounds, no collision-free IK
        solution, a start or goal in a pocket of free space (`POCKET_RADIUS`), or with a
        `constraint` a start or goal that breaks it or that no path projected onto it can
        leave or reach (`APPROACH_SAMPLES`, reason "constraint") or that is boxed in along it
        (`BOX_REACH`, reason "pocket"); with RRTConnect, after `WALL_CHECKS` validity checks,
        a joint value that divides the free space between them ("disconnected", see `_wall`);
        raises `PlanningTimeout` when the search used its time.
        """
        budget = _number(timeout, "timeout", positive=True)
        began = time.perf_counter()
        self.last_stats = dict.fromkeys(_STEPS, 0.0)
        self.padding_dropped = False
        timer = self._timer(velocity_scaling, acceleration_scaling, timing)
        lower, upper = self._bounds(bounds)
        tolerance = _number(goal_tolerance, "goal_tolerance")
        jiggle = _number(start_jiggle, "start_jiggle")
        if constraint is not None and not isinstance(constraint, OrientationConstraint):
            raise SpecTypeError(f"constraint must be an OrientationConstraint, got {constraint!r}")
        pose_tolerance = (
            _optional(position_tolerance, "position_tolerance"),
            _optional(orientation_tolerance, "orientation_tolerance"),
        )
        self._apply_acm()
        self._checker.sync()
        if carry is not None or self._checker.carried is not None:
            self._checker.carry(carry)  # recomputes the contact masks: 1.5 ms on the Panda
        try:
            q_from, q0 = self._jiggled_start(start, lower, upper, jiggle)
            goals = self._goals(goal, q0, lower, upper, tolerance, pose_tolerance)
            if constraint is not None:
                deadline = began + BOX_SHARE * budget
                goals = self._constraint_ends(q0, goals, constraint, lower, upper, deadline)
                self._cone = constraint
            self.last_stats["ends"] = time.perf_counter() - began
            straight = True
            found, failure, unprojected = 0, "", 0
            while True:  # a path whose timing cuts into the margin is searched again
                try:
                    waypoints = self._search(q0, goals, budget, began, straight, lower, upper)
                except PlanningTimeout as error:
                    if not found:
                        raise
                    # The time went to paths found and refused, not to the search.
                    raise PlanningTimeout(self._refused(found, budget, failure)) from error
                found += 1
                if q_from is not q0:
                    waypoints = np.vstack([q_from[None], waypoints])
                trajectory = None
                failure = "came closer than the margin once timed"
                try:
                    if constraint is not None:
                        t_project = time.perf_counter()
                        try:
                            waypoints = self._project(waypoints, constraint, lower, upper)
                        finally:
                            self.last_stats["project"] += time.perf_counter() - t_project
                        failure = "failed its projection onto the constraint"
                    if constraint is None and isinstance(timer, TimeParametrizer):
                        # The spline through the midpoints too hugs the checked polyline:
                        # 6 in 60 Panda paths then cut a corner into the margin (and are timed
                        # again), against 21 in 60 through the waypoints alone; the durations
                        # are the same (medians within 1 %).
                        waypoints = _subdivide(waypoints)
                    trajectory = self._timed(waypoints, timer, lower, upper, constraint)
                except PlanningError as error:  # the projection: another path may do
                    failure = f"failed its projection onto the constraint (last: {error})"
                    unprojected += 1
                    if constraint is not None and unprojected % MANIFOLD_AFTER == 0:
                        left = began + budget - time.perf_counter()
                        wall = self._manifold_wall(
                            q0,
                            goals,
                            constraint,
                            lower,
                            upper,
                            time.perf_counter() + MANIFOLD_SHARE * max(0.0, left),
                            unprojected,
                        )
                        if wall is not None:
                            raise InfeasibleError(wall, "disconnected") from error
                if trajectory is not None:
                    return trajectory
                straight = False
                if time.perf_counter() - began > budget:
                    raise PlanningTimeout(self._refused(found, budget, failure))
        finally:
            self._start_need = None
            self._padded = True
            self._cone = None
            self._open_slices.clear()
            if carry is not None:
                self._checker.carry(None)

    def _refused(self, found: int, budget: float, failure: str) -> str:
        """Why a plan ran out of time with paths found: each was refused after the search."""
        return (
            f"{self._planner_name}: {found} path{'s' if found > 1 else ''} found within "
            f"{budget:g} s, none usable: the last {failure}; raise the timeout or the padding"
        )

    def plan_cartesian(
        self,
        pose: pin.SE3,
        *,
        step: float = 0.005,
        start: Sequence[float] | None = None,
        max_joint_step: float = 0.1,
        carry: str | None = None,
        allow_partial: bool = False,
        velocity_scaling: float = 1.0,
        acceleration_scaling: float = 1.0,
    ) -> JointTrajectory:
        """A timed trajectory along the straight TCP line to `pose` (rotation by slerp).

        IK at every `step` metres (or 0.05 rad of rotation), each seeded with the previous
        solution. A joint moving more than `max_joint_step` (rad) between two steps (a
        branch change), no IK solution or a pose in collision stops the line there:
        `InfeasibleError` naming where, its `fraction` the part achieved; with
        `allow_partial`, the trajectory up to there instead. `last_stats["fraction"]` is the
        fraction achieved (1.0: the whole line), as MoveIt's computeCartesianPath returns it.
        """
        if not isinstance(pose, pin.SE3):
            raise SpecTypeError(f"plan_cartesian: pose must be a pinocchio.SE3, got {pose!r}")
        if not (np.isfinite(pose.translation).all() and np.isfinite(pose.rotation).all()):
            raise SpecError(f"plan_cartesian: pose must be finite, got {pose}")
        step = _number(step, "step", positive=True)
        jump = _number(max_joint_step, "max_joint_step", positive=True)
        timer = self._timer(velocity_scaling, acceleration_scaling)
        self.last_stats = dict.fromkeys(_STEPS, 0.0)
        self._apply_acm()
        self._checker.sync()
        if carry is not None or self._checker.carried is not None:
            self._checker.carry(carry)  # recomputes the contact masks: 1.5 ms on the Panda
        try:
            q = self._start(start, self._lower, self._upper)
            begin = self._robot.fk_frame(q)
            delta = pin.log6(begin.inverse() * pose)
            count = max(
                1,
                math.ceil(np.linalg.norm(pose.translation - begin.translation) / step),
                math.ceil(np.linalg.norm(delta.angular) / 0.05),
            )
            waypoints = [q]
            stop = None
            for k in range(1, count + 1):
                target = _interpolate(begin, pose, k / count)
                stop = self._cartesian_step(target, q, jump, k, count, pose)
                if isinstance(stop, str):
                    break
                q = stop
                waypoints.append(q)
                stop = None
            fraction = (len(waypoints) - 1) / count
            self.last_stats["fraction"] = fraction
            if stop is not None and not (allow_partial and len(waypoints) > 1):
                raise InfeasibleError(
                    f"{stop}; {fraction:.0%} of the line achieved", "cartesian", fraction
                )
            trajectory = self._timed(np.array(waypoints), timer)
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

    def _cartesian_step(
        self, target: pin.SE3, q: np.ndarray, jump: float, k: int, count: int, pose: pin.SE3
    ) -> np.ndarray | str:
        """The IK solution for step k of the line, or why there is none (a message)."""
        result = self._robot.ik(target, q)
        where = f"at {k / count:.0%} of the line to {pose.translation.round(4).tolist()}"
        if not result.success:
            return (
                f"plan_cartesian: no IK solution {where} (position error "
                f"{result.position_error:.2g} m)"
            )
        moved = np.abs(result.q - q)
        if moved.max() > jump:
            i = int(moved.argmax())
            return (
                f"plan_cartesian: joint {self._robot.joint_names[i]!r} jumps "
                f"{moved[i]:.3f} rad {where} (more than max_joint_step={jump:g}): the "
                "IK changed branch or the line passes a singularity"
            )
        clash = self._clash(result.q, f"plan_cartesian: the pose {where}")
        return result.q if clash is None else clash

    def _timer(
        self, velocity_scaling: float, acceleration_scaling: float, timing: str = "toppra"
    ) -> Any:
        """The time parametrizer for the limits scaled by these fractions (kept per pair)."""
        if timing not in ("toppra", "ruckig"):
            raise SpecError(f'timing must be "toppra" or "ruckig", got {timing!r}')
        scales = []
        for value, field in (
            (velocity_scaling, "velocity_scaling"),
            (acceleration_scaling, "acceleration_scaling"),
        ):
            number = _number(value, field, positive=True)
            if number > 1.0:
                raise SpecError(f"{field} must be in (0, 1], got {number:g}")
            scales.append(number)
        key = (scales[0], scales[1], timing)
        if key not in self._timers:
            v, a = self._vmax * key[0], self._amax * key[1]
            self._timers[key] = (
                TimeParametrizer(
                    v,
                    a,
                    self._torque,
                    None if self._torque is None else self._robot.inverse_dynamics,
                )
                if timing == "toppra"
                else JerkLimitedParametrizer(v, a, self._jmax * key[1])
            )
        return self._timers[key]

    def _bounds(
        self, bounds: tuple[Sequence[float], Sequence[float]] | None
    ) -> tuple[np.ndarray, np.ndarray]:
        """This call's joint bounds: `bounds` checked against the joint limits."""
        if bounds is None:
            return self._lower, self._upper
        if not isinstance(bounds, (tuple, list)) or len(bounds) != 2:
            raise SpecTypeError(f"bounds must be a pair (lower, upper), got {bounds!r}")
        lower = _vector(bounds[0], self._n, "bounds[0]")
        upper = _vector(bounds[1], self._n, "bounds[1]")
        names = self._robot.joint_names
        for i in range(self._n):
            if not lower[i] < upper[i]:
                raise SpecError(
                    f"bounds: joint {names[i]!r} lower {lower[i]:g} must be below upper "
                    f"{upper[i]:g}"
                )
            if lower[i] < self._lower[i] - 1e-9 or upper[i] > self._upper[i] + 1e-9:
                raise SpecError(
                    f"bounds: joint {names[i]!r} [{lower[i]:g}, {upper[i]:g}] leaves its "
                    f"limits [{self._lower[i]:g}, {self._upper[i]:g}]"
                )
        return lower, upper

    def _jiggled_start(
        self, start: Sequence[float] | None, lower: np.ndarray, upper: np.ndarray, jiggle: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """The start, and the state the search starts from: the start itself, or with
        `jiggle` > 0 and a start in collision, the nearest of `TOLERANCE_SAMPLES` random
        collision-free states within `jiggle` of it."""
        q = self._measured_start(start, lower, upper)
        clash = self._clash(q, "the start")
        if clash is None:
            return q, q
        if jiggle > 0.0:
            low, high = np.maximum(q - jiggle, lower), np.minimum(q + jiggle, upper)
            near = self._rng.uniform(low, high, (TOLERANCE_SAMPLES, self._n))
            free = [s for s in near if self._checker.valid(s)]
            if free:
                # Leaving, the arm may not go deeper into what it touches (1 mm slack).
                nearest = min(free, key=lambda s: float(np.abs(s - q).max()))
                reach = float(np.abs(nearest - q).max())
                self._start_need = (self._checker.clearance(q) - 0.001, reach)
                return q, nearest
            clash += f" (and no collision-free state within start_jiggle={jiggle:g} rad)"
        raise InfeasibleError(clash, "collision")

    def _start(
        self, start: Sequence[float] | None, lower: np.ndarray, upper: np.ndarray
    ) -> np.ndarray:
        q = self._measured_start(start, lower, upper)
        self._in_collision(q, "the start")
        return q

    def _measured_start(
        self, start: Sequence[float] | None, lower: np.ndarray, upper: np.ndarray
    ) -> np.ndarray:
        """The start inside the bounds: a measured arm slightly past a limit (MuJoCo's joint
        limits are soft: 0.1 mrad after a move that ends on one) is clipped back."""
        q = self._robot.jnt_pos_msr.copy() if start is None else _vector(start, self._n, "start")
        if start is None:
            near = (q >= lower - START_SLACK) & (q <= upper + START_SLACK)
            q[near] = np.clip(q[near], lower[near], upper[near])
        self._inside(q, "start", lower, upper)
        return q

    def _inside(self, q: np.ndarray, what: str, lower: np.ndarray, upper: np.ndarray) -> None:
        message = self._outside(q, what, lower, upper)
        if message is not None:
            raise InfeasibleError(message, "bounds")

    def _outside(
        self, q: np.ndarray, what: str, lower: np.ndarray, upper: np.ndarray
    ) -> str | None:
        outside = np.flatnonzero((q < lower - 1e-9) | (q > upper + 1e-9))
        if not len(outside):
            return None
        i = int(outside[0])
        return (
            f"{what}: joint {self._robot.joint_names[i]!r} at {q[i]:g} is outside "
            f"[{lower[i]:g}, {upper[i]:g}]"
            + (" (unlimited joints are planned within ±2π)" if upper[i] == UNLIMITED_RANGE else "")
        )

    def _clash(self, q: np.ndarray, what: str) -> str | None:
        """Why `q` is in collision (a message naming the nearest pair), or None."""
        if self._checker.valid(q):
            return None
        a, b, d = self._checker.contacts(q)[0]
        return (
            f"{what} is in collision: bodies {a!r} and {b!r} are {d * 1000:.1f} mm apart "
            f"(margin {self._margin * 1000:g} mm; negative: penetrating)"
        )

    def _in_collision(self, q: np.ndarray, what: str) -> None:
        message = self._clash(q, what)
        if message is not None:
            raise InfeasibleError(message, "collision")

    def _goals(
        self,
        goal: object,
        q0: np.ndarray,
        lower: np.ndarray,
        upper: np.ndarray,
        tolerance: float,
        pose_tolerance: tuple[float | None, float | None],
    ) -> np.ndarray:
        """The collision-free joint goals (k×n, nearest to `q0` first) of a goal or goal set,
        checked for pockets; InfeasibleError when none is left."""
        items = _goal_items(goal, self._n)
        found: list[np.ndarray] = []
        reasons: list[tuple[str, str]] = []
        for k, item in enumerate(items):
            what = "the goal" if len(items) == 1 else f"goal {k}"
            if isinstance(item, pin.SE3):
                states, why = self._ik(item, q0, lower, upper, pose_tolerance)
            else:
                states, why = self._joint_goal(item, what, lower, upper, tolerance)
            found.extend(states)
            if why is not None:
                reasons.append(why)
        if not found:
            reason, message = reasons[0]
            if len(items) > 1:
                message = f"no goal of the set can be reached; {message}"
            raise InfeasibleError(message, reason)
        goals = np.array(sorted(found, key=lambda q: float(np.abs(q - q0).sum())))
        tree = (
            f"a random tree of {POCKET_CHECKS} validity checks, half its extensions toward "
            "random TCP positions"
        )
        start_pocket = self._pocket(q0, lower, upper)
        if start_pocket is not None:
            # The start is boxed in: only goals inside its pocket can be reached.
            reached, size = start_pocket
            goals = goals[np.abs(goals - q0).max(axis=1) < reached]
            if not len(goals):
                raise InfeasibleError(
                    f"the start is in a pocket of free space: no collision-free motion from it "
                    f"gets more than {reached:.3f} rad away ({tree}: {size} free states), and "
                    "no goal lies inside",
                    "pocket",
                )
            return goals
        open_goals = [q for q in goals if self._pocket(q, lower, upper) is None]
        if not open_goals:
            raise InfeasibleError(
                f"the goal{'s are' if len(goals) > 1 else ' is'} in a pocket of free space: no "
                f"collision-free motion from it gets more than {POCKET_RADIUS:g} rad away "
                f"({tree}); the start cannot get in",
                "pocket",
            )
        return np.array(open_goals)

    def _joint_goal(
        self, q: np.ndarray, what: str, lower: np.ndarray, upper: np.ndarray, tolerance: float
    ) -> tuple[list[np.ndarray], tuple[str, str] | None]:
        outside = self._outside(q, what, lower, upper)
        if outside is not None and tolerance == 0.0:
            return [], ("bounds", outside)
        clash = self._clash(q, what) if outside is None else outside
        if clash is None:
            return [q], None
        if tolerance > 0.0:
            low, high = np.maximum(q - tolerance, lower), np.minimum(q + tolerance, upper)
            if np.all(low <= high):
                near = self._rng.uniform(low, high, (TOLERANCE_SAMPLES, self._n))
                valid = [s for s in near if self._checker.valid(s)]
                if valid:
                    return [min(valid, key=lambda s: float(np.abs(s - q).max()))], None
            clash += f" (and no collision-free state within goal_tolerance={tolerance:g} rad)"
        return [], ("collision" if outside is None else "bounds", clash)

    def _ik(
        self,
        pose: pin.SE3,
        q0: np.ndarray,
        lower: np.ndarray,
        upper: np.ndarray,
        tolerance: tuple[float | None, float | None],
    ) -> tuple[list[np.ndarray], tuple[str, str] | None]:
        """The collision-free IK solution inside the bounds nearest to `q0` among the first
        3 found from `ik_attempts` seeds (`q0` first, then random ones inside the bounds);
        an IK result within the tolerances counts as a solution."""
        if not (np.isfinite(pose.translation).all() and np.isfinite(pose.rotation).all()):
            raise SpecError(f"goal pose must be finite, got {pose}")
        seeds = [q0, *self._rng.uniform(lower, upper, (self._ik_attempts - 1, self._n))]
        found: list[np.ndarray] = []
        clash: tuple[str, str, float] | None = None
        best_error = math.inf
        position_tol, orientation_tol = tolerance
        for seed in seeds:
            result = self._robot.ik(pose, seed)
            close = (
                position_tol is not None
                and result.position_error <= position_tol
                and result.rotation_error <= (orientation_tol or 0.0) + 1e-3
            ) or (
                orientation_tol is not None
                and result.rotation_error <= orientation_tol
                and result.position_error <= (position_tol or 0.0) + 1e-4
            )
            if not (result.success or close):
                best_error = min(best_error, result.position_error)
                continue
            if self._outside(result.q, "", lower, upper) is not None:
                continue
            if not self._checker.valid(result.q):
                clash = clash or self._checker.contacts(result.q)[0]
                continue
            found.append(result.q)
            if len(found) >= 3:
                break
        if found:  # the nearest: another IK branch makes a needlessly long, contorted move
            return [min(found, key=lambda q: float(np.abs(q - q0).sum()))], None
        where = f"the goal pose at {pose.translation.round(4).tolist()}"
        if clash is not None:
            a, b, d = clash
            return [], (
                "ik-collision",
                f"{where}: every IK solution is in collision (e.g. bodies {a!r} and {b!r} "
                f"{d * 1000:.1f} mm apart, margin {self._margin * 1000:g} mm)",
            )
        return [], (
            "unreachable",
            f"{where} is unreachable: no IK solution within the bounds from {len(seeds)} "
            f"seeds (best position error {best_error:.3g} m)",
        )

    def _pocket(
        self, q: np.ndarray, lower: np.ndarray, upper: np.ndarray
    ) -> tuple[float, int] | None:
        """None when collision-free motion leads `POCKET_RADIUS` (rad, any joint) away from
        `q`; else how far it got and the tree's size. A random tree grows from `q` for
        `POCKET_CHECKS` validity checks, its extensions in turn toward a random state
        (straight, at the search's resolution) and toward a random TCP position (the tool
        held as it is, `POCKET_STEP` m a step); in open space the first straight ray gets
        out after a few checks. Seeded by the planner's seed and `q`: the same query gets
        the same verdict."""
        fk = self._robot.fk_frame
        rng = np.random.default_rng([self._seed, zlib.crc32(np.round(q, 9).tobytes()), 0])
        centre = fk(q).translation
        nodes = np.empty((POCKET_CHECKS + 1, self._n))
        tcps = np.empty((POCKET_CHECKS + 1, 3))
        nodes[0], tcps[0], size = q, centre, 1
        reached = 0.0
        low = np.maximum(q - 2 * POCKET_RADIUS, lower)
        high = np.minimum(q + 2 * POCKET_RADIUS, upper)
        checks = 0
        for k in range(POCKET_CHECKS):  # an extension may cost no check
            if checks >= POCKET_CHECKS:
                break
            # Every other extension heads for a TCP position: in a tight pocket (a hand in a
            # box, its way out under a lip) random joint directions soon hit a wall.
            if k % 2:
                point = centre + rng.uniform(-POCKET_REACH, POCKET_REACH, 3)
                index = int(np.linalg.norm(tcps[:size] - point, axis=1).argmin())
                steps = POCKET_STEPS
            else:
                target = rng.uniform(low, high)
                index = int(np.abs(nodes[:size] - target).max(axis=1).argmin())
                direction = target - nodes[index]
                steps = math.ceil(float(np.abs(direction).max()) / self._resolution)
            state, x = nodes[index], tcps[index]
            for j in range(1, steps + 1):
                if k % 2:
                    gap = float(np.linalg.norm(point - x))
                    move = self._toward(state, x, point, POCKET_STEP, False)
                    if move is None:
                        break
                    move *= min(1.0, self._resolution / float(np.abs(move).max()))
                    result = state + move
                    if self._outside(result, "", lower, upper) is not None:
                        break
                else:
                    result = nodes[index] + direction * (j / steps)
                if checks >= POCKET_CHECKS:
                    break
                checks += 1
                self.checks += 1
                if not self._checker.valid(result):
                    break
                x = fk(result).translation
                if k % 2 and float(np.linalg.norm(point - x)) >= gap:
                    break  # no nearer: the arm cannot move the TCP that way
                nodes[size], tcps[size] = result, x
                size += 1
                state = result
                reached = max(reached, float(np.abs(result - q).max()))
                if reached >= POCKET_RADIUS:
                    return None
        return reached, size - 1

    def _toward(
        self, state: np.ndarray, x: np.ndarray, point: np.ndarray, step: float, turn: bool
    ) -> np.ndarray | None:
        """The joint motion from `state` (its TCP at `x`) that moves the TCP `step` (m)
        toward `point` (damped least squares on the Jacobian; `turn`: the tool may turn,
        else it is held as it is); None within a step of it, or where no joint motion moves
        the TCP that way (a singular arm)."""
        away = point - x
        gap = float(np.linalg.norm(away))
        if gap < step:
            return None
        rows = 3 if turn else 6
        jv = self._robot.jacobian(state)[:rows]
        velocity = np.concatenate([away, np.zeros(rows - 3)])
        move = jv.T @ np.linalg.solve(jv @ jv.T + 1e-6 * np.eye(rows), velocity) * (step / gap)
        return None if float(np.abs(move).max()) < 1e-9 else move

    def _search(
        self,
        q0: np.ndarray,
        goals: np.ndarray,
        budget: float,
        began: float,
        straight: bool,
        lower: np.ndarray,
        upper: np.ndarray,
    ) -> np.ndarray:
        """OMPL's path from q0 to one of `goals` (k×n), simplified, as waypoints; `budget`
        seconds from `began` (a `perf_counter` time). `straight`: try the straight segments
        first."""
        from ompl import base as ob
        from ompl import geometric as og
        from ompl import util as ou

        self.last_stats.update(search=0.0, simplify=0.0)
        if straight:
            t = time.perf_counter()
            for q1 in goals:
                self._ends[0], self._ends[1] = q0, q1
                if self._straight(q0, q1):
                    self.last_stats["search"] = time.perf_counter() - t
                    return np.array([q0, q1])
        t_search = time.perf_counter()
        si = self._space_info
        if self._unlimited.any() or lower is not self._lower or upper is not self._upper:
            lower, upper = lower.copy(), upper.copy()
            free = self._unlimited & (lower <= -UNLIMITED_RANGE) & (upper >= UNLIMITED_RANGE)
            if free.any():
                # An unlimited joint is searched within half a turn beyond the start and
                # goals, not over the whole ±2π: a quarter of the volume per joint, or less.
                ends = np.vstack([q0[None], goals])
                lower[free] = ends.min(axis=0)[free] - math.pi
                upper[free] = ends.max(axis=0)[free] + math.pi
            si = self._ompl_space(lower, upper)
        self._ends = np.vstack([q0[None], goals])
        self._invalid = 0
        self._padding_only = 0
        self._blockers = {}
        setup = og.SimpleSetup(si)
        planner = getattr(og, self._planner_name)(si)
        if hasattr(planner, "setRange"):
            planner.setRange(RANGE)
        setup.setPlanner(planner)
        states = _states(si, np.vstack([q0[None], goals]))
        setup.setStartState(states[0])
        target = ob.GoalStates(si)
        for state in states[1:]:
            target.addState(state)
        setup.setGoal(target)
        checks = self.checks
        level = ou.getLogLevel()
        ou.setLogLevel(ou.LOG_NONE)
        try:
            status = None
            if self._planner_name == "RRTConnect":
                # A first `WALL_CHECKS` validity checks (a count, not a time: the trees the
                # wall test reads are then the same on any machine); then, unsolved, look
                # for a wall between the two trees (`_wall`) before searching on.
                until = began + WALL_AFTER * budget
                if time.perf_counter() < until:
                    first = self.checks + WALL_CHECKS
                    status = setup.solve(
                        ob.PlannerTerminationCondition(
                            lambda: self.checks >= first or time.perf_counter() > until
                        )
                    )
                    if not setup.haveExactSolutionPath():
                        wall = self._wall(planner, si, lower, upper, began + budget)
                        if wall is not None:
                            raise InfeasibleError(wall, "disconnected")
                        if self._padding_only:
                            # Unsolved, and the padding refused states the margin allows: on
                            # with the margin alone (the timed trajectory is still checked for
                            # it). The UR10 on the floor planned 20 of 30 random queries in 1 s
                            # with the padding throughout; the ten others need the states only
                            # 5-10 mm clear (6-18 % of the refused ones).
                            self._padded = False
                            self.padding_dropped = True
            if status is None or not setup.haveExactSolutionPath():
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
            blocking = self._blocking(self.checks - checks)
            raise PlanningTimeout(
                f"{self._planner_name} found no collision-free path within {budget:.3g} s "
                f"({self.checks - checks} states checked, status {status.asString()}, margin "
                f"{self._margin * 1000:g} mm){blocking}"
                + (
                    ""
                    if blocking
                    else ": raise the timeout, try another planner, or check "
                    "that the goal can be reached"
                )
            )
        # The search's wall time (setup included), as a plain OMPL script would measure it.
        self.last_stats["search"] = time.perf_counter() - t_search - t_simplify
        self.last_stats["simplify"] = t_simplify
        n = self._n
        return np.array([state[0:n] for state in path.getStates()])

    def _wall(
        self, planner: Any, si: Any, lower: np.ndarray, upper: np.ndarray, deadline: float
    ) -> str | None:
        """Why the start and goals lie in different regions of free space, or None: a joint
        value c that the search's start tree (RRTConnect's tag 1) and goal tree (tag 2) have
        not crossed from either side, at which `WALL_SAMPLES` random configurations (the
        other joints uniform within the bounds) are all in collision. Both are evidence, not
        proof: a passage through c too narrow for either to find would be missed. Gives up
        (None) at `deadline` (a `perf_counter` time)."""
        from ompl import base as ob

        data = ob.PlannerData(si)
        planner.getPlannerData(data)
        n = self._n
        trees: dict[int, list[list[float]]] = {1: [], 2: []}
        for k in range(data.numVertices()):
            vertex = data.getVertex(k)
            state = vertex.getState()
            trees.setdefault(vertex.getTag(), []).append([state[i] for i in range(n)])
        if not trees[1] or not trees[2]:
            return None
        start, goal = np.array(trees[1]), np.array(trees[2])
        for i in range(n):
            if start[:, i].max() < goal[:, i].min():
                gap = (float(start[:, i].max()), float(goal[:, i].min()))
            elif goal[:, i].max() < start[:, i].min():
                gap = (float(goal[:, i].max()), float(start[:, i].min()))
            else:
                continue
            count = max(1, math.floor((gap[1] - gap[0]) / WALL_STEP))
            for c in np.linspace(gap[0], gap[1], count + 2)[1:-1].tolist():
                blocked = self._blocked(i, c, lower, upper, deadline)
                if blocked is None:
                    return None
                if blocked:
                    name = self._robot.joint_names[i]
                    kept = (
                        ""
                        if self._cone is None
                        else f" with the tool axis within {math.degrees(SEARCH_CONE):g}° of the "
                        "constraint's"
                    )
                    wrap = (
                        "; a joint with more than a turn: try the goal's equivalent a turn "
                        "(2π) towards the start's side"
                        if upper[i] - lower[i] > 2 * math.pi + 1e-9
                        else ""
                    )
                    return (
                        f"the start and goal lie in different regions of free space: joint "
                        f"{name!r} cannot pass {c:.3f} rad (none of {WALL_SAMPLES} random "
                        f"configurations with it there is collision-free{kept}: a passage, if any, "
                        f"holds under {1 / WALL_SAMPLES:.2%} of them; neither search tree "
                        f"crossed [{gap[0]:.3f}, {gap[1]:.3f}] rad in "
                        f"{len(start) + len(goal)} states){wrap}"
                    )
        return None

    def _manifold_wall(
        self,
        q0: np.ndarray,
        goals: np.ndarray,
        constraint: OrientationConstraint,
        lower: np.ndarray,
        upper: np.ndarray,
        deadline: float,
        refused: int,
    ) -> str | None:
        """Why no path kept on `constraint` joins the start and the (single) goal, or None: a
        value c of a joint between the start's and the goal's (both first put on the axis,
        `_first_reach` kept clear of each) at which none of `MANIFOLD_SAMPLES` random
        configurations, projected onto the constraint with the joint held at c, is
        collision-free inside the bounds; every such path crosses c. Evidence, not proof, like
        `_wall`. Gives up (None) at `deadline`; the slices found open are kept for the next
        call of the same plan."""
        if len(goals) != 1:
            return None
        robot = self._robot
        ends = []
        for q in (q0, goals[0]):
            on_axis = constraint.project_joints(q, robot.fk_frame, robot.jacobian)
            if on_axis is None:
                return None
            ends.append((on_axis, self._first_reach(q, constraint)))
        (a, reach_a), (b, reach_b) = ends
        for i in range(self._n):
            low, high = sorted((float(a[i]), float(b[i])))
            low, high = low + max(reach_a, reach_b), high - max(reach_a, reach_b)
            if high <= low:
                continue
            count = max(1, math.floor((high - low) / WALL_STEP))
            for c in np.linspace(low, high, count + 1).tolist():
                if (i, c) in self._open_slices:
                    continue
                blocked = self._blocked(i, c, lower, upper, deadline, onto=constraint)
                if blocked is None:
                    return None
                if not blocked:
                    self._open_slices.add((i, c))
                else:
                    return (
                        f"no path on the constraint's axis joins the start and the goal: joint "
                        f"{robot.joint_names[i]!r} must pass {c:.3f} rad between them, and none "
                        f"of {MANIFOLD_SAMPLES} random configurations with it there, projected "
                        "onto the constraint (the joint held), is collision-free inside the "
                        f"bounds (checked after {refused} paths failed their projection; "
                        f"{_ON_AXIS})"
                    )
        return None

    def _blocked(
        self,
        i: int,
        c: float,
        lower: np.ndarray,
        upper: np.ndarray,
        deadline: float,
        onto: OrientationConstraint | None = None,
    ) -> bool | None:
        """Whether all `WALL_SAMPLES` random configurations (the other joints uniform within
        [lower, upper]) with joint `i` at `c` fail the checker in use (with a path
        constraint, the search's: the tool axis within `SEARCH_CONE` too; with `onto`,
        `MANIFOLD_SAMPLES` of them, each first projected onto that constraint, joint `i` held,
        and landing inside the bounds); None at `deadline`. The samples depend only on the
        planner's seed, the joint and the value, so the same slice gets the same verdict
        whatever ran before."""
        robot = self._robot
        cone, fk = self._cone, robot.fk_frame
        rng = np.random.default_rng([self._seed, i, round(abs(c) * 1e6), int(c < 0)])
        samples, batch = (WALL_SAMPLES, 100) if onto is None else (MANIFOLD_SAMPLES, 5)
        for first in range(0, samples, batch):
            if time.perf_counter() > deadline:
                return None
            rows = rng.uniform(lower, upper, (min(batch, samples - first), self._n))
            rows[:, i] = c
            for q in rows:
                if onto is not None:
                    q = onto.project_joints(q, fk, robot.jacobian, hold=i)
                    if q is None or self._outside(q, "", lower, upper) is not None:
                        continue
                self.checks += 1
                if self._checker.valid(q) and (
                    cone is None or cone.error(fk(q).rotation) <= SEARCH_CONE
                ):
                    return False
        return True

    def _search_valid(self, q: np.ndarray | list[float]) -> bool:
        """The search's test: `margin + padding` clear, or `margin` within `ESCAPE` of the
        start or a goal (which may themselves be closer than the padding to something)."""
        self.checks += 1
        cone = self._cone
        if (
            cone is not None
            and cone.error(self._robot.fk_frame(np.asarray(q)).rotation) > SEARCH_CONE
        ):
            return False
        d, padded = self._checker.clearances(q)
        if padded >= self._margin:
            return True
        if d >= self._margin:
            if not self._padded:
                return True
            if np.abs(self._ends - np.asarray(q)).max(axis=1).min() < ESCAPE:
                return True
            self._padding_only += 1
        self._invalid += 1
        nearest = self._checker.nearest()
        if nearest is not None:
            g1, g2, dist = nearest
            self._blockers.setdefault((min(g1, g2), max(g1, g2)), []).append(dist)
        return False

    def _blocking(self, checks: int) -> str:
        """When most of the `checks` states the search looked at were invalid: which body
        pair was the least clear in most of them, and what to do about it; else ""."""
        if checks <= 0 or self._invalid < 0.5 * checks or not self._blockers:
            return ""
        by_pair: dict[tuple[str, str], list[float]] = {}
        pads: dict[tuple[str, str], float] = {}
        for (g1, g2), distances in self._blockers.items():
            a, b, pad = self._checker.pair_names(g1, g2)
            by_pair.setdefault((a, b), []).extend(distances)
            pads[a, b] = max(pads.get((a, b), 0.0), pad)
        (a, b), distances = max(by_pair.items(), key=lambda item: len(item[1]))
        return (
            f"; {self._invalid / checks:.0%} of the states it checked were invalid, "
            f"{len(distances) / self._invalid:.0%} of those for bodies {a!r} and {b!r} (a "
            f"median {float(np.median(distances)) * 1000:.1f} mm apart, against margin "
            f"{self._margin * 1000:g} mm + padding {pads[a, b] * 1000:g} mm): if they may "
            f"touch, allow the pair (planner.acm.allow({a!r}, {b!r})), else lower their "
            f"padding (link_padding={{{b!r}: 0.0}}) or the margin"
        )

    def _straight(self, q0: np.ndarray, q1: np.ndarray) -> bool:
        """Whether the straight joint-space segment q0 -> q1 passes the search's test."""
        count = max(1, math.ceil(float(np.linalg.norm(q1 - q0)) / self._resolution))
        return all(self._search_valid(q0 + (q1 - q0) * (k / count)) for k in range(1, count))

    def _timed(
        self,
        waypoints: np.ndarray,
        timer: TimeParametrizer | JerkLimitedParametrizer,
        lower: np.ndarray | None = None,
        upper: np.ndarray | None = None,
        constraint: OrientationConstraint | None = None,
    ) -> JointTrajectory | None:
        """`timer`'s timing of the path, checked (`constraint` too); when the spline cuts
        a corner into a collision or overshoots the bounds (default: the joint limits), the path is
        subdivided (the spline then hugs it) and timed again. None when that does not
        help: the path itself grazes the margin between its checks."""
        bounds = (
            self._lower if lower is None else lower,
            self._upper if upper is None else upper,
        )
        for _ in range(3):
            t = time.perf_counter()
            trajectory = timer(waypoints)
            t_check = time.perf_counter()
            self.last_stats["timing"] += t_check - t
            ok = self._trajectory_ok(trajectory, *bounds) and (
                constraint is None or self._keeps(trajectory, constraint)
            )
            self.last_stats["check"] += time.perf_counter() - t_check
            if ok:
                return trajectory
            waypoints = _subdivide(waypoints)
        return None

    def _constraint_ends(
        self,
        q0: np.ndarray,
        goals: np.ndarray,
        constraint: OrientationConstraint,
        lower: np.ndarray,
        upper: np.ndarray,
        deadline: float,
    ) -> np.ndarray:
        """The goals a path kept on `constraint` can reach from `q0`; InfeasibleError
        ("constraint") when the start or a goal breaks it, when no path can leave the start
        along it, or when none can reach any goal (`_approach`); ("pocket") when the start,
        or every goal, is boxed in along it with the other end outside (`_boxed`, given up at
        `deadline`, a `perf_counter` time)."""
        fk = self._robot.fk_frame
        for q, what in ((q0, "the start"), *((g, "the goal") for g in goals)):
            error = constraint.error(fk(q).rotation)
            if error > constraint.tolerance:
                raise InfeasibleError(
                    f"{what} breaks the constraint: the tool axis is {math.degrees(error):.1f}° "
                    f"from the world axis (tolerance {math.degrees(constraint.tolerance):.1f}°)"
                    + self._unmet(constraint, lower, upper),
                    "constraint",
                )
        why = self._approach(q0, constraint, lower, upper, self._first_reach(q0, constraint))
        if why is not None:
            raise InfeasibleError(
                f"no path on the constraint's axis can leave the start: {why}; every path's "
                f"first projected step would fail ({_ON_AXIS})",
                "constraint",
            )
        reasons = [self._approach(g, constraint, lower, upper, None) for g in goals]
        kept = [g for g, why in zip(goals, reasons, strict=True) if why is None]
        if not kept:
            what = "the goal" if len(goals) == 1 else f"any of the {len(goals)} goals"
            raise InfeasibleError(
                f"no path on the constraint's axis can reach {what}: {reasons[0]}; every "
                f"path's last projected step would fail ({_ON_AXIS})",
                "constraint",
            )
        boxed = self._boxed(q0, constraint, lower, upper, deadline)
        if boxed is not None:
            centre, radius, evidence = boxed
            away = [float(np.linalg.norm(fk(g).translation - centre)) for g in kept]
            inside = [g for g, d in zip(kept, away, strict=True) if d <= radius]
            if not inside:
                what = "the goal is" if len(kept) == 1 else f"the nearest of {len(kept)} goals is"
                raise InfeasibleError(
                    f"the start is boxed in along the constraint: no path on the constraint's "
                    f"axis gets the TCP more than {radius * 1000:.0f} mm from the start's, and "
                    f"{what} {min(away) * 1000:.0f} mm away ({evidence}; {_ON_AXIS})",
                    "pocket",
                )
            return np.array(inside)
        open_goals, first = [], None
        for g in kept:
            boxed = self._boxed(g, constraint, lower, upper, deadline)
            if boxed is None:
                open_goals.append(g)
                continue
            centre, radius, evidence = boxed
            d = float(np.linalg.norm(fk(q0).translation - centre))
            if d <= radius:
                open_goals.append(g)
            elif first is None:
                first = (radius, evidence, d)
        if not open_goals and first is not None:
            radius, evidence, d = first
            what = "the goal is" if len(kept) == 1 else f"each of the {len(kept)} goals is"
            raise InfeasibleError(
                f"{what} boxed in along the constraint: no path on the constraint's axis gets "
                f"the TCP more than {radius * 1000:.0f} mm from the goal's, and the start is "
                f"{d * 1000:.0f} mm away ({evidence}; {_ON_AXIS})",
                "pocket",
            )
        return np.array(open_goals)

    def _first_reach(self, q: np.ndarray, constraint: OrientationConstraint) -> float:
        """How far (rad, any joint) a path's first projected state may be from its start `q`:
        3 `PROJECTION_STEP`s, plus how far `q` itself is from the axis in joint space (a start
        within the tolerance but off the axis)."""
        robot = self._robot
        on_axis = constraint.project_joints(q, robot.fk_frame, robot.jacobian)
        off = 0.0 if on_axis is None else float(np.abs(on_axis - q).max())
        return 3 * PROJECTION_STEP + off

    def _boxed(
        self,
        q: np.ndarray,
        constraint: OrientationConstraint,
        lower: np.ndarray,
        upper: np.ndarray,
        deadline: float,
    ) -> tuple[np.ndarray, float, str] | None:
        """None when a path kept on `constraint` gets the TCP `BOX_REACH` (m) from `q`'s, or
        when that cannot be told by `deadline`; else the centre and radius (m) of a sphere
        around `q`'s TCP (on the axis) that no such path leaves, and the evidence (counts,
        the pairs in collision): a tree of projected steps stayed inside it, and none of the
        states sampled on it with the tool on the axis is collision-free. Seeded by the
        planner's seed and `q`."""
        robot = self._robot
        fk, jacobian = robot.fk_frame, robot.jacobian
        root = constraint.project_joints(q, fk, jacobian)
        if root is None or not self._checker.valid(root):
            return None
        centre = fk(root).translation
        rng = np.random.default_rng([self._seed, zlib.crc32(np.round(q, 9).tobytes()), 1])
        low = np.maximum(root - BOX_SPREAD, lower)
        high = np.minimum(root + BOX_SPREAD, upper)
        nodes, tcps = [root], [centre]
        stopped: dict[tuple[str, str], int] = {}
        for k in range(BOX_TRIES):
            # Every other extension heads for a random TCP position instead of a random
            # joint state: in a tight pocket, random joint directions soon hit a wall.
            if k % 2:
                point = centre + rng.uniform(-2 * BOX_REACH, 2 * BOX_REACH, 3)
                index = int(np.argmin([float(np.linalg.norm(x - point)) for x in tcps]))
                target = None
            else:
                target = rng.uniform(low, high)
                index = int(np.argmin([float(np.abs(x - target).max()) for x in nodes]))
            state, x = nodes[index], tcps[index]
            for _ in range(int(2 * BOX_SPREAD / PROJECTION_STEP)):
                if time.perf_counter() > deadline:
                    return None
                if target is None:
                    gap = float(np.linalg.norm(point - x))
                    toward = self._toward(state, x, point, BOX_STEP, True)
                    if toward is None:
                        break
                    move = toward
                else:
                    move = target - state
                    if float(np.abs(move).max()) < PROJECTION_STEP / 2:
                        break
                move *= min(1.0, PROJECTION_STEP / float(np.abs(move).max()))
                result = constraint.project_joints(state + move, fk, jacobian)
                if (
                    result is None
                    or float(np.abs(result - state).max()) > 3 * PROJECTION_STEP
                    or self._outside(result, "", lower, upper) is not None
                ):
                    break
                self.checks += 1
                if not self._checker.valid(result):
                    pair = self._nearest_pair()
                    stopped[pair] = stopped.get(pair, 0) + 1
                    break
                x = fk(result).translation
                if target is None and float(np.linalg.norm(point - x)) >= gap:
                    break  # no nearer: the arm cannot move the TCP that way
                nodes.append(result)
                tcps.append(x)
                state = result
                if float(np.linalg.norm(x - centre)) >= BOX_REACH:
                    return None
        farthest = max(float(np.linalg.norm(x - centre)) for x in tcps)
        radius = farthest
        while True:  # shells BOX_GAP apart until one is closed
            radius += BOX_GAP
            if radius > BOX_REACH:
                return None
            shell = self._shell(nodes, (centre, radius), constraint, (lower, upper), rng, deadline)
            if shell is None:
                return None
            landed, hit = shell
            if landed >= BOX_LANDED:
                break

        def most(pairs: dict[tuple[str, str], int]) -> str:
            (a, b), count = max(pairs.items(), key=lambda item: item[1])
            return f"{count} of them for bodies {a!r} and {b!r}"

        tree = (
            f"a tree of {len(nodes) - 1} projected steps from it ({BOX_TRIES} extensions, half "
            f"toward random TCP positions) got {farthest * 1000:.0f} mm away, "
            f"{sum(stopped.values())} of its extensions stopped by a collision"
            + (f" ({most(stopped)})" if stopped else "")
        )
        return (
            centre,
            radius,
            (
                f"{tree}; none of {landed} random states with the tool on the axis and the TCP "
                f"{radius * 1000:.0f} mm away (projected from within {SHELL_NEAR:g} or "
                f"{SHELL_SPREAD:g} rad of the tree's) is collision-free (margin "
                f"{self._margin * 1000:g} mm; {most(hit)}): a way out, if any, holds under "
                f"{1 / landed:.1%} of them"
            ),
        )

    def _shell(
        self,
        nodes: list[np.ndarray],
        sphere: tuple[np.ndarray, float],
        constraint: OrientationConstraint,
        bounds: tuple[np.ndarray, np.ndarray],
        rng: np.random.Generator,
        deadline: float,
    ) -> tuple[int, dict[tuple[str, str], int]] | None:
        """`_boxed`'s shell: of `BOX_SAMPLES` states within `SHELL_SPREAD` of the tree's
        `nodes`, projected onto the constraint with the TCP on `sphere` (centre, radius), how
        many landed inside `bounds` (all in collision), and per body pair how many; (0, {}) at
        the first collision-free one; None at `deadline`."""
        robot = self._robot
        lower, upper = bounds
        hit: dict[tuple[str, str], int] = {}
        landed = 0
        for k in range(BOX_SAMPLES):
            if k % 5 == 0 and time.perf_counter() > deadline:
                return None
            near = nodes[int(rng.integers(len(nodes)))]
            spread = SHELL_SPREAD if k % 2 else SHELL_NEAR
            seed = near + rng.uniform(-spread, spread, self._n)
            result = constraint.project_joints(seed, robot.fk_frame, robot.jacobian, sphere=sphere)
            if result is None or self._outside(result, "", lower, upper) is not None:
                continue
            landed += 1
            self.checks += 1
            if self._checker.valid(result):
                return 0, {}
            pair = self._nearest_pair()
            hit[pair] = hit.get(pair, 0) + 1
        return landed, hit

    def _nearest_pair(self) -> tuple[str, str]:
        """The bodies of the pair the least clear in the checker's last check."""
        nearest = self._checker.nearest()
        return ("", "") if nearest is None else self._checker.pair_names(*nearest[:2])[:2]

    def _approach(
        self,
        q: np.ndarray,
        constraint: OrientationConstraint,
        lower: np.ndarray,
        upper: np.ndarray,
        reach: float | None,
    ) -> str | None:
        """None as soon as one of `APPROACH_SAMPLES` states within `PROJECTION_STEP` of `q`
        (`q` first, then random ones inside the bounds, seeded by the planner's seed and `q`)
        projects onto the constraint collision-free inside the bounds, within `reach` (rad, any
        joint) of `q` where given; else why none does, with the counts."""
        robot = self._robot
        rng = np.random.default_rng([self._seed, zlib.crc32(np.round(q, 9).tobytes())])
        jitter = rng.uniform(-PROJECTION_STEP, PROJECTION_STEP, (APPROACH_SAMPLES - 1, self._n))
        seeds = np.clip(np.vstack([q[None], q + jitter]), lower, upper)
        counts = dict.fromkeys(("diverged", "outside", "far", "collision"), 0)
        contact = ""
        for seed in seeds:
            result = constraint.project_joints(seed, robot.fk_frame, robot.jacobian)
            if result is None:
                counts["diverged"] += 1
            elif self._outside(result, "", lower, upper) is not None:
                counts["outside"] += 1
            elif reach is not None and float(np.abs(result - q).max()) > reach:
                counts["far"] += 1
            elif not self._checker.valid(result):
                counts["collision"] += 1
                if not contact:
                    a, b, d = self._checker.contacts(result)[0]
                    contact = f" (e.g. bodies {a!r} and {b!r} {d * 1000:.1f} mm apart)"
            else:
                return None
        parts = [
            f"{counts['diverged']} did not converge",
            f"{counts['outside']} left the bounds",
            f"{counts['collision']} were in collision{contact}",
        ]
        if reach is not None:
            parts.insert(2, f"{counts['far']} moved more than {reach:g} rad")
        return (
            f"none of {APPROACH_SAMPLES} states within {PROJECTION_STEP:g} rad of it (any "
            f"joint) projects onto the constraint collision-free (margin "
            f"{self._margin * 1000:g} mm) inside the bounds: " + ", ".join(parts)
        )

    def _unmet(
        self, constraint: OrientationConstraint, lower: np.ndarray, upper: np.ndarray
    ) -> str:
        """ ", and no configuration inside the bounds meets it ..." when none of
        `CONSTRAINT_SEEDS` random configurations inside the bounds (seeded by the planner's
        seed) projects onto the constraint inside them; else ""."""
        robot = self._robot
        rng = np.random.default_rng([self._seed, CONSTRAINT_SEEDS])
        for seed in rng.uniform(lower, upper, (CONSTRAINT_SEEDS, self._n)):
            result = constraint.project_joints(seed, robot.fk_frame, robot.jacobian)
            if result is not None and self._outside(result, "", lower, upper) is None:
                return ""
        return (
            f"; nor can any configuration inside the joint bounds meet it: none of "
            f"{CONSTRAINT_SEEDS} random ones projects onto it inside them"
        )

    def _project(
        self,
        waypoints: np.ndarray,
        constraint: OrientationConstraint,
        lower: np.ndarray,
        upper: np.ndarray,
    ) -> np.ndarray:
        """The path every `PROJECTION_STEP` projected onto the constraint (in joint space:
        each state moved the least that puts the tool axis on the world axis, the TCP's
        position free; else from the previous projected state moved as the path moves), each
        state checked; PlanningError naming where not."""
        robot = self._robot
        dense = [waypoints[0]]
        for a, b in itertools.pairwise(waypoints):
            count = max(1, math.ceil(float(np.abs(b - a).max()) / PROJECTION_STEP))
            dense.extend(a + (b - a) * (k / count) for k in range(1, count + 1))
        out = [waypoints[0]]
        q = waypoints[0]
        reach = self._first_reach(q, constraint)
        for k, state in enumerate(dense[1:-1], start=1):
            where = f"at {k / (len(dense) - 1):.0%} of the path"
            for seed in (state, q + (state - dense[k - 1])):
                result = constraint.project_joints(seed, robot.fk_frame, robot.jacobian)
                if result is not None and float(np.abs(result - q).max()) <= reach:
                    break
            else:
                raise PlanningError(f"constraint: the projection does not converge {where}")
            if self._outside(result, "", lower, upper) is not None:
                raise PlanningError(f"constraint: the projection leaves the bounds {where}")
            clash = self._clash(result, f"constraint: the projected state {where}")
            if clash is not None:
                raise PlanningError(clash)
            q = result
            out.append(q)
            reach = 3 * PROJECTION_STEP
        out.append(waypoints[-1])
        return np.array(out)

    def _keeps(self, trajectory: JointTrajectory, constraint: OrientationConstraint) -> bool:
        """Whether the timed trajectory keeps the constraint every `CHECK_STEP` / `FINE`."""
        q = trajectory.positions
        steps = np.abs(np.diff(q, axis=0)).max(axis=1)
        fk = self._robot.fk_frame
        marks = np.floor(np.concatenate([[0.0], np.cumsum(steps)]) / (CHECK_STEP / FINE))
        keep = np.diff(marks, prepend=-1.0) > 0
        keep[-1] = True
        return all(
            constraint.error(fk(state).rotation) <= constraint.tolerance for state in q[keep]
        )

    def _trajectory_ok(
        self,
        trajectory: JointTrajectory,
        lower: np.ndarray | None = None,
        upper: np.ndarray | None = None,
    ) -> bool:
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
        low = self._lower if lower is None else lower
        high = self._upper if upper is None else upper
        if np.any(q < low - 1e-9) or np.any(q > high + 1e-9):
            return False
        travelled = np.concatenate([[0.0], np.cumsum(np.abs(np.diff(q, axis=0)).max(axis=1))])
        marks = np.floor(travelled / CHECK_STEP)
        coarse = np.flatnonzero(np.diff(marks, prepend=-1.0) > 0).tolist()
        if coarse[-1] != len(grid) - 1:
            coarse.append(len(grid) - 1)
        clearance, reach = self._checker.clearance, self._checker.reach
        # Away from the start and goal (where the arm is slow) the executed arm strays from
        # the plan: it must keep TRACKING more than the margin there.
        ends = np.minimum(np.abs(q - q[0]).max(axis=1), np.abs(q - q[-1]).max(axis=1))
        need = np.where(ends < ESCAPE, self._margin, self._margin + TRACKING)
        if self._start_need is not None:
            # The first stretch leaves a start in collision (`start_jiggle`): up to the
            # collision-free state it heads for, it may not go deeper.
            need_at, reach = self._start_need
            leaving = np.abs(q - q[0]).max(axis=1) <= reach + CHECK_STEP
            need[leaving] = np.minimum(need[leaving], need_at)
        need = need.tolist()
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


def _states(si: Any, rows: np.ndarray) -> list[Any]:
    """OMPL states of space information `si` at each row of `rows` (kept by the caller
    while OMPL uses them)."""
    out = []
    for q in rows:
        state = si.allocState()
        for i, value in enumerate(q.tolist()):
            state[i] = value
        out.append(state)
    return out


def _goal_items(goal: object, n: int) -> list[np.ndarray | pin.SE3]:
    """A goal or a goal set as a list of joint vectors and poses."""
    if isinstance(goal, pin.SE3):
        return [goal]
    if isinstance(goal, (list, tuple)) and goal and any(isinstance(g, pin.SE3) for g in goal):
        items: list[np.ndarray | pin.SE3] = []
        for k, g in enumerate(goal):
            items.append(g if isinstance(g, pin.SE3) else _vector(g, n, f"goal[{k}]"))
        return items
    if np.ndim(goal) == 2:  # type: ignore[arg-type]
        rows = np.asarray(goal)
        if len(rows) == 0:
            raise SpecError("goal: an empty goal set")
        return [_vector(row, n, f"goal[{k}]") for k, row in enumerate(rows)]
    return [_vector(goal, n, "goal")]


def _optional(value: float | None, field: str) -> float | None:
    return None if value is None else _number(value, field)
