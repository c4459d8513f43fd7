"""Hardware in the loop: real robots' network protocols, served and spoken.

`FrankaArm` drives an arm at an address as a `Robot`; `attach` (what `robot_ip=` does) makes a
real arm one robot of a simulated scene; `mjkdl.hw.franka_sim` serves the Franka protocol from
MuJoCo. The vendor clients come with the `franka` extra (`pip install 'mjkdl[franka]'`) and are
loaded only when an arm is connected.
"""

from .faults import (
    ArmConnectionError,
    HardwareError,
    ProtocolVersionError,
    ReflexError,
    WatchdogWarning,
)
from .franka import FrankaArm
from .in_the_loop import ArmLink, ExternalForces, attach
from .rate_limit import ArmLimits, RateLimiter, limits_for

__all__ = [
    "ArmConnectionError",
    "ArmLimits",
    "ArmLink",
    "ExternalForces",
    "FrankaArm",
    "HardwareError",
    "ProtocolVersionError",
    "RateLimiter",
    "ReflexError",
    "WatchdogWarning",
    "attach",
    "limits_for",
]
