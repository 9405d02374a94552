"""Shared by the pytest suites (host, chaos, sim), which `make test` runs in
one session, a worker per core (pytest -n, --dist worksteal).

Workers take the collected tests in order and idle workers steal the back
half of a busy worker's queue, so the session ends soonest when the long
tests start first:

1. the tests that run `make sim` for real (marker ``make_sim``, or the
   ``make_sim_lock`` fixture of tests/sim/conftest.py): they take turns on
   one lock, so they go first, together, to the first worker's queue, and
   are the last a second worker steals;
2. the tests marked ``slow(seconds)``, longest first: ``seconds`` is about
   what the test takes alone on an idle machine (marked from about 12 s);
3. the rest, in their files' order.

`pytest -m "not slow"` leaves the long ones out while working on something.
"""

import hallhome  # noqa: F401  (first: it sets one BLAS thread before numpy loads)


def pytest_configure(config):
    config.addinivalue_line(
        "markers", "slow(seconds): about that long alone on an idle machine; started first")
    config.addinivalue_line(
        "markers", "make_sim: runs `make sim` for real (tests/sim/conftest.py make_sim_lock)")


def _rank(item):
    slow = item.get_closest_marker("slow")
    seconds = slow.args[0] if slow and slow.args else 0
    if item.get_closest_marker("make_sim") or "make_sim_lock" in getattr(item, "fixturenames", ()):
        return (0, -seconds)
    return (1, -seconds) if slow else (2, 0)


def pytest_collection_modifyitems(config, items):
    items.sort(key=_rank)  # stable: equals keep the files' order
