"""Motion planning: success, planning time and clearance on random queries in clutter.

For Menagerie's Panda (with its hand, on the floor) and the tutorial's Gen3 + 2F-85 (on the
table), the same clutter is placed around the arm's base: two shelves, a wall between them, two
posts, a box and a beam overhead. Queries are pairs of random joint configurations (uniform
within the limits, unlimited joints in [-π, π]) that keep the planner's 5 mm margin, drawn
with np.random.default_rng(0). Each is planned with `MotionPlanner.plan(goal, start=...,
timeout=1.0)` (RRTConnect): success within the timeout, planning time (everything: search,
simplification, toppra, the final check) and the search alone, as median and 90th percentile.

Then, in the same process:
  * each query's planning time in mj_steps of the same model, timed just before it (the
    shared machine's speed drifts);
  * the cost of one validity check (`CollisionChecker.valid`) on random configurations, as a
    ratio to one raw `mj_step` of the same model;
  * every planned trajectory is executed in the simulation (`TrajectoryFollower`, POSITION
    mode) and the measured arm's clearance to everything is taken at every physics step: the
    smallest, and how many trajectories came closer than the margin.

The time split of our plans (IK and pocket tests at the ends, search, simplification,
timing, final check) is printed as medians, then three like-for-like comparisons, each on
the same queries in the same run:

  (a) plain OMPL: the same RRTConnect, range, resolution and simplifier, our
      `CollisionChecker.valid` as its validity function; against our search + simplification.
  (b) (a) followed by toppra (the library: the same spline and grid as ours, its seidel
      solver, ParametrizeConstAccel) and a hand-written final check of the timed path every
      0.05 rad at the margin (no finer checks near obstacles, no re-timing when it fails);
      against our whole plan.
  (c) roboplan 0.7 (C++ RRT-Connect over Pinocchio + coal), where it imports, on the Panda
      with its own collision model: Menagerie's panda.xml through its own MJCF loader (coal
      meshes), the clutter as its boxes, the pairs our allowed-collision matrix allows (and
      adjacent links) disabled, our velocity and acceleration limits; no clearance margin
      (contact only). Its search alone, and its whole pipeline: search, its PathShortcutter
      (collision steps of 0.1 rad) and its C++ TOPP-RA (Hermite spline), with no check after
      timing. It needs LD_LIBRARY_PATH to reach the cmeel Pinocchio libraries
      (benchmarks/README.md). VAMP (`vamp-planner` 0.6.4) is an sdist whose CMake fetches
      its dependencies from GitHub: it does not build without network access, and the
      benchmark says so.

pyroboplan (the peer the issue names), where it imports, plans the same queries in the same
run: its RRTConnect (`rrt_connect`, `bidirectional_rrt`), the same timeout, its own collision
checking (Pinocchio + coal) with the same 5 mm as its `collision_distance_padding`, checking
segments every 0.1 rad like our search. Its models are built from ours for both robots: our
Pinocchio model with the fingers held where they are, and every collision geom MuJoCo uses
(meshes as coal convex hulls of MuJoCo's mesh vertices — MuJoCo collides meshes as their
convex hulls —, boxes, the floor as a half-space) with the pairs MuJoCo's filters leave
(contype/conaffinity, parent/child, <exclude>s, nothing between two parts that stay fixed
relative to each other). The same geometry and the same pairs: only the planner and the
checker differ. Unlimited joints (the Gen3's) are sampled within [-π, π], where the queries
are. pyroboplan is not a dependency: `pip install --no-deps pyroboplan==1.3.1`, then
`pip install meshcat` (benchmarks/README.md says why).

    python benchmarks/planning.py                      # a few minutes
    python benchmarks/planning.py --queries 10 --execute 3
"""

from __future__ import annotations

import argparse
import contextlib
import io
import itertools
import tempfile
import time

import mujoco
import numpy as np
import pinocchio as pin
from scenes import HOME, TOOL, tabletop_spec

import mjkdl as mjk
from mjkdl.plan import CollisionChecker, MotionPlanner, PlanningError, TrajectoryFollower

PANDA_HOME = [0.0, 0.0, 0.0, -1.57079, 0.0, 1.57079, -0.7853]
PANDA_TCP = [0.0, 0.0, 0.1034]
TABLE_TOP = 0.7


def clutter(base: np.ndarray) -> list[mjk.SceneObject]:
    """Shelves, a wall, posts, a box and a beam around an arm whose base is at `base`."""

    def box(name: str, size: list[float], offset: list[float]) -> mjk.SceneObject:
        return mjk.SceneObject(
            name=name,
            shape=mjk.Shape.BOX,
            size=size,
            pos=list(base + offset),
            fixed=True,
            rgba=[0.6, 0.5, 0.4, 1.0],
        )

    return [
        box("shelf_a", [0.12, 0.12, 0.01], [0.45, 0.35, 0.29]),
        box("shelf_b", [0.12, 0.12, 0.01], [0.45, -0.35, 0.29]),
        box("wall", [0.25, 0.01, 0.35], [0.55, 0.0, 0.35]),
        box("post_a", [0.04, 0.04, 0.3], [-0.3, 0.4, 0.3]),
        box("post_b", [0.05, 0.05, 0.25], [-0.35, -0.35, 0.25]),
        box("block", [0.08, 0.08, 0.08], [0.0, 0.55, 0.08]),
        box("beam", [0.02, 0.5, 0.02], [0.3, 0.0, 1.0]),
    ]


def panda_scene() -> tuple[mjk.Env, mjk.Robot, list[float]]:
    arm = mjk.RobotSpec(path=mjk.menagerie.model_path("franka_emika_panda"))
    spec = mjk.SceneSpec(
        timestep=0.002,
        add_floor=True,
        add_skybox=False,
        robots=[arm],
        objects=clutter(np.zeros(3)),
    )
    env = mjk.Env.build(spec)
    robot = env.create_robot("link0", "hand", tool=mjk.ToolFrameSpec(tcp_pos=PANDA_TCP))
    return env, robot, PANDA_HOME


def gen3_scene() -> tuple[mjk.Env, mjk.Robot, list[float]]:
    spec = tabletop_spec()
    spec.objects += clutter(np.array([0.0, 0.0, TABLE_TOP]))
    env = mjk.Env.build(spec)
    return env, env.create_robot("base_link", "bracelet_link", tool=TOOL), HOME


def queries(planner: MotionPlanner, count: int, rng: np.random.Generator) -> list[np.ndarray]:
    """`count` + 1 random configurations that keep the margin (consecutive pairs: queries)."""
    limits = planner.robot.joint_limits
    low = np.where(np.isfinite(limits[:, 0]), limits[:, 0], -np.pi)
    high = np.where(np.isfinite(limits[:, 1]), limits[:, 1], np.pi)
    out: list[np.ndarray] = []
    while len(out) <= count:
        q = rng.uniform(low, high)
        if planner.checker.valid(q):
            out.append(q)
    return out


# Why VAMP is not in the comparison (checked with `pip download vamp-planner --no-deps`).
VAMP = (
    "vamp-planner 0.6.4 is an sdist only; its CMake downloads CPM.cmake and fetches nanobind, "
    "nigh, pdqsort and SIMDxorshift from GitHub at build time: no build without network access"
)


def _stat(ms: np.ndarray) -> str:
    return f"median {np.median(ms):.1f} ms, p90 {np.percentile(ms, 90):.1f} ms"


def per_call(fn, count: int) -> float:
    """Median seconds per call of `fn` over 7 blocks of `count` calls."""
    blocks = []
    for _ in range(7):
        t0 = time.perf_counter()
        for _ in range(count):
            fn()
        blocks.append((time.perf_counter() - t0) / count)
    return float(np.median(blocks))


def pyroboplan_models(env: mjk.Env, robot: mjk.Robot) -> tuple | str:
    """pyroboplan's view of the scene: our Pinocchio model (fingers held), a coal geometry
    model of the geoms MuJoCo collides with MuJoCo's pairs, and the whole model's q at the
    scene's state (for the fingers); or why not."""
    try:
        import coal
        from pyroboplan.planning.rrt import RRTPlanner  # noqa: F401
    except ImportError as error:
        return f"not importable ({error})"
    m, d = env.model, env.data
    arm = [m.joint(j).id for j in robot.joint_names]
    moving = np.zeros(m.nbody, dtype=bool)
    group = np.full(m.nbody, -1)
    for k, j in enumerate(arm):
        root = int(m.jnt_bodyid[j])
        for b in range(root, m.nbody):
            if b == root or group[m.body_parentid[b]] >= k:
                group[b], moving[b] = k, True
    full = robot.model
    q_ref = pin.neutral(full)
    for jid in range(1, full.njoints):
        q_ref[full.idx_qs[jid]] = d.qpos[m.jnt_qposadr[m.joint(full.names[jid]).id]]
    geoms = pin.GeometryModel()
    index = {}
    for g in range(m.ngeom):
        if not (m.geom_contype[g] or m.geom_conaffinity[g]):
            continue
        shape = _coal_shape(coal, m, g)
        body = int(m.geom_bodyid[g])
        if moving[body]:
            fid = full.getFrameId(m.body(body).name)
            frame = full.frames[fid]
            local = pin.SE3(_quat_matrix(m.geom_quat[g]), m.geom_pos[g].copy())
            obj = pin.GeometryObject(
                f"g{g}", frame.parentJoint, fid, frame.placement * local, shape
            )
        else:
            world = pin.SE3(d.geom_xmat[g].reshape(3, 3).copy(), d.geom_xpos[g].copy())
            obj = pin.GeometryObject(f"g{g}", 0, 0, world, shape)
        index[g] = geoms.addGeometryObject(obj)
    # The fingers are held where they are: their limits pinned to their position (pyroboplan
    # samples within the limits). Pinocchio's buildReducedModel needs joint frames ours lacks.
    model = full.copy()
    fixed = np.ones(model.nq, dtype=bool)
    fixed[robot.arm_q] = False
    low, high = model.lowerPositionLimit, model.upperPositionLimit
    low[fixed] = high[fixed] = q_ref[fixed]
    unlimited = ~np.isfinite(high)
    low[unlimited], high[unlimited] = -np.pi, np.pi
    model.lowerPositionLimit, model.upperPositionLimit = low, high
    excluded = set(m.exclude_signature.tolist())
    weld = m.body_weldid
    for a, b in itertools.combinations(index, 2):
        ba, bb = int(m.geom_bodyid[a]), int(m.geom_bodyid[b])
        if not (moving[ba] or moving[bb]) or (moving[ba] and moving[bb] and group[ba] == group[bb]):
            continue
        if not (
            m.geom_contype[a] & m.geom_conaffinity[b] or m.geom_contype[b] & m.geom_conaffinity[a]
        ):
            continue
        wa, wb = int(weld[ba]), int(weld[bb])
        parent_a, parent_b = int(weld[m.body_parentid[wa]]), int(weld[m.body_parentid[wb]])
        if wa == wb or (wa and wb and (wa == parent_b or wb == parent_a)):
            continue
        if (min(ba, bb) << 16) + max(ba, bb) in excluded:
            continue
        geoms.addCollisionPair(pin.CollisionPair(index[a], index[b]))
    return model, geoms, q_ref


def _coal_shape(coal, m: mujoco.MjModel, g: int) -> object:
    """The coal shape of MuJoCo geom `g` (a mesh: the convex hull MuJoCo collides)."""
    size, kind = m.geom_size[g], m.geom_type[g]
    if kind == mujoco.mjtGeom.mjGEOM_MESH:
        mesh = m.geom_dataid[g]
        start, count = m.mesh_vertadr[mesh], m.mesh_vertnum[mesh]
        points = coal.StdVec_Vec3s()
        points.extend(list(m.mesh_vert[start : start + count].astype(float)))
        return coal.Convex.convexHull(points, False, None)
    if kind == mujoco.mjtGeom.mjGEOM_BOX:
        return coal.Box(*(2.0 * size))
    if kind == mujoco.mjtGeom.mjGEOM_PLANE:
        return coal.Halfspace(np.array([0.0, 0.0, 1.0]), 0.0)
    if kind == mujoco.mjtGeom.mjGEOM_SPHERE:
        return coal.Sphere(size[0])
    if kind == mujoco.mjtGeom.mjGEOM_CAPSULE:
        return coal.Capsule(size[0], 2.0 * size[1])
    if kind == mujoco.mjtGeom.mjGEOM_CYLINDER:
        return coal.Cylinder(size[0], 2.0 * size[1])
    raise ValueError(f"geom {g}: type {kind} has no coal shape here")


def _whole(q_ref: np.ndarray, arm: np.ndarray) -> np.ndarray:
    """The whole model's q: the arm's joints first (mjkdl's arm_q), the rest as in q_ref."""
    q = q_ref.copy()
    q[: len(arm)] = arm
    return q


def _quat_matrix(quat: np.ndarray) -> np.ndarray:
    mat = np.zeros(9)
    mujoco.mju_quat2Mat(mat, quat)
    return mat.reshape(3, 3)


def run_pyroboplan(
    models: tuple,
    configs: list[np.ndarray],
    timeout: float,
    margin: float,
    step_time,
) -> tuple[list[float], list[float], int]:
    """pyroboplan's RRTConnect on the consecutive pairs of `configs`: the seconds of each
    solved query, the same in mj_steps (`step_time()` just before each), failures."""
    from pyroboplan.planning.rrt import RRTPlanner, RRTPlannerOptions

    model, geoms, q_ref = models
    options = RRTPlannerOptions(
        max_step_size=0.1,
        rrt_connect=True,
        bidirectional_rrt=True,
        max_planning_time=timeout,
        rng_seed=0,
        collision_distance_padding=margin,
    )
    planner = RRTPlanner(model, geoms, options=options)
    seconds, steps, failures = [], [], 0
    whole = [_whole(q_ref, q) for q in configs]
    for start, goal in itertools.pairwise(whole):
        step = step_time()
        t0 = time.perf_counter()
        # It prints its progress, and divides by zero when a sample repeats a node.
        with contextlib.redirect_stdout(io.StringIO()), np.errstate(invalid="ignore"):
            path = planner.plan(start, goal)
        elapsed = time.perf_counter() - t0
        if not path:
            failures += 1
            continue
        seconds.append(elapsed)
        steps.append(elapsed / step)
    return seconds, steps, failures


def run_plain_ompl(
    planner: MotionPlanner, configs: list[np.ndarray], timeout: float
) -> tuple[list[float], list[np.ndarray], int]:
    """Plain OMPL RRTConnect with our checker as the validity function, the same range,
    resolution and simplifier: seconds (search + simplification) and the simplified path
    (waypoints) per solved query, failures."""
    from ompl import base as ob
    from ompl import geometric as og
    from ompl import util as ou

    from mjkdl.plan.planner import RANGE, SIMPLIFY

    n = planner.robot.n_joints
    limits = planner.robot.joint_limits
    low = np.where(np.isfinite(limits[:, 0]), limits[:, 0], -np.pi)
    high = np.where(np.isfinite(limits[:, 1]), limits[:, 1], np.pi)
    space = ob.RealVectorStateSpace(n)
    bounds = ob.RealVectorBounds(n)
    for i in range(n):
        bounds.setLow(i, float(low[i]))
        bounds.setHigh(i, float(high[i]))
    space.setBounds(bounds)
    si = ob.SpaceInformation(space)
    valid = planner.checker.valid
    si.setStateValidityChecker(lambda state: valid(state[0:n]))
    si.setStateValidityCheckingResolution(0.1 / space.getMaximumExtent())
    si.setup()
    ou.setLogLevel(ou.LOG_NONE)
    seconds, paths, failures = [], [], 0
    for start, goal in itertools.pairwise(configs):
        t0 = time.perf_counter()
        setup = og.SimpleSetup(si)
        rrt = og.RRTConnect(si)
        rrt.setRange(RANGE)
        setup.setPlanner(rrt)
        a, b = si.allocState(), si.allocState()
        for i in range(n):
            a[i], b[i] = float(start[i]), float(goal[i])
        setup.setStartAndGoalStates(a, b)
        setup.solve(timeout)
        if not setup.haveExactSolutionPath():
            failures += 1
            continue
        path = setup.getSolutionPath()
        simplifier = og.PathSimplifier(si)
        for name in SIMPLIFY:
            getattr(simplifier, name)(path)
        waypoints = np.array([state[0:n] for state in path.getStates()])
        seconds.append(time.perf_counter() - t0)
        paths.append(waypoints)
    return seconds, paths, failures


def run_plain_pipeline(
    planner: MotionPlanner, paths: list[np.ndarray]
) -> tuple[list[float], list[float], int]:
    """The rest of a hand-written pipeline on plain OMPL's paths: toppra (the library: the
    same natural spline and grid as ours, its seidel solver, ParametrizeConstAccel, the
    constraints built once) and a final check of the timed path every CHECK_STEP (rad, any
    joint) at the margin, without the finer checks near obstacles ours adds. Seconds of the
    timing and of the check per path; paths that fail the check (not re-timed)."""
    import toppra
    import toppra.algorithm
    import toppra.constraint

    from mjkdl.plan.planner import CHECK_STEP
    from mjkdl.plan.trajectory import KNOT_PERIOD, TimeParametrizer

    v, a = planner.velocity_limits, planner.acceleration_limits
    constraints = [
        toppra.constraint.JointVelocityConstraint(np.column_stack([-v, v])),
        toppra.constraint.JointAccelerationConstraint(np.column_stack([-a, a])),
    ]
    gridder = TimeParametrizer(v, a)
    valid = planner.checker.valid
    timing, checking, failures = [], [], 0
    for waypoints in paths:
        t0 = time.perf_counter()
        _spline, grid, points = gridder.grid(waypoints)
        s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))])
        path = toppra.SplineInterpolator(s, points, bc_type="natural")
        traj = toppra.algorithm.TOPPRA(
            constraints,
            path,
            gridpoints=grid,
            solver_wrapper="seidel",
            parametrizer="ParametrizeConstAccel",
        ).compute_trajectory(0.0, 0.0)
        t1 = time.perf_counter()
        times = np.append(np.arange(0.0, traj.duration, KNOT_PERIOD), traj.duration)
        q = traj(times)
        travelled = np.concatenate([[0.0], np.cumsum(np.abs(np.diff(q, axis=0)).max(axis=1))])
        marks = np.floor(travelled / CHECK_STEP)
        keep = np.diff(marks, prepend=-1.0) > 0
        keep[-1] = True
        ok = all(valid(state) for state in q[keep])
        t2 = time.perf_counter()
        timing.append(t1 - t0)
        checking.append(t2 - t1)
        failures += not ok
    return timing, checking, failures


def roboplan_scene(env: mjk.Env, planner: MotionPlanner) -> tuple | str:
    """roboplan's own model of the Panda scene, or why not."""
    try:
        from roboplan.core import Box, Scene, loadJointLimitsConfig, loadMjcfModel
    except ImportError as error:
        return f"roboplan does not import ({error})"
    scene = Scene("panda", loadMjcfModel(mjk.menagerie.model_path("franka_emika_panda")))
    scene.allowAdjacentLinkCollisions()
    pairs = [("hand", "left_finger"), ("hand", "right_finger"), ("left_finger", "right_finger")]
    acm = planner.acm.pairs if planner.acm is not None else {}
    pairs += list(acm)
    names = set(scene.getJointNames())
    scene.setCollisions(pairs, False)
    m = env.model
    for obj in clutter(np.zeros(3)):
        g = m.body(obj.name).id
        pose = np.eye(4)
        pose[:3, 3] = m.body_pos[g]
        size = 2.0 * np.asarray(obj.size)  # coal boxes take full side lengths
        scene.addBoxGeometry(obj.name, "universe", Box(*size), pose, np.ones(4))
    floor = np.eye(4)
    floor[2, 3] = -0.052  # its top 2 mm below the posts and the base: not touching them
    scene.addBoxGeometry("floor", "universe", Box(4.0, 4.0, 0.1), floor, np.ones(4))
    scene.addGroupFromChain("arm", "link0", "link7")
    # Menagerie's MJCF has no velocity or acceleration limits: ours, as MoveIt's YAML.
    lines = ["joint_limits:"]
    for name, v, a in zip(
        planner.robot.joint_names,
        planner.velocity_limits,
        planner.acceleration_limits,
        strict=True,
    ):
        lines += [f"  {name}:", "    has_velocity_limits: true", f"    max_velocity: [{v}]"]
        lines += ["    has_acceleration_limits: true", f"    max_acceleration: [{a}]"]
    with tempfile.NamedTemporaryFile("w", suffix=".yaml") as f:
        f.write("\n".join(lines) + "\n")
        f.flush()
        scene.importJointLimitsFromConfig(loadJointLimitsConfig(f.name))
    return scene, sorted(names)


def run_roboplan(
    rp: tuple, robot: mjk.Robot, configs: list[np.ndarray], timeout: float, step_time
) -> dict[str, list[float]]:
    """roboplan's own pipeline on the consecutive pairs of `configs` (the fingers held): its
    RRT-Connect, its path shortcutter (collision steps of 0.1 rad like the search) and its
    C++ TOPP-RA (Hermite spline) under our limits; no check after timing. Seconds of each
    stage per solved query, the search in mj_steps, trajectory durations, failures."""
    from roboplan.core import JointConfiguration, PathShortcutter, PathShortcuttingOptions
    from roboplan.rrt import RRT, RRTOptions
    from roboplan.toppra import PathParameterizerTOPPRA, TOPPRAOptions

    scene, _names = rp
    options = RRTOptions(
        group_name="arm",
        max_nodes=100000,
        max_connection_distance=2.0,
        collision_check_step_size=0.1,
        max_planning_time=timeout,
        rrt_connect=True,
    )
    rrt = RRT(scene, options)
    rrt.setRngSeed(0)
    shortcutter = PathShortcutter(
        scene, PathShortcuttingOptions(group_name="arm", max_step_size=0.1)
    )
    timing = PathParameterizerTOPPRA(scene, "arm")
    joints = robot.joint_names
    out: dict[str, list[float]] = {
        k: [] for k in ("search", "shortcut", "timing", "steps", "duration", "failures")
    }
    for start, goal in itertools.pairwise(configs):
        step = step_time()
        t0 = time.perf_counter()
        try:
            path = rrt.plan(JointConfiguration(joints, start), JointConfiguration(joints, goal))
        except RuntimeError:
            path = None
        t1 = time.perf_counter()
        if path is None or not len(path.positions):
            out["failures"].append(1.0)
            continue
        short = shortcutter.shortcut(path)
        t2 = time.perf_counter()
        traj = timing.generate(short, TOPPRAOptions())
        t3 = time.perf_counter()
        out["search"].append(t1 - t0)
        out["shortcut"].append(t2 - t1)
        out["timing"].append(t3 - t2)
        out["steps"].append((t1 - t0) / step)
        out["duration"].append(float(traj.times[-1]))
    return out


def roboplan_agreement(rp: tuple, planner: MotionPlanner, configs: list[np.ndarray]) -> float:
    """How often roboplan's checker (contact) agrees with ours at zero margin."""
    scene, names = rp
    zero = CollisionChecker(planner.robot, 0.0)
    fingers = np.full(len(names) - planner.robot.n_joints, 0.0)
    rng = np.random.default_rng(1)
    limits = planner.robot.joint_limits
    same = 0
    samples = rng.uniform(limits[:, 0], limits[:, 1], (300, planner.robot.n_joints))
    for q in samples:
        same += (not scene.hasCollisions(np.concatenate([q, fingers]))) == zero.valid(q)
    return same / len(samples)


def checker_agreement(planner: MotionPlanner, models: tuple, rng: np.random.Generator) -> float:
    """The fraction of 300 random configurations on which pyroboplan's checker (coal, same
    clearance) and ours give the same verdict: that both see the same scene."""
    from pyroboplan.core.utils import check_collisions_at_state

    model, geoms, q_ref = models
    data, geom_data = model.createData(), geoms.createData()
    limits = planner.robot.joint_limits
    low = np.where(np.isfinite(limits[:, 0]), limits[:, 0], -np.pi)
    high = np.where(np.isfinite(limits[:, 1]), limits[:, 1], np.pi)
    same = 0
    for q in rng.uniform(low, high, (300, len(low))):
        theirs = not check_collisions_at_state(
            model, geoms, _whole(q_ref, q), data, geom_data, distance_padding=planner.margin
        )
        same += theirs == planner.checker.valid(q)
    return same / 300


def benchmark(name: str, scene, args: argparse.Namespace) -> None:
    env, robot, home = scene()
    robot.ctrl_mode = mjk.CtrlMode.POSITION
    env.on_reset = lambda ctx: robot.set_joint_pos(home, call_forward=False)
    env.reset()
    robot.update()
    planner = MotionPlanner(robot)
    rng = np.random.default_rng(0)
    configs = queries(planner, args.queries, rng)
    planner.plan(configs[1], start=configs[0])  # warm-up (imports, first IK)

    # Each query is also timed in mj_steps of the same model, measured just before it: the
    # shared machine's speed drifts by 2x and more within minutes.
    scratch = mujoco.MjData(env.model)
    mujoco.mj_copyData(scratch, env.model, env.data)

    def step_time() -> float:
        t0 = time.perf_counter()
        for _ in range(20):
            mujoco.mj_step(env.model, scratch)
        return (time.perf_counter() - t0) / 20

    rp = roboplan_scene(env, planner) if name.startswith("Panda") else "Panda only here"
    models = pyroboplan_models(env, robot)
    # Every planner takes each query in turn (the shared machine's load drifts within
    # minutes: planners timed minutes apart would compare loads, not planners).
    total, search, steps, trajectories, failures, split = [], [], [], [], [], []
    plain, plain_failures = [], 0
    plain_timing, plain_check, plain_unsafe = [], [], 0
    rp_result: dict[str, list[float]] = {}
    theirs: tuple[list[float], list[float], int] = ([], [], 0)
    for start, goal in itertools.pairwise(configs):
        step_now = step_time()
        t0 = time.perf_counter()
        try:
            traj = planner.plan(goal, start=start, timeout=args.timeout)
        except PlanningError as error:
            failures.append(str(error).split(":")[0])
        else:
            total.append(time.perf_counter() - t0)
            steps.append(total[-1] / step_now)
            search.append(planner.last_stats["search"] + planner.last_stats["simplify"])
            split.append(dict(planner.last_stats))
            trajectories.append(traj)
        seconds, paths, failed = run_plain_ompl(planner, [start, goal], args.timeout)
        plain += seconds
        plain_failures += failed
        timing, checking, unsafe = run_plain_pipeline(planner, paths)
        plain_timing += timing
        plain_check += checking
        plain_unsafe += unsafe
        if not isinstance(rp, str):
            for key, values in run_roboplan(
                rp, robot, [start, goal], args.timeout, step_time
            ).items():
                rp_result.setdefault(key, []).extend(values)
        if not isinstance(models, str):
            one = run_pyroboplan(models, [start, goal], args.timeout, planner.margin, step_time)
            theirs = (theirs[0] + one[0], theirs[1] + one[1], theirs[2] + one[2])
    if not isinstance(rp, str):
        rp_agree = roboplan_agreement(rp, planner, configs)
    if not isinstance(models, str):
        agree = checker_agreement(planner, models, rng)

    # One validity check against one raw mj_step (on a scratch copy of the same state).
    samples = rng.uniform(-1.0, 1.0, (1000, robot.n_joints)) * 0.5 + np.array(home)
    index = iter(range(10**9))
    check = per_call(lambda: planner.checker.valid(samples[next(index) % 1000]), 1000)
    step = per_call(lambda: mujoco.mj_step(env.model, scratch), 1000)

    # Execute, measuring the measured arm's clearance at every step.
    watch = CollisionChecker(robot, planner.margin, reach=0.05)
    follower = TrajectoryFollower(robot)
    closest, below = [], 0
    for traj in trajectories[: args.execute]:
        env.reset()
        robot.set_joint_pos(traj.positions[0])
        robot.sync_commands()
        watch.sync()
        mins = [np.inf]

        def measure(mins: list[float] = mins) -> None:
            mins.append(watch.clearance(env.data.qpos[watch.arm_qpos_adr]))

        follower.run(traj, after_step=measure)
        closest.append(min(mins))
        below += min(mins) < planner.margin

    n = args.queries
    ms_total, ms_search = np.array(total) * 1e3, np.array(search) * 1e3
    print(f"{name}: {n} random queries, RRTConnect, timeout {args.timeout:g} s, margin 5 mm")
    print(f"  solved:                {len(total) / n * 100:.1f} % ({len(total)}/{n})")
    if failures:
        print(f"  failures:              {', '.join(sorted(set(failures)))}")
    print(
        f"  planning time:         median {np.median(ms_total):.1f} ms, "
        f"p90 {np.percentile(ms_total, 90):.1f} ms (search + simplification + toppra + check)"
    )
    print(
        f"  planning time / step:  median {np.median(steps):.0f} mj_steps, "
        f"p90 {np.percentile(steps, 90):.0f} (each against a step timed just before it)"
    )
    print(
        f"  search + simplify:     median {np.median(ms_search):.1f} ms, "
        f"p90 {np.percentile(ms_search, 90):.1f} ms"
    )
    print(f"  straight line enough:  {np.mean(np.array(search) == 0) * 100:.0f} % of solved")
    medians = {k: np.median([s[k] for s in split]) * 1e3 for k in split[0]}
    print(
        "  time split (medians):  "
        + ", ".join(f"{k} {v:.2f} ms" for k, v in medians.items() if k != "project")
    )
    ms_plain = np.array(plain) * 1e3
    ms_whole = (np.array(plain) + plain_timing + plain_check) * 1e3
    print(
        f"  (a) plain OMPL:        solved {len(plain) / n * 100:.1f} % ({plain_failures} failed), "
        f"{_stat(ms_plain)} (search + the same simplification)"
    )
    print(
        f"      ours / plain:      search + simplification "
        f"{np.median(ms_search) / np.median(ms_plain):.2f}x (medians)"
    )
    print(
        f"  (b) plain + toppra + check: {_stat(ms_whole)}; toppra median "
        f"{np.median(plain_timing) * 1e3:.2f} ms, check {np.median(plain_check) * 1e3:.2f} ms; "
        f"{plain_unsafe} of {len(plain)} timed paths fail the check (not re-timed)"
    )
    print(
        f"      ours / (b):        whole plan {np.median(ms_total) / np.median(ms_whole):.2f}x; "
        f"ours whole / plain search + simplification "
        f"{np.median(ms_total) / np.median(ms_plain):.2f}x (medians)"
    )
    if isinstance(rp, str):
        print(f"  roboplan:              {rp}; skipped")
    else:
        ms_rp = np.array(rp_result["search"]) * 1e3
        ms_rp_whole = (
            np.array(rp_result["search"]) + rp_result["shortcut"] + np.array(rp_result["timing"])
        ) * 1e3
        solved = len(rp_result["search"])
        print(
            f"  (c) roboplan 0.7:      solved {solved / n * 100:.1f} % "
            f"({len(rp_result['failures'])} failed); search {_stat(ms_rp)}; search + its "
            f"shortcutter + its TOPP-RA {_stat(ms_rp_whole)} (shortcut median "
            f"{np.median(rp_result['shortcut']) * 1e3:.1f} ms, TOPP-RA "
            f"{np.median(rp_result['timing']) * 1e3:.2f} ms); trajectory duration median "
            f"{np.median(rp_result['duration']):.2f} s; no margin, no check after timing (its "
            f"checker agrees with ours at zero margin on {rp_agree * 100:.1f} % of random states)"
        )
        print(
            f"      ours / roboplan:   whole plan / its whole pipeline "
            f"{np.median(ms_total) / np.median(ms_rp_whole):.2f}x; whole plan / its search "
            f"{np.median(ms_total) / np.median(ms_rp):.2f}x "
            f"({np.median(steps) / np.median(rp_result['steps']):.2f}x in mj_steps); search + "
            f"simplification / its search {np.median(ms_search) / np.median(ms_rp):.2f}x"
        )
    print(f"  VAMP:                  {VAMP}; skipped")
    print(f"  trajectory duration:   median {np.median([t.duration for t in trajectories]):.2f} s")
    print(
        f"  validity check:        {check * 1e6:.1f} us = {check / step:.2f} x mj_step "
        f"({step * 1e6:.1f} us)"
    )
    if closest:
        print(
            f"  executed:              {len(closest)} trajectories, closest approach "
            f"{min(closest) * 1000:.2f} mm, {below} closer than the margin"
        )
    if isinstance(models, str):
        print(f"  pyroboplan:            {models}; skipped")
    else:
        seconds, their_steps, their_failures = theirs
        ms = np.array(seconds) * 1e3
        print(
            f"  pyroboplan RRTConnect: solved {len(seconds) / n * 100:.1f} % "
            f"({their_failures} failed), median {np.median(ms):.1f} ms, p90 "
            f"{np.percentile(ms, 90):.1f} ms; median {np.median(their_steps):.0f} mj_steps "
            f"(its checker agrees with ours on {agree * 100:.1f} % of random states)"
        )
        print(
            f"  speed ratio:           pyroboplan's median / ours = "
            f"{np.median(ms) / np.median(ms_total):.1f} (ms), "
            f"{np.median(their_steps) / np.median(steps):.1f} (mj_steps)"
        )
    env.close()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--queries", type=int, default=100)
    parser.add_argument("--timeout", type=float, default=1.0)
    parser.add_argument("--execute", type=int, default=100, help="trajectories run in simulation")
    parser.add_argument("--robots", nargs="+", default=["panda", "gen3"])
    args = parser.parse_args()
    scenes = {"panda": ("Panda + hand", panda_scene), "gen3": ("Gen3 + 2F-85", gen3_scene)}
    for key in args.robots:
        benchmark(*scenes[key], args)


if __name__ == "__main__":
    main()
