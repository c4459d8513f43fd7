"""Motion generation: collision-free planning (OMPL), timed trajectories (toppra), execution."""

from ..errors import PlanningError
from .collision import CollisionChecker
from .follower import TrajectoryFollower
from .planner import DATASHEET_LIMITS, PLANNERS, MotionPlanner
from .trajectory import JointTrajectory, TimeParametrizer

__all__ = [
    "DATASHEET_LIMITS",
    "PLANNERS",
    "CollisionChecker",
    "JointTrajectory",
    "MotionPlanner",
    "PlanningError",
    "TimeParametrizer",
    "TrajectoryFollower",
]
