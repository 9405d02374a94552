"""The model's speed-ups keep its numbers: ``solve_many`` gives, to the
last bit, what ``CosseratModel.solve`` gives one problem at a time; the
identify fit gives the same with its Jacobian's Cosserat solves batched as
without; and the model gives what it gave before the speed-ups (values
recorded with the unbatched implementation)."""

import dataclasses

import numpy as np
import pytest

from hallhome import identify, model
from hallhome.identify_data import survey_from_dict, synthetic_survey
from hallhome.model import CosseratModel, ModelError, solve_many
from hallhome.paths import ROBOTS_DIR
from hallhome.robot import load_robot

PAPER = load_robot(ROBOTS_DIR / "paper_2seg.toml")
TRIO = load_robot(ROBOTS_DIR / "trio_3seg.toml")  # three segments, helical routing

FIELDS = ("s", "positions", "rotations", "tensions", "path_lengths", "displacements",
          "base_moment", "residual", "iterations", "stretches")


def assert_same(a, b):
    for f in FIELDS:
        x, y = np.asarray(getattr(a, f)), np.asarray(getattr(b, f))
        assert x.shape == y.shape and x.tobytes() == y.tobytes(), f


def neighbours(r, step=1e-8):
    """``r`` and robots one parameter off, as the columns of a
    finite-difference Jacobian see them."""
    s0, s1 = r.segments[0], r.segments[1]
    t0 = r.tendons[0]
    longer = dataclasses.replace(s0, length=s0.length * (1 + step))
    stiffer = dataclasses.replace(s1, youngs_modulus=s1.youngs_modulus * (1 + step))
    turned = dataclasses.replace(t0, routing_angle=t0.routing_angle + step)
    return [r, dataclasses.replace(r, segments=(longer,) + r.segments[1:]),
            dataclasses.replace(r, segments=(s0, stiffer) + r.segments[2:]),
            dataclasses.replace(r, tendons=(turned,) + r.tendons[1:])]


def test_solve_many_is_solve_to_the_last_bit():
    heavy = dataclasses.replace(PAPER, gravity=(9.81 * 5, 0.0, -9.81),
                                magnet=dataclasses.replace(PAPER.magnet, mass=0.02))
    jobs = []
    for r in neighbours(PAPER):
        for tau in ([0.0] * 6, [0.8, 0, 0, 0, 0, 0], [0, 0, 0, 1.2, 0, 0],
                    [0.3, 0, 0.5, 1.0, 0, 0]):
            jobs.append((CosseratModel(r, steps_per_segment=8), tau))
    for r in neighbours(TRIO):
        for tau in ([0.6] + [0.0] * 8 + [0.9], [0.0] * 4 + [1.1] + [0.0] * 5):
            jobs.append((CosseratModel(r, steps_per_segment=6), tau))
    # sideways gravity on a heavy magnet: scipy's hybrid Powell solver's turn
    jobs += [(CosseratModel(heavy, steps_per_segment=8), [0, 0, 0, t, 0, 0.5])
             for t in (1.5, 1.2)]
    jobs.append((CosseratModel(PAPER, steps_per_segment=8, gravity=False), [0, 0, 0, 1.0, 0, 0]))
    batched = solve_many([m for m, _ in jobs], [tau for _, tau in jobs])
    for (m, tau), sol in zip(jobs, batched):
        assert_same(m.solve(tau), sol)
    assert max(sol.iterations for sol in batched) > 1 + model._CHORD_STEPS


def test_solve_many_refuses_as_solve():
    stuck = dataclasses.replace(PAPER, gravity=(9.81 * 50, 0.0, -9.81),
                                magnet=dataclasses.replace(PAPER.magnet, mass=0.02))
    models = [CosseratModel(r, steps_per_segment=8) for r in (PAPER, stuck)]
    tau = [0, 0, 0, 1.5, 0, 0.5]
    with pytest.raises(ModelError, match="shooting did not converge"):
        models[1].solve(tau)
    with pytest.raises(ModelError, match="shooting did not converge"):
        solve_many(models, [tau, tau])
    with pytest.raises(ValueError, match="tensions"):
        solve_many(models, [tau, [-1.0] + tau[1:]])


def test_fit_is_the_same_with_its_columns_batched(monkeypatch):
    d = synthetic_survey(PAPER, seed=1, weights=((0, 80.0), (3, 80.0)))
    sv = survey_from_dict(d, PAPER)
    batches = []

    def counted(models, tensions):
        batches.append(len(models))
        return solve_many(models, tensions)

    monkeypatch.setattr(identify, "solve_many", counted)
    batched = identify.fit(PAPER, sv, max_nfev=2)
    assert batches and max(batches) > 4  # the columns' solves went together
    monkeypatch.setattr(identify._Model, "prepare", lambda self, robots: None)
    alone = identify.fit(PAPER, sv, max_nfev=2)
    for a, b in ((batched.values, alone.values), (batched.sigmas, alone.sigmas),
                 (batched.rms_uT, alone.rms_uT), (batched.chi2_red, alone.chi2_red)):
        assert np.asarray(a).tobytes() == np.asarray(b).tobytes()


# Tip positions (m), tip z axes and tendon path lengths (m) from the model as
# it was before the batched integration, to 1e-9: another machine's BLAS may
# round its small products otherwise, and the shooting stops at a residual of
# 1e-10, so a last bit can take one Newton step more or less there; a change
# of the model moves these by far more.
RECORDED = [
    (PAPER, [0.8, 0, 0, 0, 0, 0],
     [0.0026196815921782682, 0.004537421617305691, 0.10584547462724815],
     [0.03298658606279119, 0.057134443028997714, 0.9978213971245998],
     [0.052702975774138065, 0.05314712247954739, 0.05314712247954739, 0.1058505155868674,
      0.1058505155868674, 0.1062961581718153]),
    (PAPER, [0, 0, 0, 1.2, 0.3, 0],
     [0.009138800450043123, 0.002261266671297767, 0.10543826364912849],
     [0.17123627680034945, 0.04236999021387097, 0.9843185060928351],
     [0.05271975276460278, 0.05338823326156356, 0.05288687288884294, 0.1052219723148855,
      0.10621790786976779, 0.10654988638806186]),
    (TRIO, [0.6] + [0.0] * 8 + [0.9],
     [0.0003855037111343444, -0.0034094484898333634, 0.11992818223611817],
     [0.010950388461716852, -0.06240353819200655, 0.9979909255166891],
     [0.0449808453529216, 0.04507386470413624, 0.045017165848090145, 0.044924146496894725,
      0.0850911588467706, 0.08504496648698943, 0.08485802777460598, 0.12011237572432153,
      0.12015084092550082, 0.11985277233488288]),
]


@pytest.mark.parametrize("robot, tau, tip, axis, paths", RECORDED)
def test_the_model_gives_what_it_gave(robot, tau, tip, axis, paths):
    sol = CosseratModel(robot, steps_per_segment=8).solve(tau)
    assert sol.tip_position == pytest.approx(tip, rel=1e-9, abs=1e-12)
    assert sol.tip_rotation[:, 2] == pytest.approx(axis, rel=1e-9, abs=1e-12)
    assert sol.path_lengths == pytest.approx(paths, rel=1e-9)
