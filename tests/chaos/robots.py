"""Random robots for the chaos suite: a robot TOML drawn from a seed, its
lookup table, its plant config and a firmware ELF with that table built in.

Everything is cached under build/chaos/robots/<name>/ where the name carries
a hash of the TOML's content, so a pool is built once and reused; a change
of the generator gives new names (and new builds). The firmware is brought
up to date with the tree (lib/, firmware/) by make each time the suite runs.

Robots stay inside what the plant models: straight routing only (no helical
twist), 1 to 3 segments, 3 to 12 tendons (at least one per segment), 1 to 4
sensors on a ring above the tip.
"""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import math
import os
import random
import subprocess
import threading
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
BUILD = ROOT / "build" / "chaos"
ROBOTS = BUILD / "robots"
PY = ROOT / ".venv" / "bin" / "python"

# The robot plant and the table hold at most this many (lib/table/table.h).
MAX_TENDONS = 12


@dataclass
class Robot:
    name: str
    dir: Path
    segments: int
    tendons: int
    sensors: int

    @property
    def toml(self) -> Path:
        return self.dir / f"{self.name}.toml"

    @property
    def table_c(self) -> Path:
        return self.dir / "tables" / f"{self.name}.c"

    @property
    def plant(self) -> Path:
        return self.dir / f"{self.name}.cfg"

    @property
    def elf(self) -> Path:
        """Where `make firmware ROBOT=<name>` puts the ELF (build/fw/<robot>/)."""
        return ROOT / "build" / "fw" / self.name / f"hallhome-{self.name}.elf"

    def built(self) -> bool:
        return self.elf.exists() and self.plant.exists()

    def describe(self) -> str:
        return f"{self.name} ({self.segments} seg, {self.tendons} tendons, {self.sensors} sensors)"


def robot_toml(seed: int, segments: int | None = None, tendons: int | None = None,
               sensors: int | None = None, friction: bool = False) -> tuple[str, int, int, int]:
    """A robot description drawn from seed (counts may be forced). With
    friction, every tendon declares the path friction the plant gives it
    (10 mN + 2 %, hallhome.plantcfg's default) as a lab that measured it
    would; without, the description leaves it out and the robot has it."""
    rng = random.Random(seed)
    n_seg = segments or rng.randint(1, 3)
    n_ten = tendons or rng.randint(max(3, n_seg), MAX_TENDONS)
    n_sen = sensors or rng.randint(1, 4)
    # tendons per segment: at least one each, the rest spread at random
    per = [1] * n_seg
    for _ in range(n_ten - n_seg):
        per[rng.randrange(n_seg)] += 1
    lines = [f'description = "chaos robot {seed}: {n_seg} segments, {n_ten} tendons, '
             f'{n_sen} sensors"', ""]
    total = 0.0
    for s in range(n_seg):
        length = rng.choice([40.0, 45.0, 50.0, 53.0])
        total += length
        lines += ["[[segments]]", f"length_mm = {length}", f"disks = {int(length // 9)}",
                  "youngs_modulus_GPa = 60.0", "poisson_ratio = 0.33",
                  "outer_radius_mm = 0.5", "inner_radius_mm = 0.0",
                  "density_kg_m3 = 6450.0", "disk_mass_g = 0.2", ""]
    sid = 1
    for s, k in enumerate(per):
        offset = rng.uniform(0.0, 360.0 / max(k, 1))
        for j in range(k):
            angle = (offset + 360.0 * j / k) % 360.0
            lines += ["[[tendons]]", f"segment = {s + 1}", "routing_radius_mm = 4.5",
                      f"routing_angle_deg = {angle:.1f}", f"servo_id = {sid}", "pull_dir = 1",
                      "spool_radius_mm = 4.0", "ticks_per_rev = 4096",
                      "stiffness_EA_N = 2000.0", "free_length_mm = 150.0"]
            lines += ["friction_mN = 10.0", "friction_mu = 0.02", ""] if friction else [""]
            sid += 1
    lines += ["[magnet]", 'shape = "cylinder"', "diameter_mm = 3.5", "length_mm = 3.0",
              "polarization_T = [0.0, 0.0, 1.3]", "offset_mm = [0.0, 0.0, 2.5]", ""]
    z = total + 16.0
    phase = rng.uniform(0.0, 120.0)
    for k in range(n_sen):
        a = math.radians(phase + 360.0 * k / n_sen)
        lines += ["[[sensors]]",
                  f"position_mm = [{22.0 * math.cos(a):.4f}, {22.0 * math.sin(a):.4f}, {z:.1f}]",
                  f"rotation_deg = [180.0, 0.0, {math.degrees(a):.1f}]",
                  f"mux_channel = {k}", "i2c_address = 0x69", ""]
    lines += ["[sensing]", "noise_uT = 0.6", "", "[gravity]", "direction = [0.0, 0.0, -1.0]", "",
              "[calibration]",
              "tension_grid_N = [0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0, 1.1, 1.3, 1.5]",
              "default_tension_N = 0.8", "travel_limit_mm = 2.5", 'mode = "delta"', ""]
    return "\n".join(lines), n_seg, n_ten, n_sen


def make_robot(seed: int, friction: bool = False, **counts) -> Robot:
    text, n_seg, n_ten, n_sen = robot_toml(seed, friction=friction, **counts)
    # robot names are at most 15 characters (TBL_NAME_LEN): counts + hash
    h = hashlib.sha256(text.encode()).hexdigest()[:5]
    name = f"c{n_seg}s{n_ten}t{n_sen}k{h}"
    r = Robot(name, ROBOTS / name, n_seg, n_ten, n_sen)
    r.dir.mkdir(parents=True, exist_ok=True)
    if not r.toml.exists() or r.toml.read_text() != text:
        # whole or not at all: another worker of `pytest -n` may read it
        tmp = r.toml.with_suffix(f".tmp{os.getpid()}")
        tmp.write_text(text)
        os.replace(tmp, r.toml)
    return r


def _run(cmd: list[str], log: Path) -> None:
    with open(log, "a") as f:
        f.write("$ " + " ".join(map(str, cmd)) + "\n")
        f.flush()
        p = subprocess.run(cmd, cwd=ROOT, stdout=f, stderr=subprocess.STDOUT)
    if p.returncode != 0:
        raise RuntimeError(f"{' '.join(map(str, cmd[:3]))}... failed, see {log}")


_make_lock = threading.Lock()  # builds share build/fw/include: one make at a time


@contextlib.contextmanager
def _across_processes(name: str):
    """Held by one process at a time (the workers of `pytest -n` and a
    chaos round beside them): a lock file under build/chaos/locks."""
    d = ROBOTS.parent / "locks"
    d.mkdir(parents=True, exist_ok=True)
    with open(d / f"{name}.lock", "w") as f:
        fcntl.flock(f, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(f, fcntl.LOCK_UN)


def build_firmware(r: Robot, log: Path) -> None:
    """The firmware of robot r with its table built in: the one place that
    knows how the Makefile builds a firmware for another robot."""
    with _make_lock, _across_processes("make"):
        _run(["make", "--no-print-directory", f"-j{os.cpu_count() or 2}", "firmware",
              f"ROBOT={r.name}", f"ROBOTS_DIR={r.dir}", f"TABLES_DIR={r.table_c.parent}"],
             log)


_locks: dict[str, threading.Lock] = {}
_locks_lock = threading.Lock()


_made: set[str] = set()


def build(r: Robot) -> Robot:
    """Table and plant config of r unless made already; its firmware brought
    up to date with the tree (make rebuilds what changed) once per process;
    one build per robot at a time."""
    with _locks_lock:
        lock = _locks.setdefault(r.name, threading.Lock())
    with lock, _across_processes(r.name):
        if r.name not in _made:
            log = r.dir / "build.log"
            log.write_text("")
            if not (r.table_c.exists() and r.plant.exists()) or _stale(r):
                _generate(r, log)
            build_firmware(r, log)
            _made.add(r.name)
    return r


# What a cached table and plant config are made by: a newer one of these
# (a new table format, say) makes them again.
GENERATOR = [ROOT / "lib" / "table" / "table.h",
             *sorted((ROOT / "host_tools" / "hallhome").glob("tablegen*.py")),
             ROOT / "host_tools" / "hallhome" / "plantcfg.py"]


def _stale(r: Robot) -> bool:
    made = min(r.table_c.stat().st_mtime, r.plant.stat().st_mtime)
    return any(g.stat().st_mtime > made for g in GENERATOR if g.exists())


def _generate(r: Robot, log: Path) -> None:
    _run([str(PY), "-m", "hallhome", "tables", "--quiet", "--out-dir",
          str(r.dir / "tables"), str(r.toml)], log)
    _run([str(PY), "-c", "import sys; from hallhome.robot import load_robot; "
          "from hallhome.plantcfg import write_plant_config; "
          "write_plant_config(load_robot(sys.argv[1]), sys.argv[2])", str(r.toml),
          str(r.plant)], log)


# The pool the suite draws from: every segment count, tendon counts from the
# smallest to the table's maximum, 1 to 4 sensors. (seed, forced counts)
POOL = [
    (101, dict(segments=1, tendons=3, sensors=1)),
    (102, dict(segments=2, tendons=6, sensors=3)),
    (103, dict(segments=3, tendons=9, sensors=2)),
    (104, dict(segments=2, tendons=12, sensors=4)),
    (105, dict(segments=1, tendons=4, sensors=2)),
    (106, dict(segments=3, tendons=5, sensors=4)),
    (107, dict(segments=3, tendons=12, sensors=3)),
    (108, dict(segments=2, tendons=8, sensors=1)),
]


def pool(friction: bool = False) -> list[Robot]:
    """The robots of the pool; build() makes one when a schedule draws it.
    friction: descriptions that declare the plant's friction (robot_toml)."""
    return [make_robot(seed, friction=friction, **counts) for seed, counts in POOL]


if __name__ == "__main__":
    import sys
    import time
    for seed, counts in POOL:
        t0 = time.time()
        rb = build(make_robot(seed, **counts))
        print(f"{rb.describe()}: {time.time() - t0:.1f} s")
