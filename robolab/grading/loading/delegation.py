"""No exercise can be passed by calling the library's own version of it.

The student edition ships all of :mod:`robolab`, because the labs use it: lab 00
reads bags with :class:`robolab.bag.BagReader`, lab 04 places endpoints with
:func:`robolab.geometry.transform_points`. Some of those library functions *are*
an exercise of another (or the same) lab: ``PoseTrack.at`` is lab 00's
``pose_at``. While such an exercise is graded (the worker's ``serve`` runs
each call inside :func:`forbidden`), the worker replaces the
library's equivalents with a function that raises :class:`DelegationError`
(a ``NotImplementedError``, so no refusal test counts it as a refusal), and
puts them back afterwards: during every other call they work as usual.

:data:`FORBIDDEN` is the table, per lab and exercise, of the dotted names
replaced. It is keyed by lab for the documentation (``docs/grading.md``); the
worker does not know which lab it grades, so :func:`forbidden_for` takes the
union over labs of an exercise name (a name shared by two labs, such as
``low_variance_resample``, is the same exercise in both).

What is guarded is the *function object* each dotted name resolves to, not the
name: its ``__code__`` is swapped for code that raises, and put back afterwards.
Every way of reaching that object therefore refuses, however it was taken:

- the module attribute and any other module that holds it
  (``robolab.sim.clearance_field`` is ``robolab.sim.run.clearance_field``;
  ``filterpy.monte_carlo.systematic_resample`` is
  ``filterpy.monte_carlo.resampling.systematic_resample``), a module alias
  (``import filterpy.monte_carlo.resampling as _mc``);
- every name in the submission bound to it (``from robolab.geometry import
  transform_points as tp``), copies taken at import time (a list, a dict, a
  ``functools.partial``, a default argument), bound methods (made before or
  during the call) and, for a property, its getter.

Library code that calls the function refuses too while the exercise is graded:
the table lists functions that compute the exercise's answer, so a library
path that reaches one is the same delegation. What no guard can tell from the
student's own work is a *re-creation* of the function (its source copied or
``exec``-ed, ``types.FunctionType`` on its code): the hidden tests grade what
such a copy computes. An entry that is not a Python function (a C function) is
replaced by name, in its owner and the submission's namespace, as a fallback.
"""

from __future__ import annotations

import contextlib
import functools
import importlib
import sys
import types
from collections.abc import Iterator

__all__ = ["FORBIDDEN", "DelegationError", "forbidden", "forbidden_for", "resolve"]

#: ``{lab: {exercise: [dotted names the exercise may not call while it is graded]}}``.
FORBIDDEN: dict[str, dict[str, list[str]]] = {
    "frames": {
        "scan_to_cartesian": ["robolab.bag.Scans.endpoints", "robolab.bag.Scans.valid"],
        "transform_points": [
            "robolab.geometry.transform_points",
            "robolab.geometry.compose",
            "robolab.bag.Scans.endpoints",
        ],
        "pose_at": ["robolab.bag.PoseTrack.at", "robolab.bag.TfTree.lookup"],
    },
    "bayes": {},
    "beam_model": {},
    "landmark_pf": {
        "move_particles": ["robolab.world.cRobot.move"],
        "measurement_probability": ["robolab.world.cRobot.measurement_probability"],
        "low_variance_resample": [
            "filterpy.monte_carlo.systematic_resample",
            "filterpy.monte_carlo.stratified_resample",
        ],
    },
    "odometry_mapping": {
        "scan_endpoints": ["robolab.bag.Scans.endpoints"],
    },
    "mcl": {
        "likelihood_field": ["robolab.sim.clearance_field"],
        "low_variance_resample": [
            "filterpy.monte_carlo.systematic_resample",
            "filterpy.monte_carlo.stratified_resample",
        ],
    },
    "ekf_mapping": {
        "transition_model": ["robolab.fiducials.unicycle"],
    },
    "fastslam": {
        "predict_poses": ["robolab.fiducials.unicycle"],
        "h": ["robolab.fiducials._range_bearing"],
    },
    "ekf_slam": {
        "predict": ["robolab.fiducials.unicycle"],
        "observation": ["robolab.fiducials._range_bearing"],
    },
    "graph_slam": {
        # graph_objective stays allowed: it returns only the scalar F, which no exercise
        # returns alone (optimize_graph may record it in its history)
        "pose_pose_error": [
            "robolab.geometry.relative",
            "robolab.geometry.inverse",
            "robolab.geometry.compose",
            "robolab.evaluation._pose_pose_errors",
        ],
        "pose_landmark_error": [
            "robolab.geometry.transform_points",
            "robolab.evaluation._pose_landmark_errors",
        ],
    },
    "demo": {
        "wrap": ["robolab.geometry.wrap_angle", "robolab.geometry.angle_diff"],
        "mean_pose": ["robolab.bag.PoseTrack.at", "robolab.plotting.mcl.estimate_pose"],
    },
}


class DelegationError(NotImplementedError):
    """The exercise called the library's own version of itself."""


def forbidden_for(exercise: str) -> list[str]:
    """The dotted names replaced while ``exercise`` is graded (union over labs, in order)."""
    names: list[str] = []
    for table in FORBIDDEN.values():
        names += [n for n in table.get(exercise, []) if n not in names]
    return names


def resolve(dotted: str, *, loaded_only: bool = False) -> tuple[object, str, object]:
    """``(owner, attribute, value)`` for ``package.module.Class.attr``.

    The longest importable module prefix is imported (with ``loaded_only``, the
    longest prefix already in ``sys.modules``: nothing is imported); the rest is
    looked up as attributes. Raises ImportError or AttributeError when the name
    does not resolve.
    """
    parts = dotted.split(".")
    for cut in range(len(parts) - 1, 0, -1):
        module_name = ".".join(parts[:cut])
        if loaded_only and module_name not in sys.modules:
            continue
        try:
            owner: object = importlib.import_module(module_name)
        except ImportError:
            continue
        for part in parts[cut:-1]:
            owner = getattr(owner, part)
        # The raw attribute (a plain function for a method), not the bound descriptor.
        if isinstance(owner, type):
            value = owner.__dict__[parts[-1]]
        else:
            value = getattr(owner, parts[-1])
        return owner, parts[-1], value
    raise ImportError(f"cannot import any module of {dotted!r}")


def _first_unloaded(dotted: str) -> str | None:
    """The shortest prefix of ``dotted`` that is not imported yet (None: all are)."""
    parts = dotted.split(".")
    for cut in range(1, len(parts)):
        name = ".".join(parts[:cut])
        if name not in sys.modules:
            return name
    return None


class _BlockImports:
    """Meta-path finder refusing, during one call, the modules that hold forbidden names.

    Used for a module nobody has imported yet (``filterpy.monte_carlo``): importing
    it only to patch it would cost every worker its import time.
    """

    def __init__(self, modules: dict[str, str], exercise: str) -> None:
        self.modules, self.exercise = modules, exercise

    def find_spec(self, fullname: str, path: object = None, target: object = None) -> None:
        for module, dotted in self.modules.items():
            if fullname == module or fullname.startswith(module + "."):
                raise DelegationError(
                    f"this exercise asks you to write {self.exercise} yourself; {dotted} "
                    f"(module {fullname}) is not available while {self.exercise} is graded"
                )
        return None


def _message(dotted: str, exercise: str) -> str:
    return (
        f"this exercise asks you to write {exercise} yourself; {dotted} is not "
        f"available while {exercise} is graded"
    )


def _refusal(dotted: str, exercise: str):
    def refuse(*args, **kwargs):
        raise DelegationError(_message(dotted, exercise))

    refuse.__name__ = refuse.__qualname__ = dotted.rsplit(".", 1)[-1]
    return refuse


@functools.lru_cache(maxsize=256)
def _refusing_code(message: str, free: int, name: str) -> types.CodeType:
    """Code that raises DelegationError(message), with ``free`` free variables (a closure's
    code can only be swapped for code with as many) and the function's ``name``."""
    cells = [f"_cell{i}" for i in range(free)]
    # The error class is looked up when the code runs, in the *library's* globals: through
    # the import system, not a global name the library module does not have.
    raise_it = (
        "raise __import__('robolab.grading.loading.delegation', None, None, ['DelegationError'])"
        f".DelegationError({message!r})"
    )
    if cells:
        body = f"    if False:\n        {', '.join(cells)}\n    {raise_it}"
        source = f"def outer():\n  {' = '.join(cells)} = None\n  def refuse(*args, **kwargs):\n"
        source += "\n".join("  " + line for line in body.splitlines()) + "\n  return refuse\n"
    else:
        source = f"def refuse(*args, **kwargs):\n    {raise_it}\n"
    scope: dict = {}
    exec(compile(source, "<robolab delegation guard>", "exec"), scope)  # noqa: S102 - our text
    refuse = scope["outer"]() if cells else scope["refuse"]
    return refuse.__code__.replace(co_name=name, co_qualname=name)


def _functions(value: object) -> list[types.FunctionType]:
    """The Python functions behind a table entry (a property's accessors, a wrapper's target)."""
    if isinstance(value, property):
        found = [value.fget, value.fset, value.fdel]
    elif isinstance(value, (staticmethod, classmethod)):
        found = [value.__func__]
    else:
        found = [value, getattr(value, "__wrapped__", None)]
    return [f for f in found if type(f) is types.FunctionType]


def _same(candidate: object, original: object) -> bool:
    if candidate is original:
        return True
    try:  # a bound method stored at module level: Scans(...).endpoints
        return type(candidate) is types.MethodType and candidate.__func__ is original
    except Exception:  # noqa: BLE001 - a student's object may raise on attribute access
        return False


@contextlib.contextmanager
def forbidden(exercise: str, namespace: dict) -> Iterator[None]:
    """While the block runs, the library's equivalents of ``exercise`` raise DelegationError.

    Each function of the table is disabled in place (its code swapped), so every
    alias, copy and bound method of it refuses (see the module docstring);
    ``namespace`` (the submission's module namespace) only matters for an entry
    that is not a Python function. A forbidden name in a module nobody has
    imported yet is not imported: importing that module fails during the block
    instead. Everything is restored on exit, even when the block raises. A
    dotted name that does not resolve (the library has moved on) is skipped:
    ``tests/grading/loading/test_delegation.py`` keeps the table true.
    """
    swapped: dict[int, tuple[types.FunctionType, types.CodeType]] = {}
    undo: list[tuple[object, str, object]] = []
    names = forbidden_for(exercise) if isinstance(exercise, str) else []
    blocker = None
    try:
        unloaded: dict[str, str] = {}
        for dotted in names:
            try:
                owner, attr, original = resolve(dotted, loaded_only=True)
            except (ImportError, AttributeError, KeyError):
                module = _first_unloaded(dotted)
                if module is not None:
                    unloaded.setdefault(module, dotted)
                continue
            functions = _functions(original)
            for function in functions:
                if id(function) not in swapped:
                    code = function.__code__
                    swapped[id(function)] = (function, code)
                    function.__code__ = _refusing_code(
                        _message(dotted, exercise), len(code.co_freevars), code.co_name
                    )
            if functions:
                continue
            # Not a Python function: replace it by name, where it is and in the submission.
            refuse = _refusal(dotted, exercise)
            undo.append((owner, attr, original))
            setattr(owner, attr, refuse)
            for key, value in list(namespace.items()):
                if _same(value, original):
                    undo.append((namespace, key, value))
                    namespace[key] = refuse
        if unloaded:
            blocker = _BlockImports(unloaded, exercise)
            sys.meta_path.insert(0, blocker)
        yield
    finally:
        if blocker is not None:
            sys.meta_path.remove(blocker)
        for function, code in swapped.values():
            function.__code__ = code
        for owner, attr, original in reversed(undo):
            if owner is namespace:
                namespace[attr] = original
            else:
                setattr(owner, attr, original)
