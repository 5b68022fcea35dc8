"""The seccomp filter on its own: what it denies, what it leaves working (in a child process)."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap

import pytest

from robolab.grading.isolation import seccomp

CHILD = textwrap.dedent(
    """
    import ctypes, json, os, resource, socket, subprocess, sys, threading
    ctypes.CDLL(None, use_errno=True).prctl(38, 1, 0, 0, 0)  # no_new_privs
    os.setpgid(0, 0)
    from robolab.grading.isolation import seccomp
    seccomp.install(own_group=os.getpgrp() if sys.argv[1] == "group" else None)
    parent = os.getppid()
    results = {}

    def attempt(name, function):
        try:
            function()
            results[name] = "ok"
        except OSError as exc:
            results[name] = exc.errno

    attempt("prlimit_other", lambda: resource.prlimit(parent, resource.RLIMIT_NOFILE))
    attempt("prlimit_self", lambda: resource.setrlimit(resource.RLIMIT_CORE, (0, 0)))
    attempt("renice_other", lambda: os.setpriority(os.PRIO_PROCESS, parent, 1))
    attempt("renice_user", lambda: os.setpriority(os.PRIO_USER, 0, 1))
    attempt("nice_self", lambda: os.nice(1))
    attempt("affinity_other", lambda: os.sched_setaffinity(parent, os.sched_getaffinity(0)))
    attempt("affinity_self", lambda: os.sched_setaffinity(0, os.sched_getaffinity(0)))
    attempt("udp", lambda: socket.socket(socket.AF_INET, socket.SOCK_DGRAM))
    attempt("tcp", lambda: socket.socket(socket.AF_INET, socket.SOCK_STREAM))
    attempt("unix", lambda: socket.socket(socket.AF_UNIX))
    attempt("socketpair", lambda: socket.socketpair())
    attempt("setsid", os.setsid)
    attempt("pidfd", lambda: os.pidfd_open(parent))
    attempt("kill_other", lambda: os.kill(parent, 0))
    attempt("kill_self", lambda: os.kill(os.getpid(), 0))
    attempt("kill_group", lambda: os.killpg(os.getpgrp(), 0))
    pid = os.fork()
    if pid == 0:
        os._exit(7)
    results["fork"] = os.waitstatus_to_exitcode(os.waitpid(pid, 0)[1])
    thread = threading.Thread(target=lambda: None)
    thread.start()
    thread.join()
    results["exec"] = subprocess.run(["/bin/echo", "hi"], capture_output=True).stdout.decode()
    import numpy, scipy.linalg
    results["numpy"] = float(scipy.linalg.det(numpy.eye(3)))
    print(json.dumps(results))
    """
)

needs_seccomp = pytest.mark.skipif(not seccomp.supported(), reason="needs Linux x86_64/aarch64")


@pytest.mark.parametrize("machine", ["x86_64", "aarch64"])
@pytest.mark.parametrize("group", [None, 4242])
def test_the_filter_assembles_for_every_architecture(machine, group):
    program = seccomp.build(machine, group)
    assert len(program) % 8 == 0 and 0 < len(program) // 8 < 4096


@pytest.fixture(scope="module", params=["group", "nogroup"])
def confined(request):
    if not seccomp.supported():
        pytest.skip("needs Linux x86_64/aarch64")
    run = subprocess.run(
        [sys.executable, "-c", CHILD, request.param], capture_output=True, text=True, timeout=900
    )
    assert run.returncode == 0, run.stderr
    return request.param, json.loads(run.stdout.splitlines()[-1])


EPERM = 1


@needs_seccomp
@pytest.mark.parametrize(
    "call",
    ["prlimit_other", "renice_other", "renice_user", "affinity_other", "udp", "tcp", "unix"]
    + ["setsid", "pidfd"],
)
def test_calls_on_other_processes_and_sockets_fail_with_eperm(confined, call):
    assert confined[1][call] == EPERM


@needs_seccomp
@pytest.mark.parametrize(
    "call", ["prlimit_self", "nice_self", "affinity_self", "socketpair", "kill_self", "kill_group"]
)
def test_the_same_calls_on_the_process_itself_work(confined, call):
    assert confined[1][call] == "ok"


@needs_seccomp
def test_signals_to_others_fail_only_when_the_filter_confines_them(confined):
    mode, results = confined
    assert results["kill_other"] == (EPERM if mode == "group" else "ok")


@needs_seccomp
def test_fork_threads_exec_and_numpy_still_work(confined):
    results = confined[1]
    assert results["fork"] == 7 and results["exec"] == "hi\n" and results["numpy"] == 1.0
