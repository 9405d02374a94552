"""`hallhome learn` (model-free targets from known masses or forces, guided),
`hallhome learned` (list the learned targets) and `hallhome forget`."""

from __future__ import annotations

import json
import math
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Dict, List, Optional, Sequence, Tuple

import click
from rich.markup import escape

from hallhome import learnfit
from hallhome.client import BoardError, Client, HallhomeError, LocalError, Report
from hallhome.op_common import (G, R, TENDON, ask, cmd, declared, err, fixed3, grams, int_list,
                                json_option, newtons, operator_command, out, port_options,
                                print_json, session, show_table, wait_for, wait_saved)

SETTLE_WAIT = 30.0  # seconds to wait for the field to return to its baseline


def read_table(c: Client) -> Tuple[Report, List[Report]]:
    rep = c.command(cmd("table"))
    head = rep.first(R.TABLE)
    if head is None:
        raise HallhomeError("the board sent no table report")
    return head, rep.of(R.TENDON)


def default_points(grid: List[int], default_mN) -> List[int]:
    """The grid tension nearest the table's default and its neighbours: the
    firmware interpolates over the grid, so learned points around the
    tension in use matter (docs/app.md)."""
    d = int(default_mN) if default_mN is not None else grid[len(grid) // 2]
    i = min(range(len(grid)), key=lambda k: abs(grid[k] - d))
    return grid[max(0, i - 1):i + 2]


def parse_load(text: str) -> Tuple[float, Optional[float]]:
    """An operator's answer: `81.6` (grams) or `0.8N` (newtons) ->
    (tension N, mass g or None). Raises ValueError with what to type."""
    t = text.strip().lower().replace(" ", "")
    try:
        if t.endswith("n"):
            v = float(t[:-1])
            if not (v > 0 and math.isfinite(v)):
                raise ValueError
            return v, None
        if t.endswith("g"):
            t = t[:-1]
        v = float(t)
        if not (v > 0 and math.isfinite(v)):
            raise ValueError
        return newtons(v), v
    except ValueError:
        raise ValueError(f"{text.strip()!r} is neither a mass in grams (81.6) nor a force in "
                         "newtons (0.8N); both must be positive") from None


# --- the field, read by the host -------------------------------------------------------

def read_fields(c: Client) -> Dict[int, Tuple[float, float, float]]:
    """One `sensors` read: sensor -> (Bx, By, Bz) in uT, running sensors only."""
    out_ = {}
    for r in c.command(cmd("sensors")).of(R.SENSOR):
        if r.get("ok") == 1:
            out_[int(r.get("index"))] = tuple(r.num(k, 0.0) for k in ("bx_uT", "by_uT", "bz_uT"))
    return out_


def average_fields(c: Client, n: int) -> Dict[int, Tuple[float, float, float]]:
    """Mean field of every running sensor over n reads."""
    acc: Dict[int, List[Tuple[float, float, float]]] = {}
    for _ in range(n):
        for k, b in read_fields(c).items():
            acc.setdefault(k, []).append(b)
    return {k: tuple(sum(b[i] for b in v) / len(v) for i in range(3)) for k, v in acc.items()}


def change(b, b0) -> float:
    return math.sqrt(sum((x - y) ** 2 for x, y in zip(b, b0)))


@dataclass
class TableInfo:
    robot: str
    table_id: str
    grid: List[int]
    default_mN: Optional[int]
    noise_uT: float
    n: int
    sensor: Dict[int, int]                 # tendon -> its selected sensor
    targets: Dict[int, List[Tuple[Optional[int], str]]] = field(default_factory=dict)

    @classmethod
    def from_board(cls, head: Report, rows: Sequence[Report]) -> "TableInfo":
        return cls(str(head.get("name")), str(head.get("table_id")),
                   [g for g, _ in int_list(head.get("grid_mN")) if g is not None],
                   head.get("default_mN"), int(head.get("noise_cuT", 0) or 0) / 100.0,
                   int(head.get("tendons", 0)),
                   {int(r.get("tendon")): int(r.get("sensor")) for r in rows},
                   {int(r.get("tendon")): int_list(r.get("target_cuT")) for r in rows})

    def model_uT(self, t: int) -> Optional[List[float]]:
        vals = self.targets.get(t, [])
        if len(vals) != len(self.grid) or any(v is None for v, _ in vals):
            return None
        return [v / 100.0 for v, _ in vals]


@dataclass
class Options:
    tolerance: float
    no_model: bool
    min_field: Optional[float]
    samples: int


def settle(c: Client, info: TableInfo, t: int, b0, opts: Options) -> bool:
    """Waits until the field at tendon t's sensor is back at its baseline
    (the weight is off and the robot hangs straight again). False when the
    operator asks for a new baseline instead."""
    k = info.sensor[t]
    # back within the noise (and within --min-field when that is larger)
    floor = max(learnfit.NO_WEIGHT_SIGMAS * info.noise_uT, opts.min_field or 0.0)
    told = False
    while True:
        deadline = time.monotonic() + SETTLE_WAIT
        calm = 0
        d = float("inf")
        while time.monotonic() < deadline:
            d = change(average_fields(c, 4)[k], b0[k])
            calm = calm + 1 if d <= floor else 0
            if calm >= 2:
                return True
            if not told:
                out().print(f"waiting for the field at sensor {k} to return to its baseline "
                            f"({d:.2f} uT away) ...")
                told = True
        ans = ask(f"the field at sensor {k} is still {d:.2f} uT from its baseline after "
                  f"{SETTLE_WAIT:g} s (weight still on, robot touched?). Enter: wait again, "
                  "b: take a new baseline, q: quit").strip().lower()
        if ans == "q":
            raise KeyboardInterrupt
        if ans == "b":
            return False


def take_baseline(c: Client, opts: Options):
    c.command(cmd("release"))
    done = wait_for(c, lambda r: r.kind == R.DONE, 30.0, "the release and baseline capture")
    if not done.get("baseline"):
        raise HallhomeError("the board could not capture the straight-pose baseline (sensors?)")
    b0 = average_fields(c, opts.samples)
    out().print("baseline captured")
    return b0


def capture(c: Client, info: TableInfo, t: int, tension_N: float, mass_g: Optional[float], b0,
            points: List[Tuple[float, float]], opts: Options, timeout: float) -> Optional[dict]:
    """Measures one load on tendon t; returns the sample, or None when the
    reading is refused (the reason is printed)."""
    k = info.sensor[t]
    t_mN = tension_N * 1000.0
    fields = average_fields(c, opts.samples)
    if k not in fields:
        raise HallhomeError(f"sensor {k} (tendon {t}'s) is not running: `hallhome status`")
    dB = change(fields[k], b0[k])
    why = learnfit.check_reading(t_mN, dB, points, info.noise_uT, info.grid,
                                 None if opts.no_model else info.model_uT(t), opts.min_field,
                                 opts.tolerance)
    if why:
        out().print(f"[yellow]refused: {escape(why)}[/]")
        return None
    sample = {"tendon": t, "tension_mN": int(round(t_mN)), "force_N": round(tension_N, 4),
              "mass_g": mass_g, "sensor": k, "dB_uT": round(dB, 2), "stored_on_board": False}
    g = learnfit.nearest_grid(t_mN, info.grid, opts.tolerance)
    if g is not None:
        # A grid tension: the board measures it too and keeps it (EEPROM),
        # used from the next calibration on.
        wait_saved(c, 20.0)  # the board refuses `learn` while it writes a record
        try:
            rep = c.command(cmd("learn", t, fixed3(g / 1000.0)), timeout=max(timeout, 10.0))
        except BoardError as e:
            out().print(f"[red]{e.name}: {escape(e.text)}[/]")
            if e.name in ("BUSY", "TIMEOUT", "SENSOR_FAULT"):
                return None  # ask again: the capture can be repeated
            raise
        lr = rep.first(R.LEARNED)
        if lr is None:
            raise HallhomeError("the board accepted `learn` but sent no learned report")
        sample.update(stored_on_board=True, grid_mN=g, board_dB_uT=float(lr.get("dB_uT")))
    what = f"{mass_g:g} g, " if mass_g is not None else ""
    out().print(f"tendon {t} at {t_mN / 1000:.3f} N ({what}sensor {k}): |dB| = {dB:.2f} uT"
                + (f"; stored on the board at the grid tension {g / 1000:.3f} N "
                   f"({sample['board_dB_uT']:.2f} uT)" if sample["stored_on_board"] else
                   "; between grid tensions: fitted onto the grid in the export file"))
    return sample


def strictly_growing(vals: List[Optional[int]]) -> Tuple[List[Optional[int]], int]:
    """Keeps the first of equal or falling neighbours (the table generator
    needs learned targets that grow with tension; a plateau of the fit is
    one target, not several); returns the values and how many were dropped."""
    out_: List[Optional[int]] = []
    last = None
    dropped = 0
    for v in vals:
        if v is not None and last is not None and v <= last:
            out_.append(None)
            dropped += 1
            continue
        out_.append(v)
        if v is not None:
            last = v
    return out_, dropped


def export_doc(info: TableInfo, got: List[dict], board_targets, tol: float) -> Tuple[dict, List[str]]:
    """The learned-targets file: for the tendons learned now, this session's
    loads fitted onto the grid (a load stored on the board counts with the
    board's own value, so file and board agree); for the others, the board's
    learned entries. `samples` are the loads at grid tensions (the format's
    samples sit on the grid), `points` every load as measured."""
    rows, notes = [], []
    for t in sorted(set(board_targets) | {s["tendon"] for s in got}):
        pts = [(s["grid_mN"], s["board_dB_uT"]) if s["stored_on_board"] else (s["tension_mN"], s["dB_uT"])
               for s in got if s["tendon"] == t]
        if pts:
            fit = learnfit.fit_to_grid(pts, info.grid, tol)
            vals, dropped = strictly_growing([None if v is None else int(round(v * 100)) for v in fit])
            if dropped:
                notes.append(f"tendon {t}: the readings do not rise over {dropped} grid tension(s): "
                             "those keep the compiled target")
            if all(v is None for v in vals):
                notes.append(f"tendon {t}: the learned tensions span no grid tension; learn at "
                             "least two loads around the grid tensions you calibrate at")
        else:
            vals = [v if mark == "*" else None for v, mark in board_targets.get(t, [])]
        if any(v is not None for v in vals):
            rows.append({"tendon": t, "target_cuT": vals})
    samples = [dict(s, tension_mN=s["grid_mN"]) for s in got if s["stored_on_board"]]
    doc = {"format": "hallhome-learned", "format_version": 1, "robot": info.robot,
           "table_id": info.table_id, "grid_mN": info.grid, "g": G, "tendons": rows,
           "samples": samples, "points": got}
    return doc, notes


@click.command("learn")
@click.option("--tendon", "-k", "tendons", type=TENDON, multiple=True,
              help="Tendon to learn, 0-based (repeatable; default: every tendon).")
@click.option("--mass", "-m", "masses", type=click.FloatRange(min=0.1), multiple=True,
              help="Mass in grams to hang, any value (repeatable).")
@click.option("--force", "-F", "forces", type=click.FloatRange(min=0.001), multiple=True,
              help="Known force in newtons instead of a mass (repeatable).")
@click.option("--tolerance", type=click.FloatRange(0.0, 10.0), default=1.0, show_default=True,
              help="A load within this many % of a grid tension is also stored on the board "
                   "at that grid tension.")
@click.option("--no-model", is_flag=True,
              help="Accept readings far from the table's (model's) targets.")
@click.option("--min-field", type=click.FloatRange(min=0.0), default=None,
              help="Smallest field change (uT) that shows a weight hangs (default: 3 noise "
                   "sigmas of the table).")
@click.option("--samples", type=click.IntRange(1, 200), default=16, show_default=True,
              help="Sensor reads averaged per capture.")
@click.option("--out", "-o", "out_path", type=click.Path(dir_okay=False), default=None,
              help="Export file (default: learned_<robot>.json in the current directory).")
@port_options
@operator_command
def learn_cmd(tendons, masses, forces, tolerance, no_model, min_field, samples, out_path, port,
              timeout) -> None:
    """The paper's model-free workflow, guided: hang known masses (any
    value) or apply known forces on each tendon in turn. Each reading is
    checked (a weight hangs, the field rises with tension, it is near the
    model); loads at a grid tension are also stored on the board (EEPROM,
    used instead of the compiled targets); all points are fitted onto the
    table's grid (non-decreasing) in the export file the table generator
    compiles in. Ctrl-C stops (exit 130)."""
    con = out()
    opts = Options(tolerance, no_model, min_field, samples)
    with session(port, timeout) as c:
        head, rows = read_table(c)
        info = TableInfo.from_board(head, rows)
        todo = list(tendons) or list(range(info.n))
        for t in todo:
            if t >= info.n:
                raise click.BadParameter(f"{t}: the table has {info.n} tendons (0..{info.n - 1})",
                                         param_hint="--tendon")
        plan = [(newtons(m), m) for m in masses] + [(f, None) for f in forces]
        if not plan:
            plan = [(g / 1000.0, round(grams(g / 1000.0), 1))
                    for g in default_points(info.grid, info.default_mN)]
        con.print(f"model-free calibration of [bold]{info.robot}[/] (table {info.table_id}): "
                  f"tendons {', '.join(map(str, todo))}; loads "
                  + ", ".join((f"{m:g} g" if m is not None else f"{f:g} N") +
                              (f" ({f:.3f} N)" if m is not None else "") for f, m in plan))
        ask("Remove every weight and let the robot hang straight and slack; press Enter")
        b0 = take_baseline(c, opts)
        got: List[dict] = []
        stop = False
        for t in todo:
            points: List[Tuple[float, float]] = []
            for f_plan, m_plan in plan:
                asked = f"{m_plan:g} g" if m_plan is not None else f"{f_plan:g} N"
                while True:
                    ans = ask(f"tendon {t}: hang {asked} ({f_plan:.3f} N); what hangs, in grams "
                              "or as a force like 0.75N (Enter: as asked, s: skip, q: quit)",
                              default=f"{m_plan:g}" if m_plan is not None else f"{f_plan:g}N")
                    ans = ans.strip().lower()
                    if ans in ("s", "q"):
                        break
                    try:
                        f_N, m_g = parse_load(ans)
                    except ValueError as e:
                        con.print(f"[yellow]{escape(str(e))}[/]")
                        continue
                    s = capture(c, info, t, f_N, m_g, b0, points, opts, timeout)
                    if s is not None:
                        got.append(s)
                        points.append((s["tension_mN"], s["dB_uT"]))
                        break
                if ans == "q":
                    stop = True
                    break
            if stop:
                break
            con.print(f"tendon {t} done: remove the weight")
            if not settle(c, info, t, b0, opts):
                b0 = take_baseline(c, opts)
        if any(s["stored_on_board"] for s in got):
            wait_saved(c, 20.0)
        _, rows = read_table(c)
    board_targets = {int(r.get("tendon")): int_list(r.get("target_cuT")) for r in rows}
    bad = []
    for s in got:
        if s["stored_on_board"]:
            lst = board_targets.get(s["tendon"], [])
            gi = info.grid.index(s["grid_mN"])
            if gi >= len(lst) or lst[gi] != (round(s["board_dB_uT"] * 100), "*"):
                bad.append(f"tendon {s['tendon']} at {s['grid_mN'] / 1000:.3f} N")
    doc, notes = export_doc(info, got, board_targets, tolerance)
    path = Path(out_path or f"learned_{info.robot}.json")
    path.write_text(json.dumps(doc, indent=1) + "\n", encoding="utf-8")
    for n in notes:
        err().print(f"[yellow]note: {escape(n)}[/]")
    con.print(f"{len(got)} load(s) learned, {sum(s['stored_on_board'] for s in got)} stored on the "
              f"board; exported to {path}")
    if bad:
        raise HallhomeError("learned target(s) not in the board's table: " + ", ".join(bad))


# --- learned, forget ------------------------------------------------------------------

def _board_lacks(name: str, e: HallhomeError) -> HallhomeError:
    return HallhomeError(f"the board's firmware has no `{name}` command ({e}): flash a newer "
                         "firmware")


def learned_entries(c: Client) -> Tuple[List[dict], str]:
    """The learned targets on the board: from `learned` when the firmware
    has it, else from the `*` marks of `table`. Returns (entries, source)."""
    head, rows = read_table(c)
    info = TableInfo.from_board(head, rows)
    if declared("learned"):
        try:
            rep = c.command(cmd("learned"))
            return [{"tendon": int(r.get("tendon")), "grid": int(r.get("grid")),
                     "tension_N": info.grid[int(r.get("grid"))] / 1000.0,
                     "target_uT": int(r.get("target_cuT")) / 100.0}
                    for r in rep.of(R.LEARNED)], "learned"
        except (BoardError, LocalError) as e:
            if e.name != "UNKNOWN_COMMAND":
                raise
    out_ = []
    for t, vals in sorted(info.targets.items()):
        for gi, (v, mark) in enumerate(vals):
            if mark == "*" and v is not None:
                out_.append({"tendon": t, "grid": gi, "tension_N": info.grid[gi] / 1000.0,
                             "target_uT": v / 100.0})
    return out_, "table"


@click.command("learned")
@json_option
@port_options
@operator_command
def learned_cmd(as_json, port, timeout) -> None:
    """List the learned targets stored on the board (tendon, grid tension,
    target)."""
    with session(port, timeout) as c:
        entries, _ = learned_entries(c)
    if as_json:
        print_json({"learned": entries})
        return
    if not entries:
        out().print("no learned targets on the board")
        return
    show_table(out(), "learned targets", ["tendon", "grid", "tension N", "target uT"],
               [[str(e["tendon"]), str(e["grid"]), f"{e['tension_N']:.3f}", f"{e['target_uT']:.2f}"]
                for e in entries])


@click.command("forget")
@click.argument("tendon")
@port_options
@operator_command
def forget_cmd(tendon, port, timeout) -> None:
    """Forget the learned targets of TENDON (0-based) or of `all` tendons on
    the board: the compiled targets apply again."""
    if tendon != "all":
        try:
            k = int(tendon)
        except ValueError:
            raise click.BadParameter(f"{tendon!r} is neither a tendon ({TENDON.min}..{TENDON.max}) "
                                     "nor `all`", param_hint="TENDON") from None
        if not TENDON.min <= k <= TENDON.max:
            raise click.BadParameter(f"{k} is not in {TENDON.min}..{TENDON.max}", param_hint="TENDON")
    if not declared("forget"):
        raise HallhomeError("the firmware declarations (lib/console/con_commands.def) have no "
                            "`forget` command: this firmware cannot forget learned targets")
    with session(port, timeout) as c:
        wait_saved(c, 20.0)
        try:
            c.command(cmd("forget", tendon))
        except (BoardError, LocalError) as e:
            if e.name == "UNKNOWN_COMMAND":
                raise _board_lacks("forget", e) from None
            raise
        wait_saved(c, 20.0)
        left, _ = learned_entries(c)
    out().print(f"forgot the learned targets of {'every tendon' if tendon == 'all' else 'tendon ' + tendon}; "
                f"{len(left)} learned target(s) left on the board")
    if tendon != "all" and any(e["tendon"] == int(tendon) for e in left):
        sys.exit(1)
