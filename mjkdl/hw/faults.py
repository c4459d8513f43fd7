"""The errors an arm at an address raises, each naming the cause and the fix.

The vendor clients raise their own exceptions (libfranka's NetworkException, ControlException,
IncompatibleVersionException, ...); `translate` maps them onto `HardwareError` subclasses so a
user catches one family, as for every other mjkdl error.
"""

from __future__ import annotations

from ..errors import MjkdlError


class HardwareError(MjkdlError, RuntimeError):
    """The arm refused, lost or stopped the motion; the arm is at rest when this is raised."""


class ArmConnectionError(HardwareError, ConnectionError):
    """Nothing answers at the address, or the connection dropped."""


class ProtocolVersionError(HardwareError):
    """The client library and the robot speak different versions of the protocol."""


class ReflexError(HardwareError):
    """The robot stopped the motion with a reflex (a limit violation, a collision)."""


class WatchdogWarning(UserWarning):
    """The user's loop stopped sending: the watchdog brought the arm to rest."""


def translate(kind: str, message: str, address: str) -> HardwareError:
    """The mjkdl error for a client exception of class name `kind` with `message`."""
    text = f"{message.strip()} (arm at {address})"
    if kind == "IncompatibleVersionException" or "incompatible" in message.lower():
        return ProtocolVersionError(
            f"{text}: the client library and the robot's server speak different protocol "
            "versions; install the client release that matches the robot's system version "
            "(pylibfranka for FR3, panda-python for Panda)"
        )
    if "refused" in message.lower():
        return ArmConnectionError(
            f"{text}: the robot takes one client at a time: close the other client connected to "
            "it (another program, a FrankaArm or env still open); otherwise check that the "
            "arm (or `python -m mjkdl.hw.franka_sim`) runs at this address with FCI activated "
            "in Desk"
        )
    lower = message.lower()
    if kind == "NetworkException" or "connection" in lower or "udp receive" in lower:
        return ArmConnectionError(
            f"{text}: check that the arm (or `python -m mjkdl.hw.franka_sim`) is running and "
            "reachable at this address, that FCI is activated in Desk, and that no other "
            "client is connected"
        )
    if kind == "ControlException" or "reflex" in message.lower():
        return ReflexError(
            f"{text}: the robot stopped the motion with a reflex; lower the commanded speed "
            "or the contact forces (or raise the collision thresholds); the next command "
            "recovers automatically (automatic_error_recovery)"
        )
    if kind == "RealtimeException":
        return HardwareError(
            f"{text}: this process cannot get real-time scheduling; run on a PREEMPT_RT "
            "kernel with rtprio rights, or connect with realtime=False"
        )
    return HardwareError(f"{kind}: {text}")
