"""The grader's view of a worker's process group: CPU time of the whole tree, and a sweep.

The worker is the leader of its own process group; the seccomp filter keeps
every process it starts in that group (``setsid`` and ``setpgid`` fail) and
the worker is the reaper of its orphans. So the group *is* everything the
worker started, and the kernel's ``/proc`` says how much CPU it used:

* the leader's own time plus the time of the children it has reaped
  (``utime + stime + cutime + cstime``);
* plus the time of every other member still in the table (running, stopped
  or a zombie nobody reaped).

:class:`GroupClock` charges that to the call that is running; :meth:`GroupClock.sweep`
stops the group, charges what its members used, and kills every member but
the leader, so nothing a call started outlives it. Scanning ``/proc`` costs
milliseconds on a busy machine, so it is skipped when no process was created
on the machine since the last scan (the last pid in ``/proc/loadavg`` has not
moved): a call that forks nothing costs two small reads.

The files read on every call (a worker's ``stat`` and ``schedstat``, a thread's
``schedstat``, ``/proc/loadavg``) stay open and are re-read from offset 0
(:func:`read_proc`): a path lookup and an open per read cost more than the read. A
descriptor of ``/proc/<pid>`` names that process, not the number: once it has exited
(and been reaped) the read fails with ``ESRCH`` and the path is opened again, which is
what opening it every time would have found.
"""

from __future__ import annotations

import os
import signal
import threading
import time
from collections import OrderedDict
from dataclasses import dataclass, field

__all__ = [
    "AwakeClock",
    "GroupClock",
    "Member",
    "group_members",
    "last_pid",
    "read_proc",
    "pids_between",
    "run_delay",
    "status_values",
]

#: Environment variable naming a file where the proxy appends each worker's pid: the
#: runner's timeout leaves out the time the workers of its pytest run waited for a CPU.
WORKER_PIDS_VARIABLE = "ROBOLAB_WORKER_PIDS"

_TICK = os.sysconf("SC_CLK_TCK") if hasattr(os, "sysconf") else 100


@dataclass(frozen=True)
class Member:
    """One process of a group, from ``/proc/<pid>/stat``."""

    pid: int
    state: str
    start: int  # start time in clock ticks after boot: (pid, start) names a process uniquely
    own_seconds: float  # utime + stime
    children_seconds: float  # cutime + cstime: the children it reaped

    @property
    def cpu_seconds(self) -> float:
        """Its CPU time and that of the children it reaped."""
        return self.own_seconds + self.children_seconds


#: Most /proc files kept open by :func:`read_proc` (the least recently read is closed).
_OPEN_MAX = 64
_open: OrderedDict[str, int] = OrderedDict()
_open_lock = threading.Lock()
_open_pid = os.getpid()  # a forked child closes nothing of its parent's: it starts afresh


def read_proc(path: str) -> bytes:
    """The contents of a small ``/proc`` file, read through a descriptor kept open.

    The first read of ``path`` opens it; later reads ``pread`` it from offset 0, which
    makes the kernel generate it anew. A read that fails (the process or thread has
    gone: ``ESRCH``) closes the descriptor and opens the path once more, so a number
    reused by a new process is read as a fresh open would. Raises OSError when the
    path cannot be opened or read.
    """
    global _open_pid
    with _open_lock:
        if _open_pid != os.getpid():  # forked: the descriptors are copies, forget them
            _open.clear()
            _open_pid = os.getpid()
        fd = _open.get(path)
        if fd is not None:
            try:
                data = os.pread(fd, 4096, 0)
            except OSError:
                del _open[path]
                os.close(fd)
            else:
                _open.move_to_end(path)
                return data
        fd = os.open(path, os.O_RDONLY | os.O_CLOEXEC)
        try:
            data = os.pread(fd, 4096, 0)
        except OSError:
            os.close(fd)
            raise
        _open[path] = fd
        while len(_open) > _OPEN_MAX:
            os.close(_open.popitem(last=False)[1])
        return data


def _stat(pid: int) -> list[bytes] | None:
    try:
        return read_proc(f"/proc/{pid}/stat").rsplit(b")", 1)[1].split()
    except (OSError, IndexError):
        return None


def _stat_once(pid: int) -> list[bytes] | None:
    """``_stat`` without keeping the file open (a scan of many processes)."""
    try:
        with open(f"/proc/{pid}/stat", "rb") as f:
            return f.read().rsplit(b")", 1)[1].split()
    except (OSError, IndexError):
        return None


def _member(pid: int, fields: list[bytes]) -> Member:
    # fields[0] is the state (field 3 of stat); utime..cstime are fields 14-17, starttime 22.
    own = (int(fields[11]) + int(fields[12])) / _TICK
    children = (int(fields[13]) + int(fields[14])) / _TICK
    return Member(pid, fields[0].decode(), int(fields[19]), own, children)


def last_pid() -> int:
    """The most recently allocated pid of this pid namespace (-1 when unknown)."""
    try:
        return int(read_proc("/proc/loadavg").split()[-1])
    except (OSError, ValueError, IndexError):
        return -1


def run_delay(pid: int | str = "thread-self") -> float | None:
    """Seconds ``pid``'s main thread (default: the calling thread) has spent runnable but
    waiting for a CPU; None when unknown.

    The second field of ``/proc/<pid>/schedstat`` (nanoseconds on the run queue):
    the time a loaded machine, not the process, is responsible for.
    """
    if pid == "thread-self":  # the calling thread's own file (a descriptor per thread)
        pid = f"self/task/{threading.get_native_id()}"
    return _delay_at(f"/proc/{pid}/schedstat")


class AwakeClock:
    """Wall time of a process group *net of the time it waited for a CPU*: wall limits.

    On a loaded machine a process spends most of its wall time on the run queue,
    waiting for a core that other processes hold; that time says nothing about the
    process. What is left -- running, sleeping, blocked on a pipe -- is the same at
    any load, so a wall-clock backstop measured on this clock stops a sleeping or
    stalled submission without ever stopping one that merely waits for a core. Where
    ``/proc/<pid>/schedstat`` cannot be read (no ``CONFIG_SCHED_INFO``, not Linux) the
    clock is plain wall time.

    Waiting is read per task: every thread of the process and every thread or process
    created in its process group since :meth:`restart` (found among the new pids, as
    :class:`GroupClock` finds members). Between two readings the clock leaves out the
    longest wait of any one task that the kernel recorded meanwhile: a worker
    blocked on a thread or a child that waits for a core is waiting for a core, so
    computing in a thread or a child is charged as computing in the main thread is.
    The longest, not the sum, because two tasks waiting at once are one wait; it can
    leave out more than the group waited only while another of its tasks ran, which the
    CPU limits charge. The reader of the clock may :meth:`excuse` time the process spent
    waiting for *it* (a worker that has answered sleeps until the grader, itself
    waiting for a core, reads the answer).
    """

    def __init__(self, pid: int) -> None:
        self.pid = pid
        self._groups: set[int] = set()
        self._readings: dict[str, float] = {}  # a task's schedstat path: its last run delay
        self.restart()

    def _read_all(self) -> float:
        """Read every known task; the longest wait of one since its last reading."""
        longest = 0.0
        for path, before in list(self._readings.items()):
            delay = _delay_at(path)
            if delay is None:  # gone: what it waited since its last reading is not known
                del self._readings[path]
                continue
            longest = max(longest, delay - before)
            self._readings[path] = delay
        now = last_pid()
        new = pids_between(self._last_pid, now)
        if new is None:
            for pgid in self._groups:  # the new pids are not known: from now on
                self._add_threads(pgid)
        for tid in new or ():
            fields = _stat_once(tid)  # a thread's number has a stat file too
            if fields is not None and len(fields) > 2 and int(fields[2]) in self._groups:
                path = f"/proc/{tid}/schedstat"
                if (delay := _delay_at(path)) is not None:
                    longest = max(longest, delay)  # born since the last reading
                    self._readings[path] = delay
        self._last_pid = now
        return longest

    def _add_threads(self, pid: int) -> None:
        """Read ``pid``'s threads from now on (those already read keep their readings)."""
        try:
            tids = os.listdir(f"/proc/{pid}/task")
        except OSError:
            tids = [str(pid)]
        for tid in tids:
            path = f"/proc/{pid}/task/{tid}/schedstat"
            if path not in self._readings and (delay := _delay_at(path)) is not None:
                self._readings[path] = delay

    def _sample(self) -> None:
        # Not capped at the time since the last reading: the kernel adds a wait to a
        # task's run delay when the wait ends (the task gets a core), all at once.
        self._waited += self._read_all()
        self._sampled = time.monotonic()

    def restart(self) -> None:
        """Count from now."""
        self._wall = self._sampled = time.monotonic()
        self._last_pid = last_pid()
        self._readings.clear()
        self._groups = {_pgid(self.pid)}
        self._add_threads(self.pid)
        self._waited = self._excused = 0.0

    def watch(self, pid: int) -> None:
        """Also leave out the time ``pid`` (its threads, its process group) waits for a CPU
        from now on: a process this one waits for (the grader's pytest run waits for its
        workers)."""
        self._sample()  # what was waited so far is read without the new tasks
        self._groups.add(_pgid(pid))
        self._add_threads(pid)

    def excuse(self, seconds: float) -> None:
        """Leave ``seconds`` out: the process waited for the reader, who waited for a CPU."""
        self._excused += max(seconds, 0.0)

    def elapsed(self) -> float:
        """Seconds since :meth:`restart`, less the time spent waiting for a CPU meanwhile."""
        self._sample()
        return max(self._sampled - self._wall - self._waited - self._excused, 0.0)


def _delay_at(path: str) -> float | None:
    """The run delay (seconds) in a ``schedstat`` file; None when it cannot be read."""
    try:
        return int(read_proc(path).split()[1]) / 1e9
    except (OSError, IndexError, ValueError):
        return None


def _pgid(pid: int) -> int:
    """``pid``'s process group (``pid`` itself when it cannot be read)."""
    fields = _stat(pid)
    return int(fields[2]) if fields is not None and len(fields) > 2 else pid


#: Most new pids checked one by one; beyond that (or after a wrap) the whole of /proc is read.
_MAX_RANGE = 4096


def pids_between(since: int, now: int) -> range | None:
    """The pids allocated after ``since`` up to ``now`` (two :func:`last_pid` readings);
    None when unknown (a reading failed, the counter wrapped, or more than
    :data:`_MAX_RANGE`); empty when none were."""
    if now < 0 or since < 0 or not 0 <= now - since <= _MAX_RANGE:
        return None
    return range(since + 1, now + 1)


def status_values(pid: int | str, *names: bytes) -> list[int] | None:
    """The first number of each named line of ``/proc/<pid>/status`` (``b"Tgid"``,
    ``b"Uid"`` -- the real uid --, ``b"Threads"``); None when it cannot be read or
    lacks one of them."""
    try:
        with open(f"/proc/{pid}/status", "rb") as f:
            status = f.read()
    except OSError:
        return None
    values = []
    for name in names:
        start = status.find(b"\n" + name + b":")
        if start < 0:
            return None
        try:
            values.append(int(status[start + len(name) + 2 :].split(None, 1)[0]))
        except (ValueError, IndexError):
            return None
    return values


def group_members(pgid: int, pids: range | None = None) -> list[Member]:
    """Every process whose process group is ``pgid``, among ``pids`` (default: all of /proc).

    A number in ``pids`` may be a thread's: ``/proc/<tid>/stat`` exists, unlisted, and
    reads as its whole process (the process's CPU time; a signal sent to it goes to the
    process), so only thread-group leaders are members.
    """
    candidates = (
        (int(e.name) for e in os.scandir("/proc") if e.name.isdigit()) if pids is None else pids
    )
    found = []
    for pid in candidates:
        fields = _stat_once(pid)
        if fields is not None and len(fields) > 19 and int(fields[2]) == pgid:
            # /proc lists processes only; a number from ``pids`` is one when it leads its threads
            if pids is None or status_values(pid, b"Tgid") == [pid]:
                found.append(_member(pid, fields))
    return found


@dataclass
class GroupClock:
    """CPU time of a worker's process group, charged call by call.

    The accounting runs from the end of one call to the end of the next, so
    what a student's thread does between calls counts against the next call.

    Attributes
    ----------
    leader : int
        The worker's pid (= its process group id).
    charged : dict
        ``{(pid, start): seconds}`` of members already charged to a call.
    pending : float
        CPU seconds of charged members the leader has not reaped yet: when it
        does, they reappear in its children's time and are not charged twice.
    """

    leader: int
    charged: dict[tuple[int, int], float] = field(default_factory=dict)
    pending: float = 0.0
    _own_base: float = 0.0
    _children_seen: float = 0.0
    _children: float = 0.0
    _members: float = 0.0
    _swept_pid: int = -1
    _scanned: float = 0.0

    def __post_init__(self) -> None:
        self._open()

    def _leader(self) -> Member | None:
        fields = _stat(self.leader)
        return None if fields is None or len(fields) < 20 else _member(self.leader, fields)

    def _observe(self) -> float:
        """The leader's own seconds; adds the children it reaped since last time to the call."""
        now = self._leader()
        if now is None:
            return self._own_base  # gone: nothing more to charge
        fresh = now.children_seconds - self._children_seen
        credit = min(self.pending, max(fresh, 0.0))
        self.pending -= credit
        self._children += fresh - credit
        self._children_seen = now.children_seconds
        return now.own_seconds

    def _open(self) -> None:
        """Start charging the next call: what the group uses from now on is its."""
        self._own_base = self._observe()
        self._children = self._members = 0.0
        self._swept_pid = last_pid()

    def start_call(self) -> None:
        """A request is about to be sent (members are rescanned from now on)."""
        self._scanned = time.monotonic()

    def _new_pids(self) -> range | None:
        """The pids allocated since the last sweep, None when unknown; empty when none were."""
        return pids_between(self._swept_pid, last_pid())

    def _others(self) -> list[Member]:
        # Every member but the leader was killed at the last sweep, so only processes
        # created since then can be new members (charged zombies are left out).
        pids = self._new_pids()
        if pids is not None and not pids:
            return []
        return [
            m
            for m in group_members(self.leader, pids)
            if m.pid != self.leader and (m.pid, m.start) not in self.charged
        ]

    def used(self, *, scan_every: float = 0.5) -> float:
        """CPU seconds the group used in this call (members rescanned every ``scan_every`` s)."""
        own = self._observe() - self._own_base
        now = time.monotonic()
        if now - self._scanned >= scan_every:
            self._scanned = now
            self._members = sum(m.cpu_seconds for m in self._others())
        return own + self._children + self._members

    def sweep(self) -> tuple[float, int]:
        """End the call: charge and kill every member but the leader.

        Returns the CPU seconds of the call and how many processes were killed.
        The group is stopped first, so nothing forks while it is scanned; the
        leader is continued afterwards.
        """
        used = self._observe() - self._own_base + self._children
        pids = self._new_pids()
        if pids is not None and not pids:
            self._open()
            return used, 0  # no process was created anywhere since the last sweep
        try:
            os.killpg(self.leader, signal.SIGSTOP)
        except (ProcessLookupError, PermissionError):
            return used, 0
        killed = 0
        others: list[Member] = []
        try:
            others = self._others()
            for member in others:
                self.charged[(member.pid, member.start)] = member.cpu_seconds
                self.pending += member.cpu_seconds
                if member.state != "Z":
                    try:
                        os.kill(member.pid, signal.SIGKILL)
                        killed += 1
                    except (ProcessLookupError, PermissionError):
                        pass
        finally:
            try:
                os.kill(self.leader, signal.SIGCONT)
            except (ProcessLookupError, PermissionError):
                pass
        _wait_dead([m.pid for m in others if m.state != "Z"])
        self._open()
        return used + sum(m.cpu_seconds for m in others), killed


def _wait_dead(pids: list[int], timeout: float = 2.0) -> None:
    """Wait (briefly) until killed processes are zombies or gone: SIGKILL is asynchronous."""
    deadline = time.monotonic() + timeout
    while pids and time.monotonic() < deadline:
        pids = [p for p in pids if (f := _stat_once(p)) is not None and f[0] not in (b"Z", b"X")]
        if pids:
            time.sleep(0.002)
