"""What the X server shows: a grab of the MuJoCo viewer window (tests and docs pictures)."""

from __future__ import annotations

import os
import re
import shutil
import subprocess

import cv2
import imageio_ffmpeg
import numpy as np


def grab_window() -> np.ndarray:
    """The MuJoCo window's pixels as the X server shows them (BGR), overlays included: the
    window found by xdotool, grabbed by ffmpeg's x11grab (which imageio-ffmpeg ships)."""
    xdotool = shutil.which("xdotool")
    if xdotool is None:
        raise RuntimeError("grab_window needs xdotool (apt-get install xdotool)")
    found = subprocess.run(
        [xdotool, "search", "--onlyvisible", "--name", "^MuJoCo : ", "getwindowgeometry",
         "--shell"],
        capture_output=True, text=True, check=True,
    ).stdout  # fmt: skip
    geometry = dict(re.findall(r"^(X|Y|WIDTH|HEIGHT)=(\d+)$", found, re.MULTILINE))
    x, y, w, h = (int(geometry[k]) for k in ("X", "Y", "WIDTH", "HEIGHT"))
    png = subprocess.run(
        [imageio_ffmpeg.get_ffmpeg_exe(), "-loglevel", "error", "-f", "x11grab",
         "-video_size", f"{w}x{h}", "-i", f"{os.environ['DISPLAY']}+{x},{y}", "-frames:v", "1",
         "-f", "image2pipe", "-vcodec", "png", "-"],
        capture_output=True, check=True,
    ).stdout  # fmt: skip
    return cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_COLOR)
