"""One servo's goals and positions from `hh_bench --trace-bus` (docs/chaos.md,
"Tracing a seed").

The trace has a line per byte: `bus T us mcu XX ...` for the firmware's
bytes and `bus T us servo K XX ...` for the bytes servo K (the bench's
servo index, the tendon's) sends. This decodes the two packets a homing
decision shows in:

- Sync Write (0x83): the goal the firmware sent, every 4-byte field of the
  block written (address 108: acceleration, velocity, goal position);
- Fast Sync Read (0x8A) replies: each servo sends its own block, error, ID
  and data (servo 0 first, after the status header), and the block after
  the request's address and length is the servo's present position (132)
  or whatever else was read.

CRCs are not checked: a block the bus noise corrupted shows as a wild
value, as it reached the firmware (which drops it on its CRC). The
firmware's bytes are traced as sent; `bus T us noise mcu XX->YY` lines
name those the noise flipped on the way to the servos (`noise()`)."""

from __future__ import annotations

import re
from dataclasses import dataclass

SYNC_WRITE = 0x83
FAST_SYNC_READ = 0x8A
HEADER = [0xFF, 0xFF, 0xFD, 0x00]
STATUS_HEADER_LEN = 8  # FF FF FD 00, ID, LEN (2), instruction 0x55

LINE = re.compile(r"^bus\s+(\d+) us (mcu|servo (\d+)) ([0-9A-Fa-f]{2})\b")


@dataclass
class Event:
    t_s: float
    kind: str  # "write" (a Sync Write's block) or "read" (a Fast Sync Read reply)
    addr: int
    values: list[int]  # signed 32-bit little-endian fields (reads: one, of the request's length)
    error: int = 0


def _i32(b: list[int]) -> int:
    return int.from_bytes(bytes(b), "little", signed=True)


def decode(lines, servo_index: int, servo_id: int) -> list[Event]:
    """The Sync Write blocks for servo_id and the Fast Sync Read replies of
    servo_index, in time order."""
    out: list[Event] = []
    pkt: list[int] = []
    request = None  # (addr, length) of the last Fast Sync Read
    reply: list[int] = []
    reply_t = 0

    def close_reply():
        nonlocal reply
        if reply and request is not None:
            addr, n = request
            blk = reply[STATUS_HEADER_LEN:] if servo_index == 0 else reply
            if len(blk) >= 2 + n and blk[1] == servo_id:
                out.append(Event(reply_t / 1e6, "read", addr, [_i32(blk[2:2 + n])], blk[0]))
        reply = []

    for line in lines:
        m = LINE.match(line)
        if not m:
            continue
        t_us, who, k, byte = int(m.group(1)), m.group(2), m.group(3), int(m.group(4), 16)
        if who != "mcu":
            if int(k) == servo_index:
                if not reply:
                    reply_t = t_us
                reply.append(byte)
            continue
        close_reply()  # the firmware speaks again: every reply before is complete
        pkt.append(byte)
        if len(pkt) <= len(HEADER):
            if pkt != HEADER[:len(pkt)]:
                pkt = [byte] if byte == HEADER[0] else []
            continue
        if len(pkt) < 7 or len(pkt) < 7 + (pkt[5] | pkt[6] << 8):
            continue
        inst = pkt[7]
        params = pkt[8:-2]
        if inst == FAST_SYNC_READ and len(params) >= 4:
            request = (params[0] | params[1] << 8, params[2] | params[3] << 8)
        elif inst == SYNC_WRITE and len(params) >= 4:
            addr, n = params[0] | params[1] << 8, params[2] | params[3] << 8
            data = params[4:]
            for j in range(0, len(data) - n, n + 1):
                if data[j] == servo_id:
                    block = data[j + 1:j + 1 + n]
                    out.append(Event(t_us / 1e6, "write", addr,
                                     [_i32(block[q:q + 4]) for q in range(0, n - 3, 4)]))
        else:
            request = None
        pkt = []
    close_reply()
    return out


NOISE = re.compile(r"^bus\s+(\d+) us noise mcu ([0-9A-Fa-f]{2})->([0-9A-Fa-f]{2})\b")


def noise(lines) -> list[tuple[float, str]]:
    """The firmware's bytes the bus noise flipped: (time in s, description)."""
    out = []
    for line in lines:
        m = NOISE.match(line)
        if m:
            out.append((int(m.group(1)) / 1e6,
                        f"bus noise: a firmware byte {m.group(2)} reached the servos as {m.group(3)}"))
    return out


def describe(e: Event) -> str:
    if e.kind == "write":
        if e.addr == 108 and len(e.values) == 3:
            return f"goal {e.values[2]} at {e.values[1]} units"
        return f"write @{e.addr}: {e.values}"
    what = {132: "position", 70: "hardware error"}.get(e.addr, f"read @{e.addr}")
    return f"{what} {e.values[0]}" + (f" (error 0x{e.error:02X})" if e.error else "")
