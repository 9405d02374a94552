"""Magnetic field model: the tip magnet (magpylib) seen by the sensors, and
the paper's power-law characterisation of field against distance.

All quantities in SI units (m, T) unless a name says otherwise.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path

import magpylib as magpy
import numpy as np
from scipy import optimize
from scipy.spatial.transform import Rotation

from hallhome.robot import Magnet, Robot

# The paper's Fig. 1 fit, averaged over its three sensors: Field = A * d^B.
# The paper gives no units; with d in cm and the field in uT the curve matches
# a 3.5 mm magnet's near field (about 2900 uT at 1 cm), so those are assumed.
# No permanent magnet exceeds this polarization (NdFeB Br is at most ~1.5 T).
J_MAX = 2.0

PAPER_POWER_LAW = ((2920.5 + 2923.9 + 2927.2) / 3.0, -1.583)


def magnet_source(magnet: Magnet) -> magpy.magnet.Magnet:
    """A magpylib magnet of ``magnet``'s shape and polarization, at the origin
    with the identity orientation (its own frame)."""
    if magnet.shape == "cylinder":
        return magpy.magnet.Cylinder(polarization=magnet.polarization,
                                     dimension=magnet.dimensions)
    if magnet.shape == "cuboid":
        return magpy.magnet.Cuboid(polarization=magnet.polarization, dimension=magnet.dimensions)
    if magnet.shape == "sphere":
        return magpy.magnet.Sphere(polarization=magnet.polarization,
                                   diameter=magnet.dimensions[0])
    raise ValueError(f"magnet shape {magnet.shape!r}: expected cylinder, cuboid or sphere")


def magnet_poses(robot: Robot, tip_positions: np.ndarray, tip_rotations: np.ndarray):
    """Magnet centres (n,3) and orientations (n,3,3) in the base frame for
    tip frames (n,3) / (n,3,3): the magnet moves and turns with the tip."""
    p = np.asarray(tip_positions, float).reshape(-1, 3)
    R = np.asarray(tip_rotations, float).reshape(-1, 3, 3)
    off = np.array(robot.magnet.offset)
    rm = np.array(robot.magnet.rotation)
    return p + R @ off, R @ rm


def field_at_sensors(robot: Robot, tip_positions: np.ndarray,
                     tip_rotations: np.ndarray) -> np.ndarray:
    """The magnet's field at every sensor for each tip pose, in each sensor's
    own frame: array (n_poses, n_sensors, 3), tesla. Earth's and other
    ambient fields are not included (the delta mode cancels them)."""
    pos, rot = magnet_poses(robot, tip_positions, tip_rotations)
    src = magnet_source(robot.magnet)
    n = pos.shape[0]
    src.position = pos
    src.orientation = Rotation.from_matrix(rot)
    obs = np.array([s.position for s in robot.sensors])
    # getB with squeeze=False: (sources, path, observer groups, observers, 3)
    B = np.asarray(magpy.getB(src, obs, squeeze=False)).reshape(n, len(obs), 3)
    sr = np.array([s.rotation for s in robot.sensors])  # (m,3,3), sensor -> base
    return np.einsum("mji,nmj->nmi", sr, B)


def field_magnitude_at(magnet: Magnet, distances: np.ndarray, axis: str = "equatorial"):
    """|B| (T) of ``magnet`` alone at ``distances`` (m) from its centre, along
    its own z axis (``axis="axial"``) or x axis (``"equatorial"``)."""
    d = np.asarray(distances, float)
    direction = {"axial": (0.0, 0.0, 1.0), "equatorial": (1.0, 0.0, 0.0)}[axis]
    src = magnet_source(magnet)
    B = np.asarray(src.getB(d[:, None] * np.array(direction))).reshape(-1, 3)
    return np.linalg.norm(B, axis=1)


# --- characterisation ----------------------------------------------------------

@dataclass(frozen=True)
class PowerLawFit:
    """Field = a * distance^b fitted by least squares on log-log data;
    ``r2`` is the coefficient of determination of the fitted curve on the
    field values themselves (not their logarithms)."""

    a: float
    b: float
    r2: float
    n: int

    def __call__(self, d):
        return self.a * np.asarray(d, float) ** self.b


def fit_power_law(distance, field) -> PowerLawFit:
    """Fit Field = a * distance^b (units of the inputs). Needs at least three
    points, all positive; raises ValueError otherwise."""
    d = np.asarray(distance, float)
    f = np.asarray(field, float)
    if d.shape != f.shape or d.ndim != 1 or d.size < 3:
        raise ValueError(f"need at least 3 (distance, field) pairs, got {d.size}")
    if np.any(d <= 0) or np.any(f <= 0):
        raise ValueError("distances and field values must be positive for a power-law fit")
    b, log_a = np.polyfit(np.log(d), np.log(f), 1)
    a = math.exp(log_a)
    pred = a * d**b
    ss_res = float(np.sum((f - pred) ** 2))
    ss_tot = float(np.sum((f - f.mean()) ** 2))
    r2 = 1.0 - ss_res / ss_tot if ss_tot > 0 else 1.0
    return PowerLawFit(a=a, b=float(b), r2=r2, n=int(d.size))


@dataclass(frozen=True)
class MagnetFit:
    """Polarization |J| (T) of the magnet model that best explains measured
    (distance, |B|) pairs, with a distance offset (m, added to the nominal
    distances: the sensor die sits below the board surface) and the rms
    relative error of the fit."""

    polarization: float
    offset: float
    rms_rel: float
    at_bound: bool = False  # |J| hit the physical limit J_MAX: the model cannot explain the data


def fit_magnetization(magnet: Magnet, distances_m, field_T, axis: str = "equatorial",
                      fit_offset: bool = True) -> MagnetFit:
    """Fit the magpylib magnet's polarization magnitude (direction kept) and,
    optionally, a distance offset to measured fields, minimising relative
    (log) errors."""
    d = np.asarray(distances_m, float)
    f = np.asarray(field_T, float)
    if d.size < 2 or np.any(f <= 0) or np.any(d <= 0):
        raise ValueError("need at least 2 positive (distance, field) pairs")
    j0 = float(np.linalg.norm(magnet.polarization))
    unit = Magnet(magnet.shape, magnet.dimensions,
                  tuple(x / j0 for x in magnet.polarization), magnet.offset, magnet.rotation,
                  magnet.mass)

    def resid(x):
        off = x[1] if fit_offset else 0.0
        model = x[0] * field_magnitude_at(unit, d + off, axis)
        return np.log(model) - np.log(f)

    lo_off = -0.9 * float(d.min())
    x0 = [j0, 0.0] if fit_offset else [j0]
    bounds = ([1e-3, lo_off], [J_MAX, 0.05]) if fit_offset else ([1e-3], [J_MAX])
    sol = optimize.least_squares(resid, x0, bounds=bounds, x_scale=[1.0, 1e-3][: len(x0)])
    r = resid(sol.x)
    return MagnetFit(polarization=float(sol.x[0]),
                     offset=float(sol.x[1]) if fit_offset else 0.0,
                     rms_rel=float(np.sqrt(np.mean(np.expm1(r) ** 2))),
                     at_bound=bool(sol.x[0] >= J_MAX * 0.999))


_DIST_UNITS = {"distance_mm": 1e-3, "distance_cm": 1e-2, "distance_m": 1.0}
_FIELD_UNITS = {"field_uT": 1e-6, "field_mT": 1e-3, "field_T": 1.0}


@dataclass(frozen=True)
class FieldData:
    """Measured pairs as read from a CSV file, in the file's own units."""

    distance: np.ndarray
    field: np.ndarray
    distance_unit: str  # "mm", "cm" or "m"
    field_unit: str  # "uT", "mT" or "T"

    @property
    def distance_m(self) -> np.ndarray:
        return self.distance * _DIST_UNITS["distance_" + self.distance_unit]

    @property
    def field_T(self) -> np.ndarray:
        return self.field * _FIELD_UNITS["field_" + self.field_unit]


def read_field_csv(path: str | Path) -> FieldData:
    """Read (distance, field) pairs. Lines starting with '#' are comments;
    the header names the units: distance_mm|distance_cm|distance_m and
    field_uT|field_mT|field_T. Raises ValueError naming the file and line."""
    path = Path(path)
    rows = [ln for ln in path.read_text(encoding="utf-8").splitlines()
            if ln.strip() and not ln.lstrip().startswith("#")]
    if not rows:
        raise ValueError(f"{path.name}: no data (expected a header line and rows)")
    reader = csv.reader(rows)
    header = [h.strip() for h in next(reader)]
    if len(header) != 2 or header[0] not in _DIST_UNITS or header[1] not in _FIELD_UNITS:
        raise ValueError(f"{path.name}: header: expected '<distance_mm|distance_cm|distance_m>,"
                         f"<field_uT|field_mT|field_T>', got {','.join(header)!r}")
    d, f = [], []
    for n, row in enumerate(reader, start=2):
        try:
            if len(row) != 2:
                raise ValueError
            dv, fv = float(row[0]), float(row[1])
        except ValueError:
            raise ValueError(f"{path.name}: data row {n}: expected two numbers, "
                             f"got {','.join(row)!r}") from None
        if not (math.isfinite(dv) and math.isfinite(fv)) or dv <= 0 or fv <= 0:
            raise ValueError(f"{path.name}: data row {n}: expected positive distance and field, "
                             f"got {dv}, {fv}")
        d.append(dv)
        f.append(fv)
    if len(d) < 3:
        raise ValueError(f"{path.name}: expected at least 3 data rows, got {len(d)}")
    return FieldData(np.array(d), np.array(f), header[0].split("_")[1], header[1].split("_")[1])


def synthetic_power_law_data(seed: int = 1, noise: float = 0.01):
    """The shipped example data: the paper's fitted curve (d in cm, field in
    uT) at 1.0 .. 4.0 cm in 0.25 cm steps with ``noise`` relative Gaussian
    noise from a seeded generator. Returns (distance_cm, field_uT)."""
    a, b = PAPER_POWER_LAW
    d = np.round(np.arange(1.0, 4.0001, 0.25), 2)
    rng = np.random.default_rng(seed)
    f = a * d**b * (1.0 + noise * rng.standard_normal(d.size))
    return d, np.round(f, 1)
