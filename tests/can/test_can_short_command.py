"""A HostCommand frame with other than 8 data bytes is answered with a rejection, never executed."""
from __future__ import annotations

import uuid

import can
import pytest

from drivers.can import CanHost
from firmware_sim.can_node import CanNode


@pytest.fixture
def buses():
    channel = f"short-{uuid.uuid4().hex}"
    with can.Bus(interface="virtual", channel=channel, preserve_timestamps=True) as dev, \
            can.Bus(interface="virtual", channel=channel, preserve_timestamps=True) as host:
        yield dev, host


@pytest.mark.parametrize("data,echo", [(bytes([3, 5, 9]), (3, 5, 9)), (bytes([1]), (1, 0, 0)), (b"", (0, 0, 0)),
                                       (bytes([3, 5, 9, 0, 0, 0, 0, 0, 0]), (3, 5, 9))])
def test_a_short_or_long_host_command_is_rejected_with_an_ack(buses, device, data, echo):
    dev_bus, host_bus = buses
    node = CanNode(dev_bus, device, bitrate=500_000, heartbeat_period=0.1)
    host = CanHost(host_bus)
    host_bus.send(can.Message(arbitration_id=0x050, data=data, is_extended_id=False, is_fd=len(data) > 8))
    node.advance_to(0.01)
    node.advance_to(0.02)                          # the ack queued at 0.01 goes out after it
    host.poll()
    assert device.calls == []
    (ack,) = host.acks
    assert (ack["cmd"], ack["arg"], ack["host_seq"], ack["status"]) == (*echo, "rejected")
    assert node.rx_errors == [f"HostCommand frame with {len(data)} data bytes rejected (expected 8)"]


def test_a_rejected_command_does_not_count_as_carried_out(buses, device):
    """A served device waits for the host's first command before it runs: a rejected one must not start it."""
    dev_bus, host_bus = buses
    node = CanNode(dev_bus, device, bitrate=500_000, heartbeat_period=0.1)
    host_bus.send(can.Message(arbitration_id=0x050, data=bytes([3, 5]), is_extended_id=False))
    host_bus.send(can.Message(arbitration_id=0x050, data=bytes([99, 0, 1, 0, 0, 0, 0, 0]), is_extended_id=False))
    assert node.handle_commands() == 0                 # a short frame and an unknown command: both acknowledged
    host_bus.send(can.Message(arbitration_id=0x050, data=bytes([6, 0, 2, 0, 0, 0, 0, 0]), is_extended_id=False))
    assert node.handle_commands() == 1                 # Identify: carried out


def test_a_29_bit_frame_with_the_command_number_is_not_a_command(buses, device):
    """0x00000050 (29-bit) and 0x050 (11-bit) are different identifiers on a bus: the extended one ran as a
    HostCommand and was acknowledged Done."""
    dev_bus, host_bus = buses
    node = CanNode(dev_bus, device, bitrate=500_000, heartbeat_period=0.1)
    host_bus.send(can.Message(arbitration_id=0x050, data=bytes([6, 0, 11, 0, 0, 0, 0, 0]), is_extended_id=True))
    assert node.handle_commands() == 0 and device.calls == []
    host_bus.send(can.Message(arbitration_id=0x050, data=bytes([6, 0, 12, 0, 0, 0, 0, 0]), is_extended_id=False))
    assert node.handle_commands() == 1


def test_socketcand_reads_an_id_of_any_length_but_8_as_11_bit():
    """socketcand's rule (state_raw.c): 8 hex digits make an extended id, any other length a standard one; a send
    with id "50" or "0050" was dropped without a reply, so a client that does not pad lost its commands."""
    from firmware_sim.socketcand_server import parse_send
    for text in ("50", "050", "0050"):
        msg = parse_send(f"send {text} 2 06 00")
        assert msg.arbitration_id == 0x050 and not msg.is_extended_id and bytes(msg.data) == b"\x06\x00"
    assert parse_send("send 00000050 1 06").is_extended_id
    with pytest.raises(ValueError, match="inconsistent"):
        parse_send("send 800 1 00")                  # beyond 11 bits, not written as 8 digits
