"""hallhome identify: survey records, the fit, its refusals, the identified
TOML and the command (docs/identify.md)."""

import copy
import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from hallhome.cli import main
from hallhome.identify import cc_single, fit, fit_params, measures_friction
from hallhome.identify_data import IdentifyError, Survey, survey_from_dict, synthetic_survey
from hallhome.identify_out import identified_path, render_identified, write_identified
from hallhome.model import ConstantCurvatureModel, CosseratModel
from hallhome.paths import ROBOTS_DIR
from hallhome.robot import load_robot

ROOT = Path(__file__).resolve().parents[2]
PAPER = ROOT / "lookup_tables" / "robots" / "paper_2seg.toml"


@pytest.fixture(scope="module")
def nominal():
    return load_robot(PAPER)


def perturbed(r):
    """A robot as built: magnet +6 %, segment 1 +2 % long and 8 % stiffer,
    segment 2 1.5 % short and 7 % softer, tendons 3 % further out, tendon 2
    routed 0.6 degrees and tendon 4 -0.8 degrees off, sensor 0 0.5 mm off."""
    s1, s2 = r.segments
    segs = (dataclasses.replace(s1, length=s1.length * 1.02,
                                youngs_modulus=s1.youngs_modulus * 1.08),
            dataclasses.replace(s2, length=s2.length * 0.985,
                                youngs_modulus=s2.youngs_modulus * 0.93))
    J = tuple(np.array(r.magnet.polarization) * 1.06)
    return dataclasses.replace(
        r, segments=segs, magnet=dataclasses.replace(r.magnet, polarization=J),
        tendons=tuple(dataclasses.replace(t, routing_radius=t.routing_radius * 1.03,
                                          routing_angle=t.routing_angle + np.radians(
                                              ANGLE_OFF_DEG.get(t.index, 0.0)))
                      for t in r.tendons),
        sensors=(dataclasses.replace(r.sensors[0], position=(0.0225, 0.0003, 0.1215)),)
        + r.sensors[1:])


ANGLE_OFF_DEG = {2: 0.6, 4: -0.8}


@pytest.fixture(scope="module")
def true_robot(nominal):
    return perturbed(nominal)


@pytest.fixture(scope="module")
def survey_dict(true_robot):
    return synthetic_survey(true_robot, seed=2, weights=((0, 80.0), (3, 80.0)))


@pytest.fixture(scope="module")
def weighted_fit(nominal, survey_dict):
    return fit(nominal, survey_from_dict(survey_dict, nominal))


def test_closed_form_is_the_constant_curvature_model(nominal, true_robot):
    for r in (nominal, true_robot):
        cc = ConstantCurvatureModel(r, samples_per_segment=3)
        for i in range(len(r.tendons)):
            T = [0.0, 0.4, 1.7]
            p, R, take = cc_single(r, i, T, gravity=False)
            for k, t in enumerate(T):
                tau = np.zeros(len(r.tendons))
                tau[i] = t
                s = cc.solve(tau)
                assert np.allclose(p[k], s.tip_position, atol=1e-12)
                assert np.allclose(R[k], s.tip_rotation, atol=1e-12)
                assert take[k] == pytest.approx(s.take_up[i], abs=1e-12)


def test_closed_form_carries_gravity_as_the_cosserat_model_does():
    """paper_2seg upright: its own weight bends a bent robot further (the
    bench's plant has it too). The closed form with gravity in the bending
    plane lands within 0.02 mm of the Cosserat model's tip, which has it in
    full; without it, 0.17-0.21 mm off at 1.5 N."""
    r = load_robot(ROBOTS_DIR / "paper_2seg.toml")
    cos = CosseratModel(r)
    for i in (0, 3):
        tau = np.zeros(len(r.tendons))
        tau[i] = 1.5
        tip = cos.solve(tau).tip_position
        with_g = np.linalg.norm(cc_single(r, i, [1.5])[0][0] - tip)
        without = np.linalg.norm(cc_single(r, i, [1.5], gravity=False)[0][0] - tip)
        assert with_g < 2e-5 and without > 1.5e-4, (i, with_g, without)


@pytest.mark.slow(8)
def test_fit_with_weights_recovers_the_robot_as_built(weighted_fit, true_robot, survey_dict):
    res = weighted_fit
    assert res.refused is None, res.refused
    assert res.stiffness
    # the magnet, the lengths, EI and the sensors trade against each tendon's
    # stretch, which the fit takes from the data too (EA<i>; here it is the
    # description's): each within a few per cent
    J_true = np.linalg.norm(true_robot.magnet.polarization)
    assert res.value("magnet_J") == pytest.approx(J_true, rel=0.05)
    for j, s in enumerate(true_robot.segments):
        assert res.value(f"EI_{j + 1}") == pytest.approx(s.bending_stiffness * 1e3, rel=0.04)
        assert res.value(f"length_{j + 1}") == pytest.approx(s.length * 1e3, rel=0.04)
    assert res.value("radius") == pytest.approx(true_robot.tendons[0].routing_radius * 1e3,
                                                rel=0.01)
    assert res.value("sensor0_x") == pytest.approx(22.5, abs=0.4)
    # what the targets rest on, each tendon's bend per newton, within 1 %
    for i in range(len(true_robot.tendons)):
        assert _bend(res.robot, i) == pytest.approx(_bend(true_robot, i), rel=0.01), i
    # each tendon's bending plane, from the field's direction at the sensors
    for t in true_robot.tendons:
        assert res.value(f"angle{t.index}") == pytest.approx(np.degrees(t.routing_angle),
                                                             abs=0.1), t.index
    for p in survey_dict["pulls"]:
        assert res.value(f"engage{p['tendon']}") == pytest.approx(p["engagement_um"], abs=5.0)
    # the nominal values are far from the truth where it was perturbed: the fit moved them
    assert abs(res.value("magnet_J") - 1.3) > 0.04
    # residuals at the noise of an averaged reading, per tendon and per weight
    assert res.rms_uT < 1.0 and max(res.tendon_rms_uT.values()) < 1.0
    assert len(res.weight_rms_uT) == 2 and max(res.weight_rms_uT) < 1.0
    assert all(np.isfinite(res.sigmas)) and all(res.sigmas > 0)


def test_uncertainty_shrinks_with_weights(nominal, survey_dict, weighted_fit):
    """EI is not fitted without weights; with them it is, and the data
    (not the 30 % prior) determine it."""
    rows = {r["name"]: r for r in weighted_fit.table()}
    assert rows["EI_1"]["from_data"] and rows["EI_1"]["sigma"] < 0.1 * rows["EI_1"]["nominal"]
    d = dict(survey_dict, weights=[])
    res = fit(nominal, survey_from_dict(d, nominal))
    assert not res.stiffness and "EI_1" not in [p.name for p in res.params]
    assert res.refused is None


def test_survey_records_are_checked(nominal, survey_dict):
    def bad(change, match):
        d = copy.deepcopy(survey_dict)
        change(d)
        with pytest.raises(IdentifyError, match=match):
            survey_from_dict(d, nominal)

    bad(lambda d: d.update(format="csv"), "not a survey")
    bad(lambda d: d.update(pulls=[]), "no pulls")
    bad(lambda d: d["pulls"][1].update(tendon=0), "new index")
    bad(lambda d: d["pulls"][0].update(tendon=6), "new index")
    bad(lambda d: d["pulls"][0]["steps"][3][1].pop(), "3 sensors")
    bad(lambda d: d["pulls"][0]["steps"].reverse(), "do not pull")
    bad(lambda d: d["pulls"][0].update(steps=d["pulls"][0]["steps"][:5]), "at least 8")
    bad(lambda d: d["weights"][0].update(mass_g=-1), "mass_g")
    bad(lambda d: d["pulls"][2]["steps"][5][1][0].__setitem__(0, float("nan")), "finite")

    def flat(d):  # a pull that never moves the tip: the readings stay at the baseline
        for s in d["pulls"][4]["steps"]:
            s[1] = d["pulls"][4]["baseline_cuT"]
    bad(flat, "never changed the field")


def test_fit_of_another_robot_is_refused(nominal):
    """A magnet three times stronger than described: the fit runs into the
    plausible range and says which parameter."""
    strong = dataclasses.replace(nominal, magnet=dataclasses.replace(
        nominal.magnet, polarization=(0.0, 0.0, 3.9)))
    res = fit(nominal, survey_from_dict(synthetic_survey(strong, seed=3), nominal))
    assert res.refused is not None and "magnet_J" in res.refused


def test_helical_routing_is_not_fitted(nominal, survey_dict):
    trio = load_robot(ROOT / "lookup_tables" / "robots" / "trio_3seg.toml")
    twisted = dataclasses.replace(nominal, tendons=(dataclasses.replace(
        nominal.tendons[0], twist=0.01),) + nominal.tendons[1:])
    assert any(t.twist for t in trio.tendons)
    with pytest.raises(IdentifyError, match="helical"):
        fit(twisted, survey_from_dict(survey_dict, nominal))


@pytest.mark.slow(9)
def test_scrambled_data_are_refused(nominal, survey_dict):
    d = copy.deepcopy(survey_dict)
    rng = np.random.default_rng(1)
    for p in d["pulls"]:
        fields = [s[1] for s in p["steps"]]
        order = rng.permutation(len(fields))
        for s, k in zip(p["steps"], order):
            s[1] = fields[k]
    res = fit(nominal, survey_from_dict(d, nominal))
    assert res.refused is not None
    assert "does not explain" in res.refused or "range" in res.refused


def test_identified_toml_loads_with_the_fitted_values(tmp_path, nominal, weighted_fit):
    out, back = write_identified(weighted_fit, nominal, "synthetic.json", tmp_path / "p_id.toml")
    text = out.read_text()
    assert text.startswith("# Identified ") and "synthetic.json" in text
    assert "# identified: " in text and "+-" in text
    fitted = weighted_fit.robot
    assert back.segments[0].length == pytest.approx(fitted.segments[0].length, rel=1e-5)
    assert back.segments[1].bending_stiffness == pytest.approx(
        fitted.segments[1].bending_stiffness, rel=1e-4)
    assert back.sensors[0].position == pytest.approx(fitted.sensors[0].position, abs=1e-7)
    assert np.linalg.norm(back.magnet.polarization) == pytest.approx(
        weighted_fit.value("magnet_J"), rel=1e-5)
    # each tendon's stretch, fitted with the weights, is written (effective)
    assert back.tendons[2].stiffness_ea == pytest.approx(fitted.tendons[2].stiffness_ea, rel=1e-4)
    assert "effective: with the free length's error" in text
    # what was not fitted is unchanged, comments included
    assert back.tendons[2].free_length == nominal.tendons[2].free_length
    assert back.tendons[2].spool_radius == nominal.tendons[2].spool_radius
    assert "# NiTi" in text
    assert identified_path(nominal).name == "paper_2seg_id.toml"


def test_refused_fit_and_the_original_are_not_written(tmp_path, nominal, weighted_fit):
    refused = dataclasses.replace(weighted_fit, refused="for the test")
    with pytest.raises(IdentifyError, match="refused"):
        write_identified(refused, nominal, "s.json", tmp_path / "x.toml")
    assert not (tmp_path / "x.toml").exists()
    with pytest.raises(IdentifyError, match="overwrite"):
        write_identified(weighted_fit, nominal, "s.json", nominal.path)


def test_values_without_their_key_in_the_file_are_refused(tmp_path, nominal, weighted_fit):
    src = tmp_path / "paper_2seg.toml"
    src.write_text("\n".join(l for l in PAPER.read_text().splitlines()
                             if not l.startswith("position_mm")) + "\n")
    crippled = dataclasses.replace(nominal, path=src)
    with pytest.raises(IdentifyError, match="position_mm"):
        render_identified(weighted_fit, crippled, "s.json")


@pytest.mark.slow(7)
def test_command_fits_writes_and_plots(tmp_path, survey_dict):
    robot = tmp_path / "paper_2seg.toml"
    robot.write_text(PAPER.read_text())
    sv = tmp_path / "survey.json"
    sv.write_text(json.dumps(survey_dict))
    res = CliRunner().invoke(main, ["identify", "fit", str(robot), str(sv), "--plots",
                                    str(tmp_path / "plots"), "--json"])
    assert res.exit_code == 0, res.output
    out = json.loads(res.stdout)
    assert out["refused"] is None and out["written"].endswith("paper_2seg_id.toml")
    assert (tmp_path / "paper_2seg_id.toml").exists()
    for p in out["plots"]:
        assert Path(p).stat().st_size > 10000
    names = [r["name"] for r in out["parameters"]]
    assert "magnet_J" in names and "EI_2" in names


def test_command_refuses_garbage_and_writes_nothing(tmp_path, survey_dict):
    robot = tmp_path / "paper_2seg.toml"
    robot.write_text(PAPER.read_text())
    d = copy.deepcopy(survey_dict)
    d["pulls"][0]["steps"] = d["pulls"][0]["steps"][:3]
    sv = tmp_path / "survey.json"
    sv.write_text(json.dumps(d))
    res = CliRunner().invoke(main, ["identify", "fit", str(robot), str(sv)])
    assert res.exit_code == 1 and "at least 8" in res.output
    assert not (tmp_path / "paper_2seg_id.toml").exists()
    sv.write_text("{not json")
    res = CliRunner().invoke(main, ["identify", "fit", str(robot), str(sv)])
    assert res.exit_code == 1 and "survey.json" in res.output


def test_help_documents_the_procedure():
    res = CliRunner().invoke(main, ["identify", "--help"])
    assert res.exit_code == 0
    for word in ("Survey", "Weights", "Fit", "Install", "--survey"):
        assert word in res.output


def test_survey_from_another_robot_is_refused_with_the_reason(nominal, survey_dict):
    other = dict(survey_dict, robot="trio_3seg")
    with pytest.raises(IdentifyError, match="another robot.*--any-robot"):
        survey_from_dict(other, nominal)
    assert survey_from_dict(other, nominal, any_robot=True).pulls
    # the identified description's board name is the same robot
    assert survey_from_dict(dict(survey_dict, robot="paper_2seg_id"), nominal).pulls
    fewer = copy.deepcopy(survey_dict)
    for p in fewer["pulls"]:
        p["baseline_cuT"] = p["baseline_cuT"][:2]
    with pytest.raises(IdentifyError, match="2 sensors, the description has 3"):
        survey_from_dict(fewer, nominal)


def test_a_robot_far_from_its_description_is_refused(nominal):
    """Segments 40 % longer than described (another robot under the same
    name): no parameter set inside the plausible ranges explains it."""
    s1, s2 = nominal.segments
    longer = dataclasses.replace(nominal, segments=(
        dataclasses.replace(s1, length=s1.length * 1.4),
        dataclasses.replace(s2, length=s2.length * 1.4)))
    res = fit(nominal, survey_from_dict(synthetic_survey(longer, seed=3), nominal))
    assert res.refused is not None
    assert "does not fit this robot" in res.refused and "uT rms against" in res.refused


def test_a_fit_that_does_not_converge_is_refused(nominal, survey_dict):
    calls = []
    res = fit(nominal, survey_from_dict(dict(survey_dict, weights=[]), nominal), max_nfev=3,
              progress=lambda n, rms: calls.append((n, rms)))
    assert res.refused is not None and "did not converge" in res.refused
    assert [n for n, _ in calls] == list(range(1, len(calls) + 1)) and len(calls) >= 3
    assert all(rms > 0 for _, rms in calls)


def test_command_guides_the_next_step_and_warns_without_weights(tmp_path, survey_dict):
    robot = tmp_path / "paper_2seg.toml"
    robot.write_text(PAPER.read_text())
    sv = tmp_path / "survey.json"
    sv.write_text(json.dumps(dict(survey_dict, weights=[])))
    res = CliRunner().invoke(main, ["identify", "fit", str(robot), str(sv)])
    assert res.exit_code == 0, res.output
    assert "no weight records: the stiffness stays nominal" in res.output
    assert "fitting 25 parameters" in res.output  # fit_params(): angles included
    out = tmp_path / "paper_2seg_id.toml"
    assert out.exists()
    assert (f"next: hallhome tables {out} --out-dir {tmp_path}, then make flash "
            f"ROBOT=paper_2seg_id ROBOTS_DIR={tmp_path} TABLES_DIR={tmp_path}") in res.output


@pytest.mark.slow(6)
def test_command_refuses_another_robots_survey_unless_told(tmp_path, survey_dict):
    robot = tmp_path / "paper_2seg.toml"
    robot.write_text(PAPER.read_text())
    sv = tmp_path / "survey.json"
    sv.write_text(json.dumps(dict(survey_dict, robot="other_bot")))
    res = CliRunner().invoke(main, ["identify", "fit", str(robot), str(sv), "--no-write"])
    assert res.exit_code == 1 and "survey is of robot 'other_bot'" in res.output
    res = CliRunner().invoke(main, ["identify", "fit", str(robot), str(sv), "--no-write",
                                    "--any-robot"])
    assert res.exit_code == 0, res.output
    assert "not written (--no-write)" in res.output
    assert not (tmp_path / "paper_2seg_id.toml").exists()


@pytest.mark.slow(6)
def test_a_weight_on_every_tendon_fits_each_tendons_radius_and_stretch(tmp_path, nominal):
    """Tendons 1 and 4 routed 3 % further out, tendon 2 2 % further in, tendon
    5's tendon 30 % stiffer (EA): with one weight per tendon the fit gives
    each tendon its own radius and EA and finds them."""
    true = dataclasses.replace(nominal, tendons=tuple(
        dataclasses.replace(t, routing_radius=t.routing_radius * f, stiffness_ea=t.stiffness_ea * g)
        for t, f, g in zip(nominal.tendons, (1.0, 1.03, 0.98, 1.0, 1.03, 1.0),
                           (1.0, 1.0, 1.0, 1.0, 1.0, 1.3))))
    d = synthetic_survey(true, seed=5, weights=tuple((i, 80.0) for i in range(6)))
    sv = survey_from_dict(d, nominal)
    res = fit(nominal, sv)
    assert res.refused is None, res.refused
    names = [p.name for p in res.params]
    assert "radius" not in names and all(f"radius{i}" in names and f"EA{i}" in names
                                         for i in range(6))
    # what 1 N on each tendon does to the tip (its bending angle) within 1 %: the
    # radius, the lengths and EI alone trade against each other within their sigma
    for i in range(6):
        angles = [np.arccos(cc_single(r, i, [1.0])[1][0][2, 2]) for r in (res.robot, true)]
        assert angles[0] == pytest.approx(angles[1], rel=0.01), i
    assert res.value("radius1") > res.value("radius0") > res.value("radius2")
    assert res.value("EA5") > 1.1 * max(res.value(f"EA{i}") for i in range(5))
    out, back = write_identified(res, nominal, "s.json", tmp_path / "p_id.toml")
    assert back.tendons[1].routing_radius == pytest.approx(res.value("radius1") * 1e-3, rel=1e-5)
    assert back.tendons[5].stiffness_ea == pytest.approx(res.value("EA5"), rel=1e-4)
    assert "effective: with the free length's error" in out.read_text()
    # one weight per segment: the common radius, as before
    seg = dict(d, weights=[w for w in d["weights"] if w["tendon"] in (0, 3)])
    assert "radius" in [p.name for p in fit(nominal, survey_from_dict(seg, nominal),
                                            max_nfev=1).params]


def test_friction_needs_two_masses_on_one_tendon(nominal):
    pulls = survey_from_dict(synthetic_survey(nominal, seed=1), nominal)
    d = synthetic_survey(nominal, seed=1, weights=((0, 80.0), (3, 80.0)))
    assert not measures_friction(survey_from_dict(d, nominal))
    d = synthetic_survey(nominal, seed=1, weights=((0, 80.0), (3, 100.0), (3, 80.0)))
    assert not measures_friction(survey_from_dict(d, nominal))  # 1.25x: too close
    d = synthetic_survey(nominal, seed=1, weights=((0, 40.0), (0, 120.0)))
    assert measures_friction(survey_from_dict(d, nominal))
    assert "friction" not in [p.name for p in fit_params(nominal, pulls)]


@pytest.fixture(scope="module")
def friction_case(tmp_path_factory, true_robot):
    """A description that leaves the friction out (the TOML without its
    friction keys) and a robot as built with 14 mN + 2 %, surveyed with two
    masses per segment."""
    tmp = tmp_path_factory.mktemp("friction")
    src = tmp / "paper_2seg.toml"
    src.write_text("\n".join(l for l in PAPER.read_text().splitlines()
                             if not l.startswith("friction_mN")) + "\n")
    desc = load_robot(src)
    assert all(t.friction_N is None for t in desc.tendons)
    true = dataclasses.replace(true_robot, tendons=tuple(
        dataclasses.replace(t, friction_N=0.014) for t in true_robot.tendons))
    d = synthetic_survey(true, seed=4, weights=((0, 40.0), (0, 120.0), (3, 40.0), (3, 120.0)))
    return desc, true, survey_from_dict(d, desc)


@pytest.mark.slow(12)
def test_two_masses_fit_the_friction_the_description_leaves_out(friction_case, tmp_path):
    desc, true, sv = friction_case
    res = fit(desc, sv)
    assert res.refused is None
    assert res.value("friction") == pytest.approx(14.0, abs=2.0)
    # the targets follow: the tension reaching the tendon's end at 1.5 N
    tip = res.robot.tip_tension(res.robot.tendons[3], 1.5)
    assert tip == pytest.approx(true.tip_tension(true.tendons[3], 1.5), abs=0.003)
    # one mass cannot tell: the friction stays the description's (none)
    one = Survey(sv.pulls, tuple(w for w in sv.weights if w.mass < 0.05), sv.truth, sv.source,
                 sv.meta)
    assert "friction" not in [p.name for p in fit(desc, one).params]
    # the identified TOML gets the key its original leaves out, and loads
    out, back = write_identified(res, desc, "s.json", tmp_path / "p_id.toml")
    assert all(t.friction_N == pytest.approx(res.value("friction") * 1e-3, abs=1e-5)
               for t in back.tendons)
    assert out.read_text().count("friction_mN = ") == len(desc.tendons)


@pytest.mark.slow(10)
def test_friction_below_zero_is_refused_with_the_way_out(friction_case):
    desc, true, sv = friction_case
    # the light mass reads as heavier than it is: the friction far below zero
    light = Survey(sv.pulls, tuple(dataclasses.replace(w, delta=w.delta * (1.3 if w.mass < 0.05
                                                                          else 1.0))
                                   for w in sv.weights), sv.truth, sv.source, sv.meta)
    res = fit(desc, light)
    assert res.refused is not None and res.refused.startswith("friction")
    assert "--no-friction" in res.refused
    # the way out leaves the friction out (its parameters are what counts
    # here: one model evaluation, not a whole fit)
    kept = fit(desc, light, friction=False, max_nfev=1)
    assert "friction" not in [p.name for p in kept.params]


def test_command_fits_the_friction_of_two_masses_unless_told(tmp_path, friction_case,
                                                           monkeypatch):
    """The command's choice reaches the fit (whose friction the test above
    checks): each fit here is cut to one model evaluation, refused as not
    converged, and its parameters are still listed."""
    import hallhome.identify as identify

    desc, true, sv = friction_case
    robot = tmp_path / "paper_2seg.toml"
    robot.write_text(desc.path.read_text())
    d = synthetic_survey(true, seed=4, weights=((0, 40.0), (0, 120.0), (3, 40.0), (3, 120.0)))
    path = tmp_path / "survey.json"
    path.write_text(json.dumps(d))
    asked = []

    def one_evaluation(*args, **kw):
        asked.append(kw["friction"])
        return fit(*args, **kw, max_nfev=1)

    monkeypatch.setattr(identify, "fit", one_evaluation)
    names = {}
    for flag in ([], ["--no-friction"]):
        res = CliRunner().invoke(main, ["identify", "fit", str(robot), str(path), "--no-write",
                                        "--json", *flag])
        assert res.exit_code == 1 and "did not converge" in res.stderr, res.output
        names[bool(flag)] = [r["name"] for r in json.loads(res.stdout)["parameters"]]
    assert asked == [True, False]
    assert "friction" in names[False] and "friction" not in names[True]
    assert "--no-friction" in CliRunner().invoke(main, ["identify", "fit", "--help"]).output


def _bend(r, i, tension=1.0):
    """Tendon i's tip bending angle (rad) under ``tension`` alone."""
    return float(np.arccos(cc_single(r, i, [tension])[1][0][2, 2]))


def test_one_weight_per_segment_fits_each_tendons_stretch(nominal, true_robot):
    """Tendon 1's stretch 25 % larger than described (EA 0.8x: a softer wire
    or a longer free length), tendon 4's 20 % smaller (EA 1.25x), one weight
    per segment on tendons 0 and 3. The fit gives every tendon its own EA
    beside the common radius and finds both against their segment's other
    tendons; with the description's EA the two pulls' take-ups would drag
    the shared magnet and lengths instead."""
    true = dataclasses.replace(true_robot, tendons=tuple(
        dataclasses.replace(t, stiffness_ea=t.stiffness_ea * g)
        for t, g in zip(true_robot.tendons, (1.0, 0.8, 1.0, 1.0, 1.25, 1.0))))
    d = synthetic_survey(true, seed=7, weights=((0, 80.0), (3, 80.0)))
    res = fit(nominal, survey_from_dict(d, nominal))
    assert res.refused is None, res.refused
    names = [p.name for p in res.params]
    assert "radius" in names and "radius1" not in names
    assert all(f"EA{i}" in names for i in range(6))
    # each against the other tendons of its segment: a common factor on
    # every EA trades against the common radius (found about 5 % low here)
    ea = [res.value(f"EA{i}") / t.stiffness_ea for i, t in enumerate(true.tendons)]
    assert ea[1] / np.mean([ea[0], ea[2]]) == pytest.approx(1.0, abs=0.04), ea
    assert ea[4] / np.mean([ea[3], ea[5]]) == pytest.approx(1.0, abs=0.04), ea
    assert res.value("EA1") < 0.85 * nominal.tendons[1].stiffness_ea
    assert res.value("EA4") > 1.1 * nominal.tendons[4].stiffness_ea
    assert res.value("magnet_J") == pytest.approx(np.linalg.norm(true.magnet.polarization),
                                                  rel=0.05)
    # what the targets rest on: each tendon's bend per newton (its radius over
    # EI; every tendon has the true robot's common radius here)
    for i in range(6):
        assert _bend(res.robot, i) == pytest.approx(_bend(true, i), rel=0.015), i


def test_survey_cannot_tell_a_tendons_radius_from_its_stretch(nominal):
    """Why a tendon without a weight keeps the common radius: routed 2 %
    further out, with its EA raised to match the take-up, tendon 1's survey
    (the field at every sensor against the take-up, the engagement free)
    changes by less than 0.05 uT rms, a tenth of one reading's noise, while
    its bend per newton, and so its target, moves by 2 %."""
    from scipy.optimize import least_squares

    from hallhome.field import field_at_sensors

    T = np.linspace(0.0, 1.6, 40)

    def curve(r):
        p, R, take = cc_single(r, 1, T)
        return take, (field_at_sensors(r, p, R) - field_at_sensors(r, p[:1], R[:1])) * 1e6

    def tendon1(**kw):
        ts = list(nominal.tendons)
        ts[1] = dataclasses.replace(ts[1], **kw)
        return dataclasses.replace(nominal, tendons=tuple(ts))

    take0, b0 = curve(nominal)
    x = np.linspace(0.0, 0.85 * take0[-1], 40)

    def at(take, b, shift=0.0):
        return np.stack([np.interp(x - shift, take, b[:, k, a]) for k in range(b.shape[1])
                         for a in range(3)], axis=1)

    ref = at(take0, b0)
    t1 = nominal.tendons[1]
    wider = dict(routing_radius=t1.routing_radius * 1.02)
    sol = least_squares(lambda z: (at(*curve(tendon1(**wider, stiffness_ea=t1.stiffness_ea * z[0])),
                                      z[1] * 1e-6) - ref).ravel(), [1.0, 0.0])
    assert np.sqrt(np.mean(sol.fun ** 2)) < 0.05
    assert 1.02 < sol.x[0] < 1.2  # within the spread of a tendon's EA and free length
    other = tendon1(**wider, stiffness_ea=t1.stiffness_ea * sol.x[0])
    assert _bend(other, 1) == pytest.approx(1.02 * _bend(nominal, 1), rel=0.003)
    # the same radius with the description's EA: the survey sees it
    wrong = at(*curve(tendon1(**wider))) - ref
    assert np.sqrt(np.mean(wrong ** 2)) > 0.3


def test_a_pulls_engagement_is_found_at_its_kink():
    """engagement_ticks() on seeded hinges: flat (noise) up to the kink,
    then a field that rises and bends, as a pull's does; every kink within
    a third of a tick, whichever way the ticks run. A pull that never leaves
    the noise has none."""
    from hallhome.identify_data import engagement_ticks

    rng = np.random.default_rng(17)
    noise = 0.6e-6
    for _ in range(40):
        kink = rng.uniform(100, 200)
        sign = rng.choice([-1, 1])
        start = rng.integers(-5000, 5000)
        ticks = start + sign * np.arange(0, 400, 4.0)
        x = np.clip(np.abs(ticks - start) - kink, 0, None)
        slope = rng.uniform(1.0, 3.0, (2, 3)) * 1e-6 * rng.choice([-1, 1], (2, 3))
        delta = x[:, None, None] * slope[None] * (1 - x[:, None, None] / 2000.0)
        delta = delta + rng.normal(0, noise / 2, delta.shape)  # averaged readings
        got = engagement_ticks(ticks, delta, noise)
        assert abs(sign * (got - start) - kink) < 0.33, (kink, got, start, sign)
    flat = rng.normal(0, noise, (50, 2, 3))
    assert engagement_ticks(np.arange(50) * 4.0, flat, noise) is None


def held_record(d, tendon, hold, shift_ticks):
    """A held pull made from a synthetic survey's pull of ``tendon``: its
    steps moved ``shift_ticks`` earlier, the hold's field standing in its
    baseline (that of ``hold``'s last step)."""
    p = next(q for q in d["pulls"] if q["tendon"] == tendon)
    a = next(q for q in d["pulls"] if q["tendon"] == hold)
    return {"tendon": tendon, "hold_tendon": hold, "hold_ticks": a["steps"][-1][0],
            "baseline_cuT": p["baseline_cuT"],
            "steps": [[s[0] - shift_ticks, s[1]] for s in p["steps"]]}


def test_held_pull_records_are_checked(nominal, survey_dict):
    from hallhome.identify_data import survey_from_dict

    d = copy.deepcopy(survey_dict)
    d["held"] = [held_record(d, 1, 2, 30)]
    sv = survey_from_dict(d, nominal)
    (h,) = sv.held
    assert (h.tendon, h.hold) == (1, 2)
    per_tick = nominal.tendons[1].metres_per_tick * nominal.tendons[1].pull_dir
    assert h.shift == pytest.approx(-30 * per_tick, abs=0.4 * abs(per_tick))

    def bad(change, match):
        e = copy.deepcopy(d)
        change(e)
        with pytest.raises(IdentifyError, match=match):
            survey_from_dict(e, nominal)

    bad(lambda e: e["held"][0].update(hold_tendon=1), "two indices")
    bad(lambda e: e["held"][0].update(hold_tendon=9), "two indices")
    bad(lambda e: e["held"][0].update(hold_tendon=3), "cannot hold")  # another segment
    sideways = copy.deepcopy(d)  # a hold 90 degrees off: no shift along the tendon
    sideways["held"] = [held_record(sideways, 1, 2, 30)]
    with pytest.raises(IdentifyError, match="cannot hold"):
        survey_from_dict(sideways, dataclasses.replace(nominal, tendons=tuple(
            dataclasses.replace(t, routing_angle=np.radians(270.0)) if t.index == 2 else t
            for t in nominal.tendons)))
    bad(lambda e: e.update(pulls=[p for p in e["pulls"] if p["tendon"] != 2]),
        "need their pulls alone")
    bad(lambda e: e["held"][0].pop("hold_ticks"), "hold_ticks")
    bad(lambda e: e["held"][0].update(steps=e["held"][0]["steps"][:4]), "at least 8")

    def flat(e):
        for s in e["held"][0]["steps"]:
            s[1] = e["held"][0]["baseline_cuT"]
    bad(flat, "never changed the field")

    def engaged(e):  # the bend took up the slack before the pull's first step
        steps = e["held"][0]["steps"]
        first = next(k for k, s in enumerate(steps)
                     if max(abs(a - b) for a, b in zip(s[1][0], e["held"][0]["baseline_cuT"][0]))
                     > 1000)
        e["held"][0]["steps"] = steps[first - 1:]
    bad(engaged, "started engaged")
