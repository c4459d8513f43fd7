"""The descriptions: required fields show as REQUIRED and building without them names them,
also after the copies a task env or a worker process makes."""

from __future__ import annotations

import copy
import pickle

import pytest
from conftest import base_spec

import mjkdl as mjk
from mjkdl.spec import REQUIRED


def test_required_fields_show_as_required() -> None:
    spec = mjk.SceneSpec(timestep=0.002)
    assert spec.add_floor is REQUIRED and spec.add_skybox is REQUIRED
    assert "add_floor=REQUIRED, add_skybox=REQUIRED" in repr(spec)
    camera = mjk.CameraSpec(name="c")
    assert repr(camera).startswith(
        "CameraSpec(name='c', pos=REQUIRED, euler=[0.0, 0.0, 0.0], fovy=REQUIRED"
    )


@pytest.mark.parametrize("field", ["timestep", "add_floor", "add_skybox"])
@pytest.mark.parametrize("how", ["left out", "None", "deep copy", "pickled"])
def test_building_without_a_required_field_names_it(field: str, how: str) -> None:
    spec = base_spec()
    setattr(spec, field, None if how == "None" else REQUIRED)
    if how == "deep copy":
        spec = copy.deepcopy(spec)
    elif how == "pickled":
        spec = pickle.loads(pickle.dumps(spec))
    with pytest.raises(mjk.SpecError) as err:
        mjk.Scene.build(spec)
    assert str(err.value) == f"SceneSpec.{field} is required and has no default: set it"


@pytest.mark.parametrize(
    ("fields", "message"),
    [
        ({"fovy": 45.0}, r"cameras\[0\] \('c'\)\.pos is required"),
        ({"pos": [0, 0, 1]}, r"cameras\[0\] \('c'\)\.fovy is required \(vertical field of view"),
        ({"pos": None, "fovy": 45.0}, r"cameras\[0\] \('c'\)\.pos is required"),
    ],
)
def test_a_camera_without_pos_or_fovy_is_refused(fields: dict, message: str) -> None:
    spec = base_spec(cameras=[copy.deepcopy(mjk.CameraSpec(name="c", **fields))])
    with pytest.raises(mjk.SpecError, match=message):
        mjk.Scene.build(spec)
