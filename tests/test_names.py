"""Name lookups: MuJoCo's ids, and errors that say where and list the close names."""

from __future__ import annotations

import mujoco
import pytest

import mjkdl as mjk
from mjkdl.names import find_id, model_id

XML = """<mujoco><worldbody>
  <body name="upper_arm"><joint name="shoulder"/><geom size="0.1"/><site name="elbow_site"/>
    <body name="lower_arm"><joint name="elbow"/><geom size="0.1"/></body></body>
  <camera name="front" pos="1 0 0"/>
</worldbody></mujoco>"""


@pytest.fixture(scope="module")
def model() -> mujoco.MjModel:
    return mujoco.MjModel.from_xml_string(XML)


@pytest.mark.parametrize(
    ("obj", "name"),
    [
        (mujoco.mjtObj.mjOBJ_BODY, "lower_arm"),
        (mujoco.mjtObj.mjOBJ_JOINT, "elbow"),
        (mujoco.mjtObj.mjOBJ_SITE, "elbow_site"),
        (mujoco.mjtObj.mjOBJ_CAMERA, "front"),
    ],
)
def test_known_names_give_mujocos_ids(model, obj, name) -> None:
    assert model_id(model, obj, "thing", name, "here") == mujoco.mj_name2id(model, obj, name)


def test_unknown_name_says_where_and_lists_close_names(model) -> None:
    with pytest.raises(mjk.UnknownNameError) as err:
        model_id(model, mujoco.mjtObj.mjOBJ_BODY, "body", "lower_ram", "the test scene")
    assert str(err.value) == (
        "no body named 'lower_ram' in the test scene; close matches: lower_arm, upper_arm"
    )
    assert isinstance(err.value, KeyError)


@pytest.mark.parametrize("name", ["", "front\x00", "\x00front"])
def test_empty_names_and_names_cut_by_a_nul_byte_are_unknown(model, name) -> None:
    with pytest.raises(mjk.UnknownNameError) as err:
        model_id(model, mujoco.mjtObj.mjOBJ_CAMERA, "camera", name, "here")
    assert err.value.args[0].startswith(f"no camera named {name!r} in here; ")
    assert find_id(model, mujoco.mjtObj.mjOBJ_CAMERA, name) == -1


@pytest.mark.parametrize("name", [None, 3, b"front", ["front"]])
def test_names_that_are_not_text_never_reach_mujoco(model, name) -> None:
    # mj_name2id crashes the interpreter on None.
    with pytest.raises(mjk.SpecTypeError) as err:
        model_id(model, mujoco.mjtObj.mjOBJ_CAMERA, "camera", name, "here")
    assert str(err.value) == f"camera name in here must be a string, got {name!r}"
    assert find_id(model, mujoco.mjtObj.mjOBJ_CAMERA, name) == -1
