"""Straight-pose homes on the plant, before any firmware (docs/homing.md,
"Straight-pose homes"): for each robot, tension and plant (nominal or
perturbed), the host's shifts (hallhome.straight, from the nominal robot
description) are subtracted from the single-tendon homes, every tendon goes
there together in the plant (build/native/hh_straight), and the tensions and
the tip's deviation from straight are reported beside today's final pose
(every tendon at its single-tendon home).

Two kinds of single-tendon homes:
  field   where a calibration against the host's table lands, noise-free: the
          plant's |dB| on the selected sensor meets the table's target (what
          the firmware measures, minus noise and the one-tick rounding);
  true    the plant's true home, spool tension exactly at the target.

    .venv/bin/python -m bench.straight [--robots paper_2seg,chaos] [--seeds 10]
                                       [--tensions 0.3,0.8,1.5] [--perturb 0.05]

Robots: `paper_2seg` (lookup_tables/robots), `chaos` (the chaos suite's
pool of random robots, 1-3 segments, 3-12 tendons), or paths to TOMLs.
Prints one markdown row per robot, tension, perturbation and kind of home.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hallhome.model import CosseratModel
from hallhome.plantcfg import PlantConfigError, write_plant_config
from hallhome.robot import Robot, load_robot
from hallhome.straight import MODEL_STEPS, straight_pose
from hallhome.tablegen import compute

ROOT = Path(__file__).resolve().parents[1]
HH_STRAIGHT = ROOT / "build" / "native" / "hh_straight"
TOL_N = 0.05


@dataclass
class Case:
    """One hh_straight run: per tendon rows and the pose line."""

    tendons: list[dict]
    tip_single_mm: float
    tip_straight_mm: float
    tip_true_mm: float

    @property
    def straight_err_N(self) -> np.ndarray:
        return np.array([t["T_straight"] for t in self.tendons]) - self.target

    @property
    def alone_err_N(self) -> np.ndarray:
        return np.array([t["T_alone"] for t in self.tendons]) - self.target

    @property
    def single_err_N(self) -> np.ndarray:
        return np.array([t["T_single"] for t in self.tendons]) - self.target

    target: float = 0.0


def run_case(cfg: Path, tension_N: float, shifts, seed: int = 1, perturb: float = 0.0,
             targets_cuT=None, sensors=None, binary: Path = HH_STRAIGHT) -> Case:
    """hh_straight on one plant; targets/sensors select field homes."""
    cmd = [str(binary), str(cfg), "-t", str(round(tension_N * 1000)), "-s", str(seed),
           "-p", str(perturb), "--shift-um", ",".join(f"{v:.3f}" for v in shifts)]
    if targets_cuT is not None:
        cmd += ["--targets-cuT", ",".join(f"{v:.1f}" for v in targets_cuT),
                "--sensors", ",".join(str(int(k)) for k in sensors)]
    p = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    if p.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)}: exit {p.returncode}: {p.stderr.strip()}")
    rows, pose = [], None
    for line in p.stdout.splitlines():
        f = line.split(",")
        if f[0] == "tendon":
            rows.append(dict(i=int(f[1]), segment=int(f[2]), single=float(f[3]),
                             straight=float(f[4]), true=float(f[5]), err_ticks=float(f[6]),
                             tol_ticks=float(f[7]), plant_shift_um=float(f[8]),
                             host_shift_um=float(f[9]), T_single=float(f[10]),
                             T_straight=float(f[11]), T_alone=float(f[12])))
        elif f[0] == "pose":
            pose = [float(x) for x in f[1:4]]
    if pose is None:
        raise RuntimeError(f"{' '.join(cmd)}: no pose line")
    c = Case(rows, *pose)
    c.target = tension_N
    return c


def balanced(robot: Robot) -> bool:
    """Every segment's tendon offsets (of the tendons through it) sum to
    zero: then every tendon at one tension leaves the robot straight."""
    for j in range(1, len(robot.segments) + 1):
        v = np.zeros(2)
        for t in robot.tendons:
            if t.segment >= j:
                v += t.routing_radius * np.array([np.cos(t.routing_angle),
                                                  np.sin(t.routing_angle)])
        if np.linalg.norm(v) > 1e-9:
            return False
    return True


def robots_from(names: list[str], tmp: Path) -> list[Robot]:
    out = []
    for n in names:
        if n == "chaos":
            sys.path.insert(0, str(ROOT))
            from tests.chaos.robots import POOL, robot_toml
            for seed, counts in POOL:
                text, ns, nt, nk = robot_toml(seed, **counts)
                p = tmp / f"chaos{seed}_{ns}s{nt}t.toml"
                p.write_text(text)
                out.append(load_robot(p))
        elif n.endswith(".toml"):
            out.append(load_robot(n))
        else:
            out.append(load_robot(ROOT / "lookup_tables" / "robots" / f"{n}.toml"))
    return out


def study(robot: Robot, tensions, seeds: int, perturb: float, tmp: Path, out=print,
          plant_kw=None):
    cfg = tmp / f"{robot.name}.cfg"
    try:
        write_plant_config(robot, cfg, compression=True, **(plant_kw or {}))
    except PlantConfigError as e:
        out(f"| {robot.name} | - | - | - | not on the plant: {e} |")
        return []
    model = CosseratModel(robot, steps_per_segment=MODEL_STEPS)
    res = compute(robot)
    grid = list(robot.tension_grid)
    shape = f"{len(robot.segments)} seg, {len(robot.tendons)} t" + \
        ("" if balanced(robot) else ", unbalanced")
    rows = []
    for T in tensions:
        g = int(np.argmin([abs(x - T) for x in grid]))
        if abs(grid[g] - T) > 1e-9:
            out(f"| {robot.name} | {T} | - | - | not on the grid |")
            continue
        sp = straight_pose(robot, T, model)
        targets = [tr.delta[g, tr.selected] * 1e8 for tr in res.tendons]
        sensors = [tr.selected for tr in res.tendons]
        for kind in ("field", "true"):
            kw = dict(targets_cuT=targets, sensors=sensors) if kind == "field" else {}
            cases, lost = [], 0
            for s in range(0, seeds + 1):
                try:
                    cases.append(run_case(cfg, T, sp.shift_um, max(s, 1),
                                          perturb if s else 0.0, **kw))
                except RuntimeError:  # a plant the field target never reaches
                    if s == 0:
                        cases.append(None)
                    lost += 1
            for label, cs in (("nominal", cases[:1]), (f"+-{perturb:.0%}", cases[1:])):
                cs = [c for c in cs if c is not None]
                if not cs:
                    out(f"| {robot.name} ({shape}) | {T:.1f} | {label} | {kind} | "
                        "no home: the field never reaches the target |")
                    continue
                if label != "nominal" and lost:
                    label += f" ({lost} of {seeds} without a home)"
                e_st = np.concatenate([c.straight_err_N for c in cs])
                e_si = np.concatenate([c.single_err_N for c in cs])
                e_al = np.concatenate([c.alone_err_N for c in cs])
                e_me = e_st - e_al
                tip = max(c.tip_straight_mm for c in cs)
                tip_si = max(c.tip_single_mm for c in cs)
                dshift = np.concatenate([[t["host_shift_um"] - t["plant_shift_um"]
                                          for t in c.tendons] for c in cs])
                errt = np.concatenate([[t["err_ticks"] for t in c.tendons] for c in cs])
                tol = min(t["tol_ticks"] for t in cs[0].tendons)
                ok = np.abs(e_st).max() <= TOL_N and tip <= 0.5
                row = dict(robot=robot.name, shape=shape, T=T, plant=label, kind=kind,
                           single_worst=float(e_si[np.argmax(np.abs(e_si))]),
                           mean=float(e_st.mean()), sd=float(e_st.std()),
                           worst=float(e_st[np.argmax(np.abs(e_st))]), tip=tip,
                           alone_worst=float(e_al[np.argmax(np.abs(e_al))]),
                           method_worst=float(e_me[np.argmax(np.abs(e_me))]),
                           tip_single=tip_si, dshift_max=float(np.abs(dshift).max()),
                           err_ticks_max=float(np.abs(errt).max()), tol_ticks=tol, ok=ok)
                rows.append(row)
                out(f"| {robot.name} ({shape}) | {T:.1f} | {label} | {kind} | "
                    f"{row['single_worst']:+.3f} / {tip_si:.2f} | {row['alone_worst']:+.3f} | "
                    f"{row['mean']:+.3f} / {row['sd']:.3f} / {row['worst']:+.3f} | "
                    f"{row['method_worst']:+.3f} | {tip:.3f} | "
                    f"{row['err_ticks_max']:.2f} (tol {tol:.2f}) | "
                    f"{row['dshift_max']:.1f} | {'met' if ok else 'missed'} |")
    return rows


HEADER = ("| robot | T (N) | plant | homes | today (all at single homes): worst err (N) / tip (mm) "
          "| alone at its single home: worst err (N) | straight: err mean / SD / worst (N) "
          "| straight - alone: worst (N) | tip (mm) | worst home err vs true straight (ticks) "
          "(+-0.05 N) | host - plant shift, worst (um) | goal |\n"
          "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.straight", description=__doc__.split(
        "\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--robots", default="paper_2seg,chaos",
                    help="comma-separated: robot names, TOML paths, 'chaos'")
    ap.add_argument("--tensions", default="0.3,0.8,1.5")
    ap.add_argument("--seeds", type=int, default=10, help="perturbed plants per case")
    ap.add_argument("--perturb", type=float, default=0.05)
    ap.add_argument("--no-friction", action="store_true",
                    help="plants without path friction and backlash (the host model has none)")
    args = ap.parse_args(argv)
    if not HH_STRAIGHT.exists():
        print(f"bench.straight: {HH_STRAIGHT} missing: make native-build", file=sys.stderr)
        return 2
    tensions = [float(x) for x in args.tensions.split(",")]
    print(HEADER)
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        for r in robots_from(args.robots.split(","), tmp):
            study(r, tensions, args.seeds, args.perturb, tmp,
                  plant_kw=dict(friction_mN=0.0, friction_mu=0.0, backlash_um=0.0)
                  if args.no_friction else None)
    return 0


if __name__ == "__main__":
    sys.exit(main())
