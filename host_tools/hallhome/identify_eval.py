"""How good an identification is, on the virtual bench (docs/identify.md).

A bench survey carries the plant's truth. ``truth_values`` puts it in the
fit's parameter names; ``tension_errors`` asks what the targets generated
from a robot description (the table generator, used as a library) are worth
on the true robot: for each tendon and tension, the table's |dB| target at
its selected sensor, and the tension at which the true robot (the plant's
noise-free single-tendon pull, the calibration's definition) shows that
|dB|. A homing that lands exactly on the target leaves that error.

``python -m hallhome.identify_eval`` runs the study of docs/identify.md:
seeded perturbed robots surveyed on the bench, fitted with and without
weights, errors against the nominal description's.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from hallhome.identify import FitResult, fit
from hallhome.identify_data import IdentifyError, Survey, load_survey
from hallhome.robot import Robot, load_robot

MU0 = 4e-7 * np.pi
TENSIONS = (0.3, 0.8, 1.5)


def truth_values(robot: Robot, survey: Survey) -> dict[str, float]:
    """The plant's true values under the fit's parameter names (display
    units), from a bench survey's ``truth``; {} without one."""
    tr = survey.truth
    if not tr:
        return {}
    out = {"magnet_J": tr["magnet_moment_Am2"] * MU0 / robot.magnet.volume}
    for j, L in enumerate(tr["segment_len_mm"]):
        out[f"length_{j + 1}"] = L
        out[f"EI_{j + 1}"] = tr["segment_ei_Nm2"][j] * 1e3
    out["radius"] = float(np.mean([t["radius_mm"] for t in tr["tendons"]]))
    for k, s in enumerate(tr["sensors"]):
        for a, ax in enumerate("xyz"):
            out[f"sensor{k}_{ax}"] = s["pos_mm"][a]
    for p in survey.pulls:
        t, tt = robot.tendons[p.tendon], tr["tendons"][p.tendon]
        first = survey.meta.get("first_ticks", {}).get(p.tendon)
        if first is not None:
            out[f"engage{p.tendon}"] = ((tt["engagement_ticks"] - first) * t.pull_dir *
                                        tt["nm_per_tick"] * 1e-3)
    return out


def tension_errors(robot: Robot, truth: dict, tensions=TENSIONS) -> np.ndarray:
    """(n_tendons, len(tensions)) true tension minus target, N, of the
    targets generated from ``robot`` on the plant described by ``truth``."""
    from hallhome.tablegen import compute

    res = compute(robot)
    grid = np.array(robot.tension_grid)
    tgrid = np.array(truth["grid_mN"]) * 1e-3
    out = np.zeros((len(robot.tendons), len(tensions)))
    for i, tr in enumerate(res.tendons):
        k = tr.selected
        true_curve = np.array([row[k] for row in truth["tendons"][i]["dB_uT"]]) * 1e-6
        for n, T in enumerate(tensions):
            target = np.interp(T, grid, tr.delta[:, k])
            out[i, n] = _invert(true_curve, tgrid, target) - T
    return out


def _invert(curve, grid, y) -> float:
    """x where the rising ``curve`` over ``grid`` reaches y, extended
    linearly beyond its ends."""
    if y <= curve[0]:
        return float(grid[0] + (y - curve[0]) * (grid[1] - grid[0]) / (curve[1] - curve[0]))
    if y >= curve[-1]:
        return float(grid[-1] + (y - curve[-1]) * (grid[-1] - grid[-2]) / (curve[-1] - curve[-2]))
    return float(np.interp(y, curve, grid))


def bench_survey(bench: Path, elf: Path, plant: Path, out: Path, seed: int, perturb: float,
                 weight_g: float) -> None:
    """Runs ``hh_bench --survey`` for one seeded robot."""
    cmd = [str(bench), str(elf), "--plant", str(plant), "--seed", str(seed), "--perturb",
           str(perturb), "--survey", str(out)]
    if weight_g > 0:
        cmd += ["--survey-weight", str(weight_g)]
    subprocess.run(cmd, check=True, capture_output=True, text=True)


def _summary(errs: list[np.ndarray]) -> dict:
    e = np.array(errs)  # (runs, tendons, tensions)
    out = {}
    for n, T in enumerate(TENSIONS):
        v = e[:, :, n].ravel()
        out[f"{T:g}"] = {"mean": float(v.mean()), "sd": float(v.std(ddof=1)),
                         "worst": float(np.abs(v).max())}
    v = e.ravel()
    out["all"] = {"mean": float(v.mean()), "sd": float(v.std(ddof=1)),
                  "worst": float(np.abs(v).max())}
    return out


def study(robot_path: Path, seeds, perturb: float, weight_g: float, bench: Path, elf: Path,
          plant: Path, log=print) -> dict:
    """The bench study: per seed a survey with one weight per segment; the
    nominal description, the survey-only fit and the fit with weights
    scored by their tension errors."""
    from hallhome.tablegen import compute  # noqa: F401  (fail early without it)

    robot = load_robot(robot_path)
    rows = {"nominal": [], "survey": [], "weights": []}
    refused = {"survey": 0, "weights": 0}
    recovery: dict[str, dict[str, list]] = {}  # parameter -> {"nominal"|mode: errors}
    with tempfile.TemporaryDirectory() as tmp:
        for seed in seeds:
            path = Path(tmp) / f"s{seed}.json"
            bench_survey(bench, elf, plant, path, seed, perturb, weight_g)
            sv = load_survey(path, robot)
            truth = sv.truth
            rows["nominal"].append(tension_errors(robot, truth))
            for mode in ("survey", "weights"):
                s = sv if mode == "weights" else Survey(sv.pulls, (), truth, sv.source, sv.meta)
                try:
                    res = fit(robot, s)
                except IdentifyError as exc:
                    res = None
                    log(f"seed {seed} {mode}: {exc}")
                if res is None or res.refused:
                    refused[mode] += 1
                    log(f"seed {seed} {mode}: refused: {res.refused if res else ''}")
                    rows[mode].append(rows["nominal"][-1])
                    continue
                rows[mode].append(tension_errors(res.robot, truth))
                tv = truth_values(robot, s)
                for r in res.table():
                    if r["name"] in tv and not r["name"].startswith("engage"):
                        rec = recovery.setdefault(r["name"], {})
                        rec.setdefault(mode, []).append(r["value"] - tv[r["name"]])
                        if mode == "weights":
                            rec.setdefault("nominal", []).append(r["nominal"] - tv[r["name"]])
                    elif r["name"].startswith("engage"):
                        recovery.setdefault("engage", {}).setdefault(mode, []).append(
                            r["value"] - tv[r["name"]])
            log(f"seed {seed}: worst |error| nominal {np.abs(rows['nominal'][-1]).max():.3f} N, "
                f"survey {np.abs(rows['survey'][-1]).max():.3f} N, "
                f"weights {np.abs(rows['weights'][-1]).max():.3f} N")
    rms = {name: {k: float(np.sqrt(np.mean(np.square(v)))) for k, v in d.items()}
           for name, d in recovery.items()}
    return {"robot": robot.name, "seeds": list(seeds), "perturb": perturb, "weight_g": weight_g,
            "refused": refused, **{k: _summary(v) for k, v in rows.items()},
            "parameter_rms_error": rms}


def main(argv=None) -> int:
    root = Path(__file__).resolve().parents[2]
    ap = argparse.ArgumentParser(prog="python -m hallhome.identify_eval",
                                 description="Identification study on the virtual bench.")
    ap.add_argument("--robot", default=root / "lookup_tables/robots/paper_2seg.toml", type=Path)
    ap.add_argument("--plant", default=root / "sim/plant/configs/paper_2seg.cfg", type=Path)
    ap.add_argument("--bench", default=root / "build/sim/hh_bench", type=Path)
    ap.add_argument("--elf", default=root / "build/fw/paper_2seg/hallhome-paper_2seg.elf",
                    type=Path)
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--perturb", type=float, default=0.05)
    ap.add_argument("--weight-g", type=float, default=80.0)
    ap.add_argument("--json", type=Path, help="write the figures here too")
    a = ap.parse_args(argv)
    out = study(a.robot, range(1, a.seeds + 1), a.perturb, a.weight_g, a.bench, a.elf, a.plant,
                log=lambda m: print(m, file=sys.stderr))
    text = json.dumps(out, indent=1)
    print(text)
    if a.json:
        a.json.write_text(text + "\n")
    return 0


def fit_vs_truth(res: FitResult, robot: Robot, survey: Survey) -> list[dict]:
    """res.table() rows with the plant's true value where the survey has it."""
    tv = truth_values(robot, survey)
    rows = res.table()
    for r in rows:
        r["true"] = tv.get(r["name"])
    return rows


if __name__ == "__main__":
    sys.exit(main())
