"""The `hallhome` command. Each subcommand lives in its own module and is
registered here with `main.add_command`."""

import sys
import time
from pathlib import Path

import click

from hallhome import __version__


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="hallhome")
def main() -> None:
    """hallhome: tension calibration for tendon-driven continuum robots.

    Host side of the hallhome calibrator: robot descriptions, the static and
    magnetic models, the lookup-table generator and the serial client for the
    Arduino Mega firmware.
    """


def _load(path):
    from hallhome.robot import RobotError, load_robot
    try:
        return load_robot(path)
    except RobotError as exc:
        raise click.ClickException("invalid robot description:\n" + str(exc)) from None


@main.command("check")
@click.argument("robots", nargs=-1, required=True, type=click.Path(exists=True, dir_okay=False))
def check_cmd(robots):
    """Validate robot descriptions (TOML) and print a summary of each.

    Fails (exit 1) on an invalid file and on what the firmware cannot use
    without running the model: more sensors or tendons than it supports, a
    name longer than it holds, values implausible for their unit. `hallhome
    tables` checks the rest (saturation, clearance, signal to noise).
    """
    from hallhome.usable import firmware_limits, robot_refusals

    limits = firmware_limits()
    refused = []
    for path in robots:
        r = _load(path)
        seg = ", ".join(f"{s.length * 1e3:g} mm" for s in r.segments)
        click.echo(f"{r.name}: {len(r.segments)} segments ({seg}), {len(r.tendons)} tendons, "
                   f"{len(r.sensors)} sensors, gravity "
                   f"{'none' if r.gravity is None else [round(g, 3) for g in r.gravity]}")
        refused += robot_refusals(r, limits)
    if refused:
        raise click.ClickException("the firmware cannot use this design:\n"
                                   + "\n".join(f"  {m}" for m in refused))


@main.command("tables")
@click.argument("robots", nargs=-1, type=click.Path(exists=True, dir_okay=False))
@click.option("--all", "all_robots", is_flag=True,
              help="Every robot in lookup_tables/robots/.")
@click.option("--out-dir", type=click.Path(file_okay=False), default=None,
              help="Where to write <robot>.c and <robot>.json "
                   "(default lookup_tables/generated).")
@click.option("--learned", "learned", multiple=True,
              type=click.Path(exists=True, dir_okay=False),
              help="Learned targets exported by `hallhome learn` (learned_<robot>.json) to "
                   "compile in instead of the model's, for one robot TOML; repeatable, applied "
                   "in order. Writes <robot>_learned.c (symbol tbl_table_<robot>_learned, "
                   "`make firmware ROBOT=<robot>_learned`) and <robot>_learned.json; the "
                   "model's <robot>.c is left alone.")
@click.option("--quiet", "-q", is_flag=True, help="Print only warnings and errors.")
@click.option("--force", is_flag=True,
              help="Write the table even when the firmware cannot use the design (the "
                   "reasons become warnings, kept in the JSON).")
def tables_cmd(robots, all_robots, out_dir, learned, quiet, force):
    """Generate the C lookup table and its JSON twin for each robot TOML.

    For every tendon alone, the Cosserat model gives the tip pose at each grid
    tension and the magnet model the field at every sensor; the table holds
    the target |B(p_T) - B(p_0)| of the most sensitive sensor, the absolute
    targets, and the expected take-up travel. Output is byte-identical on
    every run.

    Exits 1, writing nothing, when the firmware cannot use a design (unless
    --force): a sensor that saturates, a sensor inside the robot or within
    the volume it sweeps, more sensors or tendons than the firmware supports,
    a target below 10 x the sensing noise, a value implausible for its unit,
    a name longer than the firmware holds. Each reason names the file, the
    key and the limit (docs/tables.md). A successful run prints, per tendon,
    the selected sensor, the target at the default tension and its
    signal-to-noise ratio.
    """
    from rich.console import Console
    from rich.progress import Progress

    from hallhome.paths import GENERATED_DIR
    from hallhome.robot import RobotError, robot_files
    from hallhome.tablegen import TableError, generate
    from hallhome.usable import FirmwareLimitError, UnusableRobot, summarise, tendon_summary

    paths = [Path(p) for p in robots]
    if all_robots:
        paths += robot_files()
    if not paths:
        raise click.UsageError("name at least one robot TOML, or --all")
    if learned and len(paths) != 1:
        raise click.UsageError("--learned applies to exactly one robot TOML")
    out = Path(out_dir) if out_dir else GENERATED_DIR
    err = Console(stderr=True, highlight=False)
    for path in paths:
        t0 = time.perf_counter()
        try:
            with Progress(console=err, transient=True, disable=quiet) as prog:
                task = prog.add_task(f"{path.stem}", total=None)

                def step(n, _task=task):
                    prog.update(_task, completed=n)
                gen = generate(path, out, progress=step, learned=learned, force=force)
        except RobotError as exc:
            raise click.ClickException("invalid robot description:\n" + str(exc)) from None
        except UnusableRobot as exc:
            lines = summarise(exc.problems, shown=3)
            raise click.ClickException(
                f"{path}: the firmware cannot use this design ({len(exc.problems)} "
                f"problem(s)); nothing written (--force writes it anyway):\n"
                + "\n".join(f"  {m}" for m in lines)) from None
        except (TableError, FirmwareLimitError) as exc:
            raise click.ClickException(str(exc)) from None
        warnings = gen.result.warnings
        if warnings:
            click.echo(f"{gen.robot.name}: {len(warnings)} warning(s), all listed in "
                       f"{gen.json_path} (\"warnings\"):", err=True)
            for w in summarise(warnings):
                click.echo(f"  warning: {w}", err=True)
        if not quiet:
            extra = ""
            if gen.learned is not None:
                extra = (f", {sum(f.count for f in gen.learned.files)} learned target(s) over "
                         f"the model table 0x{gen.learned.model_table_id:08X}")
            click.echo(f"{gen.robot.name}: wrote {gen.c_path} and {gen.json_path.name} "
                       f"(table_id 0x{gen.table['table_id']:08X}{extra}, "
                       f"{time.perf_counter() - t0:.2f} s)")
            for line in tendon_summary(gen.result):
                click.echo(line)


@main.command("solve")
@click.argument("robot", type=click.Path(exists=True, dir_okay=False))
@click.argument("tensions", nargs=-1, type=float, required=True)
@click.option("--model", type=click.Choice(["cosserat", "cc"]), default="cosserat",
              show_default=True, help="Cosserat rod or constant curvature.")
@click.option("--no-gravity", is_flag=True, help="Ignore the robot's gravity entry.")
def solve_cmd(robot, tensions, model, no_gravity):
    """Solve the static model for TENSIONS (N, one per tendon, in file order):
    print the tip position, orientation and tendon displacements."""
    import numpy as np

    from hallhome.model import ConstantCurvatureModel, CosseratModel, ModelError

    r = _load(robot)
    if len(tensions) != len(r.tendons):
        raise click.UsageError(f"{r.name} has {len(r.tendons)} tendons, got {len(tensions)} "
                               f"tensions")
    m = (ConstantCurvatureModel(r) if model == "cc"
         else CosseratModel(r, gravity=not no_gravity))
    try:
        sol = m.solve(np.array(tensions))
    except (ModelError, ValueError) as exc:
        raise click.ClickException(str(exc)) from None
    p = sol.tip_position * 1e3
    z = sol.tip_rotation[:, 2]
    click.echo(f"tip position mm: {p[0]:.4f} {p[1]:.4f} {p[2]:.4f}")
    click.echo(f"tip z axis:      {z[0]:.6f} {z[1]:.6f} {z[2]:.6f}")
    click.echo("tendon displacement mm (geometric, + = shorter): "
               + " ".join(f"{d * 1e3:.4f}" for d in sol.displacements))
    click.echo("tendon take-up mm (geometric + stretch):           "
               + " ".join(f"{d * 1e3:.4f}" for d in sol.take_up))


RMS_LIMIT = 0.10  # largest rms relative error of a magnet model that explains the data


def write_polarization(path: Path, polarization) -> None:
    """Rewrites `polarization_T = [...]` of the [magnet] table in a robot
    TOML in place (comments and layout kept), then checks the file still
    loads; restores it otherwise."""
    import re

    from hallhome.robot import RobotError, load_robot
    text = path.read_text(encoding="utf-8")
    sec = re.search(r"^\[magnet\][^\n]*\n(.*?)(?=^\[|\Z)", text, re.S | re.M)
    if sec is None:
        raise click.ClickException(f"{path}: no [magnet] table to write the fit into")
    body = sec.group(1)
    vec = "[" + ", ".join(f"{v:.4f}" for v in polarization) + "]"
    new_body, n = re.subn(r"^(polarization_T\s*=\s*)\[[^\]]*\]", lambda m: m.group(1) + vec, body,
                          count=1, flags=re.M)
    if n != 1:
        raise click.ClickException(f"{path}: no polarization_T line in [magnet] to rewrite")
    path.write_text(text[:sec.start(1)] + new_body + text[sec.end(1):], encoding="utf-8")
    try:
        load_robot(path)
    except RobotError as exc:
        path.write_text(text, encoding="utf-8")
        raise click.ClickException(f"{path}: the fitted polarization is not valid there, file "
                                   f"left unchanged:\n{exc}") from None


@main.command("characterize")
@click.argument("data", type=click.Path(exists=True, dir_okay=False))
@click.option("--plot", "plot_path", type=click.Path(dir_okay=False), default=None,
              help="PNG to write (default: <data>_fit.png beside the data): linear and log-log.")
@click.option("--robot", type=click.Path(exists=True, dir_okay=False), default=None,
              help="Also fit the magnetization of this robot's magnet model to the data.")
@click.option("--axis", type=click.Choice(["equatorial", "axial"]), default="equatorial",
              show_default=True,
              help="Where the sensor sat relative to the magnet during the measurement.")
@click.option("--write", "write_back", is_flag=True,
              help="With --robot: write the fitted polarization into the robot TOML's [magnet] "
                   "polarization_T (direction kept), when the model explains the data.")
def characterize_cmd(data, plot_path, robot, axis, write_back):
    """Fit Field = a * distance^b to measured (distance, field) pairs (the
    paper's Fig. 1), print a, b and R^2 and save a plot (linear and log-log
    axes). The CSV header names the units, e.g. 'distance_cm,field_uT'; '#'
    lines are comments. With --robot, exits 1 when the robot's magnet model
    cannot explain the data (polarization at its physical limit, or rms
    error above 10 %)."""
    import numpy as np

    from hallhome.field import fit_magnetization, fit_power_law, read_field_csv
    from hallhome.plots import plot_characterization

    if write_back and not robot:
        raise click.UsageError("--write needs --robot (the TOML to write into)")
    try:
        d = read_field_csv(data)
        fit = fit_power_law(d.distance, d.field)
    except ValueError as exc:
        raise click.ClickException(str(exc)) from None
    click.echo(f"power law: field_{d.field_unit} = a * distance_{d.distance_unit}^b")
    click.echo(f"a = {fit.a:.2f}")
    click.echo(f"b = {fit.b:.4f}")
    click.echo(f"R^2 = {fit.r2:.5f} ({fit.n} points)")
    mfit = None
    contradicts = False
    if robot:
        r = _load(robot)
        try:
            mfit = fit_magnetization(r.magnet, d.distance_m, d.field_T, axis=axis)
        except ValueError as exc:
            raise click.ClickException(str(exc)) from None
        click.echo(f"magnet model ({r.magnet.shape}, {axis}): polarization |J| = "
                   f"{mfit.polarization:.4f} T, distance offset {mfit.offset * 1e3:+.2f} mm, "
                   f"rms error {mfit.rms_rel * 100:.1f} %")
        contradicts = mfit.at_bound or mfit.rms_rel > RMS_LIMIT
    out = Path(plot_path) if plot_path else Path(data).with_name(Path(data).stem + "_fit.png")
    plot_characterization(d, fit, out, magnet=(r.magnet if robot else None), magnet_fit=mfit,
                          axis=axis)
    click.echo(f"plot: {out}")
    if contradicts:
        click.echo(f"error: the magnet model of {Path(robot).name} does not explain these data "
                   f"(polarization at its physical limit or rms error above {RMS_LIMIT:.0%}); "
                   "check the magnet's dimensions, the distance reference, the axis and the units"
                   + ("; nothing written" if write_back else ""), err=True)
        sys.exit(1)
    if write_back:
        j = np.array(r.magnet.polarization, float)
        new = j / np.linalg.norm(j) * mfit.polarization
        write_polarization(Path(robot), new)
        click.echo(f"wrote polarization_T = [{', '.join(f'{v:.4f}' for v in new)}] into {robot}; "
                   "regenerate its table (`make tables`)")


@main.command("plot")
@click.argument("robot", type=click.Path(exists=True, dir_okay=False))
@click.option("--out-dir", type=click.Path(file_okay=False), default=".", show_default=True,
              help="Directory for the PNG files.")
def plot_cmd(robot, out_dir):
    """Plot tip paths with the sensors, |dB| against tension and tendon
    displacement against tension for every tendon (PNG, headless)."""
    from hallhome.plots import plot_robot
    from hallhome.tablegen import TableError, compute

    r = _load(robot)
    try:
        res = compute(r)
    except TableError as exc:
        raise click.ClickException(str(exc)) from None
    for path in plot_robot(res, Path(out_dir)):
        click.echo(f"wrote {path}")


@main.command("bench")
@click.argument("robot", type=click.Path(exists=True, dir_okay=False),
                required=False)
@click.option("--repeat", default=5, show_default=True, help="Solves to time.")
@click.option("--check", is_flag=True,
              help="Exit 1 if a solve exceeds 50 ms or table generation 5 s.")
def bench_cmd(robot, repeat, check):
    """Time one Cosserat solve and a full table generation (default robot:
    paper_2seg)."""
    import tempfile

    import numpy as np

    from hallhome.model import CosseratModel
    from hallhome.paths import ROBOTS_DIR
    from hallhome.tablegen import generate

    path = Path(robot) if robot else ROBOTS_DIR / "paper_2seg.toml"
    r = _load(path)
    m = CosseratModel(r, steps_per_segment=8)
    tau = np.zeros(len(r.tendons))
    tau[-1] = r.default_tension
    m.solve(tau)
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        m.solve(tau)
        times.append(time.perf_counter() - t0)
    solve_ms = min(times) * 1e3
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        generate(path, tmp)
        table_s = time.perf_counter() - t0
    click.echo(f"{r.name}: Cosserat solve {solve_ms:.1f} ms (best of {repeat}, median "
               f"{sorted(times)[len(times) // 2] * 1e3:.1f} ms); table generation "
               f"{table_s:.2f} s")
    if check and (solve_ms > 50 or table_s > 5):
        click.echo("over budget (50 ms per solve, 5 s per table)", err=True)
        sys.exit(1)


@main.command("plant-config")
@click.argument("robot", type=click.Path(exists=True, dir_okay=False))
@click.argument("out", type=click.Path(dir_okay=False))
@click.option("--seed", type=int, default=None,
              help="Seed of the parameter perturbation (reproducible robots).")
@click.option("--perturb", type=click.FloatRange(0.0, 0.5), default=0.0, show_default=True,
              help="Relative spread of the perturbed physical parameters (0 = nominal).")
def plant_config_cmd(robot, out, seed, perturb):
    """Write the virtual bench's plant config (sim/plant/README.md) for a robot TOML.

    The plant is the bench's physics model of the robot; it deliberately
    differs from the host's Cosserat model, so model error is real.
    """
    from hallhome.plantcfg import PlantConfigError, write_plant_config

    try:
        path = write_plant_config(_load(robot), out, seed=seed, perturb=perturb)
    except PlantConfigError as exc:
        raise click.ClickException(f"{robot}: {exc}") from None
    click.echo(f"wrote {path}")


from hallhome.operator import register as _register_operator  # noqa: E402
_register_operator(main)

from hallhome.identify_cli import identify_group  # noqa: E402
from hallhome.op_install import install_cmd  # noqa: E402
from hallhome.op_survey import survey_cmd  # noqa: E402
identify_group.add_command(install_cmd)
identify_group.add_command(survey_cmd)
main.add_command(identify_group)
