"""The model library served to libfranka 0.9 clients, loaded as libfranka loads it (dlopen, the
31 C functions of `libfcimodels.h`), against MuJoCo on the same compiled model."""

from __future__ import annotations

import ctypes
import platform
import shutil
from collections.abc import Iterator
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from mjkdl.hw.franka_sim.arm import SimulatedArm
from mjkdl.hw.franka_sim.limits import PANDA
from mjkdl.hw.franka_sim.model_library import (
    ModelLibraryError,
    compile_model_library,
    model_library,
)
from mjkdl.hw.franka_sim.scene import FLANGE_OFFSET, franka_scene

_D = ctypes.POINTER(ctypes.c_double)
needs_cc = pytest.mark.skipif(
    shutil.which("cc") is None and shutil.which("gcc") is None,
    reason="the model library compiles with a C compiler (apt-get install gcc)",
)
_ARCH = {"x86_64": 0, "amd64": 0, "aarch64": 3, "arm64": 3}


def _p(values: np.ndarray) -> ctypes._Pointer:
    return np.ascontiguousarray(values, dtype=float).ctypes.data_as(_D)


class Library:
    """The compiled library called as libfranka's `Model` calls it (column-major arrays)."""

    def __init__(self, path: Path) -> None:
        self.lib = ctypes.CDLL(str(path))

    def pose(self, k: int, q: np.ndarray, F_T_EE: np.ndarray) -> np.ndarray:
        out = np.zeros(16)
        args = (_p(q), _p(F_T_EE.flatten(order="F"))) if k == 9 else (_p(q),)
        getattr(self.lib, f"O_T_J{k}")(*args, out.ctypes.data_as(_D))
        return out.reshape(4, 4, order="F")

    def jacobian(self, name: str, k: int, q: np.ndarray, F_T_EE: np.ndarray) -> np.ndarray:
        out = np.zeros(42)
        args: tuple = ()
        if k > 1:
            args = (_p(q), _p(F_T_EE.flatten(order="F"))) if k == 9 else (_p(q),)
        getattr(self.lib, f"{name}{k}")(*args, out.ctypes.data_as(_D))
        return out.reshape(6, 7, order="F")

    def mass(self, q, I_total, m_total, F_x_Ctotal) -> np.ndarray:
        out = np.zeros(49)
        self.lib.M_NE(
            _p(q), _p(I_total), ctypes.c_double(m_total), _p(F_x_Ctotal), out.ctypes.data_as(_D)
        )
        return out.reshape(7, 7, order="F")

    def coriolis(self, q, dq, I_total, m_total, F_x_Ctotal) -> np.ndarray:
        out = np.zeros(7)
        self.lib.c_NE(
            _p(q),
            _p(dq),
            _p(I_total),
            ctypes.c_double(m_total),
            _p(F_x_Ctotal),
            out.ctypes.data_as(_D),
        )
        return out

    def gravity(self, q, g_earth, m_total, F_x_Ctotal) -> np.ndarray:
        out = np.zeros(7)
        self.lib.g_NE(
            _p(q), _p(g_earth), ctypes.c_double(m_total), _p(F_x_Ctotal), out.ctypes.data_as(_D)
        )
        return out


@pytest.fixture(scope="module")
def arm() -> Iterator[SimulatedArm]:
    arm = SimulatedArm(franka_scene(), PANDA)
    yield arm
    arm.env.close()


@pytest.fixture(scope="module")
def library(arm, tmp_path_factory) -> Library:
    return Library(compile_model_library(arm.urdf, tmp_path_factory.mktemp("models")))


def _configurations(n: int) -> np.ndarray:
    rng = np.random.default_rng(7)
    return PANDA.q_min + rng.random((n, 7)) * (PANDA.q_max - PANDA.q_min)


@needs_cc
def test_dynamics_equal_mujocos_with_the_hand_as_the_robot_reports_it(arm, library):
    """The hand goes in as libfranka passes it (m_total, F_x_Ctotal, I_total from the state);
    MuJoCo simulates it as bodies: the mass matrix (without the rotors' armature, which the
    rigid-body model has not), C(q, dq) dq and gravity agree at random configurations."""
    m, d = arm.env.model, arm.env.data
    dofs, h = arm._dofs, arm.hand
    rng = np.random.default_rng(3)
    for q in _configurations(4):
        arm.robot.set_joint_pos(q)
        full = np.zeros((m.nv, m.nv))
        mujoco.mj_fullM(m, d, full)
        mass = full[np.ix_(dofs, dofs)] - np.diag(m.dof_armature[dofs])
        got = library.mass(q, h.I_ee, h.m_ee, h.F_x_Cee)
        np.testing.assert_allclose(got, mass, atol=1e-9)
        gravity = d.qfrc_bias[dofs].copy()
        got_g = library.gravity(q, np.array([0.0, 0.0, -9.81]), h.m_ee, h.F_x_Cee)
        np.testing.assert_allclose(got_g, gravity, atol=1e-9)
        dq = rng.normal(size=7)
        d.qvel[dofs] = dq
        mujoco.mj_forward(m, d)
        coriolis = d.qfrc_bias[dofs] - gravity
        d.qvel[:] = 0.0
        got_c = library.coriolis(q, dq, h.I_ee, h.m_ee, h.F_x_Cee)
        np.testing.assert_allclose(got_c, coriolis, atol=1e-9)


@needs_cc
def test_poses_and_jacobians_equal_mujocos(arm, library):
    """O_T_J1..7 are the links' frames in link0's, 8 the flange, 9 the end effector F_T_EE from
    the flange; zero Jacobians world-aligned at the frame's origin, body Jacobians in it."""
    m, d = arm.env.model, arm.env.data
    base = m.body("link0").id
    F_T_EE = np.linalg.inv(arm._tcp_of_flange)  # the hand's TCP
    for q in _configurations(3):
        arm.robot.set_joint_pos(q)
        r0 = d.xmat[base].reshape(3, 3)
        for k in range(1, 10):
            b = m.body(f"link{min(k, 7)}").id
            expected = np.eye(4)
            expected[:3, :3] = r0.T @ d.xmat[b].reshape(3, 3)
            expected[:3, 3] = r0.T @ (d.xpos[b] - d.xpos[base])
            if k >= 8:  # the flange: 0.107 m along link 7's z
                expected[:3, 3] += expected[:3, 2] * FLANGE_OFFSET
            if k == 9:
                expected = expected @ F_T_EE
            np.testing.assert_allclose(library.pose(k, q, F_T_EE), expected, atol=1e-9)
            jp, jr = np.zeros((3, m.nv)), np.zeros((3, m.nv))
            mujoco.mj_jac(m, d, jp, jr, r0 @ expected[:3, 3] + d.xpos[base], b)
            zero = np.vstack([r0.T @ jp[:, arm._dofs], r0.T @ jr[:, arm._dofs]])
            np.testing.assert_allclose(
                library.jacobian("O_J_J", k, q, F_T_EE), zero, atol=1e-9, err_msg=f"frame {k}"
            )
            rot = expected[:3, :3]
            body = np.vstack([rot.T @ zero[:3], rot.T @ zero[3:]])
            np.testing.assert_allclose(
                library.jacobian("Ji_J_J", k, q, F_T_EE), body, atol=1e-9, err_msg=f"frame {k}"
            )
    # the EE frame agrees with what the server reports as O_T_EE
    np.testing.assert_allclose(library.pose(9, q, F_T_EE), arm._ee_pose(q), atol=1e-9)


@needs_cc
def test_a_load_on_the_flange_is_a_rigid_body_there(arm, library):
    """m, F_x_C, I (about the centre of mass, flange axes) ride on the flange: Pinocchio's model
    of the same URDF with that inertia appended to link 7 gives the same dynamics."""
    model = pin.buildModelFromXML(arm.urdf)
    flange = model.frames[model.getFrameId("link8")].placement
    load_m, load_c = 1.3, np.array([0.01, -0.02, 0.08])
    load_i = np.array([[0.02, 0.001, 0.0], [0.001, 0.03, -0.002], [0.0, -0.002, 0.01]])
    model.inertias[7] = model.inertias[7] + flange.act(pin.Inertia(load_m, load_c, load_i))
    data = model.createData()
    rng = np.random.default_rng(5)
    for q in _configurations(2):
        dq = rng.normal(size=7)
        mass = pin.crba(model, data, q)
        mass = np.triu(mass) + np.triu(mass, 1).T
        gravity = pin.computeGeneralizedGravity(model, data, q)
        coriolis = pin.rnea(model, data, q, dq, np.zeros(7)) - gravity
        I_col = load_i.flatten(order="F")
        np.testing.assert_allclose(library.mass(q, I_col, load_m, load_c), mass, atol=1e-9)
        np.testing.assert_allclose(
            library.coriolis(q, dq, I_col, load_m, load_c), coriolis, atol=1e-9
        )
        got = library.gravity(q, np.array([0.0, 0.0, -9.81]), load_m, load_c)
        np.testing.assert_allclose(got, gravity, atol=1e-9)


@needs_cc
def test_the_library_is_compiled_once_then_taken_from_the_cache(arm, tmp_path, monkeypatch):
    first = compile_model_library(arm.urdf, tmp_path)
    assert first.parent == tmp_path and first.name.startswith("libfcimodels-")
    monkeypatch.setenv("CC", "no-such-compiler")  # a second build would fail
    assert compile_model_library(arm.urdf, tmp_path) == first
    assert sorted(p.name for p in tmp_path.iterdir()) == [first.name]


def test_no_c_compiler_names_the_fix(arm, tmp_path, monkeypatch):
    monkeypatch.setenv("CC", "no-such-compiler")
    with pytest.raises(
        ModelLibraryError,
        match=r"no C compiler was found \(looked for "
        r"CC='no-such-compiler'\): install one .*apt-get install gcc",
    ):
        compile_model_library(arm.urdf, tmp_path)


def test_a_client_of_another_architecture_is_told_which_the_simulator_builds(arm, monkeypatch):
    monkeypatch.setenv("MJKDL_CACHE_DIR", "/nonexistent-never-written")
    other = 3 if _ARCH.get(platform.machine().lower()) == 0 else 0
    with pytest.raises(
        ModelLibraryError,
        match=r"asked for a model library for linux on "
        r".*: run the client on the simulator's kind of machine",
    ):
        model_library(arm.urdf, other, 0)
    with pytest.raises(ModelLibraryError, match="for windows on"):
        model_library(arm.urdf, _ARCH.get(platform.machine().lower(), 0), 1)
