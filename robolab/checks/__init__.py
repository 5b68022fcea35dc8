"""Visible checks that the student notebooks call after each exercise.

Each lab has a module ``robolab.checks.<lab>`` with one ``check_<exercise>(func)``
per exercise. A check is quick and friendly: it prints what it tried and either
"ok" or what went wrong, and raises ``CheckFailed`` so the notebook cell shows
red. It is weaker than the hidden tests, which never ship to students.
"""

from robolab.checks.base import CheckFailed, check, passed

__all__ = ["CheckFailed", "check", "passed"]
