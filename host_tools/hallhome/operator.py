"""Operator subcommands: the bench tools a lab member runs with a laptop on
the Arduino Mega (docs/operator.md).

`register(main)` adds them to the `hallhome` command group. Every command
talks to the board through hallhome.client; the report kinds and keys of the
application (docs/app.md) are named once, in `R` below.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
import signal
import sys
import threading
import time
from contextlib import contextmanager
from pathlib import Path
from typing import Dict, Iterator, List, Optional, Tuple

import click
from rich.console import Console
from rich.live import Live
from rich.markup import escape
from rich.table import Table

from hallhome import protocol
from hallhome.client import (BoardError, BoardReset, Client, HallhomeError,
                             LocalError, Report, ReplyTimeout, find_port, list_ports)

G = 9.80665  # standard gravity, m/s^2: grams <-> newtons


class R:
    """The application's report vocabulary (docs/app.md), in one place."""

    BOOT, READY, VERSION, STATUS, HOME = "boot", "ready", "version", "status", "home"
    SENSOR, SERVO, TABLE, TENDON, HIST = "sensor", "servo", "table", "tendon", "hist"
    PROGRESS, RESULT, TARGET, DONE = "progress", "result", "target", "done"
    FAULT, RELEASED, MISSING, LEARNED = "fault", "released", "missing", "learned"


def cmd(name: str, *args) -> str:
    """A command line; the name must be declared in con_commands.def."""
    if name not in protocol.COMMANDS_BY_NAME:
        raise RuntimeError(f"command {name!r} is not declared in con_commands.def")
    return " ".join([name] + [str(a) for a in args])


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


# --- common options and the session ---------------------------------------------

def port_options(f):
    f = click.option("--timeout", type=float, default=6.0, show_default=True,
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
                        f"ignored (last: {escape(repr(c.garbled_last))})[/]")
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
    import functools

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


def board_info(c: Client) -> Dict[str, object]:
    r = c.command(cmd("version")).first(R.VERSION)
    return dict(r.fields) if r else {}


# --- ports ------------------------------------------------------------------------

@click.command("ports")
def ports_cmd() -> None:
    """List serial ports; mark Arduino Megas (USB 2341:0042, 2341:0010, ...)
    and USB serial bridges that Mega clones use."""
    ports = list_ports()
    con = out()
    if not ports:
        con.print("no serial ports found")
        return
    t = Table("port", "USB ID", "description", "board")
    for p in ports:
        mark = f"[green]{p.board}[/]" if p.mega else (f"[yellow]{p.board}[/]" if p.maybe_mega else "")
        t.add_row(p.device, p.usb_id, p.description, mark)
    con.print(t)
    try:
        con.print(f"default port: {find_port(None)}")
    except HallhomeError as e:
        con.print(escape(str(e)))


# --- status -----------------------------------------------------------------------

@click.command("status")
@port_options
@operator_command
def status_cmd(port, timeout) -> None:
    """Board, sensors and servos at a glance. Exits 1 when a sensor or servo
    is missing or reports a hardware error."""
    con = out()
    with session(port, timeout) as c:
        ver = board_info(c)
        st = c.command(cmd("status"))
        s = st.first(R.STATUS)
        homes = {h.get("tendon"): h for h in st.of(R.HOME)}
        sens: List[Report] = []
        servos: List[Report] = []
        notes = []
        try:
            sens = c.command(cmd("sensors")).of(R.SENSOR)
            servos = c.command(cmd("servos", "pos")).of(R.SERVO)
        except BoardError as e:
            notes.append(f"{e.name}: {e.text}")
    b = Table(title="board", show_header=False)
    for k in ("name", "version", "board", "table", "table_id", "tendons", "sensors"):
        if k in ver:
            b.add_row(k, str(ver[k]))
    if s:
        for k, label in (("state", "state"), ("count", "calibrations"), ("tension_mN", "last tension mN"),
                         ("fault", "last fault"), ("rehome", "quick re-home offered"),
                         ("learned", "learned tendons (mask)"), ("baseline", "baseline captured"),
                         ("loop_max_us", "longest loop us")):
            if k in s.fields:
                b.add_row(label, str(s.get(k)))
    con.print(b)
    if sens:
        t = Table("sensor", "ch", "addr", "ok", "rate Hz", "|B| uT", "Bx", "By", "Bz", "errors", title="sensors")
        for r in sens:
            bx, by, bz = (r.num(k, 0.0) for k in ("bx_uT", "by_uT", "bz_uT"))
            ok = "[green]yes[/]" if r.get("ok") == 1 else "[red]NO[/]"
            t.add_row(str(r.get("index")), str(r.get("ch")), f"0x{int(r.get('addr', 0)):02x}", ok,
                      str(r.get("rate_Hz")), f"{math.sqrt(bx * bx + by * by + bz * bz):.2f}",
                      str(r.get("bx_uT")), str(r.get("by_uT")), str(r.get("bz_uT")), str(r.get("err")))
        con.print(t)
    if servos:
        t = Table("tendon", "id", "found", "position", "home", "hw error", title="servos")
        for r in servos:
            h = homes.get(r.get("tendon"))
            found = "[green]yes[/]" if r.get("found") == 1 else "[red]NO[/]"
            hw = int(r.get("hw_error", 0) or 0)
            t.add_row(str(r.get("tendon")), str(r.get("id")), found, str(r.get("cal_pos", r.get("pos"))),
                      str(h.get("home")) if h else "-", f"[red]0x{hw:02x}[/]" if hw else "0")
        con.print(t)
    for n in notes:
        con.print(f"[yellow]{escape(n)}[/]")
    bad = ([f"sensor {r.get('index')} not running" for r in sens if r.get("ok") != 1] +
           [f"servo {r.get('id')} (tendon {r.get('tendon')}) not found" for r in servos if r.get("found") != 1] +
           [f"servo {r.get('id')} (tendon {r.get('tendon')}) hardware error 0x{int(r.get('hw_error')):02x}"
            for r in servos if r.get("found") == 1 and r.get("hw_error")])
    if bad:
        err().print("[red]attention: " + escape("; ".join(bad)) + "[/]")
        sys.exit(1)


# --- calibrate ----------------------------------------------------------------------

def missing_text(m: Report) -> str:
    return (f"[red]missing {m.get('dev')} {m.get('index')}"
            + (f" (servo id {m.get('id')})" if m.get("id") is not None else "") + "[/]")


ABORT_WAIT = 3.0  # seconds to wait for the board's confirmation of an abort
FAULT_GRACE = 1.5  # seconds to wait for the release report after a fault


class CalView:
    """Per-tendon progress of a calibration run, built from its reports."""

    def __init__(self, n_tendons: int, only: Optional[int]):
        self.rows: Dict[int, Dict[str, object]] = {}
        for t in range(n_tendons):
            if only is None or t == only:
                self.rows[t] = {"state": "waiting"}
        self.phase = "starting"
        self.start = time.monotonic()
        self.done: Optional[Report] = None
        self.faults: List[Report] = []
        self.released: Optional[Report] = None
        self.missing: List[Report] = []

    def row(self, t) -> Dict[str, object]:
        return self.rows.setdefault(int(t), {"state": "waiting"})

    def feed(self, r: Report) -> None:
        if r.kind == R.PROGRESS:
            state = r.get("state")
            t = r.get("tendon")
            if t is not None:
                row = self.row(t)
                row["id"] = r.get("id", row.get("id"))
                if state == "tendon":
                    row["state"], row["t0"] = "pulling", r.at
                elif state == "engaged":
                    row["state"], row["engaged"] = "engaged", r.get("pos")
            else:
                self.phase = str(state)
        elif r.kind == R.TARGET:
            self.row(r.get("tendon"))["target"] = r.get("target_uT")
        elif r.kind == R.RESULT:
            row = self.row(r.get("tendon"))
            row.update(state="home", home=r.get("home"), travel_um=r.get("travel_um"),
                       dB=r.get("dB_uT"), target=r.get("target_uT"), time_ms=r.get("time_ms"),
                       id=r.get("id"))
        elif r.kind == R.FAULT:
            self.faults.append(r)
            if r.get("dev") in ("servo", "tendon") and r.get("index") is not None:
                self.row(r.get("index"))["state"] = "fault: " + str(r.get("reason"))
        elif r.kind == R.MISSING:
            self.missing.append(r)
        elif r.kind == R.RELEASED:
            self.released = r
        elif r.kind == R.DONE:
            self.done = r

    @property
    def finished(self) -> bool:
        """Done, released, or a fault (which ends the run) a moment ago: the
        board follows a fault with its release, given a little time."""
        if self.done is not None or self.released is not None:
            return True
        return bool(self.faults) and time.monotonic() - self.faults[0].at > FAULT_GRACE

    def table(self, title: str) -> Table:
        t = Table("tendon", "servo", "state", "home (ticks)", "travel mm", "|dB| uT", "target uT", "time s",
                  title=title)
        for k in sorted(self.rows):
            r = self.rows[k]
            secs = ""
            if r.get("time_ms") is not None:
                secs = f"{int(r['time_ms']) / 1000:.1f}"
            elif r.get("t0") is not None and r["state"] in ("pulling", "engaged"):
                secs = f"{time.monotonic() - float(r['t0']):.1f}"
            state = str(r["state"])
            style = {"home": "green", "pulling": "cyan", "engaged": "cyan"}.get(state, "red" if "fault" in state else "")
            trav = r.get("travel_um")
            t.add_row(str(k), str(r.get("id", "")), f"[{style}]{state}[/]" if style else state,
                      str(r.get("home", r.get("engaged", "")) if r.get("home") is not None else ""),
                      f"{int(trav) / 1000:.3f}" if trav is not None else "",
                      str(r.get("dB", "")), str(r.get("target", "")), secs)
        return t


@click.command("calibrate")
@click.option("--tension", "-N", type=click.FloatRange(0.01, 10.0), default=None,
              help="Tension in newtons (default: the board's setting cal_tension).")
@click.option("--tendon", "-k", type=click.IntRange(0, 11), default=None,
              help="Calibrate only this tendon (default: every tendon).")
@click.option("--run-timeout", type=float, default=600.0, show_default=True,
              help="Longest a whole run may take before it is aborted.")
@port_options
@operator_command
def calibrate_cmd(tension, tendon, run_timeout, port, timeout) -> None:
    """Calibrate the tendons with a live progress display per tendon, then
    print the result table (home, travel, field change, time). Ctrl-C
    aborts on the board and releases every tendon."""
    con = out()
    with session(port, timeout) as c:
        info = board_info(c)
        n = int(info.get("tendons", 0) or 0)
        args = []
        if tension is not None or tendon is not None:
            if tension is None:
                s = c.command(cmd("get", "cal_tension")).first("setting")
                tension = int(s.get("value")) / 1000.0 if s else None
                if tension is None:
                    raise HallhomeError("the board did not report its cal_tension setting")
            args.append(fixed3(tension))
        if tendon is not None:
            args.append(tendon)
        view = CalView(n, tendon)
        what = f"tendon {tendon}" if tendon is not None else f"{n} tendons"
        title = f"calibration of {what}" + (f" at {fixed3(tension)} N" if tension is not None else "")
        try:
            reply = c.command(cmd("cal", *args))
        except BoardError as e:
            # refused before any motion: the reports name what is missing
            for m in e.reports:
                if m.kind == R.MISSING:
                    con.print(missing_text(m))
            raise
        for r in reply.reports:
            view.feed(r)
        deadline = time.monotonic() + run_timeout
        if not con.is_terminal:  # a log: the reports as they come, the table at the end
            for r in reply.reports:
                click.echo(r.raw)
        try:
            with Live(view.table(title), console=con, refresh_per_second=4, transient=False,
                      auto_refresh=con.is_terminal) as live:
                while not view.finished:
                    if time.monotonic() > deadline:
                        c.abort(wait=2.0, until=ends_motion)
                        raise ReplyTimeout(f"the calibration did not finish within {run_timeout:g} s: "
                                           "aborted, every tendon released")
                    r = c.event(0.25)
                    if r is not None:
                        if r.kind == R.BOOT:
                            raise BoardReset(c.reset_message(r, "during the calibration") +
                                             "; run `hallhome calibrate` again", r)
                        view.feed(r)
                        if not con.is_terminal:
                            click.echo(r.raw)
                    if con.is_terminal:
                        live.update(view.table(title))
                live.update(view.table(title))
            if not con.is_terminal:
                click.echo()
        except KeyboardInterrupt:
            got = c.abort(wait=ABORT_WAIT, until=lambda r: r.kind == R.RELEASED)
            for r in got:
                view.feed(r)
            con.print(view.table(title + " (aborted)"))
            if view.released is not None:
                err().print("[yellow]aborted: the board stopped and released every tendon[/]")
            elif any(f.get("reason") == "aborted" for f in view.faults):
                err().print("[yellow]aborted: the board stopped the calibration (no tendon was "
                            "under way, so no release was needed)[/]")
            else:
                err().print(f"[yellow]abort sent; the board did not confirm it within {ABORT_WAIT:g} s[/]")
            sys.exit(130)
        c.motion_ended()
    for m in view.missing:
        con.print(missing_text(m))
    if view.done is not None and not view.faults:
        d = view.done
        con.print(f"[green]done[/]: {d.get('mode')} calibration at {int(d.get('tension_mN', 0)) / 1000:.3f} N "
                  f"in {int(d.get('time_ms', 0)) / 1000:.1f} s (calibration #{d.get('count')})")
        return
    for f in view.faults:
        err().print(f"[red]fault: {f.get('reason')} on {f.get('dev')} {f.get('index')}"
                    + (f" (servo id {f.get('id')})" if f.get("id") is not None else "") + "[/]")
    err().print("[red]the calibration failed" +
                ("; the board released every tendon" if view.released is not None else "") + "[/]")
    sys.exit(1)


# --- learn (model-free workflow) ----------------------------------------------------

def read_table(c: Client) -> Tuple[Report, List[Report]]:
    rep = c.command(cmd("table"))
    head = rep.first(R.TABLE)
    if head is None:
        raise HallhomeError("the board sent no table report")
    return head, rep.of(R.TENDON)


def snap_to_grid(newton: float, grid_mN: List[int], tol_pct: float) -> Tuple[int, float]:
    """(grid tension in mN, relative deviation %) of the nearest grid point;
    raises ValueError when it is further than tol_pct."""
    mN = newton * 1000.0
    best = min(grid_mN, key=lambda g: abs(g - mN))
    dev = (mN - best) / best * 100.0
    if abs(dev) > tol_pct:
        raise ValueError(f"{grams(newton):.1f} g is {newton:.3f} N, {dev:+.1f} % from the nearest grid "
                         f"tension {best / 1000:.3f} N ({grams(best / 1000):.1f} g); learned targets sit "
                         f"on the table's grid (tolerance {tol_pct:g} %)")
    return best, dev


def default_points(grid: List[int], default_mN) -> List[int]:
    """The grid tension nearest the table's default and its neighbours: the
    firmware interpolates over the grid, so learned points around the
    tension in use matter (docs/app.md)."""
    d = int(default_mN) if default_mN is not None else grid[len(grid) // 2]
    i = min(range(len(grid)), key=lambda k: abs(grid[k] - d))
    return grid[max(0, i - 1):i + 2]


@click.command("learn")
@click.option("--tendon", "-k", "tendons", type=click.IntRange(0, 11), multiple=True,
              help="Tendon to learn (repeatable; default: every tendon).")
@click.option("--mass", "-m", "masses", type=click.FloatRange(min=0.1), multiple=True,
              help="Mass in grams to hang (repeatable; default: the grid tension nearest the "
                   "table's default tension and its two neighbours, as masses).")
@click.option("--tolerance", type=float, default=1.0, show_default=True,
              help="Largest deviation in % between a mass's weight and its grid tension.")
@click.option("--out", "-o", "out_path", type=click.Path(dir_okay=False), default=None,
              help="Export file (default: learned_<robot>.json in the current directory).")
@port_options
@operator_command
def learn_cmd(tendons, masses, tolerance, out_path, port, timeout) -> None:
    """The paper's model-free workflow, guided: hang known masses on each
    tendon in turn; the board records the field change for each, stores the
    learned targets (EEPROM, used instead of the compiled table's) and this
    command exports them as a file the table generator can compile in."""
    con = out()
    with session(port, timeout) as c:
        head, rows = read_table(c)
        grid = [g for g, _ in int_list(head.get("grid_mN")) if g is not None]
        n = int(head.get("tendons", 0))
        robot = str(head.get("name"))
        todo = list(tendons) or list(range(n))
        for t in todo:
            if t >= n:
                raise HallhomeError(f"tendon {t}: the table has {n} tendons (0..{n - 1})")
        if masses:
            plan = []
            for m in masses:
                try:
                    plan.append((m, snap_to_grid(newtons(m), grid, tolerance)[0]))
                except ValueError as e:
                    raise click.BadParameter(str(e), param_hint="--mass") from None
        else:
            plan = [(round(grams(g / 1000.0), 1), g) for g in default_points(grid, head.get("default_mN"))]
        con.print(f"model-free calibration of [bold]{robot}[/] (table {head.get('table_id')}): "
                  f"tendons {', '.join(map(str, todo))}, masses "
                  + ", ".join(f"{m:g} g ({g / 1000:.3f} N)" for m, g in plan))
        click.prompt("Remove every weight and let the robot hang straight and slack; press Enter",
                     default="", show_default=False)
        c.command(cmd("release"))
        done = wait_for(c, lambda r: r.kind == R.DONE, 30.0, "the release and baseline capture")
        if not done.get("baseline"):
            raise HallhomeError("the board could not capture the straight-pose baseline (sensors?)")
        con.print("baseline captured")
        samples = []
        ans = ""
        for t in todo:
            for m_plan, g_mN in plan:
                while True:
                    ans = click.prompt(f"tendon {t}: hang {m_plan:g} g ({g_mN / 1000:.3f} N); mass hung "
                                       "in grams (Enter: as asked, s: skip, q: quit)",
                                       default=f"{m_plan:g}", show_default=False).strip().lower()
                    if ans in ("s", "q"):
                        break
                    try:
                        m = float(ans)
                        g_used, dev = snap_to_grid(newtons(m), [g_mN], tolerance)
                    except ValueError as e:
                        con.print(f"[yellow]{escape(str(e))}[/]")
                        continue
                    wait_saved(c, 20.0)  # the board refuses `learn` while it writes a record
                    try:
                        rep = c.command(cmd("learn", t, fixed3(g_used / 1000.0)), timeout=max(timeout, 10.0))
                    except BoardError as e:
                        con.print(f"[red]{e.name}: {escape(e.text)}[/]")
                        if e.name in ("BUSY", "TIMEOUT", "SENSOR_FAULT"):
                            continue  # ask again: the capture can be repeated
                        raise
                    lr = rep.first(R.LEARNED)
                    if lr is None:
                        raise HallhomeError("the board accepted `learn` but sent no learned report")
                    samples.append({"tendon": t, "mass_g": m, "tension_mN": int(lr.get("tension_mN")),
                                    "deviation_pct": round(dev, 3), "sensor": lr.get("sensor"),
                                    "dB_uT": float(lr.get("dB_uT"))})
                    con.print(f"tendon {t} at {int(lr.get('tension_mN')) / 1000:.3f} N: |dB| = "
                              f"{lr.get('dB_uT')} uT at sensor {lr.get('sensor')}")
                    break
                if ans == "q":
                    break
            if ans == "q":
                break
            con.print(f"tendon {t} done: remove the weight")
        if samples:
            wait_saved(c, 20.0)
        _, rows = read_table(c)
    board_targets = {int(r.get("tendon")): int_list(r.get("target_cuT")) for r in rows}
    # The board stored each capture (EEPROM); its table, learned entries
    # marked *, is what the file records. Check that the last capture of
    # each tendon and tension is there.
    last = {(s["tendon"], s["tension_mN"]): s for s in samples}
    bad = []
    for (t, mN), s in last.items():
        lst = board_targets.get(t, [])
        gi = grid.index(mN)
        if gi >= len(lst) or lst[gi][0] != round(s["dB_uT"] * 100):
            bad.append(f"tendon {t} at {mN / 1000:.3f} N")
    doc = {
        "format": "hallhome-learned", "format_version": 1, "robot": robot,
        "table_id": head.get("table_id"), "grid_mN": grid, "g": G,
        "tendons": [{"tendon": t,
                     "target_cuT": [v if mark == "*" else None for v, mark in board_targets.get(t, [])]}
                    for t in sorted(board_targets)
                    if any(mark == "*" for _, mark in board_targets.get(t, []))],
        "samples": samples,
    }
    path = Path(out_path or f"learned_{robot}.json")
    path.write_text(json.dumps(doc, indent=1) + "\n", encoding="utf-8")
    con.print(f"{len(samples)} target(s) learned and stored on the board; exported to {path}")
    if bad:
        raise HallhomeError("learned target(s) not in the board's table: " + ", ".join(bad))


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


def wait_for(c: Client, pred, secs: float, what: str) -> Report:
    deadline = time.monotonic() + secs
    while time.monotonic() < deadline:
        r = c.event(0.25)
        if r is None:
            continue
        if r.kind == R.BOOT:
            raise BoardReset(c.reset_message(r, f"during {what}"), r)
        if r.kind == R.FAULT:
            raise HallhomeError(f"fault during {what}: {r.get('reason')} on {r.get('dev')} {r.get('index')}")
        if pred(r):
            return r
    raise ReplyTimeout(f"{what} did not finish within {secs:g} s")


# --- history --------------------------------------------------------------------------

def read_history(c: Client) -> List[Dict[str, object]]:
    # The entry of a run that just ended is written to EEPROM after it:
    # read once the board has written it.
    wait_saved(c, 20.0)
    rows = []
    for r in c.command(cmd("history")).of(R.HIST):
        homes = int_list(r.get("homes", ""))
        rows.append({"count": r.get("count"), "age": r.get("age"), "table_id": r.get("table_id"),
                     "tension_mN": r.get("tension_mN"),
                     "homes": [v if mark != "?" else None for v, mark in homes]})
    rows.sort(key=lambda x: int(x["count"]))
    return rows


@click.command("history")
@click.option("--csv", "as_csv", is_flag=True, help="Print the raw history as CSV instead.")
@click.option("--plot", "plot_path", type=click.Path(dir_okay=False), default="hallhome-history.png",
              show_default=True, help="PNG of each tendon's home over the calibrations.")
@click.option("--no-plot", is_flag=True, help="Do not write the PNG.")
@port_options
@operator_command
def history_cmd(as_csv, plot_path, no_plot, port, timeout) -> None:
    """The board's calibration history (oldest first) and a plot of each
    tendon's home over the calibrations: a drift is tendon creep."""
    with session(port, timeout) as c:
        rows = read_history(c)
    n = max((len(r["homes"]) for r in rows), default=0)
    if as_csv:
        w = csv.writer(sys.stdout, lineterminator="\n")
        w.writerow(["count", "table_id", "tension_mN"] + [f"home{t}" for t in range(n)])
        for r in rows:
            w.writerow([r["count"], r["table_id"], r["tension_mN"]] +
                       ["" if v is None else v for v in r["homes"]] + [""] * (n - len(r["homes"])))
        return
    con = out()
    if not rows:
        con.print("no calibrations in the history yet")
        return
    t = Table("calibration", "tension N", *[f"home {k}" for k in range(n)], title="calibration history")
    for r in rows:
        t.add_row(str(r["count"]), f"{int(r['tension_mN']) / 1000:.3f}",
                  *["-" if v is None else str(v) for v in r["homes"]])
    con.print(t)
    first = rows[0]["homes"]
    last = rows[-1]["homes"]
    drift = [(k, last[k] - first[k]) for k in range(min(len(first), len(last)))
             if first[k] is not None and last[k] is not None]
    if len(rows) > 1 and drift:
        con.print("drift since the oldest entry (ticks): " + ", ".join(f"tendon {k}: {d:+d}" for k, d in drift))
    if not no_plot:
        plot_history(rows, n, Path(plot_path))
        con.print(f"plot: {plot_path}")


def plot_history(rows, n, path: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 4.5))
    for k in range(n):
        pts = [(r["count"], r["homes"][k]) for r in rows if k < len(r["homes"]) and r["homes"][k] is not None]
        if pts:
            base = pts[0][1]
            ax.plot([p[0] for p in pts], [p[1] - base for p in pts], marker="o", label=f"tendon {k}")
    from matplotlib.ticker import MaxNLocator
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_xlabel("calibration")
    ax.set_ylabel("home - first home (encoder ticks)")
    ax.set_title("home over time (tendon creep)")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="small")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


# --- monitor -------------------------------------------------------------------------

SPARK = "▁▂▃▄▅▆▇█"


def sparkline(values: List[float], width: int = 40) -> str:
    v = values[-width:]
    if not v:
        return ""
    lo, hi = min(v), max(v)
    span = hi - lo or 1.0
    return "".join(SPARK[min(len(SPARK) - 1, int((x - lo) / span * (len(SPARK) - 1) + 0.5))] for x in v)


def sample_fields(c: Client) -> List[Tuple[int, bool, float, Tuple[float, float, float]]]:
    out_ = []
    for r in c.command(cmd("sensors")).of(R.SENSOR):
        b = tuple(r.num(k, 0.0) for k in ("bx_uT", "by_uT", "bz_uT"))
        out_.append((int(r.get("index")), r.get("ok") == 1, math.sqrt(sum(x * x for x in b)), b))
    return out_


@click.command("monitor")
@click.option("--samples", "-n", type=click.IntRange(min=0), default=0,
              help="Stop after this many samples (default: until Ctrl-C).")
@click.option("--interval", type=click.FloatRange(min=0.05), default=0.2, show_default=True,
              help="Seconds between samples.")
@click.option("--plot", "plot_path", type=click.Path(dir_okay=False), default=None,
              help="Also write a PNG of |B| over time per sensor at the end.")
@port_options
@operator_command
def monitor_cmd(samples, interval, plot_path, port, timeout) -> None:
    """Live field of each sensor: |B| and its change since the start, with a
    terminal chart (one line per sample when the output is not a terminal)."""
    con = out()
    hist: Dict[int, List[float]] = {}
    times: List[float] = []
    t0 = time.monotonic()
    with session(port, timeout) as c:
        live = con.is_terminal

        def render() -> Table:
            t = Table("sensor", "ok", "|B| uT", "change uT", "last samples", title="field (Ctrl-C to stop)")
            for k in sorted(hist):
                v = hist[k]
                t.add_row(str(k), "yes" if ok.get(k) else "[red]NO[/]", f"{v[-1]:.2f}", f"{v[-1] - v[0]:+.2f}",
                          sparkline(v))
            return t

        ok: Dict[int, bool] = {}
        count = 0
        try:
            ctx = Live(render(), console=con, refresh_per_second=8) if live else None
            if ctx:
                ctx.__enter__()
            try:
                while samples == 0 or count < samples:
                    tick = time.monotonic()
                    try:
                        data = sample_fields(c)
                    except BoardReset as e:
                        err().print(f"[yellow]{escape(str(e))}; monitoring goes on[/]")
                        continue
                    except BoardError as e:
                        if e.name != "BUSY":
                            raise
                        time.sleep(interval)  # still booting after a reset
                        continue
                    times.append(tick - t0)
                    for k, okk, mag, _ in data:
                        hist.setdefault(k, []).append(mag)
                        ok[k] = okk
                    count += 1
                    if ctx:
                        ctx.update(render())
                    else:
                        con.print(f"{tick - t0:8.2f} s  " + "  ".join(
                            f"s{k}={mag:.2f}uT" + ("" if okk else "(fault)") for k, okk, mag, _ in data))
                    time.sleep(max(0.0, interval - (time.monotonic() - tick)))
            finally:
                if ctx:
                    ctx.__exit__(None, None, None)
        except KeyboardInterrupt:
            pass
    if plot_path and times:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, ax = plt.subplots(figsize=(8, 4.5))
        for k, v in sorted(hist.items()):
            ax.plot(times[-len(v):], v, label=f"sensor {k}")
        ax.set_xlabel("time (s)")
        ax.set_ylabel("|B| (uT)")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize="small")
        fig.tight_layout()
        fig.savefig(plot_path, dpi=100)
        plt.close(fig)
        con.print(f"plot: {plot_path}")


# --- export ---------------------------------------------------------------------------

def current_homes(c: Client) -> Dict[str, object]:
    ver = board_info(c)
    st = c.command(cmd("status"))
    s = st.first(R.STATUS)
    _, rows = read_table(c)
    ids = {int(r.get("tendon")): r.get("id") for r in rows}
    homes = st.of(R.HOME)
    if not homes:
        raise HallhomeError("the board has no homes: calibrate first (`hallhome calibrate`)")
    return {
        "robot": ver.get("table"), "table_id": ver.get("table_id"),
        "firmware": ver.get("version"),
        "tension_N": int(s.get("tension_mN", 0)) / 1000.0 if s else None,
        "calibration_count": s.get("count") if s else None,
        "tendons": [{"tendon": int(h.get("tendon")), "servo_id": ids.get(int(h.get("tendon"))),
                     "home_ticks": h.get("home"),
                     "home_now_ticks": h.get("now") if h.get("usable") == 1 else None,
                     "rest_ticks": h.get("rest"), "usable": h.get("usable") == 1}
                    for h in homes],
    }


@click.command("export")
@click.option("--format", "fmt", type=click.Choice(["json", "csv"]), default="json", show_default=True)
@click.option("--output", "-o", type=click.Path(dir_okay=False), default=None,
              help="File to write (default: standard output).")
@port_options
@operator_command
def export_cmd(fmt, output, port, timeout) -> None:
    """The current homes, for teleoperation software. `home_now_ticks` is
    the home in the servo's present multi-turn frame (what to command);
    `home_ticks` is in the frame of the calibration."""
    with session(port, timeout) as c:
        data = current_homes(c)
    if fmt == "json":
        text = json.dumps(data, indent=1) + "\n"
    else:
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        cols = ["tendon", "servo_id", "home_ticks", "home_now_ticks", "rest_ticks", "usable"]
        w.writerow(["robot", "table_id", "tension_N", "calibration_count"] + cols)
        for t in data["tendons"]:
            w.writerow([data["robot"], data["table_id"], data["tension_N"], data["calibration_count"]] +
                       ["" if t[k] is None else t[k] for k in cols])
        text = buf.getvalue()
    if output:
        Path(output).write_text(text, encoding="utf-8")
    else:
        sys.stdout.write(text)


# --- console -------------------------------------------------------------------------

HISTORY_FILE = Path(os.environ.get("HALLHOME_HISTORY", Path.home() / ".hallhome_history"))


@click.command("console")
@port_options
@operator_command
def console_cmd(port, timeout) -> None:
    """Interactive console: type commands (`help` lists them), with line
    editing and history; `!` alone sends the realtime abort; Ctrl-D or
    `exit` leaves. Lines are checked against the firmware's declarations
    before they are sent."""
    tty = sys.stdin.isatty()
    readline = None
    con = out()
    lock = threading.Lock()
    stop = threading.Event()
    lost: List[HallhomeError] = []
    if tty:
        try:
            import readline
            try:
                readline.read_history_file(HISTORY_FILE)
            except OSError:
                pass
        except ImportError:  # no GNU readline on this platform: plain input()
            pass
    with session(port, timeout) as c:
        b = c.boot
        con.print(f"connected to {c.port}" + (f" ({b.raw})" if b else "") + "; `help` lists the commands")

        def show(r: Report) -> None:
            if r.kind == R.BOOT:
                con.print(f"[yellow]{escape(r.raw)}  <- the board reset; the console re-synchronises[/]")
            else:
                click.echo(r.raw)

        prompt = "hallhome> " if tty else ""
        at_prompt = threading.Event()

        def show_async(r: Report) -> None:
            """A report between commands: on a terminal, above the prompt
            and the half-typed line, which are drawn again."""
            if not (tty and at_prompt.is_set()):
                show(r)
                return
            buf = readline.get_line_buffer() if readline is not None else ""
            sys.stdout.write("\r\x1b[K")
            sys.stdout.flush()
            show(r)
            sys.stdout.write(prompt + buf)
            sys.stdout.flush()

        def reader() -> None:
            while not stop.is_set():
                with lock:
                    try:
                        r = c.event(0.05)
                    except HallhomeError as e:
                        lost.append(e)
                        stop.set()
                        import _thread
                        _thread.interrupt_main()
                        return
                if r is not None:
                    show_async(r)
                else:
                    time.sleep(0.02)

        th = threading.Thread(target=reader, daemon=True)
        th.start()
        try:
            while True:
                at_prompt.set()
                try:
                    line = input(prompt)
                except EOFError:
                    break
                finally:
                    at_prompt.clear()
                if not tty:
                    click.echo(f"> {line}")
                line = line.strip()
                if line in ("exit", "quit"):
                    break
                if line == "!":
                    with lock:
                        c.abort()
                    con.print("[yellow]abort sent[/]")
                    continue
                try:
                    with lock:
                        rep = c.command(line, timeout=timeout)
                    for r in rep.reports:
                        show(r)
                    click.echo("ok")
                except LocalError as e:
                    con.print(f"[red]{escape(str(e))}[/]")
                except BoardError as e:
                    for r in e.reports:
                        show(r)
                    con.print(f"[red]error:{e.code} {escape(e.text)}[/] ({e.name})")
                except (ReplyTimeout, BoardReset) as e:
                    con.print(f"[yellow]{escape(str(e))}[/]")
            if not tty:
                time.sleep(0.3)  # trailing reports of the last command
        except KeyboardInterrupt:
            if not lost:
                raise
        finally:
            stop.set()
            th.join(timeout=1.0)
            if tty and readline is not None:
                try:
                    readline.write_history_file(HISTORY_FILE)
                except OSError:
                    pass
        if lost:
            raise lost[0]


def register(main: click.Group) -> None:
    """Adds the operator subcommands to the `hallhome` group."""
    for c in (ports_cmd, console_cmd, status_cmd, calibrate_cmd, learn_cmd, history_cmd, monitor_cmd,
              export_cmd):
        main.add_command(c)
