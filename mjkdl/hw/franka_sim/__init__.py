"""A MuJoCo-backed Franka arm and hand that speak the robot's own network protocol."""

from .server import FrankaSimServer

__all__ = ["FrankaSimServer"]
