"""Operating-system isolation of the grading worker (Linux).

The worker process applies this to itself before it runs any student code,
in this order:

1. ``prctl(PR_SET_NO_NEW_PRIVS)``: nothing it executes can gain privileges.
2. As root only: a new network namespace (no network at all) and a new mount
   namespace in which the worker ``chroot``\\ s into a *view*: an empty tmpfs
   holding read-only bind mounts of the Python installation, site-packages,
   the robolab package and its data, a few devices and a fresh tmpfs work
   directory. ``solutions/`` and ``tests/`` do not exist in the view.
3. Resource limits (CPU, address space, processes, file size, open files,
   no core files).
4. As root only: drop to an unprivileged uid/gid of its own (a fresh uid per
   worker, so the process limit holds and the grader can kill everything the
   worker started by uid).
5. Landlock (ABI >= 1): read-only access to the same paths, read-write to the
   work directory, nothing else; ABI >= 4 denies TCP bind/connect; ABI >= 6
   scopes signals and abstract unix sockets to the worker's own processes.
6. The worker becomes the reaper of its orphans (``PR_SET_CHILD_SUBREAPER``),
   then installs a seccomp filter (:mod:`robolab.grading.isolation.seccomp`): no other
   process can be touched, no socket opened, no process leaves the group.

An unprivileged grader gets step 2 too when the kernel allows unprivileged
user namespaces: the worker enters a user namespace of its own (its uid
mapped to itself), builds the same view with a size-capped tmpfs work
directory and no network, then drops every capability.

Landlock alone (any user, kernel >= 5.13) already makes the answers
unreadable; the namespaces add "no network at all" and the view as a second
wall. See ``docs/grading.md`` for what holds on which system.
"""

from __future__ import annotations

import ctypes
import errno
import os
import platform
import resource
import stat
import sys
from dataclasses import asdict, dataclass, field
from pathlib import Path

from robolab.grading.isolation import processes, seccomp
from robolab.grading.isolation.landlock import landlock_abi, restrict
from robolab.grading.isolation.libc import SandboxError, _check, _libc

__all__ = [
    "SandboxError",
    "SandboxPlan",
    "SandboxReport",
    "apply",
    "directory_bytes",
    "landlock_abi",
    "plan_sandbox",
    "worker_uid",
]

#: Worker uids are UID_BASE + the worker's pid: unique per live worker, far
#: above any real account and below the 32-bit ids that mean "no id".
UID_BASE = 1_500_000_000
#: Largest file the worker may write (RLIMIT_FSIZE).
MAX_FILE_BYTES = 16 * 2**20
#: Size of the worker's tmpfs work directory (root only).
WORKDIR_BYTES = 64 * 2**20
#: Most open files.
MAX_OPEN_FILES = 256
#: Devices the worker may use.
DEVICES = ("/dev/null", "/dev/zero", "/dev/random", "/dev/urandom")
#: System paths the Python runtime and compiled extensions may need (read-only).
SYSTEM_PATHS = (
    "/usr",
    "/lib",
    "/lib64",
    "/lib32",
    "/etc/ld.so.cache",
    "/etc/localtime",
    "/etc/fonts",
)

# Syscall numbers: the same on x86_64 and aarch64 (and every architecture
# using the generic table; Landlock came after the tables were unified).
_PR_SET_NO_NEW_PRIVS = 38
_PR_SET_PDEATHSIG = 1
_PR_SET_CHILD_SUBREAPER = 36
_CLONE_NEWNS = 0x00020000
_CLONE_NEWNET = 0x40000000
_CLONE_NEWUSER = 0x10000000
_LINUX_CAPABILITY_VERSION_3 = 0x20080522
_MS_RDONLY = 1
_MS_NOSUID = 2
_MS_NODEV = 4
_MS_REMOUNT = 32
_MS_BIND = 4096
_MS_REC = 16384
_MS_PRIVATE = 1 << 18


def worker_uid(worker_pid: int) -> int:
    """The unprivileged uid a root-started worker with this pid runs as."""
    return UID_BASE + worker_pid


@dataclass
class SandboxPlan:
    """What the worker should apply to itself (decided by the grader).

    Attributes
    ----------
    workdir : str
        The worker's working and temporary directory (read-write).
    view_root : str or None
        An empty directory to build the chroot view in (root only), or None.
    drop_privileges : bool
        Switch to :func:`worker_uid` (root only).
    landlock : bool
        Apply Landlock when the kernel supports it.
    readonly : list of str
        Extra read-only paths (the robolab package and data directory).
    forbidden : list of str
        Paths that must stay unreadable (``solutions/``, ``tests/``): any
        read-only path containing one of them is left out.
    cpu_seconds, memory_bytes, max_processes : resource limits.
    cpu_lifetime_seconds : float
        Hard CPU limit over the worker's whole life (the grader restarts the
        worker before it gets close).
    seed_files : dict of str to str
        Files copied into the fresh work directory, ``{relative destination:
        source}`` (matplotlib's font cache, so no worker spends a second
        rebuilding it).
    user_namespace : bool
        Not root: build the view inside a user namespace of the worker's own
        when the kernel allows it (needs ``view_root``).
    seccomp : bool
        Install the seccomp filter of :mod:`robolab.grading.isolation.seccomp`.
    """

    workdir: str
    view_root: str | None = None
    drop_privileges: bool = False
    landlock: bool = True
    readonly: list[str] = field(default_factory=list)
    forbidden: list[str] = field(default_factory=list)
    cpu_seconds: float = 30.0
    cpu_lifetime_seconds: float = 300.0
    memory_bytes: int = 2 * 2**30
    max_processes: int = 64
    seed_files: dict[str, str] = field(default_factory=dict)
    user_namespace: bool = False
    seccomp: bool = True

    def to_dict(self) -> dict:
        return asdict(self)


@dataclass
class SandboxReport:
    """What the worker actually applied (sent back to the grader before any student code runs)."""

    landlock_abi: int = 0
    landlock: bool = False
    network_denied: str = "no"  # "namespace", "seccomp" (no sockets), "landlock-tcp" or "no"
    view: bool = False
    user_namespace: bool = False
    uid: int = -1
    process_limit: bool = False
    seccomp: bool = False
    #: What keeps the worker from signalling other processes: "uid", "landlock", "seccomp", "no".
    signals: str = "no"
    #: What caps the work directory: "tmpfs" or "" (the grader then checks its size).
    scratch: str = ""
    notes: list[str] = field(default_factory=list)

    @property
    def protects_answers(self) -> bool:
        """True when the OS keeps the worker from reading solutions/ and tests/."""
        return self.landlock or self.view

    @property
    def protects_processes(self) -> bool:
        """True when the worker can neither signal nor reconfigure another process."""
        return self.uid >= UID_BASE or (self.seccomp and self.signals != "no")

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict) -> SandboxReport:
        known = {k: data[k] for k in cls.__dataclass_fields__ if k in data}
        return cls(**known)


def plan_sandbox(
    workdir: Path,
    *,
    readonly: list[Path],
    forbidden: list[Path],
    cpu_seconds: float,
    memory_bytes: int,
    max_processes: int,
) -> SandboxPlan:
    """Decide the isolation for a worker started by this (grader) process.

    As root: the namespace view and a dropped uid; always: Landlock when the
    kernel has it. ``workdir`` must be an empty directory the grader owns; its
    parent gets the view root next to it.
    """
    linux = sys.platform == "linux"
    root = os.geteuid() == 0 and linux
    view_root = None
    if linux:
        view_root = str(workdir.parent / "view")
        os.makedirs(view_root, exist_ok=True)
    return SandboxPlan(
        workdir=str(workdir),
        view_root=view_root,
        drop_privileges=root,
        user_namespace=linux and not root,
        landlock=True,
        readonly=[str(p) for p in readonly],
        forbidden=[str(p) for p in forbidden],
        cpu_seconds=cpu_seconds,
        cpu_lifetime_seconds=max(10 * cpu_seconds, cpu_seconds + 60),
        memory_bytes=memory_bytes,
        max_processes=max_processes,
    )


# --- the worker side -----------------------------------------------------------------------------


def apply(plan: SandboxPlan) -> SandboxReport:
    """Isolate the calling process (the worker) as planned; call before any student code.

    Must run while the process has a single thread: Landlock and
    no_new_privs apply to the calling thread and the threads it creates later.

    Returns
    -------
    SandboxReport
        What was applied; steps that the system does not support are noted
        and skipped, steps that fail unexpectedly raise.

    Raises
    ------
    SandboxError
        When a supported step fails.
    """
    report = SandboxReport()
    libc = _libc()
    _check(libc.prctl(_PR_SET_NO_NEW_PRIVS, 1, 0, 0, 0), "prctl(PR_SET_NO_NEW_PRIVS)")
    readonly = _readonly_paths(plan, report)
    seeds = _read_seeds(plan)  # before the view hides their sources
    uid = worker_uid(os.getpid()) if plan.drop_privileges else None

    if plan.view_root is not None and plan.user_namespace and not plan.drop_privileges:
        _user_namespace_view(libc, plan, readonly, report)
    elif plan.view_root is not None:
        if libc.unshare(_CLONE_NEWNET) == 0:
            report.network_denied = "namespace"
        else:
            report.notes.append(f"no network namespace: {os.strerror(ctypes.get_errno())}")
        if libc.unshare(_CLONE_NEWNS) == 0:
            _enter_view(libc, plan, readonly, uid)
            report.view = True
            report.scratch = "tmpfs"
        else:
            report.notes.append(f"no mount namespace: {os.strerror(ctypes.get_errno())}")

    # Without a uid or a user namespace of its own, the worker's processes and threads
    # are counted with everything else its user runs (a desktop session: hundreds).
    own_count = uid is not None or report.user_namespace  # (root, kept: no limit at all)
    _set_limits(plan, already=0 if own_count else tasks_of_user(os.getuid()))

    if uid is not None:
        if not report.view:
            blocked = [p for p in readonly if not _others_can_reach(p)]
            if blocked:
                # Without the view an unprivileged uid could not even import the stdlib.
                report.notes.append(f"kept root: {blocked[0]} is not readable by other users")
                uid = None
            else:
                os.chown(plan.workdir, uid, uid)
        if uid is not None:
            os.setgroups([])
            os.setresgid(uid, uid, uid)
            os.setresuid(uid, uid, uid)
    _write_seeds(plan.workdir, seeds)
    report.uid = os.getuid()
    report.process_limit = report.uid != 0

    # After the uid change, which clears it: die with the grader.
    libc.prctl(_PR_SET_PDEATHSIG, 9, 0, 0, 0)

    report.landlock_abi = landlock_abi()
    if plan.landlock and report.landlock_abi > 0:
        restrict(libc, report.landlock_abi, readonly, plan.workdir, DEVICES)
        report.landlock = True
        if report.landlock_abi >= 4 and report.network_denied == "no":
            report.network_denied = "landlock-tcp"
    elif plan.landlock:
        report.notes.append("Landlock is not available on this kernel")
    os.chdir(plan.workdir)
    _confine_processes(libc, plan, report)
    return report


def _user_namespace_view(
    libc: ctypes.CDLL, plan: SandboxPlan, readonly: list[str], report: SandboxReport
) -> None:
    """Not root: the view, a capped tmpfs and no network, inside a user namespace of our own."""
    uid, gid = os.getuid(), os.getgid()
    if libc.unshare(_CLONE_NEWUSER | _CLONE_NEWNS | _CLONE_NEWNET) != 0:
        report.notes.append(f"no user namespace: {os.strerror(ctypes.get_errno())}")
        return
    try:
        # Our uid and gid map to themselves; no supplementary groups can be set.
        Path("/proc/self/setgroups").write_text("deny")
        Path("/proc/self/uid_map").write_text(f"{uid} {uid} 1")
        Path("/proc/self/gid_map").write_text(f"{gid} {gid} 1")
        report.user_namespace = True
        report.network_denied = "namespace"
        _enter_view(libc, plan, readonly, None)
        report.view = True
        report.scratch = "tmpfs"
    except OSError as exc:
        report.notes.append(f"user namespace view failed: {exc}")
    finally:
        if report.user_namespace:
            _drop_capabilities(libc)


class _CapHeader(ctypes.Structure):
    _fields_ = [("version", ctypes.c_uint32), ("pid", ctypes.c_int)]


class _CapData(ctypes.Structure):
    _fields_ = [
        ("effective", ctypes.c_uint32),
        ("permitted", ctypes.c_uint32),
        ("inheritable", ctypes.c_uint32),
    ]


def _drop_capabilities(libc: ctypes.CDLL) -> None:
    # The capabilities a new user namespace grants are no longer needed once the view is built.
    header = _CapHeader(_LINUX_CAPABILITY_VERSION_3, 0)
    data = (_CapData * 2)()
    _check(libc.capset(ctypes.byref(header), data), "capset")


def _confine_processes(libc: ctypes.CDLL, plan: SandboxPlan, report: SandboxReport) -> None:
    """Reap our orphans (so their CPU time is ours), then the seccomp filter."""
    if report.uid >= UID_BASE:
        report.signals = "uid"
    elif report.landlock and report.landlock_abi >= 6:
        report.signals = "landlock"
    if sys.platform != "linux":
        return
    _check(libc.prctl(_PR_SET_CHILD_SUBREAPER, 1, 0, 0, 0), "prctl(PR_SET_CHILD_SUBREAPER)")
    if not plan.seccomp:
        return
    if not seccomp.supported():
        report.notes.append(f"no seccomp filter for {platform.machine()}")
        return
    own_group = os.getpgrp() if report.signals == "no" else None
    try:
        seccomp.install(own_group)
    except seccomp.SeccompError as exc:
        report.notes.append(f"seccomp filter refused: {exc}")
        return
    report.seccomp = True
    if report.signals == "no":
        report.signals = "seccomp"
    if report.network_denied != "namespace":
        report.network_denied = "seccomp"


#: Most files and directories the grader counts in a work directory without a tmpfs cap.
MAX_WORKDIR_ENTRIES = 4096


def directory_bytes(path: str, limit: int) -> int:
    """Disk space used beneath ``path`` (allocated blocks), counted up to just past ``limit``.

    More than :data:`MAX_WORKDIR_ENTRIES` entries count as ``limit + 1``: the
    walk stays cheap whatever a worker created.
    """
    total, entries, pending = 0, 0, [path]
    while pending and total <= limit:
        try:
            iterator = os.scandir(pending.pop())
        except OSError:
            continue
        with iterator:
            for entry in iterator:
                entries += 1
                if entries > MAX_WORKDIR_ENTRIES:
                    return limit + 1
                try:
                    info = entry.stat(follow_symlinks=False)
                except OSError:
                    continue
                total += info.st_blocks * 512
                if entry.is_dir(follow_symlinks=False):
                    pending.append(entry.path)
    return total


def _readonly_paths(plan: SandboxPlan, report: SandboxReport) -> list[str]:
    """The Python runtime, site-packages, system libraries and extras, minus forbidden paths."""
    candidates = [sys.base_prefix, sys.base_exec_prefix, sys.prefix, sys.exec_prefix, *SYSTEM_PATHS]
    candidates += [p for p in sys.path if p and os.path.isdir(p)]
    candidates += plan.readonly
    forbidden = [os.path.realpath(p) for p in plan.forbidden]
    kept: list[str] = []
    for path in candidates:
        if not os.path.lexists(path):
            continue
        real = os.path.realpath(path)
        if any(f == real or f.startswith(real.rstrip("/") + "/") for f in forbidden):
            report.notes.append(f"left out {path}: it contains a forbidden path")
            continue
        if path not in kept:
            kept.append(path)
    # Drop paths already inside another kept directory (bind mounts would nest needlessly).
    return [
        p
        for p in kept
        if not any(
            q != p and p.startswith(q.rstrip("/") + "/") for q in kept if not os.path.islink(q)
        )
    ]


def _read_seeds(plan: SandboxPlan) -> dict[str, bytes]:
    seeds = {}
    for destination, source in plan.seed_files.items():
        if os.path.isabs(destination) or ".." in Path(destination).parts:
            raise SandboxError(
                errno.EINVAL,
                f"seed file destination must stay in the work directory: {destination}",
            )
        try:
            seeds[destination] = Path(source).read_bytes()
        except OSError:
            continue  # a missing cache only costs time
    return seeds


def _write_seeds(workdir: str, seeds: dict[str, bytes]) -> None:
    for destination, data in seeds.items():
        target = Path(workdir) / destination
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_bytes(data)


def tasks_of_user(uid: int) -> int:
    """Processes and threads of ``uid`` now: what ``RLIMIT_NPROC`` counts for it."""
    count = 0
    for entry in os.scandir("/proc"):
        if entry.name.isdigit():
            values = processes.status_values(entry.name, b"Uid", b"Threads")  # None: gone
            if values is not None and values[0] == uid:
                count += values[1]
    return count


def _set_limits(plan: SandboxPlan, already: int = 0) -> None:
    """The resource limits; ``already``: tasks the process limit counts besides the worker's."""
    cpu_soft = max(1, int(plan.cpu_seconds + 0.999))
    cpu_hard = max(cpu_soft + 1, int(plan.cpu_lifetime_seconds))
    resource.setrlimit(resource.RLIMIT_CORE, (0, 0))
    resource.setrlimit(resource.RLIMIT_CPU, (cpu_soft, cpu_hard))
    resource.setrlimit(resource.RLIMIT_AS, (plan.memory_bytes, plan.memory_bytes))
    resource.setrlimit(resource.RLIMIT_FSIZE, (MAX_FILE_BYTES, MAX_FILE_BYTES))
    resource.setrlimit(resource.RLIMIT_NOFILE, (MAX_OPEN_FILES, MAX_OPEN_FILES))
    nproc = plan.max_processes + already
    resource.setrlimit(resource.RLIMIT_NPROC, (nproc, nproc))


def _others_can_reach(path: str) -> bool:
    """Whether a user other than the owner can traverse to ``path`` (o+x on every ancestor)."""
    current = Path(path).resolve()
    for directory in [current, *current.parents]:
        try:
            mode = os.stat(directory).st_mode
        except OSError:
            return False
        if stat.S_ISDIR(mode) and not mode & stat.S_IXOTH:
            return False
    return True


def _c(text: str | None) -> bytes | None:
    return None if text is None else text.encode()


def _mount(
    libc: ctypes.CDLL,
    source: str | None,
    target: str,
    fstype: str | None,
    flags: int,
    data: str | None = None,
) -> None:
    _check(
        libc.mount(_c(source), _c(target), _c(fstype), ctypes.c_ulong(flags), _c(data)),
        f"mount {source or fstype} on {target}",
    )


def _enter_view(libc: ctypes.CDLL, plan: SandboxPlan, readonly: list[str], uid: int | None) -> None:
    """chroot into a tmpfs that holds only what the worker may see."""
    assert plan.view_root is not None
    root = plan.view_root
    # Private propagation: nothing mounted here is seen by the host.
    _mount(libc, None, "/", None, _MS_REC | _MS_PRIVATE)
    _mount(libc, "tmpfs", root, "tmpfs", _MS_NOSUID | _MS_NODEV, "mode=0755,size=4m")
    for path in readonly:
        target = root + path
        if os.path.islink(path):
            # /lib -> usr/lib on merged-/usr systems: recreate the link, not a second mount.
            os.makedirs(os.path.dirname(target), exist_ok=True)
            if not os.path.lexists(target):
                os.symlink(os.readlink(path), target)
            continue
        _bind(libc, path, target, readonly=True)
    for device in DEVICES:
        if os.path.exists(device):
            _bind(libc, device, root + device, readonly=device != "/dev/null")
    work = root + plan.workdir
    os.makedirs(work, exist_ok=True)
    owner = f",uid={uid},gid={uid}" if uid is not None else ""
    _mount(
        libc,
        "tmpfs",
        work,
        "tmpfs",
        _MS_NOSUID | _MS_NODEV,
        f"mode=0700,size={WORKDIR_BYTES}{owner}",
    )
    os.chdir(root)
    os.chroot(".")
    os.chdir("/")


def _bind(libc: ctypes.CDLL, source: str, target: str, *, readonly: bool) -> None:
    if os.path.isdir(source):
        os.makedirs(target, exist_ok=True)
    else:
        os.makedirs(os.path.dirname(target), exist_ok=True)
        if not os.path.exists(target):
            open(target, "w").close()  # noqa: SIM115 - a mount point for a file
    _mount(libc, source, target, None, _MS_BIND | _MS_REC)
    if readonly:
        # A bind mount ignores MS_RDONLY on creation; it takes a remount.
        flags = _MS_REMOUNT | _MS_BIND | _MS_RDONLY | _MS_NOSUID
        if not source.startswith("/dev/"):
            flags |= _MS_NODEV
        _mount(libc, None, target, None, flags)

