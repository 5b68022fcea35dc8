"""The ``robolab`` command.

Sub-commands (each lives in its own module; this file only parses arguments):

- ``robolab data``: regenerate the bundled data with the simulator (robolab.sim).
- ``robolab grade``, ``merge``, ``check``, ``solve``, ``release``, ``gradescope``,
  ``similarity``: the autograder and the course's tools (robolab.grading.commands).

Every user error (a bad argument, a path that cannot be written, a file that cannot
be read) is one line ``robolab: error: ...`` on stderr and exit status 2.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

#: Exit status of a user error (as argparse's).
USAGE = 2

#: Sub-commands that need the instructor's copy of robolab: the hidden tests and the
#: reference solutions, which the student edition does not have.
INSTRUCTOR_COMMANDS = ("grade", "solve", "release", "gradescope", "merge", "similarity")


def instructor_copy() -> bool:
    """True when this robolab has the answer key beside it (solutions/ and tests/labs/)."""
    from robolab.grading.labs import project_root

    root = project_root()
    return (root / "solutions").is_dir() and (root / "tests" / "labs").is_dir()


def _needs_instructor_copy(command: str) -> int:
    print(
        f"robolab: error: {command}: an instructor command; it needs the instructor's copy of "
        "robolab (the repository, with its hidden tests and reference solutions), and this is "
        "the student edition. To check your work: robolab check NOTEBOOK",
        file=sys.stderr,
    )
    return USAGE


class _Parser(argparse.ArgumentParser):
    """argparse, but a usage error is one line: ``robolab: error: <sub-command>: ...``."""

    def error(self, message: str):  # noqa: D102 - argparse's hook
        where = self.prog.removeprefix("robolab").strip()
        print(f"robolab: error: {where + ': ' if where else ''}{message}", file=sys.stderr)
        sys.exit(USAGE)


def _number(cast, valid, noun: str, rule: str):
    """An argparse type: ``cast(text)`` that must satisfy ``valid``, else a one-line error."""

    def convert(text: str):
        try:
            value = cast(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not {noun}") from None
        if not valid(value):
            raise argparse.ArgumentTypeError(f"must be {rule}, got {text}")
        return value

    return convert


_positive_seconds = _number(
    float,
    lambda v: v > 0 and math.isfinite(v),
    "a number of seconds",
    "a positive number of seconds",
)
_positive_int = _number(int, lambda v: v >= 1, "a whole number", "at least 1")
_percent = _number(float, lambda v: 0 <= v <= 100, "a percentage", "between 0 and 100 (percent)")


def _visibility(text: str) -> tuple[str, str]:
    from robolab.grading.exports.gradescope import VISIBILITIES

    exercise, sep, value = text.partition("=")
    if not sep or value not in VISIBILITIES or not exercise:
        raise argparse.ArgumentTypeError(
            f"{text!r}: expected EXERCISE=VISIBILITY with VISIBILITY one of "
            f"{', '.join(VISIBILITIES)}"
        )
    return exercise, value


def _course_options(p: argparse.ArgumentParser) -> None:
    """The course's options, shared by grade and merge (applied once, to every row)."""
    p.add_argument("--roster", type=Path, help="CSV: id,name,email,match (see docs/instructor.md)")
    p.add_argument(
        "--export",
        action="append",
        default=[],
        choices=["canvas", "moodle"],
        help="also write OUT/<lms>.csv for Canvas or Moodle import (needs --roster; repeatable)",
    )
    p.add_argument("--assignment", help="the assignment's column name in exports (default: lab)")
    p.add_argument(
        "--overrides",
        type=Path,
        help="CSV: student,exercise,points,comment; kept as OUT/overrides.csv for regrades",
    )
    p.add_argument("--due", help="due date, ISO 8601 (2026-03-01T23:59:00+01:00)")
    p.add_argument(
        "--late-penalty",
        type=_percent,
        default=0.0,
        metavar="PERCENT",
        help="percent of the points lost per started day late",
    )
    p.add_argument(
        "--late-cap",
        type=_percent,
        default=100.0,
        metavar="PERCENT",
        help="largest late penalty in percent (default 100)",
    )
    p.add_argument(
        "--submitted-times",
        type=Path,
        metavar="CSV",
        help="CSV: match,submitted (default: the files' modification times)",
    )


def _build_parser(instructor: bool = True) -> argparse.ArgumentParser:
    """The command line; the student edition (``instructor=False``) lists only its commands."""
    p = _Parser(
        prog="robolab",
        description="robolab: probabilistic-robotics labs and their autograder"
        if instructor
        else "robolab: probabilistic-robotics labs (student edition: check your notebooks)",
    )
    p.add_argument(
        "--version", action="version", version=f"robolab {__import__('robolab').__version__}"
    )
    sub = p.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    sub.required = True

    d = sub.add_parser(
        "data", help="regenerate the bundled data (maps, bags, data sets) deterministically"
    )
    d.add_argument(
        "--out", type=Path, default=None, help="output folder (default: the repository's data/)"
    )
    d.add_argument(
        "--only", nargs="*", default=None, metavar="NAME", help="regenerate only these data sets"
    )

    g = sub.add_parser("grade", help="grade student notebooks against the hidden tests")
    g.add_argument("submissions", nargs="+", type=Path, help="submitted .ipynb files")
    g.add_argument(
        "--lab", default=None, help="lab name (default: read from each notebook's metadata)"
    )
    g.add_argument(
        "--out", type=Path, default=Path("grades"), help="folder for gradebook and feedback"
    )
    g.add_argument(
        "-j", "--jobs", type=_positive_int, default=1, help="submissions graded in parallel"
    )
    g.add_argument(
        "--timeout",
        type=_positive_seconds,
        default=None,
        metavar="SECONDS",
        help="overall time limit per submission (default 600)",
    )
    g.add_argument(
        "--shard",
        metavar="K/N",
        help="grade only the K-th of N slices of FILES (the same slices on every machine); "
        "join the N output folders with robolab merge",
    )
    _course_options(g)

    m = sub.add_parser(
        "merge", help="merge the output folders of robolab grade --shard K/N into one"
    )
    m.add_argument("shards", nargs="+", type=Path, metavar="DIR", help="the N shard folders")
    m.add_argument("--out", type=Path, required=True, help="folder for the merged outputs")
    _course_options(m)

    sim = sub.add_parser(
        "similarity", help="compare submissions' exercise code, pair by pair (never runs it)"
    )
    sim.add_argument("notebooks", nargs="+", type=Path, help="submitted .ipynb files")
    sim.add_argument(
        "--out", type=Path, required=True, help="folder for similarity.csv and similarity.html"
    )
    sim.add_argument(
        "--show",
        type=_positive_int,
        default=25,
        metavar="N",
        help="closest pairs shown side by side in similarity.html (default 25)",
    )

    c = sub.add_parser("check", help="run a notebook's visible checks (for students)")
    c.add_argument("notebook", type=Path)

    s = sub.add_parser("solve", help="replace exercise stubs with the reference solutions")
    s.add_argument("notebooks", nargs="+", type=Path, help="notebooks, or folders of notebooks")
    s.add_argument(
        "-o", "--out", type=Path, required=True, help="output folder, or a .ipynb file for one"
    )

    r = sub.add_parser("release", help="build the student edition (no solutions, no hidden tests)")
    r.add_argument("out", type=Path)
    r.add_argument("--no-wheel", dest="wheel", action="store_false",
                   help="skip building dist/robolab-*.whl (the installable edition)")

    gs = sub.add_parser("gradescope", help="build a Gradescope autograder bundle for one lab")
    gs.add_argument("--lab", required=True)
    gs.add_argument("-o", "--out", type=Path, default=Path("autograder.zip"))
    gs.add_argument(
        "--visibility",
        type=_visibility,
        action="append",
        default=[],
        metavar="EXERCISE=VISIBILITY",
        help="visible, after_due_date, after_published or hidden for one exercise's tests",
    )
    gs.add_argument(
        "--default-visibility",
        default="visible",
        choices=["visible", "after_due_date", "after_published", "hidden"],
    )
    gs.add_argument("--late-penalty", type=_percent, default=0.0, metavar="PERCENT")
    gs.add_argument("--late-cap", type=_percent, default=100.0, metavar="PERCENT")
    if not instructor:  # the student edition offers only what it can do
        for name in INSTRUCTOR_COMMANDS:
            sub.choices.pop(name, None)
        offered = [a for a in sub._choices_actions if a.dest not in INSTRUCTOR_COMMANDS]
        sub._choices_actions = offered
    return p


def _dispatch(args) -> int:
    from robolab.grading import commands

    if args.command == "data":
        return commands.data(args.out, args.only)
    if args.command == "grade":
        options = ("lab", "out", "jobs", "timeout", "roster", "overrides", "assignment", "due")
        options += ("late_penalty", "late_cap", "submitted_times", "shard")
        return commands.grade(
            args.submissions, exports=args.export, **{k: getattr(args, k) for k in options}
        )
    if args.command == "merge":
        options = ("out", "roster", "overrides", "assignment", "due")
        options += ("late_penalty", "late_cap", "submitted_times")
        return commands.merge(
            args.shards, exports=args.export, **{k: getattr(args, k) for k in options}
        )
    if args.command == "similarity":
        return commands.similarity(args.notebooks, out=args.out, shown=args.show)
    if args.command == "check":
        return commands.check(args.notebook)
    if args.command == "solve":
        return commands.solve(args.notebooks, out=args.out)
    if args.command == "release":
        return commands.release(args.out, wheel=args.wheel)
    if args.command == "gradescope":
        return commands.gradescope(
            args.lab,
            out=args.out,
            visibility=dict(args.visibility),
            default_visibility=args.default_visibility,
            late_penalty=args.late_penalty,
            late_cap=args.late_cap,
        )
    raise AssertionError(args.command)


def main(argv: list[str] | None = None) -> int:
    if (sys.argv[1:] if argv is None else list(argv))[:1] == ["grade"] and instructor_copy():
        from robolab.grading.running import stopping

        # SIGINT and SIGTERM only ask a batch to stop, from its very start (the zygotes
        # start here); `robolab grade` looks at the request where stopping is safe.
        with stopping.on_signals():
            return _main(argv)
    return _main(argv)


def _main(argv: list[str] | None) -> int:
    if (sys.argv[1:] if argv is None else list(argv))[:1] == ["grade"] and instructor_copy():
        # Before anything else: the zygotes' imports (half a second) run while the
        # arguments are parsed and the batch is read. A command that ends before they
        # are ready (a usage error, --help) kills them at exit instead of waiting.
        from robolab.grading.isolation import warm

        warm.shared()  # the worker zygote first: its imports are the longest
        from robolab.grading.running.runner import start_zygotes

        start_zygotes()
    instructor = instructor_copy()
    command = (sys.argv[1:] if argv is None else list(argv))[:1]
    if not instructor and command and command[0] in INSTRUCTOR_COMMANDS:
        return _needs_instructor_copy(command[0])
    args = _build_parser(instructor).parse_args(argv)
    try:
        return _dispatch(args)
    except OSError as exc:  # a file the user named cannot be read or written
        where = f": {exc.filename}" if getattr(exc, "filename", None) else ""
        print(f"robolab: error: {exc.strerror or exc}{where}", file=sys.stderr)
        return USAGE
    except KeyboardInterrupt:
        print("robolab: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
