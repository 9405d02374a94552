"""One function over many arguments, in worker processes or one after the
other: the studies' seeds (bench/held_board.py, hallhome.identify_eval)."""

from __future__ import annotations

from typing import Any, Callable, Optional, Sequence


def map_jobs(fn: Callable[..., Any], arg_tuples: Sequence[tuple], jobs: int = 1,
             on_result: Optional[Callable[[int, Any], None]] = None) -> list:
    """``fn(*args)`` for each tuple of ``arg_tuples``, ``jobs`` worker
    processes at once (``jobs`` <= 1 or a single tuple: in this process, one
    after the other); ``on_result(index, result)`` as each result comes (in
    the order they finish when in workers); the results in the order of
    ``arg_tuples``. ``fn`` and the arguments must be picklable (``fn`` at a
    module's top level); an exception raised by ``fn`` propagates."""
    args = list(arg_tuples)
    if jobs <= 1 or len(args) <= 1:
        out = []
        for i, a in enumerate(args):
            out.append(fn(*a))
            if on_result is not None:
                on_result(i, out[-1])
        return out
    from concurrent.futures import ProcessPoolExecutor, as_completed

    got: dict = {}
    with ProcessPoolExecutor(max_workers=min(jobs, len(args))) as ex:
        futures = {ex.submit(fn, *a): i for i, a in enumerate(args)}
        for f in as_completed(futures):
            i = futures[f]
            got[i] = f.result()
            if on_result is not None:
                on_result(i, got[i])
    return [got[i] for i in range(len(args))]
