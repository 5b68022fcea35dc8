"""Run as an unprivileged grading user by test_unprivileged.py: attack the grader, report as JSON.

Usage: python unprivileged_attacks.py MODE OUT_JSON, MODE being "default" (the
sandbox as planned: a user namespace when the kernel allows one) or
"landlock" (no namespaces: Landlock and seccomp only). Everything here is
bounded: a few children (and 80 sleeping processes of the grading user's), at most
96 MiB written.
"""

from __future__ import annotations

import dataclasses
import json
import os
import resource
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[3]
sys.path.insert(0, str(ROOT))

from robolab.grading.isolation import sandbox  # noqa: E402
from robolab.grading.running.proxy import StudentCodeError, open_submission  # noqa: E402
from tests.grading import TEST_LIMITS, write_notebook  # noqa: E402
from tests.grading.isolation.test_sandbox import PROBES  # noqa: E402 - daemon() comes from there

ATTACKS = """
import os, resource, socket, time

def prlimit_grader():
    resource.prlimit(os.getppid(), resource.RLIMIT_FSIZE, (0, 0))

def renice_grader():
    os.setpriority(os.PRIO_PROCESS, os.getppid(), 19)

def renice_user():
    os.setpriority(os.PRIO_USER, os.getuid(), 19)

def pin_grader():
    os.sched_setaffinity(os.getppid(), {0})

def signal_grader():
    os.kill(os.getppid(), 0)

def udp(family, host, port):
    with socket.socket(family, socket.SOCK_DGRAM) as s:
        s.sendto(b"leak", (host, port))

def unix_connect(path):
    with socket.socket(socket.AF_UNIX) as s:
        s.connect(path)
        s.sendall(b"leak")

def read(path):
    with open(path, "rb") as f:
        return f.read(16)

def fill_scratch(n):
    block = b"x" * 2**20
    written = 0
    try:
        for i in range(n):
            with open(f"fill-{i}", "wb") as f:
                for _ in range(8):
                    f.write(block)
                    written += len(block)
    except OSError as exc:
        return written, type(exc).__name__
    return written, None

def fork_and_thread():
    import threading
    pid = os.fork()
    if pid == 0:
        os._exit(0)
    os.waitpid(pid, 0)
    thread = threading.Thread(target=len, args=("",))
    thread.start()
    thread.join()
"""

#: Processes the grading user runs besides the grader (a desktop session runs hundreds):
#: more than the worker's own process limit, which must count the worker's alone.
OTHER_PROCESSES = 80


def outcome(function, *args) -> str:
    """What a call ended in: "ok", the student's exception type name, or the grader's error kind."""
    try:
        function(*args)
    except StudentCodeError as exc:
        return exc.kind
    return "ok"


def alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


def main(mode: str, out: Path) -> None:
    if mode == "landlock":
        original = sandbox.plan_sandbox

        def plan(*args, **kwargs):
            return dataclasses.replace(original(*args, **kwargs), view_root=None)

        sandbox.plan_sandbox = plan
    folder = Path(tempfile.mkdtemp(prefix="robolab-unprivileged-"))
    notebook = write_notebook(folder / "attacks.ipynb", PROBES, ATTACKS)
    udp4 = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    udp4.bind(("127.0.0.1", 0))
    udp4.setblocking(False)
    listener = socket.socket(socket.AF_UNIX)
    listener.bind(str(folder / "grader.sock"))
    listener.listen()
    listener.setblocking(False)
    before = {
        "fsize": resource.getrlimit(resource.RLIMIT_FSIZE),
        "nice": os.getpriority(os.PRIO_PROCESS, 0),
        "affinity": sorted(os.sched_getaffinity(0)),
    }
    limits = dataclasses.replace(TEST_LIMITS, wall_seconds=30, cpu_seconds=20)
    results: dict = {"uid": os.getuid()}
    with open_submission(notebook, limits=limits) as sub:
        results["sandbox"] = sub.sandbox.to_dict()
        for name in ("prlimit_grader", "renice_grader", "renice_user", "pin_grader"):
            results[name] = outcome(getattr(sub, name))
        results["signal_grader"] = outcome(sub.signal_grader)
        results["udp4"] = outcome(sub.udp, socket.AF_INET, "127.0.0.1", udp4.getsockname()[1])
        results["udp6"] = outcome(sub.udp, socket.AF_INET6, "::1", udp4.getsockname()[1])
        results["unix"] = outcome(sub.unix_connect, str(folder / "grader.sock"))
        results["solution"] = outcome(sub.read, str(ROOT / "solutions" / "demo.py"))
        grandchild, results["detached"] = sub.daemon()
        time.sleep(0.5)
        results["daemon_alive"] = alive(grandchild)
        try:
            results["fill"] = list(sub.fill_scratch(12))  # 96 MiB asked for
        except StudentCodeError as exc:
            results["fill"] = [None, exc.kind]
        results["still_serves"] = outcome(sub.read, "/dev/null")
    others = [subprocess.Popen(["sleep", "600"]) for _ in range(OTHER_PROCESSES)]
    try:  # a fresh worker, started while its user runs many other processes
        with open_submission(notebook, limits=limits) as sub:
            results["fork_beside_many"] = outcome(sub.fork_and_thread)
    finally:
        for proc in others:
            proc.kill()
            proc.wait()
    results["daemon_alive_after_close"] = alive(grandchild)
    try:
        udp4.recvfrom(100)
        results["udp_received"] = True
    except BlockingIOError:
        results["udp_received"] = False
    try:
        listener.accept()
        results["unix_accepted"] = True
    except BlockingIOError:
        results["unix_accepted"] = False
    after = {
        "fsize": resource.getrlimit(resource.RLIMIT_FSIZE),
        "nice": os.getpriority(os.PRIO_PROCESS, 0),
        "affinity": sorted(os.sched_getaffinity(0)),
    }
    results["grader_unchanged"] = before == after
    results["before"], results["after"] = before, after
    out.write_text(json.dumps(results))


if __name__ == "__main__":
    main(sys.argv[1], Path(sys.argv[2]))
