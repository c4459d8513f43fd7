"""Property-based test of spec validation (issue #13): random SceneSpecs, valid and invalid.

Every generated spec either builds (and steps) or raises an `MjkdlError` whose message names
the field at fault, within a per-example time limit. CI runs `FAST_EXAMPLES` examples; the
10,000-example run is marked `long` and runs on demand only:

    python -m pytest -m long -p no:cacheprovider tests/test_fuzz_spec.py
"""

from __future__ import annotations

import math
import os
import re
import tempfile
from datetime import timedelta
from pathlib import Path

import numpy as np
import pytest
from conftest import deadline, two_link_arm
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st
from hypothesis.configuration import set_hypothesis_home_dir

import mjkdl as mjk

FAST_EXAMPLES = 300
LONG_EXAMPLES = 10_000
EXAMPLE_SECONDS = 20  # a hang (a FIFO, an XML bomb) fails the example instead of the run

# Every error must name where it comes from: a SceneSpec field or an entry's path.
FIELD = re.compile(r"SceneSpec\.\w+|(objects|robots|cameras)\[\d+\]")

# Hypothesis caches in ./.hypothesis by default: keep the repository clean.
set_hypothesis_home_dir(Path(tempfile.gettempdir()) / f"mjkdl-hypothesis-{os.getuid()}")

COMMON = {
    "deadline": timedelta(seconds=EXAMPLE_SECONDS),
    "database": None,  # nothing written into the repository
    "suppress_health_check": [HealthCheck.too_slow, HealthCheck.data_too_large],
}


# ----------------------------------------------------------------------------- values

# Anything a careless caller might pass where a value is expected.
junk = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(-(10**6), 10**6),
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([1e300, -1e300, 1e-300, 0.0, -0.0]),
    st.text(max_size=4),
    st.sampled_from(["floor", "mjkdl_sun", "a\x00b", "", "0.1", "yes", "no"]),
    st.lists(st.one_of(st.floats(), st.text(max_size=2), st.booleans()), max_size=5),
    st.builds(np.array, st.lists(st.floats(-1, 1), max_size=4)),
    st.just(np.array(["1", "2", "3"])),
    st.just([[0.0, 0.0, 1.0]]),
    st.sampled_from(list(mjk.Shape) + list(mjk.AttachKind) + list(mjk.Condim)),
)


def usually(good: st.SearchStrategy, junk_in: int = 25) -> st.SearchStrategy:
    """A valid value, junk one time in `junk_in`: about a third of the specs are all valid."""
    # Not k == 0: Hypothesis favours the ends of a range.
    return st.integers(0, junk_in - 1).flatmap(lambda k: junk if k == junk_in // 2 else good)


def vec(n: int, lo: float, hi: float) -> st.SearchStrategy:
    return st.lists(st.floats(lo, hi, allow_nan=False), min_size=n, max_size=n)


flags = usually(st.booleans())


def names(kind: str, i: int) -> st.SearchStrategy:
    """Mostly distinct names; clashes (with each other, the floor, a robot) stay possible."""
    clash = st.sampled_from(["cube", "j1", "base", "floor", "top"])
    return usually(st.integers(0, 9).flatmap(lambda k: clash if k == 5 else st.just(f"{kind}{i}")))


poses = usually(vec(3, -2, 2))
eulers = usually(vec(3, -400, 400))


@st.composite
def scene_objects(draw, files: dict[str, str], i: int) -> mjk.SceneObject:
    if draw(st.integers(0, 9)) == 0:  # an MJCF object
        path = draw(usually(st.sampled_from([files["part"], files["missing"], files["folder"]])))
        return mjk.SceneObject(
            name=draw(names("part", i)), mjcf_path=path, pos=draw(poses), fixed=draw(flags)
        )
    shape = draw(usually(st.sampled_from(list(mjk.Shape))))
    n = {"BOX": 3, "SPHERE": 1, "CYLINDER": 2, "CAPSULE": 2, "ELLIPSOID": 3}.get(
        getattr(shape, "name", ""), 3
    )
    return mjk.SceneObject(
        name=draw(names("obj", i)),
        shape=shape,
        size=draw(usually(vec(n, 1e-3, 2))),
        rgba=draw(usually(vec(4, 0, 1))),
        mass=draw(usually(st.floats(0.01, 10))),
        friction=draw(usually(vec(draw(st.integers(1, 3)), 0, 2))),
        condim=draw(usually(st.sampled_from(list(mjk.Condim)))),
        pos=draw(poses),
        euler=draw(eulers),
        fixed=draw(flags),
    )


def targets(kinds: list[mjk.AttachKind], known: list[str]) -> st.SearchStrategy:
    kind = usually(st.sampled_from(kinds))
    return usually(st.builds(mjk.AttachTarget, kind, usually(st.sampled_from(known))))


@st.composite
def robots(draw, files: dict[str, str], i: int) -> mjk.RobotSpec:
    attachments = draw(
        usually(
            st.lists(
                st.builds(
                    mjk.AttachmentSpec,
                    mjcf_path=usually(st.sampled_from([files["tool"], files["missing"]])),
                    attach_to=targets(list(mjk.AttachKind), ["tip", "l2", "base", "nope"]),
                    prefix=usually(st.sampled_from(["t_", "u_", ""])),
                    pos=poses,
                    euler=eulers,
                ),
                max_size=2,
            )
        )
    )
    return mjk.RobotSpec(
        path=draw(usually(st.sampled_from([files["arm"], Path(files["arm"]), files["missing"]]))),
        prefix=draw(usually(st.sampled_from(["", f"r{i}_", f"r{i}_"]))),
        attach_to=draw(st.one_of(st.none(), targets(list(mjk.AttachKind), ["cube/top", "box"]))),
        pos=draw(poses),
        euler=draw(eulers),
        attachments=attachments,
        srdf=draw(usually(st.just(""))),
        floating=draw(usually(st.just(False))),
    )


def cameras(i: int) -> st.SearchStrategy:
    return st.builds(
        mjk.CameraSpec,
        name=names("cam", i),
        pos=usually(vec(3, -3, 3)),
        euler=eulers,
        fovy=usually(st.floats(1, 179)),
        attach_to=st.one_of(
            st.none(), targets([mjk.AttachKind.Body, mjk.AttachKind.Site], ["l1", "tip", "no"])
        ),
    )


def entries(make, most: int) -> st.SearchStrategy:
    """A list of 0..`most` entries, the i-th drawn from `make(i)`."""
    return st.integers(0, most).flatmap(lambda n: st.tuples(*(make(i) for i in range(n))).map(list))


@st.composite
def scene_specs(draw, files: dict[str, str]) -> mjk.SceneSpec:
    return mjk.SceneSpec(
        timestep=draw(usually(st.floats(1e-4, 0.05))),
        add_floor=draw(flags),
        add_skybox=draw(flags),
        gravity_z=draw(usually(st.floats(-20, 0))),
        robots=draw(usually(entries(lambda i: robots(files, i), 2))),
        objects=draw(usually(entries(lambda i: scene_objects(files, i), 3))),
        cameras=draw(usually(entries(cameras, 2))),
    )


# ----------------------------------------------------------------------------- property


@pytest.fixture(scope="module")
def files(tmp_path_factory) -> dict[str, str]:
    """The model files the specs may name: an arm, a tool, a part, and bad paths."""
    root = tmp_path_factory.mktemp("fuzz")
    arm = two_link_arm('<actuator><motor joint="j1"/><motor joint="j2"/></actuator>')
    arm = arm.replace(
        '<body name="l2" pos="0.3 0 0">', '<body name="l2" pos="0.3 0 0">\n<site name="tip"/>'
    )
    (root / "arm.xml").write_text(arm)
    (root / "tool.xml").write_text(
        '<mujoco><worldbody><body name="tool"><geom type="box" size="0.02 0.02 0.02" mass="0.1"/>'
        '<site name="tcp" pos="0 0 0.03"/></body></worldbody></mujoco>'
    )
    (root / "part.xml").write_text(
        '<mujoco><worldbody><body name="part"><geom type="box" size="0.05 0.05 0.05"/>'
        '<site name="top" pos="0 0 0.05"/></body></worldbody></mujoco>'
    )
    (root / "folder").mkdir()
    return {
        "arm": str(root / "arm.xml"),
        "tool": str(root / "tool.xml"),
        "part": str(root / "part.xml"),
        "missing": str(root / "missing.xml"),
        "folder": str(root / "folder"),
    }


def _builds_or_names_a_field(spec: mjk.SceneSpec) -> None:
    with deadline(EXAMPLE_SECONDS, "building a spec"):
        try:
            scene = mjk.Scene.build(spec)
        except mjk.MjkdlError as err:
            event(f"refused: {type(err).__name__}")
            assert FIELD.search(str(err)), f"{type(err).__name__} names no field: {err}"
            return
        with scene:
            event("built")
            assert scene.model.opt.timestep == spec.timestep
            assert math.isfinite(scene.model.opt.gravity[2])
            try:
                scene.step(3)
            except mjk.SimulationError:
                event("built, diverged")


@settings(max_examples=FAST_EXAMPLES, **COMMON)
@given(data=st.data())
def test_random_specs_build_or_name_the_field(files, data) -> None:
    _builds_or_names_a_field(data.draw(scene_specs(files)))


@pytest.mark.long
@settings(max_examples=LONG_EXAMPLES, **COMMON)
@given(data=st.data())
def test_random_specs_long_run(files, data) -> None:
    _builds_or_names_a_field(data.draw(scene_specs(files)))
