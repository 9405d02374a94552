"""`hallhome history` (the board's calibration history, tendon creep) and
`hallhome export` (the homes for teleoperation software)."""

from __future__ import annotations

import csv
import datetime
import io
import json
import sys
from pathlib import Path
from typing import Dict, List, Optional, Sequence

import click

from hallhome import runlog
from hallhome.client import Client, HallhomeError
from hallhome.op_common import (R, board_info, cmd, int_list, json_option, operator_command, out,
                                port_options, print_json, session, show_table, wait_saved)
from hallhome.op_learn import read_table
from hallhome.paths import LIB_DIR
from hallhome.protocol import c_define

# The XL430 forgets its turn count at power-up (docs/store.md): a home
# re-found after a power cycle can sit whole turns away from earlier ones.
TICKS_PER_TURN = c_define(LIB_DIR / "dxl" / "dxl_xl430_reg.h", "DXL_XL430_TICKS_PER_REV")


def read_history(c: Client) -> List[Dict[str, object]]:
    # The entry of a run that just ended is written to EEPROM after it:
    # read once the board has written it.
    wait_saved(c, 20.0)
    log = runlog.load()
    rows = []
    for r in c.command(cmd("history")).of(R.HIST):
        homes = int_list(r.get("homes", ""))
        rows.append({"count": r.get("count"), "age": r.get("age"), "table_id": r.get("table_id"),
                     "tension_mN": r.get("tension_mN"),
                     "time": runlog.when(log, r.get("table_id"), r.get("count")),
                     "homes": [v if mark != "?" else None for v, mark in homes]})
    rows.sort(key=lambda x: int(x["count"]))
    return rows


def unwrap(values: Sequence[Optional[int]], turn: int = TICKS_PER_TURN) -> List[Optional[int]]:
    """A home series with whole-turn jumps removed: each home is moved by
    whole turns to lie within half a turn of the previous one (creep is a
    few ticks per run, a lost turn count a multiple of `turn`)."""
    out_: List[Optional[int]] = []
    prev: Optional[int] = None
    for v in values:
        if v is None:
            out_.append(None)
            continue
        if prev is not None:
            v -= round((v - prev) / turn) * turn
        out_.append(v)
        prev = v
    return out_


def creep(rows: List[Dict[str, object]], n: int) -> Dict[int, Dict[str, object]]:
    """Per tension (mN): the runs at it (oldest first) and, per tendon, the
    unwrapped homes and their drift since the first run at that tension."""
    groups: Dict[int, Dict[str, object]] = {}
    for tension in sorted({int(r["tension_mN"]) for r in rows}):
        runs = [r for r in rows if int(r["tension_mN"]) == tension]
        series = {}
        for k in range(n):
            raw = [r["homes"][k] if k < len(r["homes"]) else None for r in runs]
            uw = unwrap(raw)
            known = [v for v in uw if v is not None]
            series[k] = {"homes": uw, "drift": known[-1] - known[0] if len(known) > 1 else None}
        groups[tension] = {"counts": [r["count"] for r in runs], "tendons": series}
    return groups


def when_text(t: Optional[float]) -> str:
    if t is None:
        return "-"
    return datetime.datetime.fromtimestamp(t).strftime("%Y-%m-%d %H:%M")


@click.command("history")
@click.option("--csv", "as_csv", is_flag=True, help="Print the raw history as CSV instead.")
@json_option
@click.option("--plot", "plot_path", type=click.Path(dir_okay=False), default="hallhome-history.png",
              show_default=True, help="PNG of each tendon's home over the calibrations.")
@click.option("--no-plot", is_flag=True, help="Do not write the PNG.")
@port_options
@operator_command
def history_cmd(as_csv, as_json, plot_path, no_plot, port, timeout) -> None:
    """The board's calibration history (oldest first) and each tendon's
    drift per calibration tension (tendon creep; whole-turn jumps after a
    power cycle are unwrapped), with a plot. Runs are dated where this
    computer saw them end (~/.hallhome_runs.jsonl)."""
    with session(port, timeout) as c:
        rows = read_history(c)
    n = max((len(r["homes"]) for r in rows), default=0)
    groups = creep(rows, n)
    if as_json:
        print_json({"runs": [dict(r, time=(datetime.datetime.fromtimestamp(r["time"]).isoformat()
                                           if r["time"] is not None else None)) for r in rows],
                    "creep": [{"tension_mN": t, "counts": g["counts"],
                               "tendons": [{"tendon": k, "homes_unwrapped": s["homes"],
                                            "drift_ticks": s["drift"]}
                                           for k, s in g["tendons"].items()]}
                              for t, g in groups.items()]})
        return
    if as_csv:
        w = csv.writer(sys.stdout, lineterminator="\n")
        w.writerow(["count", "table_id", "tension_mN", "time"] + [f"home{t}" for t in range(n)])
        for r in rows:
            w.writerow([r["count"], r["table_id"], r["tension_mN"],
                        when_text(r["time"]) if r["time"] is not None else ""] +
                       ["" if v is None else v for v in r["homes"]] + [""] * (n - len(r["homes"])))
        return
    con = out()
    if not rows:
        con.print("no calibrations in the history yet")
        return
    show_table(con, "calibration history", ["calibration", "when", "tension N",
                                            *[f"home {k}" for k in range(n)]],
               [[str(r["count"]), when_text(r["time"]), f"{int(r['tension_mN']) / 1000:.3f}",
                 *["-" if v is None else str(v) for v in r["homes"]]] for r in rows])
    for t, g in groups.items():
        drift = [(k, s["drift"]) for k, s in g["tendons"].items() if s["drift"] is not None]
        if drift:
            con.print(f"drift at {t / 1000:.3f} N over {len(g['counts'])} runs (ticks, whole turns "
                      "removed): " + ", ".join(f"tendon {k}: {d:+d}" for k, d in drift))
    if not no_plot:
        plot_history(groups, n, Path(plot_path))
        con.print(f"plot: {plot_path}")


def plot_history(groups, n, path: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import MaxNLocator

    fig, ax = plt.subplots(figsize=(8, 4.5))
    markers = "osd^v<>"
    for gi, (tension, g) in enumerate(groups.items()):
        for k in range(n):
            pts = [(c, v) for c, v in zip(g["counts"], g["tendons"][k]["homes"]) if v is not None]
            if pts:
                base = pts[0][1]
                ax.plot([p[0] for p in pts], [p[1] - base for p in pts], marker=markers[gi % len(markers)],
                        color=f"C{k}", label=f"tendon {k}, {tension / 1000:.2f} N")
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_xlabel("calibration")
    ax.set_ylabel("home - first home at that tension (encoder ticks)")
    ax.set_title("home over time (tendon creep)")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="small", ncol=2)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


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
        "tendons": [_home_row(h, ids) for h in homes],
    }


def _home_row(h, ids) -> dict:
    """One `<home>` line of `status` as an export row: the single-tendon
    home and the straight-pose home, each in the calibration's frame and in
    the servo's present one."""
    t = int(h.get("tendon"))
    home, straight, now = h.get("home"), h.get("straight"), h.get("now")
    usable = h.get("usable") == 1
    return {"tendon": t, "servo_id": ids.get(t),
            "home_ticks": home, "home_now_ticks": now if usable else None,
            "straight_ticks": straight,
            "straight_now_ticks": (now + straight - home
                                   if usable and None not in (now, straight, home) else None),
            "rest_ticks": h.get("rest"), "usable": usable}


@click.command("export")
@click.option("--format", "fmt", type=click.Choice(["json", "csv"]), default="json", show_default=True)
@json_option
@click.option("--output", "-o", type=click.Path(dir_okay=False), default=None,
              help="File to write (default: standard output).")
@port_options
@operator_command
def export_cmd(fmt, as_json, output, port, timeout) -> None:
    """The current homes, for teleoperation software. `home_ticks` is the
    single-tendon home (the paper's definition), `straight_ticks` the
    straight-pose home (every tendon at the tension with the robot straight:
    the usual kinematic zero), both in the frame of the calibration; the
    `*_now_ticks` columns are the same in the servo's present multi-turn
    frame (what to command). `--json` is `--format json`."""
    with session(port, timeout) as c:
        data = current_homes(c)
    if fmt == "json" or as_json:
        text = json.dumps(data, indent=1) + "\n"
    else:
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        cols = ["tendon", "servo_id", "home_ticks", "home_now_ticks", "straight_ticks",
                "straight_now_ticks", "rest_ticks", "usable"]
        w.writerow(["robot", "table_id", "tension_N", "calibration_count"] + cols)
        for t in data["tendons"]:
            w.writerow([data["robot"], data["table_id"], data["tension_N"], data["calibration_count"]] +
                       ["" if t[k] is None else t[k] for k in cols])
        text = buf.getvalue()
    if output:
        Path(output).write_text(text, encoding="utf-8")
    else:
        sys.stdout.write(text)
