"""A seccomp-BPF filter that keeps the grading worker away from every process but its own.

Landlock confines files (and TCP, and with ABI 6 signals); the dropped uid of
a root grader keeps the worker from touching other processes. An
unprivileged grader has neither a uid of its own nor, on older kernels,
Landlock's signal scope: the worker runs as the grader's user and could
``prlimit`` the grader's file-size limit to zero, renice it, pin it to a CPU,
``ptrace`` it, or open a UDP socket. This filter, installed by
:func:`robolab.grading.isolation.sandbox.apply` after everything else, makes those
system calls fail with ``EPERM`` (nothing is killed, so the student sees an
ordinary ``PermissionError``):

* always denied: ``ptrace``, ``process_vm_readv``/``writev``, ``pidfd_open``,
  ``pidfd_send_signal``, ``pidfd_getfd``, ``kcmp``, ``process_madvise``,
  ``perf_event_open``, ``bpf``, the key-ring calls, ``io_uring`` (it would
  open sockets behind the filter's back), ``unshare``, ``setns`` and ``clone``
  with namespace flags (``clone3`` answers ``ENOSYS`` so the C library falls
  back to ``clone``, whose flags can be inspected), ``socket`` (every family:
  no UDP, no unix socket reachable by path, no TCP even where Landlock cannot
  deny it; ``socketpair`` still works), and ``setsid``/``setpgid``: nothing
  the worker starts can leave its process group, so killing the group kills
  all of it;
* allowed on the calling process only (pid 0): ``prlimit64``,
  ``setpriority`` and ``ioprio_set`` (``PRIO_PROCESS`` of itself),
  ``sched_setaffinity``, ``sched_setscheduler``, ``sched_setparam``,
  ``sched_setattr``, ``migrate_pages``, ``move_pages``;
* ``prctl(PR_SET_CHILD_SUBREAPER)`` is denied, so the worker stays the
  reaper of its orphans (the grader accounts their CPU time through it);
* with ``own_group`` (when neither a uid of its own nor Landlock scopes
  signals): ``kill`` and ``rt_sigqueueinfo`` only to pid 0, the group
  leader or the group itself, ``tkill``/``tgkill`` only within the leader.

The filter is inherited by every child and survives ``execve``.
"""

from __future__ import annotations

import ctypes
import errno
import os
import platform
import struct

__all__ = ["SeccompError", "install", "supported"]

_PR_SET_SECCOMP = 22
_SECCOMP_MODE_FILTER = 2
_PR_SET_CHILD_SUBREAPER = 36
_SECCOMP_RET_KILL_PROCESS = 0x80000000
_SECCOMP_RET_ERRNO = 0x00050000
_SECCOMP_RET_ALLOW = 0x7FFF0000
_X32_SYSCALL_BIT = 0x40000000
_CLONE_NAMESPACES = 0x00020000 | 0x02000000 | 0x04000000 | 0x08000000 | 0x10000000
_CLONE_NAMESPACES |= 0x20000000 | 0x40000000 | 0x00000080  # NEWNS UTS IPC USER PID NET CGROUP TIME

# BPF opcodes
_LD_W_ABS = 0x20  # BPF_LD | BPF_W | BPF_ABS
_JEQ_K = 0x15  # BPF_JMP | BPF_JEQ | BPF_K
_JGE_K = 0x35
_JSET_K = 0x45
_RET_K = 0x06

#: System call numbers: name -> (x86_64, aarch64), from <asm/unistd_64.h> and
#: <asm-generic/unistd.h>.
_NUMBERS = {
    "kill": (62, 129),
    "tkill": (200, 130),
    "tgkill": (234, 131),
    "rt_sigqueueinfo": (129, 138),
    "rt_tgsigqueueinfo": (297, 240),
    "ptrace": (101, 117),
    "process_vm_readv": (310, 270),
    "process_vm_writev": (311, 271),
    "prlimit64": (302, 261),
    "setpriority": (141, 140),
    "ioprio_set": (251, 30),
    "sched_setparam": (142, 118),
    "sched_setscheduler": (144, 119),
    "sched_setaffinity": (203, 122),
    "sched_setattr": (314, 274),
    "pidfd_open": (434, 434),
    "pidfd_send_signal": (424, 424),
    "pidfd_getfd": (438, 438),
    "socket": (41, 198),
    "setsid": (112, 157),
    "setpgid": (109, 154),
    "io_uring_setup": (425, 425),
    "io_uring_enter": (426, 426),
    "io_uring_register": (427, 427),
    "perf_event_open": (298, 241),
    "bpf": (321, 280),
    "kcmp": (312, 272),
    "process_madvise": (440, 440),
    "unshare": (272, 97),
    "setns": (308, 268),
    "keyctl": (250, 219),
    "add_key": (248, 217),
    "request_key": (249, 218),
    "migrate_pages": (256, 238),
    "move_pages": (279, 239),
    "prctl": (157, 167),
    "clone": (56, 220),
    "clone3": (435, 435),
}
#: machine -> (audit arch, index into the _NUMBERS pairs).
_ARCH = {"x86_64": (0xC000003E, 0), "aarch64": (0xC00000B7, 1), "arm64": (0xC00000B7, 1)}


_DENIED = (
    "ptrace process_vm_readv process_vm_writev pidfd_open pidfd_send_signal pidfd_getfd kcmp "
    "process_madvise perf_event_open bpf keyctl add_key request_key io_uring_setup "
    "io_uring_enter io_uring_register unshare setns socket setsid setpgid"
).split()
#: System calls allowed only when their first argument is 0 (the calling process).
_SELF_ONLY = (
    "prlimit64 sched_setaffinity sched_setscheduler sched_setparam sched_setattr "
    "migrate_pages move_pages"
).split()


class SeccompError(OSError):
    """The filter could not be installed."""


def supported() -> bool:
    """Whether this machine's architecture is known to the filter (Linux x86_64, aarch64)."""
    return os.uname().sysname == "Linux" and platform.machine() in _ARCH


class _Program:
    """A tiny BPF assembler: instructions with symbolic jump targets."""

    def __init__(self) -> None:
        self.code: list[tuple[int, object, object, int]] = []
        self.labels: dict[str, int] = {}

    def op(self, code: int, k: int, true: str | None = None, false: str | None = None) -> None:
        self.code.append((code, true, false, k & 0xFFFFFFFF))

    def label(self, name: str) -> None:
        self.labels[name] = len(self.code)

    def load_arg(self, index: int) -> None:
        # Low 32 bits of the argument (little endian): pids, flags and options are ints.
        self.op(_LD_W_ABS, 16 + 8 * index)

    def assemble(self) -> bytes:
        out = b""
        for position, (code, true, false, k) in enumerate(self.code):
            jt = self.labels[true] - position - 1 if isinstance(true, str) else 0
            jf = self.labels[false] - position - 1 if isinstance(false, str) else 0
            if not (0 <= jt < 256 and 0 <= jf < 256):
                raise SeccompError(errno.E2BIG, "seccomp filter jump out of range")
            out += struct.pack("<HBBI", code, jt, jf, k)
        return out


def build(machine: str, own_group: int | None) -> bytes:
    """The filter program for ``machine``, as ``struct sock_filter`` records.

    Parameters
    ----------
    machine : str
        ``platform.machine()`` of the worker.
    own_group : int or None
        The worker's process group (its leader's pid) when signals must be
        confined by the filter; None to leave signals to the kernel.
    """
    arch, column = _ARCH[machine]
    nr = {name: numbers[column] for name, numbers in _NUMBERS.items()}
    p = _Program()
    p.op(_LD_W_ABS, 4)  # seccomp_data.arch
    p.op(_JEQ_K, arch, None, "kill")
    p.op(_LD_W_ABS, 0)  # seccomp_data.nr
    if machine == "x86_64":
        p.op(_JGE_K, _X32_SYSCALL_BIT, "deny", None)
    for name in _DENIED:
        p.op(_JEQ_K, nr[name], "deny", None)
    p.op(_JEQ_K, nr["clone3"], "nosys", None)
    for name in _SELF_ONLY:
        p.op(_JEQ_K, nr[name], "arg0_is_zero", None)
    p.op(_JEQ_K, nr["setpriority"], "prio", None)
    p.op(_JEQ_K, nr["ioprio_set"], "ioprio", None)
    p.op(_JEQ_K, nr["prctl"], "prctl", None)
    p.op(_JEQ_K, nr["clone"], "clone", None)
    if own_group is not None:
        for name in ("kill", "rt_sigqueueinfo"):
            p.op(_JEQ_K, nr[name], "to_group", None)
        for name in ("tkill", "tgkill", "rt_tgsigqueueinfo"):
            p.op(_JEQ_K, nr[name], "to_leader", None)
    p.op(_RET_K, _SECCOMP_RET_ALLOW)

    p.label("arg0_is_zero")
    p.load_arg(0)
    p.op(_JEQ_K, 0, "allow", "deny")
    p.label("prio")  # setpriority(PRIO_PROCESS=0, who=0, prio)
    p.load_arg(0)
    p.op(_JEQ_K, 0, "arg1_is_zero", "deny")
    p.label("ioprio")  # ioprio_set(IOPRIO_WHO_PROCESS=1, who=0, prio)
    p.load_arg(0)
    p.op(_JEQ_K, 1, "arg1_is_zero", "deny")
    p.label("arg1_is_zero")
    p.load_arg(1)
    p.op(_JEQ_K, 0, "allow", "deny")
    p.label("prctl")
    p.load_arg(0)
    p.op(_JEQ_K, _PR_SET_CHILD_SUBREAPER, "deny", "allow")
    p.label("clone")
    p.load_arg(0)
    p.op(_JSET_K, _CLONE_NAMESPACES, "deny", "allow")
    if own_group is not None:
        p.label("to_group")
        p.load_arg(0)
        p.op(_JEQ_K, 0, "allow", None)
        p.op(_JEQ_K, own_group, "allow", None)
        p.op(_JEQ_K, -own_group, "allow", "deny")
        p.label("to_leader")
        p.load_arg(0)
        p.op(_JEQ_K, own_group, "allow", "deny")

    p.label("allow")
    p.op(_RET_K, _SECCOMP_RET_ALLOW)
    p.label("deny")
    p.op(_RET_K, _SECCOMP_RET_ERRNO | errno.EPERM)
    p.label("nosys")
    p.op(_RET_K, _SECCOMP_RET_ERRNO | errno.ENOSYS)
    p.label("kill")
    p.op(_RET_K, _SECCOMP_RET_KILL_PROCESS)
    return p.assemble()


class _SockFprog(ctypes.Structure):
    _fields_ = [("len", ctypes.c_ushort), ("filter", ctypes.c_void_p)]


def install(own_group: int | None = None) -> None:
    """Install the filter on the calling thread (and so on everything it starts later).

    Call while the process is single-threaded and after ``PR_SET_NO_NEW_PRIVS``.

    Parameters
    ----------
    own_group : int, optional
        Confine signals to this process group (see the module docstring).

    Raises
    ------
    SeccompError
        When the architecture is not supported or the kernel refuses the filter.
    """
    if not supported():
        raise SeccompError(errno.ENOSYS, f"no seccomp filter for {platform.machine()}")
    program = build(platform.machine(), own_group)
    buffer = ctypes.create_string_buffer(program, len(program))
    fprog = _SockFprog(len(program) // 8, ctypes.cast(buffer, ctypes.c_void_p))
    libc = ctypes.CDLL(None, use_errno=True)
    libc.prctl.argtypes = [
        ctypes.c_int,
        ctypes.c_ulong,
        ctypes.c_void_p,
        ctypes.c_ulong,
        ctypes.c_ulong,
    ]
    if libc.prctl(_PR_SET_SECCOMP, _SECCOMP_MODE_FILTER, ctypes.byref(fprog), 0, 0) != 0:
        code = ctypes.get_errno()
        raise SeccompError(code, f"prctl(PR_SET_SECCOMP): {os.strerror(code)}")
