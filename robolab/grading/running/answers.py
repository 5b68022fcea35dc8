"""A mistake costs once: while an exercise is graded, the ones below it answer as the reference.

An exercise that builds on others (a mixture of densities, a filter step over a
motion and a measurement model, a full run over a step) is graded on its own
logic, whatever the student's other functions do. While a hidden test grading
exercise ``E`` runs (the pytest plugin tells the proxy which exercise that is):

- in the worker, every name of the submission's namespace bound to an exercise
  *below* ``E`` (or not bound at all) is replaced by a stub
  (:func:`robolab.grading.wire.depcall.answered`);
  a call of the stub -- from ``E``, or from a helper of the student's -- sends
  ``("depcall", call_id, name, args, kwargs, rngs)`` to the grader and waits
  (:mod:`robolab.grading.wire.depcall`);
- the grader (:meth:`Answers.answer`) decodes the arguments with the codec
  (plain data only, bounded), runs the *reference* function on them, and sends
  back its value, what it changed in its arguments (:mod:`robolab.grading.observe`)
  and the new state of every ``numpy.random.Generator`` argument, so the
  student's generator moves exactly as if the call had drawn in the worker;
  a reference that raises (the student passed bad input) makes the stub raise
  the same builtin exception, with the same message;
- a test's own call of an exercise below ``E`` is answered by the reference in
  the grader directly (:meth:`Answers.direct`).

*Below* is :func:`dependency_table`: the exercises that the reference solution of
``E`` refers to, through its helpers, plus those the hidden tests declare ``E``
uses (``USES``), closed transitively; the table must be acyclic, so no exercise
ever gets the reference of itself or of an exercise built on it. The reference
code and the hidden tests never enter the worker: only results for the
student's own inputs do. Arguments that are not plain data (a student's own
class, a generator nested in a container) cannot cross: the stub then runs the
student's own function, as without this module.
"""

from __future__ import annotations

import ast
import importlib
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from types import ModuleType
from typing import Any

from robolab.grading.wire import depcall

__all__ = ["Answers", "DependencyCycle", "dependency_table"]


class DependencyCycle(ValueError):
    """Two exercises are each below the other: one would be graded with its own reference."""


# --- which exercises are below which ------------------------------------------------------------


def dependency_table(
    solution: Path, exercises: Iterable[str], declared: Mapping[str, Iterable[str]] | None = None
) -> dict[str, frozenset[str]]:
    """For each exercise, the lab's exercises below it.

    Parameters
    ----------
    solution : Path
        The lab's reference solution module.
    exercises : iterable of str
        The lab's exercise function names.
    declared : mapping, optional
        Further exercises each one builds on (a hidden test module's ``USES``):
        pieces a student naturally calls though the reference inlines them.

    Returns
    -------
    dict
        ``{exercise: frozenset of exercises below it}``: those its reference
        refers to, directly or through module-level helpers, and the declared
        ones, closed transitively.

    Raises
    ------
    DependencyCycle
        When an exercise would be below itself.
    """
    names = list(dict.fromkeys(exercises))
    uses = _module_references(solution)
    direct: dict[str, set[str]] = {}
    for name in names:
        reach, todo = set(), list(uses.get(name, ()))
        while todo:  # through module-level helpers and constants, not through other exercises
            used = todo.pop()
            if used in reach or used == name:
                continue
            reach.add(used)
            if used not in names:
                todo += uses.get(used, ())
        direct[name] = {n for n in reach if n in names}
        direct[name] |= {n for n in (declared or {}).get(name, ()) if n in names and n != name}
    table = {}
    for name in names:
        seen: set[str] = set()
        todo = list(direct[name])
        while todo:
            below = todo.pop()
            if below not in seen:
                seen.add(below)
                todo += direct.get(below, ())
        if name in seen:
            raise DependencyCycle(
                f"{name} is below itself ({sorted(direct[name])} lead back to it): "
                "it would be graded against its own reference"
            )
        table[name] = frozenset(seen)
    return table


def _module_references(path: Path) -> dict[str, set[str]]:
    """For each module-level name a module defines (or imports), the names its code reads."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    found: dict[str, set[str]] = {}
    for node in tree.body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            bound = [node.name]
        elif isinstance(node, (ast.Assign, ast.AnnAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            bound = [t.id for t in targets if isinstance(t, ast.Name)]
        elif isinstance(node, (ast.Import, ast.ImportFrom)):
            bound = [(a.asname or a.name).split(".")[0] for a in node.names]
        else:
            continue
        read = {n.id for n in ast.walk(node) if isinstance(n, ast.Name)}
        for name in bound:
            found.setdefault(name, set()).update(read)
    return found


# --- the grader's side ------------------------------------------------------------------------


class Answers:
    """The grader's side: which names the worker answers by call-back, and the answers.

    Parameters
    ----------
    reference : module
        The lab's reference solution (``solutions.<lab>``), in the grader only.
    below : mapping
        :func:`dependency_table` of the lab.

    Attributes
    ----------
    exercise : str or None
        The exercise the running hidden test grades (set by the pytest plugin);
        None answers nothing: every call runs the student's code only.
    suspects : frozenset of str or None
        Which of the exercises below it answer as the reference; None: all of them.
        The pytest plugin names those that fail (or have not yet passed) their own
        tests: the others are as good as the grader can tell, so they run as the
        student wrote them, and a correct notebook is graded without a call-back.
    """

    def __init__(self, reference: ModuleType, below: Mapping[str, frozenset[str]]) -> None:
        self.reference = reference
        self.below = dict(below)
        self.exercise: str | None = None
        self.suspects: frozenset[str] | None = None

    @classmethod
    def for_lab(cls, lab: str, declared: Mapping[str, Iterable[str]] | None = None) -> Answers:
        """The answers of lab ``lab``: its reference module and its dependency table."""
        from robolab.grading.labs import find_lab
        from robolab.grading.loading.notebook import lab_exercises

        found = find_lab(lab)
        below = dependency_table(found.solution, lab_exercises(lab), declared)
        return cls(importlib.import_module(f"solutions.{lab}"), below)

    def stubbed(self, name: str) -> tuple[str, ...]:
        """The names a call of ``name`` gets answered by the grader while the exercise is graded."""
        return tuple(sorted(self._answered() - {name}))

    def direct(self, name: str) -> Callable | None:
        """The reference function answering a test's own call of ``name``, or None."""
        return getattr(self.reference, name, None) if name in self._answered() else None

    def _answered(self) -> frozenset[str]:
        if self.exercise is None:
            return frozenset()
        below = self.below.get(self.exercise, frozenset())
        return below if self.suspects is None else below & self.suspects

    def answer(self, name: str, args: Any, kwargs: Any, rngs: Any) -> tuple:
        """The reply to one stub call: ``("answer", value, observation, rng states)``,
        ``("raise", {"bases", "message"})`` or ``("own", reason)``.

        ``args``, ``kwargs`` and ``rngs`` were decoded by the codec (plain data);
        ``name`` was checked against :meth:`stubbed` by the caller.
        """
        from robolab.grading.wire import observe

        function = getattr(self.reference, name, None)
        if function is None or not isinstance(args, tuple) or not isinstance(kwargs, dict):
            return ("own", "no reference")
        try:
            args, kwargs, generators = _with_generators(args, kwargs, rngs)
        except (TypeError, ValueError, KeyError) as exc:
            return ("own", f"a random generator could not be rebuilt: {exc}")
        watch = observe.Watch(args, kwargs)
        try:
            value = function(*args, **kwargs)
        except Exception as exc:  # noqa: BLE001 - the student's input, refused by the reference
            bases = [c.__name__ for c in type(exc).__mro__]
            return ("raise", {"bases": bases, "message": str(exc)})
        states = {key: gen.bit_generator.state for key, gen in generators.items()}
        return ("answer", value, watch.report(value), states)


def _with_generators(args: tuple, kwargs: dict, rngs: Any) -> tuple[tuple, dict, dict]:
    """``args`` and ``kwargs`` with each Generator rebuilt at its position from its state."""
    import numpy as np

    if not isinstance(rngs, dict):
        raise TypeError("rngs must be a dict")
    args, kwargs, generators = list(args), dict(kwargs), {}
    for key, state in rngs.items():
        kind = state.get("bit_generator") if isinstance(state, dict) else None
        if kind not in depcall.BIT_GENERATORS:
            raise ValueError(f"unknown bit generator {kind!r}")
        bits = getattr(np.random, kind)()
        bits.state = state
        generators[key] = np.random.Generator(bits)
        if isinstance(key, int) and 0 <= key < len(args):
            args[key] = generators[key]
        elif isinstance(key, str):
            kwargs[key] = generators[key]
        else:
            raise KeyError(f"no argument {key!r}")
    return tuple(args), kwargs, generators
