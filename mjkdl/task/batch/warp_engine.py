"""The MuJoCo Warp engine: many worlds on a GPU (or Warp's CPU device, to test kernels).

The tensors share memory with Warp's arrays (`wp.to_torch`, zero-copy on either device), so
writing a row of `qpos` or `ctrl` writes the world's state. float32, as MuJoCo Warp is.
"""

from __future__ import annotations

import copy
import warnings
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from typing import Any

import mujoco
import numpy as np
import torch

from .engine import Engine, Tcp, UnsupportedFeatureError


def warp_modules() -> tuple[Any, Any]:
    """(`warp`, `mujoco_warp`), imported on first use (the `warp` extra). Warp logs warnings only
    unless `MJKDL_WARP_VERBOSE` is set: it otherwise prints a line per kernel module loaded."""
    import os

    import mujoco_warp
    import warp

    if not os.environ.get("MJKDL_WARP_VERBOSE"):
        warp.config.log_level = warp.LOG_WARNING
    return warp, mujoco_warp


def warp_model(model: mujoco.MjModel, per_world: Sequence[str] = (), nworld: int = 1) -> Any:
    """`model` put on Warp's current device, the fields `per_world` ('opt.gravity' too) with
    one row per world of `nworld`; what MuJoCo Warp cannot run is named.

    MuJoCo's own auto-reset of a diverging world (which mjkdl turns off, to report divergence)
    does not exist in MuJoCo Warp: the flag is cleared on a copy and divergence is checked per
    world instead.
    """
    _, mjw = warp_modules()
    m = copy.copy(model)
    m.opt.disableflags &= ~int(mujoco.mjtDisableBit.mjDSBL_AUTORESET)
    wp, _ = warp_modules()
    batched = {name: nworld for name in per_world if name != "opt.gravity"}
    try:
        out = mjw.put_model(m, batch_sizes=batched)
        if "opt.gravity" in per_world:  # MuJoCo Warp's kernels index it by world too
            out.opt.gravity = wp.array(np.tile(m.opt.gravity, (nworld, 1)), dtype=wp.vec3)
        out.opt.warn_overflow = 0  # its kernels' prints; the batch reports such worlds
        return out
    except (NotImplementedError, ValueError) as err:
        raise UnsupportedFeatureError(
            f"MuJoCo Warp 4.0 cannot run this scene: {err} Use the CPU env (TaskEnv), or "
            "change the scene to avoid the feature"
        ) from None


class WarpEngine(Engine):
    """`nworld` copies of the host `data` on a Warp device, and torch views of its arrays."""

    name = "warp"

    def __init__(
        self,
        model: mujoco.MjModel,
        data: mujoco.MjData,
        nworld: int,
        device: str,
        nconmax: int | None = None,
        njmax: int | None = None,
        per_world: Sequence[str] = (),
    ) -> None:
        wp, mjw = warp_modules()
        self.device, self.nworld, self.dtype = device, nworld, torch.float32
        self._wp_device = wp.get_device(device)
        self._mjw = mjw
        with wp.ScopedDevice(self._wp_device):
            self.model = warp_model(model, per_world, nworld)
            self.data = mjw.put_data(model, data, nworld=nworld, nconmax=nconmax, njmax=njmax)
            wp.synchronize_device()  # the uploads are done before torch reads the arrays
        d = self.data
        t = wp.to_torch
        self.time = t(d.time)
        self.qpos, self.qvel, self.ctrl, self.act = t(d.qpos), t(d.qvel), t(d.ctrl), t(d.act)
        self.qacc_warmstart = t(d.qacc_warmstart)
        self.mocap_pos, self.mocap_quat = t(d.mocap_pos), t(d.mocap_quat)
        self.xpos, self.xquat, self.xmat, self.xipos = t(d.xpos), t(d.xquat), t(d.xmat), t(d.xipos)
        self.xanchor, self.xaxis = t(d.xanchor), t(d.xaxis)
        self.site_xpos, self.site_xmat = t(d.site_xpos), t(d.site_xmat)
        self.cvel, self.subtree_com = t(d.cvel), t(d.subtree_com)
        self.actuator_length, self.qfrc_actuator = t(d.actuator_length), t(d.qfrc_actuator)
        self.sensordata = t(d.sensordata)
        self.nacon = t(d.nacon)
        self.contact_geom = t(d.contact.geom)
        self.contact_dist = t(d.contact.dist)
        self.contact_world = t(d.contact.worldid)
        self.naconmax = int(d.naconmax)
        self.njmax, self.nconmax = int(d.njmax), int(d.naconmax) // nworld
        self.overflow = t(d.overflow)
        # Overflows of a buffer: MuJoCo Warp drops what does not fit and goes on. (Solver
        # iteration limits are not among them: the step is still the physics.)
        kinds = mjw.OverflowType
        self._room = int(kinds.ALL) & ~int(kinds.ITERATIONS) & ~int(kinds.LS_ITERATIONS)
        self.root = torch.as_tensor(model.body_rootid, device=device)
        self.tcps: dict[str, Tcp] = {}  # the arms' TCPs, by arm name
        # Warp runs on its own stream; torch's work on the same arrays is ordered around it.
        self._warp_stream = (
            wp.stream_to_torch(wp.get_stream(self._wp_device)) if self._wp_device.is_cuda else None
        )
        self._graphs: dict[int, Any] = {}  # captured physics of a control period, by substeps
        self._stepped: set[int] = set()  # substep counts run once eagerly (kernels loaded)
        self._capture = True

    @property
    def captured(self) -> bool:
        """Whether the physics now replays as a captured graph (from the second step on)."""
        return bool(self._graphs)

    @contextmanager
    def warp(self) -> Iterator[None]:
        """Warp's device for the launches inside; on a GPU, the launches wait for the torch work
        queued before and torch's later work waits for them (Warp has its own stream)."""
        wp, _ = warp_modules()
        with wp.ScopedDevice(self._wp_device):
            if self._warp_stream is None:
                yield
                return
            torch_stream = torch.cuda.current_stream(self._warp_stream.device)
            self._warp_stream.wait_stream(torch_stream)
            try:
                yield
            finally:
                torch_stream.wait_stream(self._warp_stream)

    def forward(self, rows: torch.Tensor) -> None:
        """`mj_forward` on every world (MuJoCo Warp runs all or none); the worlds not in `rows`
        get their solver warm start back, so a world mid-episode steps on as if this had not
        run."""
        keep = ~rows
        saved = self.qacc_warmstart.clone()
        with self.warp():
            self._mjw.forward(self.model, self.data)
        self.qacc_warmstart[keep] = saved[keep]

    def step(self, substeps: int, meanwhile: Callable[[], None] | None = None) -> None:
        """`substeps` physics steps of every world, then poses and velocities of the new state
        (the CPU env's refresh after `mj_step`; forces stay those of the last step). On a GPU
        a replayed graph returns once it is queued, and `meanwhile` runs after that.

        The first call runs Warp's launches one by one (loading the kernels); later calls
        replay them as one captured graph, the same launches on the same arrays without
        Python's cost per launch (on the CPU device too: ~9x for PickCube's 50 substeps).
        """
        wp, _ = warp_modules()
        with self.warp():
            graph = self._graphs.get(substeps)
            if graph is not None:
                wp.capture_launch(graph)
            elif substeps in self._stepped and self._capture:
                try:
                    # The first call loaded every kernel the step uses.
                    with wp.ScopedCapture(force_module_load=False) as capture:
                        self._physics(substeps)
                except Exception as err:  # a capture failure costs speed, never the run
                    self._capture = False
                    warnings.warn(
                        f"MuJoCo Warp's step could not be captured as a graph ({err}); "
                        "launching its kernels one by one",
                        stacklevel=3,
                    )
                    self._physics(substeps)
                else:
                    self._graphs[substeps] = capture.graph
                    wp.capture_launch(capture.graph)
            else:
                self._physics(substeps)
                self._stepped.add(substeps)
        if meanwhile is not None:
            meanwhile()

    def set_model(self, ids: np.ndarray, values: Mapping[str, np.ndarray]) -> None:
        """Into the model's arrays with one row per world (`per_world`, made at the start),
        in float32; the constants are taken as given (MuJoCo's float64 `mj_setConst` of the
        host's reset), not recomputed."""
        wp, _ = warp_modules()
        idx = torch.as_tensor(ids, device=self.device, dtype=torch.long)
        with self.warp():
            for name, rows in values.items():
                array = (
                    self.model.opt.gravity if name == "opt.gravity" else getattr(self.model, name)
                )
                view = wp.to_torch(array)
                value = torch.as_tensor(rows, device=self.device, dtype=view.dtype)
                view[idx] = value.reshape((len(ids), *view.shape[1:]))

    def failed(self) -> torch.Tensor:
        """(N,) bool: the worlds that overflowed one of MuJoCo Warp's buffers since their last
        reset (their constraint rows; the contact pool, which flags every world; ...): MuJoCo
        Warp dropped what did not fit, so their physics is wrong."""
        return (self.overflow & self._room) != 0

    def clear(self, rows: torch.Tensor) -> None:
        self.overflow[rows] = 0

    def failure_message(self, rows: torch.Tensor) -> str:
        """What overflowed in the worlds `rows` (a bool mask), and the fix."""
        _, mjw = warp_modules()
        worlds = torch.nonzero(rows).flatten()
        w = int(worlds[0])
        bits = int(self.overflow[w]) & self._room
        names = [k.name for k in mjw.OverflowType if k.value and k.value & (k.value - 1) == 0]
        which = [str(n) for n in names if bits & int(mjw.OverflowType[n])]
        return (
            f"MuJoCo Warp ran out of room in {len(worlds)} of {self.nworld} worlds (world {w}: "
            f"{', '.join(which)}) and dropped contacts or constraints; those worlds' episodes "
            f"end as diverged. Pass make_batch a larger njmax (constraint rows per world, now "
            f"{self.njmax}) or nconmax (contacts per world, pooled over the worlds, now "
            f"{self.nconmax})"
        )

    def _physics(self, substeps: int) -> None:
        _, mjw = warp_modules()
        for _ in range(substeps):
            mjw.step(self.model, self.data)
        for stage in (mjw.kinematics, mjw.com_pos, mjw.tendon, mjw.transmission, mjw.com_vel):
            stage(self.model, self.data)

    def contacts(
        self, body: int | None = None, others: Sequence[int] = ()
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """(world, geom1, geom2) of every world's contacts at zero or negative distance."""
        n = min(int(self.nacon[0]), self.naconmax)
        touching = self.contact_dist[:n] <= 0.0
        geom = self.contact_geom[:n][touching]
        return self.contact_world[:n][touching], geom[:, 0], geom[:, 1]


def world_bytes(
    model: Any, data: Any, device: str, nconmax: int | None, njmax: int | None
) -> tuple[int, int]:
    """(bytes per world, bytes shared) of MuJoCo Warp's data, measured from a one- and a
    two-world allocation (small: made and freed before the real one)."""
    wp, mjw = warp_modules()
    sizes = []
    with wp.ScopedDevice(wp.get_device(device)):
        warp_model(model)  # fails first, with the feature named, on an unsupported scene
        for n in (1, 2):
            d = mjw.put_data(model, data, nworld=n, nconmax=nconmax, njmax=njmax)
            sizes.append(_nbytes(d))
            del d
    return sizes[1] - sizes[0], 2 * sizes[0] - sizes[1]


def _nbytes(obj: Any, seen: set[int] | None = None) -> int:
    wp, _ = warp_modules()
    seen = set() if seen is None else seen
    total = 0
    for value in vars(obj).values():
        if id(value) in seen:
            continue
        seen.add(id(value))
        if isinstance(value, wp.array):
            total += int(value.capacity)
        elif hasattr(value, "__dataclass_fields__"):
            total += _nbytes(value, seen)
    return total
