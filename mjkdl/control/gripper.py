"""A gripper driven by one actuator: an action in [0, 1] in, a measured opening out."""

from __future__ import annotations

import mujoco
import numpy as np

from ..errors import SpecError, SpecTypeError
from ..scene import Scene
from ..validate import flag, real


class Gripper:
    """Opens and closes a gripper through its actuator's control value.

    `open` and `closed` are the actuator's control values at the two ends (the Panda hand's
    `actuator8`: 255 open, 0 closed; the Robotiq 2F-85's `fingers_actuator`: 0 open, 255
    closed). `command(a)` takes 0 for open and 1 for closed: with `binary`, `a < 0.5` opens
    and anything else closes; otherwise the control value is interpolated linearly.

    `opening()` is measured, not commanded: the actuator's transmission length (the finger
    tendon or joint, MuJoCo's `actuator_length`) mapped linearly so that the length the servo
    holds at `closed` reads 0 and at `open` reads 1, clipped to [0, 1]. Fingers stopped by an
    object read in between. The actuator must be a position servo (MuJoCo's affine bias
    `gain * ctrl - kp * length - kv * velocity`), as both Menagerie grippers are. On an
    actuator with a limited `ctrlrange`, `open` and `closed` must lie in it (MuJoCo clamps the
    control, so the servo would never hold an end outside it).
    """

    def __init__(
        self, scene: Scene, actuator: str, open: float, closed: float, binary: bool = True
    ) -> None:
        if not isinstance(scene, Scene):
            raise SpecTypeError(f"Gripper: scene must be a Scene or an Env, got {scene!r}")
        self._scene = scene
        self._name = actuator
        self._open = _finite(open, f"Gripper({actuator!r}).open")
        self._closed = _finite(closed, f"Gripper({actuator!r}).closed")
        if self._open == self._closed:
            raise SpecError(
                f"Gripper({actuator!r}): open and closed are the same control value "
                f"({self._open:g})"
            )
        self._binary = flag(binary, f"Gripper({actuator!r}).binary")
        self._model: mujoco.MjModel | None = None
        self._bind()

    def _bind(self) -> None:
        """Resolve the actuator in the scene's current model (again after a rebuild)."""
        scene = self._scene
        self._id = scene.actuator_id(self._name)
        model = scene.model
        self._model = model
        a = self._id
        gain, bias = model.actuator_gainprm[a], model.actuator_biasprm[a]
        servo = (
            int(model.actuator_gaintype[a]) == int(mujoco.mjtGain.mjGAIN_FIXED)
            and int(model.actuator_biastype[a]) == int(mujoco.mjtBias.mjBIAS_AFFINE)
            and bias[1] < 0
        )
        if not servo:
            raise SpecError(
                f"Gripper: actuator {self._name!r} is not a position servo (fixed gain, affine "
                "bias with a negative position term), so its opening cannot be measured"
            )
        if model.actuator_ctrllimited[a]:
            lo, hi = model.actuator_ctrlrange[a]
            for end, value in (("open", self._open), ("closed", self._closed)):
                if not lo <= value <= hi:
                    raise SpecError(
                        f"Gripper({self._name!r}).{end} must lie in the actuator's ctrlrange "
                        f"[{lo:g}, {hi:g}], got {value:g}"
                    )

        # Length the servo settles at for control value c: gain*c + bias0 + bias1*L = 0.
        def held(c: float) -> float:
            return float((gain[0] * c + bias[0]) / -bias[1])

        self._length_open = held(self._open)
        self._length_closed = held(self._closed)

    @property
    def actuator(self) -> str:
        """Name of the actuator this gripper drives."""
        return self._name

    @property
    def actuator_id(self) -> int:
        """MuJoCo id of the actuator this gripper drives (in the scene's current model)."""
        self._current()
        return self._id

    @property
    def length_range(self) -> tuple[float, float]:
        """(closed, open): the actuator lengths the servo settles at for the closed and open
        control values, which `opening()` maps onto 0 and 1."""
        self._current()
        return self._length_closed, self._length_open

    @property
    def binary(self) -> bool:
        """Whether actions snap to open/closed at 0.5."""
        return self._binary

    def _current(self) -> None:
        if self._scene.model is not self._model:
            self._bind()

    def command(self, a: float) -> float:
        """Apply action `a` in [0, 1] (0 open, 1 closed); return the control value written."""
        value = _finite(a, f"Gripper({self._name!r}).command(a)")
        if not 0.0 <= value <= 1.0:
            raise SpecError(f"Gripper({self._name!r}).command(a): a must be in [0, 1], got {a!r}")
        self._current()
        if self._binary:
            value = 0.0 if value < 0.5 else 1.0
        ctrl = self._open + value * (self._closed - self._open)
        self._scene.data.ctrl[self._id] = ctrl
        return ctrl

    def opening(self) -> float:
        """Measured opening, 1 fully open ... 0 closed (as of MuJoCo's last forward pass)."""
        self._current()
        length = float(self._scene.data.actuator_length[self._id])
        span = self._length_open - self._length_closed
        return min(1.0, max(0.0, (length - self._length_closed) / span))


def _finite(value: object, name: str) -> float:
    """A finite real scalar (Python or NumPy number, or a 0-d array) as a float."""
    if isinstance(value, np.ndarray) and value.shape == ():
        value = value[()]
    return real(value, name)
