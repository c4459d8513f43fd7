"""Registered tasks: Menagerie's Franka Panda reaching a goal and lifting a cube.

Both follow dm_robotics_panda: Cartesian velocity of the TCP plus the hand's binary gripper
(action of 7, each entry in [-1, 1]), a 0.1 s control period over 2 ms physics, episodes of
100 steps (Gymnasium's `TimeLimit`: `gymnasium.make(id, max_episode_steps=N)` changes it).
Parameters go through `gymnasium.make(id, **parameters)` (docs/task.md lists them);
`time_limit` (seconds) ends episodes earlier.
"""

from __future__ import annotations

import inspect
from collections.abc import Mapping, Sequence
from typing import Any

import gymnasium as gym
import numpy as np

from .. import menagerie
from ..errors import SpecError, SpecTypeError
from ..spec import (
    AttachKind,
    AttachTarget,
    CameraSpec,
    Condim,
    RobotSpec,
    SceneObject,
    SceneSpec,
    Shape,
    ToolFrameSpec,
)
from ..validate import flag, real
from ._check import integer, names
from .env import TaskEnv
from .goal import GoalTaskEnv, reward_type
from .initializers import PoseInitializer, PropPlacer
from .rewards import Held, LiftReward, Reached, ReachReward, SparseReward
from .spec import (
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
MAX_EPISODE_STEPS = 100  # Gymnasium's TimeLimit: 10 s at the default 0.1 s control period
REACH_GOAL_LOW = (0.3, -0.3, 0.1)
REACH_GOAL_HIGH = (0.7, 0.3, 0.5)
CUBE_LOW = (0.4, -0.15)
CUBE_HIGH = (0.6, 0.15)
TARGET_LOW = (0.4, -0.15, CUBE_HALF + 0.08)
TARGET_HIGH = (0.6, 0.15, CUBE_HALF + 0.2)


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
    the arm and a `wrist` camera on the hand looking between the fingers."""
    return SceneSpec(
        timestep=0.002,
        add_floor=True,
        add_skybox=False,
        robots=[RobotSpec(path=menagerie.model_path("franka_emika_panda"))],
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


def _cube() -> SceneObject:
    return SceneObject(
        name="cube",
        shape=Shape.BOX,
        size=[CUBE_HALF] * 3,
        rgba=[0.1, 0.4, 1.0, 1.0],
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


def _pair(value: object, field: str) -> list[float]:
    from ..compile import vector

    return vector(value, 2, field).tolist()


class _Registered(TaskEnv):
    """Parameters shared by the registered tasks, checked with messages that name them."""

    @classmethod
    def _refuse_unknown(cls, unknown: Mapping[str, Any]) -> None:
        if unknown:
            valid = [p for p in inspect.signature(cls.__init__).parameters][1:-1]
            raise SpecError(
                f"{cls.__name__}: unknown parameter(s) {sorted(unknown)}; valid: "
                f"{', '.join(valid)} (and gymnasium.make's own, e.g. max_episode_steps)"
            )

    def _finish(
        self,
        spec: TaskSpec,
        given: Mapping[str, Any],
        reward: str,
        goal: Mapping[str, Any] | None = None,
    ) -> None:
        """Apply the parameters every registered task shares (`given`: the constructor's
        arguments by name) to `spec`, then build the env (goal-conditioned with `goal`)."""
        unknown = dict(given["unknown"])
        hardware = {k: unknown.pop(k) for k in _HARDWARE if k in unknown}  # see TaskEnv
        self._refuse_unknown(unknown)
        spec.hide = given["hide_observations"]
        spec.time_limit = given["time_limit"]  # None: the registered TimeLimit alone
        spec.control_timestep = given["control_timestep"]
        if reward_type(reward) == "sparse":
            spec.reward = SparseReward(spec.success)
        size = given["camera_size"]
        if isinstance(size, (str, bytes)) or not isinstance(size, Sequence):
            raise SpecTypeError(f"camera_size must be (height, width), got {size!r}")
        if len(size) != 2:
            raise SpecError(f"camera_size must be (height, width), got {size!r}")
        h, w = integer(size[0], "camera_size[0]"), integer(size[1], "camera_size[1]")
        cams = names(given["camera_names"], "camera_names", "camera")
        spec.sensors = [*spec.sensors, *(CameraSensor(c, width=w, height=h) for c in cams)]
        render = {k: given[k] for k in _RENDER}
        render.update(hardware)
        if goal is None:
            TaskEnv.__init__(self, spec, given["render_mode"], **render)
        else:
            GoalTaskEnv.__init__(self, spec, given["render_mode"], **goal, **render)  # type: ignore[arg-type]


_RENDER = ("render_camera", "render_width", "render_height", "render_shadows")
_HARDWARE = ("robot_ip", "haptic")  # every registered task takes them (TaskEnv's)


class PandaReachEnv(_Registered, TaskEnv):
    """`mjkdl/PandaReach-v0`: bring the Panda's TCP within `success_distance` of a goal.

    Success (`info["is_success"]`): TCP within `success_distance` metres of the goal; the
    episode goes on unless `terminate_on_success`. `reward_type`: "dense" (`ReachReward`) or
    "sparse" (1 on success steps). `camera_names` (of "front", "wrist") add `{name}_rgb`
    observations of `camera_size` (height, width).
    """

    def __init__(
        self,
        render_mode: str | None = None,
        *,
        time_limit: float | None = None,
        control_timestep: float = 0.1,
        goal_low: Sequence[float] = REACH_GOAL_LOW,
        goal_high: Sequence[float] = REACH_GOAL_HIGH,
        success_distance: float = 0.05,
        reward_type: str = "dense",
        terminate_on_success: bool = False,
        camera_names: Sequence[str] = (),
        camera_size: Sequence[int] = (128, 128),
        hide_observations: Sequence[str] = HIDDEN,
        render_camera: str = "front",
        render_width: int = 640,
        render_height: int = 480,
        render_shadows: bool = False,
        **unknown: Any,
    ) -> None:
        spec = panda_reach_spec(
            goal_low, goal_high, _positive(success_distance, "success_distance")
        )
        spec.terminate_on_success = flag(terminate_on_success, "terminate_on_success")
        self._finish(spec, locals(), reward_type)


class PandaPickCubeEnv(_Registered, TaskEnv):
    """`mjkdl/PandaPickCube-v0`: lift a cube 5 cm between the Panda's fingers and hold it.

    Success: the cube at least 5 cm above its resting height while both fingers touch it;
    the episode ends once that has held for 0.5 s (`terminate_on_success`). `reward_type`:
    "dense" (`LiftReward`: reach, grasp, lift, hold) or "sparse".
    """

    def __init__(
        self,
        render_mode: str | None = None,
        *,
        time_limit: float | None = None,
        control_timestep: float = 0.1,
        cube_low: Sequence[float] = CUBE_LOW,
        cube_high: Sequence[float] = CUBE_HIGH,
        reward_type: str = "dense",
        terminate_on_success: bool = True,
        camera_names: Sequence[str] = (),
        camera_size: Sequence[int] = (128, 128),
        hide_observations: Sequence[str] = HIDDEN,
        render_camera: str = "front",
        render_width: int = 640,
        render_height: int = 480,
        render_shadows: bool = False,
        **unknown: Any,
    ) -> None:
        spec = panda_pick_cube_spec(cube_low, cube_high)
        spec.terminate_on_success = flag(terminate_on_success, "terminate_on_success")
        self._finish(spec, locals(), reward_type)


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
        time_limit: float | None = None,
        control_timestep: float = 0.1,
        goal_low: Sequence[float] = REACH_GOAL_LOW,
        goal_high: Sequence[float] = REACH_GOAL_HIGH,
        success_distance: float = 0.05,
        reward_type: str = "sparse",
        camera_names: Sequence[str] = (),
        camera_size: Sequence[int] = (128, 128),
        hide_observations: Sequence[str] = HIDDEN,
        render_camera: str = "front",
        render_width: int = 640,
        render_height: int = 480,
        render_shadows: bool = False,
        **unknown: Any,
    ) -> None:
        threshold = _positive(success_distance, "success_distance")
        spec = panda_reach_spec(goal_low, goal_high, threshold)
        goal: dict[str, Any] = {"achieved": "panda_tcp_pos", "desired": "goal_pose"}
        goal.update(goal_keys=("goal_rel",), threshold=threshold, reward_type=reward_type)
        self._finish(spec, locals(), "dense", goal)


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
        time_limit: float | None = None,
        control_timestep: float = 0.1,
        cube_low: Sequence[float] = CUBE_LOW,
        cube_high: Sequence[float] = CUBE_HIGH,
        target_low: Sequence[float] = TARGET_LOW,
        target_high: Sequence[float] = TARGET_HIGH,
        success_distance: float = 0.03,
        reward_type: str = "sparse",
        camera_names: Sequence[str] = (),
        camera_size: Sequence[int] = (128, 128),
        hide_observations: Sequence[str] = HIDDEN,
        render_camera: str = "front",
        render_width: int = 640,
        render_height: int = 480,
        render_shadows: bool = False,
        **unknown: Any,
    ) -> None:
        threshold = _positive(success_distance, "success_distance")
        lo, hi = _box3(target_low, target_high, "target")
        spec = panda_pick_cube_spec(cube_low, cube_high)
        spec.scene.objects.append(_marker("target", [0.1, 1.0, 0.1, 0.5]))
        spec.sensors = [*spec.sensors, BodyPoseSensor("target")]
        spec.initializers = [*spec.initializers, PropPlacer(["target"], lo, hi, random_yaw=False)]
        spec.terminate_on_success = False
        goal: dict[str, Any] = {"achieved": "cube_pose", "desired": "target_pose"}
        goal.update(threshold=threshold, reward_type=reward_type)
        self._finish(spec, locals(), "dense", goal)


def _positive(value: object, field: str) -> float:
    out = real(value, field)
    if out <= 0:
        raise SpecError(f"{field} must be a positive number of metres, got {value!r}")
    return out


TASKS: dict[str, type[TaskEnv]] = {
    "mjkdl/PandaReach-v0": PandaReachEnv,
    "mjkdl/PandaPickCube-v0": PandaPickCubeEnv,
    "mjkdl/PandaReachGoal-v0": PandaReachGoalEnv,
    "mjkdl/PandaPickCubeGoal-v0": PandaPickCubeGoalEnv,
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
