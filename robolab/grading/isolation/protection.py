"""What protects the answers, the network and other processes on this machine, probed once.

The isolation a worker gets depends on the machine (root or not, Landlock's
ABI, user namespaces, seccomp). Each pytest run that grades a submission
warns about gaps in its own log, which nobody reads; so a batch asks here
once, before grading, and prints the answer where the instructor sees it::

    isolation: answers unreadable (mount-namespace view, Landlock ABI 7); network none
    (network namespace); processes confined (own uid, seccomp); scratch capped (tmpfs)

:func:`probe_protection` starts a real worker and *tries*: it reads a
reference solution and a hidden test, opens TCP and UDP to a grader-side
listener and a unix socket, alongside the report the worker's sandbox sent
before any student code ran. :func:`describe_protection` caches that for the
process. :func:`require_answers_protected` is what the Gradescope bundle
calls before grading: an autograder whose workers can read the answers
refuses to grade.
"""

from __future__ import annotations

import functools
import socket
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import robolab
from robolab.grading.isolation.sandbox import SandboxReport

__all__ = [
    "Protection",
    "UnprotectedAnswers",
    "answers_protected",
    "batch_protection",
    "describe_protection",
    "probe_protection",
    "require_answers_protected",
]

_PROBE = """
import os
import socket

def probe(paths, tcp_port, udp_port):
    readable = []
    for path in paths:
        try:
            with open(path, "rb") as f:
                f.read(1)
            readable.append(path)
        except OSError:
            pass
    reached = []
    attempts = [
        ("tcp", socket.AF_INET, socket.SOCK_STREAM, ("127.0.0.1", tcp_port)),
        ("udp", socket.AF_INET, socket.SOCK_DGRAM, ("127.0.0.1", udp_port)),
        ("unix sockets", socket.AF_UNIX, socket.SOCK_STREAM, None),
    ]
    for name, family, kind, address in attempts:
        try:
            s = socket.socket(family, kind)
        except OSError:
            continue
        try:
            s.settimeout(2)
            if address is None:
                reached.append(name)  # could be created: paths on the host may be reachable
            elif kind == socket.SOCK_DGRAM:
                s.sendto(b"probe", address)
                reached.append(name)
            else:
                s.connect(address)
                reached.append(name)
        except OSError:
            pass
        finally:
            s.close()
    return readable, reached
"""


class UnprotectedAnswers(RuntimeError, PermissionError):
    """Grading refused: the worker could read the reference solutions or hidden tests."""


@dataclass(frozen=True)
class Protection:
    """The isolation of this machine's workers, as probed.

    Attributes
    ----------
    report : SandboxReport or None
        What the probe worker's sandbox applied (None when it did not start).
    readable : list of str
        Answer files the probe worker could read (must be empty).
    reached : list of str
        Network channels the probe worker could use: ``"tcp"``, ``"udp"``,
        ``"unix sockets"`` (must be empty).
    failure : str
        Why the probe could not run, or "".
    """

    report: SandboxReport | None
    readable: list[str] = field(default_factory=list)
    reached: list[str] = field(default_factory=list)
    failure: str = ""

    @property
    def answers_protected(self) -> bool:
        """The worker can read no reference solution and no hidden test."""
        return self.report is not None and self.report.protects_answers and not self.readable

    @property
    def network_protected(self) -> bool:
        """The worker can reach nothing over the network or a unix socket."""
        return self.report is not None and not self.reached

    @property
    def processes_protected(self) -> bool:
        """The worker can signal or reconfigure no process but its own."""
        return self.report is not None and self.report.protects_processes

    @property
    def problems(self) -> list[str]:
        """What is unprotected, in words (empty when everything holds)."""
        if self.report is None:
            return [f"the sandbox could not be probed: {self.failure}"]
        found = []
        if not self.answers_protected:
            what = ", ".join(Path(p).name for p in self.readable) or "no Landlock and no view"
            found.append(f"submissions can read the reference solutions and hidden tests ({what})")
        if not self.network_protected:
            found.append(f"submissions can use the network ({', '.join(self.reached)})")
        if not self.processes_protected:
            found.append("submissions can signal or reconfigure other processes of the grader")
        return found

    @property
    def column(self) -> str:
        """The gradebook's isolation column: "" when everything holds, else the problems."""
        return "UNPROTECTED: " + "; ".join(self.problems) if self.problems else ""

    def to_dict(self) -> dict:
        """A JSON-ready copy (for a probe run in a child of the grader zygote)."""
        return {
            "report": None if self.report is None else self.report.to_dict(),
            "readable": list(self.readable),
            "reached": list(self.reached),
            "failure": self.failure,
        }

    @classmethod
    def from_dict(cls, data: dict) -> Protection:
        """Inverse of :meth:`to_dict`."""
        report = data.get("report")
        return cls(
            None if report is None else SandboxReport.from_dict(report),
            [str(p) for p in data.get("readable", [])],
            [str(r) for r in data.get("reached", [])],
            str(data.get("failure", "")),
        )

    def line(self) -> str:
        """One line for the batch log: what protects what."""
        r = self.report
        if r is None:
            return f"isolation: UNKNOWN ({self.failure})"
        walls = [
            w
            for w, on in (
                ("mount-namespace view", r.view),
                (f"Landlock ABI {r.landlock_abi}", r.landlock),
            )
            if on
        ]
        answers = (
            f"answers unreadable ({', '.join(walls)})"
            if self.answers_protected
            else "answers READABLE"
        )
        network = {
            "namespace": "network none (network namespace)",
            "seccomp": "network none (seccomp: no sockets)",
            "landlock-tcp": "network: TCP denied (Landlock)",
        }.get(r.network_denied, "network OPEN")
        if self.reached:
            network = f"network OPEN ({', '.join(self.reached)})"
        guards = [
            g
            for g, on in (
                ("own uid", r.uid >= 1_500_000_000),
                ("user namespace", r.user_namespace),
                ("seccomp", r.seccomp),
                (f"signals: {r.signals}", r.signals not in ("no", "uid")),
            )
            if on
        ]
        processes = (
            f"processes confined ({', '.join(guards)})"
            if self.processes_protected
            else "processes NOT confined"
        )
        scratch = (
            "scratch capped (tmpfs)" if r.scratch == "tmpfs" else "scratch checked after each call"
        )
        return f"isolation: {answers}; {network}; {processes}; {scratch}"

    def announce(self, stream=None) -> None:
        """Print :meth:`line`, and a loud warning per problem, to ``stream`` (stderr)."""
        stream = stream or sys.stderr
        print(self.line(), file=stream)
        for problem in self.problems:
            print(f"WARNING: robolab grading: {problem}; see docs/grading.md", file=stream)


def _answer_files() -> list[str]:
    """A few reference solutions and hidden tests that exist (what a worker must not read)."""
    from robolab.grading.labs import project_root

    roots = {Path(robolab.__file__).resolve().parent.parent}
    try:
        roots.add(project_root().resolve())
    except Exception:  # noqa: BLE001 - the package's own parent is enough
        pass
    found: list[str] = []
    for root in sorted(roots):
        for pattern in ("solutions/*.py", "tests/labs/test_*.py", "tests/*.py"):
            found += [str(p) for p in sorted(root.glob(pattern))[:3]]
    return found


def probe_protection() -> Protection:
    """Start one worker and try what a hostile submission would; never raises."""
    from robolab.grading.isolation import warm
    from robolab.grading.running.proxy import Limits, open_submission

    files = _answer_files()
    tcp = socket.socket()
    udp = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        tcp.bind(("127.0.0.1", 0))
        tcp.listen()
        udp.bind(("127.0.0.1", 0))
        with tempfile.TemporaryDirectory(prefix="robolab-probe-") as folder:
            notebook = Path(folder) / "probe.ipynb"
            _write_probe(notebook)
            limits = Limits(cpu_seconds=10, wall_seconds=30)
            with warm.probing(), open_submission(notebook, limits=limits) as sub:
                readable, reached = sub.probe(files, tcp.getsockname()[1], udp.getsockname()[1])
                report = sub.sandbox
        return Protection(report, [str(p) for p in readable], [str(r) for r in reached])
    except Exception as exc:  # noqa: BLE001 - reported as a problem, loudly
        return Protection(None, failure=f"{type(exc).__name__}: {exc}")
    finally:
        tcp.close()
        udp.close()


def _write_probe(path: Path) -> None:
    import json

    cell = {
        "cell_type": "code",
        "execution_count": None,
        "metadata": {},
        "outputs": [],
        "source": _PROBE.splitlines(keepends=True),
    }
    path.write_text(
        json.dumps({"cells": [cell], "metadata": {}, "nbformat": 4, "nbformat_minor": 5})
    )


def _probe_forked() -> Protection | None:
    """:func:`probe_protection` in a child of this process's grader zygote, or None.

    The same probe, but forked from a process that has already imported numpy and the
    grader's modules, so that a batch does not import them a second time just to probe.
    None when no grader zygote runs or the child gave no answer (then the caller probes
    in this process, and says why the sandbox failed if it does).
    """
    import json
    import os
    import shutil

    from robolab.grading.isolation import warm

    ours = Path(robolab.__file__).resolve().parent
    # Only a grader zygote that runs this very robolab (a project root without a copy of
    # its own, or whose copy is this one): the probe tests this process's code.
    running = [
        (root, grader)
        for root, grader in warm.running_graders()
        if not (Path(root) / "robolab").exists() or (Path(root) / "robolab").resolve() == ours
    ]
    workers = warm.shared() if running else None
    if workers is None:
        return None
    root, grader = running[0]
    folder = tempfile.mkdtemp(prefix="robolab-probe-")  # 0700: the grader's own
    out = os.path.join(folder, "protection.json")
    log_r, log_w = os.pipe()
    try:
        request = {
            "task": "probe",
            "probe": True,  # not a submission: no idle imports for it
            "out": out,
            "args": [],
            "env": dict(os.environ, **{warm.FD_VARIABLE: str(workers.fileno())}),
            "cwd": root,
            "keep": [workers.fileno()],
        }
        try:
            child = grader.spawn(request, (log_w,))
        except warm.ZygoteError:
            return None
        finally:
            os.close(log_w)
        while os.read(log_r, 1 << 16):  # its warnings: the line printed says the same
            pass
        if child.wait(timeout=120) != 0:
            return None
        with open(out, encoding="utf-8") as f:
            return Protection.from_dict(json.load(f))
    except (OSError, ValueError, TypeError, KeyError):
        return None
    finally:
        os.close(log_r)
        shutil.rmtree(folder, ignore_errors=True)


@functools.lru_cache(maxsize=1)
def describe_protection() -> Protection:
    """:func:`probe_protection` in this process, once per process (what the gates ask)."""
    return probe_protection()


@functools.lru_cache(maxsize=1)
def batch_protection() -> Protection:
    """What a batch announces (:func:`robolab.grading.running.runner.grade_all`), once per process.

    Probed in a child of the batch's grader zygote when one runs this robolab
    (:func:`_probe_forked`): the process its pytest runs are forked from, with numpy and
    the proxy already imported. Else :func:`describe_protection`. The refusals
    (:func:`require_answers_protected`, the Gradescope bundle) always probe in the
    process that grades.
    """
    if describe_protection.cache_info().currsize:  # probed here already (a gate asked)
        return describe_protection()
    found = _probe_forked()
    return found if found is not None else describe_protection()


def answers_protected() -> bool:
    """Whether workers on this machine cannot read the reference solutions and hidden tests."""
    return describe_protection().answers_protected


def require_answers_protected() -> Protection:
    """The protection, or :class:`UnprotectedAnswers` when workers could read the answers."""
    protection = describe_protection()
    if not protection.answers_protected:
        raise UnprotectedAnswers(
            "robolab refuses to grade: " + "; ".join(protection.problems or ["answers readable"])
        )
    return protection
