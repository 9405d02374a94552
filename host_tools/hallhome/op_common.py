"""What every operator subcommand shares: the report vocabulary, the board
session, option types taken from the firmware's declarations, error
handling and output (rich tables on a terminal, plain text or JSON
otherwise).

Indices: tendons and sensors are numbered from 0 everywhere in the tools and
on the board (the robot TOML's validation messages count its `[[tendons]]`
and `[[sensors]]` entries from 1, as a text editor would).
"""

from __future__ import annotations

import functools
import json
import signal
import sys
import threading
import time
from contextlib import contextmanager
from typing import Callable, Dict, Iterator, List, Optional, Sequence, Tuple, Union

import click
from rich.console import Console
from rich.markup import escape
from rich.table import Table

from hallhome import protocol
from hallhome.client import (Client, HallhomeError, Report, ReplyTimeout, BoardReset,
                             find_port)

G = 9.80665  # standard gravity, m/s^2: grams <-> newtons


class R:
    """The application's report vocabulary (docs/app.md), in one place."""

    BOOT, READY, VERSION, STATUS, HOME = "boot", "ready", "version", "status", "home"
    SENSOR, SERVO, TABLE, TENDON, HIST = "sensor", "servo", "table", "tendon", "hist"
    PROGRESS, RESULT, TARGET, DONE = "progress", "result", "target", "done"
    FAULT, RELEASED, MISSING, LEARNED = "fault", "released", "missing", "learned"
    SETTING, HELP = "setting", "help"


def cmd(name: str, *args) -> str:
    """A command line; the name must be declared in con_commands.def."""
    if name not in protocol.COMMANDS_BY_NAME:
        raise RuntimeError(f"command {name!r} is not declared in con_commands.def")
    return " ".join([name] + [str(a) for a in args])


def declared(name: str) -> bool:
    """The command is in the firmware's declarations this host reads."""
    return name in protocol.COMMANDS_BY_NAME


def ends_motion(rep: Report) -> bool:
    """A report after which nothing the host started still moves."""
    return rep.kind in (R.DONE, R.RELEASED, R.FAULT)


def newtons(grams: float) -> float:
    return grams / 1000.0 * G


def grams(newton: float) -> float:
    return newton * 1000.0 / G


def fixed3(value: float) -> str:
    """A decimal argument as the firmware takes it (3 places)."""
    return f"{value:.3f}"


def hexaddr(v) -> str:
    """An I2C address as the datasheets write it."""
    try:
        return f"0x{int(v):02x}"
    except (TypeError, ValueError):
        return str(v)


def int_list(text) -> List[Tuple[Optional[int], str]]:
    """`1,2*,3?` -> [(1, ''), (2, '*'), (3, '?')] (lists in table and hist)."""
    out: List[Tuple[Optional[int], str]] = []
    for part in str(text).split(","):
        part = part.strip()
        if not part:
            continue
        mark = ""
        while part and not (part[-1].isdigit()):
            mark = part[-1] + mark
            part = part[:-1]
        try:
            out.append((int(part), mark))
        except ValueError:
            out.append((None, mark))
    return out


def out() -> Console:
    return Console(highlight=False, soft_wrap=True)


def err() -> Console:
    return Console(stderr=True, highlight=False, soft_wrap=True)


# --- option types from the firmware's declarations ----------------------------------

def _declared_range(command: str, arg: str, kind):
    lo, hi = protocol.arg_bounds(command, arg)
    return kind(int(lo), int(hi)) if kind is click.IntRange else kind(lo, hi)


TENSION = _declared_range("cal", "tension_N", click.FloatRange)   # newtons
TENDON = _declared_range("cal", "tendon", click.IntRange)         # 0-based


# --- output ---------------------------------------------------------------------------

Cell = Union[str, Tuple[str, str]]  # text, or (text, rich style)


def show_table(con: Console, title: str, columns: Sequence[str], rows: Sequence[Sequence[Cell]],
               header: bool = True) -> None:
    """A table: boxed and styled on a terminal; otherwise plain aligned text,
    every cell whole (a log or a script reads it)."""
    if con.is_terminal:
        t = Table(*columns, title=title, show_header=header)
        for r in rows:
            t.add_row(*[f"[{c[1]}]{escape(c[0])}[/]" if isinstance(c, tuple) and c[1]
                        else escape(c[0] if isinstance(c, tuple) else c) for c in r])
        con.print(t)
        return
    text = [[c[0] if isinstance(c, tuple) else c for c in r] for r in rows]
    if header:
        text.insert(0, list(columns))
    widths = [max(len(r[i]) for r in text) for i in range(len(columns))]
    click.echo(title)
    for r in text:
        click.echo("  ".join(v.ljust(w) for v, w in zip(r, widths)).rstrip())


def print_json(data) -> None:
    sys.stdout.write(json.dumps(data, indent=1) + "\n")


def json_option(f):
    return click.option("--json", "as_json", is_flag=True,
                        help="Print one JSON document on standard output instead of text.")(f)


# --- common options and the session ---------------------------------------------

def port_options(f):
    f = click.option("--timeout", type=click.FloatRange(min=0.1), default=6.0, show_default=True,
                     help="Seconds to wait for a reply to one command.")(f)
    f = click.option("--port", "-p", envvar="HALLHOME_PORT", metavar="PORT",
                     help="Serial port (or pty path, or pyserial URL); default: the only "
                          "Arduino Mega connected. Env: HALLHOME_PORT.")(f)
    return f


@contextmanager
def session(port: Optional[str], timeout: float) -> Iterator[Client]:
    """An open, synchronised client. On exit (also after Ctrl-C or SIGTERM)
    the client aborts any motion it started and has not seen end."""
    dev = find_port(port)
    old: Dict[int, object] = {}
    if threading.current_thread() is threading.main_thread():
        def on_term(signum, frame):
            raise KeyboardInterrupt
        for sig in (signal.SIGTERM, signal.SIGHUP):  # killed, or the terminal closed
            old[sig] = signal.signal(sig, on_term)

    def restore() -> None:
        for sig, h in old.items():
            signal.signal(sig, h)
    try:
        c = Client(dev, timeout=timeout, ends_motion=ends_motion)
    except BaseException:
        restore()
        raise
    try:
        wait_booted(c)
        yield c
    finally:
        if c.motion is not None:
            err().print(f"[yellow]stopping the {c.motion} this session started: "
                        "abort sent, the board releases every tendon[/]")
        c.close()
        if c.garbled:
            err().print(f"[yellow]note: {c.garbled} line(s) from the board were not protocol and were "
                        f"ignored (last: {escape(str(c.garbled_last))})[/]")
        restore()


BOOT_WAIT = 8.0  # the firmware's device bring-up takes at most 3 s (docs/app.md)


def wait_booted(c: Client) -> None:
    """Returns once the board has finished its boot (bring-up and
    preflight): opening a Mega's port resets it, and a command sent while it
    boots is refused as busy."""
    deadline = time.monotonic() + BOOT_WAIT
    told = False
    while True:
        s = c.command(cmd("status")).first(R.STATUS)
        if s is None or s.get("state") != "boot":
            return
        if time.monotonic() > deadline:
            raise ReplyTimeout(f"the board was still booting after {BOOT_WAIT:g} s")
        if not told:
            err().print("waiting for the board to finish booting ...")
            told = True
        time.sleep(0.2)


def operator_command(f):
    """Turns client failures into one clear message and an exit code."""

    @functools.wraps(f)
    def wrapper(*a, **kw):
        try:
            return f(*a, **kw)
        except HallhomeError as e:
            err().print(f"[red]hallhome: {escape(str(e))}[/]")
            sys.exit(e.exit_code)
        except KeyboardInterrupt:
            err().print("[yellow]interrupted[/]")
            sys.exit(130)
    return wrapper


def ask(text: str, default: str = "") -> str:
    """click.prompt that tells Ctrl-C (KeyboardInterrupt: exit 130) from the
    end of standard input (a clear error), where click says `Aborted!` for
    both."""
    try:
        return click.prompt(text, default=default, show_default=False)
    except click.exceptions.Abort as e:
        if isinstance(e.__context__, KeyboardInterrupt):
            raise KeyboardInterrupt from None
        raise HallhomeError("standard input ended before the dialogue did") from None


def board_info(c: Client) -> Dict[str, object]:
    r = c.command(cmd("version")).first(R.VERSION)
    return dict(r.fields) if r else {}


def wait_saved(c: Client, secs: float) -> None:
    """Waits until the board has written its queued EEPROM records."""
    deadline = time.monotonic() + secs
    while True:
        s = c.command(cmd("status")).first(R.STATUS)
        if s is None or not s.get("saving"):
            return
        if time.monotonic() > deadline:
            raise ReplyTimeout(f"the board was still writing its EEPROM after {secs:g} s")
        time.sleep(0.2)


def wait_for(c: Client, pred: Callable[[Report], bool], secs: float, what: str,
             seen: Optional[Callable[[Report], None]] = None) -> Report:
    """The first asynchronous report that satisfies pred within secs; a
    reset or a fault on the way is an error."""
    deadline = time.monotonic() + secs
    while time.monotonic() < deadline:
        r = c.event(0.25)
        if r is None:
            continue
        if seen is not None:
            seen(r)
        if r.kind == R.BOOT:
            raise BoardReset(c.reset_message(r, f"during {what}"), r)
        if r.kind == R.FAULT:
            raise HallhomeError(f"fault during {what}: {r.get('reason')} on {r.get('dev')} "
                                f"{r.get('index')}")
        if pred(r):
            return r
    raise ReplyTimeout(f"{what} did not finish within {secs:g} s")
