"""Credit that follows an exercise's parts, and hints across exercises.

:func:`settle` turns the hidden tests' raw outcomes into what the student is graded on:
a test gated by ``requires`` counts only when those tests pass, and a failed test that
uses an exercise failing its own checks gets a note naming it (the points do not move).
"""

from __future__ import annotations

__all__ = ["settle"]


def _label(record: dict) -> str:
    return f'"{record["description"]}"'


def settle(records: list[dict]) -> list[dict]:
    """The records as the student is graded: ``requires`` gates applied, ``uses`` hints added.

    Pure: returns new dicts, the collector's own records stay as the tests ran
    (so a rewrite after a later test starts again from the raw outcomes).

    - A passed test whose required tests did not all pass becomes "failed", with
      a message naming them (repeated until nothing changes: gates can chain).
    - A failed test that uses an exercise which fails some of its own tests gets
      a closing note pointing to that exercise's section (the points do not move:
      while the test ran, that exercise answered as the reference, see
      :mod:`robolab.grading.running.answers`).
    """
    out = [dict(r) for r in records]
    by_test: dict[tuple[str, str], list[dict]] = {}
    for r in out:
        by_test.setdefault((r.get("module", ""), r.get("test", "")), []).append(r)
    changed = True
    while changed:
        changed = False
        for r in out:
            if r["outcome"] != "passed" or not r.get("requires"):
                continue
            waiting = [
                other
                for name in r["requires"]
                for other in by_test.get((r.get("module", ""), name), [])
                if other["outcome"] != "passed"
            ]
            if waiting:
                r["outcome"] = "failed"
                r["gated"] = True
                r["message"] = (
                    f"This check passed on its own, but it counts only when `{r['exercise']}` "
                    f"also passes {', '.join(_label(w) for w in waiting[:3])}"
                    f"{' and more' if len(waiting) > 3 else ''}: refusing bad input or "
                    "finishing the whole run earns points only for a function that computes "
                    "the right values."
                )
                changed = True
    failing: dict[str, int] = {}
    for r in out:
        if r["outcome"] in ("failed", "error") and not r.get("gated"):
            failing[r["exercise"]] = failing.get(r["exercise"], 0) + 1
    for r in out:
        if r["outcome"] not in ("failed", "error"):
            continue
        culprits = [u for u in r.get("uses", []) if u in failing and u != r["exercise"]]
        if culprits:
            names = ", ".join(f"`{u}`" for u in culprits)
            one = len(culprits) == 1
            r["message"] = (r.get("message") or "").rstrip() + (
                f"\n\nNote: {names} {'is' if one else 'are'} wrong too: "
                f"{'it fails its' if one else 'they fail their'} own checks (see the section "
                f"on {names}). This check gave {r['exercise']} correct versions of "
                f"{'it' if one else 'them'}, so what it found is in {r['exercise']} itself; "
                f"fixing {names} first may still make it easier to see."
            )
    return out
