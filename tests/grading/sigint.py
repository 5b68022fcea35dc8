"""Children that get SIGINT at its default, as from a terminal.

A test run started in the background of a script (``make test &``, a CI runner's shell)
inherits SIGINT ignored, and so would every child it starts: robolab grade then keeps
ignoring it (as any command does), and a plain Python child never installs its Ctrl-C
handler. Tests that send SIGINT start their children inside :func:`sigint_default`.
"""

from __future__ import annotations

import contextlib
import signal
from collections.abc import Iterator


@contextlib.contextmanager
def sigint_default() -> Iterator[None]:
    """Children started within this block get SIGINT at its default (main thread only)."""
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
