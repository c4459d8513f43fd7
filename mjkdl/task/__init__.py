"""Gymnasium task environments on mjkdl scenes: `TaskSpec` -> `TaskEnv`.

Importing this package registers `mjkdl/PandaReach-v0`, `mjkdl/PandaPickCube-v0`,
`mjkdl/PandaPush-v0`, `mjkdl/PandaPickAndPlace-v0`, `mjkdl/PandaStack-v0` and their
goal-conditioned variants (`mjkdl/PandaReachGoal-v0`, ...); `mjkdl.task.experts.expert_for(env)`
gives each a scripted expert.
"""

from .env import Sensor, TaskEnv
from .goal import GoalReward, GoalTaskEnv
from .initializers import (
    JointInitializer,
    PhysicsRandomizer,
    PlaceAbove,
    PoseInitializer,
    PropPlacer,
)
from .randomization import Draw, Randomization, Uniform
from .registry import register as _register
from .rewards import (
    ArrayRule,
    Held,
    Lifted,
    LiftReward,
    Placed,
    PlaceReward,
    Reached,
    ReachReward,
    SparseReward,
    distance,
    height,
    place_reward,
    success_bonus,
)
from .rollout import Episode, ray_collect, run_episode
from .sensors import intrinsics
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
from .view import view

_register()

__all__ = [
    "CARTESIAN_AXES",
    "Actuation",
    "ArmSpec",
    "ArrayRule",
    "BodyPoseSensor",
    "CameraSensor",
    "ContactSensor",
    "Draw",
    "Episode",
    "GoalReward",
    "GoalTaskEnv",
    "GripperSpec",
    "Held",
    "JointInitializer",
    "LiftReward",
    "Lifted",
    "PhysicsRandomizer",
    "PlaceAbove",
    "PlaceReward",
    "Placed",
    "PoseInitializer",
    "PropPlacer",
    "Randomization",
    "ReachReward",
    "Reached",
    "RelativePositionSensor",
    "Sensor",
    "SparseReward",
    "TaskEnv",
    "TaskSpec",
    "Uniform",
    "distance",
    "height",
    "intrinsics",
    "place_reward",
    "ray_collect",
    "run_episode",
    "success_bonus",
    "view",
]


_LAZY = ("make_batch", "BatchEnv")


def __dir__() -> list[str]:
    return sorted([*globals(), *_LAZY])


def __getattr__(name: str) -> object:
    """`make_batch` and `BatchEnv` (torch: the `batch` extra; MuJoCo Warp on a GPU: the `warp`
    extra) load on first use."""
    if name in _LAZY:
        try:
            from . import batch
        except ModuleNotFoundError as missing:
            if missing.name != "torch":
                raise
            raise ImportError(
                f"mjkdl.task.{name} needs the batch extra (torch is not installed): "
                "pip install 'mjkdl[batch]'"
            ) from None
        return getattr(batch, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
