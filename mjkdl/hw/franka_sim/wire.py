"""The Franka Control Interface's wire format: TCP service messages and the UDP state/command.

Read from libfranka's public headers (`research_interface/robot/service_types.h`,
`rbk_types.h`, `gripper/types.h`): packed little-endian C structs. Two robot protocol versions
are served: 10 (libfranka >= 0.18: pylibfranka 0.21, franky 2.0; float32 state with the
accelerometers) and 5 (libfranka 0.9: panda-python 1.1; float64 state, a model library instead of
a URDF). The gripper speaks version 3 in both.
"""

from __future__ import annotations

import enum
import struct
from dataclasses import dataclass

import numpy as np

ROBOT_PORT = 1337
GRIPPER_PORT = 1338
GRIPPER_VERSION = 3

HEADER = struct.Struct("<III")  # command, command_id, size (robot service)
GRIPPER_HEADER = struct.Struct("<HII")  # the gripper's command is a uint16


class Command(enum.IntEnum):
    """Robot service commands of protocol 10 (libfranka >= 0.18)."""

    CONNECT = 0
    MOVE = 1
    STOP_MOVE = 2
    SET_COLLISION_BEHAVIOR = 3
    SET_JOINT_IMPEDANCE = 4
    SET_CARTESIAN_IMPEDANCE = 5
    SET_GUIDING_MODE = 6
    SET_EE_TO_K = 7
    SET_NE_TO_EE = 8
    SET_LOAD = 9
    AUTOMATIC_ERROR_RECOVERY = 10
    GET_ROBOT_MODEL = 11


# Protocol 5 numbers the same commands differently (GetCartesianLimit and SetFilters exist,
# the model comes as a binary library): its ids mapped onto the names above.
COMMANDS_V5 = {
    0: Command.CONNECT,
    1: Command.MOVE,
    2: Command.STOP_MOVE,
    4: Command.SET_COLLISION_BEHAVIOR,
    5: Command.SET_JOINT_IMPEDANCE,
    6: Command.SET_CARTESIAN_IMPEDANCE,
    7: Command.SET_GUIDING_MODE,
    8: Command.SET_EE_TO_K,
    9: Command.SET_NE_TO_EE,
    10: Command.SET_LOAD,
    12: Command.AUTOMATIC_ERROR_RECOVERY,
}
SET_FILTERS_V5 = 11
LOAD_MODEL_LIBRARY_V5 = 13


class MoveStatus(enum.IntEnum):
    """Move's reply; protocol 5 lacks the two `...DueToActivatedSafetyFunctions` entries."""

    SUCCESS = 0
    MOTION_STARTED = 1
    PREEMPTED = 2
    COMMAND_NOT_POSSIBLE = 5
    INVALID_ARGUMENT = 7
    REFLEX_ABORTED = 8
    ABORTED = 11


MOVE_STATUS_V5 = {
    MoveStatus.SUCCESS: 0,
    MoveStatus.MOTION_STARTED: 1,
    MoveStatus.PREEMPTED: 2,
    MoveStatus.COMMAND_NOT_POSSIBLE: 3,
    MoveStatus.INVALID_ARGUMENT: 5,
    MoveStatus.REFLEX_ABORTED: 6,
    MoveStatus.ABORTED: 9,
}


class ControllerMode(enum.IntEnum):
    """The controller a Move asks for, and the one the state reports."""

    JOINT_IMPEDANCE = 0
    CARTESIAN_IMPEDANCE = 1
    EXTERNAL = 2
    OTHER = 3


class MotionGenerator(enum.IntEnum):
    """The motion generator the state reports (a Move's request numbers them one lower)."""

    IDLE = 0
    JOINT_POSITION = 1
    JOINT_VELOCITY = 2
    CARTESIAN_POSITION = 3
    CARTESIAN_VELOCITY = 4
    NONE = 5  # torque control without a generator (protocol 10)


class RobotMode(enum.IntEnum):
    OTHER = 0
    IDLE = 1
    MOVE = 2
    GUIDING = 3
    REFLEX = 4
    USER_STOPPED = 5
    AUTOMATIC_ERROR_RECOVERY = 6


# `research_interface::robot::Error`, the 41 flags of `current_errors`/`last_motion_errors`, in
# order; the names are libfranka's `franka::Errors` fields, which ControlException messages print.
ERRORS = (
    "joint_position_limits_violation",
    "cartesian_position_limits_violation",
    "self_collision_avoidance_violation",
    "joint_velocity_violation",
    "cartesian_velocity_violation",
    "force_control_safety_violation",
    "joint_reflex",
    "cartesian_reflex",
    "max_goal_pose_deviation_violation",
    "max_path_pose_deviation_violation",
    "cartesian_velocity_profile_safety_violation",
    "joint_position_motion_generator_start_pose_invalid",
    "joint_motion_generator_position_limits_violation",
    "joint_motion_generator_velocity_limits_violation",
    "joint_motion_generator_velocity_discontinuity",
    "joint_motion_generator_acceleration_discontinuity",
    "cartesian_position_motion_generator_start_pose_invalid",
    "cartesian_motion_generator_elbow_limit_violation",
    "cartesian_motion_generator_velocity_limits_violation",
    "cartesian_motion_generator_velocity_discontinuity",
    "cartesian_motion_generator_acceleration_discontinuity",
    "cartesian_motion_generator_elbow_sign_inconsistent",
    "cartesian_motion_generator_start_elbow_invalid",
    "force_controller_desired_force_tolerance_violation",
    "start_elbow_sign_inconsistent",
    "communication_constraints_violation",
    "power_limit_violation",
    "cartesian_motion_generator_joint_position_limits_violation",
    "cartesian_motion_generator_joint_velocity_limits_violation",
    "cartesian_motion_generator_joint_velocity_discontinuity",
    "cartesian_motion_generator_joint_acceleration_discontinuity",
    "cartesian_position_motion_generator_invalid_frame",
    "controller_torque_discontinuity",
    "joint_p2p_insufficient_torque_for_planning",
    "tau_j_range_violation",
    "instability_detected",
    "joint_move_in_wrong_direction",
    "cartesian_spline_motion_generator_violation",
    "joint_via_motion_generator_planning_joint_limit_violation",
    "base_acceleration_initialization_timeout",
    "base_acceleration_invalid_reading",
)
ERROR_INDEX = {name: i for i, name in enumerate(ERRORS)}

_MATRICES = ("O_T_EE", "O_T_EE_d", "F_T_EE", "EE_T_K", "F_T_NE", "NE_T_EE")
_JOINT = ("tau_J", "tau_J_d", "dtau_J", "q", "q_d", "dq", "dq_d", "ddq_d")


def _state_dtype(real: str, accelerometers: bool) -> np.dtype:
    """`research_interface::robot::RobotState`, packed, with `real` its floating-point type."""
    fields: list[tuple[str, str, tuple[int, ...]]] = [("message_id", "<u8", ())]
    fields += [(name, real, (16,)) for name in _MATRICES]
    fields += [
        ("m_ee", real, ()),
        ("I_ee", real, (9,)),
        ("F_x_Cee", real, (3,)),
        ("m_load", real, ()),
        ("I_load", real, (9,)),
        ("F_x_Cload", real, (3,)),
        ("elbow", real, (2,)),
        ("elbow_d", real, (2,)),
    ]
    fields += [(name, real, (7,)) for name in _JOINT]
    fields += [
        ("joint_contact", real, (7,)),
        ("cartesian_contact", real, (6,)),
        ("joint_collision", real, (7,)),
        ("cartesian_collision", real, (6,)),
        ("tau_ext_hat_filtered", real, (7,)),
        ("O_F_ext_hat_K", real, (6,)),
        ("K_F_ext_hat_K", real, (6,)),
        ("O_dP_EE_d", real, (6,)),
        ("O_ddP_O", real, (3,)),
        ("elbow_c", real, (2,)),
        ("delbow_c", real, (2,)),
        ("ddelbow_c", real, (2,)),
        ("O_T_EE_c", real, (16,)),
        ("O_dP_EE_c", real, (6,)),
        ("O_ddP_EE_c", real, (6,)),
        ("theta", real, (7,)),
        ("dtheta", real, (7,)),
    ]
    if accelerometers:
        fields += [("accelerometer_top", real, (18,)), ("accelerometer_bottom", real, (18,))]
    fields += [
        ("motion_generator_mode", "u1", ()),
        ("controller_mode", "u1", ()),
        ("errors", "u1", (41,)),
        ("reflex_reason", "u1", (41,)),
        ("robot_mode", "u1", ()),
        ("control_command_success_rate", real, ()),
    ]
    return np.dtype([(n, t, s) if s else (n, t) for n, t, s in fields])


def _command_dtype(torque_finished: bool) -> np.dtype:
    """`research_interface::robot::RobotCommand`, packed (float64 in every version)."""
    fields = [
        ("message_id", "<u8"),
        ("q_c", "<f8", (7,)),
        ("dq_c", "<f8", (7,)),
        ("O_T_EE_c", "<f8", (16,)),
        ("O_dP_EE_c", "<f8", (6,)),
        ("elbow_c", "<f8", (2,)),
        ("valid_elbow", "u1"),
        ("motion_generation_finished", "u1"),
        ("tau_J_d", "<f8", (7,)),
    ]
    if torque_finished:
        fields.append(("torque_command_finished", "u1"))
    return np.dtype(fields)


@dataclass(frozen=True)
class Protocol:
    """What differs between the robot protocol versions served."""

    version: int
    libfranka: str  # the client releases that speak it, for error messages
    state: np.dtype
    command: np.dtype
    move_request: struct.Struct  # controller mode, generator mode, two deviations (, more)

    def command_of(self, wire_id: int) -> Command | None:
        if self.version == 10:
            return Command(wire_id) if wire_id in Command._value2member_map_ else None
        return COMMANDS_V5.get(wire_id)

    def command_id(self, command: Command) -> int:
        if self.version == 10:
            return int(command)
        return next(k for k, v in COMMANDS_V5.items() if v is command)

    def move_status(self, status: MoveStatus) -> int:
        return int(status) if self.version == 10 else MOVE_STATUS_V5[status]


PROTOCOL_10 = Protocol(
    version=10,
    libfranka="libfranka >= 0.18 (pylibfranka 0.21, franky 2.0)",
    state=_state_dtype("<f4", accelerometers=True),
    command=_command_dtype(torque_finished=True),
    move_request=struct.Struct("<II6d?7d"),
)
PROTOCOL_5 = Protocol(
    version=5,
    libfranka="libfranka 0.9 (panda-python 1.1)",
    state=_state_dtype("<f8", accelerometers=False),
    command=_command_dtype(torque_finished=False),
    move_request=struct.Struct("<II6d"),
)
PROTOCOLS = {p.version: p for p in (PROTOCOL_10, PROTOCOL_5)}

# Gripper (protocol 3): commands, request layouts, the UDP state.
GRIPPER_CONNECT, GRIPPER_HOMING, GRIPPER_GRASP, GRIPPER_MOVE, GRIPPER_STOP = range(5)
GRIPPER_SUCCESS, GRIPPER_FAIL, GRIPPER_UNSUCCESSFUL, GRIPPER_ABORTED = range(4)
GRASP_REQUEST = struct.Struct("<5d")  # width, epsilon inner, epsilon outer, speed, force
GRIPPER_MOVE_REQUEST = struct.Struct("<2d")  # width, speed
GRIPPER_STATE = struct.Struct("<Idd?H")  # message_id, width, max_width, is_grasped, temperature


def message(command: int, command_id: int, payload: bytes) -> bytes:
    """A robot service message: the header, then the payload."""
    return HEADER.pack(command, command_id, HEADER.size + len(payload)) + payload


def gripper_message(command: int, command_id: int, payload: bytes) -> bytes:
    return GRIPPER_HEADER.pack(command, command_id, GRIPPER_HEADER.size + len(payload)) + payload
