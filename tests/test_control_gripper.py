"""Gripper: both Menagerie grippers open and close, the opening is measured, bad input named."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from conftest import base_spec, menagerie, panda_spec, two_link_arm

import mjkdl as mjk

SETTLE = 1.0  # seconds for the fingers to travel end to end


def panda_2f85_spec(**kw) -> mjk.SceneSpec:
    """Menagerie's hand-less Panda with a Robotiq 2F-85 (prefix `g_`) on its flange."""
    nohand = Path(menagerie("franka_emika_panda")).parent / "panda_nohand.xml"
    gripper = mjk.AttachmentSpec(
        mjcf_path=menagerie("robotiq_2f85"),
        attach_to=mjk.AttachTarget(mjk.AttachKind.Site, "attachment_site"),
        prefix="g_",
    )
    return base_spec(robots=[mjk.RobotSpec(path=str(nohand), attachments=[gripper])], **kw)


def hold_arm(env: mjk.Env) -> None:
    """Keep the Panda still in POSITION mode while the fingers move."""
    arm = env.create_robot("link0", "link7")
    arm.ctrl_mode = mjk.CtrlMode.POSITION
    env.reset()


def settle(env: mjk.Env) -> None:
    env.step(round(SETTLE / env.timestep()))
    env.forward()


def panda_fingers(env: mjk.Env) -> float:
    """Mean finger travel of the Panda hand (m): 0.04 is fully open."""
    qpos = env.data.qpos
    return 0.5 * sum(qpos[env.model.joint(f"finger_joint{i}").qposadr[0]] for i in (1, 2))


def robotiq_drivers(env: mjk.Env) -> float:
    """Mean driver angle of the 2F-85 (rad): 0.8 is fully closed."""
    qpos = env.data.qpos
    side = ("g_right_driver_joint", "g_left_driver_joint")
    return 0.5 * sum(qpos[env.model.joint(j).qposadr[0]] for j in side)


def test_panda_hand_opens_and_closes() -> None:
    with mjk.Env.build(panda_spec()) as env:
        hold_arm(env)
        hand = mjk.Gripper(env, "actuator8", open=255, closed=0)
        for action, ctrl, opening in ((0.0, 255.0, 1.0), (1.0, 0.0, 0.0), (0.2, 255.0, 1.0)):
            assert hand.command(action) == ctrl
            assert env.data.ctrl[env.actuator_id("actuator8")] == ctrl
            settle(env)
            assert hand.opening() == pytest.approx(opening, abs=0.01)
            # The measurement is the finger joints' own travel, normalised by 0.04 m.
            assert hand.opening() == pytest.approx(panda_fingers(env) / 0.04, abs=1e-9)
        assert hand.actuator_id == env.actuator_id("actuator8")
        # The tendon's lengths where the servo rests at ctrl 0 and 255: the fingers' 0.04 m.
        assert hand.length_range == pytest.approx((0.0, 0.04), abs=1e-9)


def test_robotiq_2f85_opens_and_closes_continuously() -> None:
    with mjk.Env.build(panda_2f85_spec()) as env:
        hold_arm(env)
        grip = mjk.Gripper(env, "g_fingers_actuator", open=0, closed=255, binary=False)
        assert grip.command(1.0) == 255.0
        settle(env)
        # The pads meet at a driver angle of about 0.76 rad, short of the 0.8 the servo holds
        # at 255: empty and closed reads about 0.05.
        assert grip.opening() < 0.07
        # 1e-7: Menagerie rounds the actuator's gain, so 255 holds 0.80000003 rad.
        assert grip.opening() == pytest.approx(1.0 - robotiq_drivers(env) / 0.8, abs=1e-7)
        assert grip.command(0.0) == 0.0
        settle(env)
        assert grip.opening() > 0.95
        assert grip.command(0.5) == 127.5  # continuous: linear in between
        settle(env)
        # The 2F-85 creeps toward its target for seconds (soft linkage constraints).
        assert grip.opening() == pytest.approx(0.5, abs=0.08)
        # 1e-7: Menagerie rounds the actuator's gain, so 255 holds 0.80000003 rad.
        assert grip.opening() == pytest.approx(1.0 - robotiq_drivers(env) / 0.8, abs=1e-7)


@pytest.mark.parametrize(("action", "ctrl"), [(0.0, 0.0), (0.49, 0.0), (0.5, 255.0), (1.0, 255.0)])
def test_binary_actions_snap_at_one_half(action, ctrl) -> None:
    with mjk.Env.build(panda_2f85_spec()) as env:
        grip = mjk.Gripper(env, "g_fingers_actuator", open=0, closed=255)
        assert grip.binary
        assert grip.command(np.float32(action)) == ctrl


def grasp_opening(width: float) -> float:
    """Opening of the Panda hand closed on a free box `width` wide put between its fingers."""
    box = mjk.SceneObject(
        name="box",
        shape=mjk.Shape.BOX,
        size=[width / 2] * 3,
        pos=[0.5, 0.5, width / 2],
        mass=0.05,
        friction=[1.0, 0.02, 0.001],
    )
    with mjk.Env.build(panda_spec(objects=[box])) as env:
        arm = env.create_robot("link0", "hand", tool=mjk.ToolFrameSpec(tcp_pos=[0, 0, 0.1034]))
        arm.ctrl_mode = mjk.CtrlMode.POSITION
        env.reset()
        hand = mjk.Gripper(env, "actuator8", open=255, closed=0)
        hand.command(0.0)
        settle(env)
        arm.update()
        tcp = arm.fk_frame()
        # Right between the open fingers, square to them (the hand is turned 45° on link7).
        quat = pin.Quaternion(tcp.rotation)
        env.set_body_pose("box", tcp.translation, [quat.w, quat.x, quat.y, quat.z])
        env.model.opt.gravity[:] = 0.0  # so the box stays there until the fingers hold it
        env.forward()
        hand.command(1.0)
        settle(env)
        assert np.linalg.norm(env.body_frame("box").translation - tcp.translation) < 0.005
        assert hand.opening() == pytest.approx(panda_fingers(env) / 0.04, abs=1e-9)
        return hand.opening()


def test_grasp_stops_the_fingers_at_the_object() -> None:
    narrow, wide = grasp_opening(0.03), grasp_opening(0.05)
    assert 0.1 < narrow < wide < 0.95
    # Each finger stops 1 cm further out on the wider box: 0.02 m of the 0.08 m stroke.
    assert wide - narrow == pytest.approx(0.02 / 0.08, abs=0.01)


def test_gripper_follows_a_rebuilt_scene() -> None:
    with mjk.Env.build(panda_spec()) as env:
        hand = mjk.Gripper(env, "actuator8", open=255, closed=0)
        env.add_object(
            mjk.SceneObject(
                name="pillar", shape=mjk.Shape.BOX, size=[0.1] * 3, pos=[1.0, 1.0, 0.1], fixed=True
            )
        )
        hand.command(1.0)
        assert env.data.ctrl[env.actuator_id("actuator8")] == 0.0


@pytest.mark.parametrize(
    ("action", "message"),
    [
        (-0.1, r"command\(a\): a must be in \[0, 1\], got -0.1"),
        (1.5, r"a must be in \[0, 1\]"),
        (np.nan, r"command\(a\) must be finite"),
        (np.inf, r"command\(a\) must be finite"),
        ("close", r"command\(a\) must be a number"),
        ([0.5], r"command\(a\) must be a number"),
        (None, r"command\(a\) must be a number"),
        (True, r"command\(a\) must be a number"),
    ],
)
def test_bad_actions_are_named(action, message) -> None:
    with mjk.Env.build(panda_spec()) as env:
        hand = mjk.Gripper(env, "actuator8", open=255, closed=0)
        with pytest.raises(mjk.SpecError, match=r"Gripper\('actuator8'\)\.command\(a\)"):
            hand.command(action)
        with pytest.raises(ValueError, match=message):
            hand.command(action)


def test_bad_gripper_settings_are_named(tmp_path) -> None:
    with mjk.Env.build(panda_spec()) as env:
        with pytest.raises(mjk.UnknownNameError, match=r"no actuator named 'actuator9'.*actuator8"):
            mjk.Gripper(env, "actuator9", open=255, closed=0)
        with pytest.raises(mjk.SpecError, match="open and closed are the same control value"):
            mjk.Gripper(env, "actuator8", open=0, closed=0)
        with pytest.raises(mjk.SpecError, match=r"Gripper\('actuator8'\)\.open must be finite"):
            mjk.Gripper(env, "actuator8", open=np.nan, closed=0)
        with pytest.raises(mjk.SpecError, match=r"\.closed must be a number"):
            mjk.Gripper(env, "actuator8", open=255, closed="shut")
        with pytest.raises(mjk.SpecTypeError, match=r"\.binary must be True or False, got 1"):
            mjk.Gripper(env, "actuator8", open=255, closed=0, binary=1)
    path = tmp_path / "motor.xml"
    path.write_text(two_link_arm('<actuator><motor name="m" joint="j2"/></actuator>'))
    with (
        mjk.Env.build(base_spec(robots=[mjk.RobotSpec(path=str(path))])) as env,
        pytest.raises(mjk.SpecError, match="actuator 'm' is not a position servo"),
    ):
        mjk.Gripper(env, "m", open=0, closed=1)


def test_closed_scene_makes_the_gripper_raise() -> None:
    env = mjk.Env.build(panda_spec())
    hand = mjk.Gripper(env, "actuator8", open=255, closed=0)
    env.close()
    with pytest.raises(RuntimeError, match="closed"):
        hand.command(0.0)
    with pytest.raises(RuntimeError, match="closed"):
        hand.opening()


@pytest.mark.parametrize("scene", [None, "scene"])
def test_gripper_needs_a_scene(scene) -> None:
    with pytest.raises(TypeError) as err:
        mjk.Gripper(scene, "actuator8", open=255, closed=0)
    assert isinstance(err.value, mjk.SpecTypeError)
    assert str(err.value) == f"Gripper: scene must be a Scene or an Env, got {scene!r}"


@pytest.mark.parametrize(
    ("open_", "closed", "message"),
    [
        (
            1000,
            0,
            "Gripper('actuator8').open must lie in the actuator's ctrlrange [0, 255], got 1000",
        ),
        (
            255,
            -1,
            "Gripper('actuator8').closed must lie in the actuator's ctrlrange [0, 255], got -1",
        ),
    ],
)
def test_ends_outside_a_limited_ctrlrange_are_refused(open_, closed, message) -> None:
    """MuJoCo clamps the control to [0, 255]: open=1000 would read 0.255 when fully open."""
    with mjk.Env.build(panda_spec()) as env:
        with pytest.raises(mjk.SpecError) as err:
            mjk.Gripper(env, "actuator8", open=open_, closed=closed)
        assert str(err.value) == message


def test_actuator_name_with_a_nul_byte_is_not_found() -> None:
    with mjk.Env.build(panda_spec()) as env:
        with pytest.raises(mjk.UnknownNameError) as err:
            mjk.Gripper(env, "actuator8\x00x", open=255, closed=0)
        assert str(err.value) == (
            "no actuator named 'actuator8\\x00x' in the scene; close matches: actuator8, "
            "actuator7, actuator6, actuator5, actuator4"
        )
