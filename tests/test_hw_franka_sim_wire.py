"""The wire layouts against the sizes and offsets libfranka's headers give."""

from __future__ import annotations

from mjkdl.hw.franka_sim import wire


def test_protocol_10_layouts_match_libfranka_0_21():
    state = wire.PROTOCOL_10.state
    assert state.itemsize == 1377
    # offsets of libfranka >= 0.18's RobotState (float32 fields)
    assert state.fields["q"][1] == 596
    assert state.fields["tau_ext_hat_filtered"][1] == 840
    assert state.fields["accelerometer_top"][1] == 1144
    assert state.fields["errors"][1] == 1290
    assert state.fields["control_command_success_rate"][1] == 1373
    command = wire.PROTOCOL_10.command
    assert command.itemsize == 371
    assert command.fields["tau_J_d"][1] == 314
    assert wire.PROTOCOL_10.move_request.size == 113


def test_protocol_5_layouts_match_libfranka_0_9():
    assert wire.PROTOCOL_5.state.itemsize == 2373
    assert wire.PROTOCOL_5.state.fields["control_command_success_rate"][1] == 2365
    assert wire.PROTOCOL_5.command.itemsize == 370
    assert wire.PROTOCOL_5.move_request.size == 56


def test_error_names_are_libfrankas_in_order():
    assert len(wire.ERRORS) == 41
    assert wire.ERROR_INDEX["communication_constraints_violation"] == 25
    assert wire.ERROR_INDEX["controller_torque_discontinuity"] == 32
    assert wire.ERRORS[-1] == "base_acceleration_invalid_reading"


def test_protocol_5_renumbers_the_commands():
    assert wire.PROTOCOL_5.command_of(12) is wire.Command.AUTOMATIC_ERROR_RECOVERY
    assert wire.PROTOCOL_5.command_id(wire.Command.SET_LOAD) == 10
    assert wire.PROTOCOL_5.move_status(wire.MoveStatus.REFLEX_ABORTED) == 6
    assert wire.PROTOCOL_10.command_of(11) is wire.Command.GET_ROBOT_MODEL
    assert wire.PROTOCOL_10.command_of(12) is None
