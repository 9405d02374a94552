"""Field model and the paper's power-law characterisation."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from hallhome.field import (PAPER_POWER_LAW, field_at_sensors, field_magnitude_at,
                            fit_magnetization, fit_power_law, read_field_csv,
                            synthetic_power_law_data)
from hallhome.model import CosseratModel
from hallhome.paths import ROBOTS_DIR, TABLES_DIR
from hallhome.robot import Magnet, Sensor, load_robot

from test_model import make_robot

PAPER = load_robot(ROBOTS_DIR / "paper_2seg.toml")
EXAMPLE = TABLES_DIR / "examples" / "paper_fig1_synthetic.csv"
MU0_4PI = 1e-7


def _dipole(m, r):
    rn = np.linalg.norm(r)
    rh = r / rn
    return MU0_4PI * (3 * np.dot(m, rh) * rh - m) / rn**3


def test_sphere_field_is_a_dipole_that_follows_the_tip(tmp_path):
    r = make_robot(tmp_path, sensors=((20.0, 0.0, 110.0), (0.0, -15.0, 95.0)), offset_z=2.0)
    J = np.array(r.magnet.polarization)
    m = J * r.magnet.volume / (4e-7 * math.pi)
    tip_p = np.array([0.003, 0.001, 0.099])
    tip_R = Rotation.from_rotvec([0.0, 0.3, 0.1]).as_matrix()
    B = field_at_sensors(r, tip_p, tip_R)[0]
    centre = tip_p + tip_R @ np.array([0, 0, 2e-3])
    for k, s in enumerate(r.sensors):
        expect = _dipole(tip_R @ m, np.array(s.position) - centre)
        assert B[k] == pytest.approx(expect, rel=1e-9, abs=1e-15)


def test_sensor_frame_rotation(tmp_path):
    r = make_robot(tmp_path)
    B_base = field_at_sensors(r, [0, 0, 0.1], np.eye(3))[0, 0]
    rot = Rotation.from_euler("z", 90, degrees=True).as_matrix()
    s = r.sensors[0]
    turned = type(r)(**{**r.__dict__, "sensors": (Sensor(0, s.position,
                                                         tuple(map(tuple, rot)), 0, 0x69),)})
    B_s = field_at_sensors(turned, [0, 0, 0.1], np.eye(3))[0, 0]
    assert B_s == pytest.approx(rot.T @ B_base)


@settings(max_examples=10, deadline=None)
@given(st.lists(st.floats(-180, 180), min_size=3, max_size=3),
       st.integers(0, 5), st.floats(0.2, 1.5))
def test_delta_b_magnitude_is_unchanged_by_rotating_a_sensor(angles, tendon, tension):
    model = CosseratModel(PAPER)
    s0 = model.solve(np.zeros(6))
    tau = np.zeros(6)
    tau[tendon] = tension
    s1 = model.solve(tau)
    rot = tuple(map(tuple, Rotation.from_euler("xyz", angles, degrees=True).as_matrix()))
    turned = type(PAPER)(**{**PAPER.__dict__, "sensors": tuple(
        Sensor(s.index, s.position, rot, s.mux_channel, s.i2c_address) for s in PAPER.sensors)})
    def delta(robot_):
        b = field_at_sensors(robot_, [s0.tip_position, s1.tip_position],
                             [s0.tip_rotation, s1.tip_rotation])
        return np.linalg.norm(b[1] - b[0], axis=1)

    assert delta(turned) == pytest.approx(delta(PAPER), rel=1e-12)


@settings(max_examples=8, deadline=None)
@given(st.integers(0, 5), st.floats(0.2, 1.4), st.floats(0.02, 0.3))
def test_delta_b_grows_with_a_single_tendon_tension(tendon, t1, step):
    """In the working range (the grid) the target grows monotonically on the
    sensor the table selects."""
    model = CosseratModel(PAPER)
    s0 = model.solve(np.zeros(6))
    t2 = min(t1 + step, 1.5)
    tips = [s0]
    for T in (t1, t2):
        tau = np.zeros(6)
        tau[tendon] = T
        tips.append(model.solve(tau))
    b = field_at_sensors(PAPER, [s.tip_position for s in tips], [s.tip_rotation for s in tips])
    d = np.linalg.norm(b[1:] - b[0], axis=-1)  # (2, n_sensors)
    # every sensor of the paper layout sees a growing change
    assert np.all(d[1] > d[0])


def test_power_law_fit_recovers_exact_curve():
    d = np.linspace(1, 4, 10)
    fit = fit_power_law(d, 2923.9 * d**-1.583)
    assert fit.a == pytest.approx(2923.9, rel=1e-10)
    assert fit.b == pytest.approx(-1.583, rel=1e-10)
    assert fit.r2 == pytest.approx(1.0, abs=1e-12)


def test_power_law_fit_rejects_bad_data():
    with pytest.raises(ValueError, match="at least 3"):
        fit_power_law([1, 2], [3, 4])
    with pytest.raises(ValueError, match="positive"):
        fit_power_law([1, 2, -3], [3, 4, 5])


def test_shipped_example_is_the_documented_synthetic_data():
    data = read_field_csv(EXAMPLE)
    d, f = synthetic_power_law_data(seed=1)
    assert np.array_equal(data.distance, d) and np.array_equal(data.field, f)
    assert "SYNTHETIC" in EXAMPLE.read_text().splitlines()[0]
    fit = fit_power_law(data.distance, data.field)
    assert fit.a == pytest.approx(PAPER_POWER_LAW[0], rel=0.02)
    assert fit.b == pytest.approx(PAPER_POWER_LAW[1], abs=0.01)
    assert fit.r2 > 0.999


@pytest.mark.parametrize("content,message", [
    ("distance,field\n1,2\n", "header: expected"),
    ("distance_mm,field_uT\n1,2\n2,x\n3,4\n", "data row 3: expected two numbers"),
    ("distance_mm,field_uT\n1,2\n2,-1\n3,4\n", "data row 3: expected positive"),
    ("distance_mm,field_uT\n1,2\n", "expected at least 3 data rows"),
    ("# only a comment\n", "no data"),
])
def test_csv_errors(tmp_path, content, message):
    p = tmp_path / "m.csv"
    p.write_text(content)
    with pytest.raises(ValueError, match=message):
        read_field_csv(p)


def test_magnetization_fit_recovers_polarization():
    mag = PAPER.magnet
    true = Magnet(mag.shape, mag.dimensions, (0.0, 0.0, 1.1), mag.offset, mag.rotation,
                  mag.mass)
    d = np.linspace(0.008, 0.03, 8)
    measured = field_magnitude_at(true, d + 0.0015, "equatorial")
    fit = fit_magnetization(mag, d, measured, axis="equatorial")
    assert fit.polarization == pytest.approx(1.1, rel=1e-4)
    assert fit.offset == pytest.approx(0.0015, abs=1e-6)
    assert fit.rms_rel < 1e-5 and not fit.at_bound
