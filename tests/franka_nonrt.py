"""Run a Franka client example unmodified on a machine without a real-time kernel.

`python tests/franka_nonrt.py EXAMPLE.py ARGS...`: libfranka's clients refuse to connect unless
the kernel is PREEMPT_RT (`RealtimeConfig.kEnforce`, their default); against the simulator the
check is moot, so pylibfranka's and franky's `Robot` get "ignore" as their default, then the
example runs as `__main__` with its own arguments. Only the library the example imports is
loaded: both bind a `Duration` type, and pybind11 refuses a second.
"""

from __future__ import annotations

import runpy
import sys
from pathlib import Path
from typing import Any

_source = Path(sys.argv[1]).read_text()
if "import franky" in _source or "from franky" in _source:
    import franky

    class _FrankyRobot(franky.Robot):
        def __init__(self, fci_hostname: str, **kwargs: Any) -> None:
            kwargs.setdefault("realtime_config", franky.RealtimeConfig.Ignore)
            super().__init__(fci_hostname, **kwargs)

    franky.Robot = _FrankyRobot
else:
    import pylibfranka

    class _PylibfrankaRobot(pylibfranka.Robot):
        def __init__(self, address: str, realtime_config: Any = None) -> None:
            super().__init__(address, realtime_config or pylibfranka.RealtimeConfig.kIgnore)

    pylibfranka.Robot = _PylibfrankaRobot

sys.argv = sys.argv[1:]
sys.path.insert(0, str(Path(sys.argv[0]).parent))  # as `python EXAMPLE.py` would: its helpers
runpy.run_path(sys.argv[0], run_name="__main__")
