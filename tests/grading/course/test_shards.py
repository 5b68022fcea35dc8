"""Sharded grading: the slices (units against brute force), then the deploy recipe end to end.

The end-to-end test runs ``deploy/grade-shard.sh`` (the script of the Kubernetes, Slurm and
GNU parallel recipes in docs/instructor.md) as N processes, each on its own copy of the
submissions at another absolute path, merges the N folders, and compares the merged outputs
with one unsharded run of the same files, row by row.
"""

from __future__ import annotations

import itertools
import json
import os
import random
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from robolab.cli import main
from robolab.grading.course.batch import relative_paths
from robolab.grading.course.report import without_measured
from robolab.grading.course.shards import EXPECTED_SECONDS, Shard, deal, parse_shard
from tests.grading.running.test_runner import REPO

EXAMPLES = REPO / "examples" / "submissions"
SCRIPT = REPO / "deploy" / "grade-shard.sh"


# -- the slices ----------------------------------------------------------------------------


@pytest.mark.parametrize(
    "text, why",
    [
        ("0/3", "between 1 and N"),
        ("4/3", "between 1 and N"),
        ("1/0", "at least 1"),
        ("a/b", "expected K/N"),
        ("3", "expected K/N"),
        ("-1/3", "expected K/N"),
    ],
)
def test_bad_shard_is_refused_naming_the_option(text, why):
    with pytest.raises(ValueError, match=why) as exc:
        parse_shard(text)
    assert "--shard" in str(exc.value)


def test_parse_shard():
    assert parse_shard(" 3/8 ") == Shard(3, 8)


def _loads(paths, labs, shard, count):
    loads = [0.0] * count
    for lab, k in zip(labs, shard, strict=True):
        loads[k] += EXPECTED_SECONDS.get(lab, 1.0)
    return loads


def test_slices_depend_on_the_files_only_not_their_order_or_prefix():
    rng = random.Random(5)
    labs = list(EXPECTED_SECONDS)
    files = [f"sec{rng.randrange(3)}/student{i:03d}_x.ipynb" for i in range(60)]
    lab_of = {f: rng.choice(labs) for f in files}
    slices = []
    for prefix in ("/data/course", "/scratch/u/run 2", "/mnt/ñ"):
        order = files[:]
        rng.shuffle(order)
        rel = relative_paths([f"{prefix}/{f}" for f in order])
        assert rel == order  # the relative path is the same on every node
        dealt = deal(rel, [lab_of[f] for f in order], 7)
        slices.append({f: k for f, k in zip(order, dealt, strict=True)})
    assert slices[0] == slices[1] == slices[2]
    assert set(slices[0].values()) == set(range(7))  # every shard gets work


def test_every_submission_is_in_exactly_one_slice_and_slices_are_balanced_by_cost():
    """Longest-processing-time first is within 4/3 of the best split (Graham 1969):
    checked against the brute-force optimum on every small random batch."""
    rng = random.Random(1)
    labs = list(EXPECTED_SECONDS)
    for _ in range(60):
        n, count = rng.randint(1, 8), rng.randint(1, 3)
        chosen = [rng.choice(labs) for _ in range(n)]
        paths = [f"s{i}.ipynb" for i in range(n)]
        dealt = deal(paths, chosen, count)
        assert all(0 <= k < count for k in dealt)
        worst = max(_loads(paths, chosen, dealt, count))
        best = min(
            max(_loads(paths, chosen, split, count))
            for split in itertools.product(range(count), repeat=n)
        )
        assert worst <= (4 / 3 - 1 / (3 * count)) * best + 1e-9


def test_costly_labs_are_spread_not_bunched():
    # 4 costly + 12 cheap on 4 shards: each shard gets one costly submission
    labs = ["mcl"] * 4 + ["bayes"] * 12
    dealt = deal([f"{i:02d}.ipynb" for i in range(16)], labs, 4)
    assert sorted(dealt[:4]) == [0, 1, 2, 3]
    assert sorted(_loads(None, labs, dealt, 4)) == pytest.approx(
        [sum(EXPECTED_SECONDS[x] for x in labs) / 4] * 4
    )


def test_more_shards_than_submissions_leaves_empty_slices():
    assert sorted(deal(["a.ipynb", "b.ipynb"], ["bayes", "bayes"], 5)) == [0, 1]


# -- end to end: the recipe's script as N processes, merged, against one run ----------------

COURSE_OPTIONS = [
    "--roster",
    "roster.csv",
    "--due",
    "2026-03-01T23:59:00+00:00",
    "--late-penalty",
    "10",
    "--overrides",
    "overrides.csv",
    "--export",
    "canvas",
    "--export",
    "moodle",
]


def _lay_out(folder: Path) -> Path:
    """Seven submissions of two labs (one a renamed notebook of another lab), a roster,
    overrides; modification times fixed so that one is late."""
    subs = folder / "subs"
    subs.mkdir(parents=True)
    for lab in ("bayes", "demo"):
        for kind in ("correct", "partial", "wrong"):
            shutil.copy(EXAMPLES / lab / f"{kind}.ipynb", subs / f"{kind}_{lab}.ipynb")
    shutil.copy(EXAMPLES / "demo" / "correct.ipynb", subs / "mallory_bayes.ipynb")
    for i, f in enumerate(sorted(subs.iterdir())):
        when = 1772409540 + (90000 if f.name == "partial_bayes.ipynb" else -3600 * i)
        os.utime(f, (when, when))
    (folder / "roster.csv").write_text(
        "id,name,email,match\n"
        "s1,Ada,ada@x.edu,correct_*\ns2,Alan,alan@x.edu,partial_*\ns3,Grace,g@x.edu,wrong_*\n"
    )
    (folder / "overrides.csv").write_text(
        "student,exercise,points,comment\ns3,bayes_posterior,12,partly right\n"
    )
    return folder


@pytest.fixture(scope="module")
def graded(tmp_path_factory):
    """One unsharded run, and 3 shards graded by the recipe's script on 3 "nodes"."""
    base = tmp_path_factory.mktemp("course")
    whole = _lay_out(base / "whole")
    cwd = os.getcwd()
    os.chdir(whole)
    try:
        assert (
            main(
                [
                    "grade",
                    *sorted(str(p.relative_to(whole)) for p in (whole / "subs").iterdir()),
                    "--out",
                    "grades",
                    *COURSE_OPTIONS,
                ]
            )
            == 0
        )
    finally:
        os.chdir(cwd)
    nodes, procs = [], []
    robolab = shutil.which("robolab", path=os.path.dirname(sys.executable))
    for k in (1, 2, 3):
        node = base / f"node {k}" / "mnt"  # another absolute prefix on every node
        node.mkdir(parents=True)
        shutil.copytree(whole / "subs", node / "subs")  # copy2: modification times kept
        env = dict(
            os.environ, SHARDS="3", SUBMISSIONS="subs", GRADES=str(base / "grades"), ROBOLAB=robolab
        )
        env.pop("JOB_COMPLETION_INDEX", None)
        env.pop("SLURM_ARRAY_TASK_ID", None)
        # each scheduler's way of saying which slice this is
        how = [{"JOB_COMPLETION_INDEX": "0"}, {"SLURM_ARRAY_TASK_ID": "2"}, {}][k - 1]
        args = [] if how else ["3"]
        procs.append(
            subprocess.Popen(
                ["sh", str(SCRIPT), *args],
                cwd=node,
                env={**env, **how},
                stdout=subprocess.PIPE,
                stderr=subprocess.PIPE,
                text=True,
            )
        )
        nodes.append(node)
    for p in procs:
        out, err = p.communicate(timeout=600)
        assert p.returncode == 0, err
    return base, whole


def test_merged_shards_equal_one_unsharded_run(graded, capsys):
    base, whole = graded
    shards = sorted((base / "grades").iterdir())
    assert [s.name for s in shards] == ["shard-1", "shard-2", "shard-3"]
    members = [json.loads((s / "shard.json").read_text())["members"] for s in shards]
    assert sum(len(m) for m in members) == 7 and all(members)
    cwd = os.getcwd()
    os.chdir(whole)
    try:
        # the arguments' order does not matter either
        assert main(["merge", *map(str, shards[::-1]), "--out", "merged", *COURSE_OPTIONS]) == 0
    finally:
        os.chdir(cwd)
    printed = capsys.readouterr().out
    assert "merged 3 shard(s): 7 submission(s)" in printed
    one, merged = whole / "grades", whole / "merged"
    a = json.loads((one / "gradebook.json").read_text())
    b = json.loads((merged / "gradebook.json").read_text())
    assert without_measured(a) == without_measured(b)
    # the course was applied, once: a late row, an override, a flag
    late = {r["submission"]: r for r in b}["partial_bayes"]
    assert late["days_late"] == 2 and late["final"] == pytest.approx(late["total"] * 0.8)
    assert {r["submission"]: r for r in b}["wrong_bayes"]["overrides"]
    assert any("lab mismatch" in f for r in b for f in r["flags"])
    for name in ("gradebook.csv", "canvas.csv", "moodle.csv"):
        assert (one / name).read_text() == (merged / name).read_text(), name
    feedback = sorted(p.name for p in (one / "feedback").iterdir())
    assert feedback == sorted(p.name for p in (merged / "feedback").iterdir())
    for f in feedback:
        assert (one / "feedback" / f).read_text() == (merged / "feedback" / f).read_text()
    assert (merged / "report.html").is_file()


def _shards_copy(graded, tmp_path) -> list[Path]:
    base, _ = graded
    copies = []
    for s in sorted((base / "grades").iterdir()):
        shutil.copytree(s, tmp_path / s.name)
        copies.append(tmp_path / s.name)
    return copies


def _merge_error(capsys, *args) -> str:
    assert main(["merge", *map(str, args)]) == 2
    return capsys.readouterr().err


def _edit(path: Path, change) -> None:
    data = json.loads(path.read_text())
    change(data)
    path.write_text(json.dumps(data))


def test_merge_names_missing_and_duplicated_shards(graded, tmp_path, capsys):
    s1, s2, s3 = _shards_copy(graded, tmp_path)
    err = _merge_error(capsys, s1, s3, "--out", tmp_path / "m")
    assert "missing shard(s) 2 of 3" in err and "--shard 2/3" in err
    err = _merge_error(capsys, s1, s2, s3, s2, "--out", tmp_path / "m")
    assert "shard 2/3 given twice" in err
    assert not (tmp_path / "m" / "gradebook.csv").exists()


def test_merge_refuses_shards_of_other_graders(graded, tmp_path, capsys):
    s1, s2, s3 = _shards_copy(graded, tmp_path)
    state = s2 / ".robolab-state.json"
    lab = next(iter(json.loads(state.read_text())["entries"].values()))["result"]["lab"]

    def regrade(data):
        for e in data["entries"].values():
            if e["result"]["lab"] == lab:
                e["grader"] = "0123456789abcdef"

    _edit(state, regrade)
    _edit(s2 / "shard.json", lambda d: d.update(robolab="9.9.9"))
    err = _merge_error(capsys, s1, s2, s3, "--out", tmp_path / "m")
    assert f"lab {lab!r} was graded by different graders" in err
    assert "robolab 9.9.9" in err and "shard 2/3" in err


def test_merge_refuses_overlapping_unfinished_and_foreign_shards(graded, tmp_path, capsys):
    s1, s2, s3 = _shards_copy(graded, tmp_path)
    # a submission of shard 1 also in shard 2
    name, member = next(iter(json.loads((s1 / "shard.json").read_text())["members"].items()))
    _edit(s2 / "shard.json", lambda d: d["members"].update({name: member}))
    err = _merge_error(capsys, s1, s2, s3, "--out", tmp_path / "m")
    assert f"submission {name} is in shard 1/3" in err
    # a shard that was interrupted before finishing its slice
    s1, s2, s3 = _shards_copy(graded, tmp_path / "again")
    _edit(s3 / ".robolab-state.json", lambda d: d["entries"].popitem())
    err = _merge_error(capsys, s1, s2, s3, "--out", tmp_path / "m")
    assert "shard 3/3" in err and "has not finished: 1 of" in err
    # a shard of another batch (other files or N)
    _edit(s3 / "shard.json", lambda d: d.update(batch="another"))
    err = _merge_error(capsys, s1, s2, s3, "--out", tmp_path / "m")
    assert "cut from different batches" in err
    # a folder that is no shard at all, and an --out that is a grading batch
    err = _merge_error(capsys, s1, graded[1] / "grades", "--out", tmp_path / "m")
    assert "is not a shard's output" in err
    s1, s2, s3 = _shards_copy(graded, tmp_path / "third")
    err = _merge_error(capsys, s1, s2, s3, "--out", graded[1] / "grades")
    assert "holds a grading batch" in err


def test_shard_option_errors_are_one_line(tmp_path, capsys):
    nb = EXAMPLES / "bayes" / "correct.ipynb"
    assert main(["grade", str(nb), "--shard", "4/3", "--out", str(tmp_path / "g")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--shard 4/3" in err


def test_the_recipe_script_needs_a_slice(tmp_path):
    env = {
        k: v
        for k, v in os.environ.items()
        if k not in ("JOB_COMPLETION_INDEX", "SLURM_ARRAY_TASK_ID")
    }
    done = subprocess.run(
        ["sh", str(SCRIPT)],
        env={**env, "SHARDS": "2"},
        cwd=tmp_path,
        capture_output=True,
        text=True,
    )
    assert done.returncode == 2 and "no slice" in done.stderr
