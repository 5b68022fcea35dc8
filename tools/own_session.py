"""Run a command in a session of its own; pass it SIGINT, SIGTERM and SIGHUP; exit as it did.

    python tools/own_session.py COMMAND [ARG ...]

``make test`` runs its jobs through this. Linux shares the CPU per session (autogroup):
each grading worker and pytest run the grader forks has a session of its own, so the
jobs' own pytest processes, all in make's session, shared one session's share against
them, and the suite without the grader (tests run in that process) took 15 min of a
19.5 min ``make test``. A terminal's Ctrl-C reaches make and this wrapper (in the
foreground process group), not a new session: the wrapper passes it on.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys


def main(argv: list[str]) -> int:
    if not argv:
        print(__doc__.strip().splitlines()[2].strip(), file=sys.stderr)
        return 2
    proc = subprocess.Popen(argv, start_new_session=True)

    def forward(sig: int, _frame: object) -> None:
        try:
            os.killpg(proc.pid, sig)
        except ProcessLookupError:
            pass

    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        # A signal this process ignores (a job started in the background) stays ignored,
        # as it is in the child, which inherited that.
        if signal.getsignal(sig) is not signal.SIG_IGN:
            signal.signal(sig, forward)
    code = proc.wait()
    return 128 - code if code < 0 else code


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
