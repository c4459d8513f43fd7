"""The tutorial's tabletop scene (Gen3 + Robotiq 2F-85 on the table), shared by benchmarks."""

from __future__ import annotations

import os
from pathlib import Path

import mjkdl as mjk

ROOT = Path(__file__).resolve().parents[1]
HOME = [0.0, 0.2618, 3.1416, -2.2689, 0.0, 0.9599, 1.5708]
TOOL = mjk.ToolFrameSpec(tool_body="g_base", tcp_site="g_pinch")

_shared = ROOT.parent / "shared" / "menagerie"
if "MENAGERIE_ROOT" not in os.environ and _shared.is_dir():
    os.environ["MENAGERIE_ROOT"] = str(_shared)


def tabletop_spec() -> mjk.SceneSpec:
    """Gen3 with a 2F-85 (prefix `g_`) on the table's `table_top` site, and a task camera."""
    table = mjk.SceneObject(
        name="table", mjcf_path=mjk.assets.path("table"), pos=[0, 0, 0.7], fixed=True
    )
    gripper = mjk.AttachmentSpec(
        mjcf_path=mjk.menagerie.model_path("robotiq_2f85"),
        attach_to=mjk.AttachTarget(mjk.AttachKind.Site, "pinch_site"),
        prefix="g_",
    )
    arm = mjk.RobotSpec(
        path=mjk.menagerie.model_path("kinova_gen3"),
        attach_to=mjk.AttachTarget(
            mjk.AttachKind.Site, mjk.scene_object_site_name(table, "table_top")
        ),
        attachments=[gripper],
    )
    camera = mjk.CameraSpec(name="task", pos=[0.1, -0.9, 1.45], euler=[35.0, 0.0, 5.0], fovy=45.0)
    return mjk.SceneSpec(
        timestep=0.002,
        add_floor=True,
        add_skybox=True,
        objects=[table],
        robots=[arm],
        cameras=[camera],
    )
