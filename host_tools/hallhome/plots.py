"""Headless PNG plots of the model results and of a field characterisation."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from hallhome.field import field_magnitude_at, magnet_poses  # noqa: E402

# Fixed metadata so a re-run writes the same bytes.
_PNG_META = {"Software": None}


def _save(fig, path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110, metadata=_PNG_META)
    plt.close(fig)
    return path


def plot_robot(res, out_dir: Path) -> list[Path]:
    """Three PNGs for a computed robot (tablegen.RobotResult):
    <robot>_tip_paths.png, <robot>_delta_b.png, <robot>_displacement.png."""
    robot = res.robot
    grid = np.array(robot.tension_grid)
    sensors = np.array([s.position for s in robot.sensors]) * 1e3
    colors = plt.cm.tab10(np.arange(len(robot.tendons)) % 10)
    out = []

    fig, (ax_xy, ax_xz) = plt.subplots(1, 2, figsize=(11, 5))
    for tr, t, c in zip(res.tendons, robot.tendons, colors):
        tips = np.array([s.tip_position for s in tr.solutions]) * 1e3
        mag, _ = magnet_poses(robot, tips * 1e-3, np.array([s.tip_rotation for s in tr.solutions]))
        mag *= 1e3
        label = f"tendon {t.index} (seg {t.segment}, servo {t.servo_id})"
        ax_xy.plot(mag[:, 0], mag[:, 1], "-o", ms=3, color=c, label=label)
        ax_xz.plot(mag[:, 0], mag[:, 2], "-o", ms=3, color=c)
        shape = tr.solutions[-1].positions * 1e3
        ax_xz.plot(shape[:, 0], shape[:, 2], color=c, lw=0.8, alpha=0.6)
    straight = res.straight.positions * 1e3
    ax_xz.plot(straight[:, 0], straight[:, 2], "k-", lw=1.0, label="straight")
    for k, p in enumerate(sensors):
        for ax, (i, j) in ((ax_xy, (0, 1)), (ax_xz, (0, 2))):
            ax.plot(p[i], p[j], "ks", ms=8, mfc="none")
            ax.annotate(f"S{k}", (p[i], p[j]), textcoords="offset points", xytext=(5, 5))
    ax_xy.set(xlabel="x (mm)", ylabel="y (mm)", title="magnet path over the grid, top view")
    ax_xz.set(xlabel="x (mm)", ylabel="z (mm)", title="side view, shapes at the top tension")
    ax_xy.set_aspect("equal", "datalim")
    ax_xz.set_aspect("equal", "datalim")
    ax_xy.legend(fontsize=7)
    fig.suptitle(f"{robot.name}: tip paths, one tendon at a time (squares: sensors)")
    fig.tight_layout()
    out.append(_save(fig, out_dir / f"{robot.name}_tip_paths.png"))

    fig, ax = plt.subplots(figsize=(7, 5))
    for tr, t, c in zip(res.tendons, robot.tendons, colors):
        ax.plot(grid, tr.delta[:, tr.selected] * 1e6, "-o", ms=3, color=c,
                label=f"tendon {t.index} on S{tr.selected}")
    ax.axhline(10 * robot.noise * 1e6, color="gray", ls="--", lw=0.8, label="10 x noise")
    ax.axvline(robot.default_tension, color="gray", ls=":", lw=0.8)
    ax.set(xlabel="tension (N)", ylabel="|B(p_T) - B(p_0)| (uT)",
           title=f"{robot.name}: target field change on the selected sensor")
    ax.legend(fontsize=7)
    fig.tight_layout()
    out.append(_save(fig, out_dir / f"{robot.name}_delta_b.png"))

    fig, ax = plt.subplots(figsize=(7, 5))
    for tr, t, c in zip(res.tendons, robot.tendons, colors):
        ax.plot(grid, tr.travel * 1e3, "-o", ms=3, color=c, label=f"tendon {t.index} total")
        ax.plot(grid, tr.geometric * 1e3, ":", color=c, lw=0.8)
    ax.axhline(robot.travel_limit * 1e3, color="red", ls="--", lw=0.8, label="travel limit")
    ax.set(xlabel="tension (N)", ylabel="take-up from engagement (mm)",
           title=f"{robot.name}: tendon displacement (dotted: geometric only)")
    ax.legend(fontsize=7)
    fig.tight_layout()
    out.append(_save(fig, out_dir / f"{robot.name}_displacement.png"))
    return out


def plot_characterization(data, fit, path: Path, magnet=None, magnet_fit=None,
                          axis: str = "equatorial") -> Path:
    """Measured points, the power-law fit and (optionally) the fitted magnet
    model: on linear axes like the paper's Fig. 1B, and on log-log axes,
    where a power law is a straight line and a misfit at any distance shows."""
    fig, axes = plt.subplots(1, 2, figsize=(12, 5))
    d = np.linspace(data.distance.min(), data.distance.max(), 200)
    bm = None
    if magnet is not None and magnet_fit is not None:
        from hallhome.robot import Magnet
        j = np.array(magnet.polarization)
        jn = j / np.linalg.norm(j) * magnet_fit.polarization
        m = Magnet(magnet.shape, magnet.dimensions, tuple(jn), magnet.offset, magnet.rotation,
                   magnet.mass)
        scale_d = data.distance_m[0] / data.distance[0]
        scale_f = data.field_T[0] / data.field[0]
        bm = field_magnitude_at(m, d * scale_d + magnet_fit.offset, axis) / scale_f
    for ax, log in zip(axes, (False, True)):
        ax.plot(data.distance, data.field, "o", ms=4, label="measured")
        ax.plot(d, fit(d), "-", label=f"{fit.a:.1f} d^{fit.b:.3f} (R^2 {fit.r2:.4f})")
        if bm is not None:
            ax.plot(d, bm, "--", label=f"magnet model, |J| {magnet_fit.polarization:.3f} T")
        if log:
            ax.set_xscale("log")
            ax.set_yscale("log")
        ax.set(xlabel=f"distance ({data.distance_unit})", ylabel=f"field ({data.field_unit})",
               title="field against distance" + (" (log-log)" if log else ""))
        ax.legend()
    fig.tight_layout()
    return _save(fig, Path(path))
