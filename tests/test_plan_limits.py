"""Every arm plans out of the box: datasheet limits, an allowed-collision matrix by sampling.

Each of the shared Menagerie's arms (and example-robot-data's UR5 through mjkdl.urdf) gets its
published velocity limits, a sampled allowed-collision matrix, and a plan between two random
collision-free states that keeps the margin along the timed trajectory (`mj_geomDistance`).
"""

from __future__ import annotations

import warnings
from pathlib import Path

import mujoco
import numpy as np
import pytest
import yaml
from conftest import base_spec, menagerie, tutorial_spec, untested_arm, untested_robot

import mjkdl as mjk
import mjkdl.plan
from mjkdl.plan import DATASHEETS, MotionPlanner, PlanningTimeout, RobotLimits, Srdf
from mjkdl.plan.acm import compute_acm
from mjkdl.plan.limits import RAMP, match_datasheet
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
        "Universal Robots UR5 (CB3)",
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

    assert len(DATASHEETS) == 14
    for sheet in DATASHEETS:
        assert sheet.velocity_source and sheet.acceleration_source, sheet.arm
        assert sheet.kinematics_source, sheet.arm
        assert sheet.verified.startswith(("2026-11-26: ", "2026-11-28: ")), sheet.arm
        assert len(sheet.velocity) == len(sheet.links) == len(sheet.kinematics), sheet.arm
    ur10e = next(s for s in DATASHEETS if s.arm == "Universal Robots UR10e")
    assert ur10e.velocity == pytest.approx(np.radians([120, 120, 180, 180, 180, 180]), abs=1e-4)


# The joint origins (parent-frame position, quaternion or none, axis) of the published
# descriptions the table's rows were checked against on 2026-11-28: Menagerie's franka_fr3 and
# universal_robots_ur10e, lbr-stack's iiwa7 xacro, xarm_ros2's xarm6 xacro, ros-industrial's
# ur3e, ur5e and ur10 default_kinematics.yaml (as URDF joints), Interbotix's vx300s xacro.
_R = 0.5**0.5
PUBLISHED = {
    "Franka Research 3": [
        ((0, 0, 0.333), None, "0 0 1"),
        ((0, 0, 0), (1, -1, 0, 0), "0 0 1"),
        ((0, -0.316, 0), (1, 1, 0, 0), "0 0 1"),
        ((0.0825, 0, 0), (1, 1, 0, 0), "0 0 1"),
        ((-0.0825, 0.384, 0), (1, -1, 0, 0), "0 0 1"),
        ((0, 0, 0), (1, 1, 0, 0), "0 0 1"),
        ((0.088, 0, 0), (1, 1, 0, 0), "0 0 1"),
    ],
    "KUKA LBR iiwa 7 R800": [
        ((0, 0, 0.1475), None, "0 0 1"),
        ((0, -0.0105, 0.1925), None, "0 1 0"),
        ((0, 0.0105, 0.2075), None, "0 0 1"),
        ((0, 0.0105, 0.1925), None, "0 -1 0"),
        ((0, -0.0105, 0.2075), None, "0 0 1"),
        ((0, -0.0707, 0.1925), None, "0 1 0"),
        ((0, 0.0707, 0.091), None, "0 0 1"),
    ],
    "UFACTORY xArm 6": [
        ((0, 0, 0.267), None, "0 0 1"),
        ((0, 0, 0), (1, -1, 0, 0), "0 0 1"),
        ((0.0535, -0.2845, 0), None, "0 0 1"),
        ((0.0775, 0.3425, 0), (1, -1, 0, 0), "0 0 1"),
        ((0, 0, 0), (1, 1, 0, 0), "0 0 1"),
        ((0.076, 0.097, 0), (1, -1, 0, 0), "0 0 1"),
    ],
    "Universal Robots UR10e": [
        ((0, 0, 0.181), None, "0 0 1"),
        ((0, 0.176, 0), (1, 0, 1, 0), "0 1 0"),
        ((0, -0.137, 0.613), None, "0 1 0"),
        ((0, 0, 0.571), (1, 0, 1, 0), "0 1 0"),
        ((0, 0.135, 0), None, "0 0 1"),
        ((0, 0, 0.12), None, "0 1 0"),
    ],
    "Trossen ViperX 300 6DOF (vx300s)": [
        ((0, 0, 0.079), None, "0 0 1"),
        ((0, 0, 0.04805), None, "0 1 0"),
        ((0.05955, 0, 0.3), None, "0 1 0"),
        ((0.2, 0, 0), None, "1 0 0"),
        ((0.1, 0, 0), None, "0 1 0"),
        ((0.069744, 0, 0), None, "1 0 0"),
    ],
}
for _arm, (_d1, _a2, _a3, _d4, _d5, _d6) in {
    "Universal Robots UR3e": (0.15185, -0.24355, -0.2132, 0.13105, 0.08535, 0.0921),
    "Universal Robots UR5e": (0.1625, -0.425, -0.3922, 0.1333, 0.0997, 0.0996),
    "Universal Robots UR10 (CB3)": (0.1273, -0.612, -0.5723, 0.163941, 0.1157, 0.0922),
}.items():
    PUBLISHED[_arm] = [
        ((0, 0, _d1), None, "0 0 1"),
        ((0, 0, 0), (_R, _R, 0, 0), "0 0 1"),
        ((_a2, 0, 0), None, "0 0 1"),
        ((_a3, 0, _d4), None, "0 0 1"),
        ((0, -_d5, 0), (_R, _R, 0, 0), "0 0 1"),
        ((0, _d6, 0), (_R, -_R, 0, 0), "0 0 1"),  # rpy (π/2, π, π)
    ]


@pytest.mark.parametrize("arm", sorted(PUBLISHED))
def test_a_published_description_of_each_arm_matches_its_table_row(arm: str) -> None:
    """A chain with the joint origins of the arm's published description, its bodies named
    as the row's, is recognised as that row, and as no other."""
    sheet = next(s for s in DATASHEETS if s.arm == arm)
    spec = mujoco.MjSpec()
    body = spec.worldbody
    for k, (pos, quat, axis) in enumerate(PUBLISHED[arm]):
        body = body.add_body(name=f"arm/{sheet.links[k]}", pos=pos, mass=1.0, inertia=[1e-3] * 3)
        if quat is not None:
            body.quat = np.asarray(quat, dtype=float) / np.linalg.norm(quat)
        body.add_joint(name=f"j{k}", axis=[float(v) for v in axis.split()])
    model = spec.compile()
    found = match_datasheet(model, [f"j{k}" for k in range(len(PUBLISHED[arm]))])
    assert (found.sheet.arm if found.sheet else found.note) == arm


# ---------------------------------------------------------------------- per-robot limits


def test_an_arm_named_like_the_iiwa_with_other_kinematics_gets_a_warning_and_one_error() -> None:
    """The Rizon-like arm (the iiwa's body names, side offsets between its axes, summed
    offsets within 3 % of the iiwa 14's) silently got the iiwa 14's limits when arms were
    told apart by size: now the table is not used, a warning says why, and one error lists
    every missing limit."""
    with untested_arm("rizon_like") as env:
        robot = untested_robot(env, "rizon_like")
        with (
            pytest.warns(
                UserWarning,
                match=r"bodies link1, .*, link7\): its bodies are named like those of .*KUKA "
                r"LBR iiwa 14 R820 \(along joint axis 2 the offset is 0\.0600 m, theirs "
                r"0\.0000 m\).* but its kinematics differ, so their limits are not used",
            ),
            pytest.raises(mjk.SpecError) as error,
        ):
            MotionPlanner(robot)
        joints = ", ".join(f"joint{i}" for i in range(1, 8))
        assert str(error.value).startswith(
            f"no velocity limit for joints {joints}; no acceleration limit for joints {joints} "
            "(the arm's bodies: link1, "
        )
        assert "limits='joint_limits.yaml' (MoveIt's file)" in str(error.value)
        # Given in full, no table is consulted and nothing is said.
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            planner = MotionPlanner(robot, velocity_limits=[2.0] * 7, acceleration_limits=[5.0] * 7)
        assert planner.limits_source == "velocity: given\nacceleration: given"
        given = {"velocity_limits": [2.0] * 7, "acceleration_limits": [5.0] * 7}
        with pytest.raises(mjk.SpecTypeError, match=r"limits must be a RobotLimits or the path"):
            MotionPlanner(robot, limits=5, **given)
        with pytest.raises(mjk.SpecTypeError, match=r"srdf must be an Srdf or the path"):
            MotionPlanner(robot, srdf=5, acm=False, **given)
        with pytest.raises(mjk.SpecTypeError, match=r"RobotLimits.velocity must map joint names"):
            RobotLimits(velocity=[1.0])


def test_a_moveit_joint_limits_yaml_fills_in_and_one_error_lists_what_is_still_missing(
    tmp_path,
) -> None:
    with untested_arm("rizon_like") as env:
        robot = untested_robot(env, "rizon_like")
        file = tmp_path / "joint_limits.yaml"
        entries = {
            f"joint{i}": {
                "has_velocity_limits": True,
                "max_velocity": 2.0 + 0.1 * i,
                "has_acceleration_limits": i <= 5,
                "max_acceleration": 6.0,
            }
            for i in range(1, 8)
        }
        file.write_text(yaml.safe_dump({"joint_limits": entries}))
        with (
            pytest.warns(UserWarning),
            pytest.raises(
                mjk.SpecError, match=r"^no acceleration limit for joints joint6, joint7 \(the arm"
            ),
        ):
            MotionPlanner(robot, limits=file)
        with pytest.warns(UserWarning, match=r"kinematics differ"):
            planner = MotionPlanner(robot, limits=str(file), acceleration_limits=[4.0] * 7)
        assert planner.velocity_limits.tolist() == pytest.approx(
            [2.0 + 0.1 * i for i in range(1, 8)]
        )
        assert planner.limits_source == f"velocity: {file}\nacceleration: given"
        # Our own file is the same format: RobotLimits saves what it loads.
        own = RobotLimits(
            velocity={"joint1": 1.0}, acceleration={"joint1": 3.0}, effort={"joint1": 80.0}
        )
        own.save(tmp_path / "own.yaml")
        again = RobotLimits.load(tmp_path / "own.yaml")
        assert (again.velocity, again.acceleration, again.effort) == (
            {"joint1": 1.0},
            {"joint1": 3.0},
            {"joint1": 80.0},
        )
        # Per joint, the first source that has a limit: the file for joint1, then the model's
        # (none in an MJCF), then nothing: the error lists the six others.
        with (
            pytest.warns(UserWarning),
            pytest.raises(
                mjk.SpecError,
                match=r"^no velocity limit for joints joint2, joint3, joint4, joint5, joint6, "
                r"joint7;",
            ),
        ):
            MotionPlanner(robot, limits=own)


@pytest.mark.parametrize(
    ("text", "error", "message"),
    [
        (
            "joint_limits: {joint1: {max_velocity: -1}}",
            mjk.SpecError,
            r"velocity of joint "
            r"'joint1' must be a finite number > 0, got -1",
        ),
        (
            "joint_limits: {joint1: {max_velocity: fast}}",
            mjk.SpecTypeError,
            r"velocity of joint "
            r"'joint1' must be a number, got 'fast'",
        ),
        (
            "joint_limits: {joint1: {has_acceleration_limits: true}}",
            mjk.SpecError,
            r"joint_limits\.joint1 has has_acceleration_limits: true but no max_acceleration",
        ),
        ("limits: {}", mjk.SpecError, r"has no 'joint_limits' mapping"),
        ("joint_limits: [1, 2", mjk.SpecError, r"is not YAML"),
    ],
)
def test_bad_joint_limits_files_are_refused_naming_the_file(tmp_path, text, error, message) -> None:
    file = tmp_path / "joint_limits.yaml"
    file.write_text(text)
    with pytest.raises(error, match=message) as raised:
        RobotLimits.load(file)
    assert str(file) in str(raised.value)
    with pytest.raises(mjk.ModelFileError, match=r"joint limits file '.*missing.yaml'"):
        RobotLimits.load(tmp_path / "missing.yaml")


def test_the_table_matches_names_and_kinematics_not_size(tmp_path) -> None:
    """A ViperX 300 (the WX250s model with the vx300s's joint origins: its summed offsets are
    0.724 m, the table's size guess was 0.80 m) is recognised; example-robot-data's UR10 is a
    UR10 (CB3), no longer taken for a UR10e by size; the Menagerie Panda is not an FR3."""
    folder = Path(menagerie("trossen_wx250s")).parent
    spec = mujoco.MjSpec.from_file(str(folder / "wx250s.xml"))
    spec.meshdir = spec.texturedir = str(folder / "assets")
    origins = {
        "shoulder_link": [0, 0, 0.079],
        "upper_arm_link": [0, 0, 0.04805],
        "upper_forearm_link": [0.05955, 0, 0.3],
        "lower_forearm_link": [0.2, 0, 0],
        "wrist_link": [0.1, 0, 0],
        "gripper_link": [0.069744, 0, 0],
    }
    for name, pos in origins.items():
        spec.body(f"wx250s/{name}").pos = pos
    (tmp_path / "vx300s.xml").write_text(spec.to_xml())
    model = mjk.Scene.build(base_spec(robots=[mjk.RobotSpec(path=str(tmp_path / "vx300s.xml"))]))
    with model as scene:
        robot = scene.create_robot("wx250s/base_link", "wx250s/gripper_link")
        assert match_datasheet(scene.model, robot.joint_names).sheet.arm == (
            "Trossen ViperX 300 6DOF (vx300s)"
        )
    with untested_arm("ur10") as env:
        robot = untested_robot(env, "ur10")
        assert match_datasheet(env.model, robot.joint_names).sheet.arm == (
            "Universal Robots UR10 (CB3)"
        )
    scene, robot = _build("panda")
    with scene:
        found = match_datasheet(scene.model, robot.joint_names)
        assert (found.sheet.arm, found.note) == ("Franka Emika Panda", "")
    # Each table entry's kinematics, through its own convention, gives the signature of
    # the models at hand (Menagerie's and example-robot-data's) within the tolerances.
    for name in ("panda", "iiwa14", "xarm7", "wx250s", "ur5", "gen3"):
        scene, robot = _build(name)
        with scene:
            sheet = match_datasheet(scene.model, robot.joint_names).sheet
            assert sheet is not None and sheet.arm.startswith(ARMS[name][4]), name


def test_an_srdf_disables_its_pairs_and_gives_its_groups(tmp_path) -> None:
    """example-robot-data's UR5 SRDF: its disabled pairs are allowed (reason "srdf" where
    sampling had not allowed them); the Z1's SRDF: a group with a chain and named states."""
    from mjkdl.urdf import example_robot_data_path

    scene, robot = _build("ur5")
    with scene:
        srdf = example_robot_data_path("ur_description/srdf/ur5.srdf")
        planner = MotionPlanner(robot, srdf=srdf, acm_samples=200)
        acm = planner.acm
        assert acm.reason("base_link", "upper_arm_link") == "srdf"
        assert acm.reason("forearm_link", "wrist_3_link") == "srdf"
        assert acm.reason("shoulder_link", "upper_arm_link") == "adjacent"  # as sampled
        assert acm.summary()["srdf"] == 4  # the 10 pairs less the 6 adjacent ones
        # Without a matrix, the pairs join allowed_contacts.
        bare = MotionPlanner(robot, srdf=Srdf.load(srdf), acm=False)
        assert ("forearm_link", "wrist_3_link") in bare.checker._allowed_names
        bad = tmp_path / "bad.srdf"
        bad.write_text(
            '<robot><disable_collisions link1="base_link" link2="wrist_9_link"/></robot>'
        )
        with pytest.raises(
            mjk.UnknownNameError,
            match=r"no body named 'wrist_9_link' in SRDF file '.*bad.srdf', disable_collisions 0",
        ):
            MotionPlanner(robot, srdf=bad, acm_samples=200)
    z1 = Srdf.load(example_robot_data_path("z1_description/srdf/z1.srdf"))
    group = z1.groups["end_effector"]
    assert group.joints == tuple(f"joint{i}" for i in range(1, 7))
    assert group.chains == (("base", "gripperMover"),)
    assert z1.states["arm_up"]["joint2"] == pytest.approx(0.26178)
    for text, message in (
        (
            "<robot><disable_collisions link1='a'/></robot>",
            r"a <disable_collisions> has no 'link2'",
        ),
        ("<robot", r"is not XML"),
        ("<urdf/>", r"the root element is <urdf>, not <robot>"),
    ):
        bad.write_text(text)
        with pytest.raises(mjk.SpecError, match=message):
            Srdf.load(bad)
    with pytest.raises(mjk.ModelFileError, match=r"SRDF file '.*nothing.srdf'"):
        Srdf.load(tmp_path / "nothing.srdf")


# ---------------------------------------------------------------------- padding


def _tight_wrist() -> mjk.Env:
    spec = mjk.SceneSpec(
        timestep=0.002,
        add_floor=True,
        add_skybox=False,
        robots=[mjk.RobotSpec(path=str(Path(__file__).parent / "assets" / "tight_wrist.xml"))],
    )
    return mjk.Env.build(spec)


TIGHT_LIMITS = {"velocity_limits": [2.0] * 4, "acceleration_limits": [5.0] * 4}
TIGHT_START = [0.0, -0.3, 0.0, 0.5]


def test_a_pair_always_within_the_padding_keeps_only_the_margin_and_the_arm_plans() -> None:
    """As the Lite 6's link4 and link6 (0 of 30 queries planned): the upper arm's knob is
    7 mm from the wrist's ball in every pose, inside margin + padding (10 mm), in contact
    within the margin in 7 % of the samples only (the hand). The matrix lists the pair as
    unpadded: the search checks it for the margin alone, and every query plans."""
    with _tight_wrist() as env:
        arm = env.create_robot("base", "l4")
        arm.set_joint_pos(np.array(TIGHT_START))
        arm.update()
        planner = MotionPlanner(arm, **TIGHT_LIMITS)
        acm = planner.acm
        assert acm.unpadded == [("l2", "l4")]
        assert acm.padded_fraction[("l2", "l4")] == 1.0
        assert 0.03 < acm.contact_fraction[("l2", "l4")] < 0.15
        assert acm.reason("l2", "l4") is None  # still checked: the hand can hit the knob
        assert planner.checker.contacts(TIGHT_START) == [("l2", "l4", pytest.approx(0.007))]
        hit = [0.0, -0.3, 0.0, -1.5]  # the hand folded up onto the knob
        assert not planner.checker.valid(hit)
        rng = np.random.default_rng(0)
        goals = [
            q
            for q in rng.uniform([-2.5, -1.2, -2.5, -2], [2.5, 1.2, 2.5, 2], (10, 4))
            if planner.checker.valid(q)
        ]
        assert len(goals) == 8
        for goal in goals:
            traj = planner.plan(goal, start=TIGHT_START, timeout=2.0)
            assert np.abs(traj.positions[-1] - goal).max() < 1e-12


def test_a_timeout_with_most_states_invalid_names_the_pair_and_link_padding_frees_it() -> None:
    """Without the matrix the pair keeps its padding: RRT (no wall test, so no dropping of
    the padding either) times out and names it; RRTConnect, after its wall test, goes on with
    the margin alone and plans; per-link padding frees the pair from the start."""
    with _tight_wrist() as env:
        arm = env.create_robot("base", "l4")
        arm.set_joint_pos(np.array(TIGHT_START))
        arm.update()
        goal = [1.5, 0.3, 1.0, -1.0]
        planner = MotionPlanner(arm, acm=False, planner="RRT", **TIGHT_LIMITS)  # padded
        with pytest.raises(
            PlanningTimeout,
            match=r"RRT found no collision-free path within 0.3 s \(\d+ states checked, status "
            r"[\w ]+, margin 5 mm\); (9\d|100)% of the states it checked were invalid, "
            r"[89]\d% of those for bodies 'l2' and 'l4' \(a median 7.0 mm apart, against "
            r"margin 5 mm \+ padding 5 mm\): if they may touch, allow the pair "
            r"\(planner.acm.allow\('l2', 'l4'\)\), else lower their padding "
            r"\(link_padding=\{'l4': 0.0\}\) or the margin",
        ):
            planner.plan(goal, timeout=0.3)
        connect = MotionPlanner(arm, acm=False, **TIGHT_LIMITS)
        assert np.abs(connect.plan(goal, timeout=2.0).positions[-1] - goal).max() < 1e-12
        assert connect.padding_dropped
        freed = MotionPlanner(arm, acm=False, link_padding={"l4": 0.0}, **TIGHT_LIMITS)
        assert np.abs(freed.plan(goal, timeout=2.0).positions[-1] - goal).max() < 1e-12
        assert not freed.padding_dropped
        with pytest.raises(mjk.UnknownNameError, match=r"no body named 'l9' in link_padding"):
            MotionPlanner(arm, acm=False, link_padding={"l9": 0.0}, **TIGHT_LIMITS)
        with pytest.raises(mjk.SpecError, match=r"link_padding\['l4'\] must be a finite number"):
            MotionPlanner(arm, acm=False, link_padding={"l4": -1.0}, **TIGHT_LIMITS)
