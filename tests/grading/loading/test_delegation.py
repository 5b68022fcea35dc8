"""The delegation guard: while an exercise is graded, the library's version of it raises.

In-process tests of :func:`robolab.grading.loading.delegation.forbidden`, the table's
entries, and one run through the real worker (the hook in ``worker._call``).
Per lab, the mutation suite (``tests/labs/mutants``) grades delegating
submissions and requires them to lose the exercise's points.
"""

from __future__ import annotations

import numpy as np
import pytest

import robolab.geometry as geometry
from robolab.grading.loading import delegation
from robolab.grading.loading.delegation import FORBIDDEN, DelegationError, forbidden, resolve
from tests.grading import TEST_LIMITS, write_notebook

ENTRIES = sorted(
    {(lab, ex, name) for lab, t in FORBIDDEN.items() for ex, ns in t.items() for name in ns}
)


@pytest.mark.parametrize("entry", ENTRIES, ids=[f"{lab}.{ex}:{n}" for lab, ex, n in ENTRIES])
def test_every_table_entry_names_a_real_callable(entry):
    """Each dotted name of the table resolves to a function, method or property of the library."""
    _, _, dotted = entry
    owner, attr, value = resolve(dotted)
    assert callable(value) or isinstance(value, property), (
        f"{dotted} resolved to {value!r}, which is neither callable nor a property"
    )


def test_direct_calls_aliases_and_bound_methods_are_refused_then_restored():
    """Inside the guard the module attribute, an `as` alias and a bound method all raise."""
    from robolab.bag import PoseTrack

    original = geometry.transform_points
    track = PoseTrack(np.array([0.0, 1.0]), np.zeros((2, 3)))
    namespace = {"tp": original, "at": track.at, "other": geometry.wrap_angle}
    with forbidden("transform_points", namespace):
        with pytest.raises(DelegationError, match="write transform_points yourself"):
            geometry.transform_points(np.zeros((1, 2)), np.zeros(3))
        with pytest.raises(DelegationError):
            namespace["tp"](np.zeros((1, 2)), np.zeros(3))
        assert namespace["other"] is geometry.wrap_angle, "an allowed name must stay bound"
    assert geometry.transform_points is original, "the module attribute must be restored"
    assert namespace["tp"] is original, "the submission's alias must be restored"
    with forbidden("pose_at", namespace):
        with pytest.raises(DelegationError):
            namespace["at"](0.5)
        with pytest.raises(DelegationError):
            track.at(0.5)
    np.testing.assert_allclose(track.at(0.5), np.zeros(3), err_msg="PoseTrack.at after the guard")


def test_the_guard_restores_after_an_exception_and_ignores_other_exercises():
    """An exception inside the block still restores; an exercise without entries changes nothing."""
    original = geometry.transform_points
    with pytest.raises(RuntimeError), forbidden("transform_points", {}):
        raise RuntimeError("student code failed")
    assert geometry.transform_points is original, "restored after an exception"
    with forbidden("bayes_posterior", {}):
        assert geometry.transform_points is original, "an exercise without entries forbids nothing"


def test_a_module_not_imported_yet_cannot_be_imported_during_the_call(monkeypatch):
    """A forbidden name in an unloaded module: importing that module fails inside the guard."""
    import sys

    monkeypatch.setitem(FORBIDDEN, "fake", {"ex": ["robolab_fake_pkg.mod.func"]})
    assert "robolab_fake_pkg" not in sys.modules, "the fake package must not exist"
    with forbidden("ex", {}), pytest.raises(DelegationError, match="not available while ex"):
        import robolab_fake_pkg.mod  # noqa: F401
    assert not any(isinstance(f, delegation._BlockImports) for f in sys.meta_path), (
        "the import blocker must be removed after the call"
    )


def test_the_refusal_is_not_a_value_error():
    """A refusal test (pytest.raises(ValueError)) must not count a delegation as a refusal."""
    assert not issubclass(DelegationError, (ValueError, TypeError)), (
        "DelegationError must not look like a refusal of bad input"
    )


def test_the_worker_refuses_delegation_only_while_that_exercise_runs(tmp_path):
    """Through the worker: wrap() delegating fails, mean_pose() using wrap_angle inside works."""
    from robolab.grading.running.proxy import StudentCodeError, open_submission

    nb = write_notebook(
        tmp_path / "delegating.ipynb",
        "import numpy as np\nfrom robolab.geometry import wrap_angle as w\n"
        "def wrap(angle):\n    return w(angle)\n"
        "def mean_pose(poses):\n    p = np.asarray(poses, dtype=float)\n"
        "    return np.array([p[:, 0].mean(), p[:, 1].mean(), w(p[:, 2].mean())])\n",
    )
    proxy = open_submission(nb, lab="demo", limits=TEST_LIMITS)
    try:
        with pytest.raises(StudentCodeError, match="not available while wrap is graded"):
            proxy.wrap(4.0)
        got = np.asarray(proxy.mean_pose(np.array([[0.0, 0.0, 4.0]])), dtype=float)
        np.testing.assert_allclose(
            got, [0.0, 0.0, 4.0 - 2 * np.pi], err_msg="mean_pose may use wrap_angle internally"
        )
        with pytest.raises(StudentCodeError):
            proxy.wrap(4.0)  # and refused again: the guard is per call
    finally:
        proxy.close()


# --- every alias of a guarded function refuses (issue 25) ---------------------------------------


def _aliases(dotted: str) -> dict[str, object]:
    """Every way a submission can hold the function behind ``dotted``, taken before the guard.

    Each value is a zero-argument callable reaching the function: inside the guard it
    must raise DelegationError (refused before its arguments are looked at); outside,
    the function runs and complains about its missing arguments instead.
    """
    import functools
    import sys

    owner, attr, value = resolve(dotted)
    if isinstance(owner, type):
        instance = owner.__new__(owner)
        if isinstance(value, property):
            return {"property of an instance": lambda: getattr(instance, attr)}
        bound = getattr(instance, attr)
        return {
            "bound method taken before": bound,
            "bound method made during": lambda: getattr(instance, attr)(),
            "class attribute": lambda: getattr(owner, attr)(instance),
            "bound methods in a list": [bound][0],
        }
    function = value
    defining = sys.modules[function.__module__]
    namespace: dict = {"f": function}
    exec(  # noqa: S102 - what a submission's imports cell does
        f"from {owner.__name__} import {attr} as alias\n"
        f"import {defining.__name__} as _m\n"
        "table = {'k': f}\ncopies = [f]\n"
        "def defaulted(_f=f):\n    return _f()\n",
        namespace,
    )
    holders = {
        f"as {name}.{attr}": (lambda m=module: getattr(m, attr)())
        for name, module in list(sys.modules.items())
        if getattr(module, attr, None) is function
    }
    assert len(holders) >= 1 and f"as {defining.__name__}.{attr}" in holders
    return {
        **holders,
        "from-import alias": namespace["alias"],
        "module alias": lambda: getattr(namespace["_m"], attr)(),
        "dict copy": namespace["table"]["k"],
        "list copy": namespace["copies"][0],
        "default argument": namespace["defaulted"],
        "partial": functools.partial(function),
    }


@pytest.mark.parametrize("entry", ENTRIES, ids=[f"{lab}.{ex}:{n}" for lab, ex, n in ENTRIES])
def test_every_alias_copy_and_bound_method_of_a_guarded_function_refuses(entry):
    _, exercise, dotted = entry
    aliases = _aliases(dotted)
    functions = delegation._functions(resolve(dotted)[2])
    codes = [f.__code__ for f in functions]
    with forbidden(exercise, {}):
        for _how, call in aliases.items():
            with pytest.raises(DelegationError, match=f"write {exercise} yourself"):
                call()
    assert [f.__code__ for f in functions] == codes, "the functions' code must be restored"
    for how, call in aliases.items():
        try:
            call()
        except DelegationError:
            pytest.fail(f"{dotted} {how} still refuses after the guard")
        except Exception:  # noqa: BLE001, S110 - missing arguments: the function itself ran
            pass


def test_a_guarded_closure_refuses_and_keeps_its_cells(monkeypatch):
    """A function with free variables (a decorator's wrapper) is guarded as well and restored."""
    import robolab.geometry as module

    def make(scale):
        def scaled(x):
            return scale * x

        return scaled

    monkeypatch.setattr(module, "scaled_for_test", make(3.0), raising=False)
    monkeypatch.setitem(FORBIDDEN, "fake", {"ex": ["robolab.geometry.scaled_for_test"]})
    copy = [module.scaled_for_test]
    with forbidden("ex", {}), pytest.raises(DelegationError, match="write ex yourself"):
        copy[0](2.0)
    assert copy[0](2.0) == 6.0


def test_the_worker_refuses_the_guarded_function_through_submodules_and_copies(tmp_path):
    """Issue 25's attacks through the real worker: robolab.sim.run.clearance_field and
    filterpy.monte_carlo.resampling (imported as _mc at module level) while likelihood_field
    and low_variance_resample are graded; other exercises may still use them."""
    from robolab.grading.running.proxy import StudentCodeError, open_submission

    nb = write_notebook(
        tmp_path / "aliasing.ipynb",
        "import numpy as np\nimport robolab.sim.run as _run\n"
        "import filterpy.monte_carlo.resampling as _mc\n"
        "RESAMPLERS = {'s': _mc.systematic_resample}\n"
        "def likelihood_field(grid):\n    return _run.clearance_field(grid)\n"
        "def low_variance_resample(weights):\n"
        "    if len(weights) % 2:\n        return RESAMPLERS['s'](weights)\n"
        "    return _mc.systematic_resample(weights)\n"
        "def other(weights):\n    return _mc.systematic_resample(weights)\n",
        lab=None,
    )
    # robolab.sim and filterpy take seconds to import on a loaded machine: the default limits.
    proxy = open_submission(nb)
    try:
        assert proxy.problems == []
        with pytest.raises(StudentCodeError, match="not available while likelihood_field"):
            proxy.likelihood_field(None)
        for n in (3, 4):  # the dict copy, the module alias
            with pytest.raises(StudentCodeError, match="not available while low_variance_res"):
                proxy.low_variance_resample(np.full(n, 1 / n))
        assert len(proxy.other(np.full(4, 0.25))) == 4, "other exercises may use filterpy"
    finally:
        proxy.close()
