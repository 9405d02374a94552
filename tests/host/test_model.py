"""Static model validation: cases with known answers, symmetry, convergence,
and agreement of the Cosserat and constant-curvature models."""

import math

import numpy as np
import pytest

from hallhome.model import ConstantCurvatureModel, CosseratModel
from hallhome.paths import ROBOTS_DIR
from hallhome.robot import load_robot

PAPER = ROBOTS_DIR / "paper_2seg.toml"


def tiny_robot_toml(*, length_mm=100.0, gravity="none", density=0.0, disk_mass=0.0,
                    magnet_mass_g=0.0, tendons=((1, 5.0, 0.0, 0.0),), segments=1,
                    sensors=((20.0, 0.0, 110.0),), grid="[0.2, 0.5, 1.0]", default=0.5,
                    noise=0.6, travel=5.0, outer_radius=0.5, offset_z=0.0):
    """A small robot description for tests: ``tendons`` are (segment,
    radius_mm, angle_deg, twist_deg_per_mm)."""
    parts = ["description = \"test robot\""]
    for _ in range(segments):
        parts.append(f"""[[segments]]
length_mm = {length_mm / segments}
disks = 5
youngs_modulus_GPa = 60.0
poisson_ratio = 0.3
outer_radius_mm = {outer_radius}
density_kg_m3 = {density}
disk_mass_g = {disk_mass}""")
    for k, (seg, rad, ang, tw) in enumerate(tendons):
        parts.append(f"""[[tendons]]
segment = {seg}
routing_radius_mm = {rad}
routing_angle_deg = {ang}
twist_deg_per_mm = {tw}
servo_id = {k + 1}
pull_dir = 1
spool_radius_mm = 4.0
ticks_per_rev = 4096
stiffness_EA_N = 2000.0
free_length_mm = 100.0""")
    parts.append(f"""[magnet]
shape = "sphere"
diameter_mm = 3.0
polarization_T = [0.0, 0.0, 1.2]
offset_mm = [0.0, 0.0, {offset_z}]
mass_g = {magnet_mass_g}""")
    for k, pos in enumerate(sensors):
        parts.append(f"""[[sensors]]
position_mm = [{pos[0]}, {pos[1]}, {pos[2]}]
mux_channel = {k}
i2c_address = 0x69""")
    g = '"none"' if gravity == "none" else str(list(gravity))
    parts.append(f"[sensing]\nnoise_uT = {noise}")
    parts.append(f"[gravity]\ndirection = {g}")
    parts.append(f"""[calibration]
tension_grid_N = {grid}
default_tension_N = {default}
travel_limit_mm = {travel}""")
    return "\n\n".join(parts) + "\n"


def make_robot(tmp_path, name="tiny", **kw):
    p = tmp_path / f"{name}.toml"
    p.write_text(tiny_robot_toml(**kw))
    return load_robot(p)


def test_pure_tendon_moment_gives_circular_arc(tmp_path):
    r = make_robot(tmp_path)
    tau = 1.0
    sol = CosseratModel(r, steps_per_segment=16).solve([tau])
    ei = r.segments[0].bending_stiffness
    ea = r.segments[0].axial_stiffness
    kappa = tau * 5e-3 / ei
    # In space the arc is scaled by the axial strain v3 = 1 - tau/EA.
    radius = (1.0 - tau / ea) / kappa
    # bending toward the tendon at +x: centre of the circle at (radius, 0, 0)
    d = np.linalg.norm(sol.positions - np.array([radius, 0.0, 0.0]), axis=1)
    assert np.max(np.abs(d - radius)) < 1e-9
    assert np.max(np.abs(sol.positions[:, 1])) < 1e-12
    theta = kappa * r.length
    tip_x = radius * (1 - math.cos(theta))
    assert sol.tip_position[0] == pytest.approx(tip_x, rel=1e-9)
    # tendon path shortening: rho * theta plus the backbone compression
    assert sol.displacements[0] == pytest.approx(5e-3 * theta + r.length * tau / ea, rel=1e-6)
    # tendon elasticity: stretch T (path + free length) / EA on top
    stretch = tau * (sol.path_lengths[0] + 0.1) / 2000.0
    assert sol.take_up[0] == pytest.approx(sol.displacements[0] + stretch, rel=1e-12)
    assert abs(CosseratModel(r).solve([0.0]).take_up[0]) < 1e-15


def test_paper_reference_numbers():
    """device-facts.md: 1.5 N on a distal tendon bends the robot to
    2.29 1/m and moves the tip 12.8 mm; path shortening 37 / 73 um per 0.1 N."""
    r = load_robot(PAPER)
    m = CosseratModel(r, gravity=False)
    tau = np.zeros(6)
    tau[3] = 1.5
    sol = m.solve(tau)
    assert math.hypot(*sol.tip_position[:2]) * 1e3 == pytest.approx(12.8, abs=0.05)
    tau = np.zeros(6)
    tau[0] = 0.1
    assert m.solve(tau).displacements[0] * 1e6 == pytest.approx(37, abs=1.0)
    tau = np.zeros(6)
    tau[3] = 0.1
    assert m.solve(tau).displacements[3] * 1e6 == pytest.approx(73, abs=1.0)


def test_axial_compression(tmp_path):
    r = make_robot(tmp_path, tendons=((1, 5.0, 0.0, 0.0), (1, 5.0, 120.0, 0.0),
                                      (1, 5.0, 240.0, 0.0)))
    tau = 0.8
    sol = CosseratModel(r).solve([tau, tau, tau])
    ea = r.segments[0].axial_stiffness
    strain = 3 * tau / ea
    assert np.max(np.abs(sol.positions[:, :2])) < 1e-12
    assert sol.tip_position[2] == pytest.approx(r.length * (1 - strain), rel=1e-12)
    assert sol.displacements == pytest.approx([r.length * strain] * 3, rel=1e-9)


def test_small_deflection_cantilever_tip_load(tmp_path):
    """Massless rod, tip mass, gravity across: delta = P L^3 / (3 EI)."""
    r = make_robot(tmp_path, gravity=(1.0, 0.0, 0.0), magnet_mass_g=0.05, tendons=((1, 5.0, 0.0,
                                                                                      0.0),))
    sol = CosseratModel(r, steps_per_segment=32).solve([0.0])
    P = 0.05e-3 * 9.80665
    delta = P * r.length**3 / (3 * r.segments[0].bending_stiffness)
    assert delta < 0.01 * r.length  # small deflection
    assert sol.tip_position[0] == pytest.approx(delta, rel=0.005)
    assert sol.residual < 1e-12


def test_small_deflection_cantilever_distributed_load(tmp_path):
    """Own weight across: delta = w L^4 / (8 EI)."""
    r = make_robot(tmp_path, gravity=(0.0, -1.0, 0.0), density=1000.0)
    sol = CosseratModel(r, steps_per_segment=32).solve([0.0])
    w = r.segments[0].linear_density * 9.80665
    delta = w * r.length**4 / (8 * r.segments[0].bending_stiffness)
    assert delta < 0.01 * r.length
    assert -sol.tip_position[1] == pytest.approx(delta, rel=0.005)


def test_symmetry_of_tendons_and_mirror():
    r = load_robot(PAPER)
    m = CosseratModel(r)  # gravity along the axis keeps the 120 deg symmetry
    tips = []
    for i in (3, 4, 5):
        tau = np.zeros(6)
        tau[i] = 1.2
        tips.append(m.solve(tau).tip_position)
    rot = np.array([[math.cos(2 * math.pi / 3), -math.sin(2 * math.pi / 3), 0],
                    [math.sin(2 * math.pi / 3), math.cos(2 * math.pi / 3), 0], [0, 0, 1]])
    assert np.allclose(rot @ tips[0], tips[1], atol=1e-10)
    assert np.allclose(rot @ tips[1], tips[2], atol=1e-10)
    # the tendon at 0 deg bends in the x-z plane only
    assert abs(tips[0][1]) < 1e-12


def test_convergence_with_steps():
    """Second-order convergence of the integrator on the horizontal
    three-segment robot (gravity across, helical routing)."""
    r = load_robot(ROBOTS_DIR / "trio_3seg.toml")
    tau = np.zeros(len(r.tendons))
    tau[8] = 1.0
    ref = CosseratModel(r, steps_per_segment=64).solve(tau).tip_position
    err = [np.linalg.norm(CosseratModel(r, steps_per_segment=n).solve(tau).tip_position - ref)
           for n in (4, 8, 16)]
    assert err[1] < err[0] / 3 and err[2] < err[1] / 3
    assert err[1] < 2e-6  # the table generator's 8 steps: within 2 um on this robot


def test_gravity_bends_a_horizontal_robot_down(tmp_path):
    r = load_robot(ROBOTS_DIR / "trio_3seg.toml")
    sol = CosseratModel(r).solve(np.zeros(len(r.tendons)))
    assert sol.tip_position[0] < -1e-4  # sags along -x, the gravity direction
    flat = CosseratModel(r, gravity=False).solve(np.zeros(len(r.tendons)))
    assert np.allclose(flat.tip_position, [0, 0, r.length], atol=1e-12)


@pytest.mark.parametrize("index", range(6))
@pytest.mark.parametrize("tension", [0.8, 1.5])
def test_cosserat_and_constant_curvature_agree(index, tension):
    r = load_robot(PAPER)
    tau = np.zeros(6)
    tau[index] = tension
    a = CosseratModel(r, gravity=False).solve(tau)
    b = ConstantCurvatureModel(r).solve(tau)
    assert np.linalg.norm(a.tip_position - b.tip_position) < 0.1e-3
    assert abs(a.displacements[index] - b.displacements[index]) < 5e-6


def test_helical_routing_twists_the_tip(tmp_path):
    straight = make_robot(tmp_path, name="s")
    helix = make_robot(tmp_path, name="h", tendons=((1, 5.0, 0.0, 0.9),))
    a = CosseratModel(straight).solve([1.0]).tip_position
    b = CosseratModel(helix).solve([1.0]).tip_position
    assert abs(a[1]) < 1e-12 and abs(b[1]) > 1e-3  # the helix leaves the x-z plane


def test_bad_tensions_are_rejected():
    m = CosseratModel(load_robot(PAPER))
    with pytest.raises(ValueError, match="expected 6 finite values"):
        m.solve([1.0, 2.0])
    with pytest.raises(ValueError):
        m.solve([-0.1, 0, 0, 0, 0, 0])
    with pytest.raises(ValueError):
        ConstantCurvatureModel(load_robot(PAPER)).solve([1.0])


def test_solve_time_regression_guard():
    """Budget is 50 ms per solve (docs/model.md, `hallhome bench`); this guard
    allows 3x for a loaded shared machine."""
    import time
    r = load_robot(PAPER)
    m = CosseratModel(r)
    tau = np.zeros(6)
    tau[5] = 0.8
    m.solve(tau)
    best = min(_timed(m.solve, tau, time) for _ in range(3))
    assert best < 0.150


def _timed(fn, arg, time):
    t0 = time.perf_counter()
    fn(arg)
    return time.perf_counter() - t0
