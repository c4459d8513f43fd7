"""A compiled scene in words: its kinematic tree with every name, and a suggested
`create_robot(...)` call per robot, so choosing base and tip bodies needs no MJCF reading.

The suggestion is read off the tree. The base is the robot's root body. From there the arm's
serial chain is followed down while exactly one child carries further joints; the tool is the
first attachment (`RobotSpec.attachments`) below the chain, else the body where the chain
forks into several jointed branches (a hand with fingers). The tip is the body the tool hangs
from, else the chain's last jointed body, or a rigid body below it named like a tool frame
(`tool0`, `flange`, ...). A bare mounting plate (no joint, no site, one child) at the top of
an attachment is passed over: the 2F-85's `base_mount` leads to its `base`. The TCP site is
the tool's (else the tip's) site named most like a TCP (`tcp`, `pinch`, `grip`, ...), else the
tool's first site; without a site, a rigid body named so inside the tool becomes a `tcp_pos` /
`tcp_euler` offset from the tip (the Panda URDF's `panda_hand_tcp`). A model whose file marks
no TCP at all but whose maker documents one (Menagerie's Panda: Franka's TCP, 0.1034 m below
the `hand` flange) gets that TCP as an offset from the hand, which then ends the chain: the
recipe the docs and the registered tasks use.
"""

from __future__ import annotations

import json
import re
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from . import urdf
from .errors import MjkdlError
from .names import find_id
from .spec import SceneSpec

# Name parts that mark a TCP site or a tool-frame body, best first.
_TCP_WORDS = ("tcp", "pinch", "grip", "tool", "flange", "ee", "eef", "end", "attachment")

# TCPs the model files do not mark, from the makers' documentation: model file (its folder
# and name) -> (the body that ends the chain, the TCP's offset in it). Franka documents the
# Panda's TCP 0.1034 m along the flange's z; the Panda URDF's `panda_hand_tcp` says the same.
_DOCUMENTED_TCPS = {
    "franka_emika_panda/panda.xml": ("hand", (0.0, 0.0, 0.1034)),
}

_JOINT_TYPES = {
    mujoco.mjtJoint.mjJNT_FREE: "free",
    mujoco.mjtJoint.mjJNT_BALL: "ball",
    mujoco.mjtJoint.mjJNT_SLIDE: "slide",
    mujoco.mjtJoint.mjJNT_HINGE: "hinge",
}

_TRANSMISSIONS = {
    mujoco.mjtTrn.mjTRN_JOINT: ("joint", mujoco.mjtObj.mjOBJ_JOINT),
    mujoco.mjtTrn.mjTRN_JOINTINPARENT: ("joint", mujoco.mjtObj.mjOBJ_JOINT),
    mujoco.mjtTrn.mjTRN_TENDON: ("tendon", mujoco.mjtObj.mjOBJ_TENDON),
    mujoco.mjtTrn.mjTRN_SITE: ("site", mujoco.mjtObj.mjOBJ_SITE),
    mujoco.mjtTrn.mjTRN_BODY: ("body", mujoco.mjtObj.mjOBJ_BODY),
    mujoco.mjtTrn.mjTRN_SLIDERCRANK: ("slider-crank", mujoco.mjtObj.mjOBJ_SITE),
}


@dataclass(frozen=True)
class RobotSuggestion:
    """`Scene.create_robot` arguments read off the tree (names without the robot's prefix)."""

    prefix: str
    base_body: str
    tip_body: str
    tool_body: str = ""
    tcp_site: str = ""
    tcp_pos: tuple[float, float, float] = (0.0, 0.0, 0.0)
    tcp_euler: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def call(self) -> str:
        """The suggestion as Python source: `create_robot("base", "tip", ...)`."""
        args = [_quote(self.base_body), _quote(self.tip_body)]
        if self.prefix:
            args.append(f"prefix={_quote(self.prefix)}")
        tool = [
            f"{field}={_quote(value)}"
            for field, value in (("tool_body", self.tool_body), ("tcp_site", self.tcp_site))
            if value
        ]
        tool += [
            f"{field}=[{', '.join(repr(v) for v in values)}]"
            for field, values in (("tcp_pos", self.tcp_pos), ("tcp_euler", self.tcp_euler))
            if any(values)
        ]
        if tool:
            args.append(f"tool=mjk.ToolFrameSpec({', '.join(tool)})")
        return f"create_robot({', '.join(args)})"


@dataclass(frozen=True)
class _Robot:
    """Where robot `index` of the spec sits in the compiled model."""

    index: int
    file: str
    prefix: str
    model: str  # the file's folder and name, the key of _DOCUMENTED_TCPS
    roots: list[int]
    tools: list[int]  # root bodies of its attachments, in attachment order
    problem: str = ""  # why its roots could not be found

    @property
    def label(self) -> str:
        return f"robot {self.index} ({self.file}, prefix {_quote(self.prefix)})"


def describe(model: mujoco.MjModel, spec: SceneSpec) -> str:
    """Counts, the kinematic tree with every name, other actuators, suggested robot calls."""
    robots = _robots(model, spec)
    lines = [_counts(model), *_tree(model, 0, _marks(spec, robots, model))]
    others = _other_actuators(model)
    if others:
        lines += ["actuators not on a joint:", *(f"  {text}" for text in others)]
    lines += _suggestion_lines(model, robots)
    return "\n".join(lines)


def summary(model: mujoco.MjModel, spec: SceneSpec) -> str:
    """One line of counts, the objects, and one suggested `create_robot` call per robot."""
    lines = [_counts(model)]
    if spec.objects:
        lines.append("  objects: " + ", ".join(o.name for o in spec.objects))
    for robot in _robots(model, spec):
        lines += [f"  {robot.label}: {text}" for text in _robot_suggestions(model, robot)]
    return "\n".join(lines)


def tree_for(model: mujoco.MjModel, spec: SceneSpec, prefix: str) -> str:
    """The part of the tree a `create_robot(..., prefix=prefix)` call looks at: the subtrees of
    the robots with that prefix (the whole tree when none has it), with their suggestions."""
    robots = _robots(model, spec)
    mine = [r for r in robots if r.prefix == prefix and r.roots]
    roots = [root for r in mine for root in r.roots] or [0]
    marks = _marks(spec, robots, model)
    lines = [line for root in roots for line in _tree(model, root, marks)]
    return "\n".join(lines + _suggestion_lines(model, mine or robots))


def suggest(model: mujoco.MjModel, spec: SceneSpec) -> list[RobotSuggestion]:
    """Suggested `create_robot` arguments for every robot root that carries an arm."""
    out = []
    for robot in _robots(model, spec):
        for root in robot.roots:
            suggestion = _suggest(model, root, robot)
            if suggestion is not None:
                out.append(suggestion)
    return out


# ----------------------------------------------------------------------------- robots


def _robots(model: mujoco.MjModel, spec: SceneSpec) -> list[_Robot]:
    out = []
    for i, robot in enumerate(spec.robots):
        prefix = robot.prefix if isinstance(robot.prefix, str) else ""
        try:
            roots = _bodies(model, prefix, _file_roots(robot.path))
            tools = [
                body
                for att in robot.attachments
                for body in _bodies(model, prefix + att.prefix, _file_roots(att.mjcf_path))
            ]
            problem = "" if roots else "none of its file's root bodies is in the model"
        except (MjkdlError, ValueError, OSError) as err:
            roots, tools, problem = [], [], f"its file cannot be read again: {err}"
        path = Path(robot.path)
        key = f"{path.parent.name}/{path.name}"
        out.append(_Robot(i, path.name, prefix, key, roots, tools, problem))
    return out


def _file_roots(path: str | Path) -> list[str]:
    """Names of the top-level bodies a robot or attachment file adds, before prefixing."""
    if Path(path).suffix.lower() == ".urdf":
        return urdf.root_links(path)
    return [body.name for body in mujoco.MjSpec.from_file(str(path)).worldbody.bodies]


def _bodies(model: mujoco.MjModel, prefix: str, names: Iterable[str]) -> list[int]:
    ids = (find_id(model, mujoco.mjtObj.mjOBJ_BODY, prefix + n) for n in names)
    return [i for i in ids if i > 0]


def _suggest(m: mujoco.MjModel, root: int, robot: _Robot) -> RobotSuggestion | None:
    tools, prefix = robot.tools, robot.prefix
    children = _children(m)
    jointed = _jointed_subtrees(m, children)
    path = [root]
    while True:
        below = [c for c in children[path[-1]] if jointed[c] and c not in tools]
        if len(below) != 1:
            break
        path.append(below[0])
    moving = [b for b in path if any(_moves(m, j) for j in _joints(m, b))]
    if not moving:
        return None
    last = moving[-1]
    tool = next((t for t in tools if _is_below(m, t, last)), None)
    if tool is None and path[-1] != last:
        tool = path[-1]  # a rigid body that forks into several jointed branches: a hand
    tip = int(m.body_parentid[tool]) if tool is not None else last
    while tool is not None and _is_plate(m, children, tool):
        tool = children[tool][0]
    tcp = _best_site(m, _subtree(children, tool if tool is not None else tip))
    if tool is not None and not tcp:
        sites = [s for s in range(m.nsite) if m.site_bodyid[s] in _subtree(children, tool)]
        tcp = m.site(sites[0]).name if sites else ""
    base = _unprefixed(m.body(root).name, prefix)
    documented = _DOCUMENTED_TCPS.get(robot.model)
    if documented and not tcp and tool is not None and m.body(tool).name == prefix + documented[0]:
        # The hand ends the chain (its fingers stay passive joints of the robot's model).
        return RobotSuggestion(prefix, base, documented[0], tcp_pos=documented[1])
    frame = None if tcp else _best_body(m, _rigid_below(m, children, tip))
    offset = ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    if frame is not None and tool is None:
        tip = frame  # a tool frame of the arm itself (UR's tool0): the chain ends there
    elif frame is not None:
        offset = _offset(m, tip, frame)  # a TCP body inside the tool (panda_hand_tcp)
    return RobotSuggestion(
        prefix=prefix,
        base_body=base,
        tip_body=_unprefixed(m.body(tip).name, prefix),
        tool_body=_unprefixed(m.body(tool).name, prefix) if tool is not None else "",
        tcp_site=_unprefixed(tcp, prefix),
        tcp_pos=offset[0],
        tcp_euler=offset[1],
    )


def _offset(
    m: mujoco.MjModel, ancestor: int, body: int
) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    """Position and intrinsic xyz Euler angles (degrees) of `body` in `ancestor`'s frame,
    rounded to 1e-9: the form of `ToolFrameSpec.tcp_pos`/`tcp_euler`."""
    rot, pos = np.eye(3), np.zeros(3)
    while body != ancestor:
        local = np.empty(9)
        mujoco.mju_quat2Mat(local, m.body_quat[body])
        pos = m.body_pos[body] + local.reshape(3, 3) @ pos
        rot = local.reshape(3, 3) @ rot
        body = int(m.body_parentid[body])
    # R = Rx(a) Ry(b) Rz(c)
    angles = (
        np.arctan2(-rot[1, 2], rot[2, 2]),
        np.arcsin(np.clip(rot[0, 2], -1.0, 1.0)),
        np.arctan2(-rot[0, 1], rot[0, 0]),
    )
    return _rounded(pos), _rounded(np.rad2deg(angles))


def _rounded(values: Iterable[float]) -> tuple[float, float, float]:
    a, b, c = (round(float(v), 9) + 0.0 for v in values)  # + 0.0 turns -0.0 into 0.0
    return (a, b, c)


def _is_plate(m: mujoco.MjModel, children: list[list[int]], body: int) -> bool:
    sites = any(m.site_bodyid[s] == body for s in range(m.nsite))
    return m.body_jntnum[body] == 0 and not sites and len(children[body]) == 1


def _children(m: mujoco.MjModel) -> list[list[int]]:
    children: list[list[int]] = [[] for _ in range(m.nbody)]
    for b in range(1, m.nbody):
        children[int(m.body_parentid[b])].append(b)
    return children


def _jointed_subtrees(m: mujoco.MjModel, children: list[list[int]]) -> list[bool]:
    """Per body: whether it or a descendant carries a non-free joint."""
    jointed = [any(_moves(m, j) for j in _joints(m, b)) for b in range(m.nbody)]
    for b in range(m.nbody - 1, 0, -1):  # MuJoCo numbers children after their parent
        jointed[int(m.body_parentid[b])] |= jointed[b]
    return jointed


def _joints(m: mujoco.MjModel, b: int) -> range:
    return range(m.body_jntadr[b], m.body_jntadr[b] + m.body_jntnum[b])


def _moves(m: mujoco.MjModel, j: int) -> bool:
    return int(m.jnt_type[j]) != int(mujoco.mjtJoint.mjJNT_FREE)


def _is_below(m: mujoco.MjModel, body: int, ancestor: int) -> bool:
    while body > 0:
        body = int(m.body_parentid[body])
        if body == ancestor:
            return True
    return False


def _subtree(children: list[list[int]], root: int) -> set[int]:
    out, stack = set(), [root]
    while stack:
        b = stack.pop()
        out.add(b)
        stack.extend(children[b])
    return out


def _rigid_below(m: mujoco.MjModel, children: list[list[int]], body: int) -> list[int]:
    """Bodies fixed to `body` (no joint in between), below it."""
    out, stack = [], list(children[body])
    while stack:
        b = stack.pop()
        if m.body_jntnum[b] == 0:
            out.append(b)
            stack.extend(children[b])
    return sorted(out)


def _rank(name: str) -> int | None:
    """Position of the first TCP word among the name's parts (None: no TCP word)."""
    parts = re.split(r"[^a-z0-9]+", name.lower())
    ranks = [i for i, word in enumerate(_TCP_WORDS) for part in parts if part.startswith(word)]
    return min(ranks) if ranks else None


def _best(names: list[str]) -> str:
    ranked = [(rank, i, n) for i, n in enumerate(names) if (rank := _rank(n)) is not None]
    return min(ranked)[2] if ranked else ""


def _best_site(m: mujoco.MjModel, bodies: set[int]) -> str:
    return _best([m.site(s).name for s in range(m.nsite) if m.site_bodyid[s] in bodies])


def _best_body(m: mujoco.MjModel, bodies: list[int]) -> int | None:
    name = _best([m.body(b).name for b in bodies])
    return find_id(m, mujoco.mjtObj.mjOBJ_BODY, name) if name else None


def _unprefixed(name: str, prefix: str) -> str:
    return name[len(prefix) :] if prefix and name.startswith(prefix) else name


# ----------------------------------------------------------------------------- text


def _quote(text: str) -> str:
    return json.dumps(text)


def _counts(m: mujoco.MjModel) -> str:
    return (
        f"Scene: {m.nbody} bodies, {m.njnt} joints, {m.nu} actuators, {m.nsite} sites, "
        f"{m.ncam} cameras"
    )


def _marks(spec: SceneSpec, robots: list[_Robot], m: mujoco.MjModel) -> dict[int, str]:
    marks = {}
    for obj in spec.objects:
        body = find_id(m, mujoco.mjtObj.mjOBJ_BODY, obj.name)
        if body > 0:
            marks[body] = f"[object {_quote(obj.name)}]"
    for robot in robots:
        for root in robot.roots:
            marks[root] = f"[{robot.label}]"
        for tool in robot.tools:
            marks[tool] = f"[attachment of robot {robot.index}]"
    return marks


def _tree(m: mujoco.MjModel, root: int, marks: dict[int, str]) -> list[str]:
    children = _children(m)
    lines = [_body_text(m, root, marks)]

    def visit(b: int, indent: str) -> None:
        for k, child in enumerate(children[b]):
            last = k == len(children[b]) - 1
            lines.append(indent + ("└─ " if last else "├─ ") + _body_text(m, child, marks))
            visit(child, indent + ("   " if last else "│  "))

    visit(root, "")
    return lines


def _body_text(m: mujoco.MjModel, b: int, marks: dict[int, str]) -> str:
    parts = [m.body(b).name or f"(body {b})"]
    if b in marks:
        parts.append(marks[b])
    joints = [_joint_text(m, j) for j in _joints(m, b)]
    sites = [m.site(s).name for s in range(m.nsite) if m.site_bodyid[s] == b]
    cameras = [m.camera(c).name for c in range(m.ncam) if m.cam_bodyid[c] == b]
    for label, names in (("joint", joints), ("site", sites), ("camera", cameras)):
        if names:
            parts.append(f"{label}{'s' if len(names) > 1 else ''}: {', '.join(names)}")
    return "  ".join(parts)


def _joint_text(m: mujoco.MjModel, j: int) -> str:
    kind = _JOINT_TYPES.get(int(m.jnt_type[j]), "joint")
    actuators = [
        m.actuator(a).name
        for a in range(m.nu)
        if _TRANSMISSIONS.get(int(m.actuator_trntype[a]), ("",))[0] == "joint"
        and m.actuator_trnid[a, 0] == j
    ]
    driven = f", actuator {', '.join(actuators)}" if actuators else ""
    return f"{m.joint(j).name or f'(joint {j})'} ({kind}{driven})"


def _other_actuators(m: mujoco.MjModel) -> list[str]:
    out = []
    for a in range(m.nu):
        kind, obj = _TRANSMISSIONS.get(int(m.actuator_trntype[a]), ("other", None))
        if kind == "joint":
            continue
        target = mujoco.mj_id2name(m, obj, int(m.actuator_trnid[a, 0])) if obj else None
        out.append(f"{m.actuator(a).name} ({kind} {target or '?'})")
    return out


def _robot_suggestions(m: mujoco.MjModel, robot: _Robot) -> list[str]:
    if robot.problem:
        return [f"no suggestion: {robot.problem}"]
    out = []
    for root in robot.roots:
        suggestion = _suggest(m, root, robot)
        name = _quote(m.body(root).name)
        out.append(f"scene.{suggestion.call()}" if suggestion else f"no single chain at {name}")
    return out


def _suggestion_lines(m: mujoco.MjModel, robots: list[_Robot]) -> list[str]:
    if not robots:
        return []
    lines = ["suggested robot handles (names without the robot's prefix):"]
    for robot in robots:
        lines += [f"  {robot.label}: {text}" for text in _robot_suggestions(m, robot)]
    return lines
