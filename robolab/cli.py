"""The ``robolab`` command.

Sub-commands (each lives in its own module; this file only parses arguments):

- ``robolab data``: regenerate the bundled data with the simulator (robolab.sim).
- ``robolab grade``, ``check``, ``solve``, ``release``, ``gradescope``: the
  autograder (robolab.grading.commands).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


def _build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="robolab", description="robolab: probabilistic-robotics labs and their autograder"
    )
    p.add_argument(
        "--version", action="version", version=f"robolab {__import__('robolab').__version__}"
    )
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
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
    g.add_argument("-j", "--jobs", type=int, default=1, help="submissions graded in parallel")
    g.add_argument(
        "--timeout",
        type=float,
        default=None,
        metavar="SECONDS",
        help="overall time limit per submission (default 600)",
    )

    c = sub.add_parser("check", help="run a notebook's visible checks (for students)")
    c.add_argument("notebook", type=Path)

    s = sub.add_parser("solve", help="replace exercise stubs with the reference solutions")
    s.add_argument("notebooks", nargs="+", type=Path, help="notebooks, or folders of notebooks")
    s.add_argument("-o", "--out", type=Path, required=True, help="output folder")

    r = sub.add_parser("release", help="build the student edition (no solutions, no hidden tests)")
    r.add_argument("out", type=Path)
    r.add_argument("--no-wheel", dest="wheel", action="store_false",
                   help="skip building dist/robolab-*.whl (the installable edition)")

    gs = sub.add_parser("gradescope", help="build a Gradescope autograder bundle for one lab")
    gs.add_argument("--lab", required=True)
    gs.add_argument("-o", "--out", type=Path, default=Path("autograder.zip"))
    return p


def main(argv: list[str] | None = None) -> int:
    args = _build_parser().parse_args(argv)
    if args.command == "data":
        from robolab.sim import make_data

        make_data(out_dir=args.out, only=args.only)
        return 0
    from robolab.grading import commands

    if args.command == "grade":
        return commands.grade(
            args.submissions, lab=args.lab, out=args.out, jobs=args.jobs, timeout=args.timeout
        )
    if args.command == "check":
        return commands.check(args.notebook)
    if args.command == "solve":
        return commands.solve(args.notebooks, out=args.out)
    if args.command == "release":
        return commands.release(args.out, wheel=args.wheel)
    if args.command == "gradescope":
        return commands.gradescope(args.lab, out=args.out)
    raise AssertionError(args.command)


if __name__ == "__main__":
    sys.exit(main())
