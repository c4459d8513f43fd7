"""MuJoCo Warp's model and data for many worlds, with torch views of the arrays tasks read.

The views share memory with Warp's arrays (`wp.to_torch`, zero-copy on either device), so
writing a row of `qpos` or `ctrl` writes the world's state. float32, as MuJoCo Warp is.
"""

from __future__ import annotations

import copy
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np
import torch

from ..errors import MjkdlError


class UnsupportedFeatureError(MjkdlError, NotImplementedError):
    """The scene uses a MuJoCo feature that MuJoCo Warp does not implement."""


@dataclass(frozen=True)
class Tcp:
    """Where an arm's TCP is: its reference frame (site or body), the body that carries it,
    and the tool's offset from that frame (as `ArmReader` computes it)."""

    site: int
    """The reference site, or -1 for the tip body."""
    body: int
    """The body carrying the frame (the tip body, or the site's body)."""
    offset: torch.Tensor
    """(3,) TCP position in the reference frame."""
    rotation: torch.Tensor
    """(3, 3) TCP orientation in the reference frame."""


def warp_modules() -> tuple[Any, Any]:
    """(`warp`, `mujoco_warp`), imported on first use (the `warp` extra). Warp logs warnings only
    unless `MJKDL_WARP_VERBOSE` is set: it otherwise prints a line per kernel module loaded."""
    import os

    import mujoco_warp
    import warp

    if not os.environ.get("MJKDL_WARP_VERBOSE"):
        warp.config.log_level = warp.LOG_WARNING
    return warp, mujoco_warp


def warp_model(model: mujoco.MjModel) -> Any:
    """`model` put on Warp's current device; what MuJoCo Warp cannot run is named.

    MuJoCo's own auto-reset of a diverging world (which mjkdl turns off, to report divergence)
    does not exist in MuJoCo Warp: the flag is cleared on a copy and divergence is checked per
    world instead.
    """
    _, mjw = warp_modules()
    m = copy.copy(model)
    m.opt.disableflags &= ~int(mujoco.mjtDisableBit.mjDSBL_AUTORESET)
    try:
        out = mjw.put_model(m)
        out.opt.warn_overflow = 0  # its kernels' prints; the batch reports such worlds
        return out
    except (NotImplementedError, ValueError) as err:
        raise UnsupportedFeatureError(
            f"MuJoCo Warp 4.0 cannot run this scene: {err} Use the CPU env (TaskEnv), or "
            "change the scene to avoid the feature"
        ) from None


class DeviceState:
    """`nworld` copies of the host `data` on a Warp device, and torch views of its arrays."""

    def __init__(
        self,
        model: mujoco.MjModel,
        data: mujoco.MjData,
        nworld: int,
        device: str,
        nconmax: int | None = None,
        njmax: int | None = None,
    ) -> None:
        wp, mjw = warp_modules()
        self.device, self.nworld = device, nworld
        self._wp_device = wp.get_device(device)
        self._mjw = mjw
        with wp.ScopedDevice(self._wp_device):
            self.model = warp_model(model)
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

    def tcp_of(self, arm: str) -> Tcp:
        """The TCP of arm `arm` (registered by the observer)."""
        return self.tcps[arm]

    def forward(self, keep: torch.Tensor | None = None) -> None:
        """`mj_forward` on every world; worlds where `keep` is true get their solver warm start
        back, so a world mid-episode steps on as if this had not run."""
        saved = None if keep is None else self.qacc_warmstart.clone()
        with self.warp():
            self._mjw.forward(self.model, self.data)
        if saved is not None and keep is not None:
            self.qacc_warmstart[keep] = saved[keep]

    def step(self, substeps: int) -> None:
        """`substeps` physics steps of every world, then poses and velocities of the new state
        (the CPU env's refresh after `mj_step`; forces stay those of the last step). On a GPU
        a replayed graph returns once it is queued.

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

    def overflowed(self) -> torch.Tensor:
        """(N,) bool: the worlds that overflowed one of MuJoCo Warp's buffers since their last
        reset (their constraint rows; the contact pool, which flags every world; ...): MuJoCo
        Warp dropped what did not fit, so their physics is wrong."""
        return (self.overflow & self._room) != 0

    def overflow_message(self, rows: torch.Tensor) -> str:
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

    # ------------------------------------------------------------------ TCP quantities

    def frame_pos(self, tcp: Tcp) -> tuple[torch.Tensor, torch.Tensor]:
        """(N, 3) position and (N, 3, 3) rotation of the TCP's reference frame."""
        if tcp.site >= 0:
            return self.site_xpos[:, tcp.site], self.site_xmat[:, tcp.site]
        return self.xpos[:, tcp.body], self.xmat[:, tcp.body]

    def tcp_pos(self, tcp: Tcp) -> torch.Tensor:
        """(N, 3) TCP position: reference frame * offset."""
        pos, rot = self.frame_pos(tcp)
        return pos + (rot @ tcp.offset)

    def tcp_rot(self, tcp: Tcp) -> torch.Tensor:
        _, rot = self.frame_pos(tcp)
        return rot @ tcp.rotation

    def tcp_vel(self, tcp: Tcp) -> torch.Tensor:
        """(N, 6) [v, w] of the TCP point, world axes: MuJoCo's `cvel` (at the root's
        subtree centre of mass) moved to the TCP."""
        cvel = self.cvel[:, tcp.body]
        w, v = cvel[:, :3], cvel[:, 3:]
        com = self.subtree_com[:, self.root[tcp.body]]
        lin = v + torch.linalg.cross(w, self.tcp_pos(tcp) - com, dim=-1)
        return torch.cat([lin, w], dim=1)

    def contacts(self) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """(world, geom1, geom2) of the current contacts at zero or negative distance."""
        n = min(int(self.nacon[0]), self.naconmax)
        touching = self.contact_dist[:n] <= 0.0
        geom = self.contact_geom[:n][touching]
        return self.contact_world[:n][touching], geom[:, 0], geom[:, 1]


def mat_to_quat(mat: torch.Tensor) -> torch.Tensor:
    """(N, 3, 3) rotations to (N, 4) quaternions [w, x, y, z] with MuJoCo's `mju_mat2Quat`
    branches, so the sign matches the CPU env's."""
    m = mat.reshape(-1, 9)
    m00, m01, m02, m10, m11, m12, m20, m21, m22 = m.unbind(1)
    tr = m00 + m11 + m22
    one = torch.ones_like(tr)

    def q(a: torch.Tensor, b: torch.Tensor, c: torch.Tensor, d: torch.Tensor) -> torch.Tensor:
        return torch.stack([a, b, c, d], 1)

    s0 = 0.5 * torch.sqrt(torch.clamp(tr + 1, min=1e-12))
    q0 = q(s0, (m21 - m12) / (4 * s0), (m02 - m20) / (4 * s0), (m10 - m01) / (4 * s0))
    s1 = 0.5 * torch.sqrt(torch.clamp(one + m00 - m11 - m22, min=1e-12))
    q1 = q((m21 - m12) / (4 * s1), s1, (m01 + m10) / (4 * s1), (m02 + m20) / (4 * s1))
    s2 = 0.5 * torch.sqrt(torch.clamp(one - m00 + m11 - m22, min=1e-12))
    q2 = q((m02 - m20) / (4 * s2), (m01 + m10) / (4 * s2), s2, (m12 + m21) / (4 * s2))
    s3 = 0.5 * torch.sqrt(torch.clamp(one - m00 - m11 + m22, min=1e-12))
    q3 = q((m10 - m01) / (4 * s3), (m02 + m20) / (4 * s3), (m12 + m21) / (4 * s3), s3)
    out = torch.where(
        (tr > 0).unsqueeze(1),
        q0,
        torch.where(
            ((m00 > m11) & (m00 > m22)).unsqueeze(1),
            q1,
            torch.where((m11 > m22).unsqueeze(1), q2, q3),
        ),
    )
    return out / torch.linalg.norm(out, dim=1, keepdim=True)


def as_numpy(value: Any) -> np.ndarray:
    """A host NumPy copy of a tensor (float64 for floats), for the task's host callables."""
    arr = value.detach().cpu().numpy()
    return arr.astype(np.float64) if arr.dtype.kind == "f" else arr
