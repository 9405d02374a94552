"""How good an identification is, on the virtual bench (docs/identify.md).

A bench survey carries the plant's truth. ``truth_values`` puts it in the
fit's parameter names; ``tension_errors`` asks what the targets generated
from a robot description (the table generator, used as a library) are worth
on the true robot: for each tendon and tension, the table's |dB| target at
its selected sensor, and the tension at which the true robot (the plant's
noise-free single-tendon pull, the calibration's definition) shows that
|dB|. A homing that lands exactly on the target leaves that error.

``python -m hallhome.identify_eval`` runs the study of docs/identify.md:
seeded perturbed robots surveyed on the bench, fitted without weights, with
one weight per segment, with one per tendon and with two masses per segment
(the friction fitted too), errors against the nominal description's
(``make bench`` runs it too, its section 7).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import re
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from hallhome.identify import FitResult, fit
from hallhome.identify_data import IdentifyError, Survey, load_survey
from hallhome.jobs import map_jobs
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
    for i, t in enumerate(tr["tendons"]):
        out[f"radius{i}"] = t["radius_mm"]
        out[f"angle{i}"] = t["angle_deg"]
    out["friction"] = float(np.mean([t["friction_mN"] for t in tr["tendons"]]))
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


def targets(robot: Robot) -> tuple[np.ndarray, list[tuple[int, np.ndarray]]]:
    """The targets the table generator makes of ``robot``: its tension grid
    (N) and, per tendon, the selected sensor and its |dB| per grid tension
    (T)."""
    from hallhome.tablegen import compute

    res = compute(robot)
    return (np.array(robot.tension_grid),
            [(tr.selected, tr.delta[:, tr.selected].copy()) for tr in res.tendons])


def tension_errors(robot: Robot | tuple, truth: dict, tensions=TENSIONS) -> np.ndarray:
    """(n_tendons, len(tensions)) true tension minus target, N, of the
    targets generated from ``robot`` (or ``targets(robot)``, to reuse them)
    on the plant described by ``truth``."""
    grid, tgts = robot if isinstance(robot, tuple) else targets(robot)
    tgrid = np.array(truth["grid_mN"]) * 1e-3
    out = np.zeros((len(tgts), len(tensions)))
    for i, (k, curve) in enumerate(tgts):
        true_curve = np.array([row[k] for row in truth["tendons"][i]["dB_uT"]]) * 1e-6
        for n, T in enumerate(tensions):
            target = np.interp(T, grid, curve)
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
                 weight_g: float, perturb_stiffness: float | None = None,
                 weight_all: bool = False, second_g: float = 0.0, held: bool = False) -> None:
    """Runs ``hh_bench --survey`` for one seeded robot (``perturb_stiffness``:
    the backbone's stiffness spread, default ``perturb``; ``weight_all``: the
    weight on every tendon, not only on each segment's first; ``second_g``: a
    second mass hung in turn on the same tendons; ``held``: the held pulls
    too)."""
    cmd = [str(bench), str(elf), "--plant", str(plant), "--seed", str(seed), "--perturb",
           str(perturb), "--survey", str(out)]
    if perturb_stiffness is not None:
        cmd += ["--perturb-stiffness", str(perturb_stiffness)]
    if weight_g > 0:
        cmd += ["--survey-weight", f"{weight_g:g}" + (f",{second_g:g}" if second_g > 0 else "")]
        if weight_all:
            cmd += ["--survey-weight-all"]
    if held:
        cmd += ["--survey-held"]
    subprocess.run(cmd, check=True, capture_output=True, text=True)


def weighted_tendon(robot: Robot) -> list[int]:
    """Per tendon, the tendon of its segment that carries the weight when
    there is one per segment: the segment's first."""
    first: dict[int, int] = {}
    for i, t in enumerate(robot.tendons):
        first.setdefault(t.segment, i)
    return [first[t.segment] for t in robot.tendons]


def per_segment(robot: Robot, sv: Survey) -> Survey:
    """``sv`` with the weight records of each segment's first tendon only
    (hh_bench records those alike with or without --survey-weight-all)."""
    first = set(weighted_tendon(robot))
    return dataclasses.replace(sv, weights=tuple(w for w in sv.weights if w.tendon in first))


def _stats(v: np.ndarray) -> dict:
    v = np.asarray(v, float).ravel()
    return {"mean": float(v.mean()), "sd": float(v.std(ddof=1)) if v.size > 1 else 0.0,
            "worst": float(np.abs(v).max()), "n": int(v.size)}


def error_summary(errs: list[np.ndarray]) -> dict:
    """Mean, SD and worst |error| per test tension and over all of them, of
    one (tendons, tensions) error array per robot."""
    e = np.array(errs)  # (runs, tendons, tensions)
    out = {f"{T:g}": _stats(e[:, :, n]) for n, T in enumerate(TENSIONS)}
    out["all"] = _stats(e)
    return out


MODES = ("nominal", "survey", "weights", "tendons", "friction", "held")
FITS = {"survey": "survey only", "weights": "one weight per segment",
        "tendons": "one weight per tendon", "friction": "two masses per segment",
        "held": "one weight per segment and held pulls"}
# "friction": each segment's first tendon carries the weight and a second
# mass this many times heavier, so the fit finds the tendon friction too
SECOND_MASS_FACTOR = 2.0


def with_friction(robot: Robot, friction_mN: float | None) -> Robot:
    """``robot`` with every tendon's friction force set to ``friction_mN``
    (None: as described): a study of a description that gets it wrong."""
    if friction_mN is None:
        return robot
    return dataclasses.replace(robot, tendons=tuple(
        dataclasses.replace(t, friction_N=friction_mN * 1e-3) for t in robot.tendons))


def _masses(sv: Survey, grams: float | None) -> Survey:
    """``sv`` with the weight records of mass ``grams`` only (None: all)."""
    if grams is None:
        return sv
    return dataclasses.replace(sv, weights=tuple(w for w in sv.weights
                                                 if abs(w.mass * 1e3 - grams) < 1e-6))


def one_seed(robot_path: Path, seed: int, perturb: float, weight_g: float, bench: Path,
             elf: Path, plant: Path, perturb_stiffness: float | None = None,
             nominal_targets=None, workdir: Path | None = None,
             modes=("survey", "weights", "tendons"),
             description_friction_mN: float | None = None) -> dict:
    """One seeded bench robot: one survey (the weight on every tendon when
    ``modes`` has "tendons"), fitted as each mode says: "survey" without the
    weights, "weights" with one per segment, "tendons" with one per tendon.
    Returns the tension errors of the nominal and of each fit's targets (a
    refused fit keeps the nominal targets, as the user would), the fitted
    minus the true parameters, and the fits' times. "friction" fits the
    records of each segment's first tendon with a second mass
    (SECOND_MASS_FACTOR heavier) too. ``description_friction_mN``: the
    description's friction is taken to be that (``with_friction``)."""
    import time

    robot = with_friction(load_robot(robot_path), description_friction_mN)
    second = SECOND_MASS_FACTOR * weight_g if "friction" in modes else 0.0
    with tempfile.TemporaryDirectory(dir=workdir) as tmp:
        path = Path(tmp) / f"s{seed}.json"
        bench_survey(bench, elf, plant, path, seed, perturb, weight_g, perturb_stiffness,
                     weight_all="tendons" in modes, second_g=second, held="held" in modes)
        sv = load_survey(path, robot)
    truth = sv.truth
    nominal = tension_errors(nominal_targets or robot, truth)
    out = {"seed": seed, "errors": {"nominal": nominal.tolist()}, "refused": {},
           "recovery": {}, "fit_s": {},
           "radius_mm": [t["radius_mm"] for t in truth["tendons"]]}
    tv = truth_values(robot, sv)
    alone = dataclasses.replace(sv, held=())  # the held pulls count in "held" only
    one = _masses(alone, weight_g)
    surveys = {"survey": dataclasses.replace(alone, weights=()),
               "weights": per_segment(robot, one), "tendons": one,
               "friction": per_segment(robot, alone),
               "held": per_segment(robot, _masses(sv, weight_g))}
    for mode in modes:
        t0 = time.monotonic()
        try:
            res = fit(robot, surveys[mode])
            why = res.refused
            if why and mode == "friction" and why.startswith("friction"):
                # what the refusal tells the user: both masses, the
                # description's friction (--no-friction)
                out.setdefault("friction_fallback", []).append(why)
                res = fit(robot, surveys[mode], friction=False)
                why = res.refused
            elif mode == "friction" and not why:
                out["friction_mN"] = res.value("friction")
        except IdentifyError as exc:
            res, why = None, str(exc)
        out["fit_s"][mode] = time.monotonic() - t0
        if why:
            out["refused"][mode] = why
            out["errors"][mode] = nominal.tolist()
            continue
        out["errors"][mode] = tension_errors(res.robot, truth).tolist()
        for r in res.table():
            if r["name"] not in tv:
                continue
            name = re.sub(r"^(engage|radius|angle)\d+$", r"\1 (per tendon)", r["name"])
            rec = out["recovery"].setdefault(name, {})
            rec.setdefault(mode, []).append(r["value"] - tv[r["name"]])
            if mode == "weights" and not name.endswith("(per tendon)"):
                rec.setdefault("nominal", []).append(r["nominal"] - tv[r["name"]])
    return out


def studies(robot_path: Path, sets: list[dict], weight_g: float, bench: Path, elf: Path,
            plant: Path, log=print, jobs: int = 1, workdir: Path | None = None) -> list[dict]:
    """The bench study over several sets of robots, each a dict with
    ``seeds``, ``perturb`` and optionally ``perturb_stiffness``: per seed a
    survey with one weight per segment; the nominal description, the
    survey-only fit and the fit with weights scored by their tension errors
    (``one_seed``), ``jobs`` seeds at once. One summary per set."""
    robot = load_robot(robot_path)
    nominal = {}  # the same for every seed of a description
    for st in sets:
        fr = st.get("description_friction_mN")
        if fr not in nominal:
            nominal[fr] = targets(with_friction(robot, fr))
    tasks = [(k, (robot_path, seed, st["perturb"], weight_g, bench, elf, plant,
                  st.get("perturb_stiffness"), nominal[st.get("description_friction_mN")],
                  workdir, tuple(st.get("modes", MODES[1:])),
                  st.get("description_friction_mN")))
             for k, st in enumerate(sets) for seed in st["seeds"]]
    done = map_jobs(one_seed, [a for _, a in tasks], jobs,
                    lambda i, res: _log_seed(res, log, sets[tasks[i][0]]))
    per: list[list[dict]] = [[] for _ in sets]
    for (k, _), res in zip(tasks, done):
        per[k].append(res)
    return [_set_summary(robot, st, p, weight_g) for st, p in zip(sets, per)]


def study(robot_path: Path, seeds, perturb: float, weight_g: float, bench: Path, elf: Path,
          plant: Path, log=print, perturb_stiffness: float | None = None, jobs: int = 1,
          workdir: Path | None = None, modes=MODES[1:]) -> dict:
    """``studies`` of one set of robots."""
    st = {"seeds": list(seeds), "perturb": perturb, "perturb_stiffness": perturb_stiffness,
          "modes": list(modes)}
    return studies(robot_path, [st], weight_g, bench, elf, plant, log, jobs, workdir)[0]


def _set_summary(robot: Robot, st: dict, per: list[dict], weight_g: float) -> dict:
    modes = [m for m in MODES if all(m in p["errors"] for p in per)]
    rows = {m: [np.array(p["errors"][m]) for p in per] for m in modes}
    recovery: dict[str, dict[str, list]] = {}
    for p in per:
        for name, d in p["recovery"].items():
            for k, v in d.items():
                recovery.setdefault(name, {}).setdefault(k, []).extend(v)
    rms = {name: {k: float(np.sqrt(np.mean(np.square(v)))) for k, v in d.items()}
           for name, d in recovery.items()}
    fit_s = [t for p in per for t in p["fit_s"].values()]
    ps = st.get("perturb_stiffness")
    return {"robot": robot.name, "seeds": [p["seed"] for p in per], "perturb": st["perturb"],
            "perturb_stiffness": st["perturb"] if ps is None else ps,
            "weight_g": weight_g,
            "second_g": SECOND_MASS_FACTOR * weight_g if "friction" in modes else None,
            "description_friction_mN": st.get("description_friction_mN"),
            "modes": modes,
            "refused": {m: sum(m in p["refused"] for p in per) for m in modes[1:]},
            "refusals": [f"seed {p['seed']} {m}: {w}" for p in per
                         for m, w in p["refused"].items()],
            "fit_s": {"mean": float(np.mean(fit_s)) if fit_s else None,
                      "max": float(np.max(fit_s)) if fit_s else None},
            "errors": {m: [e.tolist() for e in rows[m]] for m in modes},
            "radius_mm": [p["radius_mm"] for p in per],
            "weighted_tendon": weighted_tendon(robot),
            **{m: error_summary(rows[m]) for m in modes},
            "parameter_rms_error": rms}


def _log_seed(p: dict, log, st: dict) -> None:
    e = {m: np.abs(np.array(v)).max() for m, v in p["errors"].items()}
    ref = "".join(f"; {m} fit refused: {w}" for m, w in p["refused"].items())
    ps = st.get("perturb_stiffness")
    spread = f"±{100 * st['perturb']:g} %" + (f", stiffness ±{100 * ps:g} %" if ps else "")
    log(f"{spread}, seed {p['seed']}: worst |error| nominal {e['nominal']:.3f} N"
        + "".join(f", {FITS[m]} {e[m]:.3f} N" for m in MODES[1:] if m in e) + ref)


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
    ap.add_argument("--perturb-stiffness", type=float, default=None,
                    help="the backbone's stiffness spread (default: --perturb)")
    ap.add_argument("--jobs", type=int, default=1, help="seeds at once")
    ap.add_argument("--weight-g", type=float, default=80.0)
    ap.add_argument("--modes", default=",".join(MODES[1:4]),
                    help="fits to score: survey (no weights), weights (one per segment), "
                         "tendons (one per tendon), friction (two masses per segment: the "
                         "friction fitted too), held (one per segment and the held pulls: "
                         "each tendon's radius; the bench's stepped held pulls)")
    ap.add_argument("--description-friction-mN", type=float, default=None,
                    help="study a description whose tendon friction is this (default: the "
                         "TOML's), e.g. 0 for one that leaves it out")
    ap.add_argument("--json", type=Path, help="write the figures here too")
    a = ap.parse_args(argv)
    st = {"seeds": list(range(1, a.seeds + 1)), "perturb": a.perturb,
          "perturb_stiffness": a.perturb_stiffness, "modes": a.modes.split(","),
          "description_friction_mN": a.description_friction_mN}
    bad = [m for m in st["modes"] if m not in MODES[1:]]
    if bad:
        ap.error(f"--modes: unknown {', '.join(bad)} (known: {', '.join(MODES[1:])})")
    out = studies(a.robot, [st], a.weight_g, a.bench, a.elf, a.plant,
                  log=lambda m: print(m, file=sys.stderr), jobs=a.jobs)[0]
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
