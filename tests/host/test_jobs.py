"""hallhome.jobs.map_jobs: results in the order of the arguments, one
on_result per item, fn's exception passed on, in this process and in
workers."""

import os
import time

import pytest

from hallhome.jobs import map_jobs


def _square(i: int, flag: str) -> int:
    """i*i; in workers (flag: a path) item 0 ends only once item 1 has
    (it waits up to 10 s for the file item 1 writes), so the two finish in
    the other order whatever the machine's load"""
    if flag and i == 0:
        deadline = time.monotonic() + 10.0
        while not os.path.exists(flag) and time.monotonic() < deadline:
            time.sleep(0.01)
    elif flag and i == 1:
        with open(flag, "w"):
            pass
    return i * i


def _fails_on(i: int, bad: int) -> int:
    if i == bad:
        raise ValueError(f"item {i}")
    return i


@pytest.mark.parametrize("jobs", [1, 2])
def test_results_in_input_order_and_one_report_each(jobs, tmp_path):
    n = 3
    flag = str(tmp_path / "item1-done") if jobs > 1 else ""
    seen = []
    out = map_jobs(_square, [(i, flag) for i in range(n)], jobs,
                   lambda i, r: seen.append((i, r)))
    assert out == [i * i for i in range(n)]
    assert sorted(seen) == [(i, i * i) for i in range(n)]
    if jobs == 1:
        assert seen == [(i, i * i) for i in range(n)]
    else:
        # two workers: item 0 ends after item 1, the results stay in order
        assert seen.index((1, 1)) < seen.index((0, 0))


def test_without_on_result_and_empty():
    assert map_jobs(_square, [(3, "")], jobs=2) == [9]
    assert map_jobs(_square, [], jobs=2) == []


@pytest.mark.parametrize("jobs", [1, 2])
def test_an_exception_in_fn_propagates(jobs):
    with pytest.raises(ValueError, match="item 1"):
        map_jobs(_fails_on, [(i, 1) for i in range(3)], jobs)
