"""Name lookups: MuJoCo's ids, and errors that say where and list the close names."""

from __future__ import annotations

import mujoco
import pytest

import mjkdl as mjk
from mjkdl.names import model_id

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


@pytest.mark.parametrize("name", ["", None, 3])
def test_empty_or_non_string_names_are_unknown(model, name) -> None:
    with pytest.raises(mjk.UnknownNameError, match=f"no camera named '{name}' in here"):
        model_id(model, mujoco.mjtObj.mjOBJ_CAMERA, "camera", name, "here")
