"""Is a joint configuration of a robot collision-free? MuJoCo's own collision detection.

A `CollisionChecker` runs `mj_kinematics` and `mj_collision` on a scratch `MjData` of a
private copy of the scene's model, with every colliding geom's margin set to the clearance
asked for: MuJoCo reports a contact for each pair closer than that, with the geoms the
simulation uses, its parent/child filter and `<exclude>`s. Everything that is not moved by the
arm stays where it was at the last `sync()`. Contacts between two bodies the arm does not move
(a cube on its table) are not the arm's business: the copy's contype/conaffinity bits are
rewritten so MuJoCo never even generates them, and each contact it does report is checked
against the original bits, so nothing the simulation would not collide counts either.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Mapping, Sequence

import mujoco
import numpy as np

from ..control.cartesian import _number, _pair_names
from ..errors import SpecError, SpecTypeError
from ..names import model_id
from ..robot import Robot

# Each group of arm links gets one of MuJoCo's 32 contype bits (the sign bit left alone).
_MAX_GROUPS = 31


class CollisionChecker:
    """Collision checks for the arm of `robot` at joint positions `q`, with `margin` clearance.

    `reach` (>= margin, default margin): distances up to it are measured (`clearance`), so
    one collision pass answers "at least `margin`" and "at least `reach`". `allowed_contacts`:
    pairs of body names whose contacts never count (a held object and the fingers).
    `padding` (m): what a pair of geoms should keep beyond the margin where it can (the
    planner's search): the bodies the arm moves (and a carried one) get `padding`, or
    `link_padding[body]`; a pair of two of them keeps the smaller of their two, a body
    against anything else its own (`clearances`); `unpad(pairs)` takes it off body pairs
    that never get that far apart. `reach` grows to margin + the largest padding.
    `carry(body)`: a free body that moves rigidly with the arm's tip (a grasped cube).
    """

    def __init__(
        self,
        robot: Robot,
        margin: float,
        allowed_contacts: Sequence[tuple[str, str]] = (),
        reach: float | None = None,
        padding: float = 0.0,
        link_padding: Mapping[str, float] | None = None,
    ) -> None:
        if not isinstance(robot, Robot):
            raise SpecTypeError(f"CollisionChecker: robot must be a Robot, got {robot!r}")
        self._robot = robot
        self._margin = _number(margin, "margin")
        self._padding = _number(padding, "padding")
        if link_padding is not None and not isinstance(link_padding, Mapping):
            raise SpecTypeError(
                f"link_padding must map body names to paddings (m), got {link_padding!r}"
            )
        self._link_padding = {
            str(name): _number(value, f"link_padding[{name!r}]")
            for name, value in (link_padding or {}).items()
        }
        widest = max([self._padding, *self._link_padding.values()])
        self._reach = max(
            self._margin + widest, _number(reach, "reach") if reach is not None else 0.0
        )
        self._unpadded_names: set[tuple[str, str]] = set()
        self._allowed_names = _pair_names(allowed_contacts, "allowed_contacts")
        self._model: mujoco.MjModel | None = None
        self._carry_name: str | None = None
        self._bind()

    # ------------------------------------------------------------------ setup

    def _bind(self) -> None:
        """Copy the scene's current model and find the arm's bodies (again after a rebuild)."""
        scene = self._robot.scene
        source = scene.model
        self._source = source
        model = copy.copy(source)
        self._model = model
        self._data = mujoco.MjData(model)
        joints = [
            model_id(model, mujoco.mjtObj.mjOBJ_JOINT, "joint", j, "the robot")
            for j in self._robot.joint_names
        ]
        self._qadr = np.array([model.jnt_qposadr[j] for j in joints])
        if len(joints) > _MAX_GROUPS:
            raise SpecError(
                f"CollisionChecker: {len(joints)} joints; MuJoCo's 32 contype bits give "
                f"groups for {_MAX_GROUPS} at most"
            )
        self._tip = int(model.jnt_bodyid[joints[-1]])
        first, count = int(self._qadr[0]), len(self._qadr)
        # A view of the arm's qpos, written per check, when the joints are consecutive.
        consecutive = np.array_equal(self._qadr, np.arange(first, first + count))
        self._arm_qpos = self._data.qpos[first : first + count] if consecutive else None
        self._moving = _subtree(model, int(model.jnt_bodyid[joints[0]]))
        # Bodies the arm moves, numbered by the last arm joint between them and the base.
        self._groups = np.full(model.nbody, -1)
        for k, j in enumerate(joints):
            self._groups[_subtree(model, int(model.jnt_bodyid[j]))] = k
        self._colliding = (source.geom_contype != 0) | (source.geom_conaffinity != 0)
        self._allowed = self._resolve(self._allowed_names, "allowed_contacts")
        # Bodies the arm does not move pad nothing of their own: a pair takes the other's.
        self._body_padding = np.where(self._moving, self._padding, math.inf)
        for name, value in self._link_padding.items():
            body = model_id(model, mujoco.mjtObj.mjOBJ_BODY, "body", name, "link_padding")
            self._body_padding[body] = value
        self._unpadded = self._resolve(sorted(self._unpadded_names), "unpad")
        self._carried = -1
        self._carry_qadr = -1
        self._masks(self._moving)
        model.geom_margin[self._colliding] = self._reach
        model.geom_gap[:] = 0.0
        # The midphase prunes a body pair's bounding-volume trees with the bodies' margins,
        # which the compiler took from the geoms' margins then: they must follow.
        model.body_margin[:] = 0.0
        np.maximum.at(model.body_margin, model.geom_bodyid, model.geom_margin)
        self.sync()

    def _masks(self, moving: np.ndarray) -> None:
        """Bits that make MuJoCo pair geoms the arm moves relative to each other or to the
        rest, and never two that keep their relative pose (two static bodies, the fingers and
        the hand): each group of bodies between two arm joints gets a bit of its own."""
        model = self._model
        assert model is not None
        group = self._groups.copy()
        if self._carried >= 0:
            group[self._carried] = group[self._tip]
        every = (1 << (int(group.max()) + 1)) - 1
        geom_group = group[model.geom_bodyid]
        on_arm = moving[model.geom_bodyid] & self._colliding
        static = ~moving[model.geom_bodyid] & self._colliding
        bit = np.left_shift(1, np.maximum(geom_group, 0))
        model.geom_contype[on_arm] = bit[on_arm]
        model.geom_conaffinity[on_arm] = every & ~bit[on_arm]
        model.geom_contype[static] = 0
        model.geom_conaffinity[static] = every
        self._arm_body = moving
        # Which geom pairs count, looked up per contact: the original bits collide them, one
        # moves with the arm, and their bodies are not an allowed pair.
        bits = self._source
        counts = (bits.geom_contype[:, None] & bits.geom_conaffinity[None, :]) != 0
        counts |= counts.T
        on = moving[model.geom_bodyid]
        counts &= on[:, None] | on[None, :]
        body = model.geom_bodyid
        for a, b in self._allowed:
            counts[np.ix_(body == a, body == b)] = False
            counts[np.ix_(body == b, body == a)] = False
        self._counts = counts
        own = self._body_padding.copy()
        if self._carried >= 0:
            own[self._carried] = self._padding
        pad = own[body]
        pad = np.minimum(pad[:, None], pad[None, :])
        pad[np.isinf(pad)] = 0.0  # two bodies the arm does not move: never counted
        for a, b in self._unpadded:
            pad[np.ix_(body == a, body == b)] = 0.0
            pad[np.ix_(body == b, body == a)] = 0.0
        self._pad = pad

    def _resolve(self, pairs: list[tuple[str, str]], field: str) -> set[tuple[int, int]]:
        model = self._model
        out = set()
        for i, (a, b) in enumerate(pairs):
            where = f"{field}[{i}]"
            ia = model_id(model, mujoco.mjtObj.mjOBJ_BODY, "body", a, where)
            ib = model_id(model, mujoco.mjtObj.mjOBJ_BODY, "body", b, where)
            out.add((min(ia, ib), max(ia, ib)))
        return out

    def set_allowed(self, allowed_contacts: Sequence[tuple[str, str]]) -> None:
        """Replace the pairs of body names whose contacts never count."""
        names = _pair_names(allowed_contacts, "allowed_contacts")
        self._allowed = self._resolve(names, "allowed_contacts")
        self._allowed_names = names
        self._masks(self._arm_body)

    def unpad(self, pairs: Sequence[tuple[str, str]]) -> None:
        """Take the padding off these pairs of body names: they keep only the margin."""
        names = _pair_names(pairs, "unpad")
        self._unpadded = self._resolve(names, "unpad")
        self._unpadded_names = set(names)
        self._masks(self._arm_body)

    @property
    def carried(self) -> str | None:
        """The free body moved with the tip (`carry`), or None."""
        return self._carry_name

    def carry(self, body: str | None) -> None:
        """Move free body `body` with the tip from now on (None: stop carrying)."""
        model = self._model
        assert model is not None
        moving = self._moving.copy()
        carried, qadr = -1, -1
        if body is not None:
            b = model_id(model, mujoco.mjtObj.mjOBJ_BODY, "body", body, "the scene (carry)")
            joint = int(model.body_jntadr[b])
            if model.body_jntnum[b] != 1 or model.jnt_type[joint] != mujoco.mjtJoint.mjJNT_FREE:
                raise SpecError(f"carry: body {body!r} is not a free body (it needs a free joint)")
            if self._moving[b]:
                raise SpecError(f"carry: body {body!r} already moves with the arm")
            carried, qadr = b, int(model.jnt_qposadr[joint])
            moving[b] = True
        self._carried, self._carry_qadr = carried, qadr
        self._carry_name = body
        self._masks(moving)
        self.sync()

    def sync(self) -> None:
        """Take the positions of everything the arm does not move from the scene, now."""
        if self._robot.scene.model is not self._source:
            self._bind()
            if self._carry_name is not None:
                self.carry(self._carry_name)
            return
        scene_data = self._robot.scene.data
        data = self._data
        # Fixed bodies and geoms moved in the scene's model since the copy was made.
        model, source = self._model, self._source
        for name in ("body_pos", "body_quat", "geom_pos", "geom_quat", "geom_size"):
            np.copyto(getattr(model, name), getattr(source, name))
        data.qpos[:] = scene_data.qpos
        data.mocap_pos[:] = scene_data.mocap_pos
        data.mocap_quat[:] = scene_data.mocap_quat
        if self._carried >= 0:
            # The carried body's pose in the tip's frame, as it is in the scene now.
            tip_pos, tip_mat = scene_data.xpos[self._tip], scene_data.xmat[self._tip].reshape(3, 3)
            body_pos = scene_data.xpos[self._carried]
            body_mat = scene_data.xmat[self._carried].reshape(3, 3)
            self._rel_pos = tip_mat.T @ (body_pos - tip_pos)
            self._rel_mat = tip_mat.T @ body_mat
            self._quat = np.zeros(4)

    @property
    def margin(self) -> float:
        """Clearance every pair of geoms involving the arm must keep (m)."""
        return self._margin

    @property
    def reach(self) -> float:
        """Distance (m) up to which `clearance` measures; beyond it, inf."""
        return self._reach

    @property
    def arm_qpos_adr(self) -> np.ndarray:
        """Where the arm's joints sit in MuJoCo's qpos."""
        return self._qadr

    # ------------------------------------------------------------------ checks

    def _place(self, q: np.ndarray | Sequence[float]) -> None:
        model, data = self._model, self._data
        if self._arm_qpos is not None:
            self._arm_qpos[...] = q
        else:
            data.qpos[self._qadr] = q
        _kinematics(model, data)
        if self._carried >= 0:
            tip_mat = data.xmat[self._tip].reshape(3, 3)
            adr = self._carry_qadr
            data.qpos[adr : adr + 3] = data.xpos[self._tip] + tip_mat @ self._rel_pos
            mujoco.mju_mat2Quat(self._quat, (tip_mat @ self._rel_mat).ravel())
            data.qpos[adr + 3 : adr + 7] = self._quat
            mujoco.mj_kinematics(model, data)
        _collision(model, data)

    def valid(self, q: np.ndarray | Sequence[float]) -> bool:
        """Whether the arm at `q` keeps the margin from everything (itself included)."""
        return self.clearance(q) >= self._margin

    def clearance(self, q: np.ndarray | Sequence[float]) -> float:
        """The smallest distance (m) between a geom the arm moves and another geom, at `q`;
        inf when nothing is within `reach` (negative: penetration)."""
        self._place(q)
        data = self._data
        if data.ncon == 0:
            return math.inf
        counted = self._counted()
        return float(data.contact.dist[counted].min()) if len(counted) else math.inf

    def clearances(self, q: np.ndarray | Sequence[float]) -> tuple[float, float]:
        """At `q`: `clearance` and the smallest distance less its pair's padding (inf when
        nothing is within reach): every pair keeps margin + padding when the second is at
        least the margin."""
        self._place(q)
        if self._data.ncon == 0:
            return math.inf, math.inf
        counted = self._counted()
        if not len(counted):
            return math.inf, math.inf
        con = self._data.contact
        dist = con.dist[counted]
        padded = dist - self._pad[con.geom1[counted], con.geom2[counted]]
        return float(dist.min()), float(padded.min())

    def nearest(self) -> tuple[int, int, float] | None:
        """At the last checked `q`: the geom pair the least clear of margin + padding and
        its distance (m), or None."""
        counted = self._counted()
        if not len(counted):
            return None
        con = self._data.contact
        g1, g2 = con.geom1[counted], con.geom2[counted]
        k = int(np.argmin(con.dist[counted] - self._pad[g1, g2]))
        return int(g1[k]), int(g2[k]), float(con.dist[counted[k]])

    def pair_names(self, g1: int, g2: int) -> tuple[str, str, float]:
        """The bodies of two geoms (sorted names) and the padding their pair keeps."""
        model = self._model
        assert model is not None
        a, b = (model.body(int(model.geom_bodyid[g])).name for g in (g1, g2))
        return min(a, b), max(a, b), float(self._pad[g1, g2])

    def contacts(self, q: np.ndarray | Sequence[float]) -> list[tuple[str, str, float]]:
        """The pairs of bodies closer than `reach` at `q`, nearest first: (body, body, m)."""
        self._place(q)
        model, data = self._model, self._data
        assert model is not None
        out = []
        for i in self._counted().tolist():
            c = data.contact[i]
            b1, b2 = model.geom_bodyid[c.geom1], model.geom_bodyid[c.geom2]
            out.append((model.body(b1).name, model.body(b2).name, float(c.dist)))
        nearest: dict[tuple[str, str], tuple[str, str, float]] = {}
        for a, b, d in sorted(out, key=lambda x: x[2]):
            nearest.setdefault((min(a, b), max(a, b)), (a, b, d))
        return list(nearest.values())

    def _counted(self) -> np.ndarray:
        """Indices of the contacts that count: between geoms the simulation collides, one of
        them moving with the arm, and not an allowed pair."""
        data = self._data
        con, n = data.contact, data.ncon
        # Some pair functions (box-box, multi-point mesh contacts) report points beyond the
        # margin next to the one within it.
        keep = self._counts[con.geom1[:n], con.geom2[:n]] & (con.dist[:n] < self._reach)
        return np.flatnonzero(keep)


_kinematics, _collision = mujoco.mj_kinematics, mujoco.mj_collision


def _subtree(model: mujoco.MjModel, root: int) -> np.ndarray:
    """Mask of the bodies in `root`'s subtree (parents come before their children)."""
    inside = np.zeros(model.nbody, dtype=bool)
    inside[root] = True
    for b in range(root + 1, model.nbody):
        inside[b] = inside[model.body_parentid[b]]
    return inside
