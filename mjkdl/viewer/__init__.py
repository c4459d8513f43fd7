"""Interactive viewer: MuJoCo's passive Simulate window with mjkdl's overlays and recorder."""

from .display import NoDisplayError
from .overlays import Overlays
from .viewer import SimulateViewer

__all__ = ["NoDisplayError", "Overlays", "SimulateViewer"]
