"""`hallhome ports` and `hallhome status`, and the checks they share with
the other commands: which table the board runs, and which sensor is
saturated."""

from __future__ import annotations

import math
import sys
from typing import Dict, List, Optional, Sequence

import click
from rich.markup import escape

from hallhome.client import BoardError, Client, HallhomeError, Report, find_port, list_ports
from hallhome.op_common import (R, board_info, cmd, err, hexaddr, json_option, operator_command,
                                out, port_options, print_json, session, show_table)
from hallhome.robot import SENSOR_SATURATION_T

SATURATION_UT = SENSOR_SATURATION_T * 1e6


class TableMismatch(HallhomeError):
    """The board's table is not the one the host computes from the robot."""

    exit_code = 1


# --- the table the board runs ------------------------------------------------------

def table_options(f):
    f = click.option("--learned", "learned", multiple=True,
                     type=click.Path(exists=True, dir_okay=False),
                     help="Learned targets compiled into the board's firmware (`hallhome tables "
                          "--learned`): expect that table instead; repeatable, in order.")(f)
    f = click.option("--robot", "robot", type=click.Path(exists=True, dir_okay=False), default=None,
                     help="Robot TOML the board's table should come from (default: the "
                          "project's default robot, ROBOT in the Makefile).")(f)
    return f


def expected(robot: Optional[str], learned: Sequence[str]):
    """The table the host expects (tableid.Expected), computed before the
    port is opened so the board waits for nothing."""
    from hallhome.tableid import TableIdError, expected_table
    try:
        return expected_table(robot, learned)
    except TableIdError as e:
        raise HallhomeError(f"cannot compute the expected table: {e}") from None


def table_check(info: Dict[str, object], exp) -> Optional[str]:
    """None when the board's table (from `version`) is the expected one,
    else the warning text."""
    from hallhome.tableid import mismatch
    return mismatch(exp, info.get("table"), info.get("table_id"))


# --- sensors ---------------------------------------------------------------------------

def sensor_state(r: Report) -> str:
    """`ok`, `saturated` or `not running` for one `<sensor>` report. A later
    firmware says `state=saturated`; the current one reports ok=1 with an
    axis at the AK09916's range and a growing `ovf`."""
    if r.get("state") is not None:
        return str(r.get("state"))
    axes = [r.num(k, 0.0) for k in ("bx_uT", "by_uT", "bz_uT")]
    if any(abs(v) >= SATURATION_UT * 0.999 for v in axes):
        return "saturated"
    return "ok" if r.get("ok") == 1 else "not running"


def magnitude(r: Report) -> float:
    return math.sqrt(sum(r.num(k, 0.0) ** 2 for k in ("bx_uT", "by_uT", "bz_uT")))


def missing_text(m: Report, sensors: Sequence[Report] = ()) -> str:
    """One `<missing>` report in words (why=3 of a sensor told apart with
    its `<sensor>` report when one is at hand)."""
    dev, idx = m.get("dev"), m.get("index")
    what = f"{dev} {idx}" + (f" (servo id {m.get('id')})" if m.get("id") is not None else "")
    if m.get("state") == "saturated":
        return f"sensor {idx} saturated (overflows: {m.get('ovf', '?')})"
    if dev == "sensor" and m.get("why") == 3:
        s = next((r for r in sensors if r.get("index") == idx), None)
        if s is not None and sensor_state(s) == "saturated":
            return f"sensor {idx} saturated (overflows: {s.get('ovf')}): move the magnet or iron away"
        if m.get("ovf") is not None:
            return f"sensor {idx} saturated (overflows: {m.get('ovf')})"
        return f"sensor {idx}: read errors or overflows"
    why = {1: "absent", 2: "no answer", 4: "servo hardware error"}.get(m.get("why"))
    if m.get("err") is not None:
        where = (f" on mux channel {m.get('ch')} at {hexaddr(m.get('addr'))}"
                 if m.get("addr") is not None else "")
        why = f"did not come up{where} (driver error {m.get('err')})"
    if m.get("hw_error"):
        why = f"hardware error 0x{int(m.get('hw_error')):02x}"
    return f"missing {what}" + (f": {why}" if why else "")


# --- ports ------------------------------------------------------------------------

@click.command("ports")
@json_option
def ports_cmd(as_json) -> None:
    """List serial ports; mark Arduino Megas (USB 2341:0042, 2341:0010, ...)
    and USB serial bridges that Mega clones use."""
    ports = list_ports()
    try:
        default, why = find_port(None), None
    except HallhomeError as e:
        default, why = None, str(e)
    if as_json:
        print_json({"ports": [{"device": p.device, "usb_id": p.usb_id if p.vid is not None else None,
                               "description": p.description, "board": p.board, "mega": p.mega,
                               "maybe_mega": p.maybe_mega, "serial_number": p.serial_number}
                              for p in ports],
                    "default": default, "default_error": why})
        return
    con = out()
    if not ports:
        con.print("no serial ports found")
    else:
        rows = [[p.device, p.usb_id, p.description,
                 (p.board or "", "green" if p.mega else ("yellow" if p.maybe_mega else ""))]
                for p in ports]
        show_table(con, "serial ports", ["port", "USB ID", "description", "board"], rows)
    con.print(f"default port: {default}" if default else escape(str(why)))


# --- status -----------------------------------------------------------------------

STATUS_KEYS = (("state", "state"), ("count", "calibrations"), ("tension_mN", "last tension mN"),
               ("fault", "last fault"), ("rehome", "quick re-home offered"),
               ("learned", "learned tendons (mask)"), ("baseline", "baseline captured"),
               ("loop_max_us", "longest loop us"), ("stack_free", "least free stack B"))


def read_status(c: Client) -> dict:
    ver = board_info(c)
    st = c.command(cmd("status"))
    s = st.first(R.STATUS)
    sens: List[Report] = []
    servos: List[Report] = []
    notes = []
    try:
        sens = c.command(cmd("sensors")).of(R.SENSOR)
        servos = c.command(cmd("servos", "pos")).of(R.SERVO)
    except BoardError as e:
        notes.append(f"{e.name}: {e.text}")
    return {"version": ver, "status": s, "homes": {h.get("tendon"): h for h in st.of(R.HOME)},
            "sensors": sens, "servos": servos, "notes": notes}


def status_problems(sens: Sequence[Report], servos: Sequence[Report]) -> List[str]:
    bad = []
    for r in sens:
        st = sensor_state(r)
        if st == "saturated":
            bad.append(f"sensor {r.get('index')} saturated (overflows: {r.get('ovf')})")
        elif st != "ok":
            bad.append(f"sensor {r.get('index')} {st}")
    for r in servos:
        if r.get("found") != 1:
            bad.append(f"servo {r.get('id')} (tendon {r.get('tendon')}) not found")
        elif r.get("hw_error"):
            bad.append(f"servo {r.get('id')} (tendon {r.get('tendon')}) hardware error "
                       f"0x{int(r.get('hw_error')):02x}")
    return bad


@click.command("status")
@table_options
@json_option
@port_options
@operator_command
def status_cmd(robot, learned, as_json, port, timeout) -> None:
    """Board, sensors and servos at a glance. Exits 1 when a sensor is
    saturated or not running, or a servo is missing or reports a hardware
    error; warns when the board's table is not the one the robot TOML
    gives (table_id compared)."""
    exp = expected(robot, learned)
    with session(port, timeout) as c:
        d = read_status(c)
    ver, s, sens, servos = d["version"], d["status"], d["sensors"], d["servos"]
    table_warn = table_check(ver, exp)
    bad = status_problems(sens, servos)
    if as_json:
        print_json({
            "board": ver, "status": dict(s.fields) if s else None,
            "sensors": [dict(r.fields, addr=hexaddr(r.get("addr")), state=sensor_state(r),
                             magnitude_uT=round(magnitude(r), 2)) for r in sens],
            "servos": [dict(r.fields, home=(d["homes"][r.get("tendon")].get("home")
                                             if r.get("tendon") in d["homes"] else None))
                       for r in servos],
            "notes": d["notes"], "problems": bad, "table_warning": table_warn})
        sys.exit(1 if bad else 0)
    con = out()
    rows = [[k, str(ver[k])] for k in ("name", "version", "board", "table", "table_id", "tendons",
                                        "sensors") if k in ver]
    if s:
        rows += [[label, str(s.get(k))] for k, label in STATUS_KEYS if k in s.fields]
    show_table(con, "board", ["", ""], rows, header=False)
    if sens:
        rows = []
        for r in sens:
            st = sensor_state(r)
            rows.append([str(r.get("index")), str(r.get("ch")), hexaddr(r.get("addr")),
                         (st, "green" if st == "ok" else "red"), str(r.get("rate_Hz")),
                         f"{magnitude(r):.2f}", str(r.get("bx_uT")), str(r.get("by_uT")),
                         str(r.get("bz_uT")), str(r.get("ovf", "")), str(r.get("err"))])
        show_table(con, "sensors", ["sensor", "ch", "addr", "state", "rate Hz", "|B| uT", "Bx", "By",
                                    "Bz", "overflows", "errors"], rows)
    if servos:
        rows = []
        for r in servos:
            h = d["homes"].get(r.get("tendon"))
            hw = int(r.get("hw_error", 0) or 0)
            rows.append([str(r.get("tendon")), str(r.get("id")),
                         ("yes", "green") if r.get("found") == 1 else ("NO", "red"),
                         str(r.get("cal_pos", r.get("pos"))), str(h.get("home")) if h else "-",
                         (f"0x{hw:02x}", "red") if hw else "0"])
        show_table(con, "servos", ["tendon", "id", "found", "position", "home", "hw error"], rows)
    for n in d["notes"]:
        con.print(f"[yellow]{escape(n)}[/]")
    if table_warn:
        err().print(f"[yellow]warning: {escape(table_warn)}[/]")
    if bad:
        err().print("[red]attention: " + escape("; ".join(bad)) + "[/]")
        sys.exit(1)
