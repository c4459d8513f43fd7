"""Domain randomisation, described once: ranges on a task, one draw per episode, applied at reset.

`Randomization` is the description (`TaskSpec.randomization`, `gym.make(id, randomization=...)`,
as the dataclass or its dict): for each physical or visual quantity a `Uniform` range and the
names of the elements it applies to (none: all of them). `Randomization.draw(model, rng)` makes
one episode's values, a `Draw`: plain per-element numbers (ids of the compiled model and values)
with no MuJoCo object in it, so a recorded episode stores it (`Draw.to_dict()`) and an engine
holding many worlds applies one per world. `apply(draw, model, scratch)` writes a draw into
an `MjModel` and returns what it overwrote, which `undo` writes back (the next episode's draw
starts from the nominal model, exactly).

Scale ranges multiply the nominal value; offset ranges add to it; `geom_rgba` draws each colour
channel in its range. A body's mass and its inertia are scaled by the same factor (the mass
distribution keeps its shape, so the inertia stays that of the body), and `body_com` moves the
centre of mass (the inertia is about it). The controller's own model (the arm's Pinocchio
model, its gravity compensation) stays nominal, as a real arm's controller's does.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, fields
from typing import Any

import mujoco
import numpy as np

from ..errors import SpecError, SpecTypeError, unknown_name


@dataclass(frozen=True)
class Uniform:
    """Values drawn uniformly in [`low`, `high`] for each element named in `names` (MuJoCo
    names of the field's kind; empty: every element)."""

    low: float
    high: float
    names: tuple[str, ...] = ()


# field -> (MuJoCo object kind, how the range acts, components per element)
_ELEMENTS: dict[str, tuple[mujoco.mjtObj, str, int]] = {
    "body_mass": (mujoco.mjtObj.mjOBJ_BODY, "scale", 1),
    "body_com": (mujoco.mjtObj.mjOBJ_BODY, "offset", 3),
    "geom_friction": (mujoco.mjtObj.mjOBJ_GEOM, "scale", 1),
    "joint_damping": (mujoco.mjtObj.mjOBJ_JOINT, "scale", 1),
    "joint_armature": (mujoco.mjtObj.mjOBJ_JOINT, "scale", 1),
    "joint_frictionloss": (mujoco.mjtObj.mjOBJ_JOINT, "scale", 1),
    "actuator_gain": (mujoco.mjtObj.mjOBJ_ACTUATOR, "scale", 1),
    "camera_pos": (mujoco.mjtObj.mjOBJ_CAMERA, "offset", 3),
    "camera_euler": (mujoco.mjtObj.mjOBJ_CAMERA, "offset", 3),
    "camera_fovy": (mujoco.mjtObj.mjOBJ_CAMERA, "offset", 1),
    "light_pos": (mujoco.mjtObj.mjOBJ_LIGHT, "offset", 3),
    "light_diffuse": (mujoco.mjtObj.mjOBJ_LIGHT, "scale", 1),
    "geom_rgba": (mujoco.mjtObj.mjOBJ_GEOM, "value", 3),
}
# kind -> (its name in messages, the MjModel field counting its elements)
_KINDS = {
    mujoco.mjtObj.mjOBJ_BODY: ("body", "nbody"),
    mujoco.mjtObj.mjOBJ_GEOM: ("geom", "ngeom"),
    mujoco.mjtObj.mjOBJ_JOINT: ("joint", "njnt"),
    mujoco.mjtObj.mjOBJ_ACTUATOR: ("actuator", "nu"),
    mujoco.mjtObj.mjOBJ_CAMERA: ("camera", "ncam"),
    mujoco.mjtObj.mjOBJ_LIGHT: ("light", "nlight"),
}


@dataclass(frozen=True)
class Randomization:
    """What varies from episode to episode, and how much (None: stays nominal).

    Physics: `body_mass` (scale of mass and inertia; what MuJoCo's `gravcomp` cancels of a
    body stays its nominal weight, as a robot compensates its own from its nominal model),
    `body_com` (m, each axis),
    `geom_friction` (scale of the sliding friction), `joint_damping`, `joint_armature`,
    `joint_frictionloss` (scales), `actuator_gain` (scale of an actuator's gain `gainprm[0]` and
    of its position and velocity feedback `biasprm[1:3]`: a servo's stiffness and damping, a
    motor's strength, together), `gravity` (m/s², added to each axis). Control:
    `action_latency` (whole control steps the action is applied late, drawn in [low, high]),
    `action_latency_ticks` (1 ms ticks each control period's target reaches the arm late, as a
    command delayed on its way to the robot: with `arm_drive="franka_impedance"` only, drawn
    in [low, high], below one control period),
    `action_noise` (standard deviation added to every action entry, as a fraction of the
    entry's half range: in [-1, 1] units for normalised actions).
    Observation: `observation_noise` (observation key -> standard deviation added to what the
    agent sees; rewards and success see the true values). Visual: `camera_pos` (m),
    `camera_euler` (degrees about the camera's own x, y, z axes, in turn), `camera_fovy`
    (degrees), `light_pos` (m), `light_diffuse` (scale), `geom_rgba` (each RGB
    channel drawn in the range).
    """

    body_mass: Uniform | None = None
    body_com: Uniform | None = None
    geom_friction: Uniform | None = None
    joint_damping: Uniform | None = None
    joint_armature: Uniform | None = None
    joint_frictionloss: Uniform | None = None
    actuator_gain: Uniform | None = None
    gravity: Uniform | None = None
    action_latency: tuple[int, int] | None = None
    action_latency_ticks: tuple[int, int] | None = None
    action_noise: float = 0.0
    observation_noise: Mapping[str, float] = field(default_factory=dict)
    camera_pos: Uniform | None = None
    camera_euler: Uniform | None = None
    camera_fovy: Uniform | None = None
    light_pos: Uniform | None = None
    light_diffuse: Uniform | None = None
    geom_rgba: Uniform | None = None

    def check(self, model: mujoco.MjModel, observation_keys: Sequence[str]) -> None:
        """Refuse bad ranges and unknown names, each error naming its field."""
        for name, (kind, how, _) in _ELEMENTS.items():
            rng = _uniform(getattr(self, name), name)
            if rng is None:
                continue
            if how == "scale" and rng.low <= 0.0:
                raise SpecError(
                    f"randomization.{name}: a scale range must be positive, got low={rng.low!r}"
                )
            if how == "value" and not (rng.low >= 0.0 and rng.high <= 1.0):
                raise SpecError(
                    f"randomization.{name}: colour channels lie in [0, 1], got "
                    f"[{rng.low!r}, {rng.high!r}]"
                )
            _ids(model, kind, rng.names, name)
        _uniform(self.gravity, "gravity")
        self._latency()
        _ticks(self.action_latency_ticks)
        _std(self.action_noise, "randomization.action_noise")
        if not isinstance(self.observation_noise, Mapping):
            raise SpecTypeError(
                "randomization.observation_noise must map observation keys to standard "
                f"deviations, got {self.observation_noise!r}"
            )
        for key, std in self.observation_noise.items():
            if key not in observation_keys:
                raise unknown_name(
                    "observation", key, list(observation_keys), "randomization.observation_noise"
                )
            _std(std, f"randomization.observation_noise[{key!r}]")

    def state_size(self, action_size: int) -> int:
        """Entries of MuJoCo's userdata the episode's actions on their way take (the latency's
        queue, `action_latency[1] + 1` actions of `action_size`): saved with the state."""
        lat = self._latency()
        return 0 if lat is None else (lat[1] + 1) * action_size

    def _latency(self) -> tuple[int, int] | None:
        return _whole_range(self.action_latency, "action_latency", "whole control steps")

    def draw(self, model: mujoco.MjModel, rng: np.random.Generator) -> Draw:
        """One episode's values from `rng` (the env's generator), in field order."""
        out = Draw()
        for name, (kind, _, width) in _ELEMENTS.items():
            r = getattr(self, name)
            if r is None:
                continue
            ids = _ids(model, kind, r.names, name)
            values = rng.uniform(r.low, r.high, size=(len(ids), width))
            setattr(out, name, Sample(tuple(int(i) for i in ids), values))
        if self.gravity is not None:
            out.gravity = rng.uniform(self.gravity.low, self.gravity.high, 3).tolist()
        if self.action_latency is not None:
            out.action_latency = int(
                rng.integers(self.action_latency[0], self.action_latency[1] + 1)
            )
        if self.action_latency_ticks is not None:
            low, high = self.action_latency_ticks
            out.action_latency_ticks = int(rng.integers(low, high + 1))
        out.action_noise = float(self.action_noise)
        out.observation_noise = {k: float(v) for k, v in self.observation_noise.items()}
        out.noise_seed = int(rng.integers(2**63))
        return out

    @classmethod
    def coerce(cls, value: object) -> Randomization | None:
        """`value` as a `Randomization`: the dataclass, its dict (`Uniform`s as dicts or
        `[low, high]` / `[low, high, names]`), or None."""
        if value is None or isinstance(value, Randomization):
            return value
        if not isinstance(value, Mapping):
            raise SpecTypeError(
                "randomization must be a Randomization, a dict of its fields or None, got "
                f"{value!r}"
            )
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(value) - known)
        if unknown:
            raise unknown_name("randomization field", unknown[0], sorted(known), "Randomization")
        kwargs: dict[str, Any] = {}
        for key, v in value.items():
            if key in _ELEMENTS or key == "gravity":
                kwargs[key] = _uniform_of(v, key)
            elif key in ("action_latency", "action_latency_ticks") and isinstance(v, list):
                kwargs[key] = tuple(v)
            else:
                kwargs[key] = v
        return cls(**kwargs)


def _whole_range(value: object, name: str, unit: str) -> tuple[int, int] | None:
    """`value` checked as a (low, high) range of whole numbers of `unit`, 0 <= low <= high."""
    if value is not None and (
        not isinstance(value, Sequence)
        or len(value) != 2
        or not all(isinstance(v, int) and not isinstance(v, bool) for v in value)
        or not 0 <= value[0] <= value[1]
    ):
        raise SpecError(
            f"randomization.{name} must be (low, high) {unit}, 0 <= low <= high, got {value!r}"
        )
    return None if value is None else (int(value[0]), int(value[1]))


def _ticks(value: object) -> tuple[int, int] | None:
    return _whole_range(value, "action_latency_ticks", "whole 1 ms ticks")


def fields_in_use(description: Randomization) -> list[str]:
    """The fields of `description` that vary something, in field order (an engine refuses
    those it cannot apply by name)."""
    out = []
    for f in fields(description):
        value = getattr(description, f.name)
        if f.name in ("action_latency", "action_latency_ticks"):
            value = value is not None and value[1] > 0
        elif f.name == "observation_noise":
            value = any(std > 0.0 for std in value.values())
        if value is not None and value is not False and value != 0.0:
            out.append(f.name)
    return out


# Physical field -> the MjModel fields `apply` writes for it ('opt.<name>': MjOption's), for
# engines that hold one model per world and take its values field by field.
MODEL_FIELDS: dict[str, tuple[str, ...]] = {
    "body_mass": ("body_mass", "body_inertia"),
    "body_com": ("body_ipos", "body_sameframe", "body_simple"),
    "geom_friction": ("geom_friction",),
    "joint_damping": ("dof_damping",),
    "joint_armature": ("dof_armature",),
    "joint_frictionloss": ("dof_frictionloss",),
    "actuator_gain": ("actuator_gainprm", "actuator_biasprm"),
    "gravity": ("opt.gravity",),
}
# The MjModel fields after whose change MuJoCo's derived constants must follow (mj_setConst),
# and those constants that the dynamics read (for engines that take them as computed).
CONST_INPUTS = ("body_mass", "body_ipos", "dof_armature")
CONST_OUTPUTS = (
    "body_subtreemass",
    "body_invweight0",
    "dof_invweight0",
    "tendon_invweight0",
    "actuator_acc0",
)


def model_fields(description: Randomization) -> list[str]:
    """The MjModel fields that `apply` writes for the physical fields of `description` in
    use (`MODEL_FIELDS`), in that order."""
    used = fields_in_use(description)
    return [f for name, written in MODEL_FIELDS.items() if name in used for f in written]


@dataclass
class Sample:
    """One field's draw: the compiled model's element ids and their values (n x components)."""

    ids: tuple[int, ...]
    values: np.ndarray


@dataclass
class Draw:
    """One episode's randomisation: plain numbers, documented per field as in `Randomization`
    (scales, offsets, colours per element id; `gravity` the offset added to the nominal one;
    `action_latency` in control steps, `action_latency_ticks` in 1 ms ticks; the noise levels;
    `noise_seed` the key of the episode's noise, which each step draws afresh from (key,
    step)). None: the field stays nominal."""

    body_mass: Sample | None = None
    body_com: Sample | None = None
    geom_friction: Sample | None = None
    joint_damping: Sample | None = None
    joint_armature: Sample | None = None
    joint_frictionloss: Sample | None = None
    actuator_gain: Sample | None = None
    camera_pos: Sample | None = None
    camera_euler: Sample | None = None
    camera_fovy: Sample | None = None
    light_pos: Sample | None = None
    light_diffuse: Sample | None = None
    geom_rgba: Sample | None = None
    gravity: list[float] | None = None
    action_latency: int = 0
    action_latency_ticks: int = 0
    action_noise: float = 0.0
    observation_noise: dict[str, float] = field(default_factory=dict)
    noise_seed: int = 0

    def to_dict(self) -> dict[str, Any]:
        """The draw as JSON-ready values (what a recorded demonstration stores)."""
        out: dict[str, Any] = {}
        for f in fields(self):
            v = getattr(self, f.name)
            if isinstance(v, Sample):
                v = {"ids": list(v.ids), "values": v.values.tolist()}
            out[f.name] = v
        return out

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Draw:
        """The draw `to_dict` wrote."""
        kwargs = dict(data)
        for name in _ELEMENTS:
            v = kwargs.get(name)
            if v is not None:
                kwargs[name] = Sample(tuple(v["ids"]), np.asarray(v["values"], dtype=float))
        return cls(**kwargs)


Saved = list[tuple[str, Any, np.ndarray]]
"""What `apply` overwrote: (MjModel field, index, the values before), for `undo`."""


def apply(draw: Draw, model: mujoco.MjModel, scratch: mujoco.MjData) -> Saved:
    """Write `draw` into `model`, relative to the values it holds (the nominal ones: `undo`
    the previous draw first); what it overwrote comes back for `undo`. Only the entries the
    draw names change, so a Robot's own writes (its control mode's actuator gains) stay.
    `scratch`: an `MjData` of the model without the episode's state, for MuJoCo's
    recomputation of the constants that follow masses and armature."""
    saved: Saved = []

    def write(name: str, index: Any, value: np.ndarray | int) -> None:
        array = model.opt.gravity if name == "gravity" else getattr(model, name)
        saved.append((name, index, array[index].copy()))
        array[index] = value

    if draw.gravity is not None:
        write("gravity", slice(None), model.opt.gravity + draw.gravity)
    if draw.body_mass is not None:
        ids, v = list(draw.body_mass.ids), draw.body_mass.values
        write("body_mass", ids, model.body_mass[ids] * v[:, 0])
        write("body_inertia", ids, model.body_inertia[ids] * v)
        held = [k for k, b in enumerate(ids) if model.body_gravcomp[b] > 0]
        if held:  # a robot cancels its weight from its nominal model (`RobotSpec.impedance`)
            bodies = [ids[k] for k in held]
            write("body_gravcomp", bodies, model.body_gravcomp[bodies] / v[held, 0])
    if draw.body_com is not None:
        ids = list(draw.body_com.ids)
        write("body_ipos", ids, model.body_ipos[ids] + draw.body_com.values)
        # The inertial frame left the body frame: MuJoCo's shortcuts for bodies whose frames
        # coincide no longer hold (mj_setConst refuses them).
        write("body_sameframe", ids, 0)
        write("body_simple", ids, 0)
    if draw.geom_friction is not None:
        index = (list(draw.geom_friction.ids), 0)
        write("geom_friction", index, model.geom_friction[index] * draw.geom_friction.values[:, 0])
    for name, field_name in (
        ("joint_damping", "dof_damping"),
        ("joint_armature", "dof_armature"),
        ("joint_frictionloss", "dof_frictionloss"),
    ):
        sample = getattr(draw, name)
        if sample is None:
            continue
        dofs: list[int] = []
        scales: list[float] = []
        for jid, (scale,) in zip(sample.ids, sample.values, strict=True):
            adr, n = int(model.jnt_dofadr[jid]), _dofs(int(model.jnt_type[jid]))
            dofs += range(adr, adr + n)
            scales += [scale] * n
        write(field_name, dofs, getattr(model, field_name)[dofs] * np.array(scales))
    if draw.actuator_gain is not None:
        ids, scale = list(draw.actuator_gain.ids), draw.actuator_gain.values[:, 0]
        write("actuator_gainprm", (ids, 0), model.actuator_gainprm[ids, 0] * scale)
        feedback = (ids, slice(1, 3))
        write("actuator_biasprm", feedback, model.actuator_biasprm[feedback] * scale[:, None])
    if draw.camera_pos is not None:
        ids = list(draw.camera_pos.ids)
        write("cam_pos", ids, model.cam_pos[ids] + draw.camera_pos.values)
    if draw.camera_euler is not None:
        ids = list(draw.camera_euler.ids)
        turned = np.empty((len(ids), 4))
        turn = np.empty(4)
        for row, (cam, euler) in enumerate(zip(ids, draw.camera_euler.values, strict=True)):
            mujoco.mju_euler2Quat(turn, np.radians(euler), "xyz")
            mujoco.mju_mulQuat(turned[row], model.cam_quat[cam], turn)
        write("cam_quat", ids, turned)
    if draw.camera_fovy is not None:
        ids = list(draw.camera_fovy.ids)
        write("cam_fovy", ids, model.cam_fovy[ids] + draw.camera_fovy.values[:, 0])
    if draw.light_pos is not None:
        ids = list(draw.light_pos.ids)
        write("light_pos", ids, model.light_pos[ids] + draw.light_pos.values)
    if draw.light_diffuse is not None:
        ids = list(draw.light_diffuse.ids)
        write("light_diffuse", ids, model.light_diffuse[ids] * draw.light_diffuse.values)
    if draw.geom_rgba is not None:
        write("geom_rgba", (list(draw.geom_rgba.ids), slice(0, 3)), draw.geom_rgba.values)
    _set_const(saved, model, scratch)
    return saved


def undo(saved: Saved, model: mujoco.MjModel, scratch: mujoco.MjData) -> None:
    """Give `model` back the values `apply` overwrote (exactly)."""
    for name, index, values in reversed(saved):
        array = model.opt.gravity if name == "gravity" else getattr(model, name)
        array[index] = values
    _set_const(saved, model, scratch)


def _set_const(saved: Saved, model: mujoco.MjModel, scratch: mujoco.MjData) -> None:
    # body_subtreemass, dof_invweight0 and the like follow masses, centres and armature
    if any(name in CONST_INPUTS for name, _, _ in saved):
        mujoco.mj_setConst(model, scratch)


def _dofs(joint_type: int) -> int:
    return {0: 6, 1: 3}.get(joint_type, 1)  # free, ball, slide/hinge


def _uniform(value: object, name: str) -> Uniform | None:
    if value is None:
        return None
    if not isinstance(value, Uniform):
        raise SpecTypeError(f"randomization.{name} must be a Uniform or None, got {value!r}")
    for side in ("low", "high"):
        v = getattr(value, side)
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise SpecError(f"randomization.{name}.{side} must be a finite number, got {v!r}")
    if value.low > value.high:
        raise SpecError(
            f"randomization.{name}: low must not exceed high, got [{value.low!r}, {value.high!r}]"
        )
    if not isinstance(value.names, tuple) or not all(isinstance(n, str) for n in value.names):
        raise SpecTypeError(
            f"randomization.{name}.names must be a tuple of names, got {value.names!r}"
        )
    return value


def _uniform_of(value: object, name: str) -> Uniform | None:
    """A `Uniform` from its dict or `[low, high(, names)]` (what JSON holds)."""
    if value is None or isinstance(value, Uniform):
        return value
    if isinstance(value, Mapping):
        names = tuple(value.get("names", ()))
        return Uniform(value.get("low"), value.get("high"), names)  # type: ignore[arg-type]
    if isinstance(value, Sequence) and not isinstance(value, str) and len(value) in (2, 3):
        names = tuple(value[2]) if len(value) == 3 else ()
        return Uniform(value[0], value[1], names)
    raise SpecTypeError(
        f"randomization.{name} must be a Uniform, {{'low', 'high', 'names'}} or [low, high], "
        f"got {value!r}"
    )


def _std(value: object, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise SpecTypeError(f"{where} must be a standard deviation (a number), got {value!r}")
    if not math.isfinite(value) or value < 0:
        raise SpecError(f"{where} must be a finite standard deviation >= 0, got {value!r}")
    return float(value)


def _ids(
    model: mujoco.MjModel, kind: mujoco.mjtObj, names: tuple[str, ...], field: str
) -> list[int]:
    """The ids of `names` (every element of the kind when empty; bodies: not the world)."""
    what, counter = _KINDS[kind]
    count = int(getattr(model, counter))
    if not names:
        return list(range(1 if kind == mujoco.mjtObj.mjOBJ_BODY else 0, count))
    out = []
    for n in names:
        i = mujoco.mj_name2id(model, kind, n)
        if i < 0:
            known = [mujoco.mj_id2name(model, kind, k) or "" for k in range(count)]
            raise unknown_name(what, n, [k for k in known if k], f"randomization.{field}")
        out.append(i)
    return out


_ACTION, _OBSERVATION = 0, 1  # the noise streams of a step


class Randomizer:
    """A `Randomization` at work in one env: the draw at each reset, then the episode's
    action latency and noise and observation noise.

    Nothing of it is carried from step to step outside MuJoCo's state, so a state set with
    `mj_setState` (and the episode's draw, `use`) goes on as recorded: the actions on their
    way live in userdata (`bind_state`), and a step's noise is drawn from Philox, a
    counter-based generator, at the counter (step, stream) under the draw's `noise_seed`."""

    def __init__(
        self,
        description: Randomization,
        model: mujoco.MjModel,
        action_low: np.ndarray,
        action_high: np.ndarray,
        observation_keys: Sequence[str],
    ) -> None:
        description.check(model, observation_keys)
        self.description = description
        self._keys = list(observation_keys)
        self._model = model
        self._saved: Saved = []
        self._scratch = mujoco.MjData(model)
        self._low, self._high = action_low, action_high
        half = 0.5 * (action_high - action_low)
        self._half = np.where(np.isfinite(half), half, 1.0)
        self.draw = Draw()
        self._bits = np.random.Philox(key=0)
        self._noise = np.random.Generator(self._bits)
        self._position = self._bits.state  # its counter and key are set before each draw
        self._queue = np.zeros((0, len(action_low)))  # a view of userdata once bound
        self._noisy = np.empty(len(action_low))

    def bind_state(self, userdata: np.ndarray) -> None:
        """Keep the actions on their way in `userdata[:description.state_size(n)]` (n: the
        action's entries), which `mjSTATE_INTEGRATION` saves."""
        n = len(self._low)
        self._queue = userdata[: self.description.state_size(n)].reshape(-1, n)

    def restore(self, model: mujoco.MjModel) -> None:
        """The nominal model again (before a reset's initializers settle anything); a scene
        rebuilt since (`Scene.add_object`) is compiled afresh, nominal, and checked again."""
        if model is self._model:
            undo(self._saved, model, self._scratch)
        else:
            self.description.check(model, self._keys)
            self._model, self._scratch = model, mujoco.MjData(model)
        self._saved = []

    def reset(self, model: mujoco.MjModel, rng: np.random.Generator) -> Draw:
        """Draw this episode's values from `rng` and apply them to the nominal `model`."""
        self._apply(self.description.draw(model, rng), model)
        return self.draw

    def use(self, draw: Draw, model: mujoco.MjModel) -> None:
        """Make `draw` (a recorded episode's) the episode's: `model` nominal again with it
        applied, its latency and noise from now on. A draw this env cannot hold (a longer
        latency than its queue, noise on an observation it has not) is refused."""
        slots = len(self._queue)
        if draw.action_latency and draw.action_latency >= slots:
            raise SpecError(
                f"the draw's action_latency ({draw.action_latency} steps) is beyond this env's "
                f"randomization.action_latency {self.description.action_latency}"
            )
        for key in draw.observation_noise:
            if key not in self._keys:
                raise unknown_name("observation", key, self._keys, "the draw's observation_noise")
        self.restore(model)
        self._apply(draw, model)

    def _apply(self, draw: Draw, model: mujoco.MjModel) -> None:
        self.draw = draw
        self._saved = apply(draw, model, self._scratch)
        self._position["state"]["key"][:] = (draw.noise_seed, 0)

    def _place(self, stream: int, step: int) -> np.random.Generator:
        """The noise generator at (step, stream) of the episode: the same numbers whatever
        was drawn before (no per-step allocation: the state dict is reused)."""
        counter = self._position["state"]["counter"]
        counter[1], counter[2] = step, stream
        self._bits.state = self._position
        return self._noise

    def action(self, a: np.ndarray, step: int) -> np.ndarray:
        """The action applied at control step `step` of the episode: the one `action_latency`
        steps ago (the first action until then), with the episode's action noise, within the
        action's bounds."""
        lat = self.draw.action_latency
        if lat:
            queue = self._queue
            if step == 0:  # the episode's first action fills the way
                queue[: lat + 1] = a
            queue[step % (lat + 1)] = a
            a = queue[(step + 1) % (lat + 1)]  # written `lat` steps ago
        std = self.draw.action_noise
        if std > 0.0:
            noisy = self._noisy
            self._place(_ACTION, step).standard_normal(out=noisy)
            noisy *= std
            noisy *= self._half
            noisy += a
            np.clip(noisy, self._low, self._high, out=noisy)
            return noisy
        return a

    def observe(self, obs: dict[str, np.ndarray], step: int) -> dict[str, np.ndarray]:
        """What the agent sees of the observation after `step` control steps: `obs` with the
        episode's noise on the keys that have some."""
        noise = self.draw.observation_noise
        if not noise:
            return obs
        out = dict(obs)
        rng = self._place(_OBSERVATION, step)
        for key, std in noise.items():
            if key in out and std > 0.0:
                v = out[key]
                out[key] = (v + rng.normal(0.0, std, v.shape)).astype(v.dtype)
        return out
