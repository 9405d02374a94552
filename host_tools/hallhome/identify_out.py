"""Results of `hallhome identify fit`: the identified TOML and the plots.

The identified description is the original file with the fitted values put
in place, each followed by a comment with its 1-sigma uncertainty and the
nominal value, and a header saying when and from what it was fitted. Every
comment and every value not fitted stays as it was, so the two files diff
cleanly. The file is read back with the ordinary loader before it counts.
"""

from __future__ import annotations

import datetime as _dt
import re
from pathlib import Path

import numpy as np

from hallhome.identify import FitResult
from hallhome.identify_data import IdentifyError
from hallhome.robot import Robot, RobotError, load_robot

_KEY = re.compile(r"^(\s*)([A-Za-z_][A-Za-z0-9_]*)(\s*=\s*)(.*?)(\s*#.*)?$")
_TABLE = re.compile(r"^\s*(\[\[?)\s*([A-Za-z_]+)\s*\]\]?")
# Keys a description may leave out (the loader's default stands): a fitted one
# is added to its table; a fitted required key must be in the original.
_OPTIONAL_KEYS = {"friction_mN"}


def identified_path(robot: Robot) -> Path:
    """Where the identified description goes by default: beside the original,
    ``<name>_id.toml`` (the stem is the robot's name on the board)."""
    return robot.path.with_name(f"{robot.name}_id.toml")


def _vec(v, fmt: str = ".6g") -> str:
    return "[" + ", ".join(f"{x:{fmt}}" for x in v) + "]"


def _edits(res: FitResult) -> dict:
    """{(table, index, key): (new value text, comment)} for every fitted value."""
    rows = {r["name"]: r for r in res.table()}

    def note(*names):
        parts = []
        for n in names:
            r = rows[n]
            prior = "" if r["from_data"] else ", mostly the prior"
            parts.append(f"{r['value']:.4g} +- {r['sigma']:.2g} {r['unit']} "
                         f"(nominal {r['nominal']:.4g}{prior})")
        return "# identified: " + "; ".join(parts)

    fitted = res.robot
    out = {}
    for j, s in enumerate(fitted.segments):
        if f"length_{j + 1}" in rows:
            out[("segments", j, "length_mm")] = (f"{s.length * 1e3:.4f}", note(f"length_{j + 1}"))
        if f"EI_{j + 1}" in rows:
            out[("segments", j, "youngs_modulus_GPa")] = (
                f"{s.youngs_modulus * 1e-9:.4f}",
                note(f"EI_{j + 1}") + ", as E with the TOML's radii")
    for i, t in enumerate(fitted.tendons):
        for name in ("radius", f"radius{i}"):
            if name in rows:
                out[("tendons", i, "routing_radius_mm")] = (f"{t.routing_radius * 1e3:.4f}",
                                                            note(name))
        if f"angle{i}" in rows:
            out[("tendons", i, "routing_angle_deg")] = (
                f"{np.degrees(t.routing_angle):.4f}", note(f"angle{i}"))
        if f"EA{i}" in rows:
            out[("tendons", i, "stiffness_EA_N")] = (
                f"{t.stiffness_ea:.1f}", note(f"EA{i}") + ", effective: with the free length's "
                "error")
        if "friction" in rows:
            # a fit a little below zero (within the noise, see _refusal) is none
            out[("tendons", i, "friction_mN")] = (f"{max(0.0, t.friction_N) * 1e3:.2f}",
                                                  note("friction"))
    out[("magnet", 0, "polarization_T")] = (_vec(fitted.magnet.polarization), note("magnet_J"))
    for k, s in enumerate(fitted.sensors):
        names = [f"sensor{k}_{a}" for a in "xyz"]
        if all(n in rows for n in names):
            out[("sensors", k, "position_mm")] = (_vec(np.array(s.position) * 1e3, ".4f"),
                                                  note(*names).replace("; ", ", "))
    return out


def _walk(src: list[str]):
    """Per line of a TOML text: (line number, line, table, index of the table
    among those of its name, match of a `key = value` line or None)."""
    counts: dict[str, int] = {}
    table, index = None, 0
    for n, line in enumerate(src):
        m = _TABLE.match(line)
        if m:
            table = m.group(2)
            counts[table] = counts.get(table, -1) + 1
            index = counts[table] if m.group(1) == "[[" else 0
        m = _KEY.match(line)
        yield n, line, table, index, (m if m and table is not None else None)


def _key_lines(src: list[str]) -> dict:
    """{(table, index, key): line number} of every key line, and {(table,
    index): line number} of each table's last key line."""
    out: dict = {}
    for n, _, table, index, m in _walk(src):
        if m:
            out[(table, index, m.group(2))] = n
            out[(table, index)] = n
    return out


def render_identified(res: FitResult, nominal: Robot, survey_name: str, when=None) -> str:
    """The identified TOML text (see the module docstring)."""
    when = when or _dt.datetime.now(_dt.timezone.utc)
    edits = _edits(res)
    src = nominal.path.read_text().splitlines()
    where = _key_lines(src)
    # a fitted optional key the original leaves out (a tendon without
    # friction_mN) is written after the last key of its table
    extra: dict[int, list[str]] = {}
    for (t, i, k), (val, com) in sorted(edits.items()):
        if k in _OPTIONAL_KEYS and (t, i, k) not in where and (t, i) in where:
            extra.setdefault(where[(t, i)], []).append(f"{k} = {val}   {com}")
    done = set()
    lines = []
    for n, line, table, index, m in _walk(src):
        if m and (table, index, m.group(2)) in edits:
            val, com = edits[(table, index, m.group(2))]
            line = f"{m.group(1)}{m.group(2)}{m.group(3)}{val}   {com}"
            done.add((table, index, m.group(2)))
        lines.append(line)
        for add in extra.get(n, []):
            lines.append(add)
            done.add((table, index, add.split(" ", 1)[0]))
    missing = set(edits) - done
    if missing:
        raise IdentifyError(f"{nominal.path}: cannot place the fitted "
                            + ", ".join(f"{t}[{i + 1}].{k}" for t, i, k in sorted(missing))
                            + " (write the key out in the original first)")
    kept = ["EI (no weights, nominal)"] if not res.stiffness else []
    head = [
        f"# Identified {when:%Y-%m-%d %H:%M} UTC by `hallhome identify fit` from {survey_name},",
        f"# fitted against {nominal.path.name}: {len(res.tendon_rms_uT)} pulls, "
        f"{len(res.weight_rms_uT)} weight records, residual {res.rms_uT:.2f} uT rms over "
        f"{res.n_data} values",
        f"# ({res.signal_uT:.0f} uT rms of signal). Each fitted value is followed by its 1-sigma",
        "# uncertainty and the nominal value"
        + (f"; kept from the original: {', '.join(kept)}." if kept else "."),
        "",
    ]
    return "\n".join(head + lines) + "\n"


def write_identified(res: FitResult, nominal: Robot, survey_name: str,
                     out: Path | None = None) -> tuple[Path, Robot]:
    """Writes the identified TOML (default ``identified_path``) and reads it
    back; returns the path and the loaded robot. Raises IdentifyError when
    the fit was refused or the file does not load as the fit says."""
    if res.refused:
        raise IdentifyError(f"not written: the fit was refused ({res.refused})")
    out = Path(out) if out else identified_path(nominal)
    if out.resolve() == nominal.path.resolve():
        raise IdentifyError(f"{out}: refusing to overwrite the original description")
    text = render_identified(res, nominal, survey_name)
    out.write_text(text)
    try:
        back = load_robot(out)
    except RobotError as exc:
        raise IdentifyError(f"{out}: the identified description does not load:\n{exc}") from None
    fitted = res.robot
    checks = [(b.length, f.length) for b, f in zip(back.segments, fitted.segments)]
    checks += [(b.bending_stiffness, f.bending_stiffness)
               for b, f in zip(back.segments, fitted.segments)]
    checks += [(np.linalg.norm(back.magnet.polarization),
                np.linalg.norm(fitted.magnet.polarization))]
    checks += [(b.routing_radius, f.routing_radius) for b, f in zip(back.tendons, fitted.tendons)]
    checks += [(b.stiffness_ea, f.stiffness_ea) for b, f in zip(back.tendons, fitted.tendons)]
    angles = [(b.routing_angle, f.routing_angle) for b, f in zip(back.tendons, fitted.tendons)]
    if (any(abs(a - b) > 1e-3 * abs(b) for a, b in checks)
            or any(abs(a - b) > 1e-5 for a, b in angles)):
        raise IdentifyError(f"{out}: read back, the values differ from the fit")
    return out, back


def plot_residuals(res: FitResult, path: Path) -> Path:
    """Per tendon: measured and modelled |dB| at every sensor against the
    take-up, and the residual (model - measured, vector norm)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = len(res.curves)
    fig, axes = plt.subplots(n, 2, figsize=(10, 2.2 * n), squeeze=False)
    for row, (i, (take, data, pred, eng)) in zip(axes, sorted(res.curves.items())):
        x = take * 1e3
        for k in range(data.shape[1]):
            line, = row[0].plot(x, np.linalg.norm(pred[:, k], axis=-1) * 1e6, lw=1.2,
                                label=f"model, sensor {k}")
            row[0].plot(x, np.linalg.norm(data[:, k], axis=-1) * 1e6, ".", ms=2.5,
                        color=line.get_color(), label="measured (dots)" if k == 0 else None)
            row[1].plot(x, np.linalg.norm(pred[:, k] - data[:, k], axis=-1) * 1e6, lw=0.8,
                        color=line.get_color())
        for ax in row:
            ax.axvline(eng * 1e3, color="0.6", ls=":", lw=0.8)
        row[0].set_ylabel(f"tendon {i}\n|dB| (uT)")
        row[1].set_ylabel(f"residual (uT)\nrms {res.tendon_rms_uT[i]:.2f}")
    axes[0][0].legend(fontsize=7)
    axes[-1][0].set_xlabel("take-up past the first step (mm); dotted: fitted engagement")
    axes[-1][1].set_xlabel("take-up (mm)")
    fig.suptitle(f"identify fit of {res.robot.name}: residual {res.rms_uT:.2f} uT rms"
                 + (f" (REFUSED: {res.refused})" if res.refused else ""), fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot_parameters(res: FitResult, path: Path, truth: dict | None = None) -> Path:
    """Fitted against nominal with 1-sigma bars: relative change of the
    magnet, lengths, radius and stiffness; shifts of the sensors in mm; turns
    of the tendons' routing angles in degrees.
    ``truth`` (bench surveys) adds the true values as crosses."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = [r for r in res.table() if not r["name"].startswith("engage")]
    rel = [r for r in rows if not r["name"].startswith(("sensor", "angle"))]
    sen = [r for r in rows if r["name"].startswith("sensor")]
    ang = [r for r in rows if r["name"].startswith("angle")]
    panels = [(rr, fn, unit) for rr, fn, unit in (
        (rel, lambda r, v: 100 * (v / r["nominal"] - 1), "%"),
        (sen, lambda r, v: v - r["nominal"], "mm"),
        (ang, lambda r, v: v - r["nominal"], "deg")) if rr]
    fig, axs = plt.subplots(1, len(panels), squeeze=False,
                            figsize=(5 * len(panels), 0.35 * max(len(p[0]) for p in panels) + 1.5))
    for ax, (rr, fn, unit) in zip(axs[0], panels):
        y = np.arange(len(rr))
        ax.errorbar([fn(r, r["value"]) for r in rr], y,
                    xerr=[abs(fn(r, r["value"] + r["sigma"]) - fn(r, r["value"])) for r in rr],
                    fmt="o", ms=4, capsize=2, label="fitted, 1 sigma")
        if truth:
            t = [(fn(r, truth[r["name"]]), k) for k, r in enumerate(rr) if r["name"] in truth]
            if t:
                ax.plot([a for a, _ in t], [b for _, b in t], "x", color="C3", label="true")
        ax.axvline(0, color="0.5", lw=0.8)
        ax.set_yticks(y, [r["name"] for r in rr], fontsize=8)
        ax.set_xlabel(f"fitted - nominal ({unit})")
        ax.invert_yaxis()
    axs[0][0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
