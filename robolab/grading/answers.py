"""A mistake costs once: while an exercise is graded, the exercises below it answer as the reference.

An exercise that builds on others (a mixture of densities, a filter step over a
motion and a measurement model, a full run over a step) is graded on its own
logic, whatever the student's other functions do. While a hidden test grading
exercise ``E`` runs (the pytest plugin tells the proxy which exercise that is):

- in the worker, every name of the submission's namespace bound to an exercise
  *below* ``E`` (or not bound at all) is replaced by a stub (:func:`answered`);
  a call of the stub -- from ``E``, or from a helper of the student's -- sends
  ``("depcall", call_id, name, args, kwargs, rngs)`` to the grader and waits;
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

import contextlib
import importlib
from collections.abc import Callable, Iterable, Iterator, Mapping
from pathlib import Path
from types import ModuleType
from typing import Any

__all__ = ["Answers", "DependencyCycle", "answered", "dependency_table"]

#: The bit generators whose state crosses the wire (numpy's own, plain-data states).
BIT_GENERATORS = ("PCG64", "PCG64DXSM", "Philox", "SFC64", "MT19937")


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
    from robolab.grading.solve import SolutionSource

    names = list(dict.fromkeys(exercises))
    source = SolutionSource.read(solution)
    direct: dict[str, set[str]] = {}
    for name in names:
        reach = set(source.dependencies([name], exclude=set())) | set(source.uses.get(name, ()))
        direct[name] = {n for n in reach if n in names and n != name}
        direct[name] |= {n for n in (declared or {}).get(name, ()) if n in names}
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
    insulated : bool
        Whether the exercises below it answer as the reference. The pytest plugin
        sets it only while one of them fails (or has not yet passed) its own tests:
        otherwise the student's own versions are as good as the grader can tell,
        and a correct notebook is graded without a single call-back.
    """

    def __init__(self, reference: ModuleType, below: Mapping[str, frozenset[str]]) -> None:
        self.reference = reference
        self.below = dict(below)
        self.exercise: str | None = None
        self.insulated = True

    @classmethod
    def for_lab(cls, lab: str, declared: Mapping[str, Iterable[str]] | None = None) -> Answers:
        """The answers of lab ``lab``: its reference module and its dependency table."""
        from robolab.grading.labs import find_lab
        from robolab.grading.notebook import lab_exercises

        found = find_lab(lab)
        below = dependency_table(found.solution, lab_exercises(lab), declared)
        return cls(importlib.import_module(f"solutions.{lab}"), below)

    def stubbed(self, name: str) -> tuple[str, ...]:
        """The names a call of ``name`` gets answered by the grader while the exercise is graded."""
        if self.exercise is None or not self.insulated:
            return ()
        return tuple(sorted(self.below.get(self.exercise, frozenset()) - {name}))

    def direct(self, name: str) -> Callable | None:
        """The reference function answering a test's own call of ``name``, or None."""
        if (
            self.exercise is None
            or not self.insulated
            or name not in self.below.get(self.exercise, ())
        ):
            return None
        return getattr(self.reference, name, None)

    def answer(self, name: str, args: Any, kwargs: Any, rngs: Any) -> tuple:
        """The reply to one stub call: ``("answer", value, observation, rng states)``,
        ``("raise", {"bases", "message"})`` or ``("own", reason)``.

        ``args``, ``kwargs`` and ``rngs`` were decoded by the codec (plain data);
        ``name`` was checked against :meth:`stubbed` by the caller.
        """
        from robolab.grading import observe

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
        if kind not in BIT_GENERATORS:
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


# --- the worker's side ------------------------------------------------------------------------


@contextlib.contextmanager
def answered(
    names: Iterable[str], namespace: dict, ask: Callable[[tuple], tuple]
) -> Iterator[None]:
    """While the block runs, the submission's ``names`` are answered by the grader.

    Each name bound to a function in ``namespace`` (and every other name bound to
    that same function), or not bound at all, is replaced by a stub that sends
    ``("depcall", name, args, kwargs, rngs)`` through ``ask`` and returns or
    raises what the grader replies. A name bound to something that is not
    callable (a constant that happens to share an exercise's name) is left
    alone. Everything is restored on exit, unless the student rebound it meanwhile.
    """
    undo: list[tuple[str, Any, Any]] = []
    try:
        for name in names:
            own = namespace.get(name, _UNBOUND)
            if own is not _UNBOUND and not callable(own):
                continue
            stub = _stub(name, own, ask)
            for key, value in list(namespace.items()) if own is not _UNBOUND else ():
                if value is own and key != name:
                    undo.append((key, value, stub))
                    namespace[key] = stub
            undo.append((name, own, stub))
            namespace[name] = stub
        yield
    finally:
        for key, value, stub in reversed(undo):
            if namespace.get(key) is not stub:
                continue  # the student rebound it during the call: keep theirs
            if value is _UNBOUND:
                del namespace[key]
            else:
                namespace[key] = value


_UNBOUND = object()


def _stub(name: str, own: Any, ask: Callable[[tuple], tuple]) -> Callable:
    import builtins

    import numpy as np

    def call(*args: Any, **kwargs: Any) -> Any:
        from robolab.grading import observe

        rngs, plain_args, plain_kwargs = {}, list(args), dict(kwargs)
        for key, value in [*enumerate(args), *kwargs.items()]:
            if isinstance(value, np.random.Generator):
                rngs[key] = value.bit_generator.state
                if isinstance(key, int):
                    plain_args[key] = None
                else:
                    plain_kwargs[key] = None
        reply = ask(("depcall", name, tuple(plain_args), plain_kwargs, rngs))
        if reply[0] == "answer":
            _, value, observation, states = reply
            for key, state in states.items():
                (args[key] if isinstance(key, int) else kwargs[key]).bit_generator.state = state
            return observe.replay(value, observation, args, kwargs)
        if reply[0] == "raise":
            info = reply[1]
            kind = next(
                (
                    getattr(builtins, b)
                    for b in info["bases"]
                    if isinstance(getattr(builtins, b, None), type)
                    and issubclass(getattr(builtins, b), Exception)
                ),
                Exception,
            )
            raise kind(info["message"])
        if own is _UNBOUND:  # as in Jupyter: the notebook does not define it
            raise NameError(f"name {name!r} is not defined")
        return own(*args, **kwargs)

    call.__name__ = call.__qualname__ = name
    return call
