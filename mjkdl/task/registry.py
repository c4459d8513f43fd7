"""Registered tasks: Menagerie's Franka Panda reaching, lifting, pushing, placing, stacking.

All follow dm_robotics_panda: Cartesian velocity of the TCP plus the hand's binary gripper
(action of 7, each entry in [-1, 1]), a 0.1 s control period over 2 ms physics, episodes of
100 steps (Gymnasium's `TimeLimit`: `gymnasium.make(id, max_episode_steps=N)` changes it).
Parameters go through `gymnasium.make(id, **parameters)` (docs/task.md lists them);
`time_limit` (seconds) ends episodes earlier; `actuation="joint_position"` (or
"joint_velocity", "joint_torque") makes the arm's part of the action one entry per joint,
each in [-1, 1] scaled onto the joint's range (limits, velocity limits, torque limits);
`cartesian_axes="vx,vy,vz,wz"` keeps those twist entries (the others zero: a top-down
gripper's translation and yaw, as pick benchmarks act). Each task is one `TaskSpec`
(`panda_*_spec()`), which the batched backend runs too.
"""

from __future__ import annotations

import inspect
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np

from .. import menagerie
from ..errors import SpecError, SpecTypeError
from ..spec import (
    AttachKind,
    AttachTarget,
    CameraSpec,
    Condim,
    GripperDrive,
    PhysicsOptions,
    RobotSpec,
    SceneObject,
    SceneSpec,
    Shape,
    ToolFrameSpec,
)
from ..validate import flag, real
from ._check import integer, names
from .env import TaskEnv
from .goal import REWARD_TYPES, GoalTaskEnv
from .initializers import PlaceAbove, PoseInitializer, PropPlacer
from .randomization import Randomization
from .rewards import Held, LiftReward, Placed, PlaceReward, Reached, ReachReward, SparseReward
from .spec import (
    CARTESIAN_AXES,
    Actuation,
    ArmSpec,
    BodyPoseSensor,
    CameraSensor,
    ContactSensor,
    GripperSpec,
    RelativePositionSensor,
    TaskSpec,
)

# Menagerie's "home" keyframe for the arm joints (radians): hand down, in front of the base.
PANDA_HOME = [0.0, 0.0, 0.0, -1.57079, 0.0, 1.57079, -0.7853]
GOAL_RADIUS = 0.02
CUBE_HALF = 0.02
LIFT = 0.05  # metres above its resting height that count as lifted
HOLD = 0.5  # seconds a lift must be held before the episode ends
# Observations computed but not given to the agent by default: joint torques (tens of N·m)
# and the clock (up to 10 s) swamp a network's inputs next to positions in metres, and SB3's
# PPO with its defaults learns Reach only without them (docs/task.md, Learning).
HIDDEN = ("panda_joint_torques", "time")
# `reward_type="shaped"` (PickCube, Push, PickAndPlace, Stack): the dense reward's reach stage
# as the mean of a 0.5 m term, felt from where episodes start (PickCube's first step pays a
# median 0.029 over 20 seeds, its dense reward's 0.3 m alone 0.016), and a 5 cm one, steep
# where the fingers close around the cube.
SHAPED_REACH = {"reach_scale": 0.5, "near_scale": 0.05}
# Push's: reach the point behind the cube, away from the goal, where the closed fingers
# (about 1 cm from the TCP to a pad's face) touch the cube's far side and push it on, by way
# of 6 cm above it from the cube's near side; the goal term only while the TCP is within 3 cm
# of it (ManiSkill's PushCube gates its goal term so; open fingers push from 2.1-2.5 cm).
SHAPED_PUSH = {**SHAPED_REACH, "behind": CUBE_HALF + 0.015, "gate": 0.03, "over": 0.06}
# PickAndPlace's: the goal term only while grasped, so pushing the cube under its target in
# the air pays nothing.
SHAPED_CARRY = {**SHAPED_REACH, "hold": True}
MAX_EPISODE_STEPS = 100  # Gymnasium's TimeLimit: 10 s at the default 0.1 s control period
REACH_GOAL_LOW = (0.3, -0.3, 0.1)
REACH_GOAL_HIGH = (0.7, 0.3, 0.5)
CUBE_LOW = (0.4, -0.15)
CUBE_HIGH = (0.6, 0.15)
TARGET_LOW = (0.4, -0.15, CUBE_HALF + 0.08)
TARGET_HIGH = (0.6, 0.15, CUBE_HALF + 0.2)
PUSH_GOAL_LOW = (0.35, -0.2)
PUSH_GOAL_HIGH = (0.65, 0.2)
PUSH_DISTANCE = 0.05  # panda-gym's distance_threshold
# Push's goal lands at least this far from the cube: drawn anywhere, 7 % of episodes began
# already solved, and their reward swamped what the others taught a learner (docs/task.md).
PUSH_GOAL_CLEARANCE = 0.1
PLACE_DISTANCE = 0.03
STACK_DISTANCE = 0.02


def panda_arm(name: str = "panda") -> ArmSpec:
    """The Panda from `link0` to `hand`, TCP between the fingertips, its hand as gripper."""
    return ArmSpec(
        name=name,
        base_body="link0",
        tip_body="hand",
        tool=ToolFrameSpec(tcp_pos=[0.0, 0.0, 0.1034]),
        gripper=GripperSpec(actuator="actuator8", open=255.0, closed=0.0),
        home=list(PANDA_HOME),
    )


def panda_scene(objects: list[SceneObject]) -> SceneSpec:
    """Menagerie's Panda at the world origin on a floor, `objects`, a `front` camera facing
    the arm and a `wrist` camera on the hand looking between the fingers; contact options
    for grasping (`PhysicsOptions.grasping()`) and the hand squeezing as the Franka Hand does
    (`GripperDrive.franka_hand()`: 20 N per finger, 0.05 m/s)."""
    return SceneSpec(
        timestep=0.002,
        add_floor=True,
        add_skybox=False,
        physics=PhysicsOptions.grasping(),
        robots=[
            RobotSpec(
                path=menagerie.model_path("franka_emika_panda"),
                grippers=[GripperDrive.franka_hand()],
            )
        ],
        objects=objects,
        cameras=[
            CameraSpec(name="front", pos=[1.6, 0.0, 0.9], euler=[0.0, 65.0, 90.0], fovy=45.0),
            CameraSpec(
                name="wrist",
                pos=[0.07, 0.0, 0.03],
                euler=[180.0, 20.0, -90.0],
                fovy=75.0,
                attach_to=AttachTarget(AttachKind.Body, "hand"),
            ),
        ],
    )


def _cube(name: str = "cube", rgba: tuple[float, ...] = (0.1, 0.4, 1.0, 1.0)) -> SceneObject:
    return SceneObject(
        name=name,
        shape=Shape.BOX,
        size=[CUBE_HALF] * 3,
        rgba=list(rgba),
        mass=0.05,
        condim=Condim.Torsional,
        friction=[1.0, 0.02, 0.001],
    )


def _marker(name: str, rgba: list[float]) -> SceneObject:
    return SceneObject(name=name, shape=Shape.SPHERE, size=[GOAL_RADIUS], rgba=rgba, marker=True)


def _box3(low: object, high: object, where: str) -> tuple[list[float], list[float]]:
    from ..compile import vector  # the scene's checks: length, finite numbers

    lo, hi = vector(low, 3, f"{where}_low"), vector(high, 3, f"{where}_high")
    if np.any(lo > hi):
        raise SpecError(f"{where}_low must not exceed {where}_high, got {lo} and {hi}")
    return lo.tolist(), hi.tolist()


def panda_reach_spec(
    goal_low: Sequence[float] = REACH_GOAL_LOW,
    goal_high: Sequence[float] = REACH_GOAL_HIGH,
    success_distance: float = 0.05,
) -> TaskSpec:
    """Bring the TCP within `success_distance` of a goal marker (no collisions) placed at
    random in `goal_low`..`goal_high`; the TCP starts at a random pose above the work area.
    Dense reward `ReachReward`; observations add `goal_pose` and `goal_rel` (goal - TCP)."""
    lo, hi = _box3(goal_low, goal_high, "goal")
    return TaskSpec(
        scene=panda_scene([_marker("goal", [1.0, 0.1, 0.1, 0.6])]),
        arms=[panda_arm()],
        sensors=[BodyPoseSensor("goal"), RelativePositionSensor("goal", "panda")],
        initializers=[
            PoseInitializer(
                "panda", low=[0.3, -0.2, 0.3, 165, -15, -105], high=[0.6, 0.2, 0.6, 195, 15, -75]
            ),
            PropPlacer(["goal"], low=lo, high=hi, random_yaw=False),
        ],
        reward=ReachReward("panda_tcp_pos", "goal_pose", success_distance=success_distance),
        success=Reached("panda_tcp_pos", "goal_pose", success_distance),
        normalize_actions=True,
    )


def panda_pick_cube_spec(
    cube_low: Sequence[float] = CUBE_LOW, cube_high: Sequence[float] = CUBE_HIGH
) -> TaskSpec:
    """Lift a 4 cm cube, placed at random in the xy box `cube_low`..`cube_high` on the floor,
    by 5 cm between the fingers and hold it there for 0.5 s. Staged reward `LiftReward`;
    observations add `cube_pose`, `cube_rel` (cube - TCP) and `cube_contacts` (fingers)."""
    z = CUBE_HALF + 0.002
    lo, hi = _box3([*_pair(cube_low, "cube_low"), z], [*_pair(cube_high, "cube_high"), z], "cube")
    contacts = ContactSensor("cube", ["left_finger", "right_finger"])
    return TaskSpec(
        scene=panda_scene([_cube()]),
        arms=[panda_arm()],
        sensors=[BodyPoseSensor("cube"), RelativePositionSensor("cube", "panda"), contacts],
        initializers=[PropPlacer(["cube"], low=lo, high=hi)],
        reward=LiftReward(
            "panda_tcp_pos", "cube_pose", "cube_contacts", rest_z=CUBE_HALF, lift=LIFT
        ),
        success=Held("cube_pose", "cube_contacts", rest_z=CUBE_HALF, lift=LIFT),
        terminate_on_success=True,
        success_hold=HOLD,
        normalize_actions=True,
    )


def _cube_box(
    cube_low: Sequence[float], cube_high: Sequence[float]
) -> tuple[list[float], list[float]]:
    z = CUBE_HALF + 0.002
    return _box3([*_pair(cube_low, "cube_low"), z], [*_pair(cube_high, "cube_high"), z], "cube")


def _place_spec(
    objects: list[SceneObject],
    initializers: list[Any],
    goal: str,
    success: Placed,
    contacts: bool,
) -> TaskSpec:
    """A Panda task: bring `cube` to the marker `goal` (`success`), placed by
    `initializers`; `PlaceReward` dense reward."""
    touch = ContactSensor("cube", ["left_finger", "right_finger"])
    return TaskSpec(
        scene=panda_scene(objects),
        arms=[panda_arm()],
        sensors=[
            BodyPoseSensor("cube"),
            RelativePositionSensor("cube", "panda"),
            touch,
            BodyPoseSensor(goal),
            *(BodyPoseSensor(o.name) for o in objects if o.name not in ("cube", goal)),
        ],
        initializers=initializers,
        reward=PlaceReward(
            "panda_tcp_pos",
            "cube_pose",
            f"{goal}_pose",
            success,
            contacts="cube_contacts" if contacts else "",
        ),
        success=success,
        normalize_actions=True,
    )


def panda_push_spec(
    cube_low: Sequence[float] = CUBE_LOW,
    cube_high: Sequence[float] = CUBE_HIGH,
    goal_low: Sequence[float] = PUSH_GOAL_LOW,
    goal_high: Sequence[float] = PUSH_GOAL_HIGH,
    success_distance: float = PUSH_DISTANCE,
    goal_clearance: float = PUSH_GOAL_CLEARANCE,
    block_gripper: bool = False,
) -> TaskSpec:
    """Push the cube along the floor until its centre is within `success_distance` of a
    goal marker on the floor (xy box `goal_low`..`goal_high`, at least `goal_clearance`
    from where the cube starts). Observations add `cube_pose`, `cube_rel`, `cube_contacts`
    and `goal_pose`. `block_gripper` holds the fingers closed, out of the action."""
    lo, hi = _cube_box(cube_low, cube_high)
    z = CUBE_HALF
    glo, ghi = _box3([*_pair(goal_low, "goal_low"), z], [*_pair(goal_high, "goal_high"), z], "goal")
    objects = [_cube(), _marker("goal", [1.0, 0.1, 0.1, 0.5])]
    inits: list[Any] = [
        PropPlacer(["cube"], lo, hi),
        PropPlacer(["goal"], glo, ghi, False, away_from="cube", min_distance=goal_clearance),
    ]
    spec = _place_spec(
        objects, inits, "goal", Placed("cube_pose", "goal_pose", success_distance), False
    )
    if flag(block_gripper, "block_gripper"):
        assert spec.arms[0].gripper is not None  # panda_arm's hand
        spec.arms[0].gripper = replace(spec.arms[0].gripper, held=1.0)
    return spec


def panda_pick_and_place_spec(
    cube_low: Sequence[float] = CUBE_LOW,
    cube_high: Sequence[float] = CUBE_HIGH,
    target_low: Sequence[float] = TARGET_LOW,
    target_high: Sequence[float] = TARGET_HIGH,
    success_distance: float = PLACE_DISTANCE,
) -> TaskSpec:
    """Pick the cube up and bring its centre within `success_distance` of a target marker
    in the air (box `target_low`..`target_high`). Observations add `cube_pose`,
    `cube_rel`, `cube_contacts` and `target_pose`."""
    lo, hi = _cube_box(cube_low, cube_high)
    tlo, thi = _box3(target_low, target_high, "target")
    objects = [_cube(), _marker("target", [0.1, 1.0, 0.1, 0.5])]
    inits: list[Any] = [PropPlacer(["cube"], lo, hi), PropPlacer(["target"], tlo, thi, False)]
    return _place_spec(
        objects, inits, "target", Placed("cube_pose", "target_pose", success_distance), True
    )


def panda_stack_spec(
    cube_low: Sequence[float] = CUBE_LOW,
    cube_high: Sequence[float] = CUBE_HIGH,
    success_distance: float = STACK_DISTANCE,
) -> TaskSpec:
    """Put the blue cube on the red `base` cube (both placed apart in the xy box): success
    once its centre is within `success_distance` of the `target` marker a cube's height
    above where the base was put, with no finger touching it. Observations add
    `cube_pose`, `cube_rel`, `cube_contacts`, `target_pose` and `base_pose`."""
    lo, hi = _cube_box(cube_low, cube_high)
    objects = [
        _cube(),
        _cube("base", (1.0, 0.3, 0.2, 1.0)),
        _marker("target", [0.1, 1.0, 0.1, 0.3]),
    ]
    inits: list[Any] = [
        PropPlacer(["cube", "base"], lo, hi),
        PlaceAbove("target", "base", 2 * CUBE_HALF),
    ]
    success = Placed("cube_pose", "target_pose", success_distance, "cube_contacts")
    return _place_spec(objects, inits, "target", success, True)


def _pair(value: object, field: str) -> list[float]:
    from ..compile import vector

    return vector(value, 2, field).tolist()


@dataclass(frozen=True)
class Parameter:
    """A keyword every registered task takes: its default and what it does (docs/task.md's
    table and the unknown-parameter error read these)."""

    name: str
    default: Any
    doc: str
    before_own: bool = False  # listed before the task's own parameters (the episode's)


# The parameters every registered task shares, declared once; each task's class takes only
# its own (`gym.make(id, **parameters)`). The goal variants take all but
# `terminate_on_success` and default to `reward_type="sparse"` (as HER expects).
SHARED_PARAMETERS: tuple[Parameter, ...] = (
    Parameter("time_limit", None, "seconds before `truncated`", before_own=True),
    Parameter("control_timestep", 0.1, "seconds per step", before_own=True),
    Parameter("actuation", "cartesian_velocity", "the arm's part of the action", before_own=True),
    Parameter("cartesian_axes", CARTESIAN_AXES, "the twist entries acted on", before_own=True),
    Parameter("reward_type", "dense", '"dense", "sparse", or "shaped" (the object tasks)'),
    Parameter("terminate_on_success", False, "end the episode once success holds"),
    Parameter("camera_names", (), "scene cameras added as `{name}_rgb` observations"),
    Parameter("camera_size", (128, 128), "(height, width) of those images"),
    Parameter("camera_depth", False, "each camera's `{name}_depth` too"),
    Parameter("hide_observations", HIDDEN, "observations rewards see but the agent does not"),
    Parameter("randomization", None, "what varies per episode (a `Randomization` or its dict)"),
    Parameter("render_camera", "front", "the camera `render()` shows"),
    Parameter("render_width", 640, "`render()`'s width"),
    Parameter("render_height", 480, "`render()`'s height"),
    Parameter("render_shadows", False, "shadows and reflections in `render()`"),
    Parameter("robot_ip", None, "a Franka arm at this address in the loop (docs/hardware.md)"),
    Parameter("haptic", False, "with robot_ip: the simulated contacts on the arm"),
    Parameter(
        "lockstep",
        False,
        "with robot_ip: the arm is `franka_sim --lockstep --command-timeout 10`, whose ticks "
        "wait for the env's commands (runs repeat exactly)",
    ),
    Parameter(
        "arm_drive",
        "servo",
        '"servo" (Menagerie\'s actuators) or "franka_impedance" (the arm\'s own, docs/hardware.md)',
    ),
)
_GOAL_DEFAULTS = {"reward_type": "sparse"}
_NOT_FOR_GOALS = ("terminate_on_success",)


class _Registered(TaskEnv):
    """A registered task: its own parameters in its constructor, the shared ones
    (`SHARED_PARAMETERS`) checked and applied here, with messages that name them."""

    _defaults: ClassVar[Mapping[str, Any]] = {}  # a task's own defaults of shared parameters
    # `reward_type="shaped"`: the fields it changes in the task's dense reward (None: not offered)
    _shaped: ClassVar[Mapping[str, Any] | None] = None

    @classmethod
    def shared_parameters(cls) -> dict[str, Any]:
        """The shared parameters this task takes, with its defaults."""
        goal = issubclass(cls, GoalTaskEnv)
        out = {
            p.name: p.default for p in SHARED_PARAMETERS if not (goal and p.name in _NOT_FOR_GOALS)
        }
        if goal:
            out.update(_GOAL_DEFAULTS)
        out.update(cls._defaults)
        return out

    @classmethod
    def parameter_names(cls) -> list[str]:
        """Every keyword the task takes, in the order the error messages list them."""
        own = [p for p in inspect.signature(cls.__init__).parameters][1:-1]
        shared = cls.shared_parameters()
        first = [p.name for p in SHARED_PARAMETERS if p.before_own and p.name in shared]
        rest = [p.name for p in SHARED_PARAMETERS if not p.before_own and p.name in shared]
        return [own[0], *first, *own[1:], *rest]

    def _finish(
        self,
        spec: TaskSpec,
        render_mode: str | None,
        given: Mapping[str, Any],
        goal: dict[str, Any] | None = None,
    ) -> None:
        """Apply the shared parameters `given` (the constructor's `**shared`) to `spec`, then
        build the env (goal-conditioned with `goal`: its keys, threshold)."""
        shared = self.shared_parameters()
        unknown = sorted(set(given) - set(shared))
        if unknown:
            raise SpecError(
                f"{type(self).__name__}: unknown parameter(s) {unknown}; valid: "
                f"{', '.join(self.parameter_names())} (and gymnasium.make's own, e.g. "
                "max_episode_steps)"
            )
        p = {**shared, **given}
        if goal is None:
            spec.terminate_on_success = flag(p["terminate_on_success"], "terminate_on_success")
        spec.hide = p["hide_observations"]
        spec.time_limit = p["time_limit"]  # None: the registered TimeLimit alone
        spec.control_timestep = p["control_timestep"]
        spec.randomization = Randomization.coerce(p["randomization"])
        spec.arms[0].actuation = actuation(p["actuation"])
        spec.arms[0].cartesian_axes = cartesian_axes(p["cartesian_axes"])
        shaped = goal is None and self._shaped is not None
        kinds = [*REWARD_TYPES, "shaped"] if shaped else list(REWARD_TYPES)
        kind = p["reward_type"]
        if kind not in kinds:
            offered = sorted(c.__name__ for c in _Registered.__subclasses__() if c._shaped)
            only = f" ('shaped' is offered by {', '.join(offered)})" if kind == "shaped" else ""
            raise SpecError(
                f"{type(self).__name__}: reward_type must be one of {kinds}, got {kind!r}{only}"
            )
        if kind == "shaped" and isinstance(spec.reward, (LiftReward, PlaceReward)):
            spec.reward = replace(spec.reward, **(self._shaped or {}))
        elif goal is None and kind == "sparse":
            spec.reward = SparseReward(spec.success)
        size = p["camera_size"]
        if isinstance(size, (str, bytes)) or not isinstance(size, Sequence):
            raise SpecTypeError(f"camera_size must be (height, width), got {size!r}")
        if len(size) != 2:
            raise SpecError(f"camera_size must be (height, width), got {size!r}")
        h, w = integer(size[0], "camera_size[0]"), integer(size[1], "camera_size[1]")
        cams = names(p["camera_names"], "camera_names", "camera")
        depth = flag(p["camera_depth"], "camera_depth")
        spec.sensors = [
            *spec.sensors,
            *(CameraSensor(c, width=w, height=h, depth=depth) for c in cams),
        ]
        env = {k: p[k] for k in (*_RENDER, *_HARDWARE)}
        if goal is None:
            TaskEnv.__init__(self, spec, render_mode, **env)
        else:
            goal["reward_type"] = p["reward_type"]
            GoalTaskEnv.__init__(self, spec, render_mode, **goal, **env)  # type: ignore[arg-type]


_RENDER = ("render_camera", "render_width", "render_height", "render_shadows")
# TaskEnv's: the arm, simulated or in the loop
_HARDWARE = ("robot_ip", "haptic", "lockstep", "arm_drive")


class PandaReachEnv(_Registered, TaskEnv):
    """`mjkdl/PandaReach-v0`: bring the Panda's TCP within `success_distance` of a goal.

    Success (`info["is_success"]`): TCP within `success_distance` metres of the goal; the
    episode goes on unless `terminate_on_success`. `reward_type`: "dense" (`ReachReward`) or
    "sparse" (1 on success steps). `camera_names` (of "front", "wrist") add `{name}_rgb`
    observations of `camera_size` (height, width), and with `camera_depth` each camera's
    `{name}_depth` (float32 metres along the optical axis, the same render). The shared
    parameters: `SHARED_PARAMETERS`.
    """

    def __init__(
        self,
        render_mode: str | None = None,
        *,
        goal_low: Sequence[float] = REACH_GOAL_LOW,
        goal_high: Sequence[float] = REACH_GOAL_HIGH,
        success_distance: float = 0.05,
        **shared: Any,
    ) -> None:
        spec = panda_reach_spec(
            goal_low, goal_high, _positive(success_distance, "success_distance")
        )
        self._finish(spec, render_mode, shared)


class PandaPickCubeEnv(_Registered, TaskEnv):
    """`mjkdl/PandaPickCube-v0`: lift a cube 5 cm between the Panda's fingers and hold it.

    Success: the cube at least 5 cm above its resting height while both fingers touch it;
    the episode ends once that has held for 0.5 s (`terminate_on_success`, True here).
    `reward_type`: "dense" (`LiftReward`: reach, grasp, lift, hold), "shaped" (the same
    stages, the reach stage pulling from afar and paying the last centimetres: `SHAPED_REACH`)
    or "sparse".
    """

    _defaults: ClassVar[Mapping[str, Any]] = {"terminate_on_success": True}
    _shaped = SHAPED_REACH

    def __init__(
        self,
        render_mode: str | None = None,
        *,
        cube_low: Sequence[float] = CUBE_LOW,
        cube_high: Sequence[float] = CUBE_HIGH,
        **shared: Any,
    ) -> None:
        self._finish(panda_pick_cube_spec(cube_low, cube_high), render_mode, shared)


class PandaReachGoalEnv(_Registered, GoalTaskEnv):
    """`mjkdl/PandaReachGoal-v0`: `PandaReach-v0` goal-conditioned, for HER.

    `achieved_goal` is the TCP position, `desired_goal` the goal's; `observation` the arm's
    state (goal observations left out). `reward_type` defaults to "sparse" (1 within
    `success_distance`, else 0), as HER expects; `compute_reward` gives the same numbers.
    """

    def __init__(
        self,
        render_mode: str | None = None,
        *,
        goal_low: Sequence[float] = REACH_GOAL_LOW,
        goal_high: Sequence[float] = REACH_GOAL_HIGH,
        success_distance: float = 0.05,
        **shared: Any,
    ) -> None:
        threshold = _positive(success_distance, "success_distance")
        spec = panda_reach_spec(goal_low, goal_high, threshold)
        goal: dict[str, Any] = {"achieved": "panda_tcp_pos", "desired": "goal_pose"}
        goal.update(goal_keys=("goal_rel",), threshold=threshold)
        self._finish(spec, render_mode, shared, goal)


class PandaPickCubeGoalEnv(_Registered, GoalTaskEnv):
    """`mjkdl/PandaPickCubeGoal-v0`: bring the cube within `success_distance` of a target
    marker in the air above the floor (`target_low`..`target_high`), goal-conditioned.

    `achieved_goal` is the cube's position, `desired_goal` the target's; `observation` the
    arm's state, the cube's pose, `cube_rel` and the finger contacts. Sparse reward by
    default.
    """

    def __init__(
        self,
        render_mode: str | None = None,
        *,
        cube_low: Sequence[float] = CUBE_LOW,
        cube_high: Sequence[float] = CUBE_HIGH,
        target_low: Sequence[float] = TARGET_LOW,
        target_high: Sequence[float] = TARGET_HIGH,
        success_distance: float = 0.03,
        **shared: Any,
    ) -> None:
        threshold = _positive(success_distance, "success_distance")
        lo, hi = _box3(target_low, target_high, "target")
        spec = panda_pick_cube_spec(cube_low, cube_high)
        spec.scene.objects.append(_marker("target", [0.1, 1.0, 0.1, 0.5]))
        spec.sensors = [*spec.sensors, BodyPoseSensor("target")]
        spec.initializers = [*spec.initializers, PropPlacer(["target"], lo, hi, random_yaw=False)]
        spec.terminate_on_success = False
        goal = {"achieved": "cube_pose", "desired": "target_pose", "threshold": threshold}
        self._finish(spec, render_mode, shared, goal)


class PandaPushEnv(_Registered, TaskEnv):
    """`mjkdl/PandaPush-v0`: push the cube along the floor to a goal on the floor.

    Success: the cube's centre within `success_distance` (5 cm, panda-gym's) of the goal,
    which starts at least `goal_clearance` (10 cm) from the cube. `block_gripper` holds the
    fingers closed and drops the gripper's action entry, as panda-gym's Push does.
    `reward_type`: "dense" (`PlaceReward`: reach the cube, bring it to the goal), "shaped"
    (`SHAPED_PUSH`: reach the point behind the cube, away from the goal, with PickCube's two
    reach terms; the goal term only while the TCP is there) or "sparse". Without
    `block_gripper` the gripper stays in the action; the expert keeps it closed.
    """

    _shaped = SHAPED_PUSH

    def __init__(
        self,
        render_mode: str | None = None,
        *,
        cube_low: Sequence[float] = CUBE_LOW,
        cube_high: Sequence[float] = CUBE_HIGH,
        goal_low: Sequence[float] = PUSH_GOAL_LOW,
        goal_high: Sequence[float] = PUSH_GOAL_HIGH,
        success_distance: float = PUSH_DISTANCE,
        goal_clearance: float = PUSH_GOAL_CLEARANCE,
        block_gripper: bool = False,
        **shared: Any,
    ) -> None:
        threshold = _positive(success_distance, "success_distance")
        clear = _clearance(goal_clearance)
        spec = panda_push_spec(
            cube_low, cube_high, goal_low, goal_high, threshold, clear, block_gripper
        )
        self._finish(spec, render_mode, shared)


class PandaPickAndPlaceEnv(_Registered, TaskEnv):
    """`mjkdl/PandaPickAndPlace-v0`: pick the cube up and bring it to a target in the air.

    Success: the cube's centre within `success_distance` (3 cm) of the target marker.
    `reward_type`: "dense" (`PlaceReward`: reach, grasp, bring to the target), "shaped"
    (`SHAPED_CARRY`: PickCube's two reach terms; the goal term only while grasped) or
    "sparse".
    """

    _shaped = SHAPED_CARRY

    def __init__(
        self,
        render_mode: str | None = None,
        *,
        cube_low: Sequence[float] = CUBE_LOW,
        cube_high: Sequence[float] = CUBE_HIGH,
        target_low: Sequence[float] = TARGET_LOW,
        target_high: Sequence[float] = TARGET_HIGH,
        success_distance: float = PLACE_DISTANCE,
        **shared: Any,
    ) -> None:
        threshold = _positive(success_distance, "success_distance")
        spec = panda_pick_and_place_spec(cube_low, cube_high, target_low, target_high, threshold)
        self._finish(spec, render_mode, shared)


class PandaStackEnv(_Registered, TaskEnv):
    """`mjkdl/PandaStack-v0`: put the blue cube on top of the red one and let go.

    Success: the blue cube's centre within `success_distance` (2 cm) of the point a cube's
    height above where the red cube was placed (`target_pose`), no finger touching it.
    `reward_type`: "dense" (`PlaceReward`), "shaped" (`SHAPED_REACH`) or "sparse".
    """

    _shaped = SHAPED_REACH

    def __init__(
        self,
        render_mode: str | None = None,
        *,
        cube_low: Sequence[float] = CUBE_LOW,
        cube_high: Sequence[float] = CUBE_HIGH,
        success_distance: float = STACK_DISTANCE,
        **shared: Any,
    ) -> None:
        threshold = _positive(success_distance, "success_distance")
        self._finish(panda_stack_spec(cube_low, cube_high, threshold), render_mode, shared)


class PandaPushGoalEnv(_Registered, GoalTaskEnv):
    """`mjkdl/PandaPushGoal-v0`: `PandaPush-v0` goal-conditioned, for HER: `achieved_goal`
    the cube's position, `desired_goal` the goal's; sparse reward by default."""

    def __init__(
        self,
        render_mode: str | None = None,
        *,
        cube_low: Sequence[float] = CUBE_LOW,
        cube_high: Sequence[float] = CUBE_HIGH,
        goal_low: Sequence[float] = PUSH_GOAL_LOW,
        goal_high: Sequence[float] = PUSH_GOAL_HIGH,
        success_distance: float = PUSH_DISTANCE,
        goal_clearance: float = PUSH_GOAL_CLEARANCE,
        block_gripper: bool = False,
        **shared: Any,
    ) -> None:
        threshold = _positive(success_distance, "success_distance")
        clear = _clearance(goal_clearance)
        spec = panda_push_spec(
            cube_low, cube_high, goal_low, goal_high, threshold, clear, block_gripper
        )
        goal = {"achieved": "cube_pose", "desired": "goal_pose", "threshold": threshold}
        self._finish(spec, render_mode, shared, goal)


class PandaPickAndPlaceGoalEnv(_Registered, GoalTaskEnv):
    """`mjkdl/PandaPickAndPlaceGoal-v0`: `PandaPickAndPlace-v0` goal-conditioned, for HER:
    `achieved_goal` the cube's position, `desired_goal` the target's."""

    def __init__(
        self,
        render_mode: str | None = None,
        *,
        cube_low: Sequence[float] = CUBE_LOW,
        cube_high: Sequence[float] = CUBE_HIGH,
        target_low: Sequence[float] = TARGET_LOW,
        target_high: Sequence[float] = TARGET_HIGH,
        success_distance: float = PLACE_DISTANCE,
        **shared: Any,
    ) -> None:
        threshold = _positive(success_distance, "success_distance")
        spec = panda_pick_and_place_spec(cube_low, cube_high, target_low, target_high, threshold)
        goal = {"achieved": "cube_pose", "desired": "target_pose", "threshold": threshold}
        self._finish(spec, render_mode, shared, goal)


class PandaStackGoalEnv(_Registered, GoalTaskEnv):
    """`mjkdl/PandaStackGoal-v0`: `PandaStack-v0` goal-conditioned, for HER: `achieved_goal`
    the blue cube's position, `desired_goal` the point on top of the red one (success and
    reward by distance alone, as HER relabels them)."""

    def __init__(
        self,
        render_mode: str | None = None,
        *,
        cube_low: Sequence[float] = CUBE_LOW,
        cube_high: Sequence[float] = CUBE_HIGH,
        success_distance: float = STACK_DISTANCE,
        **shared: Any,
    ) -> None:
        threshold = _positive(success_distance, "success_distance")
        spec = panda_stack_spec(cube_low, cube_high, threshold)
        goal = {"achieved": "cube_pose", "desired": "target_pose", "threshold": threshold}
        self._finish(spec, render_mode, shared, goal)


ACTUATIONS = tuple(a.value for a in Actuation)


def actuation(value: object) -> Actuation:
    """`value` (an `Actuation` or its name: "cartesian_velocity", "joint_position",
    "joint_velocity", "joint_torque") checked as the arm's action mode."""
    if isinstance(value, Actuation):
        return value
    if not isinstance(value, str) or value not in ACTUATIONS:
        raise SpecError(f"actuation must be one of {list(ACTUATIONS)}, got {value!r}")
    return Actuation(value)


def cartesian_axes(value: object) -> tuple[str, ...]:
    """`value` ("vx,vy,vz,wz" or a sequence of entries) as `ArmSpec.cartesian_axes`; the
    env checks the entries."""
    if isinstance(value, str):
        return tuple(a.strip() for a in value.split(","))
    if not isinstance(value, Sequence):
        raise SpecTypeError(
            f"cartesian_axes must be a comma-separated string or a sequence of "
            f"{CARTESIAN_AXES} entries, got {value!r}"
        )
    return tuple(value)


def _positive(value: object, field: str) -> float:
    out = real(value, field)
    if out <= 0:
        raise SpecError(f"{field} must be a positive number of metres, got {value!r}")
    return out


def _clearance(value: object) -> float:
    out = real(value, "goal_clearance")
    if out < 0:
        raise SpecError(f"goal_clearance must be >= 0 metres (0: anywhere), got {value!r}")
    return out


TASKS: dict[str, type[TaskEnv]] = {
    "mjkdl/PandaReach-v0": PandaReachEnv,
    "mjkdl/PandaPickCube-v0": PandaPickCubeEnv,
    "mjkdl/PandaReachGoal-v0": PandaReachGoalEnv,
    "mjkdl/PandaPickCubeGoal-v0": PandaPickCubeGoalEnv,
    "mjkdl/PandaPush-v0": PandaPushEnv,
    "mjkdl/PandaPickAndPlace-v0": PandaPickAndPlaceEnv,
    "mjkdl/PandaStack-v0": PandaStackEnv,
    "mjkdl/PandaPushGoal-v0": PandaPushGoalEnv,
    "mjkdl/PandaPickAndPlaceGoal-v0": PandaPickAndPlaceGoalEnv,
    "mjkdl/PandaStackGoal-v0": PandaStackGoalEnv,
}


def register() -> None:
    """Register the tasks with Gymnasium (done by `import mjkdl.task`; idempotent)."""
    for env_id, cls in TASKS.items():
        if env_id not in gym.registry:
            gym.register(
                id=env_id,
                entry_point=f"{__name__}:{cls.__name__}",
                max_episode_steps=MAX_EPISODE_STEPS,
                disable_env_checker=False,
            )
