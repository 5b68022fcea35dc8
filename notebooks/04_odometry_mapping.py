# ---
# jupyter:
#   jupytext:
#     cell_metadata_filter: tags
#     notebook_metadata_filter: kernelspec,language_info,robolab
#     text_representation:
#       extension: .py
#       format_name: percent
#       format_version: '1.3'
#   kernelspec:
#     display_name: Python 3
#     language: python
#     name: python3
#   language_info:
#     name: python
#   robolab:
#     lab: odometry_mapping
# ---

# %% [markdown]
# # Lab 04 — Mapping with raw odometry
#
# A robot drove 80 s through an office, recording laser scans (`/base_scan`, 360 beams, 10 Hz) and its
# **wheel odometry** (`/odom`). If we knew exactly where the robot was at every scan, building a map would be easy:
# draw every beam into a grid. This lab does exactly that with the **simple counting algorithm**,
# trusting the odometry as if it were the truth, and then asks the lab's
# question: **why does the resulting map differ so much from reality?**
#
# The bundled bag was made by robolab's simulator, so it also has what a real robot never has: the
# **ground-truth** pose (`/ground_truth`) and the true floor plan (`data/office.yaml`). We use them to *prove*
# the answer rather than guess it.
#
# Steps:
#
# 1. from a scan and a pose to beam endpoints in the world (`scan_endpoints`);
# 2. the grid cells a beam passes through (`beam_cells`);
# 3. the counting map: hits / visits per cell (`counting_map_update`, `occupancy_from_counts`) and
#    clipping at 0.5 (`clip_map`);
# 4. the map from raw odometry at 2 s, 8 s and 20 s, then from the ground truth;
# 5. odometry drift against time: the answer, with evidence;
# 6. one step further: the log-odds occupancy grid with the inverse range sensor model (Probabilistic Robotics,
#    Tables 9.1 and 9.2).
#
# Units: metres, radians, seconds. Frames follow ROS: `map`, `odom`, `base_link`, `base_laser_link`.

# %%
import numpy as np
import matplotlib.pyplot as plt
from scipy import ndimage
from robolab.progress import progress_bar

from robolab import DATA_DIR
from robolab.bag import BagReader, laser_pose_in_base
from robolab.geometry import anchor_odometry, compose, transform_points, wrap_angle
from robolab.maps import OccupancyGrid, load_map
from robolab.raycast import cast_rays
from robolab.plotting import plot_map, plot_scan
from robolab.plotting.odometry_mapping import (plot_beam_cells, plot_map_comparison, plot_map_snapshots, plot_odometry_drift,
                                               plot_trajectories)
from robolab.checks import odometry_mapping as checks

SNAPSHOTS = [2.0, 8.0, 20.0]  # seconds: the three snapshots of section 4

# %% [markdown]
# ## 0. The data
#
# `BagReader` gives typed views of the bag: `scans(topic)` (ranges `(T, B)`, beam `angles`, `range_min`,
# `range_max`, `frame_id`), `odometry(topic)` (a `PoseTrack` with `.at(t)` interpolation) and `tf()`. The laser is
# mounted on the robot at a fixed pose `base_link -> base_laser_link`, which `laser_pose_in_base` reads from `/tf`.
#
# Odometry lives in its own frame `odom`, which starts where the robot started. We anchor it in the map frame at
# the **first ground-truth pose** (the robot knows where it starts, nothing more):
#
# $$
# x^{map}_t = x^{map}_0 \oplus \left( (x^{odom}_0)^{-1} \oplus x^{odom}_t \right) ,
# $$
#
# with $\oplus$ the pose composition (`robolab.geometry.compose`): the motion odometry measured since the start,
# put onto the first true pose (`robolab.geometry.anchor_odometry`). The simulated odometry starts at the origin of
# `odom`; a real robot's does not, and $x^{map}_0 \oplus x^{odom}_t$ would then report drift that is not there.
# From then on, odometry is on its own.

# %%
with BagReader(DATA_DIR / "mapping.bag") as bag:
    print({name: info.count for name, info in bag.topics.items()})
    scans = bag.scans("/base_scan")
    odom = bag.odometry("/odom")
    truth = bag.odometry("/ground_truth")
    laser_offset = laser_pose_in_base(bag.tf(), scans.frame_id)

t = scans.stamps - scans.stamps[0]                        # seconds since the first scan
true_poses = truth.at(scans.stamps)                        # map -> base_link at every scan
odom_poses = anchor_odometry(odom.at(scans.stamps), truth.at(scans.stamps[0]))  # raw odometry, anchored at the start
true_map = load_map(DATA_DIR / "office.yaml")
print(f"{len(scans)} scans of {scans.beams} beams over {t[-1]:.0f} s; range [{scans.range_min:.2f}, {scans.range_max:.1f}] m")
print("laser mount base_link -> laser (x, y, theta):", laser_offset)
print("map:", true_map.shape, "cells of", true_map.resolution, "m")
plot_trajectories(true_poses, odom_poses, true_map, title="The run: ground truth and raw odometry over the true map");


# %% [markdown]
# A scan is plain data. We pass one scan to the exercise functions as a dict:

# %%
def scan_at(i):
    """Scan i of the bag as the dict the exercises take."""
    return {"ranges": scans.ranges[i], "angles": scans.angles,
            "range_min": scans.range_min, "range_max": scans.range_max}

r = scans.ranges
print("no return (inf):", np.isinf(r).mean().round(3), " at range_max:", (r == scans.range_max).mean().round(3),
      " below range_min:", (r < scans.range_min).mean().round(4))


# %% [markdown]
# ## 1. Beam endpoints in the world
#
# The laser sits at $x_s = x_t \oplus x_{laser}$ (robot pose composed with the mounting pose). Beam $k$ with range
# $z_k$ at angle $\theta_k$ in the laser frame ends at (the endpoint equation of the likelihood field model,
# Probabilistic Robotics Table 6.3, line 4):
#
# $$
# \begin{pmatrix} x_k \\ y_k \end{pmatrix} = \begin{pmatrix} x_s \\ y_s \end{pmatrix}
# + z_k \begin{pmatrix} \cos(\theta_s + \theta_k) \\ \sin(\theta_s + \theta_k) \end{pmatrix}.
# $$
#
# Only real returns are endpoints: a `sensor_msgs/LaserScan` range is a **hit** when it is finite and
# `range_min <= r < range_max`. NaN, 0, `inf` ("nothing in range", REP-117), ranges below `range_min` and
# max-range readings (`r >= range_max`) are no obstacle, and must never become one.
# Use `compose` and `transform_points` from `robolab.geometry`.

# %% tags=["exercise"]
def scan_endpoints(scan, pose, laser_offset):
    r"""World coordinates of the endpoints of a scan's hit beams.

    The laser sits at ``x_s = pose (+) laser_offset`` (pose composition); beam
    ``k`` with range :math:`z_k` at angle :math:`\theta_k` (laser frame) ends at

    .. math::

        \begin{pmatrix} x_k \\ y_k \end{pmatrix} =
        \begin{pmatrix} x_s \\ y_s \end{pmatrix} + z_k
        \begin{pmatrix} \cos(\theta_s + \theta_k) \\ \sin(\theta_s + \theta_k) \end{pmatrix}

    (the endpoint equation of the likelihood field model, Probabilistic
    Robotics Table 6.3, line 4, with the sensor's mounting pose folded into
    :math:`x_s`).

    Only **hit** beams give endpoints: finite ranges with ``r > 0`` and
    ``range_min <= r < range_max``. NaN, 0, inf, ranges below ``range_min`` and
    max-range readings (``r >= range_max``: nothing detected) are left out; they
    are never turned into obstacles.

    Parameters
    ----------
    scan : dict
        ``ranges`` (B,) metres, ``angles`` (B,) radians in the laser frame,
        ``range_min``, ``range_max`` metres.
    pose : array_like, shape (3,)
        Robot (``base_link``) pose ``(x, y, theta)`` in the world.
    laser_offset : array_like, shape (3,)
        Laser pose in ``base_link`` (the ``base_link -> laser`` transform).

    Returns
    -------
    numpy.ndarray, shape (P, 2)
        ``(x, y)`` of each hit beam's endpoint, in the scan's beam order
        (``P`` = number of hit beams, possibly 0).

    Raises
    ------
    ValueError
        ``pose`` or ``laser_offset`` not three numbers, or a scan whose ranges and
        angles differ in length.
    """
    # YOUR CODE HERE
    raise NotImplementedError


# %%
checks.check_scan_endpoints(scan_endpoints)

# %%
i = int(np.searchsorted(t, 20.0))
pts = scan_endpoints(scan_at(i), true_poses[i], laser_offset)
ax = plot_map(true_map, title=f"Scan at t = {t[i]:.1f} s, placed with the true pose")
ax.plot(pts[:, 0], pts[:, 1], ".", color="tab:red", ms=3, label="beam endpoints")
ax.plot(*true_poses[i, :2], "o", color="tab:green", label="robot")
ax.legend(loc="upper right");


# %% [markdown]
# ## 2. The cells a beam passes through
#
# To count "this beam went through that cell", we need every grid cell a beam touches. We work in **continuous
# cell coordinates** `(row, col)` = `grid.world_to_map(xy)[..., ::-1]`: cell $(i, j)$ is the square
# $[i, i+1) \times [j, j+1)$, so `floor` of a point's coordinates is the cell `grid.world_to_cell` gives.
# The beam is the segment $p(t) = s + t\,(e - s)$, $t \in [0, 1]$, and its cells are
#
# $$
# C(s, e) = \{(\lfloor p_r(t) \rfloor, \lfloor p_c(t) \rfloor) : t \in [0, 1]\},
# $$
#
# every cell that contains a point of the segment (a *supercover*; Bresenham's line skips cells the beam clips at
# a corner). The first cell is `floor(s)`, the last `floor(e)`: **the end cell is included**.
#
# One way (Amanatides & Woo's traversal, swept column by column): in column $j$ the beam is at parameters
# $t$ with $j \le p_c(t) < j + 1$; over that interval $p_r$ goes from one value to another, and the rows in
# between are the column's cells. Do it for all beams at once: `np.repeat` and `np.cumsum` turn per-beam counts
# into flat arrays without a Python loop. Return the cells `(N, 2)` and, for each, the index of its beam `(N,)`.

# %% tags=["exercise"]
def beam_cells(start_cell, end_cell):
    r"""Every grid cell a straight beam touches (exact supercover), for many beams at once.

    A beam is the closed segment :math:`p(t) = s + t\,(e - s)`, :math:`t \in [0, 1]`,
    in continuous cell coordinates ``(row, col)`` (``grid.world_to_map(xy)[..., ::-1]``).
    Cell ``(i, j)`` is the half-open square ``[i, i+1) x [j, j+1)``, the
    convention of :meth:`~robolab.maps.OccupancyGrid.world_to_cell`; the beam's
    cells are exactly

    .. math:: C(s, e) = \{ (\lfloor p_r(t) \rfloor, \lfloor p_c(t) \rfloor) : t \in [0, 1] \},

    every cell that contains a point of the segment and no other. The first cell
    is ``floor(s)`` and the last ``floor(e)``: the **end cell is included** (the
    counting algorithm counts it as visited and hit). A beam through a grid
    corner gets only the cells that own a point of it under the half-open
    convention (no extra corner neighbours); a beam along a grid line lies in
    the cells above / right of the line.

    The traversal is exact (not sampled): for each column ``j`` the beam
    crosses, the parameter interval on which ``j <= p_c(t) < j + 1`` gives the
    beam's row span in that column, and the cells are those rows (the column
    sweep form of Amanatides & Woo's grid traversal, 1987). Vectorized over
    beams and cells with no Python loop. Cells outside a map are returned too;
    the caller keeps those inside.

    Parameters
    ----------
    start_cell : array_like, shape (2,) or (B, 2)
        Beam start(s) ``(row, col)`` in continuous cell coordinates; one start
        is shared by all beams (the laser).
    end_cell : array_like, shape (2,) or (B, 2)
        Beam end(s) ``(row, col)``.

    Returns
    -------
    cells : numpy.ndarray of int64, shape (N, 2)
        ``(row, col)`` of the touched cells, beam after beam, each beam's cells
        ordered from its start cell to its end cell, no cell twice within a beam.
    beam : numpy.ndarray of int64, shape (N,)
        Index of the beam each cell belongs to (non-decreasing).

    Raises
    ------
    ValueError
        Shapes other than (2,) / (B, 2), mismatched B, non-finite coordinates.
    """
    # YOUR CODE HERE
    raise NotImplementedError


# %%
checks.check_beam_cells(beam_cells)

# %%
start = np.array([1.3, 0.6])
ends = np.array([[6.7, 8.2], [7.5, 1.1], [0.2, 6.4], [4.4, 4.6]])
cells, beam = beam_cells(start, ends)
plot_beam_cells(start, ends, cells, beam, title="Cells touched by four beams from (1.3, 0.6) (supercover)");


# %% [markdown]
# ## 3. The simple counting algorithm
#
# Every cell keeps two counters: **visits**, how many beams went through it or ended in it, and **hits**, how many
# ended in it. The map is the frequency with which a beam that reached a cell was reflected there (the
# "reflection map", Probabilistic Robotics section 9.2):
#
# $$
# p(m_i) \approx \frac{\text{hits}_i}{\text{visits}_i}.
# $$
#
# For each beam of a scan taken from the laser pose $x_s$:
#
# * a **hit** ($\text{range\_min} \le z < \text{range\_max}$): every cell of `beam_cells` gets a visit; the end cell,
#   where the beam was reflected, gets a hit as well;
# * a **no-return** beam (`inf` or $z \ge \text{range\_max}$): nothing was reflected within range, so the cells up to
#   `range_max` get a visit and none a hit;
# * an **invalid** beam (NaN, $\le 0$, $<$ `range_min`): no information, ignored.
#
# Drop the cells outside the grid. `np.bincount` counts many (possibly repeated) cell indices at once.
# `pose` here is the **laser's** pose in the map frame, `compose(robot_pose, laser_offset)`. The grid is
# immutable: return new `hits, visits` arrays.

# %% tags=["exercise"]
def counting_map_update(hits, visits, scan, pose, grid):
    r"""Integrate one scan into the counting map (the simple counting algorithm).

    Every cell keeps two counters: ``visits``, how many beams passed through
    or ended in it, and ``hits``, how many beams ended in it. The map is

    .. math:: p(m_i) \approx \frac{\mathrm{hits}_i}{\mathrm{visits}_i},

    the frequency with which a beam that reached cell ``i`` was reflected
    there (the "reflection map" of Probabilistic Robotics, section 9.2).
    For each beam from the laser at ``pose``:

    * a **hit** (``range_min <= r < range_max``, finite): every cell of
      :func:`beam_cells` from the laser to the endpoint gets a visit, and the
      endpoint's cell (the last one) a hit as well;
    * a **no-return** beam (``+inf`` or ``r >= range_max``): the cells up to
      ``range_max`` get a visit and no cell a hit: free space, no obstacle;
    * an **invalid** beam (NaN, ``<= 0``, ``< range_min``): ignored.

    A cell counts at most once per beam, and many times per scan if several
    beams cross it. Cells outside the grid are dropped. Cells no beam reaches
    keep their counts exactly.

    Parameters
    ----------
    hits, visits : array_like, shape grid.shape
        Counts so far (non-negative; not modified).
    scan : dict
        ``ranges`` (B,), ``angles`` (B,), ``range_min``, ``range_max``.
    pose : array_like, shape (3,)
        The **laser's** pose in the map frame, ``compose(robot_pose, laser_offset)``.
    grid : robolab.maps.OccupancyGrid
        The map's geometry (shape, resolution, origin); its cell values are not used.

    Returns
    -------
    hits, visits : numpy.ndarray of float, shape grid.shape
        New arrays with this scan's counts added; ``hits <= visits`` holds
        cell by cell whenever it held before.
    """
    # YOUR CODE HERE
    raise NotImplementedError


# %%
checks.check_counting_map_update(counting_map_update)


# %% [markdown]
# The map itself: hits / visits where a beam came, and **unknown** (-1) where none did.

# %% tags=["exercise"]
def occupancy_from_counts(hits, visits):
    r"""The counting map: occupancy ``hits / visits``, unknown (-1) where no beam came.

    .. math::

        m_i = \begin{cases} \mathrm{hits}_i / \mathrm{visits}_i & \mathrm{visits}_i > 0 \\
                             -1 \ (\text{unknown}) & \mathrm{visits}_i = 0 \end{cases}

    Parameters
    ----------
    hits, visits : array_like, same shape
        Non-negative counts with ``hits <= visits``.

    Returns
    -------
    numpy.ndarray of float, same shape
        Values in [0, 1], or -1 (:data:`robolab.maps.UNKNOWN`) for never-visited
        cells: ready for ``grid.with_data(...)``.

    Raises
    ------
    ValueError
        Negative or non-finite counts, ``hits`` and ``visits`` of different shapes,
        or more hits than visits in a cell (a hit is also a visit).
    """
    # YOUR CODE HERE
    raise NotImplementedError


# %%
checks.check_occupancy_from_counts(occupancy_from_counts)


# %% [markdown]
# Clipping turns the counting map into a binary map at 0.5: below is free (0), at or above is occupied (1). Unknown stays unknown.
#
# $$
# \hat m_i = \begin{cases} 1 & m_i \ge 0.5 \\ 0 & 0 \le m_i < 0.5 \\ -1 & \text{unknown} \end{cases}
# $$

# %% tags=["exercise"]
def clip_map(occupancy, threshold=0.5):
    r"""Clip an occupancy map to 0 / 1 at ``threshold``; unknown stays -1.

    .. math::

        \hat m_i = \begin{cases} 1 & m_i \ge \tau \\ 0 & 0 \le m_i < \tau \\
                                  -1 & m_i = -1 \ (\text{unknown}) \end{cases}

    A value exactly at the threshold counts as occupied, as in
    :attr:`robolab.maps.OccupancyGrid.occupied`.

    Parameters
    ----------
    occupancy : array_like
        Occupancy in [0, 1], or -1 for unknown cells.
    threshold : float
        ``tau`` in [0, 1] (default 0.5).

    Returns
    -------
    numpy.ndarray of float, same shape
        Values in {-1, 0, 1}.

    Raises
    ------
    ValueError
        An occupancy outside [0, 1] other than -1 (unknown), a NaN, or a
        ``threshold`` outside [0, 1].
    """
    # YOUR CODE HERE
    raise NotImplementedError


# %%
checks.check_clip_map(clip_map)

# %% [markdown]
# ## 4. The map from raw odometry
#
# Now the whole bag: one `counting_map_update` for every second scan (the scans are 0.1 s apart, so two in a row see
# nearly the same walls; all of them would take twice as long for the same map) with the laser pose from
# **raw odometry**, keeping copies of the map at 2 s, 8 s and 20 s. The map has the geometry (resolution, origin) of the true floor plan, so the two
# can be compared cell by cell.

# %%
empty = true_map.with_data(np.full(true_map.shape, -1.0))  # geometry only

def build_counting_map(robot_poses, label, every=2):
    """Run the counting algorithm over the bag; return the final map and the maps at SNAPSHOTS."""
    laser_poses = compose(robot_poses, laser_offset)
    hits, visits = np.zeros(empty.shape), np.zeros(empty.shape)
    snaps = {}
    for i in progress_bar(range(0, len(scans), every), desc=label, unit="scan"):
        hits, visits = counting_map_update(hits, visits, scan_at(i), laser_poses[i], empty)
        for s in SNAPSHOTS:
            if s not in snaps and t[i] >= s:
                snaps[s] = empty.with_data(occupancy_from_counts(hits, visits))
    return empty.with_data(occupancy_from_counts(hits, visits)), snaps

odom_map, odom_snaps = build_counting_map(odom_poses, "raw odometry")


# %%
def upto(poses, s):
    return poses[t <= s]

maps = [odom_snaps[s] for s in SNAPSHOTS] + [odom_map]
labels = [f"t = {s:.0f} s" for s in SNAPSHOTS] + [f"t = {t[-1]:.0f} s (end)"]
paths = [upto(odom_poses, s) for s in SNAPSHOTS] + [odom_poses]
plot_map_snapshots(maps, labels, paths=paths, title="Counting map from raw odometry, without clipping")
plot_map_snapshots([m.with_data(clip_map(m.data)) for m in maps], labels, paths=paths,
                   title="Counting map from raw odometry, clipped at 0.5");

# %% [markdown]
# ## 5. The same bag with the ground-truth poses
#
# Same scans, same algorithm, only the poses change.

# %%
truth_map, truth_snaps = build_counting_map(true_poses, "ground truth")
plot_map_comparison(odom_map.with_data(clip_map(odom_map.data)), truth_map.with_data(clip_map(truth_map.data)),
                    left_title="raw odometry", right_title="ground-truth poses",
                    title="Clipped counting maps after the whole run (80 s)",
                    left_path=odom_poses, right_path=true_poses, true_path=true_poses);

# %% [markdown]
# How close is each map to the real walls? Count the occupied cells of a map that lie within one cell of a true wall
# (**precision**), and the true walls the robot could see that have an occupied cell within one cell (**recall**).
# "Could see" = where noise-free rays from the true laser poses end (`robolab.raycast.cast_rays` in the true map).

# %%
ring = np.ones((3, 3), dtype=bool)
near_true_wall = ndimage.binary_dilation(true_map.occupied, ring)
lp = compose(true_poses[::4], laser_offset)
z_true = cast_rays(true_map, lp, scans.angles, scans.range_max)
a = lp[:, 2:3] + scans.angles
ends = np.stack([lp[:, :1] + (z_true + 1e-6) * np.cos(a), lp[:, 1:2] + (z_true + 1e-6) * np.sin(a)], -1)
wall_cells = true_map.world_to_cell(ends[z_true < scans.range_max])
wall_cells = wall_cells[true_map.contains_cell(wall_cells)]
seen = np.zeros(true_map.shape, dtype=bool)
seen[wall_cells[:, 0], wall_cells[:, 1]] = True   # the true walls the laser could reach

def agreement(grid):
    occ = grid.data >= 0.5
    precision = (occ & near_true_wall).sum() / max(occ.sum(), 1)
    recall = (seen & ndimage.binary_dilation(occ, ring)).sum() / max(seen.sum(), 1)
    return precision, recall

for name, grid in [("raw odometry", odom_map), ("ground truth", truth_map)]:
    p, r = agreement(grid)
    print(f"{name:>13}: {p:6.1%} of occupied cells are on a true wall, {r:6.1%} of visible wall cells found")

# %% [markdown]
# ## 6. Why does the resulting map differ so much from reality?
#
# The scans are the same in both maps; only the poses differ. So compare the poses: the odometry's position and
# heading error against the ground truth, over time. The dotted lines mark the snapshot times.

# %%
plot_odometry_drift(t, true_poses, odom_poses, marks=SNAPSHOTS)
pos_err = np.hypot(*(odom_poses[:, :2] - true_poses[:, :2]).T)
head_err = np.degrees(np.abs(wrap_angle(odom_poses[:, 2] - true_poses[:, 2])))
for s in SNAPSHOTS + [t[-1]]:
    k = int(np.searchsorted(t, s))
    k = min(k, len(t) - 1)
    print(f"t = {t[k]:5.1f} s: position error {pos_err[k]:.2f} m, heading error {head_err[k]:.1f} deg, "
          f"a wall 5 m away is displaced by about {5 * np.radians(head_err[k]):.2f} m")


# %% [markdown]
# **Question 1.** Why does the resulting map differ so much from reality? Use the figures above as evidence:
# what grows with time, and why does a *heading* error of a few degrees hurt the map more than a position error of
# the same size in metres? Where in the odometry map do you see the same wall drawn several times?
#
# *Your answer here.*
#
# **Question 2.** A natural fix is "a more accurate robot pose generation, for example using the laser scanner as an
# additional localization tool". Which of the following labs does that, and what does it need that this lab did not
# have?
#
# *Your answer here.*
#
# **Question 3.** Even with the ground-truth poses, some walls are grey rather than black in the unclipped map, and
# there are light streaks *outside* the building. Which beams cause each? (Hint: look at beams that graze a wall
# at a shallow angle, and at the max-range readings.)
#
# *Your answer here.*

# %% [markdown]
# ## 7. One step further: log-odds occupancy grid mapping
#
# The counting map has no notion of how *sure* it is. Occupancy grid mapping (Probabilistic Robotics, Table 9.1)
# keeps for each cell the **log-odds** of being occupied and adds the evidence of each scan:
#
# $$
# l_{t,i} = l_{t-1,i} + \text{inverse\_sensor\_model}(m_i, x_t, z_t) - l_0,
# \qquad l = \log\frac{p}{1 - p}.
# $$
#
# The inverse range sensor model (Table 9.2) looks at each cell's centre from the laser pose $(x, y, \theta)$:
#
# $$
# r = \sqrt{(x_i - x)^2 + (y_i - y)^2}, \qquad \phi = \operatorname{atan2}(y_i - y, x_i - x) - \theta, \qquad
# k = \operatorname{argmin}_j |\phi - \theta_j|
# $$
#
# $$
# \text{inverse\_sensor\_model} = \begin{cases}
# l_0 & r > \min(z_{max}, z_k + \alpha/2) \text{ or } |\phi - \theta_k| > \beta/2 \\
# l_{occ} & z_k < z_{max} \text{ and } |r - z_k| < \alpha/2 \\
# l_{free} & r \le z_k
# \end{cases}
# $$
#
# with $\alpha$ the thickness of obstacles and $\beta$ the width of a beam (wrap angle differences with
# `wrap_angle`). A no-return beam is $z_k = z_{max}$; invalid beams are dropped before looking for the nearest one.
# Only cells within $z_{max} + \alpha/2$ of the laser can change: compute $r$, $\phi$ and $k$ for all of them at once
# (`np.searchsorted` on the sorted beam angles finds the nearest beam).

# %% tags=["exercise"]
def logodds_update(logodds, scan, pose, grid, inverse_sensor_model_params):
    r"""One step of occupancy grid mapping in log-odds form (Probabilistic Robotics, Table 9.1).

    For every cell :math:`m_i` in the perceptual field of the scan,

    .. math:: l_{t,i} = l_{t-1,i} + \mathrm{inverse\_sensor\_model}(m_i, x_t, z_t) - l_0 ,

    and other cells keep their value. The inverse range sensor model is Table
    9.2: with :math:`(x_i, y_i)` the centre of cell ``i`` and :math:`(x, y, \theta)`
    the laser pose,

    .. math::

        r &= \sqrt{(x_i - x)^2 + (y_i - y)^2}, \qquad
        \phi = \mathrm{wrap}(\operatorname{atan2}(y_i - y, x_i - x) - \theta) \\
        k &= \operatorname{argmin}_j |\mathrm{wrap}(\phi - \theta_j)| \\
        &\text{if } r > \min(z_{max}, z_k + \alpha/2) \text{ or } |\phi - \theta_k| > \beta/2:
            \ l_0 \ \text{(no information)} \\
        &\text{else if } z_k < z_{max} \text{ and } |r - z_k| < \alpha/2: \ l_{occ} \\
        &\text{else if } r \le z_k: \ l_{free}

    with :math:`z_{max}` = ``scan['range_max']``. A no-return beam (``+inf`` or
    ``r >= range_max``) is a reading :math:`z_k = z_{max}`: free up to the max
    range, never occupied. Invalid beams (NaN, ``<= 0``, ``< range_min``) are
    removed before the nearest-beam search. The evidence a scan adds does not
    depend on the map, so updates commute: the result after several scans is
    the prior plus the sum of each scan's evidence, in any order.

    Parameters
    ----------
    logodds : array_like, shape grid.shape
        Current log-odds :math:`l_{t-1}` (finite; not modified).
    scan : dict
        ``ranges`` (B,), ``angles`` (B,), ``range_min``, ``range_max``.
    pose : array_like, shape (3,)
        The **laser's** pose in the map frame.
    grid : robolab.maps.OccupancyGrid
        The map's geometry.
    inverse_sensor_model_params : dict
        ``l_occ``, ``l_free``, ``l_0`` (log-odds), ``alpha`` (obstacle thickness,
        metres, > 0), ``beta`` (beam width, radians, > 0); the notebook's
        ``PARAMS`` below is an example.

    Returns
    -------
    numpy.ndarray of float, shape grid.shape
        The updated log-odds :math:`l_t`, a new array.

    Raises
    ------
    ValueError
        ``logodds`` not of ``grid.shape`` or not finite, ``pose`` not three numbers,
        a missing key of ``inverse_sensor_model_params`` (or both ``alpha`` and
        ``alpha_cells``), ``alpha``, ``alpha_cells`` or ``beta`` <= 0.
    """
    # YOUR CODE HERE
    raise NotImplementedError


# %%
checks.check_logodds_update(logodds_update)


# %% [markdown]
# And back to a probability (Table 9.1, last line): $p(m_i) = 1 - \dfrac{1}{1 + \exp(l_i)}$. Beware of
# `exp` overflowing for large $|l|$.

# %% tags=["exercise"]
def logodds_to_probability(logodds):
    r"""Occupancy probability from log-odds (Probabilistic Robotics, Table 9.1, last line).

    .. math:: p(m_i) = 1 - \frac{1}{1 + \exp(l_i)}

    computed stably (no overflow for large ``|l|``; ``l = +-inf`` gives 1 / 0).

    Parameters
    ----------
    logodds : array_like
        Log-odds, any shape; NaN is rejected.

    Returns
    -------
    numpy.ndarray of float, same shape
        Probabilities in [0, 1]; 0.5 where the log-odds are 0.
    """
    # YOUR CODE HERE
    raise NotImplementedError


# %%
checks.check_logodds_to_probability(logodds_to_probability)

# %%
PARAMS = {"l_occ": np.log(0.7 / 0.3), "l_free": np.log(0.35 / 0.65), "l_0": 0.0,
          "alpha": 0.1, "beta": np.radians(2.0)}   # alpha two cells, beta two beam spacings

def build_logodds_map(robot_poses, label, every=8):
    laser_poses = compose(robot_poses, laser_offset)
    l = np.zeros(empty.shape)
    for i in progress_bar(range(0, len(scans), every), desc=label, unit="scan"):
        l = logodds_update(l, scan_at(i), laser_poses[i], empty, PARAMS)
    return empty.with_data(logodds_to_probability(l))

logodds_truth = build_logodds_map(true_poses, "log-odds, ground truth")
logodds_odom = build_logodds_map(odom_poses, "log-odds, raw odometry")
plot_map_comparison(logodds_odom, logodds_truth, left_title="raw odometry", right_title="ground-truth poses",
                    title="Log-odds occupancy grids (every 8th scan), p(occupied)",
                    left_path=odom_poses, right_path=true_poses);

# %% [markdown]
# **Question 4.** Compare the log-odds map from the ground-truth poses with the counting map. Which walls got
# sharper, and why (think of what $\alpha$ and the nearest-beam rule do to a beam that grazes a wall)? Does the
# log-odds map fix the raw-odometry map? What would?
#
# *Your answer here.*

# %% [markdown]
# ## 8. One step further: the Intel Research Lab, a real CARMEN log
#
# The Intel lab log holds 910 laser scans with the poses a SLAM system corrected them to, and the raw wheel
# odometry. We map it with your `logodds_update` twice, from every 8th scan: with the corrected poses, and with raw
# odometry anchored at the first corrected pose. Cells no beam reached stay unknown (`robolab.maps.from_logodds`). The data set is not
# part of robolab: `robolab.datasets.fetch("intel_lab")` downloads it (0.45 MB) when you are online.

# %%
from robolab.datasets import locate, read_carmen
from robolab.evaluation import occupancy_iou, occupied_distances
from robolab.realdata.mapping import carmen_poses, map_carmen

folder = locate("intel_lab")
if folder is None:
    print("The Intel lab log is not on disk: robolab.datasets.fetch('intel_lab') downloads it (0.45 MB).")
else:
    log = read_carmen(folder / "intel-corrected.log.gz")
    intel_params = {"l_occ": np.log(0.7 / 0.3), "l_free": np.log(0.35 / 0.65), "l_0": 0.0,
                    "alpha": 0.2, "beta": np.radians(2.0)}   # 0.1 m cells: alpha two cells
    corrected = map_carmen(log, logodds_update, intel_params, resolution=0.1, every=8)
    raw = map_carmen(log, logodds_update, intel_params, resolution=0.1, every=8,
                     poses=carmen_poses(log, "odometry"))
    fig, axes = plt.subplots(1, 2, figsize=(13, 6))
    plot_map(corrected, ax=axes[0], title="Intel lab, corrected poses")
    plot_map(raw, ax=axes[1], title="Intel lab, raw odometry")
    d = occupied_distances(raw, corrected)
    print(f"raw-odometry walls lie a median {np.median(d):.2f} m (90 %: {np.percentile(d, 90):.2f} m) from the "
          f"corrected map's; IoU of the walls within 0.2 m: {occupancy_iou(raw, corrected, 0.2):.2f}")

# %% [markdown]
# **Question 5.** The printed numbers compare the two Intel maps. Where in the raw-odometry map does the error
# come from: a few large jumps, or a slow drift? Which lab fixes it, and with what sensor?
#
# *Your answer here.*
