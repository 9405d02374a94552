"""Runs the native closed loop (homing core + plant, no AVR): the project's
hh_closedloop for items 1-3 and bench/hh_mc.c for items 4-5, and parses their
CSV output."""
from __future__ import annotations

import math
import re
import subprocess
from typing import Dict, List, Optional


def _run(cmd: List[str], timeout: float = 600.0) -> str:
    p = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
    if p.returncode not in (0, 3):  # 3: hh_closedloop counted faults (reported)
        raise RuntimeError(f"{' '.join(cmd)} failed ({p.returncode}): {p.stderr.strip()[-400:]}")
    return p.stdout


def _num(s: str) -> float:
    try:
        return float(s)
    except ValueError:
        return math.nan


def parse_closedloop(text: str) -> Dict:
    """hh_closedloop output: `home,...` rows and the `summary,k=v,...` line."""
    homes = []
    summary: Dict[str, float] = {}
    for line in text.splitlines():
        f = line.strip().split(",")
        if f[0] == "home" and len(f) >= 10:
            homes.append(
                {
                    "run": int(f[1]),
                    "tendon": int(f[2]),
                    "home_ticks": _num(f[3]),
                    "true_home_ticks": _num(f[4]),
                    "err_ticks": _num(f[5]),
                    "tension_N": _num(f[6]),
                    "tension_err_N": _num(f[7]),
                    "sim_ms": _num(f[8]),
                    "fault": f[9],
                }
            )
        elif f[0] == "summary":
            for kv in f[1:]:
                if "=" in kv:
                    k, v = kv.split("=", 1)
                    summary[k] = _num(v)
    return {"homes": homes, "summary": summary}


def closedloop(binary: str, config: str, runs: int, tension_mN: int, seed: int,
               mode: str = "full", perturb: float = 0.0) -> Dict:
    cmd = [binary, config, "-n", str(runs), "-t", str(tension_mN), "-s", str(seed),
           "-p", str(perturb), "-m", mode, "-q"]
    out = parse_closedloop(_run(cmd))
    out["cmd"] = " ".join(cmd)
    return out


def parse_cols(text: str) -> Dict[str, List[Dict]]:
    """hh_mc output: `cols,<kind>,names...` then `<kind>,values...` rows."""
    cols: Dict[str, List[str]] = {}
    rows: Dict[str, List[Dict]] = {}
    for line in text.splitlines():
        f = line.strip().split(",")
        if len(f) < 2:
            continue
        if f[0] == "cols":
            cols[f[1]] = f[2:]
            rows.setdefault(f[1], [])
        elif f[0] in cols:
            names = cols[f[0]]
            rec = {}
            for n, v in zip(names, f[1:]):
                x = _num(v)
                rec[n] = v if (math.isnan(x) and v.lower() != "nan") else x
            rows[f[0]].append(rec)
    return rows


def mc(binary: str, config: str, study: str, extra: List[str]) -> Dict:
    cmd = [binary, config, study] + extra
    out = parse_cols(_run(cmd))
    out["cmd"] = " ".join(cmd)
    return out


def read_cfg(path: str) -> Dict:
    """The few plant-config facts the report needs: spool factor and each
    tendon's segment (sim/plant/README.md format)."""
    nm_per_tick = 6136.0
    seg: Dict[int, int] = {}
    seg_default = 1
    with open(path) as fh:
        for raw in fh:
            line = raw.split("#", 1)[0].strip()
            if "=" not in line:
                continue
            k, v = (s.strip() for s in line.split("=", 1))
            if k == "nm_per_tick":
                nm_per_tick = float(v.split()[0])
            m = re.fullmatch(r"tendon\.(\d+|\*)\.segment", k)
            if m:
                if m.group(1) == "*":
                    seg_default = int(float(v.split()[0]))
                else:
                    seg[int(m.group(1))] = int(float(v.split()[0]))
            m = re.fullmatch(r"tendon\.(\d+)\.\w+", k)
            if m:
                seg.setdefault(int(m.group(1)), seg_default)
    n = max(seg) + 1 if seg else 0
    return {"nm_per_tick": nm_per_tick, "segment": [seg.get(i, seg_default) for i in range(n)],
            "n_sensors": _count_sensors(path)}


def _count_sensors(path: str) -> int:
    idx = set()
    with open(path) as fh:
        for raw in fh:
            m = re.match(r"\s*sensor\.(\d+)\.", raw)
            if m:
                idx.add(int(m.group(1)))
    return max(idx) + 1 if idx else 0


def dxl_bench(binary: Optional[str]) -> Dict:
    """Bus cycle figures of build/native/hh_dxl_bench (simulated bus)."""
    if not binary:
        return {}
    try:
        text = _run([binary], timeout=120)
    except (OSError, RuntimeError, subprocess.TimeoutExpired) as e:
        return {"error": str(e)}
    out = {}
    for line in text.splitlines():
        m = re.match(r"\s*(sync read|fast sync read), simulated bus\s+([\d.]+) ms\s+([\d.]+) ms", line)
        if m:
            key = "fast_sync" if m.group(1).startswith("fast") else "sync"
            out[key + "_wire_ms"] = float(m.group(2))
            out[key + "_simavr_ms"] = float(m.group(3))
        m = re.match(r"target: at most ([\d.]+) ms", line.strip())
        if m:
            out["target_ms"] = float(m.group(1))
    return out
