"""`Scene.describe()`, `print(scene)` and the tree in create_robot's unknown-name error: the
names are MuJoCo's own, the tree is MuJoCo's, and each suggested call builds the robot a user
expects (its TCP where MuJoCo puts that site or body)."""

from __future__ import annotations

import re

import mujoco
import numpy as np
import pytest
from conftest import (
    PANDA_HOME,
    PANDA_TCP,
    ROOT,
    base_spec,
    gripper,
    menagerie,
    table_object,
    tutorial_spec,
)

import mjkdl as mjk
from mjkdl.describe import _DOCUMENTED_TCPS, RobotSuggestion, suggest
from mjkdl.urdf import example_robot_data_path

UR5 = "ur_description/urdf/ur5_robot.urdf"
_CONNECTOR = re.compile(r"^((?:│  |   )*)(?:├─ |└─ )?")


def _parse_tree(text: str) -> list[tuple[int, str, dict[str, str]]]:
    """(depth, body name, {"joint": ..., "site": ..., "camera": ...}) per tree line."""
    lines = text.splitlines()[1:]
    end = next(
        i for i, line in enumerate(lines) if not line.startswith(("world", "│", "├", "└", " "))
    )
    out = []
    for k, line in enumerate(lines[:end]):
        lead = _CONNECTOR.match(line)
        depth = 0 if k == 0 else len(lead.group(1)) // 3 + 1
        name, *fields = line[lead.end() :].split("  ")
        parts = {}
        for field in fields:
            key, _, value = field.partition(": ")
            if value:
                parts[key.rstrip("s")] = value
        out.append((depth, name, parts))
    return out


def _joint_entries(value: str) -> list[tuple[str, str, str]]:
    """(name, type, actuator or "") from "j1 (hinge, actuator a1), j2 (slide)"."""
    return [
        (name, kind, actuator or "")
        for name, kind, actuator in re.findall(r"(\S+) \((\w+)(?:, actuator ([^)]+))?\)", value)
    ]


def test_tree_names_and_parents_are_mujocos(tutorial_scene) -> None:
    scene = tutorial_scene()
    m = scene.model
    rows = _parse_tree(scene.describe())
    assert [name for _, name, _ in rows] == [m.body(b).name for b in range(m.nbody)]
    stack: list[str] = []
    for b, (depth, name, _) in enumerate(rows):
        stack[depth:] = [name]
        parent = stack[depth - 1] if depth else "world"
        assert parent == m.body(m.body_parentid[b]).name, name
    joints = [e for _, _, parts in rows for e in _joint_entries(parts.get("joint", ""))]
    kinds = {
        int(v): k.removeprefix("mjJNT_").lower() for k, v in mujoco.mjtJoint.__members__.items()
    }
    assert [(n, k) for n, k, _ in joints] == [
        (m.joint(j).name, kinds[int(m.jnt_type[j])]) for j in range(m.njnt)
    ]
    for n, _, actuator in joints:
        if actuator:
            assert m.actuator_trnid[m.actuator(actuator).id, 0] == m.joint(n).id
    sites = [s for _, _, parts in rows if "site" in parts for s in parts["site"].split(", ")]
    assert sites == [m.site(i).name for i in range(m.nsite)]
    cameras = {(name, c) for _, name, parts in rows for c in parts.get("camera", "").split(", ")}
    expected = {(m.body(m.cam_bodyid[c]).name, m.camera(c).name) for c in range(m.ncam)}
    assert {pair for pair in cameras if pair[1]} == expected
    named = [a for _, _, a in joints if a] + ["g_fingers_actuator"]
    assert sorted(named) == sorted(m.actuator(a).name for a in range(m.nu))
    assert "g_fingers_actuator (tendon g_split)" in scene.describe()


def test_counts_and_marks(tutorial_scene) -> None:
    scene = tutorial_scene()
    m = scene.model
    text = scene.describe()
    assert text.splitlines()[0] == (
        f"Scene: {m.nbody} bodies, {m.njnt} joints, {m.nu} actuators, {m.nsite} sites, "
        f"{m.ncam} cameras"
    )
    assert '│     └─ base_link  [robot 0 (gen3.xml, prefix "")]' in text
    assert "g_base_mount  [attachment of robot 0]" in text
    assert '├─ table  [object "table"]' in text


def _build(scene: mjk.Scene, s: RobotSuggestion) -> mjk.Robot:
    tool = mjk.ToolFrameSpec(
        tool_body=s.tool_body,
        tcp_site=s.tcp_site,
        tcp_pos=list(s.tcp_pos),
        tcp_euler=list(s.tcp_euler),
    )
    return scene.create_robot(s.base_body, s.tip_body, prefix=s.prefix, tool=tool)


def _tcp_matches(robot: mjk.Robot, scene: mjk.Scene, site: str = "", body: str = "") -> None:
    """The robot's TCP at random configurations is MuJoCo's pose of `site` (or `body`)."""
    m, d = scene.model, scene.data
    rng = np.random.default_rng(1)
    for _ in range(5):
        q = rng.uniform(*np.clip(robot.joint_limits, -3.0, 3.0).T)
        robot.set_joint_pos(q)
        frame = robot.fk_frame()
        if site:
            pos, rot = d.site_xpos[m.site(site).id], d.site_xmat[m.site(site).id]
        else:
            pos, rot = d.xpos[m.body(body).id], d.xmat[m.body(body).id]
        assert np.abs(frame.translation - pos).max() < 1e-9
        assert np.abs(frame.rotation - rot.reshape(3, 3)).max() < 1e-9


def test_gen3_2f85_suggestion_builds_the_tutorial_robot(tutorial_scene) -> None:
    scene = tutorial_scene()
    (s,) = suggest(scene.model, scene.spec)
    assert s == RobotSuggestion("", "base_link", "bracelet_link", "g_base", "g_pinch")
    text = str(scene)
    call = re.search(r"scene\.(create_robot\(.*\))$", text, flags=re.M).group(1)
    robot = eval(f"scene.{call}", {"scene": scene, "mjk": mjk})  # the printed call runs
    assert robot.joint_names == [f"joint_{i}" for i in range(1, 8)]
    _tcp_matches(robot, scene, site="g_pinch")


def test_prefixed_second_arm() -> None:
    first = mjk.RobotSpec(path=menagerie("kinova_gen3"), pos=[-0.6, 0.0, 0.0])
    second = mjk.RobotSpec(
        path=menagerie("kinova_gen3"), prefix="r2_", pos=[0.6, 0, 0], attachments=[gripper()]
    )
    with mjk.Scene.build(base_spec(robots=[first, second])) as scene:
        bare, tooled = suggest(scene.model, scene.spec)
        assert bare == RobotSuggestion("", "base_link", "bracelet_link", "", "pinch_site")
        assert tooled == RobotSuggestion("r2_", "base_link", "bracelet_link", "g_base", "g_pinch")
        assert '└─ r2_base_link  [robot 1 (gen3.xml, prefix "r2_")]' in scene.describe()
        robot = _build(scene, tooled)
        assert robot.joint_names[0] == "r2_joint_1"
        _tcp_matches(robot, scene, site="r2_g_pinch")
        _tcp_matches(_build(scene, bare), scene, site="pinch_site")


def test_panda_suggestion_is_the_one_recipe() -> None:
    arm = mjk.RobotSpec(path=menagerie("franka_emika_panda"), prefix="p/")
    with mjk.Scene.build(base_spec(robots=[arm])) as scene:
        (s,) = suggest(scene.model, scene.spec)
        assert s == RobotSuggestion("p/", "link0", "hand", tcp_pos=tuple(PANDA_TCP))
        assert s.call() == (
            'create_robot("link0", "hand", prefix="p/", '
            "tool=mjk.ToolFrameSpec(tcp_pos=[0.0, 0.0, 0.1034]))"
        )
        robot = _build(scene, s)
        assert robot.joint_names == [f"p/joint{i}" for i in range(1, 8)]  # fingers: passive
        # The TCP sits between the fingertip pads, on the hand's axis.
        pads = [scene.model.body(f"p/{side}_finger").id for side in ("left", "right")]
        robot.set_joint_pos(PANDA_HOME)
        centre = np.mean([scene.data.xpos[b] for b in pads], axis=0)
        hand = scene.data.xmat[scene.model.body("p/hand").id].reshape(3, 3)
        offset = hand.T @ (robot.fk_frame().translation - centre)
        assert np.abs(offset[:2]).max() < 1e-9


def test_the_panda_recipe_is_franka_s_tcp_as_the_urdf_marks_it() -> None:
    """The documented offset is the Panda URDF's `panda_hand_tcp`, read off that file."""
    urdf = mjk.RobotSpec(path=example_robot_data_path("panda_description/urdf/panda.urdf"))
    with mjk.Scene.build(base_spec(robots=[urdf])) as scene:
        (s,) = suggest(scene.model, scene.spec)
    assert s.tcp_pos == tuple(PANDA_TCP) == _DOCUMENTED_TCPS["franka_emika_panda/panda.xml"][1]


def test_panda_urdf_tcp_is_its_hand_tcp_link() -> None:
    arm = mjk.RobotSpec(
        path=example_robot_data_path("panda_description/urdf/panda.urdf"), euler=[10, 20, 30]
    )
    with mjk.Scene.build(base_spec(robots=[arm])) as scene:
        (s,) = suggest(scene.model, scene.spec)
        assert s == RobotSuggestion(
            "", "panda_link0", "panda_link8", "panda_hand", "", (0, 0, 0.1034), (0, 0, -45)
        )
        assert "tcp_pos=[0.0, 0.0, 0.1034], tcp_euler=[0.0, 0.0, -45.0]" in s.call()
        robot = _build(scene, s)
        assert robot.n_joints == 7
        _tcp_matches(robot, scene, body="panda_hand_tcp")


def test_ur5_urdf_suggestion_ends_at_tool0() -> None:
    table = table_object()
    arm = mjk.RobotSpec(
        path=example_robot_data_path(UR5),
        attach_to=mjk.AttachTarget(mjk.AttachKind.Site, "table/table_top"),
    )
    with mjk.Scene.build(base_spec(objects=[table], robots=[arm])) as scene:
        (s,) = suggest(scene.model, scene.spec)
        assert s == RobotSuggestion("", "base_link", "tool0")
        robot = _build(scene, s)
        assert robot.n_joints == 6
        _tcp_matches(robot, scene, body="tool0")


def test_floating_legged_robot_gets_no_arm_suggestion() -> None:
    go2 = mjk.RobotSpec(
        path=example_robot_data_path("go2_description/urdf/go2.urdf"), floating=True
    )
    with mjk.Scene.build(base_spec(robots=[go2])) as scene:
        assert suggest(scene.model, scene.spec) == []
        assert 'robot 0 (go2.urdf, prefix ""): no single chain at "base"' in str(scene)
        assert "base  [robot 0 (go2.urdf" in scene.describe()
        assert "root_joint (free)" in scene.describe()


def test_short_form_is_counts_objects_and_calls(tutorial_scene) -> None:
    scene = tutorial_scene()
    lines = str(scene).splitlines()
    assert lines[0] == scene.describe().splitlines()[0]
    assert lines[1] == "  objects: table, cube"
    assert lines[2].startswith('  robot 0 (gen3.xml, prefix ""): scene.create_robot(')
    assert len(lines) == 3


def test_unknown_body_shows_the_tree(tutorial_scene) -> None:
    scene = tutorial_scene()
    with pytest.raises(mjk.UnknownNameError) as info:
        scene.create_robot("base_lnk", "bracelet_link")
    message = str(info.value)
    assert isinstance(info.value, KeyError)
    assert message.startswith("no body named 'base_lnk' in the model; close matches: base_link")
    assert "\nbase_link  [robot 0" in message
    assert "bracelet_link  joint: joint_7 (hinge, actuator joint_7)" in message
    assert 'scene.create_robot("base_link", "bracelet_link"' in message
    assert "cube" not in message  # only the robot's part of the scene


def test_unknown_body_with_a_prefix_shows_that_robot() -> None:
    first = mjk.RobotSpec(path=menagerie("kinova_gen3"), pos=[-0.6, 0.0, 0.0])
    second = mjk.RobotSpec(path=menagerie("kinova_gen3"), prefix="r2_", pos=[0.6, 0, 0])
    with mjk.Scene.build(base_spec(robots=[first, second])) as scene:
        with pytest.raises(KeyError) as info:
            scene.create_robot("base_link", "bracelet", prefix="r2_")
        message = str(info.value)
        assert "\nr2_base_link  [robot 1" in message
        assert "\nbase_link" not in message
        with pytest.raises(KeyError) as info:
            scene.create_robot("base_link", "bracelet_link", prefix="r3_")
        assert "\nworld\n├─ base_link" in str(info.value)  # no such robot: the whole tree


def test_closed_scene() -> None:
    scene = mjk.Scene.build(tutorial_spec())
    scene.close()
    with pytest.raises(RuntimeError, match="closed"):
        scene.describe()
    assert str(scene) == "Scene (closed)"


def test_one_panda_recipe_everywhere() -> None:
    """The docs, the examples, the registered tasks and the tests use the call describe()
    suggests for Menagerie's Panda."""
    from mjkdl.task.registry import panda_arm  # the task layer, imported only here

    tip, tcp = _DOCUMENTED_TCPS["franka_emika_panda/panda.xml"]
    arm = panda_arm()
    assert (arm.base_body, arm.tip_body, tuple(arm.tool.tcp_pos)) == ("link0", tip, tcp)
    assert tuple(PANDA_TCP) == tcp
    common = (ROOT / "examples" / "common.py").read_text()
    assert f"PANDA_TCP = {list(tcp)}" in common and 'tip: str = "hand"' in common
    calls = re.findall(
        r'create_robot\("link0", "(\w+)", tool=mjk\.ToolFrameSpec\(tcp_pos=\[([^\]]*)\]\)\)',
        (ROOT / "docs" / "control.md").read_text(),
    )
    assert calls and all(
        t == tip and tuple(float(v) for v in pos.split(",")) == tcp for t, pos in calls
    )
