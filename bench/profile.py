"""Where each phase's worst main-loop pass went, by function: the program
counter samples `hh_bench --loop-profile FILE` keeps (every 16 cycles of the
worst pass of each phase, with the room of app_poll() it fell in), named
from the firmware's symbols (avr-nm).

    .venv/bin/python -m bench.profile build/fw/paper_2seg/hallhome-paper_2seg.elf FILE \\
        [--phase engaged] [--top 12]

Per phase: the pass's length, each room's share, and the functions the
samples fell in, longest first (µs = samples x the sampling period).
"""
from __future__ import annotations

import argparse
import bisect
import json
import subprocess
import sys
from collections import Counter
from typing import Dict, List, Optional, Tuple


def symbols(elf: str) -> Tuple[List[int], List[Tuple[int, int, str]]]:
    """The firmware's functions as (start, end, name), sorted, and their starts."""
    out = subprocess.run(["avr-nm", "-S", "--defined-only", elf], capture_output=True,
                         text=True, check=True).stdout
    funcs = []
    for line in out.splitlines():
        parts = line.split()
        if len(parts) == 4 and parts[2] in "tTwW":
            start, size = int(parts[0], 16), int(parts[1], 16)
            if start < 0x800000:  # flash, not RAM
                funcs.append((start, start + size, parts[3]))
    funcs.sort()
    return [f[0] for f in funcs], funcs


# The ATmega2560's interrupt vectors: a 4-byte jump each at the start of
# flash, which avr-nm gives no size.
VECTORS = 57


def name_of(pc: int, starts: List[int], funcs: List[Tuple[int, int, str]]) -> str:
    k = bisect.bisect_right(starts, pc) - 1
    if k >= 0 and funcs[k][0] <= pc < funcs[k][1]:
        return funcs[k][2]
    if pc < 4 * VECTORS:
        return f"__vector_{pc // 4}"  # the vector's jump to its handler
    return f"?0x{pc:05x}"


def phase_profile(ph: Dict, rooms: List[str], us_per_sample: float, starts, funcs) -> Dict:
    """One phase's worst pass: µs per room and per (room, function)."""
    by_room: Counter = Counter()
    by_func: Counter = Counter()
    for s in ph["samples"]:
        room, pc = rooms[s >> 24] if (s >> 24) < len(rooms) else str(s >> 24), s & 0xFFFFFF
        by_room[room] += 1
        by_func[(room, name_of(pc, starts, funcs))] += 1
    return {"name": ph["name"], "max_us": ph["max_us"], "max_at_s": ph["max_at_s"],
            "samples": len(ph["samples"]),
            "rooms": {r: n * us_per_sample for r, n in by_room.most_common()},
            "functions": [(r, f, n * us_per_sample) for (r, f), n in by_func.most_common()]}


def main(argv: Optional[List[str]] = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("elf", help="the firmware the bench ran")
    ap.add_argument("profile", help="hh_bench --loop-profile's file")
    ap.add_argument("--phase", default=None, help="this phase only (e.g. engaged)")
    ap.add_argument("--top", type=int, default=12, help="functions shown per phase")
    ap.add_argument("--json", action="store_true", help="the profiles as JSON")
    a = ap.parse_args(argv)
    try:
        with open(a.profile) as fh:
            prof = json.load(fh)
        starts, funcs = symbols(a.elf)
    except (OSError, ValueError, subprocess.CalledProcessError) as e:
        print(f"bench.profile: {e}", file=sys.stderr)
        return 2
    us = prof["every_cycles"] / (prof["f_cpu"] / 1e6)
    phases = [p for p in prof["phases"] if a.phase is None or p["name"] == a.phase]
    if not phases:
        print(f"bench.profile: no phase {a.phase!r} in {a.profile}", file=sys.stderr)
        return 2
    res = [phase_profile(p, prof["rooms"], us, starts, funcs) for p in phases]
    if a.json:
        json.dump(res, sys.stdout, indent=1)
        print()
        return 0
    for r in res:
        print(f"{r['name']}: worst pass {r['max_us']:.0f} us at {r['max_at_s']:.3f} s "
              f"({r['samples']} samples, {us:g} us each)")
        print("  rooms: " + ", ".join(f"{k} {v:.0f}" for k, v in r["rooms"].items()))
        for room, f, v in r["functions"][:a.top]:
            print(f"  {v:7.0f} us  {room:8s} {f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
