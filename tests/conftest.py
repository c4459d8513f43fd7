"""Shared fixtures: Menagerie lookup for tests, and the tutorial's tabletop scene."""

from __future__ import annotations

import importlib.util
import os
import re
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
ASSETS = ROOT / "mjkdl" / "assets"
_SHARED_MENAGERIE = ROOT.parent / "shared" / "menagerie"

if "MENAGERIE_ROOT" not in os.environ and _SHARED_MENAGERIE.is_dir():
    os.environ["MENAGERIE_ROOT"] = str(_SHARED_MENAGERIE)
# Offscreen rendering without a display; MuJoCo reads this once, when first imported.
os.environ.setdefault("MUJOCO_GL", "egl")

import mjkdl as mjk  # noqa: E402  (after MENAGERIE_ROOT is set)

HOME = [0.0, 0.2618, 3.1416, -2.2689, 0.0, 0.9599, 1.5708]


# ---------------------------------------------------------------------- nothing written here

_NOT_CHECKED = {
    ".git",
    "__pycache__",
    ".pytest_cache",
    ".ruff_cache",
    ".mypy_cache",
    ".hypothesis",
    "mutants",
}
_files_at_start: set[Path] = set()


def _repository_files() -> set[Path]:
    """Every file in the repository tree, caches and git's own files aside."""
    found = set()
    for path in ROOT.rglob("*"):
        relative = path.relative_to(ROOT)
        if not _NOT_CHECKED & set(relative.parts) and path.is_file():
            found.add(relative)
    return found


def pytest_sessionstart(session: pytest.Session) -> None:
    _files_at_start.update(_repository_files())


def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    """Fail the session when a test left a file in the repository (MUJOCO_LOG.TXT, a video):
    tests write into tmp_path."""
    new = sorted(str(p) for p in _repository_files() - _files_at_start)
    if new:
        reporter = session.config.pluginmanager.get_plugin("terminalreporter")
        if reporter is not None:
            reporter.write_line("")
            reporter.write_sep("=", "tests left files in the repository", red=True)
            reporter.write_line(", ".join(new))
        session.exitstatus = pytest.ExitCode.TESTS_FAILED


def _menagerie_has(name: str) -> bool:
    """True when `name` resolves without a download (MENAGERIE_ROOT or the package's cache)."""
    return name in mjk.menagerie.available()


_MENAGERIE_SKIP = "MuJoCo Menagerie model"


def _menagerie_missing(what: str) -> str:
    """Why `what` (one model's name, or several) is not on this machine."""
    where = mjk.menagerie.source()
    return where.problem() or (
        f"not under MENAGERIE_ROOT={where.root}"
        if where.root is not None
        else f"MENAGERIE_ROOT is not set and the package's cache {where.cache} does not hold "
        f"{what} (tests never download)"
    )


def menagerie(name: str) -> str:
    """Path of a Menagerie model, or skip the test when it is not on this machine."""
    if not _menagerie_has(name):
        pytest.skip(f"{_MENAGERIE_SKIP} {name!r} not available: {_menagerie_missing('it')}")
    return mjk.menagerie.model_path(name)


# ---------------------------------------------------------------------- extras


@dataclass(frozen=True)
class Extra:
    """An optional dependency group: the modules a test needs from it, and how to install it."""

    name: str
    modules: tuple[str, ...]
    install: str

    @property
    def reason(self) -> str:
        """The skip reason: the same words for every test, so the summary can group them."""
        return f"needs the {self.name} extra: {self.install}"


EXTRAS = {
    extra.name: extra
    for extra in (
        Extra("rl", ("torch", "stable_baselines3", "sb3_contrib"), 'pip install -e ".[rl]"'),
        Extra("batch", ("torch",), 'pip install -e ".[batch]"'),
        Extra("warp", ("torch", "warp", "mujoco_warp"), 'pip install -e ".[warp]"'),
        Extra("warp-rl", ("torch", "mujoco_warp", "rsl_rl"), 'pip install -e ".[warp-rl]"'),
        Extra("franka", ("pylibfranka", "franky", "panda_py"), 'pip install -e ".[franka]"'),
        Extra(
            "lerobot",
            ("lerobot",),
            'pip install -e ".[lerobot]" in an environment of its own (lerobot 0.4 pins '
            "torch < 2.11)",
        ),
        Extra(
            "robomimic",
            ("robomimic", "torchvision"),
            "pip install robomimic==0.3.0 torch torchvision six -e . in an environment of its "
            "own (.ci/run)",
        ),
    )
}
# Extras that must be installed where this is set (a comma-separated list, or "all"): their
# tests fail instead of skipping. CI sets it after installing them.
_REQUIRED = {n for n in os.environ.get("MJKDL_REQUIRE_EXTRAS", "").split(",") if n}
_EXTRA_SKIP = re.compile(r"needs the (\S+) extra: ")


def _extra(name: str) -> Extra:
    try:
        return EXTRAS[name]
    except KeyError:
        raise KeyError(f"no extra {name!r} in conftest.EXTRAS; known: {sorted(EXTRAS)}") from None


def extra_missing(name: str) -> str | None:
    """Why extra `name` is unusable here (its skip reason), or None when all its modules import."""
    extra = _extra(name)
    if all(importlib.util.find_spec(module) is not None for module in extra.modules):
        return None
    return extra.reason


def needs_extra(name: str) -> None:
    """Skip the calling test (or, at module level, its module) unless extra `name` is
    installed; fail instead where MJKDL_REQUIRE_EXTRAS names it."""
    reason = extra_missing(name)
    if reason is None:
        return
    if name in _REQUIRED or "all" in _REQUIRED:
        pytest.fail(f"{reason}, and MJKDL_REQUIRE_EXTRAS asks for its tests to run", pytrace=False)
    pytest.skip(reason, allow_module_level=True)


def import_extra(name: str, module: str) -> ModuleType:
    """`module` of extra `name`, imported; skips as `needs_extra` does when it is missing."""
    needs_extra(name)
    return importlib.import_module(module)


def _skip_reasons(terminalreporter) -> list[tuple[str, str]]:
    """(node id, reason) of every skipped test and module."""
    return [
        (report.nodeid, str(report.longrepr[2]))
        for report in terminalreporter.stats.get("skipped", [])
        if isinstance(report.longrepr, tuple)
    ]


def pytest_terminal_summary(terminalreporter, exitstatus: int, config: pytest.Config) -> None:
    """Say what did not run: tests skipped for want of an extra, one line per extra with its
    install line, and for want of Menagerie models. A run without them still looks green, yet
    part of the suite did not run. Where MJKDL_EXTRA_SKIPS names a file, the node ids skipped
    for an extra are written there (CI reruns them after installing the extras)."""
    skipped = _skip_reasons(terminalreporter)
    by_extra: dict[str, list[str]] = {}
    for nodeid, reason in skipped:
        found = _EXTRA_SKIP.search(reason)
        if found:
            by_extra.setdefault(found.group(1), []).append(nodeid)
    if os.environ.get("MJKDL_EXTRA_SKIPS"):
        # in the order they ran: some modules' tests share a server and follow each other
        ids = list(
            dict.fromkeys(nodeid for nodeid, reason in skipped if _EXTRA_SKIP.search(reason))
        )
        Path(os.environ["MJKDL_EXTRA_SKIPS"]).write_text("".join(f"{i}\n" for i in ids))
    if by_extra:
        terminalreporter.write_sep("=", "extras not installed", yellow=True)
        for name in sorted(by_extra):
            count = len(by_extra[name])
            terminalreporter.write_line(
                f"{name}: {count} skipped (tests, or whole test files); to run them: "
                f"{_extra(name).install}"
            )
    reasons = [reason for _, reason in skipped if _MENAGERIE_SKIP in reason]
    if not reasons:
        return
    models = sorted({r.split("'")[1] for r in reasons})
    terminalreporter.write_sep("=", "MuJoCo Menagerie", yellow=True)
    terminalreporter.write_line(
        f"{len(reasons)} tests skipped for want of Menagerie models ({', '.join(models)}): "
        f"{_menagerie_missing('them')}. README.md says how to get them; "
        "`python -m mjkdl.menagerie` lists what is found where."
    )


def base_spec(**kw) -> mjk.SceneSpec:
    """A SceneSpec with the three required fields set."""
    fields = {"timestep": 0.002, "add_floor": True, "add_skybox": False}
    fields.update(kw)
    return mjk.SceneSpec(**fields)


def table_object() -> mjk.SceneObject:
    return mjk.SceneObject(
        name="table", mjcf_path=mjk.assets.path("table"), pos=[0.0, 0.0, 0.7], fixed=True
    )


def gripper(prefix: str = "g_") -> mjk.AttachmentSpec:
    return mjk.AttachmentSpec(
        mjcf_path=menagerie("robotiq_2f85"),
        attach_to=mjk.AttachTarget(mjk.AttachKind.Site, "pinch_site"),
        prefix=prefix,
    )


def gripper_tool(prefix: str = "g_") -> mjk.ToolFrameSpec:
    return mjk.ToolFrameSpec(tool_body=f"{prefix}base", tcp_site=f"{prefix}pinch")


def two_link_arm(actuators: str = "", tip: str = "") -> str:
    """MJCF of a small two-joint arm (bodies base, l1, l2; joints j1, j2) plus `actuators`;
    `tip`: bodies inside l2 (more links)."""
    return f"""
<mujoco model="two_link">
  <worldbody>
    <body name="base">
      <geom type="cylinder" size="0.05 0.02"/>
      <body name="l1" pos="0 0 0.05">
        <joint name="j1" axis="0 0 1"/>
        <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.02" mass="1"/>
        <body name="l2" pos="0.3 0 0">
          <joint name="j2" axis="0 1 0"/>
          <geom type="capsule" fromto="0 0 0 0.25 0 0" size="0.02" mass="0.5"/>
          {tip}
        </body>
      </body>
    </body>
  </worldbody>
  {actuators}
</mujoco>
"""


def tutorial_spec() -> mjk.SceneSpec:
    """Gen3 + 2F-85 on the table's `table_top`, a cube and a task camera."""
    table = table_object()
    cube = mjk.SceneObject(
        name="cube",
        shape=mjk.Shape.BOX,
        size=[0.025, 0.025, 0.025],
        pos=[0.35, 0.10, 0.725],
        rgba=[0.1, 0.25, 1.0, 1.0],
        mass=0.1,
        condim=mjk.Condim.Torsional,
        friction=[0.8, 0.02, 0.001],
    )
    arm = mjk.RobotSpec(
        path=menagerie("kinova_gen3"),
        attach_to=mjk.AttachTarget(
            mjk.AttachKind.Site, mjk.scene_object_site_name(table, "table_top")
        ),
        attachments=[gripper()],
    )
    camera = mjk.CameraSpec(name="task", pos=[0.1, -0.9, 1.45], euler=[35.0, 0.0, 5.0], fovy=45.0)
    return base_spec(objects=[table, cube], robots=[arm], cameras=[camera])


@pytest.fixture
def tutorial_scene() -> Callable[[], mjk.Scene]:
    """Builds the tutorial scene; closes every scene it built after the test."""
    built: list[mjk.Scene] = []

    def build(cls: type[mjk.Scene] = mjk.Scene) -> mjk.Scene:
        scene = cls.build(tutorial_spec())
        built.append(scene)
        return scene

    yield build
    for scene in built:
        scene.close()


# ---------------------------------------------------------------------- Panda (control tests)

PANDA_HOME = [0.0, 0.0, 0.0, -1.57079, 0.0, 1.57079, -0.7853]
PANDA_TCP = [0.0, 0.0, 0.1034]  # between the fingertips, below Menagerie's `hand` body


def panda_spec(**kw) -> mjk.SceneSpec:
    """Menagerie's Panda with its hand at the origin, plus whatever `kw` adds to the scene."""
    arm = mjk.RobotSpec(path=menagerie("franka_emika_panda"))
    return base_spec(robots=[arm], **kw)


def panda_arm(env: mjk.Env, mode: mjk.CtrlMode = mjk.CtrlMode.VELOCITY) -> mjk.Robot:
    """The Panda chain `link0` -> `hand` with the TCP offset, reset to `PANDA_HOME` in `mode`."""
    robot = env.create_robot("link0", "hand", tool=mjk.ToolFrameSpec(tcp_pos=PANDA_TCP))
    env.on_reset = lambda ctx: robot.set_joint_pos(PANDA_HOME, call_forward=False)
    robot.ctrl_mode = mode
    env.reset()
    robot.update()
    return robot


@contextmanager
def deadline(seconds: float, what: str) -> Iterator[None]:
    """Turn `what` running longer than `seconds` (a hang) into a TimeoutError (SIGALRM)."""

    def expire(signum: int, frame: object) -> None:
        raise TimeoutError(f"{what} took more than {seconds} s")

    previous = signal.signal(signal.SIGALRM, expire)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


# ---------------------------------------------------------------------- Panda, two shelves, a wall

SHELF_TOP = 0.30  # m, the shelves' upper surface
DOWN = [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]]  # TCP z pointing down


def shelf_objects() -> list[mjk.SceneObject]:
    """Two shelves either side of the Panda's x axis and a wall between them, 0.7 m tall."""

    def board(name: str, size: list[float], pos: list[float]) -> mjk.SceneObject:
        return mjk.SceneObject(
            name=name, shape=mjk.Shape.BOX, size=size, pos=pos, fixed=True, rgba=[0.6, 0.5, 0.4, 1]
        )

    return [
        board("shelf_a", [0.12, 0.12, 0.01], [0.45, 0.35, SHELF_TOP - 0.01]),
        board("shelf_b", [0.12, 0.12, 0.01], [0.45, -0.35, SHELF_TOP - 0.01]),
        board("wall", [0.25, 0.01, 0.35], [0.55, 0.0, 0.35]),
    ]


# ---------------------------------------------------------------------- simulated Franka (mjkdl.hw)

FRANKA_EXAMPLES = Path(__file__).resolve().parent / "data" / "franka_examples"
_franka_hosts = iter(range(1, 250))


def _franka_host() -> str:
    """A loopback address of this test process's own (the robot's ports are fixed: 1337,
    1338), so parallel runs and other servers on 127.0.0.1 do not collide."""
    return f"127.{os.getpid() % 250 + 1}.{next(_franka_hosts)}.1"


@dataclass
class FrankaSim:
    """A running simulator: its address, process and log (stderr lines, read as they come)."""

    host: str
    proc: subprocess.Popen
    log: list[str]

    def wait_for(self, text: str, timeout: float = 10.0) -> str:
        """The first log line holding `text`; the log is read by a thread, so a line the
        server wrote before its reply may not be in `log` yet when the reply comes."""
        deadline = time.monotonic() + timeout
        while True:
            found = [line for line in self.log if text in line]
            if found or time.monotonic() > deadline:
                assert found, f"no {text!r} in the server's log: {self.log[-5:]}"
                return found[0]
            time.sleep(0.01)


@contextmanager
def franka_sim(*args: str, host: str = "") -> Iterator[FrankaSim]:
    """`python -m mjkdl.hw.franka_sim` in another process, its log collected; stopped after."""
    host = host or _franka_host()
    proc = subprocess.Popen(
        [sys.executable, "-m", "mjkdl.hw.franka_sim", "--host", host, *args],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        cwd=ROOT,
    )
    try:
        assert proc.stderr is not None
        line = proc.stderr.readline()  # the first line says it listens (or why it cannot)
        assert "franka_sim: panda on" in line or "franka_sim: fr3 on" in line, line
        sim = FrankaSim(host, proc, [line])
        reader = threading.Thread(target=sim.log.extend, args=(proc.stderr,), daemon=True)
        reader.start()
        yield sim
    finally:
        proc.terminate()
        proc.wait(timeout=30)


def run_franka_example(
    path: Path, *args: str, stdin: str = "", timeout: float = 120, stop: bool = False
) -> str:
    """An unmodified client example in its own process; its output. libfranka refuses a kernel
    without PREEMPT_RT unless told to ignore it: tests/franka_nonrt.py says so, then runs the
    example as `__main__`. `stop`: the example runs until stopped, after `timeout` seconds."""
    try:
        done = subprocess.run(
            [sys.executable, str(ROOT / "tests" / "franka_nonrt.py"), str(path), *args],
            input=stdin,
            capture_output=True,
            text=True,
            timeout=timeout,
            cwd=path.parent,
        )
    except subprocess.TimeoutExpired as expired:
        if not stop:
            raise
        return _text(expired.stdout) + _text(expired.stderr)
    return done.stdout + done.stderr


def _text(output: bytes | str | None) -> str:
    if isinstance(output, bytes):
        return output.decode(errors="replace")
    return output or ""


@pytest.fixture(scope="module")
def franka_server() -> Iterator[str]:
    """The address of a lockstep simulated Franka arm for one test module (mjkdl's own
    clients, tests/test_hw_*.py)."""
    needs_extra("franka")
    with franka_sim("--lockstep", "--command-timeout", "10") as sim:
        yield sim.host


# Arms no Menagerie folder here holds, for the planner's per-arm tests: a seven-joint arm
# named like the KUKA iiwa with another arm's kinematics (as a Flexiv Rizon 4 is), and
# example-robot-data's UR10.
RIZON_LIKE = Path(__file__).resolve().parent / "assets" / "rizon_like.xml"
RIZON_LIKE_START = [0.0, 0.3, 0.0, 1.2, 0.0, 0.8, 0.0]
UR10_HOME = [0.0, -1.57, 1.57, -1.57, -1.57, 0.0]


def untested_arm(name: str, objects: list[mjk.SceneObject] | None = None) -> mjk.Env:
    """An Env with "rizon_like" or "ur10" on the floor (its robot: `env.robots[0]`-style,
    built by `untested_robot`)."""
    from mjkdl.urdf import example_robot_data_path

    path = (
        str(RIZON_LIKE)
        if name == "rizon_like"
        else str(example_robot_data_path("ur_description/urdf/ur10_robot.urdf"))
    )
    spec = mjk.SceneSpec(
        timestep=0.002,
        add_floor=True,
        add_skybox=False,
        robots=[mjk.RobotSpec(path=path)],
        objects=objects or [],
    )
    return mjk.Env.build(spec)


def untested_robot(env: mjk.Env, name: str) -> mjk.Robot:
    """The arm of `untested_arm(name)` at its start, in POSITION mode."""
    base, tip, start = (
        ("base", "link7", RIZON_LIKE_START)
        if name == "rizon_like"
        else ("base_link", "tool0", UR10_HOME)
    )
    robot = env.create_robot(base, tip)
    robot.set_joint_pos(np.array(start))
    robot.ctrl_mode = mjk.CtrlMode.POSITION
    robot.update()
    return robot


def sigint_as_from_a_terminal() -> None:
    """`Popen(preexec_fn=)` for a child a test stops with Ctrl+C (SIGINT): the signal's
    default action, as a terminal gives it. A shell that ran pytest in the background leaves
    SIGINT ignored, the child inherits that, and Python installs no KeyboardInterrupt then."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)
