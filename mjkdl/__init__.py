"""mjkdl: MuJoCo scenes from plain dataclasses, Pinocchio kinematics and dynamics on top."""

from . import assets, menagerie
from .control import CartesianVelocityController, Gripper, SolveStatus
from .errors import (
    BuildError,
    MjkdlError,
    ModelFileError,
    SimulationError,
    SpecError,
    SpecTypeError,
    UnknownNameError,
)
from .hw import in_the_loop as _in_the_loop  # noqa: F401  (registers robot_ip= links)
from .ik import IKResult
from .record import (
    ImageWriteError,
    OffscreenRenderError,
    RecordingError,
    VideoRecorder,
    VideoResolution,
    VideoWriteError,
    save_image,
)
from .robot import IgnoredCommandWarning, Robot
from .scene import Env, ResetHookError, ResetInfo, Scene, mujoco_log_path, mujoco_version
from .spec import (
    AttachKind,
    AttachmentSpec,
    AttachTarget,
    CameraSpec,
    Condim,
    CtrlMode,
    ForceTorqueSensorSpec,
    GripperDrive,
    JointImpedanceDrive,
    PhysicsOptions,
    ResetContext,
    ResetOptions,
    RobotSpec,
    SceneObject,
    SceneSpec,
    Shape,
    ToolFrameSpec,
    scene_object_site_name,
)
from .viewer import NoDisplayError, SimulateViewer

__version__ = "0.1.0"

__all__ = [
    "AttachKind",
    "AttachTarget",
    "AttachmentSpec",
    "BuildError",
    "CameraSpec",
    "CartesianVelocityController",
    "Condim",
    "CtrlMode",
    "Env",
    "ForceTorqueSensorSpec",
    "Gripper",
    "GripperDrive",
    "IKResult",
    "IgnoredCommandWarning",
    "ImageWriteError",
    "JointImpedanceDrive",
    "MjkdlError",
    "ModelFileError",
    "NoDisplayError",
    "OffscreenRenderError",
    "PhysicsOptions",
    "RecordingError",
    "ResetContext",
    "ResetHookError",
    "ResetInfo",
    "ResetOptions",
    "Robot",
    "RobotSpec",
    "Scene",
    "SceneObject",
    "SceneSpec",
    "Shape",
    "SimulateViewer",
    "SimulationError",
    "SolveStatus",
    "SpecError",
    "SpecTypeError",
    "ToolFrameSpec",
    "UnknownNameError",
    "VideoRecorder",
    "VideoResolution",
    "VideoWriteError",
    "assets",
    "menagerie",
    "mujoco_log_path",
    "mujoco_version",
    "save_image",
    "scene_object_site_name",
]
