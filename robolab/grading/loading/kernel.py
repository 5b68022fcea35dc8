"""Run a notebook's needed cells the way a Jupyter kernel would, without a kernel.

:func:`run_cells` executes each cell's Python (already transformed by
:func:`robolab.grading.loading.notebook.to_python`) whole, in order, in one namespace:
a cell that raises stops there, as in Jupyter, and the next cell still runs.
Like IPython's ``run_ast_nodes``, each top-level statement is compiled on
its own, with the ``from __future__`` flags of the statements before it (in
this cell and earlier ones), so a future import need not open its cell.
Each cell gets a load time limit, enforced with ``SIGALRM`` by raising
:class:`LoadTimeout`, a ``BaseException`` that a student's ``except Exception``
does not swallow (the grader's own wall limit stays the hard one).

Transformed cells call ``get_ipython()``: :class:`Shell` answers the calls a
kernel would, for grading. ``%time STATEMENT`` runs the statement in the
namespace (its bindings persist, as in IPython); ``%timeit STATEMENT`` runs it
once in a throwaway local scope (IPython's timing function keeps nothing
either); ``%%writefile`` and ``%run`` work inside the notebook's working folder
(:mod:`robolab.grading.loading.magics`); ``%store -r`` restores nothing (a fresh
kernel has nothing stored); every other line magic (``%matplotlib``,
``%load_ext``, ``%pip``), ``!cmd`` and cell magic does nothing, and
``x = !cmd`` gives an empty list.

:class:`Notebook` is the module the cells run in, as a kernel holds it: named
``__main__`` and registered as ``sys.modules["__main__"]``, with its working
folder as the current directory and first on ``sys.path``. The grading worker
(isolated, its scratch folder) and ``robolab check`` (the student's own
process, a temporary folder) both load a notebook through it, identically.
"""

from __future__ import annotations
import __future__

import ast
import builtins
import functools
import importlib
import linecache
import operator
import os
import signal
import sys
import time
import traceback
import types
from collections.abc import Callable

from robolab.grading.loading import magics

__all__ = ["LoadTimeout", "Notebook", "Shell", "load_budget", "new_namespace", "run_cells"]

#: The name a notebook's module has in a kernel (and in ``sys.modules``).
MAIN = "__main__"

#: Cell magics that write their body to a file (``%%file`` is IPython's alias).
WRITE_MAGICS = frozenset({"writefile", "file"})

_FUTURE_FLAGS = functools.reduce(
    operator.or_, (getattr(__future__, f).compiler_flag for f in __future__.all_feature_names)
)


def load_budget(wall_seconds: float, cpu_seconds: float) -> tuple[float, float]:
    """Wall and CPU seconds the needed cells may take together, under a worker's request limits.

    A little less than the limits (a fifth, at most one second), so the cell
    that uses them up is stopped and named before the grader's own hard limit
    ends the whole load.
    """
    return (
        wall_seconds - min(1.0, wall_seconds / 5),
        cpu_seconds - min(1.0, cpu_seconds / 5),
    )


class LoadTimeout(BaseException):
    """A cell ran past the load budget (not an Exception: ``except Exception`` passes it)."""


class Shell:
    """What ``get_ipython()`` returns to a cell run for grading (see the module docstring).

    ``folder`` is the notebook's working folder (None: the current directory),
    the only one its file magics read or write.
    """

    def __init__(self, namespace: dict, folder: str | None = None) -> None:
        self.user_ns = namespace
        self.folder = folder

    def run_line_magic(self, magic_name: str, line: str, _stack_depth: int = 1) -> object:
        if magic_name == "time":
            return self._run(line, self.user_ns)
        if magic_name == "timeit":
            self._run(line, {})  # once, its names local to the timing run
        if magic_name == "run":
            magics.run_file(self._folder(), line, self.user_ns, self._run_ipython)
        return None

    def run_cell_magic(self, magic_name: str, line: str, cell: str) -> None:
        # Python-running cell magics were unwrapped when the notebook was read.
        if magic_name in WRITE_MAGICS:
            magics.write_file(self._folder(), line, cell)
            importlib.invalidate_caches()  # an `import` right after finds the new module
        return None

    def system(self, cmd: str) -> None:
        return None

    def getoutput(self, cmd: str, split: bool = True, depth: int = 0) -> list:
        return []

    def _folder(self) -> str:
        return self.folder if self.folder is not None else os.getcwd()

    def _run(self, statement: str, local: dict) -> object:
        try:
            code = compile(statement, "<magic>", "eval")
        except SyntaxError:
            exec(compile(statement, "<magic>", "exec"), self.user_ns, local)  # noqa: S102
            return None
        return eval(code, self.user_ns, local)  # noqa: S307 - the student's own statement

    def _run_ipython(self, sources: list[str], filename: str) -> None:
        """A ``.ipy`` file or a notebook run by ``%run``: its cells, in the notebook's namespace."""
        from robolab.grading.loading.notebook import to_python

        for source in sources:
            python = to_python(source)
            if python is not None:
                exec(compile(python, filename, "exec", dont_inherit=True), self.user_ns)  # noqa: S102


def _display(*objects: object, **options: object) -> None:
    """``display()`` of a kernel: rich output goes nowhere when grading."""
    return None


def new_namespace(
    module_name: str, namespace: dict | None = None, folder: str | None = None
) -> dict:
    """A module namespace whose builtins include ``get_ipython`` and ``display``, as in a kernel.

    They live in the namespace's own ``__builtins__``, so they are no
    definitions of the notebook. ``folder`` is its working folder (see :class:`Shell`).
    """
    namespace = {} if namespace is None else namespace
    namespace.setdefault("__name__", module_name)
    shell = Shell(namespace, folder)
    namespace["__builtins__"] = dict(vars(builtins), get_ipython=lambda: shell, display=_display)
    return namespace


class Notebook:
    """The module a notebook runs in, as a Jupyter kernel holds it, with ``folder`` as its folder.

    While entered, the module is ``sys.modules["__main__"]`` (``__name__ ==
    "__main__"``; ``sys.modules[__name__]`` and ``import __main__`` are the
    notebook; pickle finds its classes), ``folder`` is the current directory and
    the first entry of ``sys.path`` (the notebook's folder in Jupyter: a module
    written there with ``%%writefile`` imports). :meth:`exit` puts back what it
    changed and forgets the modules imported from ``folder``; the grading
    worker never exits (it is the notebook's process).

    Parameters
    ----------
    folder : str
        An existing folder the notebook may write in: the worker's scratch
        folder, or a temporary folder for ``robolab check``.
    """

    def __init__(self, folder: str | os.PathLike) -> None:
        self.folder = os.path.realpath(folder)
        if not os.path.isdir(self.folder):
            raise NotADirectoryError(f"folder must be an existing folder, got {folder!s}")
        self.module = types.ModuleType(MAIN)
        self.namespace = new_namespace(MAIN, self.module.__dict__, self.folder)
        self._saved: tuple | None = None

    def enter(self) -> Notebook:
        self._saved = (sys.modules.get(MAIN), os.getcwd(), set(sys.modules))
        sys.modules[MAIN] = self.module
        os.chdir(self.folder)
        sys.path.insert(0, self.folder)
        return self

    def exit(self) -> None:
        if self._saved is None:
            return
        main, cwd, modules = self._saved
        self._saved = None
        if main is not None:
            sys.modules[MAIN] = main
        os.chdir(cwd)
        if self.folder in sys.path:
            sys.path.remove(self.folder)
        for name in set(sys.modules) - modules:  # the notebook's own modules, not the library's
            origin = getattr(sys.modules.get(name), "__file__", None) or ""
            if os.path.isabs(origin) and magics.inside(self.folder, origin) is not None:
                del sys.modules[name]

    def __enter__(self) -> Notebook:
        return self.enter()

    def __exit__(self, *exc: object) -> None:
        self.exit()

    def run(
        self,
        cells: list[tuple[int, str]],
        wall_seconds: float,
        cpu_seconds: float,
        on_done: Callable[[], None] | None = None,
        *,
        wall_timer: bool = True,
    ) -> list[tuple[int, str, str]]:
        """:func:`run_cells` in this notebook's namespace."""
        return run_cells(
            self.namespace, cells, wall_seconds, cpu_seconds, on_done, wall_timer=wall_timer
        )


def run_cells(
    namespace: dict,
    cells: list[tuple[int, str]],
    wall_seconds: float,
    cpu_seconds: float,
    on_done: Callable[[], None] | None = None,
    *,
    wall_timer: bool = True,
) -> list[tuple[int, str, str]]:
    """Run each cell whole, in order; return ``(cell_index, kind, message)`` of those that failed.

    ``kind`` is ``"syntax"``, ``"error"`` or ``"timeout"``. The cells share a
    budget of ``wall_seconds`` and ``cpu_seconds`` (see :func:`load_budget`):
    the cell that exhausts it is stopped, and the cells after it are not run.
    ``on_done`` runs after each cell (the worker flushes the student's output there).
    With ``wall_timer=False`` no wall-clock timer is armed: the caller sends ``SIGALRM``
    itself once ``wall_seconds`` are spent (the grader does, on a clock that leaves out
    the time the worker waited for a CPU, which this process cannot see).
    """
    problems = []
    flags = 0
    wall_end = time.monotonic() + wall_seconds
    cpu_end = time.process_time() + cpu_seconds
    stopped: int | None = None
    for cell_index, source in cells:
        if stopped is not None:
            problems.append(
                (cell_index, "timeout", f"not run: cell {stopped + 1} used up {_SPENT}")
            )
            continue
        filename = f"<cell {cell_index + 1}>"
        linecache.cache[filename] = (len(source), None, source.splitlines(True), filename)
        try:
            tree = compile(
                source, filename, "exec", flags=flags | ast.PyCF_ONLY_AST, dont_inherit=True
            )
        except (SyntaxError, ValueError) as exc:
            line = f" (line {exc.lineno})" if getattr(exc, "lineno", None) else ""
            problems.append((cell_index, "syntax", f"it does not run: {_msg(exc)}{line}"))
            continue
        try:
            with _time_limit(
                wall_end - time.monotonic() if wall_timer else None, cpu_end - time.process_time()
            ):
                # Statement by statement, as IPython's run_ast_nodes: a `from __future__`
                # import anywhere in a cell holds from there on, in later cells too.
                for node in tree.body:
                    code = compile(
                        ast.Module(body=[node], type_ignores=[]),
                        filename,
                        "exec",
                        flags=flags,
                        dont_inherit=True,
                    )
                    flags |= code.co_flags & _FUTURE_FLAGS
                    exec(code, namespace)  # noqa: S102 - running the student's cells is the point
        except LoadTimeout as exc:
            stopped = cell_index
            what = (
                f"{cpu_seconds:g} s of CPU time" if exc.args == ("cpu",) else f"{wall_seconds:g} s"
            )
            problems.append(
                (
                    cell_index,
                    "timeout",
                    f"it was stopped after running longer than {_SPENT} ({what}); it defines "
                    "a name your graded functions need, so move slow demos to a cell of their own",
                )
            )
        except BaseException as exc:  # noqa: BLE001 - SystemExit in a cell too
            line = _line_in(exc, filename)
            problems.append(
                (cell_index, "error", f"running it raised {type(exc).__name__}: {_msg(exc)}{line}")
            )
        finally:
            if on_done is not None:
                on_done()
    return problems


_SPENT = "the time allowed to load your notebook"


class _time_limit:
    """``LoadTimeout`` after ``wall`` seconds or ``cpu`` CPU seconds (again every 0.5 s after).

    ``wall=None``: no wall timer, but a ``SIGALRM`` sent by someone else still stops the cell.
    """

    _TIMERS = (
        (signal.ITIMER_REAL, signal.SIGALRM, "wall"),
        (signal.ITIMER_PROF, signal.SIGPROF, "cpu"),
    )

    def __init__(self, wall: float | None, cpu: float) -> None:
        self.limits = (0 if wall is None else max(wall, 0.01), max(cpu, 0.01))
        self.armed = False
        self.previous: list = []

    def _handler(self, which: str):
        def fire(signum: int, frame: object) -> None:
            if self.armed:
                raise LoadTimeout(which)

        return fire

    def __enter__(self) -> _time_limit:
        try:
            for _, signum, which in self._TIMERS:
                self.previous.append(signal.signal(signum, self._handler(which)))
        except ValueError:  # not the main thread: no limit but the grader's
            return self
        self.armed = True
        for (timer, _, _), seconds in zip(self._TIMERS, self.limits, strict=True):
            if seconds:
                signal.setitimer(timer, seconds, 0.5)
        return self

    def __exit__(self, *exc: object) -> None:
        if not self.armed:
            return
        self.armed = False
        for (timer, signum, _), previous in zip(self._TIMERS, self.previous, strict=True):
            signal.setitimer(timer, 0)
            signal.signal(signum, previous or signal.SIG_DFL)


def _msg(exc: BaseException) -> str:
    try:
        text = str(exc)
    except BaseException:  # noqa: BLE001 - a student's __str__ may raise anything
        text = "<no message>"
    if isinstance(exc, SyntaxError):
        text = exc.msg or text
    return text if len(text) <= 2000 else text[:2000] + " [...]"


def _line_in(exc: BaseException, filename: str) -> str:
    """`` (line N)`` of the deepest frame of the cell in the traceback."""
    line = None
    try:
        for frame in traceback.extract_tb(exc.__traceback__):
            if frame.filename == filename:
                line = frame.lineno
    except BaseException:  # noqa: BLE001
        return ""
    return f" (line {line})" if line else ""


def flush() -> None:
    """Flush stdout and stderr (between cells, so the grader sees output in order)."""
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except Exception:  # noqa: BLE001 - the student may have closed or replaced it
            pass
