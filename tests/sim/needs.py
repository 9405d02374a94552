"""What the bench suites need built before they run (`make sim-test` builds
it): a missing file fails the test with the command that builds it."""

import pytest


def built(*paths):
    missing = [p for p in paths if not p.exists()]
    if missing:
        pytest.fail("not built (run `make sim-test`): " + ", ".join(map(str, missing)))
