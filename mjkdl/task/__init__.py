"""Gymnasium task environments on mjkdl scenes: `TaskSpec` -> `TaskEnv`.

Importing this package registers `mjkdl/PandaReach-v0` and `mjkdl/PandaPickCube-v0`.
"""

from .env import Sensor, TaskEnv
from .initializers import JointInitializer, PhysicsRandomizer, PoseInitializer, PropPlacer
from .registry import register as _register
from .rewards import (
    Held,
    Lifted,
    LiftReward,
    Reached,
    ReachReward,
    SparseReward,
    distance,
    height,
)
from .rollout import Episode, ray_collect, run_episode
from .sensors import intrinsics
from .spec import (
    Actuation,
    ArmSpec,
    BodyPoseSensor,
    CameraSensor,
    ContactSensor,
    GripperSpec,
    RelativePositionSensor,
    TaskSpec,
)
from .view import view

_register()

__all__ = [
    "Actuation",
    "ArmSpec",
    "BodyPoseSensor",
    "CameraSensor",
    "ContactSensor",
    "Episode",
    "GripperSpec",
    "Held",
    "JointInitializer",
    "LiftReward",
    "Lifted",
    "PhysicsRandomizer",
    "PoseInitializer",
    "PropPlacer",
    "ReachReward",
    "Reached",
    "RelativePositionSensor",
    "Sensor",
    "SparseReward",
    "TaskEnv",
    "TaskSpec",
    "distance",
    "height",
    "intrinsics",
    "ray_collect",
    "run_episode",
    "view",
]
