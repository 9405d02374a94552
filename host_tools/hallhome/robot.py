"""Robot descriptions: load and validate a robot TOML into SI dataclasses.

A robot description lives in ``lookup_tables/robots/<name>.toml``. The file
stem is the robot's name (a C identifier, it names the generated table). Keys
carry their unit in their name (``length_mm``, ``youngs_modulus_GPa``); the
loader converts everything to SI units (m, kg, s, N, Pa, T, rad) so that the
models never see a millimetre. docs/model.md describes every key.

Every problem in a file is reported, each naming the file, the key and what
was expected, e.g. ``paper_2seg.toml: segments[1].length_mm: expected a
positive length in mm, got -53``. ``load_robot`` raises ``RobotError`` with
all of them. Values that are valid but implausible for their unit (a length
in metres where millimetres are expected, a modulus in Pa where GPa are) are
kept in ``Robot.doubts`` with the same naming: the generator refuses such a
robot unless forced (hallhome.usable).
"""

from __future__ import annotations

import math
import re
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

# AK09916 full scale per axis, datasheet section 11.3.4 (+-32752 LSB at 0.15 uT/LSB).
SENSOR_SATURATION_T = 4912e-6
# AK09916 resolution, datasheet section 2 (0.15 uT/LSB).
SENSOR_LSB_T = 0.15e-6
# Density of sintered NdFeB, for the magnet's weight when the TOML gives none.
NDFEB_DENSITY_KG_M3 = 7500.0
STANDARD_GRAVITY = 9.80665
# ICM-20948 I2C addresses (AD0 low / high).
ICM_ADDRESSES = (0x68, 0x69)
MUX_CHANNELS = 8


class RobotError(ValueError):
    """A robot description is invalid. ``problems`` lists every message, each
    of the form ``<file>: <key>: <what was expected>, got <value>``."""

    def __init__(self, problems: list[str]):
        self.problems = list(problems)
        super().__init__("\n".join(self.problems))


@dataclass(frozen=True)
class Segment:
    """One segment of the backbone, numbered from the base (1-based ``number``).

    The backbone is an elastic rod or tube (``outer_radius``, ``inner_radius``;
    ``inner_radius`` 0 for a solid rod) with Young's modulus ``youngs_modulus``
    and Poisson ratio ``poisson_ratio``. ``disks`` spacer disks carry the
    tendons; they are treated as smeared mass (``disk_mass`` each) and as
    continuous routing. All lengths in m, modulus in Pa, masses in kg.
    """

    number: int
    length: float
    disks: int
    youngs_modulus: float
    poisson_ratio: float
    outer_radius: float
    inner_radius: float
    density: float
    disk_mass: float

    @property
    def area(self) -> float:
        """Cross-section area of the backbone, m^2."""
        return math.pi * (self.outer_radius**2 - self.inner_radius**2)

    @property
    def second_moment(self) -> float:
        """Second moment of area about a bending axis, m^4."""
        return math.pi / 4.0 * (self.outer_radius**4 - self.inner_radius**4)

    @property
    def shear_modulus(self) -> float:
        """G = E / (2 (1 + nu)), Pa."""
        return self.youngs_modulus / (2.0 * (1.0 + self.poisson_ratio))

    @property
    def bending_stiffness(self) -> float:
        """EI, N m^2."""
        return self.youngs_modulus * self.second_moment

    @property
    def torsional_stiffness(self) -> float:
        """GJ with J = 2 I (circular section), N m^2."""
        return self.shear_modulus * 2.0 * self.second_moment

    @property
    def axial_stiffness(self) -> float:
        """EA, N."""
        return self.youngs_modulus * self.area

    @property
    def shear_stiffness(self) -> float:
        """GA, N (no shear correction factor; shear is negligible here)."""
        return self.shear_modulus * self.area

    @property
    def linear_density(self) -> float:
        """Mass per length of backbone plus smeared disks, kg/m."""
        return self.density * self.area + self.disks * self.disk_mass / self.length


@dataclass(frozen=True)
class Tendon:
    """One tendon, numbered in file order from 0 (``index``).

    It runs from its spool through the robot base and is fixed at the distal
    end of segment ``segment`` (1-based). In the backbone frame at arc length
    s its offset from the backbone is ``routing_radius`` at angle
    ``routing_angle + twist * s`` (rad, about the backbone's z axis, from its
    x axis); ``twist`` = 0 is straight parallel routing.

    Actuation: servo ``servo_id`` winds the tendon on a spool of radius
    ``spool_radius`` (m); ``ticks_per_rev`` encoder ticks per turn;
    ``pull_dir`` = +1 when increasing position ticks shortens the tendon, -1
    when decreasing does. Elasticity: axial stiffness ``stiffness_ea`` (N) and
    ``free_length`` (m), the tendon length between the robot base and the
    spool. The length that stretches under tension T is the path inside the
    robot plus ``free_length``: stretch = T * (path + free_length) / EA.
    Friction along the path: pulled from slack (a calibration's approach, a
    weight hung from slack), a spool-side tension T reaches the tendon's end
    as T (1 - ``friction_mu``) - ``friction_N`` (``Robot.tip_tension``);
    None where the description does not say (no friction term).
    """

    index: int
    segment: int
    routing_radius: float
    routing_angle: float
    twist: float
    servo_id: int
    pull_dir: int
    spool_radius: float
    ticks_per_rev: int
    stiffness_ea: float
    free_length: float
    friction_N: float | None = None
    friction_mu: float | None = None

    @property
    def metres_per_tick(self) -> float:
        """Tendon take-up per encoder tick, m."""
        return 2.0 * math.pi * self.spool_radius / self.ticks_per_rev

    def offset(self, s: float) -> np.ndarray:
        """Routing offset r(s) in the backbone frame, m (3-vector, z = 0)."""
        a = self.routing_angle + self.twist * s
        return np.array([self.routing_radius * math.cos(a), self.routing_radius * math.sin(a), 0.0])


@dataclass(frozen=True)
class Magnet:
    """The permanent magnet at the robot tip.

    ``shape`` is ``"cylinder"`` (dimensions = (diameter, length), axis along
    the magnet's z), ``"cuboid"`` (dimensions = (a, b, c)) or ``"sphere"``
    (dimensions = (diameter,)); metres. ``polarization`` is the magnetic
    polarization J = mu0 M in the magnet's own frame, tesla (remanence Br for
    an axially magnetised N42 cylinder is about (0, 0, 1.3)). The magnet frame
    is the tip frame translated by ``offset`` (m, tip frame) and rotated by
    ``rotation`` (3x3 matrix, tip frame). ``mass`` in kg.
    """

    shape: str
    dimensions: tuple[float, ...]
    polarization: tuple[float, float, float]
    offset: tuple[float, float, float]
    rotation: tuple[tuple[float, float, float], ...]
    mass: float

    @property
    def volume(self) -> float:
        """Magnet volume, m^3."""
        if self.shape == "cylinder":
            return math.pi * (self.dimensions[0] / 2.0) ** 2 * self.dimensions[1]
        if self.shape == "cuboid":
            return float(np.prod(self.dimensions))
        return math.pi / 6.0 * self.dimensions[0] ** 3


@dataclass(frozen=True)
class Sensor:
    """One magnetometer (ICM-20948 / AK09916), numbered in file order.

    ``position`` is its centre in the robot base frame (m; the base frame has
    its origin at the proximal end of segment 1 and z along the straight
    backbone). ``rotation`` is the sensor frame's orientation in the base
    frame (3x3; a field b_base reads as rotation.T @ b_base). ``mux_channel``
    is the TCA9548A channel 0..7, or None when wired directly;
    ``i2c_address`` the 7-bit ICM-20948 address.
    """

    index: int
    position: tuple[float, float, float]
    rotation: tuple[tuple[float, float, float], ...]
    mux_channel: int | None
    i2c_address: int


@dataclass(frozen=True)
class Robot:
    """A validated robot description in SI units.

    ``name``: the TOML file stem (a C identifier; the table format limits
    its length to TBL_NAME_LEN - 1).
    ``gravity``: gravitational acceleration in the base frame (m/s^2), or
    None. ``tension_grid``: strictly increasing tensions (N) the tables are
    computed at; ``default_tension`` (N) lies on the grid. ``noise``: the
    assumed 1-sigma magnetometer noise per axis (T). ``travel_limit``: safety
    limit on tendon take-up past engagement (m). ``mode``: "delta" or
    "absolute", the firmware's default target mode. ``doubts``: values outside
    the plausible range of their unit (see the module docstring).
    """

    name: str
    path: Path
    description: str
    segments: tuple[Segment, ...]
    tendons: tuple[Tendon, ...]
    magnet: Magnet
    sensors: tuple[Sensor, ...]
    gravity: tuple[float, float, float] | None
    tension_grid: tuple[float, ...]
    default_tension: float
    noise: float
    travel_limit: float
    mode: str
    doubts: tuple[str, ...] = ()

    @property
    def length(self) -> float:
        """Total backbone length, m."""
        return sum(s.length for s in self.segments)

    def segment_end(self, number: int) -> float:
        """Arc length at the distal end of segment ``number`` (1-based), m."""
        return sum(s.length for s in self.segments[:number])

    def tendon_stretch(self, tendon: Tendon, tension: float, path_length: float) -> float:
        """Elastic stretch of ``tendon`` at ``tension`` (N) given its path
        length inside the robot (m): T * (path + free_length) / EA, m."""
        return tension * (path_length + tendon.free_length) / tendon.stiffness_ea

    def tip_tension(self, tendon: Tendon, tension: float) -> float:
        """The tension ``tendon`` delivers at its end when its spool side
        holds ``tension`` (N), pulled from slack through the path's friction:
        max(0, T (1 - friction_mu) - friction_N); T where the description has
        no friction. Every model solve of a calibration's pull or a hung
        weight goes through it, so the targets are those of the spool-side
        tension the calibration is asked for."""
        mu = tendon.friction_mu or 0.0
        f0 = tendon.friction_N or 0.0
        return max(0.0, tension * (1.0 - mu) - f0)

    def tip_tensions(self, tensions) -> np.ndarray:
        """``tip_tension`` of every tendon, for a vector of spool tensions."""
        return np.array([self.tip_tension(t, float(x)) for t, x in zip(self.tendons, tensions)])


# --- validation -------------------------------------------------------------------

# The name's length limit belongs to the firmware (TBL_NAME_LEN): hallhome.usable
# checks it against lib/table/table.h.
_C_IDENT = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")

_TOP_KEYS = {"description", "segments", "tendons", "magnet", "sensors", "sensing", "gravity",
             "calibration"}
_SEGMENT_KEYS = {"length_mm", "disks", "youngs_modulus_GPa", "poisson_ratio", "outer_radius_mm",
                 "inner_radius_mm", "density_kg_m3", "disk_mass_g"}
_TENDON_KEYS = {"segment", "routing_radius_mm", "routing_angle_deg", "twist_deg_per_mm",
                "servo_id", "pull_dir", "spool_radius_mm", "ticks_per_rev", "stiffness_EA_N",
                "free_length_mm", "friction_mN", "friction_mu"}
_MAGNET_KEYS = {"shape", "diameter_mm", "length_mm", "size_mm", "polarization_T", "offset_mm",
                "rotation_deg", "mass_g"}
_SENSOR_KEYS = {"position_mm", "rotation_deg", "mux_channel", "i2c_address"}
_SENSING_KEYS = {"noise_uT"}
_GRAVITY_KEYS = {"direction", "g_m_s2"}
_CALIBRATION_KEYS = {"tension_grid_N", "default_tension_N", "travel_limit_mm", "mode"}


# Units a value is often given in by mistake: (factor to this unit, that unit).
_UNIT_SLIPS = {"mm": ((1e3, "m"), (1e-3, "um")), "GPa": ((1e-9, "Pa"), (1e-3, "MPa")),
               "kg/m^3": ((1e3, "g/cm^3"),), "g": ((1e3, "kg"),)}


class _Checker:
    def __init__(self, path: Path):
        self.file = path.name
        self.problems: list[str] = []
        self.doubts: list[str] = []

    def plausible(self, name: str, v: Any, lo: float, hi: float, unit: str) -> None:
        """A doubt when a valid value ``v`` lies outside [lo, hi] (its unit's
        plausible range for a tendon-driven continuum robot); 0 always passes
        for optional masses and radii."""
        if v is None or v == 0 or lo <= abs(v) <= hi:
            return
        hint = ""
        for scale, other in _UNIT_SLIPS.get(unit, ()):
            if lo <= abs(v) * scale <= hi:
                hint = f"; a value in {other}?"
                break
        self.doubts.append(f"{self.file}: {name}: {v!r} is implausible (expected "
                           f"{lo:g}..{hi:g} {unit}{hint})")

    def fail(self, key: str, expected: str, got: Any = None, show: bool = True) -> None:
        msg = f"{self.file}: {key}: expected {expected}"
        if show:
            msg += f", got {got!r}"
        self.problems.append(msg)

    def keys(self, table: Any, where: str, allowed: set[str]) -> bool:
        if not isinstance(table, dict):
            self.fail(where, "a table", table)
            return False
        for k in sorted(table):
            if k not in allowed:
                prefix = f"{where}." if where else ""
                self.problems.append(
                    f"{self.file}: {prefix}{k}: unknown key (allowed: {', '.join(sorted(allowed))})")
        return True

    def number(self, table: dict, where: str, key: str, expected: str, lo: float | None = None,
               hi: float | None = None, lo_open: bool = False, default: Any = None,
               integer: bool = False) -> Any:
        name = f"{where}.{key}" if where else key
        if key not in table:
            if default is not None:
                return default
            self.fail(name, f"{expected} (missing)", show=False)
            return None
        v = table[key]
        ok_type = isinstance(v, int) if integer else isinstance(v, (int, float))
        if isinstance(v, bool) or not ok_type or (isinstance(v, float) and not math.isfinite(v)):
            self.fail(name, expected, v)
            return None
        if lo is not None and (v <= lo if lo_open else v < lo):
            self.fail(name, expected, v)
            return None
        if hi is not None and v > hi:
            self.fail(name, expected, v)
            return None
        return v

    def vector(self, table: dict, where: str, key: str, expected: str, default: Any = None,
               nonzero: bool = False) -> tuple[float, float, float] | None:
        name = f"{where}.{key}" if where else key
        if key not in table:
            if default is not None:
                return default
            self.fail(name, f"{expected} (missing)", show=False)
            return None
        v = table[key]
        if (not isinstance(v, list) or len(v) != 3
                or any(isinstance(x, bool) or not isinstance(x, (int, float))
                       or not math.isfinite(x) for x in v)):
            self.fail(name, expected, v)
            return None
        if nonzero and not any(v):
            self.fail(name, expected, v)
            return None
        return (float(v[0]), float(v[1]), float(v[2]))

    def array_of_tables(self, doc: dict, key: str, expected: str) -> list:
        if key not in doc:
            self.fail(key, f"{expected} (missing)", show=False)
            return []
        v = doc[key]
        if not isinstance(v, list) or not v or not all(isinstance(t, dict) for t in v):
            self.fail(key, expected, v)
            return []
        return v


def _rotation(deg: tuple[float, float, float]) -> tuple[tuple[float, float, float], ...]:
    m = Rotation.from_euler("xyz", deg, degrees=True).as_matrix()
    return tuple(tuple(float(x) for x in row) for row in m)


def load_robot(path: str | Path) -> Robot:
    """Read and validate the robot description at ``path`` (TOML).

    Returns a ``Robot`` in SI units. Raises ``RobotError`` listing every
    problem (unknown keys, missing fields, values out of range, tendons routed
    to a missing segment, two tendons on one servo, two sensors on one mux
    channel and address), and ``FileNotFoundError`` if the file is missing.
    """
    path = Path(path)
    text = path.read_bytes()
    ck = _Checker(path)
    try:
        doc = tomllib.loads(text.decode("utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise RobotError([f"{path.name}: not valid TOML: {exc}"]) from None

    name = path.stem
    if not _C_IDENT.match(name):
        ck.problems.append(f"{path.name}: file name: expected a C identifier as the robot "
                           f"name, got {name!r}")
    ck.keys(doc, "", _TOP_KEYS)
    description = doc.get("description", "")
    if not isinstance(description, str):
        ck.fail("description", "a string", description)
        description = ""

    segments = []
    for i, t in enumerate(ck.array_of_tables(doc, "segments", "an array of [[segments]] tables")):
        w = f"segments[{i + 1}]"
        ck.keys(t, w, _SEGMENT_KEYS)
        length = ck.number(t, w, "length_mm", "a positive length in mm", 0, lo_open=True)
        disks = ck.number(t, w, "disks", "a disk count >= 0 (integer)", 0, integer=True)
        e = ck.number(t, w, "youngs_modulus_GPa", "a positive modulus in GPa", 0, lo_open=True)
        nu = ck.number(t, w, "poisson_ratio", "a Poisson ratio in 0..0.5", 0, 0.5)
        ro = ck.number(t, w, "outer_radius_mm", "a positive radius in mm", 0, lo_open=True)
        ri = ck.number(t, w, "inner_radius_mm", "a radius in mm, >= 0 and below outer_radius_mm",
                       0, default=0.0)
        if ro is not None and ri is not None and ri >= ro:
            ck.fail(f"{w}.inner_radius_mm", f"a radius in mm below outer_radius_mm ({ro})", ri)
            ri = None
        rho = ck.number(t, w, "density_kg_m3", "a density >= 0 in kg/m^3", 0, default=0.0)
        dm = ck.number(t, w, "disk_mass_g", "a mass >= 0 in g", 0, default=0.0)
        for key, v, lo, hi, unit in (("length_mm", length, 5, 2000, "mm"),
                                     ("youngs_modulus_GPa", e, 1e-3, 1000, "GPa"),
                                     ("outer_radius_mm", ro, 0.05, 50, "mm"),
                                     ("inner_radius_mm", ri, 0.02, 50, "mm"),
                                     ("density_kg_m3", rho, 100, 25000, "kg/m^3"),
                                     ("disk_mass_g", dm, 1e-3, 100, "g")):
            ck.plausible(f"{w}.{key}", v, lo, hi, unit)
        if None not in (length, disks, e, nu, ro, ri, rho, dm):
            segments.append(Segment(i + 1, length * 1e-3, disks, e * 1e9, float(nu), ro * 1e-3,
                                    ri * 1e-3, float(rho), dm * 1e-3))
    n_seg = len(doc["segments"]) if isinstance(doc.get("segments"), list) else 0

    tendons = []
    servo_of: dict[int, int] = {}
    for i, t in enumerate(ck.array_of_tables(doc, "tendons", "an array of [[tendons]] tables")):
        w = f"tendons[{i + 1}]"
        ck.keys(t, w, _TENDON_KEYS)
        seg = ck.number(t, w, "segment", f"the number of an existing segment, 1..{n_seg}", 1,
                        n_seg, integer=True)
        rr = ck.number(t, w, "routing_radius_mm", "a positive radius in mm", 0, lo_open=True)
        ra = ck.number(t, w, "routing_angle_deg", "an angle in degrees, -360..360", -360, 360)
        tw = ck.number(t, w, "twist_deg_per_mm", "a helix rate in degrees per mm, -90..90", -90,
                       90, default=0.0)
        sid = ck.number(t, w, "servo_id", "a DYNAMIXEL ID 0..252", 0, 252, integer=True)
        pd = t.get("pull_dir")
        if "pull_dir" not in t:
            ck.fail(f"{w}.pull_dir", "+1 or -1 (missing)", show=False)
        elif pd not in (1, -1) or isinstance(pd, bool):
            ck.fail(f"{w}.pull_dir", "+1 (increasing ticks shortens the tendon) or -1", pd)
            pd = None
        sr = ck.number(t, w, "spool_radius_mm", "a positive radius in mm", 0, lo_open=True)
        tpr = ck.number(t, w, "ticks_per_rev", "encoder ticks per revolution, 1..1048576", 1,
                        1 << 20, integer=True)
        ea = ck.number(t, w, "stiffness_EA_N", "a positive axial stiffness EA in N", 0,
                       lo_open=True)
        fl = ck.number(t, w, "free_length_mm", "a length >= 0 in mm", 0)
        fr = (ck.number(t, w, "friction_mN", "a friction force in mN, 0..1000", 0, 1000)
              if "friction_mN" in t else None)
        fmu = (ck.number(t, w, "friction_mu", "a fraction of the tension, 0..0.4", 0, 0.4)
               if "friction_mu" in t else None)
        for key, v, lo, hi, unit in (("routing_radius_mm", rr, 0.2, 100, "mm"),
                                     ("spool_radius_mm", sr, 0.5, 100, "mm"),
                                     ("stiffness_EA_N", ea, 10, 1e7, "N"),
                                     ("free_length_mm", fl, 1, 10000, "mm")):
            ck.plausible(f"{w}.{key}", v, lo, hi, unit)
        if sid is not None:
            if sid in servo_of:
                ck.fail(f"{w}.servo_id", f"a servo ID not used by another tendon (tendons"
                        f"[{servo_of[sid] + 1}] already uses it)", sid)
            servo_of.setdefault(sid, i)
        bad_friction = ("friction_mN" in t and fr is None) or ("friction_mu" in t and fmu is None)
        if None not in (seg, rr, ra, tw, sid, pd, sr, tpr, ea, fl) and not bad_friction:
            tendons.append(Tendon(i, seg, rr * 1e-3, math.radians(ra), math.radians(tw) * 1e3,
                                  sid, pd, sr * 1e-3, tpr, float(ea), fl * 1e-3,
                                  None if fr is None else fr * 1e-3,
                                  None if fmu is None else float(fmu)))

    magnet = None
    if "magnet" not in doc:
        ck.fail("magnet", "a [magnet] table (missing)", show=False)
    elif ck.keys(doc["magnet"], "magnet", _MAGNET_KEYS):
        magnet = _load_magnet(ck, doc["magnet"])

    sensors = []
    taken: dict[tuple, int] = {}
    for i, t in enumerate(ck.array_of_tables(doc, "sensors", "an array of [[sensors]] tables")):
        w = f"sensors[{i + 1}]"
        ck.keys(t, w, _SENSOR_KEYS)
        pos = ck.vector(t, w, "position_mm", "[x, y, z] in mm in the base frame")
        rot = ck.vector(t, w, "rotation_deg", "[rx, ry, rz] xyz Euler angles in degrees",
                        default=(0.0, 0.0, 0.0))
        mux = t.get("mux_channel", "none")
        if mux == "none":
            mux = None
        elif isinstance(mux, bool) or not isinstance(mux, int) or not 0 <= mux < MUX_CHANNELS:
            ck.fail(f"{w}.mux_channel", f"a TCA9548A channel 0..{MUX_CHANNELS - 1} or \"none\"",
                    mux)
            mux = -1
        addr = t.get("i2c_address")
        if addr not in ICM_ADDRESSES or isinstance(addr, bool):
            ck.fail(f"{w}.i2c_address", "an ICM-20948 address, 0x68 or 0x69", addr)
            addr = None
        if mux != -1 and addr is not None:
            # One sensor per mux channel (design: one ICM-20948 per channel);
            # directly wired sensors must differ in address.
            slot = ("mux", mux) if mux is not None else ("direct", addr)
            if slot in taken:
                where = (f"mux channel {mux}" if mux is not None
                         else f"the direct bus at address 0x{addr:02x}")
                ck.fail(f"{w}.mux_channel", f"a mux channel no other sensor uses (sensors"
                        f"[{taken[slot] + 1}] is already on {where})", mux if mux is not None
                        else "none")
            taken.setdefault(slot, i)
        for x in pos or ():
            ck.plausible(f"{w}.position_mm", x, 0, 2000, "mm")
        if None not in (pos, rot, addr) and mux != -1:
            sensors.append(Sensor(i, tuple(x * 1e-3 for x in pos), _rotation(rot), mux, addr))

    noise = 0.6e-6
    if "sensing" in doc and ck.keys(doc["sensing"], "sensing", _SENSING_KEYS):
        n = ck.number(doc["sensing"], "sensing", "noise_uT",
                      "a positive 1-sigma noise in uT, at most 100", 0, 100, lo_open=True,
                      default=0.6)
        ck.plausible("sensing.noise_uT", n, 0.01, 100, "uT")
        noise = None if n is None else n * 1e-6

    gravity = None
    if "gravity" not in doc:
        ck.fail("gravity", "a [gravity] table with direction = [x, y, z] or \"none\" (missing)",
                show=False)
    elif ck.keys(doc["gravity"], "gravity", _GRAVITY_KEYS):
        g = doc["gravity"]
        gm = ck.number(g, "gravity", "g_m_s2", "a gravitational acceleration in m/s^2, 0..50", 0,
                       50, default=STANDARD_GRAVITY)
        if g.get("direction") == "none":
            gravity = None
        else:
            d = ck.vector(g, "gravity", "direction", "[x, y, z] (not all zero) or \"none\"",
                          nonzero=True)
            if d is not None and gm is not None:
                v = np.array(d) / np.linalg.norm(d) * gm
                gravity = (float(v[0]), float(v[1]), float(v[2]))

    grid, default, limit, mode = (), None, None, "delta"
    if "calibration" not in doc:
        ck.fail("calibration", "a [calibration] table (missing)", show=False)
    elif ck.keys(doc["calibration"], "calibration", _CALIBRATION_KEYS):
        c = doc["calibration"]
        w = "calibration"
        gr = c.get("tension_grid_N")
        if (not isinstance(gr, list) or len(gr) < 2
                or any(isinstance(x, bool) or not isinstance(x, (int, float)) for x in gr)
                or any(x <= 0 or x > 60 for x in gr)
                or any(b <= a for a, b in zip(gr, gr[1:]))):
            ck.fail(f"{w}.tension_grid_N", "at least 2 strictly increasing tensions in N, each "
                    "in (0, 60]", gr)
        else:
            grid = tuple(float(x) for x in gr)
        default = ck.number(c, w, "default_tension_N", "a tension in N inside the grid", 0,
                            lo_open=True)
        if default is not None and grid and not grid[0] <= default <= grid[-1]:
            ck.fail(f"{w}.default_tension_N", f"a tension in N inside the grid "
                    f"[{grid[0]}, {grid[-1]}]", default)
        limit = ck.number(c, w, "travel_limit_mm", "a positive travel in mm", 0, lo_open=True)
        ck.plausible(f"{w}.travel_limit_mm", limit, 0.05, 200, "mm")
        mode = c.get("mode", "delta")
        if mode not in ("delta", "absolute"):
            ck.fail(f"{w}.mode", "\"delta\" or \"absolute\"", mode)

    if ck.problems:
        raise RobotError(ck.problems)
    return Robot(name=name, path=path.resolve(), description=description,
                 segments=tuple(segments), tendons=tuple(tendons), magnet=magnet,
                 sensors=tuple(sensors), gravity=gravity, tension_grid=grid,
                 default_tension=float(default), noise=float(noise),
                 travel_limit=limit * 1e-3, mode=mode, doubts=tuple(ck.doubts))


def _load_magnet(ck: _Checker, t: dict) -> Magnet | None:
    w = "magnet"
    shape = t.get("shape")
    dims: tuple[float, ...] | None = None
    if shape == "cylinder":
        d = ck.number(t, w, "diameter_mm", "a positive diameter in mm", 0, lo_open=True)
        h = ck.number(t, w, "length_mm", "a positive length in mm", 0, lo_open=True)
        dims = None if None in (d, h) else (d * 1e-3, h * 1e-3)
    elif shape == "sphere":
        d = ck.number(t, w, "diameter_mm", "a positive diameter in mm", 0, lo_open=True)
        dims = None if d is None else (d * 1e-3,)
    elif shape == "cuboid":
        s = ck.vector(t, w, "size_mm", "[a, b, c] positive sizes in mm")
        if s is not None and min(s) <= 0:
            ck.fail(f"{w}.size_mm", "[a, b, c] positive sizes in mm", list(s))
            s = None
        dims = None if s is None else tuple(x * 1e-3 for x in s)
    else:
        ck.fail(f"{w}.shape", "\"cylinder\", \"cuboid\" or \"sphere\"", shape)
    pol = ck.vector(t, w, "polarization_T", "[Jx, Jy, Jz] in tesla, magnet frame, |J| < 2 T",
                    nonzero=True)
    if pol is not None and np.linalg.norm(pol) >= 2.0:
        ck.fail(f"{w}.polarization_T", "[Jx, Jy, Jz] in tesla, |J| < 2 T", list(pol))
        pol = None
    off = ck.vector(t, w, "offset_mm", "[x, y, z] in mm in the tip frame")
    rot = ck.vector(t, w, "rotation_deg", "[rx, ry, rz] xyz Euler angles in degrees",
                    default=(0.0, 0.0, 0.0))
    mass = ck.number(t, w, "mass_g", "a mass >= 0 in g", 0, default=-1.0)
    for key, v in (("diameter_mm", t.get("diameter_mm")), ("length_mm", t.get("length_mm"))):
        if isinstance(v, (int, float)) and not isinstance(v, bool) and v > 0:
            ck.plausible(f"{w}.{key}", v, 0.2, 100, "mm")
    for x in (dims or ()) if shape == "cuboid" else ():
        ck.plausible(f"{w}.size_mm", x * 1e3, 0.2, 100, "mm")
    if mass is not None and mass > 0:
        ck.plausible(f"{w}.mass_g", mass, 1e-3, 1000, "g")
    if None in (dims, pol, off, rot, mass):
        return None
    mag = Magnet(shape, dims, pol, tuple(x * 1e-3 for x in off), _rotation(rot), 0.0)
    m = mass * 1e-3 if mass >= 0 else mag.volume * NDFEB_DENSITY_KG_M3
    return Magnet(shape, dims, pol, mag.offset, mag.rotation, float(m))


def robot_files(directory: Path | None = None) -> list[Path]:
    """Every robot description in ``directory`` (default lookup_tables/robots), sorted."""
    from hallhome.paths import ROBOTS_DIR
    return sorted((directory or ROBOTS_DIR).glob("*.toml"))
