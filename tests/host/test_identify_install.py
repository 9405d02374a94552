"""`hallhome identify install`'s plan: what it sends, and every reason it
refuses (the board's table must have the same tendons, grid and sensor
selection as the identified description)."""

from hallhome.op_install import plan
from hallhome.op_learn import TableInfo


def board(n=2, grid=(200, 800), sensors=(0, 1), name="paper_2seg"):
    return TableInfo(name, "0x12345678", list(grid), 800, 0.6, n,
                     {i: s for i, s in enumerate(sensors)})


def table(n=2, grid=(200, 800), sensors=(0, 1)):
    return {"n_tendons": n, "grid_mN": list(grid),
            "tendons": [{"sensor": s, "target_lsb": [200 * (i + 1), 600 * (i + 1)]}
                        for i, s in enumerate(sensors)]}


def test_a_fitting_description_plans_every_target_in_uT():
    p = plan(table(), board(), "paper_2seg_id")
    assert p.refusals == []
    # the table's LSB (15 cuT each) in uT
    assert p.targets == {0: [(200, 30.0), (800, 90.0)], 1: [(200, 60.0), (800, 180.0)]}


def test_every_mismatch_is_named():
    p = plan(table(sensors=(0, 2)), board(), "paper_2seg_id")
    assert p.refusals == ["tendon 1: the identified robot selects sensor 2, the board's table "
                          "sensor 1 (the targets are that sensor's field)"]
    p = plan(table(grid=(300, 800)), board(), "paper_2seg")
    assert len(p.refusals) == 1 and "tension grid [300, 800] mN here" in p.refusals[0]
    p = plan(table(n=1, sensors=(0,)), board(), "paper_2seg")
    assert p.refusals == ["1 tendons here, 2 in the board's table"]
    p = plan(table(), board(), "trio_3seg")
    assert p.refusals == ["the board runs the table of 'paper_2seg', this description is "
                          "'trio_3seg' (--force installs anyway)"]
    assert plan(table(), board(), "trio_3seg", force=True).refusals == []
