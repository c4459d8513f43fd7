"""Faults of an arm at an address: each an mjkdl error naming the cause and the fix."""

from __future__ import annotations

import pytest
from conftest import needs_extra

from mjkdl.errors import MjkdlError
from mjkdl.hw.connection import ArmConnection
from mjkdl.hw.faults import (
    ArmConnectionError,
    HardwareError,
    ProtocolVersionError,
    ReflexError,
    translate,
)

needs_extra("franka")

NOBODY = "127.0.0.97"  # a loopback address nothing listens on (the tests' servers use others)


@pytest.mark.parametrize("client", ["pylibfranka", "panda-py"])
def test_nothing_listening_names_the_address_and_the_fix(client: str) -> None:
    with pytest.raises(ArmConnectionError) as caught:
        ArmConnection(NOBODY, "panda", client=client)
    text = str(caught.value)
    assert NOBODY in text and "python -m mjkdl.hw.franka_sim" in text
    assert isinstance(caught.value, ConnectionError) and isinstance(caught.value, MjkdlError)


def test_bad_addresses_and_watchdogs_are_refused_before_connecting() -> None:
    with pytest.raises(ValueError, match="robot_ip must be a host name or IP address, got 7"):
        ArmConnection(7, "panda")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match=r"watchdog must be seconds in \(0, 10\), got 0"):
        ArmConnection(NOBODY, "panda", watchdog=0)
    with pytest.raises(ValueError, match="model must be one of 'panda', 'fr3', got 'ur5'"):
        ArmConnection(NOBODY, "ur5")


@pytest.mark.parametrize(
    ("kind", "message", "error", "fix"),
    [
        (
            "ControlException",
            "libfranka: Move command aborted: motion aborted by reflex! "
            '["joint_velocity_violation"]',
            ReflexError,
            "lower the commanded speed",
        ),
        (
            "IncompatibleVersionException",
            "libfranka: Incompatible library version (Robot: 9, libfranka: 10)",
            ProtocolVersionError,
            "install the client release that matches",
        ),
        (
            "NetworkException",
            "libfranka: UDP receive: Timeout",
            ArmConnectionError,
            "no other client is connected",
        ),
        (  # panda-py raises libfranka's errors as RuntimeError
            "RuntimeError",
            "libfranka: UDP receive: Timeout",
            ArmConnectionError,
            "no other client is connected",
        ),
        (
            "NetworkException",
            "libfranka: Connection to FCI refused. Please install FCI feature or enable FCI "
            "mode in Desk.",
            ArmConnectionError,
            "the robot takes one client at a time",
        ),
        (
            "RealtimeException",
            "libfranka: unable to set realtime scheduling",
            HardwareError,
            "realtime=False",
        ),
    ],
)
def test_client_exceptions_become_named_mjkdl_errors(
    kind: str, message: str, error: type[HardwareError], fix: str
) -> None:
    err = translate(kind, message, "172.16.0.2")
    assert type(err) is error
    assert message in str(err) and "172.16.0.2" in str(err) and fix in str(err)
