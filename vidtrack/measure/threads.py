"""A second thread for a measurer's side task, and the seconds each stage took.

A measurer with two independent stages (``mil``'s correlation filter beside
its superpixels) submits one of them to a :class:`SecondThread` and meets it
later; the stages' compiled kernels release the GIL, so the two really run
side by side.  Each task reads only its arguments and its own state, so a
run with the thread gives the same results as one without; the thread is a
runtime choice (speed), never a tracker option.

Timings (:func:`tic`) are a dict of accumulated seconds per stage name, which
``vidtrack bench`` reads from a measurer's ``timings_``.
"""

from __future__ import annotations

import time
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Any, Callable


def tic(timings: dict[str, float], name: str, start: float) -> float:
    """Add the seconds since ``start`` (a :func:`time.perf_counter` value) to ``timings[name]``; return now."""
    now = time.perf_counter()
    timings[name] = timings.get(name, 0.0) + now - start
    return now


class SecondThread:
    """Tasks run one after another on one worker thread, or at once on the caller's (``enabled=False``).

    Either way :meth:`submit` returns a :class:`~concurrent.futures.Future`,
    and an exception is raised where its result is taken.  The thread starts
    with the first task; the object pickles (and deep-copies) without it.

    Parameters
    ----------
    enabled
        Run the tasks on the worker thread (False: in the calling thread, at once).
    name
        Prefix of the worker thread's name.
    """

    def __init__(self, enabled: bool = True, name: str = "vidtrack") -> None:
        self.enabled = enabled
        self.name = name
        self._executor: ThreadPoolExecutor | None = None

    def submit(self, task: Callable[..., Any], *args: Any) -> Future:
        """``task(*args)`` on the worker, queued after the tasks before it (or run here now)."""
        if not self.enabled:
            done: Future = Future()
            try:
                done.set_result(task(*args))
            except BaseException as exc:  # raised where the result is taken, as from the thread
                done.set_exception(exc)
            return done
        if self._executor is None:
            self._executor = ThreadPoolExecutor(max_workers=1, thread_name_prefix=self.name)
        return self._executor.submit(task, *args)

    def close(self) -> None:
        """Wait for the queued tasks and stop the worker thread (a later task starts a new one)."""
        if self._executor is not None:
            self._executor.shutdown(wait=True)
            self._executor = None

    def __getstate__(self) -> dict:
        return {"enabled": self.enabled, "name": self.name, "_executor": None}
