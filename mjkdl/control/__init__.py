"""Controllers usable from any control script: Cartesian velocity control and grippers."""

from .cartesian import CartesianVelocityController, SolveStatus
from .gripper import Gripper

__all__ = ["CartesianVelocityController", "Gripper", "SolveStatus"]
