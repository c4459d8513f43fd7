"""Run a Franka client example unmodified on a machine without a real-time kernel.

`python tests/franka_nonrt.py EXAMPLE.py ARGS...`: libfranka's clients refuse to connect unless
the kernel is PREEMPT_RT (`RealtimeConfig.kEnforce`, their default); against the simulator the
check is moot, so the clients' `Robot` is given `kIgnore` as its default, then the example runs
as `__main__` with its own arguments.
"""

from __future__ import annotations

import runpy
import sys

import pylibfranka


class _Robot(pylibfranka.Robot):
    def __init__(self, address: str, realtime_config=pylibfranka.RealtimeConfig.kIgnore):
        super().__init__(address, realtime_config)


pylibfranka.Robot = _Robot  # type: ignore[misc]
sys.argv = sys.argv[1:]
runpy.run_path(sys.argv[0], run_name="__main__")
