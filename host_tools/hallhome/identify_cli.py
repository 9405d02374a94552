"""`hallhome identify`: identify the robot as built (docs/identify.md)."""

from __future__ import annotations

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
       and after. They measure each segment's bending stiffness, with the
       tendon's friction at that tension folded in.
    3. Fit: `hallhome identify fit ROBOT.toml SURVEY.json` fits the magnet,
       segment lengths, routing radius, sensor positions, each tendon's
       engagement and the stiffness, reports them against the nominal
       values with their uncertainty, plots the residuals per tendon, and
       writes ROBOT_id.toml beside the original (refused fits write
       nothing).
    4. Install: generate the table of the identified TOML
       (`hallhome tables ROBOT_id.toml`) and flash it.

    The board cannot stream a survey yet: surveys come from files, e.g. the
    virtual bench's (`build/sim/hh_bench --plant CFG --survey FILE
    [--survey-weight GRAMS] FIRMWARE.elf`).
    """


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
              help="Identified TOML to write (default: ROBOT_id.toml beside ROBOT).")
@click.option("--no-write", is_flag=True, help="Fit and report only.")
@click.option("--plots", "plot_dir", type=click.Path(file_okay=False),
              help="Write identify_residuals.png and identify_parameters.png here.")
@click.option("--no-weights", is_flag=True,
              help="Ignore the survey's weight records (a geometry-only fit).")
@click.option("--sigma-uT", "sigma_uT", type=click.FloatRange(0.01, 100.0), default=1.0,
              show_default=True, help="Field residual that counts as one sigma (noise and "
              "model error of one averaged reading).")
@click.option("--evaluate", is_flag=True,
              help="With a bench survey's truth: tension errors of the nominal and the "
                   "identified targets (runs the table generator twice).")
@click.option("--json", "as_json", is_flag=True, help="Print the result as JSON.")
def fit_cmd(robot, survey, out, no_write, plot_dir, no_weights, sigma_uT, evaluate, as_json):
    """Fit ROBOT.toml to a survey file and write the identified TOML.

    Exits 1, writing nothing, when the fit is refused: it did not converge,
    a parameter left its plausible range, or the model cannot explain the
    data (the reason is printed).
    """
    import numpy as np

    from hallhome.cli import _load
    from hallhome.identify import fit
    from hallhome.identify_data import IdentifyError, Survey, load_survey
    from hallhome.identify_eval import fit_vs_truth, tension_errors, truth_values
    from hallhome.identify_out import plot_parameters, plot_residuals, write_identified

    nominal = _load(robot)
    try:
        sv = load_survey(survey, nominal)
    except IdentifyError as exc:
        raise click.ClickException(str(exc)) from None
    if no_weights:
        sv = Survey(sv.pulls, (), sv.truth, sv.source, sv.meta)
    n_par = 1 + 2 * len(nominal.segments) + 1 + 3 * len(nominal.sensors) + len(sv.pulls)
    say = (lambda m: click.echo(m, err=True)) if as_json else click.echo
    say(f"survey {survey}: {len(sv.pulls)} pulls, {len(sv.weights)} weight records "
        f"(source {sv.source}); fitting about {n_par} parameters ...")
    t0 = time.monotonic()
    try:
        res = fit(nominal, sv, sigma_uT=sigma_uT)
    except IdentifyError as exc:
        raise click.ClickException(str(exc)) from None
    say(f"fit done in {time.monotonic() - t0:.1f} s: residual {res.rms_uT:.2f} uT rms "
        f"({res.signal_uT:.0f} uT rms of signal), reduced chi-square {res.chi2_red:.2f}")
    rows = fit_vs_truth(res, nominal, sv)
    result = {"robot": nominal.name, "survey": str(survey), "refused": res.refused,
              "rms_uT": res.rms_uT, "signal_uT": res.signal_uT, "chi2_red": res.chi2_red,
              "tendon_rms_uT": res.tendon_rms_uT, "weight_rms_uT": res.weight_rms_uT,
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
    if res.refused:
        click.echo(f"refused: {res.refused}", err=True)
        sys.exit(1)
