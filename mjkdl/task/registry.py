"""Registered tasks: Menagerie's Franka Panda reaching for a ball and lifting a cube.

Both follow dm_robotics_panda: Cartesian velocity of the TCP plus the hand's binary gripper
(action of 7), a 0.1 s control period over 2 ms physics, 10 s episodes.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym

from .. import menagerie
from ..spec import CameraSpec, Condim, RobotSpec, SceneObject, SceneSpec, Shape, ToolFrameSpec
from .env import TaskEnv
from .initializers import PoseInitializer, PropPlacer
from .rewards import Lifted, LiftReward, ReachReward
from .spec import ArmSpec, BodyPoseSensor, GripperSpec, TaskSpec

# Menagerie's "home" keyframe for the arm joints (radians): hand down, in front of the base.
PANDA_HOME = [0.0, 0.0, 0.0, -1.57079, 0.0, 1.57079, -0.7853]
BALL_RADIUS = 0.03
CUBE_HALF = 0.02
LIFT = 0.1


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
    """Menagerie's Panda at the world origin on a floor, `objects`, and a `front` camera."""
    return SceneSpec(
        timestep=0.002,
        add_floor=True,
        add_skybox=False,
        robots=[RobotSpec(path=menagerie.model_path("franka_emika_panda"))],
        objects=objects,
        cameras=[CameraSpec(name="front", pos=[1.6, 0.0, 0.9], euler=[0.0, 65.0, 90.0], fovy=45.0)],
    )


def panda_reach_spec() -> TaskSpec:
    """Reach a 3 cm ball dropped at random on the floor in front of the arm; the TCP starts
    at a random pose above the work area. Reward `clip(1 - distance, 0, 1)`."""
    ball = SceneObject(
        name="ball", shape=Shape.SPHERE, size=[BALL_RADIUS], rgba=[1.0, 0.0, 0.0, 1.0], mass=0.1
    )
    z = BALL_RADIUS + 0.002
    return TaskSpec(
        scene=panda_scene([ball]),
        arms=[panda_arm()],
        sensors=[BodyPoseSensor("ball", name="goal")],
        initializers=[  # the arm first: the ball is then placed clear of it
            PoseInitializer(
                "panda", low=[0.3, -0.2, 0.3, 165, -15, -105], high=[0.6, 0.2, 0.6, 195, 15, -75]
            ),
            PropPlacer(["ball"], low=[0.35, -0.3, z], high=[0.65, 0.3, z]),
        ],
        reward=ReachReward("panda_tcp_pos", "goal_pose"),
    )


def panda_pick_cube_spec() -> TaskSpec:
    """Lift a 4 cm cube placed at random on the floor by 10 cm. Reward `LiftReward` (1 when
    lifted, up to 0.5 for approaching and raising it); the episode ends once it is lifted."""
    cube = SceneObject(
        name="cube",
        shape=Shape.BOX,
        size=[CUBE_HALF] * 3,
        rgba=[0.1, 0.4, 1.0, 1.0],
        mass=0.05,
        condim=Condim.Torsional,
        friction=[1.0, 0.02, 0.001],
    )
    z = CUBE_HALF + 0.002
    return TaskSpec(
        scene=panda_scene([cube]),
        arms=[panda_arm()],
        sensors=[BodyPoseSensor("cube")],
        initializers=[PropPlacer(["cube"], low=[0.4, -0.15, z], high=[0.6, 0.15, z])],
        reward=LiftReward("panda_tcp_pos", "cube_pose", rest_z=CUBE_HALF, lift=LIFT),
        terminated=Lifted("cube_pose", rest_z=CUBE_HALF, lift=LIFT),
    )


def panda_reach(render_mode: str | None = None, **kwargs: Any) -> TaskEnv:
    """`mjkdl/PandaReach-v0`; keyword arguments go to `TaskEnv`."""
    kwargs.setdefault("render_camera", "front")
    return TaskEnv(panda_reach_spec(), render_mode, **kwargs)


def panda_pick_cube(render_mode: str | None = None, **kwargs: Any) -> TaskEnv:
    """`mjkdl/PandaPickCube-v0`; keyword arguments go to `TaskEnv`."""
    kwargs.setdefault("render_camera", "front")
    return TaskEnv(panda_pick_cube_spec(), render_mode, **kwargs)


def register() -> None:
    """Register the tasks with Gymnasium (done by `import mjkdl.task`; idempotent)."""
    for env_id, entry in (
        ("mjkdl/PandaReach-v0", "panda_reach"),
        ("mjkdl/PandaPickCube-v0", "panda_pick_cube"),
    ):
        if env_id not in gym.registry:
            gym.register(id=env_id, entry_point=f"{__name__}:{entry}", disable_env_checker=False)
