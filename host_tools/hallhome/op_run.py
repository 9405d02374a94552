"""Commands that move the tendons and wait until the board reports the end:
`hallhome calibrate`, `rehome`, `home` and `release`."""

from __future__ import annotations

import sys
import time
from typing import Callable, Dict, List, Optional

import click
from rich.live import Live
from rich.markup import escape
from rich.table import Table

from hallhome import runlog
from hallhome.client import BoardError, BoardReset, Client, HallhomeError, Report, ReplyTimeout
from hallhome.op_common import (R, TENDON, TENSION, board_info, cmd, ends_motion, err, fixed3,
                                json_option, operator_command, out, port_options, print_json,
                                session, show_table)
from hallhome.op_console import explain
from hallhome.op_status import TableMismatch, expected, missing_text, table_check, table_options

ABORT_WAIT = 3.0  # seconds to wait for the board's confirmation of an abort
FAULT_GRACE = 1.5  # seconds to wait for the release report after a fault
COLUMNS = ["tendon", "servo", "state", "home (ticks)", "travel mm", "|dB| uT", "target uT", "time s"]


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
            row.update(state="home", home=r.get("home"), straight=r.get("straight"),
                       travel_um=r.get("travel_um"),
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

    @property
    def ok(self) -> bool:
        return self.done is not None and not self.faults

    def cells(self) -> List[List[object]]:
        out_ = []
        for k in sorted(self.rows):
            r = self.rows[k]
            secs = ""
            if r.get("time_ms") is not None:
                secs = f"{int(r['time_ms']) / 1000:.1f}"
            elif r.get("t0") is not None and r["state"] in ("pulling", "engaged"):
                secs = f"{time.monotonic() - float(r['t0']):.1f}"
            state = str(r["state"])
            style = {"home": "green", "pulling": "cyan", "engaged": "cyan"}.get(
                state, "red" if "fault" in state else "")
            trav = r.get("travel_um")
            out_.append([str(k), str(r.get("id", "")), (state, style),
                         str(r.get("home")) if r.get("home") is not None else "",
                         f"{int(trav) / 1000:.3f}" if trav is not None else "",
                         str(r.get("dB", "")), str(r.get("target", "")), secs])
        return out_

    def table(self, title: str) -> Table:
        t = Table(*COLUMNS, title=title)
        for c in self.cells():
            t.add_row(*[f"[{x[1]}]{x[0]}[/]" if isinstance(x, tuple) and x[1]
                        else (x[0] if isinstance(x, tuple) else x) for x in c])
        return t

    def as_json(self) -> dict:
        d = self.done
        return {
            "ok": self.ok,
            "mode": d.get("mode") if d else None,
            "tension_N": int(d.get("tension_mN", 0)) / 1000.0 if d and d.get("tension_mN") is not None else None,
            "time_s": int(d.get("time_ms", 0)) / 1000.0 if d else None,
            "count": d.get("count") if d else None,
            "tendons": [{"tendon": k, "servo_id": r.get("id"), "state": r["state"],
                         "home_ticks": r.get("home"), "straight_ticks": r.get("straight"),
                         "travel_mm": int(r["travel_um"]) / 1000 if r.get("travel_um") is not None else None,
                         "dB_uT": _f(r.get("dB")), "target_uT": _f(r.get("target")),
                         "time_s": int(r["time_ms"]) / 1000 if r.get("time_ms") is not None else None}
                        for k, r in sorted(self.rows.items())],
            "faults": [dict(f.fields) for f in self.faults],
            "missing": [dict(m.fields) for m in self.missing],
            "released": self.released is not None,
        }


def _f(v) -> Optional[float]:
    try:
        return float(v)
    except (TypeError, ValueError):
        return None


def follow(c: Client, view: CalView, title: str, run_timeout: float, quiet: bool,
           what: str = "calibration", again: str = "calibrate",
           log: Callable[[Report], bool] = lambda r: True) -> None:
    """Feeds the run's reports to the view until it ends: a live table on a
    terminal, the reports for which `log` holds as a log otherwise (nothing
    with `quiet`). Ctrl-C aborts on the board and exits 130."""
    con = out()
    live_ok = con.is_terminal and not quiet
    deadline = time.monotonic() + run_timeout
    try:
        with Live(view.table(title), console=con, refresh_per_second=4, transient=False,
                  auto_refresh=live_ok) if live_ok else _Null() as live:
            while not view.finished:
                if time.monotonic() > deadline:
                    c.abort(wait=2.0, until=ends_motion)
                    raise ReplyTimeout(f"the run did not finish within {run_timeout:g} s: "
                                       "aborted, every tendon released")
                r = c.event(0.25)
                if r is not None:
                    if r.kind == R.BOOT:
                        raise BoardReset(c.reset_message(r, f"during the {what}") +
                                         f"; run `hallhome {again}` again", r)
                    view.feed(r)
                    if not con.is_terminal and not quiet and log(r):
                        click.echo(r.raw)
                if live_ok:
                    live.update(view.table(title))
            if live_ok:
                live.update(view.table(title))
    except KeyboardInterrupt:
        got = c.abort(wait=ABORT_WAIT, until=lambda r: r.kind == R.RELEASED)
        for r in got:
            view.feed(r)
        if not quiet:
            show_table(con, title + " (aborted)", COLUMNS, view.cells())
        if view.released is not None:
            err().print("[yellow]aborted: the board stopped and released every tendon[/]")
        elif any(f.get("reason") == "aborted" for f in view.faults):
            err().print("[yellow]aborted: the board stopped the run (no tendon was under way, "
                        "so no release was needed)[/]")
        else:
            err().print(f"[yellow]abort sent; the board did not confirm it within {ABORT_WAIT:g} s[/]")
        sys.exit(130)
    c.motion_ended()


class _Null:
    def __enter__(self):
        return self

    def __exit__(self, *a):
        return False

    def update(self, *_):
        pass


def explain_refusal(c: Client, reports: List[Report]) -> List[str]:
    """The `<missing>` reports of a refused or failed run in words; sensor
    overflows are told apart with a `sensors` read."""
    missing = [m for m in reports if m.kind == R.MISSING]
    sens: List[Report] = []
    if any(m.get("dev") == "sensor" and m.get("why") == 3 for m in missing):
        try:
            sens = c.command(cmd("sensors")).of(R.SENSOR)
        except HallhomeError:
            pass
    return [missing_text(m, sens) for m in missing]


def finish(c: Client, view: CalView, what: str, as_json: bool, info: Dict[str, object]) -> None:
    """Prints the end of a run and exits 1 unless it succeeded."""
    con = out()
    notes = explain_refusal(c, view.missing) if view.missing else []
    if view.done is not None and view.done.get("count") is not None:
        runlog.record(info.get("table_id"), view.done.get("count"), view.done.get("tension_mN"),
                      view.done.get("mode"))
    if as_json:
        d = view.as_json()
        d["notes"] = notes
        print_json(d)
        if not view.ok:
            sys.exit(1)
        return
    for n in notes:
        con.print(f"[red]{escape(n)}[/]")
    if view.ok:
        d = view.done
        con.print(f"[green]done[/]: {d.get('mode')} {what} at {int(d.get('tension_mN', 0)) / 1000:.3f} N "
                  f"in {int(d.get('time_ms', 0)) / 1000:.1f} s (calibration #{d.get('count')})")
        return
    for f in view.faults:
        err().print(f"[red]fault: {f.get('reason')} on {f.get('dev')} {f.get('index')}"
                    + (f" (servo id {f.get('id')})" if f.get("id") is not None else "") + "[/]")
    err().print(f"[red]the {what} failed" +
                ("; the board released every tendon" if view.released is not None else "") + "[/]")
    sys.exit(1)


def start(c: Client, line: str, as_json: bool) -> List[Report]:
    """Sends a run's command; a refusal names the missing devices."""
    try:
        return c.command(line).reports
    except BoardError as e:
        notes = explain_refusal(c, e.reports)
        if e.name in ("TENSION_RANGE", "BAD_TENDON", "SETTING_RANGE"):
            notes.append(explain(e, c))  # the range that applies
        if as_json:
            print_json({"ok": False, "error": {"code": e.code, "name": e.name, "text": e.text},
                        "notes": notes})
        else:
            for n in notes:
                out().print(f"[red]{escape(n)}[/]")
        raise


run_timeout_option = click.option("--run-timeout", type=click.FloatRange(min=1.0), default=600.0,
                                  show_default=True,
                                  help="Longest the run may take before it is aborted (s).")


@click.command("calibrate")
@click.option("--tension", "-N", type=TENSION, default=None,
              help=f"Tension in newtons, {TENSION.min:g}..{TENSION.max:g} (the board's limits; "
                   "default: the board's setting cal_tension).")
@click.option("--tendon", "-k", type=TENDON, default=None,
              help=f"Calibrate only this tendon, {TENDON.min}..{TENDON.max} (0-based; default: "
                   "every tendon).")
@click.option("--force", is_flag=True,
              help="Calibrate even when the board's table is not the one the robot TOML gives.")
@table_options
@run_timeout_option
@json_option
@port_options
@operator_command
def calibrate_cmd(tension, tendon, force, robot, learned, run_timeout, as_json, port, timeout) -> None:
    """Calibrate the tendons with a live progress display per tendon, then
    print the result table (home, travel, field change, time). Refuses when
    the board's table is not the one computed from the robot TOML (--force
    overrides). Ctrl-C aborts on the board and releases every tendon."""
    con = out()
    exp = expected(robot, learned)
    with session(port, timeout) as c:
        info = board_info(c)
        warn = table_check(info, exp)
        if warn:
            if not force:
                raise TableMismatch(warn + "; --force calibrates anyway")
            err().print(f"[yellow]warning: {escape(warn)}[/]")
        n = int(info.get("tendons", 0) or 0)
        if tendon is not None and tendon >= n:
            raise HallhomeError(f"--tendon {tendon}: the board's table has {n} tendons (0..{n - 1})")
        args = []
        if tension is not None or tendon is not None:
            if tension is None:
                s = c.command(cmd("get", "cal_tension")).first(R.SETTING)
                if s is None:
                    raise HallhomeError("the board did not report its cal_tension setting")
                tension = int(s.get("value")) / 1000.0
            args.append(fixed3(tension))
        if tendon is not None:
            args.append(tendon)
        view = CalView(n, tendon)
        what = f"tendon {tendon}" if tendon is not None else f"{n} tendons"
        title = f"calibration of {what}" + (f" at {fixed3(tension)} N" if tension is not None else "")
        reports = start(c, cmd("cal", *args), as_json)
        for r in reports:
            view.feed(r)
            if not con.is_terminal and not as_json:
                click.echo(r.raw)
        follow(c, view, title, run_timeout, quiet=as_json)
        if not as_json:
            if not con.is_terminal:
                click.echo()
            show_table(con, title, COLUMNS, view.cells())
        finish(c, view, "calibration", as_json, info)


@click.command("rehome")
@run_timeout_option
@json_option
@port_options
@operator_command
def rehome_cmd(run_timeout, as_json, port, timeout) -> None:
    """Quick re-home from the stored homes after a power cycle; waits for
    the end and prints the result table like `calibrate`."""
    con = out()
    with session(port, timeout) as c:
        info = board_info(c)
        n = int(info.get("tendons", 0) or 0)
        view = CalView(n, None)
        for r in start(c, cmd("rehome"), as_json):
            view.feed(r)
        follow(c, view, "quick re-home", run_timeout, quiet=as_json, what="quick re-home",
               again="rehome")
        if not as_json:
            show_table(con, "quick re-home", COLUMNS, view.cells())
        finish(c, view, "re-home", as_json, info)


def simple_move(name: str, port, timeout, run_timeout: float) -> Report:
    """Sends `home` or `release` and waits for its `<done>`."""
    with session(port, timeout) as c:
        start(c, cmd(name), False)
        c.motion = c.motion or name  # `release` too: abort it if the host goes away
        done = wait_for_end(c, run_timeout, f"`{name}`")
        c.motion_ended()
    return done


def wait_for_end(c: Client, secs: float, what: str) -> Report:
    from hallhome.op_common import wait_for
    try:
        return wait_for(c, lambda r: r.kind == R.DONE, secs, what)
    except KeyboardInterrupt:
        c.abort(wait=ABORT_WAIT, until=lambda r: r.kind == R.RELEASED)
        err().print("[yellow]aborted: the board stopped and released every tendon[/]")
        sys.exit(130)


@click.command("home")
@run_timeout_option
@port_options
@operator_command
def home_cmd(run_timeout, port, timeout) -> None:
    """Drive every tendon to its stored home and wait until it arrives."""
    d = simple_move("home", port, timeout, run_timeout)
    out().print(f"[green]done[/]: every tendon at its home in {int(d.get('time_ms', 0)) / 1000:.1f} s")


@click.command("release")
@run_timeout_option
@port_options
@operator_command
def release_cmd(run_timeout, port, timeout) -> None:
    """Slacken every tendon and wait until it is done (the board also
    captures the straight-pose baseline for `learn`)."""
    d = simple_move("release", port, timeout, run_timeout)
    out().print(f"[green]done[/]: every tendon slack in {int(d.get('time_ms', 0)) / 1000:.1f} s"
                + ("; baseline captured" if d.get("baseline") == 1 else ""))
