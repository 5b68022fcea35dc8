"""pytest plugin for the hidden lab tests.

A hidden test module ``tests/labs/test_<lab>.py`` asks for the ``lab`` fixture
and calls exercise functions on it (``lab.p_hit(...)``). By default ``lab`` is
the reference module ``solutions.<lab>``; with ``pytest --notebook PATH`` it is
a proxy to the student's notebook running in an isolated worker process.

Every hidden test carries ``@pytest.mark.grades("exercise_name", points=N)``.
"""

from __future__ import annotations

import importlib

import pytest


def pytest_addoption(parser):
    group = parser.getgroup("robolab")
    group.addoption("--notebook", action="store", default=None, metavar="PATH",
                    help="grade the student notebook at PATH instead of the reference solutions")


def pytest_configure(config):
    config.addinivalue_line("markers", "grades(exercise, points): hidden test grading one exercise function")


def lab_name_of(module_name: str) -> str:
    """``tests.labs.test_beam_model`` -> ``beam_model``."""
    leaf = module_name.rsplit(".", 1)[-1]
    if not leaf.startswith("test_"):
        raise ValueError(f"hidden test module {module_name!r} must be named test_<lab>")
    return leaf[len("test_"):]


@pytest.fixture(scope="module")
def lab(request):
    """The exercise functions under test: ``solutions.<lab>`` or the student's notebook."""
    name = lab_name_of(request.module.__name__)
    notebook = request.config.getoption("--notebook")
    if notebook is None:
        return importlib.import_module(f"solutions.{name}")
    from robolab.grading.proxy import open_submission  # the isolated worker

    proxy = open_submission(notebook, lab=name)
    request.addfinalizer(proxy.close)
    return proxy
