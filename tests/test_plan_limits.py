"""Every arm plans out of the box: datasheet limits, an allowed-collision matrix by sampling.

Each of the shared Menagerie's arms (and example-robot-data's UR5 through mjkdl.urdf) gets its
published velocity limits, a sampled allowed-collision matrix, and a plan between two random
collision-free states that keeps the margin along the timed trajectory (`mj_geomDistance`).
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from conftest import base_spec, menagerie, tutorial_spec

import mjkdl as mjk
import mjkdl.plan
from mjkdl.plan import DATASHEETS, MotionPlanner
from mjkdl.plan.acm import compute_acm
from mjkdl.plan.limits import RAMP
from mjkdl.urdf import example_robot_data_path

DEG = np.pi / 180.0
# name: (Menagerie model or None, file, base body, tip body, the table's arm)
ARMS = {
    "panda": ("franka_emika_panda", "panda.xml", "link0", "hand", "Franka Emika Panda"),
    "iiwa14": ("kuka_iiwa_14", "iiwa14.xml", "base", "link7", "KUKA LBR iiwa 14 R820"),
    "xarm7": ("ufactory_xarm7", "xarm7.xml", "link_base", "link7", "UFACTORY xArm 7"),
    "wx250s": (
        "trossen_wx250s",
        "wx250s.xml",
        "wx250s/base_link",
        "wx250s/gripper_link",
        "Trossen WidowX 250 6DOF (wx250s)",
    ),
    "ur5": (
        None,
        "ur_description/urdf/ur5_robot.urdf",
        "base_link",
        "wrist_3_link",
        "Universal Robots UR5e",
    ),
    "gen3": ("kinova_gen3", "gen3.xml", "base_link", "bracelet_link", "Kinova Gen3 (7 DoF)"),
}


def _build(name: str) -> tuple[mjk.Scene, mjk.Robot]:
    model, file, base, tip, _ = ARMS[name]
    if name == "gen3":  # with the 2F-85 on its wrist, on the table
        scene = mjk.Scene.build(tutorial_spec())
        return scene, scene.create_robot(base, tip)
    if model is None:
        path = str(example_robot_data_path(file))
    else:
        path = menagerie(model).rsplit("/", 1)[0] + "/" + file
    scene = mjk.Scene.build(base_spec(robots=[mjk.RobotSpec(path=path)]))
    return scene, scene.create_robot(base, tip)


@pytest.mark.parametrize("name", list(ARMS))
def test_every_arm_plans_with_published_limits_and_a_sampled_matrix(name: str) -> None:
    scene, robot = _build(name)
    try:
        planner = MotionPlanner(robot)
        sheet = next(d for d in DATASHEETS if d.arm.startswith(ARMS[name][4]))
        if name == "ur5":  # the URDF's own velocity limits come through the model
            assert planner.velocity_limits.tolist() == [3.15, 3.15, 3.15, 3.2, 3.2, 3.2]
            assert "velocity: the model's (a URDF's <limit velocity>)" in planner.limits_source
        else:
            assert planner.velocity_limits.tolist() == pytest.approx(list(sheet.velocity))
        if sheet.acceleration is None:
            expected = planner.velocity_limits / RAMP
            assert "not published" in planner.limits_source
        else:
            expected = np.array(sheet.acceleration)
        assert planner.acceleration_limits == pytest.approx(expected)
        assert sheet.arm in planner.limits_source
        acm = planner.acm
        assert acm is not None
        # Each moving link and its parent are adjacent (the first one's parent: the mount).
        summary = acm.summary()
        assert summary["adjacent"] >= robot.n_joints - 1
        assert summary["never"] == summary["default"] == 0  # listed, not allowed:
        assert "never" in acm.sampled.values()
        m = scene.model
        bodies = [m.body(m.joint(j).bodyid[0]).name for j in robot.joint_names]
        assert acm.reason(bodies[1], bodies[2]) == "adjacent"
        # Two random collision-free states with the arm's own parts allowed as sampled:
        # the plan between them keeps the margin at every sampled instant, by MuJoCo's
        # own distance on the scene's model.
        limits = robot.joint_limits
        low = np.where(np.isfinite(limits[:, 0]), limits[:, 0], -np.pi)
        high = np.where(np.isfinite(limits[:, 1]), limits[:, 1], np.pi)
        bounds = None
        if name == "ur5":
            # ±2π joints: the floor splits the shoulder's 4π into regions no path joins
            # (issue 31); one turn of bounds per call keeps the query in one.
            low, high = np.maximum(low, -np.pi), np.minimum(high, np.pi)
            bounds = (low, high)
        rng = np.random.default_rng(3)
        free = [
            q for q in rng.uniform(low, high, (200, robot.n_joints)) if planner.checker.valid(q)
        ]
        assert len(free) >= 2
        traj = planner.plan(free[1], start=free[0], timeout=5.0, bounds=bounds)
        assert np.abs(traj.positions[-1] - free[1]).max() < 1e-9
        samples = [traj.sample(t) for t in np.linspace(0, traj.duration, 300)]
        speed = np.abs([s[1] for s in samples]).max(axis=0)
        assert np.all(speed <= planner.velocity_limits * 1.01 + 1e-9)
        checker = planner.checker
        data = mujoco.MjData(m)
        pairs = _counted_pairs(m, robot, acm.pairs)
        fromto = np.zeros(6)
        worst = np.inf
        for t in np.linspace(0, traj.duration, 60):
            data.qpos[checker.arm_qpos_adr] = traj.sample(t)[0]
            mujoco.mj_kinematics(m, data)
            for g1, g2 in pairs:
                d = mujoco.mj_geomDistance(m, data, g1, g2, 0.05, fromto)
                if d < worst:
                    worst, closest = (
                        d,
                        (m.body(m.geom_bodyid[g1]).name, m.body(m.geom_bodyid[g2]).name),
                    )
        assert worst >= planner.margin - 1e-4, closest
    finally:
        scene.close()


def _counted_pairs(
    m: mujoco.MjModel, robot: mjk.Robot, allowed: dict[tuple[str, str], str]
) -> list[tuple[int, int]]:
    """Geom pairs of the arm's moving bodies with each other (not allowed, not in one rigid
    group, not excluded by the model) and with the world's geoms, that MuJoCo's bits would
    collide."""
    root = m.joint(robot.joint_names[0]).bodyid[0]
    moving = np.zeros(m.nbody, dtype=bool)
    moving[root] = True
    for b in range(root + 1, m.nbody):
        moving[b] = moving[m.body_parentid[b]]
    joint_body = {int(m.joint(j).bodyid[0]) for j in robot.joint_names}

    def group(b: int) -> int:
        while b not in joint_body and moving[b]:
            b = int(m.body_parentid[b])
        return b if moving[b] else -1

    geoms = [g for g in range(m.ngeom) if m.geom_contype[g] or m.geom_conaffinity[g]]
    excluded = set(m.exclude_signature.tolist())
    out = []
    for i, g1 in enumerate(geoms):
        for g2 in geoms[i + 1 :]:
            b1, b2 = int(m.geom_bodyid[g1]), int(m.geom_bodyid[g2])
            if not (moving[b1] or moving[b2]) or group(b1) == group(b2):
                continue
            if not (
                m.geom_contype[g1] & m.geom_conaffinity[g2]
                or m.geom_contype[g2] & m.geom_conaffinity[g1]
            ):
                continue
            a, b = m.body(b1).name, m.body(b2).name
            if (min(a, b), max(a, b)) in allowed:
                continue
            if m.body_parentid[b1] == b2 or m.body_parentid[b2] == b1:
                continue
            if {(b1 << 16) + b2, (b2 << 16) + b1} & excluded:  # the model's <exclude>s (SRDF)
                continue
            out.append((g1, g2))
    return out


def test_the_matrix_is_cached_inspectable_and_editable(tmp_path, monkeypatch) -> None:
    monkeypatch.setenv("MJKDL_CACHE_DIR", str(tmp_path))
    scene, robot = _build("iiwa14")
    try:
        limits = robot.joint_limits
        first = compute_acm(robot, 0.005, limits[:, 0], limits[:, 1], samples=300, seed=1)
        files = list((tmp_path / "acm").glob("*.json"))
        assert len(files) == 1
        again = compute_acm(robot, 0.005, limits[:, 0], limits[:, 1], samples=300, seed=1)
        assert again.pairs == first.pairs
        assert again.contact_fraction == first.contact_fraction
        # Another margin is another matrix.
        compute_acm(robot, 0.02, limits[:, 0], limits[:, 1], samples=300, seed=1)
        assert len(list((tmp_path / "acm").glob("*.json"))) == 2
        planner = MotionPlanner(robot, acm_samples=300, seed=1)
        acm = planner.acm
        assert acm.reason("link1", "link2") == "adjacent"
        assert ("link2", "link1") in acm
        a, b = next(pair for pair, reason in acm.pairs.items() if reason == "adjacent")
        acm.disallow(a, b)
        assert acm.reason(a, b) is None
        acm.allow("link1", "link7")
        assert acm.reason("link1", "link7") == "user"
        q = np.zeros(7)
        planner.contacts(q)  # applies the edits
        assert ("link1", "link7") in [tuple(sorted(p)) for p in planner.checker._allowed_names]
        with pytest.raises(mjk.UnknownNameError, match=r"no body named 'link9' in .*allow"):
            acm.allow("link1", "link9")
        with pytest.raises(mjk.SpecError, match=r"cannot collide with itself \('link1'\)"):
            acm.allow("link1", "link1")
        # MoveIt's choice: the pairs no sample brought into contact allowed too.
        moveit = MotionPlanner(
            robot, acm_samples=300, seed=1, acm_allow=("adjacent", "always", "default", "never")
        ).acm
        assert moveit.pairs == acm.sampled
        with pytest.raises(mjk.SpecError, match=r"acm_allow must be a tuple of adjacent, "):
            MotionPlanner(robot, acm_allow="never")
        with pytest.raises(mjk.SpecError, match=r"acm_samples must be an integer >= 10"):
            MotionPlanner(robot, acm_samples=3)
    finally:
        scene.close()


HOVERING_DISC = """
<mujoco model="hover">
  <worldbody>
    <body name="base">
      <geom type="box" size="0.3 0.3 0.01"/>
      <body name="l1" pos="0 0 0.05">
        <joint name="j1" axis="0 0 1"/>
        <geom type="capsule" fromto="0 0 0 0.1 0 0" size="0.01" mass="1"/>
        <body name="l2" pos="0.1 0 0">
          <joint name="j2" axis="0 0 1"/>
          <geom type="cylinder" size="0.05 0.005" pos="0.1 0 -0.032" mass="0.5"/>
        </body>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


def test_a_link_always_within_the_margin_of_its_mount_is_allowed(tmp_path) -> None:
    """As the UR5e's shoulder over its mount (issue 31): a disc 3 mm above the base plate,
    not the plate's child, is within a 5 mm margin in every pose."""
    path = tmp_path / "hover.xml"
    path.write_text(HOVERING_DISC)
    spec = base_spec(add_floor=False, robots=[mjk.RobotSpec(path=str(path))])
    with mjk.Scene.build(spec) as scene:
        arm = scene.create_robot("base", "l2")
        limits = {"velocity_limits": [1.0, 1.0], "acceleration_limits": [2.0, 2.0]}
        with pytest.raises(
            mjk.plan.InfeasibleError,
            match=r"the start is in collision: bodies '(base|l2)' and '(base|l2)' are 3.0 mm",
        ):
            MotionPlanner(arm, acm=False, **limits).plan([1.0, 1.0])
        planner = MotionPlanner(arm, **limits)
        assert planner.acm.reason("base", "l2") == "always"
        assert planner.acm.contact_fraction[("base", "l2")] == 1.0
        assert planner.acm.reason("l1", "l2") == "adjacent"
        traj = planner.plan([1.0, 1.0])
        assert np.abs(traj.positions[-1] - [1.0, 1.0]).max() < 1e-12


def test_every_datasheet_names_its_source_and_how_it_was_checked() -> None:
    from mjkdl.plan import DATASHEETS

    assert len(DATASHEETS) == 12
    for sheet in DATASHEETS:
        assert sheet.velocity_source and sheet.acceleration_source, sheet.arm
        assert sheet.verified.startswith("2026-11-26: "), sheet.arm
        assert len(sheet.velocity) == len(sheet.links), sheet.arm
    ur10e = next(s for s in DATASHEETS if s.arm == "Universal Robots UR10e")
    assert ur10e.velocity == pytest.approx(np.radians([120, 120, 180, 180, 180, 180]), abs=1e-4)
