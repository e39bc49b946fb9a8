"""Waiting for something observable (a file, a process's exit) with a deadline, never for a fixed time."""

from __future__ import annotations

import time
from collections.abc import Callable

POLL = 0.02
"""Seconds between looks: short beside every event the tests wait for, long beside the look itself."""


def wait_for(event: Callable[[], object], timeout: float) -> bool:
    """True as soon as ``event()`` is true, False if it is still false after ``timeout`` seconds."""
    deadline = time.monotonic() + timeout
    while not event():
        if time.monotonic() > deadline:
            return False
        time.sleep(POLL)
    return True
