"""The servo model (sim/devices/xl430_model.c) driven by ROBOTIS's own Python
DynamixelSDK (PyPI ``dynamixel-sdk``) as the bus master, over a
pseudo-terminal served by ``build/native/hh_xl430_pty`` (built by
``make unit``).

Each test asserts a refusal the e-manual documents (XL430-W250 page, control
table Range and Access columns, Bus Watchdog(98); Protocol 2.0 page, Status
Packet error numbers, Action, Factory Reset). A model that stores what a real
servo refuses lets a firmware bug pass on the bench and show only on
hardware, so every check reads the field back as well.

SDK 4.1.0's ``txPacket`` does not stuff outgoing packets (see
test_dxl_sdk.py); the packets that need stuffing are stuffed here with the
SDK's own ``addStuffing`` and sent with ``stuffed_txrx``.
"""

import time

import pytest

from xl430pty import xl430_port

from dynamixel_sdk import COMM_SUCCESS, GroupSyncWrite, PacketHandler

ID = 5
BOOT_S = 0.1  # boot time given to the model (--boot-ms 100)

# Protocol 2.0, "Status Packet" / "Error"
INSTRUCTION, DATA_RANGE, DATA_LENGTH, DATA_LIMIT, ACCESS = 2, 4, 5, 6, 7

# XL430-W250 control table addresses
RETURN_DELAY, OPERATING_MODE, HOMING_OFFSET, MAX_VOLTAGE, VELOCITY_LIMIT = 9, 11, 20, 32, 44
ID_ADDR, TORQUE, STATUS_RETURN, WATCHDOG = 7, 64, 68, 98
PROFILE_ACC, PROFILE_VEL, GOAL, PRESENT_VELOCITY = 108, 112, 116, 128

PH = PacketHandler(2.0)


@pytest.fixture
def port():
    with xl430_port((ID,), BOOT_S * 1000) as handler:
        yield handler


def write(port, addr, value, size, dxl_id=ID):
    fn = {1: PH.write1ByteTxRx, 2: PH.write2ByteTxRx, 4: PH.write4ByteTxRx}[size]
    rc, err = fn(port, dxl_id, addr, value & ((1 << (8 * size)) - 1))
    assert rc == COMM_SUCCESS, PH.getTxRxResult(rc)
    return err & 0x7F


def read(port, addr, size, dxl_id=ID):
    fn = {1: PH.read1ByteTxRx, 2: PH.read2ByteTxRx, 4: PH.read4ByteTxRx}[size]
    value, rc, err = fn(port, dxl_id, addr)
    assert rc == COMM_SUCCESS, PH.getTxRxResult(rc)
    assert err == 0
    return value


def signed(value, size):
    return value - (1 << (8 * size)) if value >= 1 << (8 * size - 1) else value


def stuffed_txrx(port, packet):
    """Sends an SDK-built instruction packet stuffed as the e-manual requires
    and returns (result, error byte) of the status packet."""
    stuffed = PH.addStuffing(list(packet))
    total = (stuffed[5] | stuffed[6] << 8) + 7
    stuffed = stuffed[:total]
    crc = PH.updateCRC(0, stuffed, total - 2)
    stuffed[total - 2], stuffed[total - 1] = crc & 0xFF, crc >> 8
    assert b"\xff\xff\xfd\xfd" in bytes(stuffed[7:]), "the packet was meant to need stuffing"
    port.clearPort()
    port.writePort(stuffed)
    port.setPacketTimeout(12)
    rx, rc = PH.rxPacket(port, False)
    assert rc == COMM_SUCCESS, PH.getTxRxResult(rc)
    return rx[8] & 0x7F


def write_packet(addr, data, dxl_id=ID):
    length = len(data) + 5
    raw = [0xFF, 0xFF, 0xFD, 0x00, dxl_id, length & 0xFF, length >> 8, 0x03,
           addr & 0xFF, addr >> 8] + list(data) + [0, 0]
    return raw


def wait_boot():
    time.sleep(BOOT_S + 0.05)


# --- Data Range: out-of-range values are refused and not stored ---------------

@pytest.mark.parametrize("addr,size,bad,good,name", [
    (TORQUE, 1, 2, 1, "Torque Enable 0..1"),
    (RETURN_DELAY, 1, 255, 254, "Return Delay Time 0..254"),
    (STATUS_RETURN, 1, 3, 2, "Status Return Level 0..2"),
    (WATCHDOG, 1, 128, 127, "Bus Watchdog 0..127"),
    (MAX_VOLTAGE, 2, 160, 130, "Max Voltage Limit 60..140"),
    (MAX_VOLTAGE, 2, 59, 60, "Max Voltage Limit 60..140"),
    (OPERATING_MODE, 1, 2, 1, "Operating Mode 1, 3, 4, 16"),
    (VELOCITY_LIMIT, 4, 1024, 1023, "Velocity Limit 0..1023"),
    (PROFILE_ACC, 4, 32768, 32767, "Profile Acceleration 0..32767"),
])
def test_out_of_range_value_refused_and_not_stored(port, addr, size, bad, good, name):
    before = read(port, addr, size)
    assert write(port, addr, bad, size) == DATA_RANGE, name
    assert read(port, addr, size) == before, name
    assert write(port, addr, good, size) == 0, name
    assert read(port, addr, size) == good, name


def test_id_above_252_refused(port):
    assert write(port, ID_ADDR, 253, 1) == DATA_RANGE
    assert read(port, ID_ADDR, 1) == ID
    value, rc, _ = PH.read1ByteTxRx(port, 253, ID_ADDR)
    assert rc != COMM_SUCCESS, "nobody may answer at ID 253"


def test_profile_velocity_above_velocity_limit_refused(port):
    assert read(port, VELOCITY_LIMIT, 4) == 265
    assert write(port, PROFILE_VEL, 1000, 4) == DATA_RANGE
    assert write(port, PROFILE_VEL, 266, 4) == DATA_RANGE
    assert read(port, PROFILE_VEL, 4) == 0
    assert write(port, PROFILE_VEL, 265, 4) == 0
    # the limit is the field, not a constant: a lower limit lowers the cap
    assert write(port, VELOCITY_LIMIT, 100, 4) == 0
    assert write(port, PROFILE_VEL, 101, 4) == DATA_RANGE
    assert read(port, PROFILE_VEL, 4) == 265
    # time-based profile (Drive Mode bit 2): milliseconds, up to 32737
    assert write(port, 10, 4, 1) == 0
    assert write(port, PROFILE_VEL, 32737, 4) == 0
    assert write(port, PROFILE_VEL, 32738, 4) == DATA_RANGE


def test_refused_profile_velocity_keeps_the_speed_within_the_limit(port):
    assert write(port, OPERATING_MODE, 4, 1) == 0
    assert write(port, PROFILE_VEL, 1000, 4) == DATA_RANGE
    assert write(port, TORQUE, 1, 1) == 0
    assert write(port, GOAL, 40000, 4) == 0
    time.sleep(0.05)
    speed = signed(read(port, PRESENT_VELOCITY, 4), 4)
    assert 0 < speed <= 265


# --- Data Length: writes that cover part of a field ----------------------------

@pytest.mark.parametrize("addr,size,name", [
    (GOAL, 2, "2 of the 4 bytes of Goal Position"),
    (PROFILE_VEL, 1, "1 of the 4 bytes of Profile Velocity"),
    (GOAL + 2, 2, "the upper half of Goal Position"),
    (MAX_VOLTAGE + 1, 1, "the high byte of Max Voltage Limit"),
])
def test_partial_write_refused(port, addr, size, name):
    before = read(port, addr, size)
    assert write(port, addr, 0x0101 & ((1 << (8 * size)) - 1), size) == DATA_LENGTH, name
    assert read(port, addr, size) == before, name


# --- Access: undefined and read-only addresses -----------------------------------

@pytest.mark.parametrize("addr,size", [(14, 1), (56, 4), (66, 1), (96, 1), (132, 4), (0, 2)])
def test_write_to_undefined_or_read_only_address_refused(port, addr, size):
    before = read(port, addr, size)
    assert write(port, addr, 1, size) == ACCESS
    assert read(port, addr, size) == before


def test_eeprom_locked_while_torque_on(port):
    assert write(port, TORQUE, 1, 1) == 0
    assert write(port, RETURN_DELAY, 20, 1) == ACCESS
    assert read(port, RETURN_DELAY, 1) == 0
    assert write(port, TORQUE, 0, 1) == 0
    assert write(port, RETURN_DELAY, 20, 1) == 0
    assert read(port, RETURN_DELAY, 1) == 20


# --- Bus Watchdog(98) ---------------------------------------------------------

def test_bus_watchdog_expiry_zeroes_profile_and_locks_goals(port):
    assert write(port, OPERATING_MODE, 4, 1) == 0
    assert write(port, PROFILE_ACC, 50, 4) == 0
    assert write(port, PROFILE_VEL, 100, 4) == 0
    assert write(port, TORQUE, 1, 1) == 0
    assert write(port, WATCHDOG, 1, 1) == 0  # 20 ms
    time.sleep(0.1)
    assert read(port, WATCHDOG, 1) == 0xFF
    assert read(port, PROFILE_ACC, 4) == 0
    assert read(port, PROFILE_VEL, 4) == 0
    assert write(port, GOAL, 1000, 4) == DATA_RANGE
    assert write(port, WATCHDOG, 0, 1) == 0
    assert write(port, GOAL, 1000, 4) == 0


# --- Action, Factory Reset, Reboot ------------------------------------------------

def action(port):
    """The SDK's own action packet and status parser: its action() and
    txRxPacket() do not wait for the status packet of an Action."""
    packet = [0] * 10
    packet[4], packet[5], packet[6], packet[7] = ID, 3, 0, 0x05
    assert PH.txPacket(port, packet) == COMM_SUCCESS
    port.setPacketTimeout(11)
    rx, rc = PH.rxPacket(port, False)
    assert rc == COMM_SUCCESS, PH.getTxRxResult(rc)
    assert rx[4] == ID
    return rx[8] & 0x7F


def test_action_without_reg_write_is_an_instruction_error(port):
    assert action(port) == INSTRUCTION
    rc, err = PH.regWriteTxRx(port, ID, 65, 1, [1])
    assert (rc, err) == (COMM_SUCCESS, 0)
    assert read(port, 65, 1) == 0
    assert action(port) == 0
    assert read(port, 65, 1) == 1
    assert action(port) == INSTRUCTION, "the registered write is spent"


def test_broadcast_factory_reset_all_not_executed(port):
    assert write(port, RETURN_DELAY, 10, 1) == 0
    PH.factoryReset(port, 0xFE, 0xFF)
    wait_boot()
    assert read(port, RETURN_DELAY, 1) == 10, "firmware 42+ ignores a broadcast Reset All"
    assert read(port, ID_ADDR, 1) == ID
    # the other options are executed when broadcast
    PH.factoryReset(port, 0xFE, 0x02)
    wait_boot()
    assert read(port, RETURN_DELAY, 1) == 250


def test_factory_reset_reboots_the_servo(port):
    assert write(port, RETURN_DELAY, 10, 1) == 0
    assert write(port, TORQUE, 1, 1) == 0
    rc, err = PH.factoryReset(port, ID, 0x02)
    assert (rc, err) == (COMM_SUCCESS, 0)
    _, rc, _ = PH.ping(port, ID)
    assert rc != COMM_SUCCESS, "a servo that is rebooting does not answer"
    wait_boot()
    assert read(port, TORQUE, 1) == 0
    assert read(port, RETURN_DELAY, 1) == 250


def test_reboot_with_torque_on(port):
    assert write(port, TORQUE, 1, 1) == 0
    rc, err = PH.reboot(port, ID)
    assert (rc, err) == (COMM_SUCCESS, 0)
    wait_boot()
    assert read(port, TORQUE, 1) == 0


# --- the firmware's goal packet: one sync write of acceleration, velocity, goal ----

def sync_goal(port, acc, vel, goal):
    group = GroupSyncWrite(port, PH, PROFILE_ACC, 12)
    data = list(acc.to_bytes(4, "little") + vel.to_bytes(4, "little") +
                goal.to_bytes(4, "little", signed=True))
    assert group.addParam(ID, data)
    assert group.txPacket() == COMM_SUCCESS


def test_sync_write_with_refused_velocity_drops_the_whole_goal(port):
    assert write(port, OPERATING_MODE, 4, 1) == 0
    assert write(port, TORQUE, 1, 1) == 0
    goal_before = read(port, GOAL, 4)
    sync_goal(port, 20, 1000, goal_before + 500)
    time.sleep(0.01)
    assert read(port, GOAL, 4) == goal_before
    assert read(port, PROFILE_ACC, 4) == 0
    assert read(port, PROFILE_VEL, 4) == 0
    sync_goal(port, 20, 100, goal_before + 500)
    time.sleep(0.01)
    assert read(port, GOAL, 4) == goal_before + 500
    assert read(port, PROFILE_VEL, 4) == 100


# --- stuffed instruction packets -------------------------------------------------

def test_stuffed_write_accepted_and_refused(port):
    # Homing Offset bytes FF FF FD FF = -131073, inside +-1044479
    assert stuffed_txrx(port, write_packet(HOMING_OFFSET, [0xFF, 0xFF, 0xFD, 0xFF])) == 0
    assert signed(read(port, HOMING_OFFSET, 4), 4) == -131073
    # Goal Position bytes FF FF FD 00 = 16645119, outside 0..4095 (position mode)
    assert write(port, TORQUE, 1, 1) == 0
    goal_before = read(port, GOAL, 4)
    assert stuffed_txrx(port, write_packet(GOAL, [0xFF, 0xFF, 0xFD, 0x00])) == DATA_LIMIT
    assert read(port, GOAL, 4) == goal_before

