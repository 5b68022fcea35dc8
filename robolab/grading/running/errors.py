"""What a student's code can do wrong, as the grader reports it: one exception class each.

``StudentCodeError`` carries a one-line message and a ``kind`` (``timeout``, ``crash``,
``result``, ``protocol`` ...); ``student_error_class`` rebuilds a built-in exception the
worker raised (by name only: nothing of the student's objects crosses).
"""

from __future__ import annotations

import builtins
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    pass


class StudentCodeError(Exception):
    """Raised by, or because of, student code.

    Attributes
    ----------
    kind : str
        The student's exception type name (``"ValueError"``), or ``"crash"``,
        ``"timeout"``, ``"missing"``, ``"result"`` (a result that is not plain
        data) or ``"protocol"`` (the worker broke the protocol).
    message : str
        What happened, in words that may be shown to the student.
    student_traceback : str
        The traceback from the worker (student code only), may be empty.
    """

    def __init__(self, message: str, *, kind: str = "error", student_traceback: str = "") -> None:
        super().__init__(message)
        self.kind = kind
        self.message = message
        self.student_traceback = student_traceback

    def __str__(self) -> str:
        return self.message


class WorkerCrashed(StudentCodeError):
    """The worker died: segfault, ``os._exit``, ``sys.exit``, memory limit, killed."""


class WorkerTimeout(StudentCodeError):
    """A call exceeded its wall-time or CPU-time limit."""


class ScratchExceeded(WorkerCrashed):
    """A call wrote more files than its work directory may hold (without the tmpfs view)."""


class MissingFunction(StudentCodeError, AttributeError):
    """The notebook does not define the function."""


class WorkerStartError(RuntimeError):
    """The worker could not be started or isolated: grading itself cannot run."""


class IsolationWarning(UserWarning):
    """The operating system does not isolate the worker as documented."""


# Builtin exceptions a student's exception is re-raised as (together with
# StudentCodeError), so that `pytest.raises(ValueError)` works across the boundary.
_REBUILT = (
    ArithmeticError,
    AssertionError,
    AttributeError,
    BufferError,
    EOFError,
    FloatingPointError,
    ImportError,
    IndexError,
    KeyError,
    LookupError,
    MemoryError,
    ModuleNotFoundError,
    NameError,
    NotImplementedError,
    OSError,
    BlockingIOError,
    ChildProcessError,
    ConnectionError,
    BrokenPipeError,
    ConnectionAbortedError,
    ConnectionRefusedError,
    ConnectionResetError,
    FileExistsError,
    FileNotFoundError,
    InterruptedError,
    IsADirectoryError,
    NotADirectoryError,
    PermissionError,
    ProcessLookupError,
    TimeoutError,
    OverflowError,
    RecursionError,
    ReferenceError,
    RuntimeError,
    SystemError,
    TypeError,
    UnboundLocalError,
    UnicodeError,
    ValueError,
    ZeroDivisionError,
)
_BUILTIN_BY_NAME = {cls.__name__: cls for cls in _REBUILT}
_student_classes: dict[str, type[StudentCodeError]] = {}


def student_error_class(bases: list[str]) -> type[StudentCodeError]:
    """The class a student exception is re-raised as, from its builtin base class names.

    The first name that is a rebuildable builtin wins (``LinAlgError`` arrives
    as ``["ValueError", "Exception", ...]``); without one, StudentCodeError.
    """
    for name in bases:
        builtin = _BUILTIN_BY_NAME.get(name)
        if builtin is None or getattr(builtins, name, None) is not builtin:
            continue
        cls = _student_classes.get(name)
        if cls is None:
            cls = type(f"Student{name}", (StudentCodeError, builtin), {"__module__": __name__})
            _student_classes[name] = cls
        return cls
    return StudentCodeError
