"""Demonstrations: record episodes to HDF5 (robomimic's layout), replay them exactly,
drive the arm by hand, evaluate policies (in simulation, or deployed on an arm), export to
LeRobot.

The command line is `python -m mjkdl.demos collect | replay | teleop | evaluate |
export-lerobot`; each command is a function here too.
"""

from .collect import CollectResult, collect
from .deploy import DeploymentFault, DeploymentStopped, StopKey
from .episodes import EpisodeResult, file_env, make_env, restore, run_episode, run_seeds
from .evaluate import Evaluation, evaluate, wilson_interval
from .hdf5 import (
    Demo,
    DemoFile,
    DemoFileError,
    DemoWriteError,
    EpisodeBuffer,
    EpisodeData,
    EpisodeWriter,
    StoredModelWarning,
)
from .lerobot import ExportError, LeRobotExport, export_lerobot
from .lerobot_policy import LeRobotPolicy  # registers `lerobot:PATH` policy sources
from .policy import Policy, PolicyError, PolicySource, make_policy, policy_rate
from .replay import ReplayResult, ReplayWarning, replay, replay_all
from .robomimic_policy import RobomimicPolicy  # registers `robomimic:CKPT` policy sources
from .sb3_policy import SB3Policy  # registers `sb3:PATH.zip` policy sources

__all__ = [
    "CollectResult",
    "Demo",
    "DemoFile",
    "DemoFileError",
    "DemoWriteError",
    "DeploymentFault",
    "DeploymentStopped",
    "EpisodeBuffer",
    "EpisodeData",
    "EpisodeResult",
    "EpisodeWriter",
    "Evaluation",
    "ExportError",
    "LeRobotExport",
    "LeRobotPolicy",
    "Policy",
    "PolicyError",
    "PolicySource",
    "ReplayResult",
    "ReplayWarning",
    "RobomimicPolicy",
    "SB3Policy",
    "StopKey",
    "StoredModelWarning",
    "collect",
    "evaluate",
    "export_lerobot",
    "file_env",
    "make_env",
    "make_policy",
    "policy_rate",
    "replay",
    "replay_all",
    "restore",
    "run_episode",
    "run_seeds",
    "wilson_interval",
]
