"""hallhome.jobs.map_jobs: results in the order of the arguments, one
on_result per item, fn's exception passed on, in this process and in
workers."""

import time

import pytest

from hallhome.jobs import map_jobs


def _slow_square(i: int, n: int) -> int:
    """i*i, the earlier items the slower (so workers finish them last)"""
    time.sleep(0.1 * (n - i))
    return i * i


def _fails_on(i: int, bad: int) -> int:
    if i == bad:
        raise ValueError(f"item {i}")
    return i


@pytest.mark.parametrize("jobs", [1, 2])
def test_results_in_input_order_and_one_report_each(jobs):
    n = 3
    seen = []
    out = map_jobs(_slow_square, [(i, n) for i in range(n)], jobs,
                   lambda i, r: seen.append((i, r)))
    assert out == [i * i for i in range(n)]
    assert sorted(seen) == [(i, i * i) for i in range(n)]
    if jobs == 1:
        assert seen == [(i, i * i) for i in range(n)]
    else:
        # two workers: item 1 (0.2 s) ends before item 0 (0.3 s)
        assert seen[0][0] != 0


def test_without_on_result_and_empty():
    assert map_jobs(_slow_square, [(3, 3)], jobs=2) == [9]
    assert map_jobs(_slow_square, [], jobs=2) == []


@pytest.mark.parametrize("jobs", [1, 2])
def test_an_exception_in_fn_propagates(jobs):
    with pytest.raises(ValueError, match="item 1"):
        map_jobs(_fails_on, [(i, 1) for i in range(3)], jobs)
