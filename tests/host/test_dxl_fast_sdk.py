"""Fast Sync Read (instruction 0x8A) of the servo model checked against
ROBOTIS's own parser: DynamixelSDK's ``GroupSyncRead.fastSyncRead()`` drives
a chain of models (sim/devices/xl430_model.c) over the pseudo-terminal of
``build/native/hh_xl430_pty`` (built by ``make unit``), every byte one model
sends being seen by the others as on a shared bus.

The SDK reads the reply as one status packet from ID 0xFE, checks only its
final CRC, and takes per servo a block of ERR, ID, the data and a 2-byte CRC
field. The models must answer that way: the first ID sends the header, each
one its block in the request's ID order, the last one the CRC, and a silent
servo breaks the chain (the ones after it never get their turn).
"""

import time

import pytest

from xl430pty import xl430_port

from dynamixel_sdk import (COMM_RX_CORRUPT, COMM_RX_TIMEOUT, COMM_SUCCESS, GroupSyncRead,
                           PacketHandler)

IDS = (1, 2, 3, 4, 5, 6)
PROFILE_ACC, PRESENT_POSITION = 108, 132

PH = PacketHandler(2.0)


@pytest.fixture
def port():
    with xl430_port(IDS, 50) as handler:
        time.sleep(0.1)  # boot
        yield handler


def set_profile(port, dxl_id, acc, vel):
    for addr, value in ((PROFILE_ACC, acc), (PROFILE_ACC + 4, vel)):
        rc, err = PH.write4ByteTxRx(port, dxl_id, addr, value)
        assert rc == COMM_SUCCESS and err == 0, PH.getTxRxResult(rc)


def group(port, addr, size, ids):
    g = GroupSyncRead(port, PH, addr, size)
    for dxl_id in ids:
        assert g.addParam(dxl_id)
    return g


def raw_reply(port, g, wait_s=0.05):
    """Sends the SDK's fast sync read request and returns every byte that came back."""
    port.clearPort()
    assert g.fastSyncReadTxPacket() == COMM_SUCCESS
    time.sleep(wait_s)
    data = bytes(port.readPort(512))
    port.is_using = False  # the SDK's receive step, skipped here, would clear it
    return data


def test_sdk_reads_every_servo_in_one_packet(port):
    for dxl_id in IDS:
        set_profile(port, dxl_id, 1000 + 7 * dxl_id, 10 * dxl_id)
    g = group(port, PROFILE_ACC, 8, IDS)
    rc = g.fastSyncRead()
    assert rc == COMM_SUCCESS, PH.getTxRxResult(rc)
    for dxl_id in IDS:
        assert g.isAvailable(dxl_id, PROFILE_ACC, 8)
        assert g.getData(dxl_id, PROFILE_ACC, 4) == 1000 + 7 * dxl_id
        assert g.getData(dxl_id, PROFILE_ACC + 4, 4) == 10 * dxl_id
    # Present Position as the plain read gives it
    g = group(port, PRESENT_POSITION, 4, IDS)
    assert g.fastSyncRead() == COMM_SUCCESS
    for dxl_id in IDS:
        value, rc, err = PH.read4ByteTxRx(port, dxl_id, PRESENT_POSITION)
        assert rc == COMM_SUCCESS and err == 0
        assert g.getData(dxl_id, PRESENT_POSITION, 4) == value


def test_reply_layout_byte_by_byte(port):
    ids = (3, 1, 2)  # answered in the request's order, not by ID
    for dxl_id in ids:
        set_profile(port, dxl_id, 100 * dxl_id, 0)
    reply = raw_reply(port, group(port, PROFILE_ACC, 4, ids))
    n, per = 4, 4 + 4
    assert len(reply) == 8 + len(ids) * per, reply.hex()
    assert reply[:5] == b"\xff\xff\xfd\x00\xfe"
    assert int.from_bytes(reply[5:7], "little") == 1 + len(ids) * per
    assert reply[7] == 0x55
    for i, dxl_id in enumerate(ids):
        block = reply[8 + i * per: 8 + (i + 1) * per]
        assert block[0] == 0 and block[1] == dxl_id
        assert int.from_bytes(block[2:2 + n], "little") == 100 * dxl_id
        # each block's CRC field: the CRC of the packet up to the end of the
        # block's data; for the last block that is the packet CRC the SDK checks
        end = 8 + i * per + 2 + n
        assert int.from_bytes(block[2 + n:], "little") == PH.updateCRC(0, list(reply), end)


def test_silent_servo_breaks_the_chain(port):
    ids = (1, 9, 2)  # no servo 9
    g = group(port, PRESENT_POSITION, 4, ids)
    reply = raw_reply(port, g, wait_s=0.1)
    # header and servo 1's block; servo 2 waits for 9's block, which never comes
    assert len(reply) == 8 + 8, reply.hex()
    assert int.from_bytes(reply[5:7], "little") == 1 + 3 * 8
    assert reply[9] == 1
    # what the SDK makes of it: no success, no data
    rc = g.fastSyncRead()
    assert rc in (COMM_RX_TIMEOUT, COMM_RX_CORRUPT), PH.getTxRxResult(rc)
    assert not g.isAvailable(1, PRESENT_POSITION, 4)
    # the chain works again at the next request
    g = group(port, PRESENT_POSITION, 4, (1, 2))
    assert g.fastSyncRead() == COMM_SUCCESS
    assert g.isAvailable(2, PRESENT_POSITION, 4)


def test_sdk_refuses_a_corrupted_reply(port):
    """The model's reply with one byte flipped fails the SDK's CRC check:
    the check the model's good replies pass is a real one."""
    g = group(port, PRESENT_POSITION, 4, IDS[:3])
    reply = bytearray(raw_reply(port, g))
    assert len(reply) == 8 + 3 * 8
    total = len(reply)
    assert PH.updateCRC(0, list(reply), total - 2) == int.from_bytes(reply[-2:], "little")
    reply[12] ^= 0x04
    assert PH.updateCRC(0, list(reply), total - 2) != int.from_bytes(reply[-2:], "little")
