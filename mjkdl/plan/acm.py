"""Which pairs of an arm's own bodies never count as collisions: MoveIt's allowed-collision
matrix, computed by sampling as its setup assistant does.

Over `samples` random joint positions within the limits (unlimited joints within ±π), a pair
of the robot's bodies (the arm, what it carries on its tip, and the body it is mounted on)
is classified *adjacent* (parent and child: MuJoCo never collides them), *always* (in contact
in at least `ALWAYS` of the samples: the UR5e's shoulder 3 mm above its mount), *default* (in
contact in the model's default pose, `qpos0` clipped to the limits) or *never* (in none of the
samples). "In contact" means closer than the planner's margin. Pairs of bodies that keep their
relative pose (a hand and its fingers) are not the planner's business and are not listed. A
pair gets the first reason that applies, in that order.

The search keeps `margin + padding` where it can. A pair that is not allowed but closer than
that in at least `ALWAYS` of the samples (a UFACTORY Lite 6's link4 and link6 stay within
9.4 mm of each other: never inside a 5 mm margin, always inside margin + 5 mm padding) would
leave the search almost no valid state: it is listed in `unpadded`, and the planner checks it
for the margin alone.

Only the reasons in `allow` (default `ALLOW`: adjacent and always) make a pair allowed; the
others are kept in `sampled` for inspection. MoveIt allows all four; here *never* saves
nothing (MuJoCo's collision pass runs whole and pairs are filtered after it) and sampling misses
rare contacts, and *default* caught the Panda's hand and link5 (3 mm apart at `qpos0`), which
then met 27 mm deep in 4 of 50 trajectories executed in `benchmarks/planning.py`'s clutter.
`allow=REASONS[:4]` is MoveIt's choice.

The result is cached per model (a hash of the robot's bodies, geoms, joint ranges, the margin,
the paddings and the sample count): in memory, and as JSON under `acm_cache_dir()`.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
from collections.abc import Iterator
from pathlib import Path

import mujoco
import numpy as np

from ..errors import SpecError, unknown_name
from ..robot import Robot
from .collision import CollisionChecker

# A pair in contact in at least this fraction of the samples is "always" in contact
# (MoveIt's setup assistant uses 95 %).
ALWAYS = 0.95
SAMPLES = 2000
REASONS = ("adjacent", "always", "default", "never", "user", "srdf")
ALLOW = ("adjacent", "always")
_Fractions = dict[tuple[str, str], float]
_MEMORY: dict[str, tuple[dict[tuple[str, str], str], _Fractions, _Fractions]] = {}
_FORMAT = "4"


def acm_cache_dir() -> Path:
    """Where computed matrices are kept: `$MJKDL_CACHE_DIR/acm`, else
    `$XDG_CACHE_HOME/mjkdl/acm`, else `~/.cache/mjkdl/acm`. Safe to delete."""
    base = os.environ.get("MJKDL_CACHE_DIR")
    if base:
        return Path(base).expanduser() / "acm"
    cache = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(cache).expanduser() / "mjkdl" / "acm"


def _key(a: str, b: str) -> tuple[str, str]:
    return (a, b) if a <= b else (b, a)


class AllowedCollisionMatrix:
    """Pairs of body names whose contacts do not count, each with its reason (`REASONS`).

    Inspect with `reason(a, b)`, `pairs` or `len()`; edit with `allow(a, b)` and
    `disallow(a, b)` (the planner applies edits at its next `plan`). `candidates`: every
    pair the sampling looked at, `contact_fraction[pair]` how often it was in contact;
    `padded_fraction[pair]` how often closer than margin + padding; `unpadded`: the pairs
    not allowed that were that close in at least `ALWAYS` of the samples (checked for the
    margin alone); `sampled`: every classified pair and its reason, allowed or not.
    """

    def __init__(
        self,
        pairs: dict[tuple[str, str], str],
        bodies: set[str],
        contact_fraction: dict[tuple[str, str], float] | None = None,
        allow: tuple[str, ...] = ALLOW,
        padded_fraction: dict[tuple[str, str], float] | None = None,
    ) -> None:
        self.sampled = {_key(*p): r for p, r in pairs.items()}
        self._pairs = {p: r for p, r in self.sampled.items() if r in allow}
        self._bodies = set(bodies)
        self.contact_fraction = dict(contact_fraction or {})
        self.padded_fraction = dict(padded_fraction or {})
        self.unpadded = sorted(
            p for p, f in self.padded_fraction.items() if f >= ALWAYS and p not in self._pairs
        )
        self.version = 0  # bumped by every edit

    @property
    def pairs(self) -> dict[tuple[str, str], str]:
        """A copy of the allowed pairs (sorted names) and their reasons."""
        return dict(self._pairs)

    def reason(self, a: str, b: str) -> str | None:
        """Why the pair (a, b) is allowed; None when its contacts count."""
        return self._pairs.get(_key(a, b))

    def __contains__(self, pair: object) -> bool:
        if not (isinstance(pair, tuple) and len(pair) == 2):
            return False
        return _key(str(pair[0]), str(pair[1])) in self._pairs

    def __len__(self) -> int:
        return len(self._pairs)

    def __iter__(self) -> Iterator[tuple[str, str]]:
        return iter(sorted(self._pairs))

    def _check(self, a: str, b: str, what: str) -> None:
        for name in (a, b):
            if name not in self._bodies:
                where = f"{what} (the robot's bodies)"
                raise unknown_name("body", name, sorted(self._bodies), where)
        if a == b:
            raise SpecError(f"{what}: a body cannot collide with itself ({a!r})")

    def allow(self, a: str, b: str, reason: str = "user") -> None:
        """Let bodies `a` and `b` touch (`reason`: "user", or "srdf" for an SRDF's pair)."""
        self._check(a, b, "AllowedCollisionMatrix.allow")
        if reason not in REASONS[4:]:
            raise SpecError(
                f"AllowedCollisionMatrix.allow: reason must be user or srdf, got {reason!r}"
            )
        self._pairs[_key(a, b)] = reason
        self.version += 1

    def disallow(self, a: str, b: str) -> None:
        """Count contacts between `a` and `b` again."""
        self._check(a, b, "AllowedCollisionMatrix.disallow")
        self._pairs.pop(_key(a, b), None)
        self.version += 1

    def summary(self) -> dict[str, int]:
        """How many pairs each reason allows."""
        return {r: sum(1 for v in self._pairs.values() if v == r) for r in REASONS}


def robot_bodies(model: mujoco.MjModel, robot: Robot) -> tuple[np.ndarray, int]:
    """Mask of the robot's bodies (the arm's subtree and its mount) and the mount's id."""
    first = int(model.joint(robot.joint_names[0]).bodyid[0])
    mount = int(model.body_parentid[first])
    inside = np.zeros(model.nbody, dtype=bool)
    inside[first] = True
    for b in range(first + 1, model.nbody):
        inside[b] = inside[model.body_parentid[b]]
    inside[mount] = mount != 0
    return inside, mount


def compute_acm(
    robot: Robot,
    margin: float,
    lower: np.ndarray,
    upper: np.ndarray,
    *,
    samples: int = SAMPLES,
    seed: int = 0,
    use_cache: bool = True,
    allow: tuple[str, ...] = ALLOW,
    padding: float = 0.0,
    link_padding: dict[str, float] | None = None,
) -> AllowedCollisionMatrix:
    """The allowed-collision matrix of `robot`'s arm at `margin` (m) and the search's
    paddings (see `CollisionChecker`), sampled within [lower, upper] (cached; see the
    module's docstring)."""
    if isinstance(samples, bool) or not isinstance(samples, int) or samples < 10:
        raise SpecError(f"acm_samples must be an integer >= 10, got {samples!r}")
    model = robot.scene.model
    mask, _mount = robot_bodies(model, robot)
    names = {b: model.body(b).name for b in np.flatnonzero(mask).tolist()}
    checker = CollisionChecker(robot, margin, padding=padding, link_padding=link_padding)
    pads = np.minimum(checker._body_padding[mask], 1.0)  # inf: pads nothing of its own
    key = _fingerprint(model, robot, mask, margin, lower, upper, samples, seed, pads)
    pairs: dict[tuple[str, str], str] | None = None
    fractions: _Fractions = {}
    padded: _Fractions = {}
    if use_cache and key in _MEMORY:
        pairs, fractions, padded = _MEMORY[key]
    file = acm_cache_dir() / f"{key}.json"
    if pairs is None and use_cache and file.is_file():
        try:
            stored = json.loads(file.read_text())
            pairs = {_key(a, b): r for a, b, r in stored["pairs"]}
            fractions = {_key(a, b): f for a, b, f in stored["fractions"]}
            padded = {_key(a, b): f for a, b, f in stored["padded"]}
        except (OSError, ValueError, KeyError, TypeError):
            pairs = None
    if pairs is None:
        pairs, fractions, padded = _sample(checker, margin, lower, upper, mask, samples, seed)
        if use_cache:
            try:
                file.parent.mkdir(parents=True, exist_ok=True)
                record = {
                    "format": _FORMAT,
                    "pairs": [[a, b, r] for (a, b), r in sorted(pairs.items())],
                    "fractions": [[a, b, f] for (a, b), f in sorted(fractions.items())],
                    "padded": [[a, b, f] for (a, b), f in sorted(padded.items())],
                }
                file.write_text(json.dumps(record))
            except OSError:
                pass  # a read-only home: the memory cache still holds it
    if use_cache:
        _MEMORY[key] = (dict(pairs), dict(fractions), dict(padded))
    if isinstance(allow, str) or any(r not in REASONS[:4] for r in allow):
        raise SpecError(f"acm_allow must be a tuple of {', '.join(REASONS[:4])}; got {allow!r}")
    return AllowedCollisionMatrix(pairs, set(names.values()), fractions, tuple(allow), padded)


def _sample(
    checker: CollisionChecker,
    margin: float,
    lower: np.ndarray,
    upper: np.ndarray,
    mask: np.ndarray,
    samples: int,
    seed: int,
) -> tuple[dict[tuple[str, str], str], _Fractions, _Fractions]:
    model, data = checker._model, checker._data
    assert model is not None
    groups = checker._groups
    colliding = np.zeros(model.nbody, dtype=bool)
    colliding[model.geom_bodyid[checker._colliding]] = True
    bodies = np.flatnonzero(mask & colliding)
    moving = checker._moving
    # Candidate pairs: two of the robot's bodies that can move relative to each other.
    index = np.full((model.nbody, model.nbody), -1)
    candidates: list[tuple[int, int]] = []
    for i, a in enumerate(bodies.tolist()):
        for b in bodies[i + 1 :].tolist():
            if not (moving[a] or moving[b]) or (groups[a] == groups[b] and groups[a] >= 0):
                continue
            index[a, b] = index[b, a] = len(candidates)
            candidates.append((a, b))
    counts = np.zeros(len(candidates), dtype=np.int64)
    near = np.zeros(len(candidates), dtype=np.int64)
    geom_body = model.geom_bodyid
    counts_mask, pad = checker._counts, checker._pad

    def touching(q: np.ndarray, within: float = 0.0) -> np.ndarray:
        """The candidate pairs closer than the margin (+ `within` of their padding)."""
        checker._place(q)
        n = data.ncon
        con = data.contact
        g1, g2 = con.geom1[:n], con.geom2[:n]
        keep = counts_mask[g1, g2] & (con.dist[:n] < margin + within * pad[g1, g2])
        found = index[geom_body[g1[keep]], geom_body[g2[keep]]]
        return np.unique(found[found >= 0])

    rng = np.random.default_rng(seed)
    for q in rng.uniform(lower, upper, (samples, len(lower))):
        closer = touching(q, 1.0)
        near[closer] += 1
        n = data.ncon
        con = data.contact
        inside = counts_mask[con.geom1[:n], con.geom2[:n]] & (con.dist[:n] < margin)
        found = index[geom_body[con.geom1[:n][inside]], geom_body[con.geom2[:n][inside]]]
        counts[np.unique(found[found >= 0])] += 1
    default = np.clip(model.qpos0[checker.arm_qpos_adr], lower, upper)
    at_default = set(touching(default).tolist())
    pairs: dict[tuple[str, str], str] = {}
    fractions: _Fractions = {}
    padded: _Fractions = {}
    for k, (a, b) in enumerate(candidates):
        pair = _key(model.body(a).name, model.body(b).name)
        fractions[pair] = float(counts[k]) / samples
        padded[pair] = float(near[k]) / samples
        if model.body_parentid[a] == b or model.body_parentid[b] == a:
            pairs[pair] = "adjacent"
        elif counts[k] >= math.ceil(ALWAYS * samples):
            pairs[pair] = "always"
        elif k in at_default:
            pairs[pair] = "default"
        elif counts[k] == 0:
            pairs[pair] = "never"
    return pairs, fractions, padded


def _fingerprint(
    model: mujoco.MjModel,
    robot: Robot,
    mask: np.ndarray,
    margin: float,
    lower: np.ndarray,
    upper: np.ndarray,
    samples: int,
    seed: int,
    pads: np.ndarray,
) -> str:
    """A hash of what the matrix depends on: the robot's bodies and geoms, the limits, the
    margin and paddings."""
    digest = hashlib.sha256(_FORMAT.encode())
    bodies = np.flatnonzero(mask)
    geoms = np.flatnonzero(mask[model.geom_bodyid])
    digest.update("|".join(model.body(b).name for b in bodies).encode())
    parents = model.body_parentid[bodies]
    for array in (
        parents - bodies,
        model.body_pos[bodies],
        model.body_quat[bodies],
        model.geom_type[geoms],
        model.geom_size[geoms],
        model.geom_pos[geoms],
        model.geom_quat[geoms],
        model.geom_contype[geoms],
        model.geom_conaffinity[geoms],
        model.geom_bodyid[geoms] - bodies[0],
        model.geom_rbound[geoms],
        model.qpos0[robot.scene.model.jnt_qposadr[[model.joint(j).id for j in robot.joint_names]]],
        np.asarray(lower, dtype=float),
        np.asarray(upper, dtype=float),
        np.array([margin, samples, seed], dtype=float),
        pads,
    ):
        digest.update(np.ascontiguousarray(np.round(array, 9)).tobytes())
    return digest.hexdigest()[:24]
