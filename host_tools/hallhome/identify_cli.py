"""`hallhome identify`: identify the robot as built (docs/identify.md)."""

from __future__ import annotations

import dataclasses
import json
import sys
import time
from pathlib import Path

import click


@click.group("identify")
def identify_group():
    """Identify the robot as built, once per robot, and fit its description to it.

    Tension targets are only as good as the robot's TOML; real magnets,
    backbones and sensor placements differ from the drawing. The procedure
    (docs/identify.md):

    \b
    1. Survey (no weights): every tendon, the others slack, is pulled
       alone from slack through its range, up to the travel the table
       expects for the top grid tension; the spool position and the field
       of every sensor are recorded at each step.
    2. Weights (optional, recommended): with every servo slack, hang one
       known mass on one tendon of each segment and record the field before
       and after. They measure each segment's bending stiffness (with the
       description's tendon friction). Hang a second mass, at least 1.5
       times the first, on the same tendon and the fit finds the friction
       too.
       Held pulls (`identify survey` runs them: `survey T H` on the
       board): every tendon pulled again from slack while another tendon of
       its segment holds a bend. The bend moves its engagement by its routing
       radius times the bend, so the fit gives each tendon its own radius,
       which one weight per segment cannot tell (on the bench also
       hh_bench --survey-held).
    3. Fit: `hallhome identify fit ROBOT.toml SURVEY.json` fits the magnet,
       segment lengths, routing radius, each tendon's routing angle and
       engagement (and, with weights, its stretch), sensor positions and the
       stiffness, reports them against
       the nominal values with their uncertainty, plots the residuals per
       tendon, and writes ROBOT_id.toml beside the original (refused fits
       write nothing).
    4. Install: generate the table of the identified TOML
       (`hallhome tables ROBOT_id.toml`), build and flash its firmware
       (`make flash ROBOT=<robot>_id`), calibrate.

    `hallhome identify survey` runs steps 1 and 2 on the board (its `survey`
    command) and writes the survey file; the virtual bench writes one too
    (`build/sim/hh_bench --plant CFG --survey FILE [--survey-weight GRAMS]
    FIRMWARE.elf`). `make sim` runs the whole path on the bench's perturbed
    robot (IDENTIFY=0 skips it).
    """


def next_steps(written: Path) -> str:
    """What the user does with an identified TOML: its table, its firmware."""
    from hallhome.paths import ROBOTS_DIR

    stem = written.stem
    if written.resolve().parent == Path(ROBOTS_DIR).resolve():
        return (f"next: hallhome tables {written}, then make flash ROBOT={stem} "
                "PORT=/dev/ttyACM0")
    d = written.parent
    return (f"next: hallhome tables {written} --out-dir {d}, then make flash ROBOT={stem} "
            f"ROBOTS_DIR={d} TABLES_DIR={d} PORT=/dev/ttyACM0")


def _rows_text(rows, truth: bool) -> list[str]:
    head = f"{'parameter':<12} {'nominal':>10} {'fitted':>10} {'1 sigma':>8} {'unit':<7}"
    out = [head + (f" {'true':>10}" if truth else "")]
    for r in rows:
        line = (f"{r['name']:<12} {r['nominal']:>10.4g} {r['value']:>10.4g} {r['sigma']:>8.2g} "
                f"{r['unit']:<7}")
        if truth:
            line += f" {r['true']:>10.4g}" if r.get("true") is not None else f" {'-':>10}"
        if not r["from_data"]:
            line += "  (mostly the prior: the data hardly tell)"
        out.append(line)
    return out


@identify_group.command("fit")
@click.argument("robot", type=click.Path(exists=True, dir_okay=False))
@click.argument("survey", type=click.Path(exists=True, dir_okay=False))
@click.option("--out", type=click.Path(dir_okay=False),
              help="Identified TOML to write (default: ROBOT_id.toml beside ROBOT). Its file "
                   "name is the robot's name on the board: at most 15 characters.")
@click.option("--no-write", is_flag=True, help="Fit and report only.")
@click.option("--plots", "plot_dir", type=click.Path(file_okay=False),
              help="Write identify_residuals.png (measured and modelled field per tendon, "
                   "the residual beside it) and identify_parameters.png (fitted minus "
                   "nominal, 1 sigma) here.")
@click.option("--no-weights", is_flag=True,
              help="Ignore the survey's weight records (a geometry-only fit: the stiffness "
                   "stays nominal).")
@click.option("--no-friction", is_flag=True,
              help="With two masses on a tendon: keep the description's tendon friction "
                   "instead of fitting it.")
@click.option("--any-robot", is_flag=True,
              help="Fit a survey that names another robot than ROBOT.")
@click.option("--sigma-uT", "sigma_uT", type=click.FloatRange(0.01, 100.0), default=1.0,
              show_default=True, help="Field residual that counts as one sigma (noise and "
              "model error of one averaged reading).")
@click.option("--evaluate", is_flag=True,
              help="With a bench survey's truth: tension errors of the nominal and the "
                   "identified targets (runs the table generator twice).")
@click.option("--json", "as_json", is_flag=True, help="Print the result as JSON (progress "
              "goes to standard error).")
def fit_cmd(robot, survey, out, no_write, plot_dir, no_weights, no_friction, any_robot, sigma_uT,
            evaluate, as_json):
    """Fit ROBOT.toml to a survey file and write the identified TOML.

    Prints the fitted parameters against the nominal ones with their 1-sigma
    uncertainty ("mostly the prior" marks the ones the data hardly tell),
    the field residual per tendon and per weight record (uT rms; about the
    noise, well under 1 uT, when the model explains the robot), and writes
    ROBOT_id.toml. Next: generate its table (`hallhome tables
    ROBOT_id.toml`) and build and flash its firmware (`make flash
    ROBOT=<name>_id`, the TOML in lookup_tables/robots or ROBOTS_DIR).

    \b
    Exits 1, writing nothing, with the reason, when:
    - the survey is malformed or from another robot (its name, sensor or
      tendon count), or a pull never moves the field;
    - the fit did not converge;
    - a parameter ended at the edge of its plausible range (the
      description does not fit this robot);
    - with two masses on a tendon, the friction came out below zero
      (--no-friction keeps the description's);
    - the model cannot explain the data (residual above 10 % of the signal);
    - a held pull started engaged (its engagement is not seen).

    With held pulls it prints, per held pull, how far the bend moved the
    engagement, measured and fitted (um).
    """
    import numpy as np

    from hallhome.cli import _load
    from hallhome.identify import fit, fit_params, measures_friction
    from hallhome.identify_data import IdentifyError, load_survey
    from hallhome.identify_eval import fit_vs_truth, tension_errors, truth_values
    from hallhome.identify_out import (identified_path, plot_parameters, plot_residuals,
                                       write_identified)

    nominal = _load(robot)
    try:
        sv = load_survey(survey, nominal, any_robot=any_robot)
    except IdentifyError as exc:
        raise click.ClickException(str(exc)) from None
    if no_weights:
        sv = dataclasses.replace(sv, weights=())
    friction = measures_friction(sv) and not no_friction
    n_par = len(fit_params(nominal, sv, friction=friction))
    say = (lambda m: click.echo(m, err=True)) if as_json else click.echo
    say(f"survey {survey}: {len(sv.pulls)} pulls, {len(sv.weights)} weight records"
        + (f", {len(sv.held)} held pulls" if sv.held else "")
        + f" (source {sv.source}); fitting {n_par} parameters (2-20 s) ...")
    if not sv.weights:
        say("no weight records: the stiffness stays nominal, so the geometry is identified "
            "but not the tension a take-up means; hang one known weight per segment for "
            "that (docs/identify.md)")
    missing = sorted(set(range(len(nominal.tendons))) - {p.tendon for p in sv.pulls})
    if missing:
        say(f"no pull of tendon(s) {', '.join(map(str, missing))}: their engagement is not "
            "fitted")
    t0 = time.monotonic()
    last = [t0]

    def progress(nfev, rms):
        now = time.monotonic()
        if now - last[0] >= 3.0:
            last[0] = now
            say(f"  ... {now - t0:.0f} s, {nfev} model evaluations, residual {rms:.2f} uT rms")

    try:
        res = fit(nominal, sv, sigma_uT=sigma_uT, progress=progress, friction=friction)
    except IdentifyError as exc:
        raise click.ClickException(str(exc)) from None
    say(f"fit done in {time.monotonic() - t0:.1f} s: residual {res.rms_uT:.2f} uT rms "
        f"({res.signal_uT:.0f} uT rms of signal), reduced chi-square {res.chi2_red:.2f}")
    rows = fit_vs_truth(res, nominal, sv)
    result = {"robot": nominal.name, "survey": str(survey), "refused": res.refused,
              "rms_uT": res.rms_uT, "signal_uT": res.signal_uT, "chi2_red": res.chi2_red,
              "tendon_rms_uT": res.tendon_rms_uT, "weight_rms_uT": res.weight_rms_uT,
              "held_shifts_um": [{"tendon": i, "hold": a, "measured": m, "model": f}
                                 for i, a, m, f in res.held_shifts_um],
              "parameters": rows}
    if plot_dir:
        d = Path(plot_dir)
        d.mkdir(parents=True, exist_ok=True)
        result["plots"] = [str(plot_residuals(res, d / "identify_residuals.png")),
                           str(plot_parameters(res, d / "identify_parameters.png",
                                               truth_values(nominal, sv)))]
    if evaluate and sv.truth and not res.refused:
        say("evaluating the targets on the bench's true robot ...")
        result["tension_error_N"] = {
            "tensions_N": [0.3, 0.8, 1.5],
            "nominal": tension_errors(nominal, sv.truth).round(4).tolist(),
            "identified": tension_errors(res.robot, sv.truth).round(4).tolist()}
    if not res.refused and not no_write:
        try:
            path, _ = write_identified(res, nominal, Path(survey).name, out)
        except IdentifyError as exc:
            raise click.ClickException(str(exc)) from None
        result["written"] = str(path)
    if as_json:
        click.echo(json.dumps(result, indent=1, default=float))
    else:
        for line in _rows_text(rows, any(r.get("true") is not None for r in rows)):
            click.echo(line)
        click.echo("residual per tendon (uT rms): " + ", ".join(
            f"{i}: {v:.2f}" for i, v in sorted(res.tendon_rms_uT.items())))
        if res.weight_rms_uT:
            click.echo("residual per weight (uT rms): "
                       + ", ".join(f"{v:.2f}" for v in res.weight_rms_uT))
        if res.held_shifts_um:
            click.echo("held pulls, engagement moved by the bend (um, measured / fitted): "
                       + ", ".join(f"{i} (held {a}): {m:.1f} / {f:.1f}"
                                   for i, a, m, f in res.held_shifts_um))
        if "tension_error_N" in result:
            te = result["tension_error_N"]
            for k in ("nominal", "identified"):
                e = np.abs(np.array(te[k]))
                click.echo(f"tension error of the {k} targets at 0.3/0.8/1.5 N: worst "
                           f"{e.max() * 1e3:.1f} mN, mean |error| {e.mean() * 1e3:.1f} mN")
        for p in result.get("plots", []):
            click.echo(f"wrote {p}")
        if "written" in result:
            click.echo(f"wrote {result['written']}")
    if "written" in result:
        say(next_steps(Path(result["written"])))
    elif not res.refused and no_write:
        say(f"not written (--no-write); without it: {Path(out) if out else identified_path(nominal)}")
    if res.refused:
        click.echo(f"refused: {res.refused}", err=True)
        sys.exit(1)
