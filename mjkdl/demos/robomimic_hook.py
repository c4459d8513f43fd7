"""robomimic's own scripts, run as robomimic documents them (`python robomimic/scripts/train.py
--config bc.json`), on mjkdl's files: `python -m mjkdl.demos.robomimic install` adds a call to
`install()` to robomimic's private macro file (`robomimic/macros_private.py`, which robomimic
imports with its macros, early in its own imports). `install()` registers mjkdl's env type
(`mjkdl.demos.robomimic.register`) as soon as robomimic's `env_utils` and `file_utils`, which
that patches, have finished loading. This module imports nothing of robomimic's: it runs while
robomimic is being imported.
"""

from __future__ import annotations

import importlib
import sys
from types import FrameType
from typing import Any

_PATCHED = ("robomimic.utils.env_utils", "robomimic.utils.file_utils")
_ENV_MODULE = "mjkdl.demos.robomimic"  # registers mjkdl's env type with robomimic
MARK = "# mjkdl: robomimic's scripts build mjkdl's env type"
LINES = f"{MARK}\nfrom mjkdl.demos.robomimic_hook import install\n\ninstall()\n"
"""What `python -m mjkdl.demos.robomimic install` adds to `robomimic/macros_private.py`."""


def _loaded(name: str) -> bool:
    module = sys.modules.get(name)
    return module is not None and not getattr(module.__spec__, "_initializing", False)


def _register() -> None:
    # By name, once robomimic's modules have loaded: mjkdl.demos.robomimic imports them (and
    # this module, for the lines `install` writes), so nothing here may import it earlier.
    importlib.import_module(_ENV_MODULE).register()


def install() -> None:
    """Register mjkdl's env type with robomimic now, or once the modules it patches have
    loaded (a profile hook watches for the end of their module code)."""
    if _ENV_MODULE in sys.modules:
        return  # being imported: whoever imports it registers (its `main` does)
    if all(_loaded(n) for n in _PATCHED):
        _register()
        return
    previous = sys.getprofile()

    def watch(frame: FrameType, event: Any, arg: Any) -> None:
        if previous is not None:
            previous(frame, event, arg)
        if event == "return" and frame.f_code.co_name == "<module>":
            name = frame.f_globals.get("__name__")
            done = [n for n in _PATCHED if n == name or _loaded(n)]
            if len(done) == len(_PATCHED):
                sys.setprofile(previous)
                _register()

    sys.setprofile(watch)
