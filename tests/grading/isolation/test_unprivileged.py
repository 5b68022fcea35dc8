"""An unprivileged grader: the worker runs as the grader's own user and must still touch nothing.

The grader of these tests runs as ``nobody`` (``setpriv``), started by root in
a private mount namespace in which the Python installation is made reachable
(it may live under a home directory other users cannot enter). The attacks
are in ``unprivileged_attacks.py``; they run once per mode and report JSON.
Skipped when the machine cannot do this (not root, no ``setpriv``/``unshare``,
no ``nobody``, no Landlock).
"""

from __future__ import annotations

import json
import os
import pwd
import shlex
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

from robolab.grading.isolation import sandbox

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[2]


def _blocked_ancestor(path: Path) -> Path | None:
    """The first directory above ``path`` that other users cannot traverse, or None."""
    for directory in reversed(path.parents):
        if not os.stat(directory).st_mode & 0o001:
            return directory
    return None


def _script(mode: str, out: Path) -> str:
    user = pwd.getpwnam("nobody")
    python = Path(sys.executable)
    lines = ["set -e"]
    blocked = _blocked_ancestor(python.resolve())
    if blocked is not None:
        # Re-expose the one child of the blocked directory on the way to Python, read-only.
        child = python.resolve().relative_to(blocked).parts[0]
        stash = tempfile.mkdtemp(prefix="robolab-pyenv-")
        lines += [
            f"mount --bind {shlex.quote(str(blocked / child))} {stash}",
            f"mount -t tmpfs -o mode=755,size=1m tmpfs {shlex.quote(str(blocked))}",
            f"mkdir {shlex.quote(str(blocked / child))}",
            f"mount --bind -o ro {stash} {shlex.quote(str(blocked / child))}",
        ]
    lines.append(
        f"exec setpriv --reuid={user.pw_uid} --regid={user.pw_gid} --clear-groups "
        f"env HOME={out.parent} {shlex.quote(sys.executable)} "
        f"{HERE / 'unprivileged_attacks.py'} {mode} {out}"
    )
    return "\n".join(lines)


def _possible() -> str | None:
    if os.geteuid() != 0:
        return "needs root to start an unprivileged grader"
    if not (shutil.which("setpriv") and shutil.which("unshare")):
        return "needs setpriv and unshare"
    try:
        pwd.getpwnam("nobody")
    except KeyError:
        return "needs the user nobody"
    if sandbox.landlock_abi() == 0:
        return "needs Landlock"
    if _blocked_ancestor(ROOT) is not None:
        return "the repository is not readable by other users"
    return None


@pytest.fixture(scope="module", params=["default", "landlock"])
def attacks(request):
    reason = _possible()
    if reason:
        pytest.skip(reason)
    folder = Path(tempfile.mkdtemp(prefix="robolab-unprivileged-out-"))
    folder.chmod(0o777)
    out = folder / "results.json"
    script = _script(request.param, out)
    try:
        run = subprocess.run(
            ["unshare", "-m", "--propagation", "private", "sh", "-c", script],
            capture_output=True,
            text=True,
            timeout=900,
        )
        if run.returncode != 0 or not out.exists():
            if "unshare failed" in run.stderr or "mount" in run.stderr:
                pytest.skip(f"cannot set up an unprivileged grader: {run.stderr[-300:]}")
            raise AssertionError(f"the unprivileged grader failed:\n{run.stdout}\n{run.stderr}")
        yield request.param, json.loads(out.read_text())
    finally:
        shutil.rmtree(folder, ignore_errors=True)


def test_the_grader_really_was_unprivileged(attacks):
    mode, results = attacks
    assert results["uid"] != 0 and results["sandbox"]["uid"] == results["uid"]
    assert results["sandbox"]["seccomp"] and results["sandbox"]["landlock"]
    if mode == "landlock":
        assert not results["sandbox"]["view"] and results["sandbox"]["network_denied"] == "seccomp"


@pytest.mark.parametrize(
    "attack", ["prlimit_grader", "renice_grader", "renice_user", "pin_grader", "signal_grader"]
)
def test_the_worker_cannot_touch_the_grader(attacks, attack):
    _, results = attacks
    assert results[attack] == "PermissionError"


def test_the_grader_is_unchanged(attacks):
    _, results = attacks
    assert results["grader_unchanged"], (results["before"], results["after"])


def test_no_datagram_or_unix_socket_traffic_leaves(attacks):
    _, results = attacks
    assert results["udp4"] != "ok" and results["udp6"] != "ok" and results["unix"] != "ok"
    assert not results["udp_received"] and not results["unix_accepted"]


def test_the_answers_stay_unreadable(attacks):
    _, results = attacks
    assert results["solution"] in ("PermissionError", "FileNotFoundError")


def test_a_daemon_does_not_outlive_its_call(attacks):
    _, results = attacks
    assert not results["detached"], "setsid must fail"
    assert not results["daemon_alive"] and not results["daemon_alive_after_close"]


def test_scratch_space_is_capped(attacks):
    _, results = attacks
    written, error = results["fill"]
    # Either the tmpfs is full (the call raises inside the worker and returns what it wrote) or
    # the grader finds the work directory over its cap after the call and fails it.
    assert error is not None
    if written is not None:
        assert written <= sandbox.WORKDIR_BYTES
    assert results["still_serves"] == "ok"


def test_the_process_limit_counts_the_workers_own_processes(attacks):
    """Without a uid or a user namespace of its own, the worker shares its user's process
    count with everything else that user runs: its limit is on top of those, so a
    submission can still start a thread or a child however many the user runs."""
    _, results = attacks
    assert results["fork_beside_many"] == "ok"
