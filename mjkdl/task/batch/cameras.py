"""The task's cameras for every world at once: MuJoCo Warp's batch renderer (ray tracing).

One render context holds every `CameraSensor` of the task; each read updates the cameras'
poses (`camlight`), refits the scene's bounding-volume hierarchy and renders all worlds.
Depth is the CPU env's (metres along the optical axis, the same geometry ray-traced); RGB
is shaded by MuJoCo Warp's own lighting model, not OpenGL's, so colours differ from the
CPU env's frames (docs/task.md, "Many worlds", gives the measured gap).
"""

from __future__ import annotations

from collections.abc import Sequence

import mujoco
import numpy as np
import torch

from ...names import model_id
from ..sensors import CameraReader
from ..spec import CameraSensor
from .engine import UnsupportedFeatureError
from .warp_engine import WarpEngine, warp_modules


class BatchCameras:
    """Every camera sensor of a task, rendered for all worlds: `{name}_rgb` (N, H, W, 3)
    uint8, `{name}_depth` (N, H, W) float32 metres, `{name}_intrinsics` (N, 3, 3).

    One context renders them all, so shadows are on for every camera when any sensor asks
    for them; reflections do not exist in MuJoCo Warp's renderer and are refused."""

    def __init__(
        self,
        cameras: Sequence[tuple[CameraSensor, CameraReader, str]],
        model: mujoco.MjModel,
        state: WarpEngine,
    ) -> None:
        wp, mjw = warp_modules()
        self._state = state
        ids: list[int] = []
        sizes: list[tuple[int, int]] = []
        depth: list[bool] = []
        self._outputs: list[tuple[str, str | None, int, int]] = []  # rgb key, depth key, h, w
        self._intrinsics: dict[str, torch.Tensor] = {}
        dev, n = state.device, state.nworld
        for sensor, reader, where in cameras:
            if sensor.reflections:
                raise UnsupportedFeatureError(
                    f"{where} (CameraSensor): reflections=True; MuJoCo Warp's renderer draws "
                    "no reflections. Set reflections=False or use the CPU env"
                )
            cam = model_id(model, mujoco.mjtObj.mjOBJ_CAMERA, "camera", sensor.camera, where)
            if cam in ids:
                raise UnsupportedFeatureError(
                    f"{where} (CameraSensor): camera {sensor.camera!r} is observed twice; the "
                    "batched renderer draws each camera once. Observe it once or use the CPU env"
                )
            keys = list(reader.buffers)
            rgb_key = next(k for k in keys if k.endswith("_rgb"))
            depth_key = next((k for k in keys if k.endswith("_depth")), None)
            k_key = next(k for k in keys if k.endswith("_intrinsics"))
            h, w = reader.buffers[rgb_key].shape[:2]
            ids.append(cam)
            sizes.append((w, h))
            depth.append(depth_key is not None)
            self._outputs.append((rgb_key, depth_key, h, w))
            k = torch.as_tensor(np.array(reader.buffers[k_key]), device=dev, dtype=torch.float32)
            self._intrinsics[k_key] = k.expand(n, 3, 3)
        self._shadows = any(sensor.shadows for sensor, _, _ in cameras)
        with wp.ScopedDevice(wp.get_device(dev)):
            self._context = mjw.create_render_context(
                model,
                nworld=n,
                cam_res=sizes,
                render_rgb=[True] * len(ids),
                render_depth=depth,
                cam_active=ids,
                use_shadows=self._shadows,
                # Of MuJoCo Warp's shading options these come closest to the CPU env's OpenGL
                # frames (PickCube's front and wrist cameras, mean absolute difference in
                # levels: defaults 27 and 65; no specular 27 and 49; no ambient 21 and 52;
                # neither 21 and 35).
                enable_specular=False,
                use_ambient_lighting=False,
            )
        rc = self._context
        self._rgb_adr = [int(a) for a in rc.rgb_adr.numpy()]
        self._depth_adr = [int(a) for a in rc.depth_adr.numpy()]
        # The packed colour words as bytes: [b, g, r, a] per pixel (little-endian uint32).
        self._packed = wp.to_torch(rc.rgb_data).view(torch.uint8).reshape(n, -1, 4)
        self._depth_data = wp.to_torch(rc.depth_data)

    def read(self) -> dict[str, torch.Tensor]:
        """Render the worlds' current state; every camera's observations, by name."""
        _, mjw = warp_modules()
        s = self._state
        with s.warp():
            mjw.camlight(s.model, s.data)  # the cameras' poses of this state
            mjw.refit_bvh(s.model, s.data, self._context)
            mjw.render(s.model, s.data, self._context)
        out: dict[str, torch.Tensor] = {}
        n = s.nworld
        for i, (rgb_key, depth_key, h, w) in enumerate(self._outputs):
            a = self._rgb_adr[i]
            pixels = self._packed[:, a : a + h * w]
            out[rgb_key] = pixels[..., [2, 1, 0]].reshape(n, h, w, 3)
            if depth_key is not None:
                d = self._depth_adr[i]
                out[depth_key] = self._depth_data[:, d : d + h * w].reshape(n, h, w).clone()
        for key, k in self._intrinsics.items():
            out[key] = k.clone()
        return out


def image_bytes(readers: Sequence[object], model: mujoco.MjModel) -> int:
    """Bytes per world the camera sensors among `readers` take on the device: MuJoCo Warp's
    packed colour (4 per pixel) and depth (4) buffers, the observations read from them (3
    and 4), and the scene hierarchy's bounds per geom (28); 0 without cameras."""
    total = 0
    for reader in readers:
        if isinstance(reader, CameraReader):
            for key, buf in reader.buffers.items():
                if key.endswith(("_rgb", "_depth")):
                    h, w = buf.shape[:2]
                    total += h * w * (7 if key.endswith("_rgb") else 8)
    return total + 28 * model.ngeom if total else 0
