"""Serial client for the hallhome firmware's console (docs/console.md).

One `Client` talks to one board over any port pyserial can open
(`serial_for_url`: a device such as /dev/ttyACM0, a pty path of the virtual
bench, or `loop://`). It

* synchronises with an empty line (the firmware answers `ok`), tolerating the
  boot banner and the Arduino bootloader's start-up delay after a DTR reset;
* sends one command line and collects the `<...>` reports up to its one final
  `ok` or `error:<code> <text>`; an error becomes a `BoardError` carrying the
  code, its name from con_errors.def and the firmware's text;
* checks every line locally with `protocol.check_command` first, so a line the
  firmware would reject is never sent (`LocalError`, same code);
* sends the realtime abort `!` on request, and on `close()` when a motion
  command it started has not been seen to finish, so the board is never left
  calibrating by a host that went away;
* notices a `<boot ...>` banner in mid-session (the board reset: `BoardReset`,
  and the next command re-synchronises first), counts lines that are not
  protocol (`garbled`), turns a missing reply into `ReplyTimeout` and a lost
  port into `Disconnected`.

Command names, error codes and their texts come only from protocol.py, which
reads the firmware's declarations.
"""

from __future__ import annotations

import collections
import errno
import os
import time
from dataclasses import dataclass, field
from typing import Callable, Deque, Dict, List, Optional

import serial
import serial.tools.list_ports

from hallhome import protocol

BAUD = 115200

# Longest the firmware holds a reply (the console's pending deadline, 3 s)
# plus margin for the USB link and a slow simulator.
DEFAULT_TIMEOUT = 6.0
# How long sync() keeps trying: the Mega's bootloader delays the firmware by
# about 1.5 s after the DTR reset that opening the port causes.
SYNC_TIMEOUT = 6.0
SYNC_RETRY = 0.4
QUIET = 0.15  # a pause this long ends the drain after a sync

# Commands that start motion which outlives their `ok`: if the host that
# started one goes away before it is seen to end, close() aborts it.
MOTION_COMMANDS = ("cal", "survey", "rehome", "home")
for _name in MOTION_COMMANDS:
    if _name not in protocol.COMMANDS_BY_NAME:
        raise RuntimeError(f"command {_name!r} is no longer declared in con_commands.def")

ABORT_BYTE = b"!"
BOOT_PREFIX = "<boot "  # the firmware's banner after any reset

# USB IDs of Arduino Mega 2560 boards. Clones carry a generic USB serial
# bridge, so a port with one of those IDs is only "possibly" a Mega.
MEGA_IDS = {
    (0x2341, 0x0042): "Arduino Mega 2560 R3",
    (0x2341, 0x0010): "Arduino Mega 2560",
    (0x2341, 0x0242): "Arduino Mega 2560 R3 (DFU firmware)",
    (0x2A03, 0x0042): "Arduino Mega 2560 R3 (arduino.org)",
    (0x2A03, 0x0010): "Arduino Mega 2560 (arduino.org)",
}
CLONE_IDS = {
    (0x1A86, 0x7523): "CH340 (Mega clone?)",
    (0x1A86, 0x55D4): "CH9102 (Mega clone?)",
    (0x10C4, 0xEA60): "CP210x (Mega clone?)",
    (0x0403, 0x6001): "FT232R (Mega clone?)",
}


# --- errors --------------------------------------------------------------------

class HallhomeError(Exception):
    """Base of every failure the client reports; `exit_code` is what the
    command line tool exits with."""

    exit_code = 1


class LocalError(HallhomeError):
    """A command line the firmware would reject; it was not sent."""

    exit_code = 2

    def __init__(self, line: str, code: int, message: str):
        self.line, self.code = line, code
        err = protocol.ERRORS.get(code)
        self.name = err.id if err else None
        super().__init__(f"`{line}` not sent: {message}")


class BoardError(HallhomeError):
    """The firmware answered `error:<code> <text>`."""

    exit_code = 1

    def __init__(self, line: str, code: int, text: str, reports: List["Report"] = ()):
        self.line, self.code, self.text = line, code, text
        err = protocol.ERRORS.get(code)
        self.name = err.id if err else None
        self.reports = list(reports)
        super().__init__(f"`{line}`: error {code} {self.name or '(unknown code)'}: {text}")


class ReplyTimeout(HallhomeError):
    exit_code = 3


class BoardReset(HallhomeError):
    """The board printed its boot banner in mid-session: it reset (power,
    watchdog, reset button or a DTR pulse) and whatever it was doing ended."""

    exit_code = 4

    def __init__(self, message: str, boot: "Report"):
        self.boot = boot
        super().__init__(message)


class Disconnected(HallhomeError):
    """The port could not be opened or went away (cable unplugged)."""

    exit_code = 5


class PortNotFound(HallhomeError):
    exit_code = 5


class PortBusy(HallhomeError):
    """Another program (another `hallhome` command) has the port open: the
    client takes an exclusive lock, so a second session never steals the
    first one's replies or resets the board under it."""

    exit_code = 6


# --- reports and replies --------------------------------------------------------

@dataclass
class Report:
    """One `<kind key=value ...>` line. Integer values are ints, decimals
    (`0.800`) and words are strings."""

    kind: str
    fields: Dict[str, object]
    raw: str
    at: float = 0.0  # time.monotonic() when it arrived

    def get(self, key: str, default=None):
        return self.fields.get(key, default)

    def num(self, key: str, default: Optional[float] = None) -> Optional[float]:
        """A field as a number (ints and fixed-point decimals), else default."""
        v = self.fields.get(key)
        if isinstance(v, int):
            return v
        try:
            return float(v)  # type: ignore[arg-type]
        except (TypeError, ValueError):
            return default


@dataclass
class Reply:
    line: str
    reports: List[Report] = field(default_factory=list)

    def of(self, kind: str) -> List[Report]:
        return [r for r in self.reports if r.kind == kind]

    def first(self, kind: str) -> Optional[Report]:
        for r in self.reports:
            if r.kind == kind:
                return r
        return None


# --- ports ---------------------------------------------------------------------

@dataclass
class PortInfo:
    device: str
    description: str
    vid: Optional[int]
    pid: Optional[int]
    serial_number: Optional[str]
    board: Optional[str]   # what the USB IDs say, or None
    mega: bool             # an Arduino Mega by its USB IDs
    maybe_mega: bool       # a USB serial bridge that Mega clones use

    @property
    def usb_id(self) -> str:
        return f"{self.vid:04X}:{self.pid:04X}" if self.vid is not None else "-"


def classify(vid: Optional[int], pid: Optional[int]) -> tuple:
    """(board name or None, is a Mega, may be a Mega clone) for USB IDs."""
    if vid is None or pid is None:
        return None, False, False
    if (vid, pid) in MEGA_IDS:
        return MEGA_IDS[(vid, pid)], True, False
    if (vid, pid) in CLONE_IDS:
        return CLONE_IDS[(vid, pid)], False, True
    return None, False, False


def list_ports(comports: Callable = serial.tools.list_ports.comports) -> List[PortInfo]:
    out = []
    for p in sorted(comports(), key=lambda p: p.device):
        board, mega, maybe = classify(p.vid, p.pid)
        out.append(PortInfo(p.device, p.description or "", p.vid, p.pid, p.serial_number,
                            board, mega, maybe))
    return out


def find_port(explicit: Optional[str] = None, comports: Callable = serial.tools.list_ports.comports) -> str:
    """The port to use: the one given, else the only Arduino Mega connected
    (by USB IDs), else the only clone-type USB serial bridge. Raises
    PortNotFound with what to do otherwise."""
    if explicit:
        return explicit
    ports = list_ports(comports)
    megas = [p for p in ports if p.mega]
    if len(megas) == 1:
        return megas[0].device
    if len(megas) > 1:
        raise PortNotFound("several Arduino Megas are connected (" + ", ".join(p.device for p in megas)
                           + "): choose one with --port or HALLHOME_PORT")
    clones = [p for p in ports if p.maybe_mega]
    if len(clones) == 1:
        return clones[0].device
    if len(clones) > 1:
        raise PortNotFound("no Arduino Mega by USB ID, several possible clones (" +
                           ", ".join(p.device for p in clones) + "): choose one with --port")
    raise PortNotFound("no Arduino Mega found: plug it in, or give the port with --port or "
                       "HALLHOME_PORT (`hallhome ports` lists the serial ports)")


# --- the client ----------------------------------------------------------------

class Client:
    """A session with one board. Not thread-safe: one thread at a time (the
    interactive console serialises with a lock)."""

    def __init__(self, port: str, *, baud: int = BAUD, timeout: float = DEFAULT_TIMEOUT,
                 sync: bool = True, sync_timeout: float = SYNC_TIMEOUT,
                 on_report: Optional[Callable[[Report], None]] = None,
                 ends_motion: Optional[Callable[[Report], bool]] = None):
        self.port = port
        self.ends_motion = ends_motion  # a report that says the motion ended
        self.timeout = timeout
        self.on_report = on_report
        self.garbled = 0                 # lines that were not protocol
        self.garbled_last: Optional[str] = None
        self.resets = 0                  # boot banners seen after the first sync
        self.boot: Optional[Report] = None
        self.motion: Optional[str] = None  # motion command started and not seen to end
        self._buf = bytearray()
        self._events: Deque[Report] = collections.deque()
        self._synced = False
        self._need_sync = True
        self._closed = False
        try:
            ser = serial.serial_for_url(port, do_not_open=True, baudrate=baud, timeout=0.05,
                                        write_timeout=2.0, exclusive=True)
            ser.open()
        except (serial.SerialException, OSError, ValueError) as e:
            if getattr(e, "errno", None) in (errno.EAGAIN, errno.EWOULDBLOCK, errno.EBUSY):
                raise PortBusy(f"port busy: {port} is in use by another program (another "
                               "hallhome command?); wait until it ends, or stop it") from None
            raise Disconnected(f"cannot open {port}: {_why(e)}") from None
        self.ser = ser
        if sync:
            self.sync(sync_timeout)

    # -- context management: never leave a started calibration running --
    def __enter__(self) -> "Client":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        """Aborts a motion this client started and has not seen end (best
        effort: the port may already be gone), then closes the port."""
        if self._closed:
            return
        self._closed = True
        try:
            if self.motion is not None:
                self.abort(wait=1.0)
        except HallhomeError:
            pass
        finally:
            try:
                self.ser.close()
            except (serial.SerialException, OSError):
                pass

    # -- byte level --
    def _write(self, data: bytes) -> None:
        try:
            self.ser.write(data)
            self.ser.flush()
        except (serial.SerialException, OSError) as e:
            raise Disconnected(self._lost(e)) from None

    def _lost(self, e: Exception) -> str:
        return (f"lost the connection to the board on {self.port} ({_why(e)}): "
                "is the USB cable plugged in?")

    def _read_line(self, deadline: float) -> Optional[str]:
        """The next complete line (without CR/LF), or None at the deadline."""
        while True:
            nl = self._buf.find(b"\n")
            if nl >= 0:
                raw = bytes(self._buf[:nl]).rstrip(b"\r")
                del self._buf[:nl + 1]
                try:
                    return raw.decode("ascii")
                except UnicodeDecodeError:
                    self._garble(printable(raw))
                    continue
            if time.monotonic() >= deadline:
                return None
            try:
                n = self.ser.in_waiting
                chunk = self.ser.read(n if n else 1)
            except (serial.SerialException, OSError) as e:
                raise Disconnected(self._lost(e)) from None
            if chunk:
                self._buf += chunk

    def _garble(self, text: str) -> None:
        self.garbled += 1
        self.garbled_last = text

    def _next(self, deadline: float) -> Optional[dict]:
        """The next parsed protocol line (dict from protocol.parse_line, with
        `report` set to a Report for reports); garbled lines are counted and
        skipped. None at the deadline."""
        while True:
            line = self._read_line(deadline)
            if line is None:
                return None
            if line == "":
                continue
            # A reset cuts the line being written: the banner then follows
            # the cut line's start without a line break, and the whole may
            # even parse as one report (`loops=<boot name=...>`).
            cut = line.rfind(BOOT_PREFIX)
            if cut > 0:
                self._garble(line[:cut])
                line = line[cut:]
            try:
                msg = protocol.parse_line(line)
            except protocol.ProtocolError:
                self._garble(line)
                continue
            msg["raw"] = line
            if msg["type"] == "report":
                rep = Report(msg["kind"], msg["fields"], line, time.monotonic())
                msg["report"] = rep
                if rep.kind == "boot":
                    self._on_boot(rep)
                elif self.motion is not None and self.ends_motion is not None and self.ends_motion(rep):
                    self.motion = None
                if self.on_report is not None:
                    self.on_report(rep)
            return msg

    def _on_boot(self, rep: Report) -> None:
        if self._synced:
            self.resets += 1
            self._need_sync = True
        self.boot = rep
        self.motion = None  # a reset board runs nothing

    def reset_message(self, rep: Report, during: str) -> str:
        why = rep.get("reset")
        return (f"the board reset{f' (reset={why})' if why else ''} {during}: "
                "whatever it was doing has stopped and nothing moves")

    # -- protocol level --
    def sync(self, timeout: float = SYNC_TIMEOUT) -> None:
        """Sends empty lines until the board answers `ok`, then drains what
        is left (extra `ok`s, a late reply of an earlier session). Reports
        that arrive meanwhile are kept as events."""
        start = time.monotonic()
        deadline = start + timeout
        got = False
        while not got and time.monotonic() < deadline:
            self._write(b"\n")
            retry = min(deadline, time.monotonic() + SYNC_RETRY)
            while True:
                msg = self._next(retry)
                if msg is None:
                    break
                if msg["type"] == "ok":
                    got = True
                    break
                if msg["type"] == "report":
                    self._events.append(msg["report"])
        if not got:
            raise ReplyTimeout(
                f"no answer from a hallhome board on {self.port} within {timeout:g} s "
                "(is the firmware flashed, is this the right port?)"
                + (f"; {self.garbled} unreadable lines, last '{self.garbled_last}': wrong baud rate "
                   "or another program on the port?" if self.garbled else ""))
        while True:
            msg = self._next(time.monotonic() + QUIET)
            if msg is None:
                break
            if msg["type"] == "report":
                self._events.append(msg["report"])
        self._synced = True
        self._need_sync = False

    def command(self, line: str, timeout: Optional[float] = None) -> Reply:
        """Sends one command line and returns its reports once the board
        answers `ok`. Raises LocalError (not sent), BoardError (`error:`),
        ReplyTimeout, BoardReset or Disconnected."""
        line = line.strip()
        if "!" in line:
            raise LocalError(line, 0, "`!` is the realtime abort, the board would act on it "
                                      "at once; send it alone (abort())")
        try:
            cmd, _ = protocol.check_command(line)
        except protocol.CommandError as e:
            raise LocalError(line, e.code, str(e)) from None
        except ValueError:
            self.sync()
            return Reply(line)
        if self._need_sync:
            self.sync()
        self._write(line.encode("ascii") + b"\n")
        wait = self.timeout if timeout is None else timeout
        deadline = time.monotonic() + wait
        reply = Reply(line)
        while True:
            msg = self._next(deadline)
            if msg is None:
                self._need_sync = True
                raise ReplyTimeout(
                    f"no reply to `{line}` within {wait:g} s from {self.port}"
                    + (f" ({self.garbled} unreadable lines so far)" if self.garbled else "")
                    + ": the board may be hung; reset it and try again")
            if msg["type"] == "report":
                rep = msg["report"]
                if rep.kind == "boot" and self._synced:
                    raise BoardReset(self.reset_message(rep, f"while `{line}` was waiting for its "
                                                             "reply"), rep)
                reply.reports.append(rep)
                continue
            if msg["type"] == "ok":
                if cmd.name in MOTION_COMMANDS:
                    self.motion = cmd.name
                return reply
            raise BoardError(line, msg["code"], msg["text"], reply.reports)

    def event(self, timeout: float) -> Optional[Report]:
        """The next asynchronous report (kept ones first), or None when none
        arrives within timeout. A final reply with no command waiting for it
        is counted as garbled. A `<boot>` comes back as a report (check
        `kind == "boot"`, or use `self.resets`)."""
        if self._events:
            return self._events.popleft()
        deadline = time.monotonic() + timeout
        while True:
            msg = self._next(deadline)
            if msg is None:
                return None
            if msg["type"] == "report":
                return msg["report"]
            self._garble(f"{msg['raw']} (a reply with no command waiting for it)")

    def abort(self, wait: float = 0.0, until: Callable[[Report], bool] = lambda r: False) -> List[Report]:
        """Sends the realtime stop `!`. With wait > 0, collects reports for up
        to `wait` seconds or until one satisfies `until`; returns them. The
        motion this client started counts as ended."""
        self._write(ABORT_BYTE)
        self.motion = None
        got = []
        if wait > 0:
            deadline = time.monotonic() + wait
            while True:
                msg = self._next(deadline)
                if msg is None:
                    break
                if msg["type"] == "report":
                    got.append(msg["report"])
                    if until(msg["report"]):
                        break
        return got

    def motion_ended(self) -> None:
        """The caller saw the motion it started end (result or fault)."""
        self.motion = None


def printable(raw: bytes) -> str:
    """Bytes as text an operator can read: ASCII kept, anything else as \\xNN."""
    return "".join(chr(b) if 0x20 <= b < 0x7F else f"\\x{b:02x}" for b in raw)


def _why(e: Exception) -> str:
    s = str(e)
    if isinstance(e, OSError) and e.strerror:
        s = e.strerror
    return s or type(e).__name__


def default_port() -> Optional[str]:
    return os.environ.get("HALLHOME_PORT") or None
