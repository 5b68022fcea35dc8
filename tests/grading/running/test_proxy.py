"""The proxy: calls cross to the worker and back; errors, crashes and hangs cost one call only."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from robolab.grading.loading.notebook import NotebookError
from robolab.grading.running.proxy import (
    MissingFunction,
    StudentCodeError,
    WorkerCrashed,
    WorkerTimeout,
    open_submission,
    student_error_class,
)
from tests.grading import TEST_LIMITS, write_notebook

FUNCTIONS = """
import os
import sys
import time
import numpy as np

SCALE = 2.0

def normalize(weights):
    w = np.asarray(weights, dtype=float)
    if np.any(w < 0):
        raise ValueError("weights must be non-negative")
    return w / w.sum()

def echo(*args, **kwargs):
    return args, kwargs

def scaled(x):
    return SCALE * x

def stub(x):
    raise NotImplementedError

def lookup(key):
    return {"a": 1}[key]

def singular():
    return np.linalg.inv(np.zeros((2, 2)))

class CustomError(Exception):
    pass

def custom():
    raise CustomError("mine")

def mutate(a):
    a[0] = 99.0
    return a

def crash():
    os._exit(3)

def leave():
    sys.exit(0)

def hang():
    time.sleep(60)

def spin():
    while True:
        pass

def chatty(n):
    for i in range(n):
        print("line", i)
    return n
"""


@pytest.fixture(scope="module")
def proxy(tmp_path_factory):
    path = write_notebook(
        tmp_path_factory.mktemp("proxy") / "sub.ipynb", FUNCTIONS, "print('demo')"
    )
    with open_submission(path, lab="demo", limits=TEST_LIMITS) as sub:
        yield sub


def test_metadata(proxy):
    assert proxy.lab == "demo"
    assert proxy.path.name == "sub.ipynb"
    assert {"normalize", "echo", "CustomError"} <= set(proxy.functions)
    assert "np" not in proxy.functions and "SCALE" not in proxy.functions
    assert proxy.problems == []


def test_values_round_trip(proxy):
    np.testing.assert_allclose(proxy.normalize([1.0, 3.0]), [0.25, 0.75])
    args, kwargs = proxy.echo(np.arange(3), (1, "a"), k={"x": np.float32(2)})
    np.testing.assert_array_equal(args[0], [0, 1, 2])
    assert args[1] == (1, "a") and kwargs == {"k": {"x": np.float32(2)}}
    assert proxy.scaled(1.5) == 3.0  # module constants are defined


def test_arguments_changed_in_place_are_changed_for_the_caller(proxy):
    # As in-process (tests/grading/wire/test_observe.py has the general oracle test).
    a = np.zeros(3)
    got = proxy.mutate(a)
    assert got is a and a[0] == 99.0


def test_student_exceptions_keep_their_builtin_type(proxy):
    with pytest.raises(ValueError, match="non-negative") as info:
        proxy.normalize([-1.0, 2.0])
    assert isinstance(info.value, StudentCodeError)
    assert info.value.kind == "ValueError"
    assert 'File "<cell 1>"' in info.value.student_traceback
    assert "raise ValueError" in info.value.student_traceback
    with pytest.raises(KeyError) as info:
        proxy.lookup("b")
    assert isinstance(info.value, StudentCodeError)
    # numpy's LinAlgError subclasses ValueError: it is one across the boundary too.
    with pytest.raises(ValueError) as info:
        proxy.singular()
    assert info.value.kind == "LinAlgError"


def test_a_stub_does_not_pass_for_a_value_error(proxy):
    with pytest.raises(NotImplementedError) as info:
        proxy.stub(1)
    assert not isinstance(info.value, ValueError)


def test_custom_exceptions_are_plain_student_code_errors(proxy):
    with pytest.raises(StudentCodeError) as info:
        proxy.custom()
    assert type(info.value) is StudentCodeError
    assert info.value.kind == "CustomError" and str(info.value) == "mine"


def test_missing_function(proxy):
    with pytest.raises(MissingFunction, match="does not define mean_pose"):
        proxy.mean_pose  # noqa: B018 - the attribute access is what raises
    assert not hasattr(proxy, "mean_pose")
    with pytest.raises(AttributeError):
        proxy.__wrapped__  # noqa: B018


def test_crash_costs_one_call_and_the_worker_restarts(proxy):
    with pytest.raises(WorkerCrashed, match="status 3"):
        proxy.crash()
    np.testing.assert_allclose(proxy.normalize([1.0, 1.0]), [0.5, 0.5])
    with pytest.raises(WorkerCrashed, match="SystemExit"):
        proxy.leave()
    assert proxy.scaled(2.0) == 4.0


def test_wall_time_limit(proxy):
    # What the wall limit counts (time not spent waiting for a CPU) is charged, at least the
    # limit and at most a poll interval more, whatever the machine's load.
    before = proxy.spent_seconds
    with pytest.raises(WorkerTimeout, match=f"{TEST_LIMITS.wall_seconds:g} s of wall time"):
        proxy.hang()
    assert TEST_LIMITS.wall_seconds <= proxy.spent_seconds - before <= TEST_LIMITS.wall_seconds + 1
    assert proxy.scaled(1.0) == 2.0
    # A function that timed out once gets a tenth of the budget (at least 1 s) from then on.
    before = proxy.spent_seconds
    with pytest.raises(WorkerTimeout, match="1 s of wall time"):
        proxy.hang()
    assert 1 <= proxy.spent_seconds - before <= 2
    assert any("hang(): timed out" in line for line in proxy.limits_hit())


def test_cpu_time_limit(tmp_path):
    path = write_notebook(tmp_path / "spin.ipynb", FUNCTIONS)
    limits = replace(TEST_LIMITS, cpu_seconds=1, wall_seconds=30)
    with open_submission(path, limits=limits) as sub:
        with pytest.raises(WorkerTimeout, match="CPU time"):
            sub.spin()
        # The CPU limit stopped it, not the wall limit (however loaded the machine); the
        # kernel's RLIMIT_CPU (whole seconds) backs the grader's polling up.
        assert 1 <= sub.spent_cpu_seconds <= limits.cpu_seconds + 2
        assert sub.spent_seconds < limits.wall_seconds
        [line] = sub.limits_hit()
        assert line.startswith("spin(): timed out: used more than 1 s of CPU time")


def test_output_is_captured_and_bounded(proxy):
    proxy.chatty(3)
    assert "line 2" in proxy.output()
    assert proxy.chatty(20_000) == 20_000
    text = proxy.output()
    assert len(text) < TEST_LIMITS.max_output_bytes + 200
    assert "more bytes of output were dropped" in text


def test_load_problems_are_recorded_and_the_rest_loads(tmp_path):
    # As in Jupyter, a cell stops at its first error; the next cells still run.
    path = write_notebook(
        tmp_path / "p.ipynb",
        "import numpy as np\ndef f(x):\n    return x + 1\n"
        "import no_such_module\ndef e():\n    pass",
        "def broken(:\n",
        "@undefined_decorator\ndef g():\n    pass\ndef h():\n    return 2",
        "def k():\n    return 3",
        lab=None,
    )
    with open_submission(path, limits=TEST_LIMITS) as sub:
        assert sub.f(1) == 2 and sub.k() == 3
        assert not {"e", "g", "h", "broken"} & set(sub.functions)
        kinds = sorted((p.cell_index, p.kind) for p in sub.problems)
        assert kinds == [(0, "error"), (1, "syntax"), (2, "error")]
        messages = " ".join(p.message for p in sub.problems)
        assert "no_such_module" in messages and "undefined_decorator" in messages
        assert [p.where for p in sorted(sub.problems, key=lambda p: p.cell_index)] == [
            "cell 1, `import numpy as np`",
            "cell 2, `def broken(:`",
            "cell 3, `@undefined_decorator`",
        ]


def test_a_cell_past_the_load_limit_is_stopped_and_named(tmp_path):
    path = write_notebook(
        tmp_path / "h.ipynb",
        "def f():\n    return 1\nclass Slow:\n    while True:\n        pass",
        lab=None,
    )
    limits = replace(TEST_LIMITS, wall_seconds=4)
    with open_submission(path, limits=limits) as sub:
        assert [(p.kind, p.where) for p in sub.problems] == [("timeout", "cell 1, `def f():`")]
        assert "time allowed to load your notebook" in sub.problems[0].message
        assert sub.f() == 1  # defined before the loop, as in the kernel
        assert "Slow" not in sub.functions
        # The load's CPU time is the submission's (the cell spun until the load budget).
        assert sub.spent_cpu_seconds >= 1
        assert [line.split(":")[0] for line in sub.limits_hit()] == ["loading the notebook"]


def test_definitions_that_hang_fail_every_call_quickly(tmp_path):
    # A cell that swallows the load-limit signal hangs until the grader's wall limit.
    path = write_notebook(
        tmp_path / "h.ipynb",
        "def f():\n    return 1\nclass Slow:\n    while True:\n        try:\n"
        "            while True:\n                pass\n        except BaseException:\n"
        "            pass",
        lab=None,
    )
    limits = replace(TEST_LIMITS, wall_seconds=2)
    sub = open_submission(path, limits=limits)
    try:
        assert any("loading the notebook" in p.message for p in sub.problems)
        spent = sub.spent_cpu_seconds, sub.spent_seconds
        for _ in range(3):  # each fails at once: no worker is started, no time is charged
            with pytest.raises(WorkerTimeout):
                sub.f()
            assert sub._worker is None and (sub.spent_cpu_seconds, sub.spent_seconds) == spent
    finally:
        sub.close()


def test_closed_proxy_refuses_calls(tmp_path):
    path = write_notebook(tmp_path / "c.ipynb", "def f():\n    return 1", lab=None)
    sub = open_submission(path, limits=TEST_LIMITS)
    assert sub.f() == 1
    sub.close()
    with pytest.raises(RuntimeError, match="closed"):
        sub.f()


def test_not_a_notebook(tmp_path):
    path = tmp_path / "x.ipynb"
    path.write_text("nope")
    with pytest.raises(NotebookError, match="x.ipynb"):
        open_submission(path)


@pytest.mark.parametrize(
    "bases, expected",
    [
        (["ValueError", "Exception", "BaseException"], ValueError),
        (["UnicodeDecodeError", "UnicodeError", "ValueError"], UnicodeError),
        (["PermissionError", "OSError"], PermissionError),
        (["Exception", "BaseException"], None),
        (["NotARealBuiltin", "TypeError"], TypeError),
    ],
)
def test_student_error_classes(bases, expected):
    cls = student_error_class(bases)
    error = cls("message", kind="X", student_traceback="tb")
    assert isinstance(error, StudentCodeError) and str(error) == "message"
    if expected is None:
        assert cls is StudentCodeError
    else:
        assert isinstance(error, expected)


def test_a_forgotten_proxy_does_not_leave_its_worker_running(tmp_path):
    import gc

    path = write_notebook(tmp_path / "f.ipynb", "def f():\n    return 1")
    sub = open_submission(path, limits=TEST_LIMITS)
    process, base = sub._worker.process, sub._worker.base
    del sub
    gc.collect()
    assert process.poll() is not None
    assert not base.exists()


def test_threads_that_outlive_a_call_are_the_submissions_own(tmp_path):
    """A pool of threads made at load serves every call: the threads are not processes
    the call left behind (which the sweep after each call kills), nor charged again."""
    path = write_notebook(
        tmp_path / "pool.ipynb",
        "from concurrent.futures import ThreadPoolExecutor\n"
        "POOL = ThreadPoolExecutor(2)\n"
        "def square(x):\n"
        "    return POOL.submit(lambda: x * x).result()\n",
        lab=None,
    )
    with open_submission(path, limits=TEST_LIMITS) as sub:
        assert [sub.square(i) for i in range(6)] == [i * i for i in range(6)]
        assert sub.limits_hit() == [] and sub.spent_cpu_seconds < 1


def test_numba_parallel_code_gets_the_same_pool_on_every_machine(tmp_path):
    """A student's ``prange`` runs on a pool of a fixed size (not one thread per core of
    the grading machine, which could meet the process limit and changes a parallel sum's
    rounding), and the pool's threads live from call to call."""
    from robolab.grading.running.channel import NUMBA_THREADS

    path = write_notebook(
        tmp_path / "prange.ipynb",
        "import numba\n"
        "import numpy as np\n"
        "@numba.njit(parallel=True)\n"
        "def _total(x):\n"
        "    s = 0.0\n"
        "    for i in numba.prange(x.shape[0]):\n"
        "        s += x[i]\n"
        "    return s\n"
        "def total(n):\n"
        "    return _total(np.arange(n, dtype=float)), numba.get_num_threads()\n",
        lab=None,
    )
    limits = replace(TEST_LIMITS, cpu_seconds=30, wall_seconds=60)
    with open_submission(path, limits=limits) as sub:
        for n in (10, 1000, 100_000):
            assert sub.total(n) == (n * (n - 1) / 2, NUMBA_THREADS)
        assert sub.limits_hit() == []
