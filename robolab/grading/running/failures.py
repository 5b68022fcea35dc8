"""What a failed hidden test reports: its title, its message in words, its crash line.

:func:`failure_message` turns a failure into feedback without hidden test source;
:func:`report_crash_only` spares pytest formatting tracebacks that a grading run
(``--tb=no``) never shows.
"""

from __future__ import annotations

import re

import pytest

#: Longest failure message kept in a report; longer ones are cut in the middle.
MAX_MESSAGE_CHARS = 2000


def title_of(doc: str | None) -> str:
    """A docstring's first paragraph on one line: the check's title (a whole sentence)."""
    paragraph = (doc or "").strip().split("\n\n")[0]
    return " ".join(paragraph.split())


def describe(item: pytest.Item) -> str:
    """A test's name in words: its docstring's title, else its name without ``test_``."""
    doc = getattr(getattr(item, "obj", None), "__doc__", None)
    base = title_of(doc) or item.name.split("[")[0].removeprefix("test_").replace("_", " ")
    param = item.name[len(item.name.split("[")[0]) :]
    return base + (f" {param}" if param else "")


_REWRITE_TAIL = re.compile(r"\n(assert |\s*\+\s+where ).*", re.DOTALL)
_DID_NOT_RAISE = re.compile(r"DID NOT RAISE (?:<class '(?:[\w.]*\.)?(\w+)'>|\(?([\w., ]+)\)?)")


def failure_message(exc: BaseException | None, crash_message: str | None) -> str:
    """The failure in words, without hidden test source.

    The student's traceback when the student's code raised (the proxy attaches
    ``student_traceback``); otherwise the exception's message as pytest reports
    it, with the assertion-rewrite explanation dropped when the assertion has a
    message of its own.
    """
    student_tb = getattr(exc, "student_traceback", None)
    message = getattr(exc, "message", None)
    if student_tb:
        kind = getattr(exc, "kind", None) or type(exc).__name__
        text = f"{kind}: {message}\n{student_tb}" if message else f"{kind}\n{student_tb}"
    elif student_tb is not None and isinstance(message, str):
        text = message  # the proxy's own words: a crash, a timeout, a result that is not plain data
    else:
        text = crash_message or (f"{type(exc).__name__}: {exc}" if exc is not None else "")
        head = _REWRITE_TAIL.sub("", text)
        if head.strip() and head.strip() not in ("AssertionError", "AssertionError:"):
            text = head
    # pytest.fail's own words (a refusal naming its input, "Not run: ...") without pytest's label
    text = text.strip().removeprefix("Failed: ")
    if (missed := _DID_NOT_RAISE.search(text)) is not None:
        kind = missed.group(1) or missed.group(2) or "an error"
        text = (
            f"expected {kind} for the bad input this check names, but the function returned "
            "normally: the text asks to refuse such input with a clear error, not to compute "
            "on it"
        )
    if len(text) > MAX_MESSAGE_CHARS:
        half = MAX_MESSAGE_CHARS // 2
        cut = len(text) - MAX_MESSAGE_CHARS
        text = f"{text[:half]}\n... ({cut} characters cut) ...\n{text[-half:]}"
    return text


def tracebacks_unshown(config: pytest.Config) -> bool:
    """True when no failure's traceback is shown (``--tb=no``, as the runner asks): only
    the crash line of each failure is read (the report's message, ``-ra``'s summary)."""
    return config.getoption("tbstyle", "auto") == "no" and not config.getoption("fulltrace", False)


def report_crash_only(item: pytest.Item) -> None:
    """Make ``item``'s failure reports hold only the crash line pytest would have found.

    pytest formats every failure's whole traceback (filtering its entries, reading their
    source) although ``--tb=no`` never shows it: 7 % of a grading run's CPU for a
    submission that fails a third of its tests (issue 29). The crash line is
    ``ExceptionInfo._getreprcrash()`` whatever the style, so it is computed alone here.
    Anything pytest formats its own way (a fixture not found, a conftest that failed to
    import, an exception without a traceback) and a pytest without these internals
    keep pytest's own formatting.
    """
    try:
        from _pytest._code.code import ReprExceptionInfo, ReprTraceback
        from _pytest.config import ConftestImportFailure
        from _pytest.fixtures import FixtureLookupError
    except ImportError:
        return
    full = item._repr_failure_py

    def crash_only(excinfo, style=None):
        if (
            isinstance(excinfo.value, (ConftestImportFailure, FixtureLookupError))
            or excinfo.tb is None
            or not hasattr(excinfo, "_getreprcrash")
        ):
            return full(excinfo, style)
        return ReprExceptionInfo(
            reprtraceback=ReprTraceback([], None, "short"), reprcrash=excinfo._getreprcrash()
        )

    item._repr_failure_py = crash_only
