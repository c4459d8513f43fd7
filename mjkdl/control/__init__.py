"""Controllers usable from any control script: Cartesian velocity, operational space, grippers."""

from .cartesian import CartesianSettings, CartesianVelocityController, SolveStatus
from .gripper import Gripper
from .osc import OperationalSpaceController

__all__ = [
    "CartesianSettings",
    "CartesianVelocityController",
    "Gripper",
    "OperationalSpaceController",
    "SolveStatus",
]
