"""`hallhome identify survey`: the identification survey run on the board
(docs/identify.md, "Survey on the board").

The board's `survey` command pulls every tendon (or one) alone, the others
released, from slack to three quarters of the table's top grid tension
(APP_SURVEY_EIGHTHS in lib/app/app_priv.h), as a calibration pulls, and
streams `<sv t=I p=TICKS b=x0,y0,z0,x1,...>` lines: the pulled
tendon, its servo position and every sensor's newest raw sample (cuT, sensor
frame). Nothing is stored on the board; every tendon ends released. This
module turns those lines into the survey file `hallhome identify fit` reads,
and optionally guides the hung weights, read through `sensors`.
"""

from __future__ import annotations

import itertools
import json
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Dict, List, Optional, Sequence, Tuple

import click
from rich.markup import escape

from hallhome import protocol
from hallhome.client import BoardError, Client, HallhomeError, Report
from hallhome.op_common import (R, TENDON, cmd, err, json_option, operator_command, out,
                                port_options, print_json, session)
from hallhome.op_learn import average_fields, read_table
from hallhome.op_run import CalView, follow, run_timeout_option, start, wait_for_end

SV = "sv"  # the board's survey sample report
# Slack samples before the engagement the board reported, this many ticks
# short of it, make a pull's baseline (the detection lies past the true
# engagement: the field has risen by 8 noise levels there).
BASE_GUARD_TICKS = 8
MIN_BASE_SAMPLES = 2
MIN_STEPS = 8  # what `identify fit` needs of a pull (identify_data.load_survey)
# Past the slack, a sample more than this many ticks from the one before was
# taken while the servo still ran at the take-up's speed (the engagement is
# detected a few samples late, at up to 19 ticks per sample): its field lags
# its position and it is left out. The survey's take-up near the engagement
# and its approach move about 1.6 ticks between two lines (APP_SURVEY_V,
# lib/app/app_priv.h).
MAX_JUMP_TICKS = 6
# How far short of the reported engagement the field may already rise: the
# detection comes a few samples past the true engagement.
FAST_GUARD_TICKS = 40
# The share of a pull's range past the engagement that goes into the file:
# the last stretch, where the fine approach closes on the survey's target,
# carries the tendon friction the fit's model has no term for (on the bench's
# plant its residuals there pull the fit into a stronger magnet with a smaller
# routing radius: 3 fits of 10 on seeds 1-10 with the whole range, none
# with 85 %; docs/identify.md).
KEEP_RANGE = 0.85


class SurveyError(HallhomeError):
    pass


@dataclass
class Sample:
    ticks: int
    b: List[List[float]]  # per sensor [x, y, z], cuT


def parse_sample(r: Report, n_sensors: int) -> Tuple[int, Sample]:
    """An `<sv>` report as (tendon, sample); ValueError when malformed."""
    t, p = r.get("t"), r.get("p")
    vals = [int(v) for v in str(r.get("b", "")).split(",") if v.strip()]
    if not isinstance(t, int) or not isinstance(p, int) or len(vals) != 3 * n_sensors:
        raise ValueError(f"malformed survey sample: {r.raw}")
    return t, Sample(p, [vals[3 * k:3 * k + 3] for k in range(n_sensors)])


class SurveyView(CalView):
    """A calibration-like progress view that also keeps the samples."""

    def __init__(self, n_tendons: int, only: Optional[int], n_sensors: int):
        super().__init__(n_tendons, only)
        self.n_sensors = n_sensors
        self.samples: Dict[int, List[Sample]] = {}
        self.engaged: Dict[int, int] = {}
        self.bad = 0
        self.dropped = 0
        # a held pull (`survey T H`): the held tendon and where it stands
        # (<progress state=hold>); the samples and engagement after it are
        # the held pull's
        self.hold: Optional[Tuple[int, int]] = None
        self.held_samples: Dict[int, List[Sample]] = {}
        self.held_engaged: Dict[int, int] = {}

    def feed(self, r: Report) -> None:
        if r.kind == SV:
            try:
                t, s = parse_sample(r, self.n_sensors)
            except ValueError:
                self.bad += 1
                return
            (self.held_samples if self.hold else self.samples).setdefault(t, []).append(s)
            return
        if r.kind == R.PROGRESS and r.get("state") == "hold" and isinstance(r.get("pos"), int):
            self.hold = (int(r.get("tendon")), int(r.get("pos")))
        if r.kind == R.PROGRESS and r.get("state") == "engaged" and isinstance(r.get("pos"), int):
            (self.held_engaged if self.hold else self.engaged)[int(r.get("tendon"))] = \
                int(r.get("pos"))
        if r.kind == "dropped":
            self.dropped += int(r.get("reports", 0) or 0)
        super().feed(r)

    @property
    def ok(self) -> bool:
        return (self.done is not None and self.done.get("mode") == "survey"
                and not self.faults)


def pull_of(tendon: int, samples: Sequence[Sample], engaged: Optional[int],
            pull_dir: int, keep: float = KEEP_RANGE) -> dict:
    """One pull of the survey file from a tendon's samples in arrival order:
    samples at one position averaged into one step, steps kept only while the
    take-up grows (a re-approach after an overshoot goes back first) and up to
    `keep` of the range past the reported engagement, the baseline from the
    slack samples taken before the pull first came near that engagement."""
    if not samples:
        raise SurveyError(f"tendon {tendon}: no survey samples arrived")
    if engaged is None:
        raise SurveyError(f"tendon {tendon}: the board reported no engagement")
    steps: List[Tuple[int, List[List[float]], int]] = []  # ticks, sum, count
    prev: Optional[int] = None
    for s in samples:
        jump, prev = (abs(s.ticks - prev) if prev is not None else 0), s.ticks
        if jump > MAX_JUMP_TICKS and pull_dir * (engaged - s.ticks) < FAST_GUARD_TICKS:
            continue
        if steps and steps[-1][0] == s.ticks:
            t0, acc, n = steps[-1]
            steps[-1] = (t0, [[a + b for a, b in zip(ra, rb)] for ra, rb in zip(acc, s.b)], n + 1)
        else:
            steps.append((s.ticks, [list(map(float, v)) for v in s.b], 1))
    kept: List[Tuple[int, List[List[float]]]] = []
    top = max((pull_dir * t for t, _, _ in steps), default=0)
    last = pull_dir * engaged + keep * (top - pull_dir * engaged)
    for ticks, acc, n in steps:
        if (kept and pull_dir * (ticks - kept[-1][0]) <= 0) or pull_dir * ticks > last:
            continue
        kept.append((ticks, [[round(x / n, 1) for x in v] for v in acc]))
    # the slack samples before the pull first came near its engagement: a
    # back-off after a take-up that ran on passes those positions again, with
    # the field still high from the pull (the path's friction; bench seed 5
    # at ±10 %, stiffness ±25 %: a sample 8 ticks short at 120 uT moved the
    # baseline by 6 uT and the fit into a wrong valley)
    slack = list(itertools.takewhile(
        lambda s: pull_dir * (engaged - s.ticks) >= BASE_GUARD_TICKS, samples))
    if len(slack) < MIN_BASE_SAMPLES:
        raise SurveyError(f"tendon {tendon}: {len(slack)} slack sample(s) before its engagement "
                          f"at {engaged}, {MIN_BASE_SAMPLES} needed for its baseline (the "
                          "tendon started too close to engagement? `release`, then survey again)")
    ns = len(slack[0].b)
    base = [[round(sum(s.b[k][a] for s in slack) / len(slack), 1) for a in range(3)]
            for k in range(ns)]
    if len(kept) < MIN_STEPS:
        raise SurveyError(f"tendon {tendon}: {len(kept)} distinct positions, {MIN_STEPS} "
                          "needed (samples lost on the console?)")
    return {"tendon": tendon, "baseline_cuT": base, "steps": [[t, b] for t, b in kept],
            "samples": len(samples)}


def scan_of(tendon: int, samples: Sequence[Sample], pull_dir: int) -> dict:
    """A scan of a held run (`survey T H`) as a pull record: its points from
    the last time it went back (a scan whose first point found the tendon
    engaged starts again further back), the samples at each averaged into
    one step, the first point (slack: the board checks it) the baseline."""
    if not samples:
        raise SurveyError(f"tendon {tendon}: no scan samples arrived")
    k = max((n for n in range(1, len(samples))
             if pull_dir * (samples[n].ticks - samples[n - 1].ticks) < 0), default=0)
    steps: List[Tuple[int, List[List[float]], int]] = []
    for s in samples[k:]:
        if steps and steps[-1][0] == s.ticks:
            t0, acc, n = steps[-1]
            steps[-1] = (t0, [[a + b for a, b in zip(ra, rb)] for ra, rb in zip(acc, s.b)], n + 1)
        else:
            steps.append((s.ticks, [list(map(float, v)) for v in s.b], 1))
    kept = [(t, [[round(x / n, 1) for x in v] for v in acc]) for t, acc, n in steps]
    if len(kept) < MIN_STEPS:
        raise SurveyError(f"tendon {tendon}: {len(kept)} scan points, {MIN_STEPS} needed "
                          "(samples lost on the console?)")
    return {"tendon": tendon, "baseline_cuT": kept[0][1], "steps": [[t, b] for t, b in kept],
            "samples": len(samples) - k}


def held_of(view: SurveyView, dirs: Dict[int, int]) -> dict:
    """The held record of a `survey T H` run (docs/identify.md, "Held pulls
    on the board"): the board streams the pulled tendon's two scans of its
    engagement, alone before the hold and held after it (scan_of()); the
    held tendon and where it stood. The scan alone goes in as `free_steps`:
    the shift is measured between two crossings made alike."""
    if view.hold is None:
        raise SurveyError("not a held pull: no <progress state=hold>")
    t = next((k for k in view.held_samples if k != view.hold[0]), None)
    if t is None or t not in view.samples:
        raise SurveyError("not a held pull: no scan of the pulled tendon before and after the hold")
    d = dirs.get(t, 1)
    p = scan_of(t, view.held_samples[t], d)
    free = scan_of(t, view.samples[t], d)
    return {"tendon": t, "hold_tendon": view.hold[0], "hold_ticks": view.hold[1],
            "baseline_cuT": p["baseline_cuT"], "steps": p["steps"],
            "free_baseline_cuT": free["baseline_cuT"], "free_steps": free["steps"],
            "samples": p["samples"] + free["samples"]}


def survey_doc(robot: str, table_id: str, view: SurveyView, dirs: Dict[int, int],
               weights: List[dict], held: Sequence[dict] = ()) -> dict:
    pulls = [pull_of(t, view.samples.get(t, []), view.engaged.get(t), dirs.get(t, 1))
             for t in sorted(set(view.rows) | set(view.samples))]
    doc = {"format": "hallhome-survey", "version": 1, "field_unit": "cuT", "robot": robot,
           "source": "board", "table_id": table_id, "pulls": pulls}
    if weights:
        doc["weights"] = weights
    if held:
        doc["held"] = list(held)
    return doc


def robot_for_holds(path: Optional[str], name: str):
    """The robot description that chooses the held pulls: `path`, or the
    project's description of the board's table (`NAME` or `NAME_id`); None
    when there is none."""
    from hallhome.paths import ROBOTS_DIR
    from hallhome.robot import load_robot

    base = name[:-3] if name.endswith("_id") else name
    p = Path(path) if path else ROBOTS_DIR / f"{base}.toml"
    return load_robot(p) if p.is_file() else None


def weight_tendons(rows: Sequence[Report], which: str) -> List[int]:
    """The tendons that get a weight: the first of each segment, or all."""
    seen, pick = set(), []
    for r in rows:
        i, seg = int(r.get("tendon")), r.get("segment")
        if which == "all" or seg not in seen:
            pick.append(i)
        seen.add(seg)
    return pick


def record_weights(c: Client, tendons: Sequence[int], masses_g: Sequence[float], n_avg: int,
                   n_sensors: int, wait: Callable[[str], None]) -> List[dict]:
    """With every tendon released: per tendon and mass, the field averaged
    over n_avg `sensors` reads before and with the mass hung on it (the user
    hangs and removes it when `wait` says so)."""
    def fields() -> List[List[float]]:
        got = average_fields(c, n_avg)
        if len(got) != n_sensors:
            raise SurveyError(f"{n_sensors - len(got)} sensor(s) not reading: see `hallhome "
                              "status`")
        return [[round(x * 100.0, 1) for x in got[k]] for k in range(n_sensors)]

    recs = []
    for i in tendons:
        for mass_g in masses_g:
            base = fields()
            wait(f"hang {mass_g:g} g on tendon {i}, let it settle, then press Enter")
            hung = fields()
            wait(f"take the weight off tendon {i}, then press Enter")
            recs.append({"tendon": i, "mass_g": mass_g, "baseline_cuT": base,
                         "field_cuT": hung})
    return recs


# A pull whose field reached less than this share of the top grid target
# ended at its bound (its travel limit, a field that stopped rising, its
# time): the board ends that tendon's pull there and goes on with the next.
BOUND_SHARE = 0.97


def reached(view: SurveyView, tendon: int) -> Optional[float]:
    """The share of its top target a pull's field reached (its <result>), or
    None without one."""
    row = view.rows.get(tendon, {})
    try:  # the board's decimals arrive as text (protocol.parse_line)
        db, target = float(row.get("dB")), float(row.get("target"))
    except (TypeError, ValueError):
        return None
    return round(db / target, 3) if target > 0 else None


def run_held(c: Client, desc, dirs: Dict[int, int], n: int, ns: int, run_timeout: float,
             as_json: bool) -> List[dict]:
    """The held pulls of the survey (`survey T H`, one run each; docs/identify.md):
    every tendon with a hold of its segment (identify_data.held_pairs() on
    the description `desc`), its engagement scanned alone, then again while
    the hold, pulled alone to its target, keeps the robot bent. Their
    records; none when there is no description or the firmware runs none."""
    from hallhome.identify_data import held_pairs

    if desc is None:
        err().print("[yellow]no robot description of the board's table here: no held pulls "
                    "(give it with --robot ROBOT.toml)[/]")
        return []
    pairs = held_pairs(desc)
    recs: List[dict] = []
    for k, (t, h) in enumerate(pairs, 1):
        view = SurveyView(n, t, ns)
        title = f"held pull {k} of {len(pairs)}: tendon {t}, tendon {h} holding the bend"
        if not as_json:
            out().print(title)
        try:
            for r in c.command(cmd("survey", t, h)).reports:
                view.feed(r)
        except BoardError as e:
            if e.name == "TOO_MANY_ARGS":
                err().print("[yellow]this board's firmware runs no held pulls (`survey T H`): "
                            "flash the current firmware; the survey goes on without them[/]")
                return recs
            raise
        follow(c, view, title, run_timeout, quiet=as_json, what="held pull",
               again="identify survey", log=lambda r: r.kind != SV)
        if not view.ok:
            for f in view.faults:
                err().print(f"[red]fault: {f.get('reason')} on {f.get('dev')} {f.get('index')}[/]")
            raise HallhomeError(f"the held pull of tendon {t} (tendon {h} holding) did not "
                                "complete; nothing written")
        recs.append(held_of(view, dirs))
    return recs


@click.command("survey")
@click.option("--out", "out_path", type=click.Path(dir_okay=False), default=None,
              help="Survey file to write (default: <robot>_survey.json here).")
@click.option("--tendon", "-k", type=TENDON, default=None,
              help="Survey only this tendon (0-based; default: every tendon).")
@click.option("--weight-g", type=click.FloatRange(0.0, 10000.0, min_open=False), default=0.0,
              show_default=True, help="Mass to hang after the pulls (0: survey only).")
@click.option("--weight2-g", type=click.FloatRange(0.0, 10000.0), default=0.0,
              help="A second mass, at least 1.5 times --weight-g, hung in turn on the same "
              "tendons: the fit then finds the tendon friction too (0: none).")
@click.option("--weights", "which", type=click.Choice(["segment", "all"]), default="segment",
              show_default=True, help="Hang the weight on the first tendon of each segment, "
              "or on every tendon.")
@click.option("--samples", type=click.IntRange(4, 64), default=16, show_default=True,
              help="Field reads averaged per weight record.")
@click.option("--no-prompt", "hang_wait", type=click.FloatRange(0.5, 600.0), default=None,
              metavar="SECONDS", help="Do not wait for Enter: wait this long for each weight "
              "to be hung or taken off (scripts).")
@click.option("--held/--no-held", default=True, show_default=True,
              help="After the pulls alone, pull every tendon again from slack while a tendon "
              "of its segment holds the robot bent (`survey T H`): with one weight per "
              "segment the fit then finds each tendon's routing radius. Every tendon of a "
              "survey of all.")
@click.option("--robot", "robot_path", type=click.Path(exists=True, dir_okay=False),
              default=None, help="Robot description that chooses the holds (default: "
              "lookup_tables/robots/<the board's table name>.toml).")
@run_timeout_option
@json_option
@port_options
@operator_command
def survey_cmd(out_path, tendon, weight_g, weight2_g, which, samples, hang_wait, held,
               robot_path, run_timeout, as_json, port, timeout) -> None:
    """Survey the robot on the board for `hallhome identify fit`.

    Every tendon (or --tendon), the others released, is pulled alone from
    slack to three quarters of the table's top grid tension (a robot stiffer
    than its table takes more tension for the same field), as a calibration
    pulls, while the board streams its servo position and every sensor's
    field; every tendon ends released and nothing is stored on the board. A pull that reaches
    its bound first (its travel limit, a field that stops rising, its time:
    a robot that differs from its table) ends there, is marked, and the
    survey goes on with the next tendon. With --weight-g, the
    tool then guides the weights: with every servo slack, hang the mass on
    the first tendon of each segment (--weights all: on every tendon) when
    asked; the field is read before and with it. With --weight2-g too, the
    second mass is hung after the first on each of those tendons, and the
    fit finds the tendon friction from the two.

    Held pulls (unless --no-held; a survey of every tendon): after the pulls
    alone, each tendon that has a hold (a tendon of its segment 30-75
    degrees from it or from its opposite; the first of equals) is pulled
    again, one run per tendon at five eighths of the top grid tension: the
    tendon's engagement is crossed in 2-tick steps, each point averaged;
    the hold is pulled alone to its target and kept there, the field with
    the robot bent is the reference, and the tendon's engagement is crossed
    again in the same steps. How far the bend moved its engagement gives
    its routing radius. Each held pull is shown as it runs (paper_2seg: six,
    about 10 s each). The survey file goes to
    --out; fit it with `hallhome identify fit ROBOT.toml SURVEY.json`.
    Ctrl-C aborts on the board and releases every tendon; nothing is
    written then."""
    from hallhome.identify import FRICTION_MASS_RATIO

    if weight2_g > 0.0 and not weight2_g >= FRICTION_MASS_RATIO * weight_g > 0.0:
        raise click.BadParameter(f"{weight2_g:g} g: the second mass must be at least "
                                 f"{FRICTION_MASS_RATIO:g} times --weight-g ({weight_g:g} g), "
                                 "which must be given", param_hint="--weight2-g")
    with session(port, timeout) as c:
        head, rows = read_table(c)
        robot, table_id = str(head.get("name")), str(head.get("table_id"))
        n, ns = int(head.get("tendons", 0) or 0), int(head.get("sensors", 0) or 0)
        if tendon is not None and tendon >= n:
            raise HallhomeError(f"--tendon {tendon}: the board's table has {n} tendons "
                                f"(0..{n - 1})")
        dirs = {int(r.get("tendon")): int(r.get("dir", 1) or 1) for r in rows}
        view = SurveyView(n, tendon, ns)
        title = f"survey of {robot}" + (f", tendon {tendon}" if tendon is not None else "")
        try:
            for r in start(c, cmd("survey", *([tendon] if tendon is not None else [])), as_json):
                view.feed(r)
        except BoardError as e:
            if e.name == "UNKNOWN_COMMAND":
                raise HallhomeError("this board's firmware has no `survey` command: flash the "
                                    "current firmware (make flash)") from None
            raise
        follow(c, view, title, run_timeout, quiet=as_json, what="survey", again="identify survey",
               log=lambda r: r.kind != SV)
        if not view.ok:
            for f in view.faults:
                err().print(f"[red]fault: {f.get('reason')} on {f.get('dev')} {f.get('index')}[/]")
            raise HallhomeError("the survey did not complete; nothing written")
        if view.bad or view.dropped:
            err().print(f"[yellow]{view.bad} malformed and {view.dropped} dropped report(s) "
                        "during the survey (the fit uses what arrived)[/]")
        held_recs: List[dict] = []
        if held and tendon is None:
            held_recs = run_held(c, robot_for_holds(robot_path, robot), dirs, n, ns,
                                 run_timeout, as_json)
        weights: List[dict] = []
        if weight_g > 0.0:
            start(c, cmd("release"), as_json)
            c.motion = "release"
            wait_for_end(c, 30.0, "`release`")
            c.motion_ended()
            picks = weight_tendons(rows, which) if tendon is None else [tendon]

            def wait(msg: str) -> None:
                if hang_wait is not None:
                    err().print(f"{msg.split(', then')[0]}: waiting {hang_wait:g} s")
                    time.sleep(hang_wait)
                else:
                    click.prompt(msg, default="", show_default=False, prompt_suffix=" ",
                                 err=True)

            masses = [weight_g] + ([weight2_g] if weight2_g > 0.0 else [])
            weights = record_weights(c, picks, masses, samples, ns, wait)
    doc = survey_doc(robot, table_id, view, dirs, weights, held_recs)
    path = Path(out_path or f"{robot}_survey.json")
    path.write_text(json.dumps(doc, indent=1) + "\n")
    summary = {"written": str(path), "robot": robot, "table_id": table_id,
               "pulls": [{"tendon": p["tendon"], "steps": len(p["steps"]),
                          "samples": p["samples"], "reached": reached(view, p["tendon"])}
                         for p in doc["pulls"]],
               "held": [{"tendon": h["tendon"], "hold_tendon": h["hold_tendon"],
                         "steps": len(h["steps"])} for h in held_recs],
               "weights": len(weights), "dropped_reports": view.dropped,
               "time_s": int(view.done.get("time_ms", 0)) / 1000.0}
    if as_json:
        print_json(summary)
        return
    for p in summary["pulls"]:
        bound = p["reached"] is not None and p["reached"] < BOUND_SHARE
        out().print(f"tendon {p['tendon']}: {p['steps']} positions from {p['samples']} samples"
                    + (f" [yellow](ended at its bound, {100 * p['reached']:.0f} % of the top "
                       "target's field)[/]" if bound else ""))
    for h in summary["held"]:
        out().print(f"tendon {h['tendon']} held by tendon {h['hold_tendon']}: {h['steps']} "
                    "positions")
    out().print(f"[green]survey written[/]: {escape(str(path))} ({len(doc['pulls'])} pulls, "
                f"{len(held_recs)} held pulls, "
                f"{len(weights)} weight records, {summary['time_s']:.1f} s on the board); next: "
                f"hallhome identify fit ROBOT.toml {escape(str(path))}")
    sys.stdout.flush()


# --- the board's survey from a console log (make sim, sim/identify.sh) ------------------

def parse_report(line: str) -> Optional[Report]:
    """A console line (with or without the bench's `[ t ]` time stamp) as a
    report (protocol.parse_line, as the client reads the board), or None."""
    text = line.strip()
    if text.startswith("["):
        text = text.split("]", 1)[-1].strip()
    try:
        msg = protocol.parse_line(text)
    except protocol.ProtocolError:
        return None
    return Report(msg["kind"], msg["fields"], text) if msg["type"] == "report" else None


def from_log(lines: Sequence[str], robot: str, n_tendons: int, n_sensors: int) -> dict:
    """The survey file of a console log holding a `survey` run and any held
    pulls after it (`survey T H`, each a run of its own); the pull direction
    of each tendon read from its samples (the board pulls). A held pull that
    did not complete is left out, named on stderr."""
    views: List[SurveyView] = []
    for line in lines:
        r = parse_report(line)
        if r is None:
            continue
        if r.kind == R.PROGRESS and r.get("state") == "start" or not views:
            views.append(SurveyView(n_tendons, None, n_sensors))
        views[-1].feed(r)
    plain = [v for v in views if v.hold is None and (v.samples or v.done or v.faults)]
    if not plain or not plain[0].ok:
        why = "; ".join(f.raw for f in plain[0].faults) if plain else ""
        raise SurveyError(f"the board's survey did not complete: {why or 'no <done mode=survey>'}")
    view = plain[0]
    dirs = {t: (1 if s[-1].ticks >= s[0].ticks else -1) for t, s in view.samples.items() if s}
    held = []
    for v in views:
        if v.hold is None:
            continue
        try:
            if not v.ok:
                raise SurveyError("; ".join(f.raw for f in v.faults) or "it did not complete")
            held.append(held_of(v, dirs))
        except SurveyError as e:
            print(f"survey: a held pull left out (tendon {v.hold[0]} held): {e}", file=sys.stderr)
    return survey_doc(robot, "", view, dirs, [], held)


def main(argv: Optional[Sequence[str]] = None) -> int:
    """python -m hallhome.op_survey LOG WEIGHTS OUT: the survey file of the
    board's `survey` in LOG (a bench console log) with the weight records and
    the truth of WEIGHTS (`hh_bench --survey` with its weights: the bench
    hangs them), written to OUT."""
    import argparse

    ap = argparse.ArgumentParser(prog="python -m hallhome.op_survey", description=main.__doc__)
    ap.add_argument("log")
    ap.add_argument("weights")
    ap.add_argument("out")
    a = ap.parse_args(argv)
    bench = json.loads(Path(a.weights).read_text())
    ns = len(bench["pulls"][0]["baseline_cuT"])
    try:
        doc = from_log(Path(a.log).read_text(errors="replace").splitlines(), bench["robot"],
                       len(bench["pulls"]), ns)
    except SurveyError as e:
        print(f"survey: {e}", file=sys.stderr)
        return 1
    for k in ("weights", "truth", "seed", "perturb"):
        if k in bench:
            doc[k] = bench[k]
    doc["source"] = "board survey, bench weights"
    Path(a.out).write_text(json.dumps(doc, indent=1) + "\n")
    print(f"survey: {len(doc['pulls'])} pulls of the board ("
          + ", ".join(f"tendon {p['tendon']}: {len(p['steps'])}" for p in doc["pulls"])
          + f" positions), {len(doc.get('held', []))} held pulls of the board, "
          f"{len(doc.get('weights', []))} weight records of the bench")
    return 0


if __name__ == "__main__":
    sys.exit(main())
