"""The "real" arm the simulator can serve: Gaz et al.'s identified joint friction, noise and
latency of the measured state, from a preset or a JSON file, refused by field when wrong."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import mujoco
import numpy as np
import pytest
from conftest import franka_sim

from mjkdl.errors import SpecError, UnknownNameError
from mjkdl.hw.franka_sim import wire
from mjkdl.hw.franka_sim.arm import SimulatedArm
from mjkdl.hw.franka_sim.limits import PANDA
from mjkdl.hw.franka_sim.reality import GAZ2019_FRICTION, REALITIES, Reality, reality_from
from mjkdl.hw.franka_sim.scene import franka_scene


def test_the_identified_friction_is_gaz_et_al_s_model() -> None:
    f = GAZ2019_FRICTION
    np.testing.assert_array_equal(f.torque(np.zeros(7)), np.zeros(7))  # none at rest
    dq = np.full(7, 0.5)
    tau = f.torque(dq)
    # joint 4: phi1 = 1.2794 N·m, phi2 = 5.5903 s/rad, phi3 = 0.036194 rad/s
    expected = 1.2794 / (1 + np.exp(-5.5903 * (0.5 + 0.036194))) - 1.2794 / (
        1 + np.exp(-5.5903 * 0.036194)
    )
    assert tau[3] == pytest.approx(expected, rel=1e-12)
    assert tau[3] == pytest.approx(0.5144, abs=1e-4)  # N·m at 0.5 rad/s
    assert np.all(tau > 0) and np.all(f.torque(-dq) < 0)  # it opposes the motion


def _arm(reality: Reality | None) -> SimulatedArm:
    arm = SimulatedArm(franka_scene("empty"), PANDA, reality)
    m, d = arm.env.model, arm.env.data
    d.qvel[[m.jnt_dofadr[m.joint(f"joint{i}").id] for i in range(1, 8)]] = 0.4
    arm.robot.update()
    return arm


def test_the_joints_lose_the_friction_torque_and_the_sensor_reads_the_command() -> None:
    plain, real = _arm(None), _arm(REALITIES["panda-gaz2019"])
    try:
        dq = real.dq.copy()
        np.testing.assert_array_equal(dq, plain.dq)
        plain.step(None)
        real.step(None)
        applied = real.robot.jnt_trq_cmd - plain.robot.jnt_trq_cmd
        np.testing.assert_allclose(applied, -GAZ2019_FRICTION.torque(dq), atol=1e-12)
        np.testing.assert_array_equal(real.tau_J, plain.tau_J)  # link-side sensor: the command
        plain.step(None)  # (the measured state of the next cycle)
        real.step(None)
        assert real.dq[3] < plain.dq[3] - 1e-4  # the friction brakes the joint
    finally:
        plain.env.close()
        real.env.close()


def test_the_client_reads_the_state_late_and_noisy() -> None:
    arm = _arm(Reality(name="lagging", state_latency=3))
    noisy = _arm(Reality(name="noisy", q_noise=1e-3, dq_noise=1e-2, seed=7))
    state = np.zeros(1, dtype=wire.PROTOCOL_10.state)
    try:
        seen = []
        for _ in range(6):
            arm.step(None)
            seen.append(arm.q)
        arm.write_state(state, 1)
        np.testing.assert_allclose(state["q"][0], seen[-4], atol=1e-6)  # 3 cycles late (float32)
        assert np.abs(state["q"][0] - seen[-3]).max() > 1e-5
        assert np.abs(seen[-1] - seen[-4]).max() > 1e-4  # the arm moved meanwhile
        noisy.step(None)
        noisy.write_state(state, 1)
        err = state["q"][0] - noisy.q
        assert 0.0 < np.abs(err).max() < 5e-3
        np.testing.assert_array_equal(state["theta"], state["q"])
    finally:
        arm.env.close()
        noisy.env.close()


def test_the_training_arm_already_has_the_identified_link_masses() -> None:
    """Gaz et al.'s link masses (their supplementary material, table VIII; the authors'
    DynPars2VREP.m) are Menagerie's: a "real" preset has no masses of its own to change."""
    arm = SimulatedArm(franka_scene("empty"), PANDA)
    try:
        m = arm.env.model
        masses = [m.body(f"link{i}").mass[0] for i in range(1, 8)]
        gaz = [4.970684, 0.646926, 3.228604, 3.587895, 1.225946, 1.666555, 0.735522]
        np.testing.assert_allclose(masses, gaz, atol=1e-9)
    finally:
        arm.env.close()


def test_a_load_in_the_hand_weighs_on_the_joints_as_a_point_mass_there() -> None:
    plain = SimulatedArm(franka_scene("empty"), PANDA)
    loaded = SimulatedArm(
        franka_scene("empty"), PANDA, Reality(load_mass=1.5, load_com=(0.02, 0.0, 0.1))
    )
    try:
        m0, d0, m1, d1 = plain.env.model, plain.env.data, loaded.env.model, loaded.env.data
        hand = m1.body("hand").id
        assert m1.body_mass[hand] == pytest.approx(m0.body_mass[hand] + 1.5, abs=1e-12)
        assert m1.body_subtreemass[1] == pytest.approx(m0.body_subtreemass[1] + 1.5, abs=1e-9)
        # the load's point, in the world: the flange (the hand turned +45°) at (0.02, 0, 0.1)
        rot = d1.xmat[hand].reshape(3, 3)
        c45 = np.cos(np.pi / 4)
        point = d1.xpos[hand] + rot @ np.array([0.02 * c45, 0.02 * c45, 0.1])
        jac = np.zeros((3, m1.nv))
        mujoco.mj_jac(m1, d1, jac, None, point, hand)
        extra = d1.qfrc_bias - d0.qfrc_bias  # at rest, the same joints: gravity alone
        np.testing.assert_allclose(extra, jac.T @ np.array([0.0, 0.0, 9.81 * 1.5]), atol=1e-9)
        assert loaded.hand.m_ee == plain.hand.m_ee  # the robot is not told of it
    finally:
        plain.env.close()
        loaded.env.close()


def test_presets_and_files_and_their_errors(tmp_path: Path) -> None:
    assert reality_from(None).name == "nominal" and reality_from(None).friction is None
    assert reality_from("panda-gaz2019").friction is GAZ2019_FRICTION
    path = tmp_path / "lab_arm.json"
    path.write_text(json.dumps({"friction": "panda-gaz2019", "dq_noise": 0.002}))
    lab = reality_from(str(path))
    assert (lab.name, lab.friction, lab.dq_noise) == ("lab_arm", GAZ2019_FRICTION, 0.002)
    with pytest.raises(UnknownNameError, match="no reality preset or file named 'panda-gaz'"):
        reality_from("panda-gaz")
    path.write_text(json.dumps({"q_noize": 0.1}))
    with pytest.raises(UnknownNameError, match=r"no field named 'q_noize' in --reality .*lab_arm"):
        reality_from(str(path))
    path.write_text(json.dumps({"state_latency": -1}))
    with pytest.raises(SpecError, match=r"reality.state_latency must be a whole number >= 0"):
        reality_from(str(path))
    path.write_text(json.dumps({"friction": {"phi1": [1.0] * 6, "phi2": [1] * 7, "phi3": [0] * 7}}))
    with pytest.raises(SpecError, match=r"reality.friction.phi1 must be 7 finite numbers"):
        reality_from(str(path))


def test_the_server_serves_a_reality_by_name_and_refuses_an_unknown_one() -> None:
    with franka_sim("--lockstep", "--scene", "empty", "--reality", "panda-gaz2019") as sim:
        assert "reality panda-gaz2019" in sim.log[0], sim.log[0]
    done = subprocess.run(
        [sys.executable, "-m", "mjkdl.hw.franka_sim", "--host", "127.0.0.1", "--reality", "real"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert done.returncode == 2
    assert "franka_sim: no reality preset or file named 'real' in --reality" in done.stderr
