"""Shared by the sim suite, which `make sim-test` runs in several workers
(pytest -n)."""

import fcntl
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture
def make_sim_lock():
    """Held for the whole test by the tests that run `make sim` and the
    files it keeps under build/ (the identification per robot and seed, the
    EEPROM images, build/sim/summary.json, the console link, the identified
    robot's firmware directory): one such test at a time, whichever worker
    it runs in."""
    lock = ROOT / "build" / "sim" / ".make-sim.lock"
    lock.parent.mkdir(parents=True, exist_ok=True)
    with open(lock, "w") as f:
        fcntl.flock(f, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(f, fcntl.LOCK_UN)
