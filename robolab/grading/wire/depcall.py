"""The worker's side of a depcall: exercises below the graded one, answered by the grader.

While the grader grades exercise ``E``, it names the exercises below ``E`` with the
call (:mod:`robolab.grading.running.answers`). :func:`answered` replaces them in the
submission's namespace by stubs; a stub sends ``("depcall", name, args, kwargs,
rngs)`` through the worker's channel -- every top-level ``numpy.random.Generator``
argument replaced by None, its bit generator's state in ``rngs`` -- and returns or
raises what the grader replies:

- ``("answer", value, observation, rng_states)``: the reference's value; the
  observation (:mod:`robolab.grading.wire.observe`) of what it changed in its
  arguments is replayed on the student's arrays, and each generator is set to the
  state the reference left it in, so it moves as if the call had drawn here;
- ``("raise", {"bases", "message"})``: the reference refused the arguments; the
  stub raises the nearest builtin exception with the same message;
- ``("own", reason)``: the arguments are not plain data; the student's own
  function runs (a name the notebook does not define raises NameError, as in Jupyter).
"""

from __future__ import annotations

import builtins
import contextlib
from collections.abc import Callable, Iterable, Iterator
from typing import Any

__all__ = ["BIT_GENERATORS", "answered"]

#: The bit generators whose state crosses the wire (numpy's own, plain-data states).
BIT_GENERATORS = ("PCG64", "PCG64DXSM", "Philox", "SFC64", "MT19937")


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
    import numpy as np  # the worker imports it only after its sandbox is applied

    from robolab.grading.wire import observe

    def call(*args: Any, **kwargs: Any) -> Any:
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
