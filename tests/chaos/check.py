"""The invariants of the chaos suite, checked on one schedule's console log
and the bench's summary (ground truth, sim/bench/truth.c). docs/chaos.md
defines each one and its bound."""

from __future__ import annotations

import json
import re
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

RELEASE_MS = 100.0          # every stop releases every tendon within this
PULL_FACTOR = 1.25          # bounded pull: true tension <= 1.25 x target + 0.1 N
PULL_OFFSET_MN = 100.0
ACCURACY = 0.15             # final calibration: true tension within 15 % of target,
REF_MATCH = 0.05            # or within 5 % of target of an undisturbed calibration's
# Invariants judged against an undisturbed calibration of the same robot and
# bench seed (runner.reference()) when they fail on their own bound.
NEEDS_REFERENCE = ("recovery", "accuracy")
# The motion loop never leaves the servos alone longer while a calibration
# runs: clean calibrations of the pool's robots measure 8-24 ms.
BUS_GAP_MS = 50.0
# Stops the release bound applies to. A power cycle is not one: the servos
# lose power and the robot rests where it was (at its homes after a
# calibration, which the quick re-home relies on).
RELEASE_STOPS = {"bang", "fault", "released", "watchdog", "external"}
# Fault reports that stop nothing: `refused` answers a press or `cal` the
# board could not act on while idle (a device missing). Nothing moved and
# nothing starts; the robot stays as the last run or move left it (held at
# its homes after a completed calibration, the documented idle state), so
# the bench's stop at that line is not one the release bound applies to.
NOT_A_STOP = ("<fault reason=refused",)

LINE = re.compile(r"^\[\s*([0-9.]+)\] (.*)$")
FIELDS = re.compile(r'(\w+)=("[^"]*"|\S+?)(?=\s|>|$)')


def max_takeup_mm() -> float:
    """The firmware's take-up search for a tendon's starting slack
    (hom_config_t.max_takeup_um, set in lib/homing/homing.c)."""
    m = re.search(r"max_takeup_um\s*=\s*(\d+)", (ROOT / "lib/homing/homing.c").read_text())
    return int(m.group(1)) / 1000.0 if m else 4.0


def search_covers_mm(robot: str) -> list[float]:
    """Per tendon, the slack the firmware's take-up finds from where a run
    may leave it (docs/app.md "Recovery"): the search past the engagement
    window (max_takeup_um) plus the window's width and the slack margin
    before it. A tendon never seen engaged has a window of one release (1.5 x
    the top-grid travel + the 0.6 mm margin) each side of where it stood
    when the first run after a power-up without stored homes found it: that
    run may come after one whose release the power-up cut (chaos seed 2065:
    release, power cycle in the slack check, release, fault before the
    tendon's take-up: 7.56 mm, found). Repeated stops add nothing to it."""
    from .robots import ROBOTS  # local: robots imports this module's callers
    table = json.loads((ROBOTS / robot / "tables" / f"{robot}.json").read_text())["table"]
    return [max_takeup_mm() + 2.0 * (1.5 * t["travel_um"][-1] / 1000.0 + 0.6) + 0.6 + 0.05
            for t in table["tendons"][: table["n_tendons"]]]


@dataclass
class Verdict:
    violations: dict[str, list[str]] = field(default_factory=dict)
    figures: dict[str, float] = field(default_factory=dict)

    def add(self, inv: str, msg: str) -> None:
        self.violations.setdefault(inv, []).append(msg)

    def fig(self, name: str, v: float, worst=max) -> None:
        self.figures[name] = v if name not in self.figures else worst(self.figures[name], v)


def parse_console(out: str) -> list[tuple[float, str]]:
    lines = []
    for ln in out.splitlines():
        m = LINE.match(ln)
        if m:
            lines.append((float(m.group(1)), m.group(2)))
    return lines


def fields(line: str) -> dict[str, str]:
    return dict(FIELDS.findall(line))


def runs(console: list[tuple[float, str]]) -> list[dict]:
    """Calibration attempts: from a start report to its end line (done,
    fault, released) or a reboot; results seen on the way."""
    out, cur = [], None
    for t, ln in console:
        if ln.startswith("<progress state=start"):
            cur = {"t": t, "end": None, "end_t": None, "results": {}, "mode": fields(ln).get("mode")}
            out.append(cur)
        elif cur is not None and cur["end"] is None:
            if ln.startswith(("<done", "<fault", "<released")) or "<boot name=" in ln:
                # (a reset may cut a report: the boot report then ends its
                # line, a cut <result> too: seed 9140's power cycle)
                cur["end"], cur["end_t"] = ln, t
            elif ln.startswith("<result "):
                f = fields(ln)
                cur["results"][int(f.get("tendon", -1))] = int(f.get("home", -1))
    return out


_EVENT = re.compile(r"(?:^|\s)(send|raw)(?: (.*))?$")


def line_ends_sent(sch, steps: list) -> list[float]:
    """When the schedule sent each console line end (CR, or LF not right
    after CR, as the bench counts them): its timed traffic and the step
    chain's `send` / `raw` events, at the times the bench fired them."""
    out, n = [], -1
    for ln in getattr(sch, "lines", []):
        if ln.startswith("step "):
            n += 1
            if n >= len(steps):
                continue
            t, body = steps[n][0], ln[5:]
        else:
            m = re.match(r"([0-9.]+)s (.*)$", ln)
            if not m:
                continue
            t, body = float(m.group(1)), m.group(2)
        m = _EVENT.search(body)
        if not m:
            continue
        if m.group(1) == "send":
            out.append(t)
        else:
            text = (m.group(2) or "").encode("latin-1", "replace").decode("unicode_escape")
            out += [t] * len(re.findall(r"\r\n?|\n", text))
    return sorted(out)


def cut_by_overrun(console, sent: list[float], t0: float) -> bool:
    """Whether the line sent at t0 is the first line end after a reported
    overrun: the bytes lost may have held the end of the line before it, so
    this line completes that cut line and its reply is the cut line's (an
    `error:6 line too long`, say). docs/chaos.md, "replies"."""
    reports = [t for t, ln in console if t < t0 and ln.startswith("<overrun")]
    return bool(reports) and not [t for t in sent if reports[-1] < t < t0 - 1e-6]


def motion_spans(console, attempts: list[dict]) -> list[tuple[float, float]]:
    """When anything moved: every calibration attempt from its start report
    to its end (its done, fault, or the reset that cut it), and every app
    move from its `<released` report (or `home`'s start) to its `<done
    mode=release|home>` or the next reset."""
    spans = [(a["t"], a["end_t"] if a["end_t"] is not None else float("inf")) for a in attempts]
    start, after_fault = None, False
    for t, ln in console:
        if ln.startswith("<released") and start is None and not after_fault:
            start = t  # a fault's own <released> ends its run: no move follows
        elif start is not None and (ln.startswith(("<done mode=release", "<done mode=home"))
                                    or "<boot name=" in ln):
            spans.append((start, t))
            start = None
        if ln.startswith("<"):
            after_fault = ln.startswith("<fault")
    if start is not None:
        spans.append((start, float("inf")))
    return spans


def first_attempt(attempts: list[dict], console, t0: float, within: float = 6.0):
    """The calibration a press or `cal` at t0 started: its start report, or a
    fault that refused it, within `within` s. A run already under way at t0
    (a press kept over a release started it just before) is the one that
    answers: a press while a run goes is ignored, as documented (seed 8387:
    the final press came 0.27 s into such a run, and the checker took a
    background `cal 99`'s error for its answer)."""
    for a in attempts:
        if a["t"] < t0 and (a["end_t"] is None or a["end_t"] > t0):
            return a
    for t, ln in console:
        if t < t0:
            continue
        if t > t0 + within:
            return None
        if ln.startswith("<progress state=start"):
            return next(a for a in attempts if a["t"] == t)
        if ln.startswith("<fault"):
            return {"t": t, "end": ln, "end_t": t, "results": {}, "mode": None}
    return None


def check(sch, summary: dict, out: str, ref: dict | None = None) -> Verdict:
    """The verdict on one schedule. ref: what an undisturbed calibration of the
    same robot and bench seed achieved (runner.reference()); when it ended in a
    fault, the robot is beyond its table there (the model the table came from
    and the plant disagree), and a clean attempt that ends in the same fault
    is that, not a failed recovery: counted as the figure beyond_table."""
    v = Verdict()
    ref_fault = None
    if ref and ref.get("end", "").startswith("<fault"):
        ref_fault = fields(ref["end"]).get("reason")
    console = parse_console(out)
    tr = summary.get("truth", {})
    target = float(summary.get("target_mN", 800))
    attempts = runs(console)
    steps = summary.get("steps", {}).get("log", [])

    # --- recovery: every clean attempt after a disturbance completes
    for n, idx in enumerate(sch.clean_steps):
        final = n == len(sch.clean_steps) - 1
        tag = "final calibration" if final else f"recovery attempt {n + 1}"
        if idx >= len(steps):
            v.add("recovery", f"{tag}: never started (the script stalled at step "
                  f"{len(steps)} of {summary.get('steps', {}).get('count')})")
            continue
        t0 = steps[idx][0]
        a = first_attempt(attempts, console, t0)
        if a is None:
            said = [ln for t, ln in console if t0 <= t <= t0 + 6.0
                    and ln.startswith(("error:", "<fault", "<missing"))]
            if said and said[0].startswith("error:") and cut_by_overrun(
                    console, line_ends_sent(sch, steps), t0):
                # the start line completed a line an overrun had cut: its
                # reply is that line's, nothing was asked to start
                v.fig("starts_cut_by_overrun", 1)
                continue
            v.add("recovery", f"{tag} at {t0:.2f}s: no calibration started"
                  + (f" ({said[0]})" if said else ""))
            continue
        if a["end"] is None or not a["end"].startswith("<done"):
            if (ref_fault and a["end"] and a["end"].startswith("<fault")
                    and fields(a["end"]).get("reason") == ref_fault):
                v.fig("beyond_table", 1)
                continue
            v.add("recovery", f"{tag} at {t0:.2f}s: {a['end'] or 'did not end'}")
    robot = getattr(sch, "robot", None)
    covers = search_covers_mm(robot) if robot else None
    for t in tr.get("tendons", []):
        limit = covers[t["tendon"]] if covers else max_takeup_mm()
        v.fig("max_start_slack_mm", t["max_start_slack_mm"])
        v.fig("max_paid_out_mm", t["paid_out_mm"])
        if t["max_start_slack_mm"] > limit:
            v.add("recovery", f"tendon {t['tendon']}: {t['max_start_slack_mm']:.2f} mm slack at a "
                  f"run's start, beyond the {limit:.1f} mm the take-up search covers")

    # --- bounded pull before each tendon's home is recorded
    bound = PULL_FACTOR * target + PULL_OFFSET_MN
    for t in tr.get("tendons", []):
        v.fig("peak_ratio", t["peak_before_home_mN"] / target)
        if t["peak_before_home_mN"] > bound:
            v.add("bounded_pull", f"tendon {t['tendon']}: {t['peak_before_home_mN']:.0f} mN "
                  f"({t['peak_before_home_mN'] / target:.2f}x target) at {t['peak_at_s']:.2f}s, "
                  f"bound {bound:.0f} mN")

    # --- release after every stop, no baseline while taut
    excused = set()
    for t, ln in console:
        if "not_released" in ln or "unreleased" in ln:
            f = fields(ln)
            for key in ("tendon", "index"):
                if key in f and f[key].isdigit():
                    excused.add(int(f[key]))
    refusals = {round(t, 6) for t, ln in console if ln.startswith(NOT_A_STOP)}
    moving = motion_spans(console, attempts)
    for s in tr.get("stops", []):
        if s["kind"] == "fault" and round(s["t_s"], 6) in refusals:
            v.fig("refusals_at_rest", 1)
            continue
        if s["kind"] == "external" and not any(a <= s["t_s"] <= b for a, b in moving):
            # the reset pin (a host opening the port) with nothing moving:
            # the board keeps the robot as it rests (docs/app.md, Button and LED)
            v.fig("resets_at_rest", 1)
            continue
        lat = [ms for i, ms in enumerate(s["tendon_ms"]) if i not in excused]
        worst = -1.0 if any(ms < 0 for ms in lat) else max(lat, default=0.0)
        if s["kind"] in RELEASE_STOPS:
            v.fig("release_ms", worst if worst >= 0 else 1e9)
            if worst < 0 or worst > RELEASE_MS:
                v.add("release", f"{s['kind']} at {s['t_s']:.3f}s ({s['tension_mN']:.0f} mN): "
                      + ("never released" if worst < 0 else f"released after {worst:.1f} ms"))
    if tr.get("baselines_taut", 0):
        v.add("release", f"{tr['baselines_taut']} baseline(s) taken with a tendon taut "
              f"(up to {tr['baseline_max_mN']:.1f} mN)")
    v.fig("baseline_max_mN", tr.get("baseline_max_mN", 0.0))

    # --- replies: exactly one final reply per line
    c = tr.get("console", {})
    v.fig("lines_sent", c.get("lines_sent", 0))
    v.fig("replies", c.get("replies", 0))
    if c.get("unanswered", 0):
        v.add("replies", f"{c['unanswered']} of {c['lines_sent']} lines never answered, the "
              f"first sent at {c.get('first_unanswered_s', 0):.3f}s ({c['replies']} replies, "
              f"{c.get('overrun_reports', 0)} overrun reports)")
    if c.get("extra_replies", 0):
        v.add("replies", f"{c['extra_replies']} replies to no line")

    # --- timing: the motion loop keeps talking to the servos
    gap = tr.get("max_bus_gap_ms", 0.0)
    v.fig("bus_gap_ms", gap)
    if gap > BUS_GAP_MS:
        v.add("timing", f"servo bus silent {gap:.0f} ms during a run (at {tr['max_bus_gap_at_s']:.2f}s)")

    # --- final calibration: accuracy, EEPROM records, resets
    final = None
    if sch.clean_steps and sch.clean_steps[-1] < len(steps):
        final = first_attempt(attempts, console, steps[sch.clean_steps[-1]][0])
    if final and final["end"] and final["end"].startswith("<done"):
        # the undisturbed first calibration of a boot, and a repeat one
        refs = [x for x in (ref, (ref or {}).get("repeat"))
                if x and x.get("end", "").startswith("<done")]
        ref_mN = {}
        for x in refs:
            for t in x.get("tendons", []):
                ref_mN.setdefault(t["tendon"], []).append(t["tension_at_home_mN"])
        for t in summary.get("tendons", []):
            err = (t["tension_at_home_mN"] - target) / target
            v.fig("final_err_pct", abs(err) * 100.0)
            rs = ref_mN.get(t["tendon"], [])
            r = min(rs, key=lambda x: abs(t["tension_at_home_mN"] - x)) if rs else None
            if r is not None:
                v.fig("final_vs_reference_pct", abs(t["tension_at_home_mN"] - r) / target * 100.0)
            if abs(err) > ACCURACY and (r is None or
                                        abs(t["tension_at_home_mN"] - r) > REF_MATCH * target):
                v.add("accuracy", f"tendon {t['tendon']}: {t['tension_at_home_mN']:.0f} mN at home, "
                      f"target {target:.0f} mN ({err * 100:+.1f} %)"
                      + (f", undisturbed {r:.0f} mN" if r is not None else ""))
        count = fields(final["end"]).get("count")
        # the ready of the last boot: a later one (a `servos` bring-up among
        # the background lines) may be cut by the bench's end (seed 3070)
        boots = [t for t, ln in console if t > final["end_t"] and "<boot name=" in ln]
        t_boot = boots[-1] if boots else final["end_t"]
        ready = [ln for t, ln in console if t > t_boot and ln.startswith("<ready")][:1]
        # whole lines only: the bench's end may cut the last (seed 12302:
        # a background `history` 3 ms before the end, "homes=221")
        hist = [ln for t, ln in console
                if t > final["end_t"] and ln.startswith("<hist age=0") and ln.endswith(">")]
        if not ready:
            v.add("eeprom", "no boot after the final calibration")
        else:
            f = fields(ready[-1])
            if f.get("homes") != "stored" or f.get("count") != count:
                v.add("eeprom", f"after the final calibration (count={count}) the boot reports "
                      f"homes={f.get('homes')} count={f.get('count')}")
            elif final["mode"] == "full" and len(final["results"]) == len(summary["tendons"]):
                want = ",".join(str(final["results"][i]) for i in sorted(final["results"]))
                got = fields(hist[-1]).get("homes") if hist else None
                if got is None and any(t > final["end_t"] and ln.startswith("<overrun")
                                       for t, ln in console):
                    # every `history` asked lost to a console overrun the
                    # firmware reported: the homes are not read, not wrong
                    v.fig("eeprom_homes_unread", 1)
                elif got != want:
                    v.add("eeprom", f"stored homes {got}, calibrated {want}")
    resets = tr.get("resets", {})
    if resets.get("total", 0) > resets.get("injected", 0):
        boots = [ln for t, ln in console if ln.startswith("<boot")]
        v.add("resets", f"{resets['total'] - resets['injected']} unexpected reset(s): "
              + "; ".join(fields(b).get("reset", "?") for b in boots[1:]))
    if summary.get("exit_code") == 2 or "no summary" in summary.get("reason", ""):
        v.add("harness", f"bench refused the schedule: {summary.get('reason')}")
    elif summary.get("exit_code") == 5:
        v.add("harness", "bench interrupted by a signal (run it again)")
    elif summary.get("exit_code") not in (0, 3):
        v.add("resets", f"bench ended: {summary.get('reason')}")
    return v
