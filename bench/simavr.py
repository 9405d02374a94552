"""Runs calibrations of the real firmware ELF on the simavr bench (hh_bench,
docs in sim/README.md) and parses its console and JSON summary."""
from __future__ import annotations

import json
import os
import re
import subprocess
import tempfile
from concurrent.futures import ThreadPoolExecutor
from typing import Dict, List, Optional

LINE = re.compile(r"^\[\s*([\d.]+)\]\s?(.*)$")
KV = re.compile(r"(\w+)=(\"[^\"]*\"|\S+)")


def parse_report(text: str) -> Dict[str, str]:
    """`<kind k=v ...>` -> {"_kind": kind, k: v}."""
    text = text.strip()
    if not (text.startswith("<") and text.endswith(">")):
        return {}
    body = text[1:-1]
    kind = body.split(" ", 1)[0]
    out = {"_kind": kind}
    for k, v in KV.findall(body):
        out[k] = v.strip('"')
    return out


def parse_console(stdout: str) -> List[Dict]:
    """Timestamped console lines -> [{"t": s, "text": line, "rep": {...}}]."""
    lines = []
    for raw in stdout.splitlines():
        m = LINE.match(raw)
        if not m:
            continue
        text = m.group(2)
        lines.append({"t": float(m.group(1)), "text": text, "rep": parse_report(text)})
    return lines


def run(hh_bench: str, elf: str, plant: str, seed: int, events: List[str], until: str,
        limit_s: float, tension_mN: int, workdir: str, perturb: float = 0.0,
        extra_args: Optional[List[str]] = None) -> Dict:
    """One hh_bench invocation (extra_args: more hh_bench options). Returns
    {"ok", "exit", "summary", "lines", "wall_s", "error"}."""
    summ = os.path.join(workdir, f"summary_{seed}_{tension_mN}_{len(events)}_{perturb:g}.json")
    cmd = [hh_bench, elf, "--plant", plant, "--seed", str(seed), "--perturb", f"{perturb:g}",
           "--summary", summ, "--timestamps", "--limit", f"{limit_s:g}s",
           "--tension", f"{tension_mN / 1000:g}", "--until", until, "--fail-on", "^<fault"]
    cmd += list(extra_args or [])
    for e in events:
        cmd += ["--at", e]
    res = {"ok": False, "cmd": " ".join(cmd), "seed": seed, "tension_mN": tension_mN}
    try:
        p = subprocess.run(cmd, capture_output=True, text=True, timeout=limit_s * 4 + 60)
    except (OSError, subprocess.TimeoutExpired) as e:
        res["error"] = str(e)
        return res
    res["exit"] = p.returncode
    res["lines"] = parse_console(p.stdout)
    try:
        with open(summ) as fh:
            res["summary"] = json.load(fh)
    except (OSError, ValueError) as e:
        res["error"] = f"no summary: {e}"
        res["stderr"] = p.stderr[-500:]
        return res
    res["ok"] = p.returncode == 0 and res["summary"].get("until", {}).get("matched", False)
    if not res["ok"]:
        last = [l["text"] for l in res["lines"] if l["text"].startswith("<")][-3:]
        res["error"] = (f"exit {p.returncode}, {res['summary'].get('reason', '')}; "
                        f"last reports: {' / '.join(last) or 'none'}")
    return res


# The end of a calibration: `<done mode=... time_ms=...>` (docs/console.md);
# `<cal ... state=done>` accepted too.
DONE = r"^<(done |cal .*state=done)"
DONE_QUICK = r"^<(done mode=quick|cal .*mode=quick.*state=done)"


def _done(lines: List[Dict], mode: Optional[str] = None) -> Optional[Dict]:
    for l in lines:
        r = l["rep"]
        if r.get("_kind") == "done" or (r.get("_kind") == "cal" and r.get("state") == "done"):
            if mode is None or r.get("mode") == mode:
                return l
    return None


def _t_of(lines: List[Dict], kind: str, **match) -> Optional[Dict]:
    for l in lines:
        r = l["rep"]
        if r.get("_kind") == kind and all(r.get(k) == v for k, v in match.items()):
            return l
    return None


def calibration(hh_bench: str, elf: str, plant: str, seed: int, tension_mN: int,
                workdir: str, limit_s: float = 60.0, extra_events: Optional[List[str]] = None,
                perturb: float = 0.0, until: Optional[str] = None,
                extra_args: Optional[List[str]] = None) -> Dict:
    """A full calibration at tension_mN from the bench's seeded random slack,
    nominal robot. Adds "cal_s" (start report to done report, simulated),
    "done_ms" (the firmware's own time_ms), "homes" (tendon -> home in the
    plant's motor frame), "tension_N" (tendon -> true single-tendon tension
    at the shaft position) and "done_t" (console time of done)."""
    ev = [f"0.3s send set cal_tension {tension_mN}", "0.6s send cal"] + list(extra_events or [])
    r = run(hh_bench, elf, plant, seed, ev, until or DONE, limit_s, tension_mN, workdir, perturb,
            extra_args)
    if not r["ok"]:
        return r
    lines = r["lines"]
    start = _t_of(lines, "progress", state="start")
    done = _done(lines)
    r["done_t"] = done["t"] if done else None
    r["cal_s"] = done["t"] - start["t"] if (done and start) else None
    try:
        r["done_ms"] = float(done["rep"].get("time_ms")) if done else None
    except (TypeError, ValueError):
        r["done_ms"] = None
    tend = {int(t["tendon"]): t for t in r["summary"].get("tendons", [])}
    homes = {}
    for l in lines:
        rep = l["rep"]
        if rep.get("_kind") == "result" and "home" in rep:
            i = int(rep["tendon"])
            home = float(rep["home"])
            t = tend.get(i)
            if t is not None:
                # encoder frame -> plant frame: whole turns between them
                turns = round((t["shaft_ticks"] - t["present_ticks"]) / 4096.0)
                home += 4096.0 * turns
            homes[i] = home
    r["homes"] = homes
    # where the time goes: start -> first tendon, per tendon, final move -> done
    first = next((l for l in lines if l["rep"].get("_kind") == "progress"
                  and l["rep"].get("state") == "tendon"), None)
    final = _t_of(lines, "progress", state="final")
    tend_ms = []
    for l in lines:
        if l["rep"].get("_kind") == "result" and "time_ms" in l["rep"]:
            try:
                tend_ms.append(float(l["rep"]["time_ms"]))
            except ValueError:
                pass
    # per tendon: its start -> engagement (take-up) and engagement -> home
    t_start: Dict[str, float] = {}
    t_eng: Dict[str, float] = {}
    takeup, fine = [], []
    for l in lines:
        rep = l["rep"]
        k, i = rep.get("_kind"), rep.get("tendon")
        if k == "progress" and rep.get("state") == "tendon":
            t_start[i] = l["t"]
        elif k == "progress" and rep.get("state") == "engaged" and i in t_start:
            t_eng[i] = l["t"]
            takeup.append(l["t"] - t_start[i])
        elif k == "result" and i in t_eng:
            fine.append(l["t"] - t_eng[i])
    r["phases"] = {
        "prep_s": first["t"] - start["t"] if (first and start) else None,
        "tendon_s": [x / 1000.0 for x in tend_ms],
        "takeup_s": takeup,
        "fine_s": fine,
        "final_s": done["t"] - final["t"] if (final and done) else None,
    }
    r["tension_N"] = {i: t["tension_at_home_mN"] / 1000.0 for i, t in tend.items()}
    r["shaft_err_ticks"] = {i: t["err_ticks"] for i, t in tend.items()}
    return r


def rehome_and_status(hh_bench: str, elf: str, plant: str, seed: int, tension_mN: int,
                      done_t: float, workdir: str, limit_s: float = 90.0) -> Dict:
    """The same seeded calibration again (simavr is deterministic), a
    `status` just after it (worst main-loop time so far), a power cycle with
    the robot at its homes, and a quick re-home. Adds "loop_max_us",
    "status_t", "quick_s" and "quick_ms"."""
    t_status = done_t + 0.3
    t_cycle = done_t + 1.0
    # 3 s after power-up: later than the long-press abort the bench produces
    # about 2 s after a power cycle (see "phantom" below)
    t_rehome = t_cycle + 3.0
    ev = [f"0.3s send set cal_tension {tension_mN}", "0.6s send cal",
          f"{t_status:.3f}s send status", f"{t_cycle:.3f}s power-cycle",
          f"{t_rehome:.3f}s send rehome"]
    r = run(hh_bench, elf, plant, seed, ev, DONE_QUICK, limit_s, tension_mN, workdir)
    lines = r.get("lines", [])
    st = _t_of(lines, "status")
    r["loop_max_us"] = float(st["rep"]["loop_max_us"]) if st and "loop_max_us" in st["rep"] else None
    r["loops"] = float(st["rep"]["loops"]) if st and "loops" in st["rep"] else None
    r["status_t"] = st["t"] if st else None
    # a release reported between the power cycle and the re-home: the robot
    # was no longer at its homes when the quick re-home started
    r["phantom"] = [l["text"] for l in lines
                    if t_cycle < l["t"] < t_rehome and l["rep"].get("_kind") == "released"]
    qs = [l for l in lines if l["rep"].get("_kind") == "progress"
          and l["rep"].get("state") == "start" and l["rep"].get("mode") == "quick"]
    qd = _done(lines, "quick")
    r["quick_s"] = qd["t"] - qs[0]["t"] if (qd and qs) else None
    try:
        r["quick_ms"] = float(qd["rep"]["time_ms"]) if qd else None
    except (KeyError, ValueError):
        r["quick_ms"] = None
    return r


BUS = re.compile(r"^bus\s+(\d+) us mcu ([0-9A-Fa-f]{2})\b")


def parse_bus_packets(text: str) -> List[Dict]:
    """MCU packets from `hh_bench --trace-bus` lines: [{"t_us", "id", "inst",
    "addr"}] for every DYNAMIXEL 2.0 instruction packet the firmware sent
    (t_us: its first byte; addr: the first two parameter bytes, little
    endian, 0 when the packet has none)."""
    tb = []
    for line in text.splitlines():
        m = BUS.match(line)
        if m:
            tb.append((int(m.group(1)), int(m.group(2), 16)))
    out: List[Dict] = []
    i = 0
    while i + 8 <= len(tb):
        if [b for _, b in tb[i:i + 4]] == [0xFF, 0xFF, 0xFD, 0x00]:
            n = tb[i + 5][1] | (tb[i + 6][1] << 8)  # LEN = params + 3
            addr = tb[i + 8][1] | (tb[i + 9][1] << 8) if n >= 5 and i + 10 <= len(tb) else 0
            out.append({"t_us": tb[i][0], "id": tb[i + 4][1], "inst": tb[i + 7][1], "addr": addr})
            i += 7 + max(n, 3)
        else:
            i += 1
    return out


def _read_stats(d: List[float]) -> Dict:
    d = sorted(d)
    return {"reads": len(d) + 1, "median_ms": d[len(d) // 2],
            "p95_ms": d[int(0.95 * (len(d) - 1))], "max_ms": d[-1]}


def bus_cycle(hh_bench: str, elf: str, plant: str, workdir: str, limit_s: float = 15.0) -> Dict:
    """Position-read period of the firmware during a calibration: a traced
    run (calibration from 0.6 s, to its end), intervals between successive
    position reads (sync read or fast sync read of address 132) after 1 s;
    and per phase of the calibration (the phase the last report line before
    the read named: `engaged` is the fine approach), for the phases with 20
    reads or more."""
    cmd = [hh_bench, elf, "--plant", plant, "--seed", "1", "--perturb", "0", "--limit",
           f"{limit_s:g}s", "--at", "0.6s send cal", "--until", "^<done mode=full",
           "--trace-bus"]
    try:
        # one stream: the report lines name the phase of the bus lines after them
        p = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                           timeout=300)
    except (OSError, subprocess.TimeoutExpired) as e:
        return {"error": str(e)}
    text = p.stdout
    pk = parse_bus_packets(text)
    reads = [x["t_us"] for x in pk if x["inst"] in (0x82, 0x8A) and x["addr"] == 132
             and x["t_us"] >= 1_000_000]
    writes = [x["t_us"] for x in pk if x["inst"] in (0x83, 0x03) and x["t_us"] >= 1_000_000]
    if len(reads) < 3:
        return {"error": f"{len(reads)} position reads in the trace"}
    # the phase of each moment: report lines carry no time in a traced run,
    # so each takes the time of the bus line before it
    marks, last = [], 0
    for line in text.splitlines():
        m = BUS_T.match(line)
        if m:
            last = int(m.group(1))
            continue
        m = PHASE.search(line)
        if m:
            marks.append((last, m.group(1) or "idle"))
    gaps = [(b - a) / 1000.0 for a, b in zip(reads, reads[1:])]
    phases: Dict[str, List[float]] = {}
    k, phase = 0, "idle"
    for a, gap in zip(reads, gaps):
        while k < len(marks) and marks[k][0] <= a:
            phase = marks[k][1]
            k += 1
        phases.setdefault(phase, []).append(gap)
    out = _read_stats(gaps)
    out.update({"goal_writes": len(writes), "window_s": (reads[-1] - reads[0]) / 1e6,
                "by_phase": {ph: _read_stats(d) for ph, d in phases.items() if len(d) >= 20}})
    return out


BUS_T = re.compile(r"^bus\s+(\d+) us")
PHASE = re.compile(r"<(?:progress state=(\w+)|result |done )")


def batch(jobs: List[Dict], parallel: int, progress=None) -> List[Dict]:
    """Runs calibration() jobs (dicts of its keyword arguments) on `parallel`
    processes at once; results in job order."""
    out: List[Optional[Dict]] = [None] * len(jobs)

    def one(k):
        r = calibration(**jobs[k])
        out[k] = r
        if progress:
            progress(k, r)
        return r

    with ThreadPoolExecutor(max_workers=max(1, parallel)) as ex:
        list(ex.map(one, range(len(jobs))))
    return out  # type: ignore[return-value]


def probe(hh_bench: str, elf: str, plant: str, workdir: str) -> Dict:
    """Can the firmware calibrate on the bench? One calibration with a short
    limit; returns its result (ok False with the reason when not)."""
    return calibration(hh_bench, elf, plant, 1, 800, workdir, limit_s=40.0)


def scratch_dir(base: str) -> str:
    os.makedirs(base, exist_ok=True)
    return tempfile.mkdtemp(prefix="simavr_", dir=base)
