"""CollisionChecker: its clearances are MuJoCo's own distances, for every pair that can touch."""

from __future__ import annotations

import mujoco
import numpy as np
from conftest import tutorial_spec

import mjkdl as mjk
from mjkdl.plan import CollisionChecker

REACH = 0.03


def test_clearance_to_the_scene_matches_mujocos_geom_distance() -> None:
    # The Gen3's 2F-85 has bodies of several geoms (MuJoCo's midphase prunes their trees with
    # the bodies' margins) and the table is one body of several boxes: every pair of an arm
    # body and a scene object within REACH must be reported, at MuJoCo's distance.
    spec = tutorial_spec()
    spec.objects.append(
        mjk.SceneObject(
            name="wall",
            shape=mjk.Shape.BOX,
            size=[0.25, 0.01, 0.3],
            pos=[0.5, 0.0, 1.0],
            fixed=True,
        )
    )
    env = mjk.Env.build(spec)
    try:
        robot = env.create_robot("base_link", "bracelet_link")
        checker = CollisionChecker(robot, 0.005, reach=REACH)
        m = env.model
        data = mujoco.MjData(m)
        mujoco.mj_copyData(data, m, env.data)
        scene_bodies = {m.body(name).id for name in ("table", "cube", "wall")}
        root = m.joint(robot.joint_names[0]).bodyid[0]

        def on_arm(body: int) -> bool:
            while body > root:
                body = m.body_parentid[body]
            return body == root

        arm_geoms = [
            g
            for g in range(m.ngeom)
            if on_arm(m.geom_bodyid[g]) and (m.geom_contype[g] or m.geom_conaffinity[g])
        ]
        scene_geoms = [g for g in range(m.ngeom) if m.geom_bodyid[g] in scene_bodies]
        limits = robot.joint_limits
        low = np.where(np.isfinite(limits[:, 0]), limits[:, 0], -np.pi)
        high = np.where(np.isfinite(limits[:, 1]), limits[:, 1], np.pi)
        fromto = np.zeros(6)
        compared = 0
        for q in np.random.default_rng(0).uniform(low, high, (150, robot.n_joints)):
            data.qpos[checker.arm_qpos_adr] = q
            mujoco.mj_kinematics(m, data)
            reference: dict[tuple[str, str], float] = {}
            for a in arm_geoms:
                for s in scene_geoms:
                    d = mujoco.mj_geomDistance(m, data, a, s, REACH, fromto)
                    key = (m.body(m.geom_bodyid[a]).name, m.body(m.geom_bodyid[s]).name)
                    reference[key] = min(reference.get(key, np.inf), d)
            ours = {
                (a, b) if (a, b) in reference else (b, a): d
                for a, b, d in checker.contacts(q)
                if (a, b) in reference or (b, a) in reference
            }
            for key, d in reference.items():
                if d >= REACH - 1e-3:  # at the edge of the reach either answer is right
                    continue
                assert key in ours, (key, d)
                if d >= 0.0:  # penetration depths differ between MuJoCo's pair functions
                    assert abs(ours[key] - d) < 1e-3, (key, ours[key], d)
                    compared += 1
        assert compared > 20
    finally:
        env.close()
