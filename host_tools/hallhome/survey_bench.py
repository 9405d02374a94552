"""The board's survey with its held pulls on the virtual bench (make sim,
sim/identify.sh; docs/identify.md).

    python -m hallhome.survey_bench ROBOT.toml LOG [--no-held] -- HH_BENCH FW.elf [options]

runs the bench (its console on a pipe, `--control -` for the commands) and
sends what `hallhome identify survey` sends a board: `survey`, then, each
once the run before has ended, `survey T H` for every held pull the robot
description allows (identify_data.held_pairs()). The console log goes to
LOG, for `python -m hallhome.op_survey`. Exit 0 when the survey and every
held pull ended with `<done mode=survey>`, 1 otherwise (the log says why).
"""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path
from typing import List, Optional, Sequence

# simulated seconds the whole survey may take (paper_2seg: 12 s of pulls
# alone, 6 held pulls of about 10 s)
LIMIT_S = 200


def commands(robot_toml: str, held: bool) -> List[str]:
    """`survey`, then one `survey T H` per held pull of the description."""
    from hallhome.identify_data import held_pairs
    from hallhome.robot import load_robot

    pairs = held_pairs(load_robot(robot_toml)) if held else []
    return ["survey"] + [f"survey {t} {h}" for t, h in pairs]


def run(bench: Sequence[str], cmds: Sequence[str], log: Path) -> int:
    """Runs the bench, sending each command once the board is ready for it;
    returns the number of runs that ended with <done mode=survey>."""
    args = list(bench) + ["--timestamps", "--control", "-", "--limit", f"{LIMIT_S}s"]
    pending = list(cmds)
    done = 0
    with open(log, "w") as f, subprocess.Popen(args, stdin=subprocess.PIPE,
                                               stdout=subprocess.PIPE,
                                               stderr=subprocess.STDOUT, text=True) as p:
        assert p.stdin is not None and p.stdout is not None

        def send_next() -> bool:
            if not pending:
                return False
            p.stdin.write(f"send {pending.pop(0)}\n")
            p.stdin.flush()
            return True

        for line in p.stdout:
            f.write(line)
            text = line.split("]", 1)[-1].strip() if line.startswith("[") else line.strip()
            ended = text.startswith("<done mode=survey") or text.startswith("<released")
            if text.startswith("<done mode=survey"):
                done += 1
            if text.startswith("<ready") and done == 0 and len(pending) == len(cmds):
                send_next()
            elif text.startswith("error:") and len(pending) < len(cmds):
                ended = True  # the command was refused: on with the next
            if ended and not send_next():
                break
        p.terminate()
    return done


def main(argv: Optional[Sequence[str]] = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if "--" not in argv:
        print(__doc__, file=sys.stderr)
        return 2
    k = argv.index("--")
    ap = argparse.ArgumentParser(prog="python -m hallhome.survey_bench",
                                 description="the board's survey and held pulls on the bench")
    ap.add_argument("robot")
    ap.add_argument("log")
    ap.add_argument("--no-held", action="store_true", help="the pulls alone only")
    a = ap.parse_args(argv[:k])
    cmds = commands(a.robot, not a.no_held)
    done = run(argv[k + 1:], cmds, Path(a.log))
    print(f"survey_bench: {done} of {len(cmds)} runs done ({len(cmds) - 1} held pulls)",
          file=sys.stderr)
    return 0 if done == len(cmds) else 1


if __name__ == "__main__":
    sys.exit(main())
