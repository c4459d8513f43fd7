"""A "real" arm for rehearsals: how the served arm differs from the nominal simulation.

`Reality` describes the differences the simulator puts between its arm and the training
simulation: joint friction (the identified model of Gaz et al., below), a load in the hand
the robot is not told of, noise on the measured joint positions and velocities, and a latency
of the state the client reads. Link masses, centres of mass and inertias are those Gaz et al.
identified already in the training simulation (Menagerie's Panda takes them from franka_ros's
`inertial.yaml`), so no preset changes them. The server takes
one with `--reality NAME` (a preset of `REALITIES`) or `--reality FILE` (JSON of the fields).

The preset "panda-gaz2019" is the Panda's joint friction identified in C. Gaz, M. Cognetti,
A. Oliva, P. Robuffo Giordano, A. De Luca, "Dynamic Identification of the Franka Emika Panda
Robot With Retrieval of Feasible Parameters Using Penalty-Based Optimization", IEEE RA-L 4(4),
2019, with the parameters the authors publish (github.com/marcocognetti/FrankaEmikaPandaDynModel,
`matlab/dyn_model_panda/get_FrictionTorque.m`): per joint,
tau_f(dq) = phi1 / (1 + exp(-phi2 (dq + phi3))) - phi1 / (1 + exp(-phi2 phi3)),
the torque the joint loses to friction (zero at rest).
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import pinocchio as pin

from mjkdl.errors import SpecError, SpecTypeError, unknown_name


@dataclass(frozen=True)
class JointFriction:
    """Gaz et al.'s friction model, one value per joint: `phi1` (N·m), `phi2` (s/rad),
    `phi3` (rad/s)."""

    phi1: tuple[float, ...]
    phi2: tuple[float, ...]
    phi3: tuple[float, ...]

    def torque(self, dq: np.ndarray) -> np.ndarray:
        """The friction torque (N·m) at joint velocities `dq`, which the joints lose."""
        p1, p2, p3 = (np.asarray(v) for v in (self.phi1, self.phi2, self.phi3))
        return p1 / (1.0 + np.exp(-p2 * (dq + p3))) - p1 / (1.0 + np.exp(-p2 * p3))


# Gaz et al. 2019, the authors' published parameters (see the module doc).
GAZ2019_FRICTION = JointFriction(
    phi1=(0.54615, 0.87224, 0.64068, 1.2794, 0.83904, 0.30301, 0.56489),
    phi2=(5.1181, 9.0657, 10.136, 5.5903, 8.3469, 17.133, 10.336),
    phi3=(0.039533, 0.025882, -0.04607, 0.036194, 0.026226, -0.021047, 0.0035526),
)


@dataclass(frozen=True)
class Reality:
    """How the served arm differs from the nominal simulation (the defaults: not at all).

    `friction`: joint friction the arm's joints lose (None: none); `load_mass` (kg) at
    `load_com` (m, in the flange frame, as libfranka's `setLoad` takes it): a load the hand
    carries that the robot's model does not know (its controller sags under it unless the
    client sets it); `q_noise` (rad) and
    `dq_noise` (rad/s): standard deviations of Gaussian noise on the measured `q`/`theta`
    and `dq`/`dtheta` the client reads (from a generator seeded with `seed`); `state_latency`:
    whole robot cycles (1 ms) the measured state the client reads lags the arm.
    """

    name: str = "nominal"
    friction: JointFriction | None = None
    load_mass: float = 0.0
    load_com: tuple[float, float, float] = (0.0, 0.0, 0.0)
    q_noise: float = 0.0
    dq_noise: float = 0.0
    state_latency: int = 0
    seed: int = 0

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise SpecTypeError(f"reality.name must be a non-empty string, got {self.name!r}")
        com = np.asarray(self.load_com, dtype=float)
        if com.shape != (3,) or not np.all(np.isfinite(com)):
            raise SpecError(f"reality.load_com must be 3 finite numbers (m), got {self.load_com!r}")
        for field_name in ("load_mass", "q_noise", "dq_noise"):
            v = getattr(self, field_name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise SpecError(f"reality.{field_name} must be a finite number, got {v!r}")
            if v < 0:
                raise SpecError(f"reality.{field_name} must be >= 0, got {v!r}")
        for field_name in ("state_latency", "seed"):
            v = getattr(self, field_name)
            if isinstance(v, bool) or not isinstance(v, int) or v < 0:
                raise SpecError(f"reality.{field_name} must be a whole number >= 0, got {v!r}")
        f = self.friction
        if f is not None:
            for field_name in ("phi1", "phi2", "phi3"):
                v = np.asarray(getattr(f, field_name), dtype=float)
                if v.shape != (7,) or not np.all(np.isfinite(v)):
                    raise SpecError(
                        f"reality.friction.{field_name} must be 7 finite numbers, got "
                        f"{getattr(f, field_name)!r}"
                    )

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], where: str = "reality") -> Reality:
        """A `Reality` from its JSON fields (`friction`: {phi1, phi2, phi3} or a preset's
        name whose friction it takes, e.g. "panda-gaz2019")."""
        known = {f.name for f in fields(cls)}
        for key in data:
            if key not in known:
                raise unknown_name("field", str(key), sorted(known), where)
        kwargs = dict(data)
        friction = kwargs.get("friction")
        if isinstance(friction, str):
            if friction not in REALITIES:
                raise unknown_name("reality preset", friction, REALITIES, f"{where}: friction")
            kwargs["friction"] = REALITIES[friction].friction
        elif isinstance(friction, Mapping):
            try:
                kwargs["friction"] = JointFriction(**{k: tuple(v) for k, v in friction.items()})
            except TypeError as err:
                raise SpecError(
                    f"{where}: friction takes phi1, phi2, phi3 (7 numbers each): {err}"
                ) from None
        elif friction is not None:
            raise SpecTypeError(
                f"{where}: friction must be {{phi1, phi2, phi3}} or a preset name, got {friction!r}"
            )
        return cls(**kwargs)


REALITIES: dict[str, Reality] = {
    "nominal": Reality(),
    "panda-gaz2019": Reality(name="panda-gaz2019", friction=GAZ2019_FRICTION),
}
"""The presets `--reality NAME` takes."""


def reality_from(value: str | Reality | None) -> Reality:
    """A preset's name, a JSON file's path, a `Reality` or None (nominal) as a `Reality`."""
    if value is None:
        return REALITIES["nominal"]
    if isinstance(value, Reality):
        return value
    if not isinstance(value, str):
        raise SpecTypeError(f"reality must be a preset name or a JSON file, got {value!r}")
    if value in REALITIES:
        return REALITIES[value]
    path = Path(value)
    if not path.is_file():
        raise unknown_name("reality preset or file", value, REALITIES, "--reality")
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError) as err:
        raise SpecError(f"--reality {path}: not a readable JSON file: {err}") from None
    if not isinstance(data, Mapping):
        raise SpecError(f"--reality {path}: the JSON must be an object of Reality's fields")
    return Reality.from_dict({"name": path.stem, **data}, f"--reality {path}")


def add_load(model: mujoco.MjModel, body: int, mass: float, com: Sequence[float]) -> None:
    """Add a point `mass` at `com` (flange frame) to the Franka hand `body` of `model`: its
    mass, centre of mass and inertia (parallel axes, then principal axes) as one body."""
    flange_to_hand = pin.utils.rotate("z", np.pi / 4)  # the hand is the flange turned -45°
    p = flange_to_hand @ np.asarray(com, dtype=float)
    m0, c0 = float(model.body_mass[body]), model.body_ipos[body].copy()
    rot = np.zeros(9)
    mujoco.mju_quat2Mat(rot, model.body_iquat[body])
    r = rot.reshape(3, 3)
    total = m0 + mass
    c = (m0 * c0 + mass * p) / total

    def steiner(m: float, d: np.ndarray) -> np.ndarray:
        return m * (float(d @ d) * np.eye(3) - np.outer(d, d))

    inertia = r @ np.diag(model.body_inertia[body]) @ r.T + steiner(m0, c0 - c)
    inertia += steiner(mass, p - c)
    values, axes = np.linalg.eigh(inertia)
    if np.linalg.det(axes) < 0:
        axes[:, 0] *= -1.0
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, axes.flatten())
    model.body_mass[body] = total
    model.body_ipos[body] = c
    model.body_inertia[body] = values
    model.body_iquat[body] = quat
    model.body_sameframe[body] = 0  # the inertial frame left the body's
    model.body_simple[body] = 0
    mujoco.mj_setConst(model, mujoco.MjData(model))  # subtree masses and the like


class StateLag:
    """The measured state as the client reads it: `latency` cycles late, with noise."""

    def __init__(self, reality: Reality) -> None:
        self.reality = reality
        self._rng = np.random.default_rng(reality.seed)
        self._past: list[tuple[np.ndarray, np.ndarray]] = []

    def read(self, q: np.ndarray, dq: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """What the client reads this cycle of the arm at `q`, `dq`."""
        r = self.reality
        self._past.append((q.copy(), dq.copy()))
        if len(self._past) > r.state_latency + 1:
            self._past.pop(0)
        q_out, dq_out = self._past[0]
        if r.q_noise:
            q_out = q_out + self._rng.normal(0.0, r.q_noise, 7)
        if r.dq_noise:
            dq_out = dq_out + self._rng.normal(0.0, r.dq_noise, 7)
        return q_out, dq_out
