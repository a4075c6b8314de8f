"""One call at a time into a tracker."""
from __future__ import annotations

import contextlib
import threading

from nrmlc.errors import ParameterError


class OneCallAtATime:
    """A tracker's state is one particle cloud, advanced frame by frame: two threads inside
    ``init`` or ``update`` at once would interleave their frames, so the second is refused."""

    def __init__(self) -> None:
        self._busy = threading.Lock()

    def __getstate__(self) -> dict:
        state = self.__dict__.copy()
        state.pop("_busy", None)  # a lock cannot be pickled; a copy gets its own
        return state

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self._busy = threading.Lock()

    @contextlib.contextmanager
    def _alone(self, what: str):
        if not self._busy.acquire(blocking=False):
            raise ParameterError(f"{type(self).__name__}.{what}: called while another thread is inside init or "
                                 f"update of the same tracker; use one tracker per thread (or a lock around it)")
        try:
            yield
        finally:
            self._busy.release()
