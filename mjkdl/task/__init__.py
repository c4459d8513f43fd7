"""Gymnasium task environments on mjkdl scenes: `TaskSpec` -> `TaskEnv`.

Importing this package registers `mjkdl/PandaReach-v0` and `mjkdl/PandaPickCube-v0`.
"""

from .env import Sensor, TaskEnv
from .initializers import JointInitializer, PhysicsRandomizer, PoseInitializer, PropPlacer
from .registry import register as _register
from .rewards import Lifted, LiftReward, Reached, ReachReward, distance, height
from .rollout import Episode, ray_collect, run_episode
from .sensors import intrinsics
from .spec import (
    Actuation,
    ArmSpec,
    BodyPoseSensor,
    CameraSensor,
    GripperSpec,
    TaskSpec,
)
from .view import view

_register()

__all__ = [
    "Actuation",
    "ArmSpec",
    "BodyPoseSensor",
    "CameraSensor",
    "Episode",
    "GripperSpec",
    "JointInitializer",
    "LiftReward",
    "Lifted",
    "PhysicsRandomizer",
    "PoseInitializer",
    "PropPlacer",
    "ReachReward",
    "Reached",
    "Sensor",
    "TaskEnv",
    "TaskSpec",
    "distance",
    "height",
    "intrinsics",
    "ray_collect",
    "run_episode",
    "view",
]
