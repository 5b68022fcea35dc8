"""Submissions that modify their inputs or return aliases lose those tests' points when graded.

The labs whose hidden tests check it (``grep -n "shares_memory\\|must not modify\\|not
modified" tests/labs``): frames (transform_points keeps its input), landmark_pf
(move_particles keeps its input; low_variance_resample returns copies that do
not alias), fastslam (predict_poses keeps its input; fastslam_step neither
modifies nor aliases the state). bayes, beam_model, demo, ekf_mapping, mcl and
odometry_mapping have no such test.

Each mutant is the solved notebook with one exercise wrapped: the wrapper
returns the reference's values but changes its input by one ulp in place, or
returns views of its input. Graded through the real path, the tests that
check inputs and aliasing must fail, as they do in-process, and the tests of
the other exercises (except those calling the mutated one) still pass.
"""

from __future__ import annotations

import nbformat
import pytest

from robolab.grading.running.runner import grade_all
from tests.grading.loading.fidelity_variants import Cell, Variant, solved_cells

pytestmark = pytest.mark.slow

#: Nudges the first argument by one ulp, in place, after computing the right answer.
NUDGE_INPUT = """\
out = _{name}_impl(*args, **kwargs)
first = args[0]
if isinstance(first, np.ndarray) and first.flags.writeable:
    first[...] = np.nextafter(first, np.inf)
return out
"""

#: Resampled particles as views of the input (one broadcast row, or a list of row views).
RESAMPLE_VIEWS = """\
out = np.asarray(_{name}_impl(*args, **kwargs))
particles = args[0]
idx = [int(np.flatnonzero((particles == row).all(axis=1))[0]) for row in out]
if len(set(idx)) == 1:
    return np.broadcast_to(particles[idx[0]], out.shape)
return [particles[i] for i in idx]
"""

#: The step's landmark arrays written into the input state and returned: modified and aliased.
STATE_ALIASES = """\
out = _{name}_impl(*args, **kwargs)
state = args[0]
for key in ("means", "covs"):
    if np.shape(state[key]) == np.shape(out[key]):
        state[key][...] = out[key]
        out[key] = state[key]
return out
"""

MUTANTS = {
    "frames": {"transform_points": NUDGE_INPUT},
    "landmark_pf": {"move_particles": NUDGE_INPUT, "low_variance_resample": RESAMPLE_VIEWS},
    "fastslam": {"predict_poses": NUDGE_INPUT, "fastslam_step": STATE_ALIASES},
}

#: The hidden tests that check inputs and aliasing, which the mutants must fail.
CHECKING_TESTS = {
    "frames": {"test_transform_points_invariants"},
    "landmark_pf": {
        "test_move_particles_without_noise_is_exact",
        "test_low_variance_resample_returns_copies_that_do_not_alias",
    },
    "fastslam": {
        "test_predict_poses_wraps_heading_and_keeps_input",
        "test_fastslam_step_resampling_copies_landmarks_without_aliasing",
    },
}


#: Exercises that call a mutated exercise (their tests may fail with it).
USERS = {"frames": set(), "landmark_pf": {"particle_filter"}, "fastslam": {"fastslam"}}


def mutant(lab: str) -> Variant:
    cells, exercises = solved_cells(lab)
    out = []
    for position, cell in enumerate(cells):
        source = cell.source
        for name in exercises.get(position, []):
            if name in MUTANTS[lab]:
                source = source.replace(f"\ndef {name}(", f"\ndef _{name}_impl(")
                body = MUTANTS[lab][name].format(name=name)
                source += f"\n\ndef {name}(*args, **kwargs):\n" + "".join(
                    f"    {line}\n" for line in body.splitlines()
                )
        out.append(Cell("import numpy as np\n" + source, cell.tags))
    return Variant("aliasing-mutant", lab, out)


@pytest.fixture(scope="module")
def results(tmp_path_factory):
    folder = tmp_path_factory.mktemp("aliasing")
    paths = []
    for lab in MUTANTS:
        path = folder / f"{lab}.ipynb"
        nbformat.write(mutant(lab).notebook(), str(path))
        paths.append(path)
    return dict(zip(MUTANTS, grade_all(paths, jobs=2, progress=False), strict=True))


@pytest.mark.parametrize("lab", list(MUTANTS))
def test_modifying_inputs_or_returning_aliases_loses_exactly_those_tests(results, lab):
    result = results[lab]
    assert not result.errors and not result.fatal, result.errors
    failed = {t.nodeid.rsplit("::", 1)[-1].split("[")[0] for t in result.tests if not t.passed}
    # Tests of functions that call the mutated one (particle_filter calls move_particles)
    # may fail too; the tests that check inputs and aliasing must.
    assert CHECKING_TESTS[lab] <= failed, {
        t.nodeid: t.message[:200] for t in result.tests if not t.passed
    }
    mutated = set(MUTANTS[lab])
    assert all(
        t.passed for t in result.tests if t.exercise not in mutated and t.exercise not in USERS[lab]
    ), [t.nodeid for t in result.tests if not t.passed]
