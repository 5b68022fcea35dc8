"""Before/after of issue 29's second pass: another checkout's MCL and FastSLAM beside this one.

Loads ``solutions/mcl.py``, ``solutions/landmark_pf.py``, ``solutions/fastslam.py`` and
``robolab/geometry.py`` of another checkout (``OLD``, for example a clone of main before
the change) as separate modules next to this checkout's, checks that both give the
same particles, weights and maps bit for bit, and times them interleaved in one process
(best of N rounds, process CPU time): MCL's step and its parts at 5 000 and 100 000
particles x 60 beams, and the FastSLAM step at 1000 particles x 100 landmarks. The old
modules use this checkout's other library modules (the compiled kernels, the table cache)
but the other checkout's ``robolab/fieldsum.py`` when it has one, so the figures are those
of the changed modules alone. With ``ROBOLAB_RAYCAST=numpy`` both sides run the numpy
path (the grading worker's).

Run: ``python benchmarks/before_after.py OLD`` (without ``OLD`` it prints this line and exits).
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import timing  # before numpy: one BLAS thread

# isort: split
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from robolab.fiducials import FiducialRobot  # noqa: E402
from robolab.plotting import mcl as mclplot  # noqa: E402
from solutions import fastslam as fs  # noqa: E402
from solutions import landmark_pf as lpf  # noqa: E402
from solutions import mcl  # noqa: E402

SIZES = timing.sized(((5000, 60), (100_000, 6)), ((200, 1),))
FASTSLAM = timing.sized((1000, 100, 30, 5), (20, 10, 3, 1))  # particles, landmarks, steps, rounds


def _load(path: Path, name: str):
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


def old_modules(old: Path):
    """The other checkout's mcl, landmark_pf and fastslam, using its own geometry (and
    its own field sum, for MCL's look-up, when it has one)."""
    geometry = _load(old / "robolab" / "geometry.py", "old_geometry")
    resample = _load(old / "solutions" / "landmark_pf.py", "old_landmark_pf")
    old_mcl = _load(old / "solutions" / "mcl.py", "old_mcl")
    old_fs = _load(old / "solutions" / "fastslam.py", "old_fastslam")
    modules = [old_mcl, old_fs, resample]
    if (old / "robolab" / "fieldsum.py").exists() and hasattr(old_mcl, "pose_table_sum"):
        fieldsum = _load(old / "robolab" / "fieldsum.py", "old_fieldsum")
        old_mcl.pose_table_sum = fieldsum.pose_table_sum
        modules.append(fieldsum)
    for module in modules:
        for name in ("wrap_angle", "compose", "angle_diff"):
            if hasattr(module, name):
                setattr(module, name, getattr(geometry, name))
    old_mcl.low_variance_resample = resample.low_variance_resample
    return old_mcl, resample, old_fs


def mcl_rows(old_mcl, old_lpf):
    data = mclplot.load_localization()
    field = mcl.likelihood_field(data.grid, 0.1, 2.0)
    scan = data.scan(100)
    prm = {"alphas": (0.1,) * 4, "z_hit": 0.9, "z_rand": 0.1, "max_beams": 60,
           "laser_pose": data.laser_pose, "force_update": True}
    o0, o1 = data.odom[99], data.odom[100]

    def contenders(particles, weights, pred, w):
        fns = {}
        for tag, m, r in (("before", old_mcl, old_lpf), ("after", mcl, lpf)):
            fns[tag, "step"] = lambda m=m: m.mcl_step(
                particles, weights, o0, o1, scan, field, prm, np.random.default_rng(1)
            )
            fns[tag, "motion"] = lambda m=m: m.sample_motion_model_odometry(
                particles, o0, o1, prm["alphas"], np.random.default_rng(2)
            )
            fns[tag, "likelihood"] = lambda m=m: m.likelihood_field_model(scan, pred, field, prm)
            fns[tag, "resample"] = lambda r=r: r.low_variance_resample(
                pred, w, np.random.default_rng(3)
            )
        return fns

    rows = []
    for n, rounds in SIZES:
        rng = np.random.default_rng(0)
        particles = mcl.init_uniform(data.grid, n, rng)
        weights = np.full(n, 1.0 / n)
        pred = mcl.sample_motion_model_odometry(particles, o0, o1, prm["alphas"], rng)
        w = mcl.normalize_log_weights(mcl.likelihood_field_model(scan, pred, field, prm))
        fns = contenders(particles, weights, pred, w)
        for part in ("step", "motion", "likelihood", "resample"):
            a, b = fns["before", part](), fns["after", part]()
            a, b = (a[:2], b[:2]) if part == "step" else ((a,), (b,))
            assert all(np.array_equal(x, y) for x, y in zip(a, b, strict=True)), part
        best = timing.interleaved(fns, rounds)
        rows += [(f"MCL {part}, {n} particles", best["before", part], best["after", part])
                 for part in ("step", "motion", "likelihood", "resample")]
    return rows


def fastslam_rows(old_fs):
    m, k, n_steps, rounds = FASTSLAM
    run = FiducialRobot(seed=0, n_fiducials=k, n_steps=n_steps).to_run()
    steps = [(run.commands[t], run.observations(t)) for t in range(n_steps)]
    rng = np.random.default_rng(5)
    state = fs.init_particles(m, k, run.x0, init="prior")
    state["means"] = run.fiducials[None] + rng.normal(0.0, 0.2, (m, k, 2))
    state["covs"][:] = 0.04 * np.eye(2)
    state["seen"][:] = True
    state["poses"] = run.x0 + rng.normal(0.0, [0.05, 0.05, 0.01], (m, 3))

    def replay(module):
        s, r = state, np.random.default_rng(6)
        for u, z in steps:
            s = module.fastslam_step(s, u, z, run.Q, run.Qt, r, dt=run.dt)
        return s

    a, b = replay(old_fs), replay(fs)
    assert all(np.array_equal(a[key], b[key]) for key in a), "FastSLAM states differ"
    best = timing.interleaved({"before": lambda: replay(old_fs), "after": lambda: replay(fs)},
                              rounds)
    return [(f"FastSLAM step, {m} x {k}", best["before"] / n_steps, best["after"] / n_steps)]


def main() -> None:
    if len(sys.argv) < 2:
        print("benchmarks/before_after.py OLD: times another checkout's MCL and FastSLAM "
              "beside this one's (give the checkout's path)")
        return
    pinned = timing.pin_to_one_core()
    old_mcl, old_lpf, old_fs = old_modules(Path(sys.argv[1]).resolve())
    rows = mcl_rows(old_mcl, old_lpf) + fastslam_rows(old_fs)
    print(f"before ({sys.argv[1]}) / after (this checkout), same bits checked; {pinned}; "
          f"{timing.load_average()}; process CPU time, interleaved, best of the rounds")
    print(f"{'what':36s} {'before [ms]':>12s} {'after [ms]':>11s} {'before/after':>13s}")
    for name, before, after in rows:
        print(f"{name:36s} {before * 1e3:12.3f} {after * 1e3:11.3f} {before / after:12.2f}x")


if __name__ == "__main__":
    main()
