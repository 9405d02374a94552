"""hallhome.client: transport-level failures, local validation, port choice.

The protocol behaviour against the real firmware (replies, errors, reports,
a board reset, a killed bench) is tested in test_operator_bench.py. Here a
transport test double stands in for the board only where the virtual bench
cannot produce the failure on demand: bytes that are not protocol, a cable
pulled in the middle of a reply, a board that never answers, a reply split
across reads, a line cut by a reset at a chosen byte (the bench's resets cut
lines wherever they fall).
"""

import os
import select
import threading
import time

import pytest

from hallhome import client as hc
from hallhome import protocol
from hallhome.client import (BoardError, BoardReset, Client, Disconnected, LocalError, PortNotFound,
                             ReplyTimeout)


class TransportDouble:
    """Transport test double: the master side of a pty pair, answering each
    line the client writes with the bytes `respond(line)` returns (None:
    no answer). Not a model of the firmware: a script per test."""

    def __init__(self, respond):
        self.master, self.slave = os.openpty()
        self.path = os.ttyname(self.slave)
        self.respond = respond
        self.lines = []         # lines received, in order
        self.raw = bytearray()  # every byte received
        self._stop = False
        self._t = threading.Thread(target=self._run, daemon=True)
        self._t.start()

    def _run(self):
        buf = b""
        while True:
            if self._stop:
                os.close(self.master)
                return
            if not select.select([self.master], [], [], 0.02)[0]:
                continue
            try:
                data = os.read(self.master, 256)
            except OSError:
                return
            self.raw += data
            buf += data
            while b"\n" in buf:
                line, buf = buf.split(b"\n", 1)
                line = line.rstrip(b"\r").decode("ascii", "replace")
                self.lines.append(line)
                out = self.respond(line)
                if out == "CLOSE":
                    self._stop = True
                    break
                if out:
                    self.send(out)

    def send(self, data: bytes):
        os.write(self.master, data)

    def unplug(self):
        """Pulls the cable: the master side closes."""
        self._stop = True
        if threading.current_thread() is not self._t:
            self._t.join()

    def close(self):
        self.unplug()
        os.close(self.slave)


@pytest.fixture
def double():
    made = []

    def make(respond):
        d = TransportDouble(respond)
        made.append(d)
        return d

    yield make
    for d in made:
        d.close()


def answers(table):
    """respond() from a dict line -> bytes; empty lines get ok."""
    def respond(line):
        if line == "":
            return b"ok\r\n"
        return table.get(line)
    return respond


# --- garbled bytes ------------------------------------------------------------

def test_garbled_lines_are_counted_and_skipped(double):
    d = double(answers({"version": b"\xff\xfe\x00garbage\r\n<ver name=x>\r\nnot protocol\r\nok\r\n"}))
    with Client(d.path, timeout=2) as c:
        r = c.command("version")
        assert [x.kind for x in r.reports] == ["ver"]
        assert c.garbled == 2
        assert c.garbled_last == "not protocol"


def test_reply_split_across_reads_is_reassembled(double):
    def respond(line):
        if line == "":
            return b"ok\r\n"
        if line == "status":
            d.send(b"<status sta")
            time.sleep(0.2)
            d.send(b"te=1 t=\"a b\">\r")
            time.sleep(0.1)
            return b"\nok\r\n"
    d = double(respond)
    with Client(d.path, timeout=2) as c:
        r = c.command("status")
        assert r.first("status").fields == {"state": 1, "t": "a b"}
        assert c.garbled == 0


def test_garbled_final_reply_times_out_and_resyncs(double):
    calls = {"n": 0}

    def respond(line):
        if line == "":
            return b"ok\r\n"
        if line == "status":
            calls["n"] += 1
            return b"o\xebk\r\n" if calls["n"] == 1 else b"ok\r\n"
    d = double(respond)
    with Client(d.path, timeout=0.5) as c:
        with pytest.raises(ReplyTimeout, match=r"no reply to `status` within 0.5 s.*1 unreadable"):
            c.command("status")
        n_lines = len(d.lines)
        c.command("status")
        # the client synchronised (an empty line) before the next command
        assert d.lines[n_lines:] == ["", "status"]


def test_stray_bytes_before_sync(double):
    d = double(answers({"help": b"<help cmd=help>\r\nok\r\n"}))
    with Client(d.path, timeout=1, sync=False) as c:
        d.send(b"\x00\x13junk from the bootloader\r\n")
        c.sync()
        assert c.garbled == 1
        assert c.command("help").first("help").get("cmd") == "help"


def test_sync_drains_late_replies_of_an_earlier_session(double):
    # a reply still on its way from before (held `servos scan`), then the
    # sync's own ok: the next command must get its own reply, not these
    d = double(answers({"version": b"<version name=hallhome>\r\nok\r\n"}))
    c = Client(d.path, timeout=1, sync=False)
    d.send(b"<servo tendon=0 id=1 found=1>\r\nok\r\nok\r\n")
    c.sync()
    assert c.event(0.1).kind == "servo"  # kept as an event
    assert c.command("version").first("version").get("name") == "hallhome"
    c.close()


def test_final_reply_without_a_command_is_counted(double):
    d = double(answers({}))
    with Client(d.path, timeout=1) as c:
        d.send(b"ok\r\n<done mode=home time_ms=5>\r\n")
        assert c.event(1.0).kind == "done"
        assert c.garbled == 1


def test_boot_banner_glued_to_a_cut_line_is_a_reset(double):
    # the reset cut `<status ... loops=` and the banner followed on the
    # same line: taken together they even look like one report
    d = double(answers({"status": b"<status state=idle loops=<boot name=hallhome reset=watchdog>\r\n",
                        "version": b"<version name=hallhome>\r\nok\r\n"}))
    with Client(d.path, timeout=1) as c:
        with pytest.raises(BoardReset, match=r"reset \(reset=watchdog\) while `status`") as e:
            c.command("status")
        assert e.value.boot.kind == "boot" and c.resets == 1 and c.garbled == 1
        n = len(d.lines)
        assert c.command("version").first("version") is not None
        assert d.lines[n:] == ["", "version"]  # re-synchronised first


# --- silence -------------------------------------------------------------------

def test_silent_port_fails_sync_with_clear_message(double):
    d = double(lambda line: None)
    with pytest.raises(ReplyTimeout, match="no answer from a hallhome board on .* within 0.6 s"):
        Client(d.path, sync_timeout=0.6)
    assert d.lines.count("") >= 1  # it did try


def test_wrong_baud_rate_hint(double):
    d = double(lambda line: b"\x8f\x9a\xe3\r\n")
    with pytest.raises(ReplyTimeout, match="wrong baud rate"):
        Client(d.path, sync_timeout=0.5)


# --- disconnect ------------------------------------------------------------------

def test_unplug_mid_reply(double):
    def respond(line):
        if line == "":
            return b"ok\r\n"
        if line == "sensors":
            d.send(b"<sensor n=0 ok=1>\r\n")
            time.sleep(0.1)
            return "CLOSE"
    d = double(respond)
    c = Client(d.path, timeout=2)
    with pytest.raises(Disconnected, match="lost the connection to the board on .*USB cable") as e:
        c.command("sensors")
    assert e.value.exit_code == hc.Disconnected.exit_code
    c.close()  # closing a lost port is quiet


def test_unplug_while_waiting_for_events_and_abort_on_close(double):
    def respond(line):
        if line == "":
            return b"ok\r\n"
        if line == "cal":
            return b"ok\r\n"
    d = double(respond)
    c = Client(d.path, timeout=2)
    c.command("cal")
    assert c.motion == "cal"
    d.unplug()
    with pytest.raises(Disconnected):
        c.event(1.0)
    c.close()  # the abort cannot be sent; close still succeeds


def test_open_missing_port():
    with pytest.raises(Disconnected, match="cannot open /dev/does-not-exist"):
        Client("/dev/does-not-exist")


# --- abort on close --------------------------------------------------------------

def test_close_aborts_a_started_calibration(double):
    d = double(answers({"cal 0.8 1": b"ok\r\n<cal t=1 state=pull>\r\n"}))
    c = Client(d.path, timeout=1)
    c.command("cal 0.8 1")
    assert c.motion == "cal"
    c.close()
    time.sleep(0.1)
    assert d.raw.endswith(b"!")


def test_close_after_seen_end_sends_no_abort(double):
    d = double(answers({"cal": b"ok\r\n"}))
    c = Client(d.path, timeout=1)
    c.command("cal")
    c.motion_ended()
    c.close()
    time.sleep(0.1)
    assert b"!" not in d.raw


def test_board_error_carries_code_name_and_text(double):
    d = double(answers({"cal 5": b"<x a=1>\r\nerror:16 tension outside the table grid\r\n"}))
    with Client(d.path, timeout=1) as c:
        with pytest.raises(BoardError) as e:
            c.command("cal 5")
        assert (e.value.code, e.value.name) == (16, "TENSION_RANGE")
        assert e.value.text == "tension outside the table grid"
        assert [r.kind for r in e.value.reports] == ["x"]
        assert c.motion is None


# --- local validation (no board needed: nothing is sent) -------------------------

@pytest.mark.parametrize("line,name", [
    ("frobnicate", "UNKNOWN_COMMAND"),
    ("cal 99", "OUT_OF_RANGE"),
    ("cal x", "BAD_NUMBER"),
    ("learn 1", "MISSING_ARG"),
    ("status 1", "TOO_MANY_ARGS"),
    ("servos all", "BAD_WORD"),
    ("get " + "x" * 60, "LINE_TOO_LONG"),
])
def test_local_validation_rejects_without_sending(line, name):
    c = Client("loop://", sync=False)
    with pytest.raises(LocalError) as e:
        c.command(line)
    assert e.value.code == protocol.ERROR_CODES[name]
    assert c.ser.in_waiting == 0  # loop:// would echo anything written
    c.close()


def test_abort_byte_refused_inside_a_line():
    c = Client("loop://", sync=False)
    with pytest.raises(LocalError, match="realtime abort"):
        c.command("cal!")
    assert c.ser.in_waiting == 0


# --- port choice ------------------------------------------------------------------

class P:
    def __init__(self, device, vid=None, pid=None, desc="n/a"):
        self.device, self.vid, self.pid, self.description = device, vid, pid, desc
        self.serial_number = None


def test_find_port_prefers_the_only_mega():
    ports = [P("/dev/ttyS0"), P("/dev/ttyACM0", 0x2341, 0x0042), P("/dev/ttyUSB0", 0x1A86, 0x7523)]
    assert hc.find_port(None, lambda: ports) == "/dev/ttyACM0"
    assert hc.find_port("/dev/x", lambda: ports) == "/dev/x"
    infos = hc.list_ports(lambda: ports)
    assert [(i.device, i.mega, i.maybe_mega) for i in infos] == [
        ("/dev/ttyACM0", True, False), ("/dev/ttyS0", False, False), ("/dev/ttyUSB0", False, True)]
    assert infos[0].usb_id == "2341:0042"


def test_find_port_old_mega_and_clone_fallback():
    assert hc.find_port(None, lambda: [P("/dev/ttyACM3", 0x2341, 0x0010)]) == "/dev/ttyACM3"
    assert hc.find_port(None, lambda: [P("/dev/ttyUSB1", 0x1A86, 0x7523), P("/dev/ttyS0")]) == "/dev/ttyUSB1"


def test_find_port_failures_say_what_to_do():
    with pytest.raises(PortNotFound, match="no Arduino Mega found.*--port"):
        hc.find_port(None, lambda: [P("/dev/ttyS0")])
    with pytest.raises(PortNotFound, match="several Arduino Megas.*ttyACM0, /dev/ttyACM1"):
        hc.find_port(None, lambda: [P("/dev/ttyACM0", 0x2341, 0x42), P("/dev/ttyACM1", 0x2341, 0x10)])
    with pytest.raises(PortNotFound, match="several possible clones"):
        hc.find_port(None, lambda: [P("/dev/ttyUSB0", 0x1A86, 0x7523), P("/dev/ttyUSB1", 0x10C4, 0xEA60)])
