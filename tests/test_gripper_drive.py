"""GripperDrive: the Panda hand squeezes with the Franka Hand's force and moves its fingers at
its speed; bad drives are named."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from conftest import PANDA_HOME, PANDA_TCP, base_spec, menagerie

import mjkdl as mjk
from mjkdl.compile import compile_scene


def hand_spec(prefix: str = "", **drive) -> mjk.SceneSpec:
    arm = mjk.RobotSpec(
        path=menagerie("franka_emika_panda"),
        prefix=prefix,
        grippers=[mjk.GripperDrive(actuator="actuator8", **drive)],
    )
    return base_spec(robots=[arm])


def finger_dofs(model: mujoco.MjModel, prefix: str = "") -> list[int]:
    return [int(model.joint(f"{prefix}finger_joint{i}").dofadr[0]) for i in (1, 2)]


def test_the_drive_rewrites_the_servo_damping_and_pads() -> None:
    franka = mjk.GripperDrive.franka_hand()
    assert franka == mjk.GripperDrive("actuator8", 20.0, 0.05, "fingertip_pad_collision")
    own = compile_scene(base_spec(robots=[mjk.RobotSpec(path=menagerie("franka_emika_panda"))]))
    model = compile_scene(hand_spec("p/", force=30.0, speed=0.04))
    a = model.actuator("p/actuator8").id
    # The tendon carries half of its force to each finger: 60 N for 30 N a finger, all of it
    # from 5 mm (of each finger) short of the target on.
    np.testing.assert_allclose(model.actuator_forcerange[a], [-60.0, 60.0])
    assert model.actuator_biasprm[a, 1] == pytest.approx(-60.0 / 0.005)
    # The same control values command the same finger positions (255: 4 cm open).
    b = own.actuator("actuator8").id
    for m, i in ((own, b), (model, a)):
        assert m.actuator_gainprm[i, 0] * 255 / -m.actuator_biasprm[i, 1] == pytest.approx(0.04)
    assert model.actuator_biasprm[a, 2] == own.actuator_biasprm[b, 2]  # its own kv kept
    np.testing.assert_allclose(model.dof_damping[finger_dofs(model, "p/")], 30.0 / 0.04)
    pads = model.geom_bodyid == model.body("p/left_finger").id
    assert np.all(model.geom_solmix[pads] == 1000.0) and np.all(model.geom_priority[pads] == 0)
    np.testing.assert_allclose(model.geom_solref[pads], [[0.004, 2.0]] * int(pads.sum()))
    np.testing.assert_allclose(model.geom_solimp[pads, :3], [[0.95, 0.99, 0.001]] * 8)
    hand = model.geom_bodyid == model.body("p/hand").id  # the rest as the model has it
    assert np.all(model.geom_solmix[hand] == 1.0)
    np.testing.assert_allclose(model.geom_solref[hand, 0], 0.02)
    assert model.dof_damping[model.joint("p/joint1").dofadr[0]] == own.dof_damping[0]
    # franka_hand(): only the fingertip pads (5 boxes a finger), not the finger's mesh.
    arm = mjk.RobotSpec(path=menagerie("franka_emika_panda"), prefix="p/", grippers=[franka])
    tips = compile_scene(base_spec(robots=[arm]))
    finger = tips.geom_bodyid == tips.body("p/left_finger").id
    boxes = finger & (tips.geom_type == mujoco.mjtGeom.mjGEOM_BOX)
    assert int(boxes.sum()) == 5 and np.all(tips.geom_solmix[boxes] == 1000.0)
    assert np.all(tips.geom_solmix[finger & ~boxes] == 1.0)


def test_the_hand_squeezes_with_its_force_and_moves_at_its_speed() -> None:
    """A fixed 4 cm block between the fingers at the Panda's home pose: the fingers press on
    it with the drive's 20 N each; a free finger moves at 0.05 m/s."""
    with mjk.Env.build(hand_spec()) as env:
        m, d = env.model, env.data
        d.qpos[:7] = d.ctrl[:7] = PANDA_HOME
        mujoco.mj_forward(m, d)
        tcp = d.body("hand").xpos + d.body("hand").xmat.reshape(3, 3) @ PANDA_TCP
    block = mjk.SceneObject(name="block", shape=mjk.Shape.BOX, size=[0.02, 0.02, 0.02],
                            pos=list(tcp), fixed=True)  # fmt: skip
    spec = hand_spec()
    spec.objects = [block]
    with mjk.Env.build(spec) as env:
        m, d = env.model, env.data
        hand, fingers = m.actuator("actuator8").id, finger_dofs(m)
        d.qpos[:7] = d.ctrl[:7] = PANDA_HOME
        d.qpos[m.joint("finger_joint1").qposadr[0] : m.joint("finger_joint2").qposadr[0] + 1] = 0.04
        d.ctrl[hand] = 0.0  # close
        speeds = []
        for _ in range(400):  # 0.8 s: at 0.05 m/s the fingers meet the block after 0.4 s
            mujoco.mj_step(m, d)
            speeds.append(-d.qvel[fingers[0]])
        assert np.median(speeds[50:150]) == pytest.approx(0.05, rel=0.03)
        assert d.qpos[m.joint("finger_joint1").qposadr[0]] == pytest.approx(0.02, abs=1e-3)
        block_body = m.body("block").id
        per_finger = {"left_finger": 0.0, "right_finger": 0.0}
        for i in range(d.ncon):
            c = d.contact[i]
            bodies = {int(m.geom_bodyid[c.geom1]), int(m.geom_bodyid[c.geom2])}
            if block_body in bodies:
                other = m.body(next(iter(bodies - {block_body}))).name
                force = np.zeros(6)
                mujoco.mj_contactForce(m, d, i, force)
                per_finger[other] += force[0]
        # 20 N a finger: on a free object the two balance; this block is fixed and a hair off
        # centre, so the fingers' coupling (an equality) shifts a little between them.
        assert sum(per_finger.values()) == pytest.approx(40.0, rel=0.01)
        assert min(per_finger.values()) > 15.0


@pytest.mark.parametrize(
    ("drive", "error", "message"),
    [
        (
            "actuator8",
            mjk.SpecTypeError,
            "robots[0].grippers[0] must be a GripperDrive, got 'actuator8'",
        ),
        (
            mjk.GripperDrive(),
            mjk.SpecError,
            "robots[0].grippers[0].actuator is empty: name the gripper's actuator",
        ),
        (
            mjk.GripperDrive("actuator8", force=0.0),
            mjk.SpecError,
            "robots[0].grippers[0].force must be positive (N), got 0.0",
        ),
        (
            mjk.GripperDrive("actuator8", speed=float("nan")),
            mjk.SpecError,
            "robots[0].grippers[0].speed must be finite, got nan",
        ),
        (
            mjk.GripperDrive("actuator8", pads="pad"),
            mjk.SpecError,
            "robots[0].grippers[0].pads: no geom of finger body 'left_finger' has a name or "
            "class starting with 'pad'; its classes: ['collision', 'fingertip_pad_collision_1',",
        ),
        (
            mjk.GripperDrive("actuator9"),
            mjk.UnknownNameError,
            "actuator9",
        ),
        (
            mjk.GripperDrive("actuator1"),
            mjk.SpecError,
            "robots[0].grippers[0]: actuator 'actuator1' must drive slide finger joints with "
            "equal coefficients, got joints ['joint1'] (slide: [False])",
        ),
    ],
)
def test_bad_drives_are_named(drive, error, message) -> None:
    arm = mjk.RobotSpec(path=menagerie("franka_emika_panda"), grippers=[drive])
    with pytest.raises(error) as caught:
        compile_scene(base_spec(robots=[arm]))
    assert message in str(caught.value)
