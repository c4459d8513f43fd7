"""The arm's published limits (Franka's datasheets, the values libfranka's `rate_limiting.h`
uses): what the reflexes of the simulated arm check the commands and the measured state against."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..joint_impedance import TAU_MAX


def _arr(values: list[float]) -> np.ndarray:
    return np.asarray(values, dtype=float)


@dataclass(frozen=True)
class ArmLimits:
    """Joint range, velocity, acceleration, jerk, torque and torque rate; Cartesian speed,
    acceleration and jerk of the end effector (translation, rotation)."""

    name: str
    q_min: np.ndarray
    q_max: np.ndarray
    dq_max: np.ndarray
    ddq_max: np.ndarray
    dddq_max: np.ndarray
    tau_max: np.ndarray = field(default_factory=TAU_MAX.copy)
    dtau_max: float = 1000.0
    v_max: tuple[float, float] = (1.7, 2.5)
    a_max: tuple[float, float] = (13.0, 25.0)
    j_max: tuple[float, float] = (6500.0, 12500.0)


PANDA = ArmLimits(
    name="panda",
    q_min=_arr([-2.8973, -1.7628, -2.8973, -3.0718, -2.8973, -0.0175, -2.8973]),
    q_max=_arr([2.8973, 1.7628, 2.8973, -0.0698, 2.8973, 3.7525, 2.8973]),
    dq_max=_arr([2.175, 2.175, 2.175, 2.175, 2.61, 2.61, 2.61]),
    ddq_max=_arr([15.0, 7.5, 10.0, 12.5, 15.0, 20.0, 20.0]),
    dddq_max=_arr([7500.0, 3750.0, 5000.0, 6250.0, 7500.0, 10000.0, 10000.0]),
)
# FR3's datasheet. MuJoCo Menagerie has no FR3 model, so `--model fr3` simulates the Panda's
# kinematics and dynamics and checks commands against these limits (its joint 6 range starts at
# 0.5445 rad, where the Panda's starts below zero).
FR3 = ArmLimits(
    name="fr3",
    q_min=_arr([-2.7437, -1.7837, -2.9007, -3.0421, -2.8065, 0.5445, -3.0159]),
    q_max=_arr([2.7437, 1.7837, 2.9007, -0.1518, 2.8065, 4.5169, 3.0159]),
    dq_max=_arr([2.62, 2.62, 2.62, 2.62, 5.26, 4.18, 5.26]),
    ddq_max=_arr([10.0] * 7),
    dddq_max=_arr([5000.0] * 7),
    v_max=(3.0, 2.5),
    a_max=(9.0, 17.0),
    j_max=(4500.0, 8500.0),
)
MODELS = {"panda": PANDA, "fr3": FR3}
