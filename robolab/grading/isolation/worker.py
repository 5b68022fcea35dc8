"""The grading worker: defines a submission's functions and runs calls to them, isolated.

Started by :mod:`robolab.grading.running.proxy` as::

    python -I -B -m robolab.grading.isolation.worker CONFIG_JSON

``CONFIG_JSON`` names two inherited pipe descriptors and the sandbox plan.
The worker first isolates itself (:func:`robolab.grading.isolation.sandbox.apply`, while
it is still single-threaded and before any student code exists in it), then
answers requests until its request pipe closes.

Wire protocol: each message from the worker is an 8-byte little-endian length followed
by a pickle (protocol 5). Each message from the grader is a frame of
:func:`robolab.grading.wire.arrays.encode`: a pickle whose arrays follow it out of band
(and a large array sent before may be named by its slot). Grader -> worker (trusted,
plain pickle)::

    ("define", [(cell_index, source), ...], wall_seconds, cpu_seconds)
    ("call", call_id, name, args, kwargs, cpu_seconds, answered_names)
    ("answer", value, observation, rng_states) | ("raise", info) | ("own", reason)
                                              # replies to a depcall, during a call

Worker -> grader (untrusted: decoded with :func:`robolab.grading.wire.codec.loads`)::

    ("failed", message)                       # the sandbox could not be applied
    ("ready", sandbox_report_dict)
    ("defined", [function names], [(cell_index, "error", message)])
    ("ok", call_id, value, observation)      # observation: see robolab.grading.wire.observe
    ("error", call_id, {"type", "bases", "message", "traceback"}, observation)
    ("missing", call_id, name)
    ("exit", call_id, description)            # SystemExit / KeyboardInterrupt
    ("depcall", call_id, name, args, kwargs, rngs)  # a call of an exercise below the one
                                              # graded, answered by the grader's reference
                                              # (robolab.grading.wire.depcall)

Once student code has run, nothing this process says can be trusted: the
grader enforces every limit itself and decodes with an allow-list.
"""

from __future__ import annotations

import builtins
import json
import os
import pickle
import struct
import sys

HEADER = struct.Struct("<Q")
#: Longest exception message or traceback sent back, in characters.
MAX_TEXT = 20_000
#: Freed memory malloc may keep for reuse (:func:`~.libc.pad_heap`): 32 MiB resident at most.
HEAP_PAD_BYTES = 1 << 25
#: Top-level packages a submission must never import.
FORBIDDEN_PACKAGES = frozenset({"solutions", "tests"})


class RefuseAnswers:
    """Meta-path finder that refuses ``solutions`` and ``tests`` (the answers).

    The editable install maps ``solutions`` to the repository; this refuses it
    before that finder is asked. It is only the first wall: the sandbox makes
    the files themselves unreadable.
    """

    @staticmethod
    def find_spec(fullname: str, path: object = None, target: object = None) -> None:
        if fullname.partition(".")[0] in FORBIDDEN_PACKAGES:
            raise ModuleNotFoundError(
                f"No module named {fullname!r} (not available to submissions)", name=fullname
            )
        return None


def write_frame(fd: int, payload: bytes) -> None:
    """Write one length-prefixed message, completely (the payload is not copied)."""
    write_all(fd, [memoryview(HEADER.pack(len(payload))), memoryview(payload)])


def write_all(fd: int, views: list[memoryview]) -> None:
    """Write every byte of ``views``, in order, to the blocking descriptor ``fd``."""
    views = [v.cast("B") if v.ndim != 1 or v.format != "B" else v for v in views if v.nbytes]
    while views:
        written = os.writev(fd, views[:64])
        while written:
            if written >= views[0].nbytes:
                written -= views.pop(0).nbytes
            else:
                views[0], written = views[0][written:], 0


def read_frame(fd: int) -> tuple[bytearray, list, bool] | None:
    """Read one request frame of the grader (:mod:`~.wire.arrays`): the pickle, its
    out-of-band buffers, each in memory of its own, and whether it names slots; None at
    end of file."""
    from robolab.grading.wire.arrays import LENGTH, READONLY, REQUEST_HEADER, SLOTTED

    header = _read_exactly(fd, REQUEST_HEADER.size)
    if header is None:
        return None
    size, count = REQUEST_HEADER.unpack(header)
    slotted, count = bool(count & SLOTTED), count & ~SLOTTED
    lengths = _read_exactly(fd, LENGTH.size * count) if count else b""
    body = _read_exactly(fd, size)
    if lengths is None or body is None:
        raise EOFError("the request pipe closed in the middle of a message")
    buffers: list = []
    for (length,) in LENGTH.iter_unpack(lengths):
        data = _read_exactly(fd, length & ~READONLY)
        if data is None:
            raise EOFError("the request pipe closed in the middle of a message")
        buffers.append(memoryview(data).toreadonly() if length & READONLY else data)
    return body, buffers, slotted


def _read_exactly(fd: int, size: int) -> bytearray | None:
    """``size`` bytes read straight into one buffer; None at end of file before the first."""
    data = bytearray(size)
    view, got = memoryview(data), 0
    while got < size:
        n = os.readv(fd, [view[got:]])
        if not n:
            if not got:
                return None
            raise EOFError("the request pipe closed in the middle of a message")
        got += n
    return data


def _send(fd: int, message: tuple) -> None:
    write_frame(fd, pickle.dumps(message, protocol=5))


def _text(value: object) -> str:
    try:
        text = str(value)
    except BaseException:  # noqa: BLE001 - a student's __str__ may raise anything
        text = f"<{type(value).__name__} whose str() failed>"
    return text if len(text) <= MAX_TEXT else text[:MAX_TEXT] + " [...]"


def describe_exception(exc: BaseException) -> dict:
    """Type name, builtin base classes, message and traceback of a student exception."""
    import traceback

    kind = type(exc)
    bases = [c.__name__ for c in kind.__mro__ if getattr(builtins, c.__name__, None) is c]
    # Drop the worker's own frame: the student's traceback starts in their code.
    tb = exc.__traceback__.tb_next if exc.__traceback__ is not None else None
    try:
        text = "".join(traceback.format_exception(kind, exc, tb))
    except BaseException:  # noqa: BLE001
        text = f"{kind.__name__}: {_text(exc)}\n"
    if len(text) > MAX_TEXT:
        text = text[: MAX_TEXT // 2] + "\n[...]\n" + text[-MAX_TEXT // 2 :]
    return {"type": kind.__qualname__, "bases": bases, "message": _text(exc), "traceback": text}


def define(notebook, cells: list[tuple[int, str]], wall_seconds: float, cpu_seconds: float):
    """Run the notebook's needed cells whole, in order, as a kernel would; return the failures.

    ``notebook`` is the :class:`robolab.grading.loading.kernel.Notebook` the worker
    entered: the notebook runs as ``__main__`` with the scratch folder as its
    folder. See :func:`robolab.grading.loading.kernel.run_cells`: a cell that raises
    or does not compile is recorded and the next cell still runs; the cell that uses
    up the load budget (``cpu_seconds`` here, ``wall_seconds`` on the grader's clock,
    which sends ``SIGALRM``) is stopped and named.
    """
    import signal

    from robolab.grading.loading import kernel

    # The grader sends SIGALRM when the load's wall budget is spent on its clock (which leaves
    # out the time this worker waited for a CPU): it stops a cell, and is ignored between cells.
    signal.signal(signal.SIGALRM, signal.SIG_IGN)
    return notebook.run(cells, wall_seconds, cpu_seconds, kernel.flush, wall_timer=False)


def function_names(namespace: dict) -> list[str]:
    """Public callables of the submission's namespace (functions, classes, imported callables)."""
    import types

    return sorted(
        name
        for name, value in namespace.items()
        if not name.startswith("__") and callable(value) and not isinstance(value, types.ModuleType)
    )


def _dumps(value: object) -> bytes:
    from robolab.grading.wire.codec import dumps  # imports numpy: only after the sandbox is applied

    return dumps(value)


def _watch(args: tuple, kwargs: dict, kept=None):
    """A snapshot of the call's argument arrays (see :mod:`~.wire.observe`), or None.

    ``kept(array)``: the worker's untouched copy of an argument, if it has one.
    """
    from robolab.grading.wire.observe import (
        Watch,  # imports numpy: only after the sandbox is applied
    )

    try:
        return Watch(args, kwargs, kept)
    except Exception:  # noqa: BLE001 - an argument numpy cannot copy: nothing is observed
        return None


def _limit_cpu(cpu_seconds: float) -> None:
    # Cooperative per-call CPU budget; the grader measures and enforces it too.
    import resource

    usage = resource.getrusage(resource.RUSAGE_SELF)
    used = usage.ru_utime + usage.ru_stime
    soft, hard = resource.getrlimit(resource.RLIMIT_CPU)
    wanted = int(used + cpu_seconds) + 1
    if hard != resource.RLIM_INFINITY:
        wanted = min(wanted, hard)
    resource.setrlimit(resource.RLIMIT_CPU, (wanted, hard))


def _call(
    response_fd: int,
    namespace: dict,
    call_id: int,
    name: str,
    args: tuple,
    kwargs: dict,
    cpu_seconds: float,
    kept=None,
) -> None:
    watch = None
    function = namespace.get(name)
    if name.startswith("__") or function is None or not callable(function):
        _send(response_fd, ("missing", call_id, name))
        return
    try:
        _limit_cpu(cpu_seconds)
        watch = _watch(args, kwargs, kept)
        value = function(*args, **kwargs)
        observation = watch.report(value) if watch is not None else None
        payload = _dumps(("ok", call_id, value, observation))
    except (SystemExit, KeyboardInterrupt, GeneratorExit) as exc:
        code = getattr(exc, "code", None)
        _send(response_fd, ("exit", call_id, f"{type(exc).__name__}({_text(code)})"))
        return
    except BaseException as exc:  # noqa: BLE001 - any student failure is reported, not fatal
        try:  # what it changed before raising, as a caller in-process would see it
            observation = watch.report(None) if watch is not None else None
        except BaseException:  # noqa: BLE001 - `watch` unbound, or the snapshot itself failed
            observation = None
        _send(response_fd, ("error", call_id, describe_exception(exc), observation))
        return
    finally:
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except Exception:  # noqa: BLE001 - the student may have closed or replaced it
                pass
    write_frame(response_fd, payload)


def _asker(request_fd: int, response_fd: int, call_id: int, received):
    """Send a depcall of the running call to the grader and return its reply."""
    from robolab.grading.wire.arrays import decode

    def ask(message: tuple) -> tuple:
        try:
            payload = _dumps((message[0], call_id, *message[1:]))
        except Exception as exc:  # noqa: BLE001 - arguments that are not plain data
            return ("own", f"the arguments cannot be sent: {_text(exc)}")
        write_frame(response_fd, payload)
        frame = read_frame(request_fd)
        if frame is None:
            raise EOFError("the grader closed the request pipe during a call")
        body, buffers, slotted = frame
        return decode(body, buffers, received, slotted)  # from the grader, the trusted side

    return ask


def reap_children() -> None:
    """Reap the children the grader killed after the last call (the worker is their reaper)."""
    while True:
        try:
            pid, _ = os.waitpid(-1, os.WNOHANG)
        except ChildProcessError:
            return
        if pid == 0:
            return


def serve(request_fd: int, response_fd: int) -> int:
    """Answer define and call requests until the grader closes the request pipe."""
    from robolab.grading.loading import kernel
    from robolab.grading.wire.arrays import ReceivedArrays, decode

    received = ReceivedArrays()  # the large arrays this worker's grader stored here
    # The notebook's module, as a kernel holds it: `__main__`, in the scratch folder
    # (the working folder the sandbox left writable), which is first on sys.path.
    notebook = kernel.Notebook(os.getcwd()).enter()
    namespace = notebook.namespace
    while True:
        frame = read_frame(request_fd)
        if frame is None:
            return 0
        reap_children()
        body, buffers, slotted = frame
        request = decode(body, buffers, received, slotted)  # from the grader, the trusted side
        if request[0] == "define":
            problems = define(notebook, *request[1:])
            for stream in (sys.stdout, sys.stderr):
                stream.flush()
            _send(response_fd, ("defined", function_names(namespace), problems))
        elif request[0] == "call":
            from robolab.grading.loading.delegation import (
                forbidden,  # the library's copy of the exercise
            )
            from robolab.grading.wire.depcall import answered

            call_id, name, args, kwargs, cpu_seconds, *below = request[1:]
            ask = _asker(request_fd, response_fd, call_id, received)
            # The library's copy of the exercise is disabled while it runs; the exercises
            # below it are answered by the grader's reference (a mistake costs once).
            with forbidden(name, namespace), answered(below[0] if below else (), namespace, ask):
                _call(
                    response_fd, namespace, call_id, name, args, kwargs, cpu_seconds, received.kept
                )
        else:
            raise ValueError(f"unknown request {request[0]!r}")


def main(argv: list[str] | None = None) -> int:
    """Isolate this process, then serve the grader (see the module docstring)."""
    argv = sys.argv if argv is None else argv
    config = json.loads(argv[1])
    request_fd, response_fd = config["request_fd"], config["response_fd"]
    for fd in (request_fd, response_fd):
        os.set_inheritable(fd, False)  # children the student starts do not get the protocol pipes

    # Imported here, before anything that could start threads (numpy's BLAS).
    from robolab.grading.isolation import sandbox

    sys.meta_path.insert(0, RefuseAnswers())
    try:
        report = sandbox.apply(sandbox.SandboxPlan(**config["plan"]))
    except Exception as exc:  # noqa: BLE001 - reported to the grader, which refuses to grade
        _send(response_fd, ("failed", f"{type(exc).__name__}: {exc}"))
        return 3
    sys.stdout.reconfigure(line_buffering=True)
    from robolab.grading.isolation.libc import pad_heap

    # Large temporaries reuse freed pages instead of faulting fresh ones in on every call.
    pad_heap(HEAP_PAD_BYTES)
    import numpy  # noqa: F401 - warm the import every submission makes

    _send(response_fd, ("ready", report.to_dict()))
    return serve(request_fd, response_fd)


if __name__ == "__main__":
    sys.exit(main())
