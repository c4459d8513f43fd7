"""VideoRecorder: MP4s that play at simulated speed, finalised on errors, clear failures."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
import threading
from pathlib import Path

import cv2
import mujoco
import numpy as np
import pytest
from conftest import HOME, ROOT, base_spec, tutorial_spec

import mjkdl as mjk

FAST = {"shadows": False, "reflections": False}


def _moving_env(timestep: float = 0.002) -> tuple[mjk.Env, mjk.Robot]:
    """The tutorial scene with the arm servoing from its zero pose towards HOME."""
    spec = tutorial_spec()
    spec.timestep = timestep
    env = mjk.Env.build(spec)
    robot = env.create_robot("base_link", "bracelet_link")
    robot.jnt_pos_cmd = np.array(HOME)
    return env, robot


def _read_video(path: Path) -> tuple[int, int, float, list[np.ndarray]]:
    cap = cv2.VideoCapture(str(path))
    assert cap.isOpened(), f"OpenCV cannot open {path}"
    width = int(cap.get(cv2.CAP_PROP_FRAME_WIDTH))
    height = int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT))
    fps = cap.get(cv2.CAP_PROP_FPS)
    frames = []
    while True:
        ok, frame = cap.read()
        if not ok:
            break
        frames.append(frame)
    cap.release()
    return width, height, fps, frames


def test_one_simulated_second_is_one_second_of_video(tmp_path: Path) -> None:
    env, robot = _moving_env()
    path = tmp_path / "one_second.mp4"
    with env, mjk.VideoRecorder.open(env, path, 1280, 720, 30, **FAST) as rec:
        captured = []  # MuJoCo's free camera (the default) frames the whole arm
        for _ in range(500):  # 1.0 s at 2 ms
            robot.update()
            robot.step()
            captured.append(rec.record_frame())
        assert rec.frames_written == 30
        assert sum(captured) == 30 and captured[0]
    width, height, fps, frames = _read_video(path)
    assert (width, height) == (1280, 720)
    assert fps == pytest.approx(30.0, abs=0.01)
    assert abs(len(frames) - 30) <= 1
    change = np.abs(frames[0].astype(int) - frames[-1].astype(int)).mean()
    assert change > 1.0, f"first and last frames are alike (mean abs difference {change:.2f})"


@pytest.mark.parametrize("timestep", [0.001, 0.005, 0.02])
def test_frame_count_does_not_depend_on_the_timestep(tmp_path: Path, timestep: float) -> None:
    spec = base_spec(timestep=timestep)
    spec.objects = [
        mjk.SceneObject(name="ball", shape=mjk.Shape.SPHERE, size=[0.05], pos=[0, 0, 1], mass=0.2)
    ]
    path = tmp_path / f"dt_{timestep}.mp4"
    with mjk.Scene.build(spec) as scene:
        rec = mjk.VideoRecorder.open_preset(scene, path, mjk.VideoResolution.R480p, fps=30, **FAST)
        for _ in range(round(1.0 / timestep)):
            scene.step()
            rec.record_frame()
        rec.close()
    assert rec.frames_written == 30
    width, height, _, frames = _read_video(path)
    assert (width, height) == (854, 480)
    assert abs(len(frames) - 30) <= 1


def test_record_frame_samples_by_simulation_time(tmp_path: Path) -> None:
    scene = mjk.Scene.build(base_spec())
    with scene, mjk.VideoRecorder.open(scene, tmp_path / "clock.mp4", 320, 240, 10, **FAST) as rec:
        assert rec.record_frame() is True  # the first call always captures
        assert rec.record_frame() is False  # same simulation time
        scene.step(49)  # 0.098 s: the next frame is due at 0.1 s
        assert rec.record_frame() is False
        scene.step()
        assert rec.record_frame() is True
        scene.data.time = 0.0  # time going back (a reset) starts a new segment at once
        assert rec.record_frame() is True
        assert rec.frames_written == 3


def test_a_loop_that_raises_still_leaves_a_playable_file(tmp_path: Path) -> None:
    env, robot = _moving_env()
    path = tmp_path / "interrupted.mp4"
    raised = pytest.raises(RuntimeError, match="controller failed")
    with env, raised, mjk.VideoRecorder.open(env, path, 640, 360, 30, **FAST) as rec:
        for i in range(500):
            robot.update()
            robot.step()
            rec.record_frame()
            if i == 249:
                raise RuntimeError("controller failed")
    assert rec.closed
    width, height, _, frames = _read_video(path)
    assert (width, height) == (640, 360)
    assert abs(len(frames) - 15) <= 1


def test_bad_output_paths_are_named(tmp_path: Path) -> None:
    with mjk.Scene.build(base_spec()) as scene:
        missing = tmp_path / "no_such_folder" / "out.mp4"
        with pytest.raises(mjk.VideoWriteError, match="does not exist") as err:
            mjk.VideoRecorder.open(scene, missing, 320, 240, 30)
        assert isinstance(err.value, OSError) and "no_such_folder" in str(err.value)
        if os.geteuid() == 0:
            locked = Path("/proc/self")  # not writable, even for root
        else:
            locked = tmp_path / "locked"
            locked.mkdir(mode=0o500)
        with pytest.raises(mjk.VideoWriteError, match="permission denied"):
            mjk.VideoRecorder.open(scene, locked / "out.mp4", 320, 240, 30)
        with pytest.raises(mjk.SpecError, match=r"\.mp4"):
            mjk.VideoRecorder.open(scene, tmp_path / "out.avi", 320, 240, 30)
        with pytest.raises(mjk.SpecError, match="video path contains a NUL byte"):
            mjk.VideoRecorder.open(scene, f"{tmp_path}/a\x00b.mp4", 320, 240, 30)
        with pytest.raises(mjk.SpecTypeError, match=r"video path must be a path .* got None"):
            mjk.VideoRecorder.open(scene, None, 320, 240, 30)


def test_unknown_camera_lists_close_matches(tmp_path: Path) -> None:
    scene = mjk.Scene.build(tutorial_spec())
    with scene, mjk.VideoRecorder.open(scene, tmp_path / "cam.mp4", 320, 240, 30, **FAST) as rec:
        with pytest.raises(mjk.UnknownNameError) as err:
            rec.use_camera("tsak")
        assert isinstance(err.value, KeyError)
        assert err.value.args[0] == "no camera named 'tsak' in the scene; close matches: task"
        rec.use_camera("task")
        rec.use_camera("")  # back to the free camera
        assert rec.record_frame()


def test_sizes_beyond_the_offscreen_buffer_and_bad_numbers_are_refused(tmp_path: Path) -> None:
    out = tmp_path / "size.mp4"
    with mjk.Scene.build(base_spec()) as scene:
        assert (scene.model.vis.global_.offwidth, scene.model.vis.global_.offheight) == (1920, 1080)
        with pytest.raises(mjk.SpecError, match=r"width 2560 exceeds .*offwidth = 1920"):
            mjk.VideoRecorder.open(scene, out, 2560, 1440, 30)
        with pytest.raises(mjk.SpecError, match=r"height 1200 exceeds .*offheight = 1080"):
            mjk.VideoRecorder.open(scene, out, 1920, 1200, 30)
        with pytest.raises(mjk.SpecError, match="must be even"):
            mjk.VideoRecorder.open(scene, out, 641, 480, 30)
        with pytest.raises(mjk.SpecError, match=r"fps must be from 0\.01 to 240"):
            mjk.VideoRecorder.open(scene, out, 640, 480, 0)
        with pytest.raises(mjk.SpecError, match="VideoResolution"):
            mjk.VideoRecorder.open_preset(scene, out, (640, 480))
        assert not out.exists()


def test_closed_scene_and_closed_recorder_raise_runtime_error(tmp_path: Path) -> None:
    scene = mjk.Scene.build(base_spec())
    rec = mjk.VideoRecorder.open(scene, tmp_path / "closed.mp4", 320, 240, 30, **FAST)
    assert rec.record_frame()
    scene.close()
    with pytest.raises(RuntimeError, match="scene is closed"):
        rec.record_frame()
    with pytest.raises(RuntimeError, match="scene is closed"):
        mjk.VideoRecorder.open(scene, tmp_path / "again.mp4", 320, 240, 30)
    rec.close()
    rec.close()  # idempotent
    with pytest.raises(RuntimeError, match="VideoRecorder is closed"):
        rec.record_frame()
    with pytest.raises(RuntimeError, match="VideoRecorder is closed"):
        rec.use_camera("")
    assert rec.frames_written == 1 and rec.path.stat().st_size > 0


def test_renders_headless_without_mujoco_gl(tmp_path: Path) -> None:
    """No DISPLAY and no MUJOCO_GL (MuJoCo then picks GLFW): the recorder falls back to EGL."""
    script = textwrap.dedent(
        f"""
        import sys
        sys.path.insert(0, {str(ROOT)!r})
        import mjkdl as mjk
        spec = mjk.SceneSpec(timestep=0.01, add_floor=True, add_skybox=False)
        path = {str(tmp_path / "headless.mp4")!r}
        with mjk.Scene.build(spec) as scene, mjk.VideoRecorder.open(scene, path, 320, 240, 10) as r:
            for _ in range(20):
                scene.step()
                r.record_frame()
        print("frames", r.frames_written)
        """
    )
    env = {
        k: v for k, v in os.environ.items() if k not in ("DISPLAY", "MUJOCO_GL", "WAYLAND_DISPLAY")
    }
    env.pop("PYOPENGL_PLATFORM", None)
    done = subprocess.run(
        [sys.executable, "-c", script], env=env, capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 0, done.stderr
    assert "frames 2" in done.stdout  # 0.01 s to 0.2 s at 10 fps
    _, _, _, frames = _read_video(tmp_path / "headless.mp4")
    assert len(frames) == 2


# ----------------------------------------------------------------------------- nothing lost


def _ball_scene(timestep: float) -> mjk.Scene:
    ball = mjk.SceneObject(name="ball", shape=mjk.Shape.SPHERE, size=[0.05], pos=[0, 0, 1], mass=1)
    return mjk.Scene.build(base_spec(timestep=timestep, objects=[ball]))


def test_timestep_longer_than_a_frame_repeats_frames(tmp_path: Path) -> None:
    """dt = 0.05 s at 30 fps: 1.5 frames per step, so frames must be repeated (issue #15)."""
    path = tmp_path / "coarse.mp4"
    with _ball_scene(0.05) as scene:
        with mjk.VideoRecorder.open(scene, path, 320, 240, 30, **FAST) as rec:
            for _ in range(20):  # 1.0 s
                scene.step()
                rec.record_frame()
        # the first capture is at t = 0.05, the last at 1.0: floor(0.95 * 30) + 1 frames
        assert rec.frames_written == 29
    _, _, fps, frames = _read_video(path)
    assert fps == pytest.approx(30.0, abs=0.01)
    assert abs(len(frames) - 30) <= 1  # one simulated second plays for one second


def test_frames_per_capture_are_bounded(tmp_path: Path) -> None:
    with _ball_scene(0.01) as scene:
        for fps in (1e6, 241, 0.009):
            with pytest.raises(mjk.SpecError, match=r"fps must be from 0\.01 to 240 frames per"):
                mjk.VideoRecorder.open(scene, tmp_path / "fast.mp4", 320, 240, fps)
        with mjk.VideoRecorder.open(scene, tmp_path / "jump.mp4", 320, 240, 30, **FAST) as rec:
            rec.record_frame()
            scene.data.time += 0.5  # a half-second hop is real time: 15 repeated frames
            rec.record_frame()
            assert rec.frames_written == 1 + 15
            scene.data.time += 3600.0  # an hour's jump is a new segment, not 108,000 frames
            rec.record_frame()
            assert rec.frames_written == 1 + 15 + 1
            scene.step()
            assert rec.record_frame() is False  # 10 ms later: the next frame is not due yet
    _, _, _, frames = _read_video(tmp_path / "jump.mp4")
    assert len(frames) == 17


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="needs /dev/full")
@pytest.mark.filterwarnings("ignore:video .* cannot be read back:RuntimeWarning")  # on exit
def test_full_disk_is_a_recording_error_not_success(tmp_path: Path) -> None:
    path = tmp_path / "full.mp4"
    path.symlink_to("/dev/full")  # every write fails with ENOSPC, as on a full disk
    with (
        _ball_scene(0.01) as scene,
        pytest.raises(mjk.RecordingError, match=r"full\.mp4"),
        mjk.VideoRecorder.open(scene, path, 320, 240, 30, **FAST) as rec,
    ):
        for _ in range(100):
            scene.step()
            rec.record_frame()


def test_lost_frames_are_a_recording_error(tmp_path: Path, monkeypatch) -> None:
    """An encoder that silently drops frames: close() counts the file's frames."""
    put = mjk.record._Encoder.put
    monkeypatch.setattr(mjk.record._Encoder, "put", lambda self, f, n: put(self, f, n - 1 or 1))
    path = tmp_path / "lossy.mp4"
    with _ball_scene(0.05) as scene:
        rec = mjk.VideoRecorder.open(scene, path, 320, 240, 30, **FAST)
        for _ in range(10):
            scene.step()
            rec.record_frame()
        with pytest.raises(mjk.RecordingError, match=r"lossy\.mp4' holds 10 frames, 14 were"):
            rec.close()
    assert len(_read_video(path)[3]) == 10  # the file read back by OpenCV agrees


def test_empty_recording_is_an_error_but_never_hides_the_real_one(tmp_path: Path) -> None:
    with _ball_scene(0.01) as scene:
        rec = mjk.VideoRecorder.open(scene, tmp_path / "empty.mp4", 320, 240, 30, **FAST)
        with pytest.raises(mjk.RecordingError, match=r"no frame was recorded: .*empty\.mp4"):
            rec.close()
        with (
            pytest.raises(KeyError, match="boom"),
            pytest.warns(RuntimeWarning, match="no frame"),
            mjk.VideoRecorder.open(scene, tmp_path / "e2.mp4", 320, 240, 30, **FAST),
        ):
            raise KeyError("boom")


def test_the_warning_points_at_the_users_with_block(tmp_path: Path) -> None:
    with _ball_scene(0.01) as scene:
        with (
            pytest.raises(KeyError),
            pytest.warns(RuntimeWarning, match="no frame") as warned,
            mjk.VideoRecorder.open(scene, tmp_path / "e3.mp4", 320, 240, 30, **FAST),
        ):
            raise KeyError("boom")
        assert warned[0].filename == __file__


# ----------------------------------------------------------------------------- what is recorded


def _bgr_to_rgb(frame: np.ndarray) -> np.ndarray:
    return frame[:, :, ::-1].astype(int)


def _reference(scene: mjk.Scene, size: tuple[int, int], **view) -> np.ndarray:
    """What MuJoCo's own Renderer shows of the scene's current state (no shadows/reflections)."""
    renderer = mujoco.Renderer(scene.model, height=size[1], width=size[0])
    try:
        renderer.scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = False
        renderer.scene.flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = False
        renderer.update_scene(scene.data, **view)
        return renderer.render().astype(int)
    finally:
        renderer.close()


RED_BLOCK = mjk.SceneObject(
    name="block",
    shape=mjk.Shape.BOX,
    size=[0.3, 0.3, 0.3],
    pos=[0, 0, 0.3],
    mass=1,
    rgba=[1, 0, 0, 1],
    fixed=True,
)


def test_a_rebuilt_scene_is_recorded_through_the_chosen_view(tmp_path: Path) -> None:
    """After add_object the recorder renders the new model through the same camera or view."""
    front = mjk.CameraSpec(name="front", pos=[2.0, 0, 0.5], euler=[90, 90, 0], fovy=45)
    size = (320, 240)
    path = tmp_path / "rebuilt.mp4"
    view = mujoco.MjvCamera()
    mujoco.mjv_defaultCamera(view)
    view.lookat[:], view.distance, view.azimuth, view.elevation = [0, 0, 0.3], 3.0, 45.0, -30.0
    hidden = mujoco.MjvOption()  # the followed view's own option: geom group 0 not drawn
    hidden.geomgroup[0] = 0
    expected = []
    scene = mjk.Scene.build(base_spec(cameras=[front]))
    with scene, mjk.VideoRecorder.open(scene, path, *size, 10, **FAST) as rec:
        rec.use_camera("front")
        scene.add_object(RED_BLOCK)  # a new model: the recorder follows it
        rec.record_frame()
        expected.append(_reference(scene, size, camera="front"))
        rec.follow_view(view, hidden)
        scene.remove_object("block")
        scene.add_object(RED_BLOCK)
        scene.data.time += 0.1
        rec.record_frame()
        expected.append(_reference(scene, size, camera=view, scene_option=hidden))
        rec.use_camera("front")  # the followed view's option goes with it
        scene.data.time += 0.1
        rec.record_frame()
        expected.append(_reference(scene, size, camera="front"))
    frames = [_bgr_to_rgb(f) for f in _read_video(path)[3]]
    assert len(frames) == 3
    for i, (got, want) in enumerate(zip(frames, expected, strict=True)):
        assert np.abs(got - want).mean() < 3.0, f"frame {i} is not the chosen view"
    # the block is in the front camera's picture: red dominates its centre
    centre = frames[0][100:140, 140:180]
    assert centre[..., 0].mean() > 150 and centre[..., 1].mean() < 60
    assert np.abs(frames[1] - frames[0]).mean() > 10.0  # the floor and block not drawn


def test_an_overlay_draws_into_the_recorded_scene(tmp_path: Path) -> None:
    seen: list[tuple[type, int]] = []

    def overlay(scn: mujoco.MjvScene) -> None:
        seen.append((type(scn), scn.ngeom))
        mujoco.mjv_initGeom(
            scn.geoms[scn.ngeom],
            mujoco.mjtGeom.mjGEOM_SPHERE,
            np.array([0.5, 0, 0]),
            np.zeros(3),
            np.eye(3).ravel(),
            np.array([0, 0, 1, 1], dtype=np.float32),
        )
        scn.ngeom += 1

    camera = mujoco.MjvCamera()
    mujoco.mjv_defaultCamera(camera)
    camera.lookat[:], camera.distance = [0, 0, 0.5], 2.0
    path = tmp_path / "overlay.mp4"
    with _ball_scene(0.01) as scene:
        with mjk.VideoRecorder.open(scene, path, 320, 240, 10, **FAST) as rec:
            rec.follow_view(camera, None, overlay)
            rec.record_frame()
        plain = _reference(scene, (320, 240), camera=camera)
        assert seen == [(mujoco.MjvScene, scene.model.ngeom)]
    frame = _bgr_to_rgb(_read_video(path)[3][0])
    blue = (frame[..., 2] > 150) & (frame[..., 0] < 80) & (frame[..., 1] < 80)
    assert (
        blue.sum() > 500 and blue.sum() > 10 * ((plain[..., 2] > 150) & (plain[..., 0] < 80)).sum()
    )


def test_open_preset_defaults_and_passes_its_options(tmp_path: Path) -> None:
    shadow, reflection = mujoco.mjtRndFlag.mjRND_SHADOW, mujoco.mjtRndFlag.mjRND_REFLECTION
    cases = [({}, 60.0, (1, 1)), ({"shadows": False}, 60.0, (0, 1))]
    cases += [({"reflections": False}, 60.0, (1, 0)), ({"fps": 24}, 24.0, (1, 1))]
    with _ball_scene(0.01) as scene:
        for i, (kwargs, fps, flags) in enumerate(cases):
            res = mjk.VideoResolution.R480p
            with mjk.VideoRecorder.open_preset(scene, tmp_path / f"p{i}.mp4", res, **kwargs) as rec:
                assert rec.fps == fps
                drawn = rec._renderer.scene.flags  # what MuJoCo will render with
                assert (drawn[shadow], drawn[reflection]) == flags, kwargs
                rec.record_frame()
            assert _read_video(rec.path)[:2] == (854, 480)


def test_a_jump_of_one_second_is_real_time_and_more_starts_a_new_segment(tmp_path: Path) -> None:
    scene = _ball_scene(0.01)
    with scene, mjk.VideoRecorder.open(scene, tmp_path / "jumps.mp4", 160, 120, 30, **FAST) as rec:
        scene.data.time = 0.0
        rec.record_frame()
        scene.data.time = 1.0  # exactly one second on: 30 frame periods, repeated
        rec.record_frame()
        assert rec.frames_written == 1 + 30
        scene.data.time = 2.5  # 1.5 s on: a new segment, one frame
        rec.record_frame()
        assert rec.frames_written == 1 + 30 + 1


def test_closed_scene_message_names_the_call(tmp_path: Path) -> None:
    scene = _ball_scene(0.01)
    rec = mjk.VideoRecorder.open(scene, tmp_path / "c.mp4", 160, 120, 30, **FAST)
    rec.record_frame()
    scene.close()
    with pytest.raises(RuntimeError) as err:
        rec.record_frame()
    assert str(err.value) == "VideoRecorder.record_frame: the scene is closed"
    rec.close()


# ----------------------------------------------------------------------------- GL backend


class _ContextMade(Exception):
    """Raised by a stand-in GL context class when MuJoCo's Renderer makes one."""


def _stand_in(module: str) -> type:
    def __init__(self, *args, **kwargs):
        raise _ContextMade(module)

    return type("GLContext", (), {"__module__": module, "__init__": __init__})


@pytest.fixture
def gl_context(monkeypatch):
    """MuJoCo's Renderer backend module, with MUJOCO_GL unset."""
    from mujoco.rendering.classic import gl_context

    monkeypatch.delenv("MUJOCO_GL", raising=False)
    return gl_context


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="the EGL fallback is Linux-only")
def test_an_implicit_glfw_backend_renders_through_egl(gl_context, monkeypatch) -> None:
    glfw = _stand_in("mujoco.glfw")
    monkeypatch.setattr(gl_context, "GLContext", glfw)
    with mjk.Scene.build(base_spec()) as scene:
        renderer = mjk.record.offscreen_renderer(scene.model, 64, 48, **FAST)
        try:
            renderer.update_scene(scene.data)
            image = renderer.render()
        finally:
            renderer.close()
    assert image.shape == (48, 64, 3) and image.std() > 0  # drawn, on EGL
    assert gl_context.GLContext is glfw  # MuJoCo's choice is restored


@pytest.mark.parametrize("asked", ["glfw", " GLFW "])
def test_an_explicit_glfw_backend_is_respected(gl_context, monkeypatch, asked) -> None:
    monkeypatch.setattr(gl_context, "GLContext", _stand_in("mujoco.glfw"))
    monkeypatch.setenv("MUJOCO_GL", asked)
    with mjk.Scene.build(base_spec()) as scene, pytest.raises(_ContextMade, match=r"mujoco\.glfw"):
        mjk.record.offscreen_renderer(scene.model, 64, 48)


def test_another_backend_is_used_as_mujoco_chose_it(gl_context, monkeypatch) -> None:
    monkeypatch.setattr(gl_context, "GLContext", _stand_in("mujoco.osmesa"))
    with mjk.Scene.build(base_spec()) as scene, pytest.raises(_ContextMade, match="osmesa"):
        mjk.record.offscreen_renderer(scene.model, 64, 48)


def test_without_egl_the_implicit_glfw_backend_is_kept(gl_context, monkeypatch) -> None:
    import mujoco.egl

    glfw = _stand_in("mujoco.glfw")
    monkeypatch.setattr(gl_context, "GLContext", glfw)
    monkeypatch.setattr(mujoco.egl, "GLContext", _stand_in("mujoco.egl"))  # EGL fails too
    with mjk.Scene.build(base_spec()) as scene, pytest.raises(_ContextMade, match=r"mujoco\.glfw"):
        mjk.record.offscreen_renderer(scene.model, 64, 48)
    assert gl_context.GLContext is glfw


# ------------------------------------------------------------------------ messages and defaults


def test_open_defaults_and_refuses_what_is_not_a_scene(tmp_path: Path) -> None:
    flags = (mujoco.mjtRndFlag.mjRND_SHADOW, mujoco.mjtRndFlag.mjRND_REFLECTION)
    scene = _ball_scene(0.01)
    with scene, mjk.VideoRecorder.open(scene, tmp_path / "d.mp4", 160, 120) as rec:
        assert rec.fps == 30.0
        assert [rec._renderer.scene.flags[f] for f in flags] == [1, 1]
        rec.record_frame()
    with pytest.raises(mjk.SpecError) as err:
        mjk.VideoRecorder.open(object(), tmp_path / "o.mp4", 160, 120)  # type: ignore[arg-type]
    assert str(err.value) == "VideoRecorder needs a Scene or Env, got object"


def test_output_path_errors_name_the_path_and_folder(tmp_path: Path) -> None:
    with _ball_scene(0.01) as scene:
        avi, missing = tmp_path / "out.avi", tmp_path / "nope" / "out.mp4"
        with pytest.raises(mjk.SpecError) as err:
            mjk.VideoRecorder.open(scene, avi, 160, 120)
        assert str(err.value) == f"video path must end in .mp4, got {str(avi)!r}"
        with pytest.raises(mjk.VideoWriteError) as err:
            mjk.VideoRecorder.open(scene, missing, 160, 120)
        assert str(err.value) == (
            f"cannot write video {str(missing)!r}: folder {str(missing.parent)!r} does not exist"
        )
        folder = tmp_path / "folder.mp4"
        folder.mkdir()  # passes the permission bits, fails to open
        with pytest.raises(mjk.VideoWriteError) as err:
            mjk.VideoRecorder.open(scene, folder, 160, 120)
        assert str(err.value) == f"cannot write video {str(folder)!r}: Is a directory"
        if os.geteuid() == 0:
            with pytest.raises(mjk.VideoWriteError) as err:
                mjk.VideoRecorder.open(scene, "/proc/self/out.mp4", 160, 120)
            assert str(err.value) == "cannot write video '/proc/self/out.mp4': permission denied"


def test_an_existing_file_is_overwritten_and_kept_when_opening_fails(tmp_path: Path) -> None:
    path = tmp_path / "old.mp4"
    path.write_bytes(b"an older video")
    with _ball_scene(0.01) as scene:
        with pytest.raises(mjk.SpecError, match="offscreen buffer"):
            mjk.VideoRecorder.open(scene, path, 2560, 1440)
        assert path.read_bytes() == b"an older video"  # not ours to delete
        with mjk.VideoRecorder.open(scene, path, 160, 120, 10, **FAST) as rec:
            for _ in range(20):
                scene.step()
                rec.record_frame()
    assert len(_read_video(path)[3]) == 2


def test_the_free_camera_is_kept_over_a_rebuild(tmp_path: Path) -> None:
    path = tmp_path / "free.mp4"
    scene = mjk.Scene.build(base_spec())
    with scene, mjk.VideoRecorder.open(scene, path, 320, 240, 10, **FAST) as rec:
        scene.add_object(RED_BLOCK)
        rec.record_frame()
        expected = _reference(scene, (320, 240))  # MuJoCo's default free camera
    frame = _bgr_to_rgb(_read_video(path)[3][0])
    assert np.abs(frame - expected).mean() < 3.0


def test_encoder_settings_are_in_the_stream_and_its_thread_is_named(tmp_path: Path) -> None:
    path = tmp_path / "x264.mp4"
    scene = _ball_scene(0.01)
    before = set(threading.enumerate())
    with scene, mjk.VideoRecorder.open(scene, path, 160, 120, 10, **FAST) as rec:
        started = set(threading.enumerate()) - before
        assert [(t.name, t.daemon) for t in started] == [("mjkdl-video-encoder", True)]
        rec.record_frame()
    # x264 writes its settings into the stream: libx264's ultrafast preset, constant quality 23
    options = path.read_bytes().split(b"x264 - core", 1)[1].split(b"\x00", 1)[0].decode()
    assert "crf=23.0" in options.split() and "subme=0" in options.split()
    assert "me=dia" in options.split() and "cabac=0" in options.split()


class _BrokenWriter:
    """Stands in for imageio-ffmpeg's frame writer when ffmpeg has died."""

    def __init__(self, writer, error: Exception) -> None:
        self._writer, self._error = writer, error

    def send(self, frame) -> None:
        raise self._error

    def close(self) -> None:
        self._writer.close()


@pytest.mark.parametrize(
    ("error", "shown"),
    [(BrokenPipeError("pipe closed\nffmpeg said more"), "pipe closed"), (OSError(), "OSError")],
)
def test_an_encoder_failure_is_a_write_error_naming_the_file(tmp_path: Path, error, shown) -> None:
    path = tmp_path / "broken.mp4"
    with _ball_scene(0.01) as scene:
        rec = mjk.VideoRecorder.open(scene, path, 160, 120, 100, **FAST)
        encoder = rec._encoder
        encoder._writer = _BrokenWriter(encoder._writer, error)
        with pytest.raises(mjk.VideoWriteError) as err:
            for _ in range(50):  # the failure comes back on a later frame or at close
                scene.step()
                rec.record_frame()
            rec.close()
        assert str(err.value) == f"video encoder failed writing {str(path)!r}: {shown}"
        if not rec.closed:  # raised by record_frame: the file is short of what was recorded
            with pytest.raises(mjk.RecordingError, match=r"broken\.mp4"):
                rec.close()
    assert not encoder._thread.is_alive()


@pytest.mark.parametrize(
    ("error", "shown"),
    [
        (RuntimeError("ffmpeg failed:\nInvalid data\nmoov atom not found "), "moov atom not found"),
        (OSError(), "OSError"),
    ],
)
def test_an_unreadable_video_is_a_recording_error(tmp_path: Path, monkeypatch, error, shown):
    def unreadable(path):
        raise error

    path = tmp_path / "unreadable.mp4"
    with _ball_scene(0.01) as scene:
        rec = mjk.VideoRecorder.open(scene, path, 160, 120, 10, **FAST)
        rec.record_frame()
        monkeypatch.setattr(mjk.record.imageio_ffmpeg, "count_frames_and_secs", unreadable)
        with pytest.raises(mjk.RecordingError) as err:
            rec.close()
    assert str(err.value) == f"video {str(path)!r} cannot be read back: {shown}"


def test_offscreen_renderer_sizes_and_defaults() -> None:
    flags = (mujoco.mjtRndFlag.mjRND_SHADOW, mujoco.mjtRndFlag.mjRND_REFLECTION)
    with mjk.Scene.build(base_spec()) as scene:
        for bad, shown in ((0, "0"), (-2, "-2"), (True, "True"), (1.5, "1.5")):
            with pytest.raises(mjk.SpecError) as err:
                mjk.record.offscreen_renderer(scene.model, bad, 48)
            assert str(err.value) == f"width must be a positive integer, got {shown}"
            with pytest.raises(mjk.SpecError) as err:
                mjk.record.offscreen_renderer(scene.model, 64, bad)
            assert str(err.value) == f"height must be a positive integer, got {shown}"
        renderer = mjk.record.offscreen_renderer(scene.model, 1, 1)  # the smallest image
        try:
            assert [renderer.scene.flags[f] for f in flags] == [1, 1]
            renderer.update_scene(scene.data)
            assert renderer.render().shape == (1, 1, 3)
        finally:
            renderer.close()


@pytest.mark.parametrize(("mujoco_gl", "shown"), [(None, "default (glfw)"), ("osmesa", "osmesa")])
def test_no_gl_context_is_an_offscreen_render_error(gl_context, monkeypatch, mujoco_gl, shown):
    def no_display(self, *args, **kwargs):
        raise mujoco.FatalError("gladLoadGL error")

    backend = type("GLContext", (), {"__module__": "mujoco.osmesa", "__init__": no_display})
    monkeypatch.setattr(gl_context, "GLContext", backend)
    if mujoco_gl is not None:
        monkeypatch.setenv("MUJOCO_GL", mujoco_gl)
    with mjk.Scene.build(base_spec()) as scene, pytest.raises(mjk.OffscreenRenderError) as err:
        mjk.record.offscreen_renderer(scene.model, 64, 48)
    assert str(err.value) == (
        f"cannot create an OpenGL context for offscreen rendering (MUJOCO_GL={shown}): "
        "gladLoadGL error. On a machine without a display set MUJOCO_GL=egl (or osmesa) before "
        "importing mujoco or mjkdl."
    )


def test_open_checks_sizes_and_rates_with_exact_messages(tmp_path: Path) -> None:
    out = tmp_path / "o.mp4"
    with _ball_scene(0.01) as scene:
        for width, height, field, value in ((641, 480, "width", 641), (640, 1, "height", 1)):
            with pytest.raises(mjk.SpecError) as err:
                mjk.VideoRecorder.open(scene, out, width, height)
            assert str(err.value) == f"{field} must be even for H.264 yuv420p video, got {value}"
        for fps in (0, -30, 1e-300, 240.001):
            with pytest.raises(mjk.SpecError) as err:
                mjk.VideoRecorder.open(scene, out, 160, 120, fps)
            assert str(err.value) == (
                f"fps must be from 0.01 to 240 frames per simulated second, got {fps!r}"
            )
        for fps in (0.01, 0.5, 1, 240):  # the limits are inclusive
            with mjk.VideoRecorder.open(scene, out, 160, 120, fps, **FAST) as rec:
                rec.record_frame()
            assert rec.fps == fps
    closed = _ball_scene(0.01)
    closed.close()
    with pytest.raises(RuntimeError) as err:
        mjk.VideoRecorder.open(closed, out, 160, 120)
    assert str(err.value) == "VideoRecorder.open: the scene is closed"


# ----------------------------------------------------------------------------- bad input


FIXED, TRACKING = mujoco.mjtCamera.mjCAMERA_FIXED, mujoco.mjtCamera.mjCAMERA_TRACKING
TWO_CAMERAS = [
    mjk.CameraSpec(name=name, pos=[2.0, 0, 0.5], euler=[90, 90, 0], fovy=45)
    for name in ("front", "side")
]
NOT_A_TYPE = "is not mjCAMERA_FREE (0), mjCAMERA_TRACKING (1) or mjCAMERA_FIXED (2)"


def _camera(kind: int, fixedcamid: int = -1, trackbodyid: int = -1) -> mujoco.MjvCamera:
    camera = mujoco.MjvCamera()
    camera.type, camera.fixedcamid, camera.trackbodyid = kind, fixedcamid, trackbodyid
    return camera


def _two_camera_scene() -> mjk.Scene:
    """Two model cameras (ids 0, 1) and two bodies: the world (0) and a ball (1)."""
    ball = mjk.SceneObject(name="ball", shape=mjk.Shape.SPHERE, size=[0.05], pos=[0, 0, 1], mass=1)
    scene = mjk.Scene.build(base_spec(cameras=TWO_CAMERAS, objects=[ball]))
    assert (scene.model.ncam, scene.model.nbody) == (2, 2)
    return scene


@pytest.mark.parametrize(
    ("kind", "fixedcamid", "trackbodyid", "message"),
    [
        (FIXED, 50, 0, "camera.fixedcamid 50 is not a camera of the scene (it has 2: 0..1)"),
        (FIXED, -1, 0, "camera.fixedcamid -1 is not a camera of the scene (it has 2: 0..1)"),
        (FIXED, 2, 0, "camera.fixedcamid 2 is not a camera of the scene (it has 2: 0..1)"),
        (TRACKING, 0, 999, "camera.trackbodyid 999 is not a body of the scene (it has 2: 0..1)"),
        (TRACKING, 0, -1, "camera.trackbodyid -1 is not a body of the scene (it has 2: 0..1)"),
        (99, 0, 0, f"camera.type 99 {NOT_A_TYPE}"),
        (-1, 0, 0, f"camera.type -1 {NOT_A_TYPE}"),
        (mujoco.mjtCamera.mjCAMERA_USER, 0, 0, f"camera.type 3 {NOT_A_TYPE}"),
    ],
)
def test_follow_view_refuses_a_camera_mujoco_would_end_the_process_on(
    tmp_path: Path, kind: int, fixedcamid: int, trackbodyid: int, message: str
) -> None:
    """mjv_updateScene calls mju_error on each of these: the interpreter would exit."""
    scene = _two_camera_scene()
    with scene, mjk.VideoRecorder.open(scene, tmp_path / "v.mp4", 160, 120, 10, **FAST) as rec:
        with pytest.raises(mjk.SpecError) as err:
            rec.follow_view(_camera(kind, fixedcamid, trackbodyid))
        assert str(err.value) == f"follow_view: {message}"
        assert rec.record_frame()  # still the free camera
        fine = (_camera(FIXED, 0), _camera(FIXED, 1), _camera(TRACKING, -1, 0))
        for camera in (*fine, _camera(TRACKING, -1, 1)):  # first and last camera and body
            rec.follow_view(camera)
            scene.data.time += 0.1
            assert rec.record_frame()
        assert rec.frames_written == 5


@pytest.mark.parametrize("kind", [mujoco.mjtCamera.mjCAMERA_FREE, TRACKING])
@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("lookat", [float("nan"), 0.0, 0.3]),
        ("distance", float("inf")),
        ("azimuth", float("nan")),
        ("elevation", float("-inf")),
    ],
)
def test_a_camera_placed_by_a_nan_is_refused_not_recorded_black(
    tmp_path: Path, kind: int, field: str, value: object
) -> None:
    scene = _two_camera_scene()
    camera = _camera(kind, trackbodyid=1)
    camera.lookat[:], camera.distance, camera.azimuth, camera.elevation = [0, 0, 0.3], 3, 45, -30
    with scene, mjk.VideoRecorder.open(scene, tmp_path / "v.mp4", 160, 120, 10, **FAST) as rec:
        rec.follow_view(camera)
        assert rec.record_frame()
        if field == "lookat":
            camera.lookat[:] = value
        else:
            setattr(camera, field, value)
        pose = [camera.lookat.tolist(), camera.distance, camera.azimuth, camera.elevation]
        message = (
            "the camera's lookat {}, distance {}, azimuth {} and elevation {} must be finite"
        ).format(*pose)
        scene.data.time += 0.1
        with pytest.raises(mjk.SpecError) as err:  # live: checked before the next frame
            rec.record_frame()
        assert str(err.value) == f"record_frame: {message}"
        with pytest.raises(mjk.SpecError) as err:
            rec.follow_view(camera)
        assert str(err.value) == f"follow_view: {message}"
        assert rec.frames_written == 1


def test_a_fixed_camera_in_a_scene_without_cameras_is_refused(tmp_path: Path) -> None:
    scene = _ball_scene(0.01)
    assert scene.model.ncam == 0
    with scene, mjk.VideoRecorder.open(scene, tmp_path / "v.mp4", 160, 120, 10, **FAST) as rec:
        with pytest.raises(mjk.SpecError) as err:
            rec.follow_view(_camera(FIXED, 0))
        assert str(err.value) == (
            "follow_view: camera.fixedcamid 0 is not a camera of the scene (it has none)"
        )
        assert rec.record_frame()  # still the free camera


def test_a_named_camera_is_found_again_when_a_rebuild_renumbers_it(tmp_path: Path) -> None:
    eye = tmp_path / "eye.xml"
    eye.write_text(
        '<mujoco><worldbody><body name="post" pos="0 0 0.2">'
        '<geom type="box" size="0.1 0.1 0.2" rgba="0 1 0 1"/>'
        '<camera name="eye" pos="0 -1.5 0.3" euler="80 0 0"/></body></worldbody></mujoco>'
    )
    posts = [
        mjk.SceneObject(name=n, mjcf_path=eye, pos=[x, 0, 0]) for n, x in (("a", -1), ("b", 1))
    ]
    size = (160, 120)
    path = tmp_path / "renumbered.mp4"
    scene = mjk.Scene.build(base_spec(objects=posts))
    assert scene.camera_names() == ["a/eye", "b/eye"]
    with scene, mjk.VideoRecorder.open(scene, path, *size, 10, **FAST) as rec:
        rec.use_camera("b/eye")
        scene.remove_object("a")  # b/eye is camera 0 now, and the only one
        rec.record_frame()
        expected = _reference(scene, size, camera="b/eye")
    frame = _bgr_to_rgb(_read_video(path)[3][0])
    assert np.abs(frame - expected).mean() < 3.0


def test_a_followed_camera_is_checked_before_every_frame_and_after_a_rebuild(
    tmp_path: Path,
) -> None:
    scene = _two_camera_scene()
    camera = _camera(TRACKING, trackbodyid=1)  # the ball
    with scene, mjk.VideoRecorder.open(scene, tmp_path / "v.mp4", 160, 120, 10, **FAST) as rec:
        rec.follow_view(camera)
        assert rec.record_frame()
        scene.remove_object("ball")  # the model shrinks: body 1 is gone
        scene.data.time += 0.1
        with pytest.raises(mjk.SpecError) as err:
            rec.record_frame()
        assert str(err.value) == (
            "record_frame: camera.trackbodyid 1 is not a body of the scene (it has 1: 0)"
        )
        camera.type, camera.fixedcamid = FIXED, 7  # a live camera, edited between frames
        with pytest.raises(mjk.SpecError) as err:
            rec.record_frame()
        assert str(err.value) == (
            "record_frame: camera.fixedcamid 7 is not a camera of the scene (it has 2: 0..1)"
        )
        camera.fixedcamid = 1
        assert rec.record_frame()
        assert rec.frames_written == 2


@pytest.mark.parametrize(
    ("args", "message"),
    [
        ((None,), "camera must be a mujoco.MjvCamera, got None"),
        (("nope",), "camera must be a mujoco.MjvCamera, got 'nope'"),
        ((99,), "camera must be a mujoco.MjvCamera, got 99"),
        ((mujoco.MjvCamera(), "x"), "option must be a mujoco.MjvOption or None, got 'x'"),
        ((mujoco.MjvCamera(), None, 5), "overlay must be callable or None, got 5"),
    ],
)
def test_follow_view_checks_its_arguments(tmp_path: Path, args: tuple, message: str) -> None:
    with (
        _ball_scene(0.01) as scene,
        mjk.VideoRecorder.open(scene, tmp_path / "v.mp4", 160, 120, 10, **FAST) as rec,
    ):
        with pytest.raises(mjk.SpecTypeError) as err:
            rec.follow_view(*args)
        assert str(err.value) == f"follow_view: {message}"
        assert rec.record_frame()  # nothing was taken over


def test_a_followed_view_without_option_survives_a_rebuild(tmp_path: Path) -> None:
    size = (320, 240)
    path = tmp_path / "followed.mp4"
    view = mujoco.MjvCamera()
    mujoco.mjv_defaultCamera(view)
    view.lookat[:], view.distance, view.azimuth, view.elevation = [0, 0, 0.3], 3.0, 45.0, -30.0
    scene = mjk.Scene.build(base_spec())
    with scene, mjk.VideoRecorder.open(scene, path, *size, 10, **FAST) as rec:
        rec.follow_view(view)  # no option: MuJoCo's default visualisation
        scene.add_object(RED_BLOCK)
        rec.record_frame()
        expected = _reference(scene, size, camera=view)
        free = _reference(scene, size)
    frame = _bgr_to_rgb(_read_video(path)[3][0])
    assert np.abs(frame - expected).mean() < 3.0
    assert np.abs(frame - free).mean() > 10.0  # not MuJoCo's free camera


@pytest.mark.parametrize("time", [float("nan"), float("inf"), float("-inf")])
def test_a_non_finite_simulation_time_is_a_simulation_error(tmp_path: Path, time: float) -> None:
    scene = _ball_scene(0.01)
    with scene, mjk.VideoRecorder.open(scene, tmp_path / "t.mp4", 160, 120, 10, **FAST) as rec:
        assert rec.record_frame()
        scene.data.time = time
        with pytest.raises(mjk.SimulationError) as err:
            rec.record_frame()
        assert str(err.value) == (
            f"record_frame: the simulation time data.time is {time}; frames are taken by "
            "simulation time, which must be finite"
        )
        assert isinstance(err.value, RuntimeError) and err.value.warnings == {}
        assert str(err.value.time) == str(time)
        scene.data.time = 0.1  # the clock is untouched: the next frame is due
        assert rec.record_frame()
        assert rec.frames_written == 2


@pytest.mark.parametrize(
    ("fps", "error", "message"),
    [
        ("30", mjk.SpecTypeError, "fps must be a number, got '30'"),
        (True, mjk.SpecTypeError, "fps must be a number, got True"),
        (None, mjk.SpecTypeError, "fps must be a number, got None"),
        (float("nan"), mjk.SpecError, "fps must be finite, got nan"),
        (float("inf"), mjk.SpecError, "fps must be finite, got inf"),
        (
            1e-300,
            mjk.SpecError,
            "fps must be from 0.01 to 240 frames per simulated second, got 1e-300",
        ),
        (
            0.0099,
            mjk.SpecError,
            "fps must be from 0.01 to 240 frames per simulated second, got 0.0099",
        ),
    ],
)
def test_fps_is_a_number_ffmpeg_can_write(tmp_path: Path, fps, error, message) -> None:
    out = tmp_path / "fps.mp4"
    with _ball_scene(0.01) as scene:
        with pytest.raises(error) as err:
            mjk.VideoRecorder.open(scene, out, 160, 120, fps)
        assert type(err.value) is error and str(err.value) == message
    assert not out.exists()


@pytest.mark.parametrize(
    ("flags", "message"),
    [
        ({"shadows": "no"}, "shadows must be True or False, got 'no'"),
        ({"reflections": None}, "reflections must be True or False, got None"),
        ({"shadows": 0}, "shadows must be True or False, got 0"),
        ({"shadows": False, "reflections": 1}, "reflections must be True or False, got 1"),
    ],
)
def test_quality_flags_must_be_true_or_false(tmp_path: Path, flags: dict, message: str) -> None:
    out = tmp_path / "flags.mp4"
    with _ball_scene(0.01) as scene:
        for make in (
            lambda: mjk.VideoRecorder.open(scene, out, 160, 120, **flags),
            lambda: mjk.VideoRecorder.open_preset(scene, out, mjk.VideoResolution.R480p, **flags),
            lambda: mjk.record.offscreen_renderer(scene.model, 64, 48, **flags),
        ):
            with pytest.raises(mjk.SpecTypeError) as err:
                make()
            assert str(err.value) == message
    assert not out.exists()


@pytest.mark.parametrize(
    ("name", "error", "message"),
    [
        (None, mjk.SpecTypeError, "use_camera: name must be a string, got None"),
        (5, mjk.SpecTypeError, "use_camera: name must be a string, got 5"),
        ("fr\x00ont", mjk.SpecError, "use_camera: name contains a NUL byte: 'fr\\x00ont'"),
    ],
)
def test_use_camera_needs_a_name(tmp_path: Path, name, error, message) -> None:
    scene = _two_camera_scene()
    with scene, mjk.VideoRecorder.open(scene, tmp_path / "n.mp4", 160, 120, 10, **FAST) as rec:
        with pytest.raises(error) as err:
            rec.use_camera(name)
        assert type(err.value) is error and str(err.value) == message
        assert rec.record_frame()


# ---------------------------------------------------------------------- save_image


def test_save_image_writes_what_the_renderer_gives(tmp_path: Path) -> None:
    with _ball_scene(0.002) as scene, mujoco.Renderer(scene.model, 48, 64) as renderer:
        renderer.update_scene(scene.data)
        rgb = renderer.render()
    rgb[0, 0] = (255, 0, 0)  # a red pixel: the channel order must survive
    path = mjk.save_image(tmp_path / "frame.png", rgb)
    assert path == tmp_path / "frame.png"
    back = cv2.cvtColor(cv2.imread(str(path)), cv2.COLOR_BGR2RGB)
    assert np.array_equal(back, rgb)  # PNG is lossless
    grey = rgb[:, :, 1].copy()
    mjk.save_image(str(tmp_path / "grey.png"), grey)
    assert np.array_equal(cv2.imread(str(tmp_path / "grey.png"), cv2.IMREAD_GRAYSCALE), grey)


def test_save_image_refuses_bad_input_by_name(tmp_path: Path) -> None:
    rgb = np.zeros((4, 5, 3), np.uint8)
    cases = [
        ((tmp_path / "a.png", rgb.tolist()), mjk.SpecTypeError, "must be a NumPy array, got list"),
        (
            (tmp_path / "a.png", rgb.astype(np.float32)),
            mjk.SpecError,
            r"save_image\(rgb\) must be uint8 of shape \(H, W, 3\) or \(H, W\), got float32 of "
            r"shape \(4, 5, 3\)",
        ),
        ((tmp_path / "a.png", rgb[:, :, :2]), mjk.SpecError, r"got uint8 of shape \(4, 5, 2\)"),
        ((tmp_path / "a.png", rgb[:0]), mjk.SpecError, r"save_image\(rgb\) is empty"),
        ((None, rgb), mjk.SpecTypeError, r"save_image\(path\) must be a path"),
        (
            (tmp_path / "a.xyz", rgb),
            mjk.ImageWriteError,
            r"a\.xyz': no image writer for suffix '\.xyz'; use \.png",
        ),
        (
            (tmp_path / "missing" / "a.png", rgb),
            mjk.ImageWriteError,
            r"folder '.*missing' does not exist",
        ),
    ]
    for args, error, message in cases:
        with pytest.raises(error, match=message):
            mjk.save_image(*args)
    (tmp_path / "dir.png").mkdir()
    with pytest.raises(OSError, match=r"cannot write image '.*dir\.png'"):
        mjk.save_image(tmp_path / "dir.png", rgb)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dir.png"]
