"""Motion generation: collision-free planning (OMPL), timed trajectories (toppra), execution."""

from ..errors import InfeasibleError, PlanningError, PlanningTimeout
from .acm import AllowedCollisionMatrix, acm_cache_dir
from .collision import CollisionChecker
from .constraints import OrientationConstraint
from .follower import FollowerStop, TrajectoryFollower
from .limits import DATASHEETS, Datasheet, RobotLimits
from .planner import PLANNERS, MotionPlanner
from .srdf import Srdf, SrdfGroup
from .trajectory import JointTrajectory, TimeParametrizer

__all__ = [
    "DATASHEETS",
    "PLANNERS",
    "AllowedCollisionMatrix",
    "CollisionChecker",
    "Datasheet",
    "FollowerStop",
    "InfeasibleError",
    "JointTrajectory",
    "MotionPlanner",
    "OrientationConstraint",
    "PlanningError",
    "PlanningTimeout",
    "RobotLimits",
    "Srdf",
    "SrdfGroup",
    "TimeParametrizer",
    "TrajectoryFollower",
    "acm_cache_dir",
]
