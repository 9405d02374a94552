"""When each calibration happened, as far as this computer knows.

The board keeps no clock: its history (`<hist>`) numbers the runs but does
not date them. Every run a `hallhome` command sees end (`<done ... count=C>`)
is appended here with the time, keyed by the board's table_id and the
calibration count, so `hallhome history` can date the runs this computer
watched. File: ~/.hallhome_runs.jsonl, or HALLHOME_RUNS (empty: no log).
"""

from __future__ import annotations

import json
import os
import time
from pathlib import Path
from typing import Dict, Optional, Tuple

Key = Tuple[str, int]  # (table_id as 0x... lower case, calibration count)


def path() -> Optional[Path]:
    p = os.environ.get("HALLHOME_RUNS")
    if p is None:
        return Path.home() / ".hallhome_runs.jsonl"
    return Path(p) if p and p != os.devnull else None


def _key(table_id, count) -> Optional[Key]:
    try:
        tid = int(str(table_id), 16) if not isinstance(table_id, int) else table_id
        return f"0x{tid:08x}", int(count)
    except (TypeError, ValueError):
        return None


def record(table_id, count, tension_mN=None, mode=None, when: Optional[float] = None) -> None:
    """Appends one finished run; never fails the command that calls it."""
    p, k = path(), _key(table_id, count)
    if p is None or k is None:
        return
    entry = {"table_id": k[0], "count": k[1], "time": when if when is not None else time.time(),
             "tension_mN": tension_mN, "mode": mode}
    try:
        with open(p, "a", encoding="utf-8") as f:
            f.write(json.dumps(entry) + "\n")
    except OSError:
        pass


def load() -> Dict[Key, float]:
    """(table_id, count) -> Unix time of the latest record of that run."""
    p = path()
    out: Dict[Key, float] = {}
    if p is None:
        return out
    try:
        lines = p.read_text(encoding="utf-8").splitlines()
    except OSError:
        return out
    for line in lines:
        try:
            e = json.loads(line)
            k = _key(e["table_id"], e["count"])
            if k is not None:
                out[k] = float(e["time"])
        except (ValueError, KeyError, TypeError):
            continue  # a line cut by a crash: skip it
    return out


def when(log: Dict[Key, float], table_id, count) -> Optional[float]:
    k = _key(table_id, count)
    return log.get(k) if k is not None else None
