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

What is replaced, for each dotted name ``robolab.bag.PoseTrack.at``:

- the attribute itself (the module's function, the class's method), so
  ``import robolab.bag as b; b.PoseTrack.at(...)`` and bound methods made
  during the call fail;
- every reference to it in the submission's namespace: ``from robolab.geometry
  import transform_points`` binds the function under the student's own name
  (``as tp`` too), and so does a bound method stored at module level.

Library code that imported the function under its own name (``from
robolab.geometry import transform_points`` inside :mod:`robolab.bag`) keeps its
reference: the table lists every public entry point that computes the
exercise's answer, so a student cannot reach it through another door.
"""

from __future__ import annotations

import contextlib
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


def _refusal(dotted: str, exercise: str):
    def refuse(*args, **kwargs):
        raise DelegationError(
            f"this exercise asks you to write {exercise} yourself; {dotted} is not "
            f"available while {exercise} is graded"
        )

    refuse.__name__ = refuse.__qualname__ = dotted.rsplit(".", 1)[-1]
    return refuse


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

    ``namespace`` is the submission's module namespace; names in it bound to a
    forbidden function are replaced too. A forbidden name in a module nobody
    has imported yet is not imported: importing that module fails during the
    block instead. Everything is restored on exit, even when the block raises.
    A dotted name that does not resolve (the library has moved on) is skipped:
    ``tests/grading/loading/test_delegation.py`` keeps the table true.
    """
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
            raw = original.fget if isinstance(original, property) else original
            refuse = _refusal(dotted, exercise)
            replacement = property(refuse) if isinstance(original, property) else refuse
            undo.append((owner, attr, original))
            setattr(owner, attr, replacement)
            for key, value in list(namespace.items()):
                if _same(value, raw) or _same(value, original):
                    undo.append((namespace, key, value))
                    namespace[key] = refuse
        if unloaded:
            blocker = _BlockImports(unloaded, exercise)
            sys.meta_path.insert(0, blocker)
        yield
    finally:
        if blocker is not None:
            sys.meta_path.remove(blocker)
        for owner, attr, original in reversed(undo):
            if owner is namespace:
                namespace[attr] = original
            else:
                setattr(owner, attr, original)
