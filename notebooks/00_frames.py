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
#     lab: frames
# ---

# %% [markdown]
# # Lab 00 — Bags and frames
#
# Every later lab reads laser scans and odometry that a robot recorded, and every one of
# them has to put a laser reading *somewhere*: in front of the laser, on the robot, in
# the world. This lab is about exactly that, and nothing else.
#
# The setting is ROS's AMCL localization node. AMCL, when it is not run on
# a live robot, is fed by a function `processBag` that opens a recorded **bag**, keeps the
# messages of two topics, `/tf` and `base_scan`, and re-publishes them in time order, as
# if the robot were driving now:
#
# ```cpp
# std::vector<std::string> topics = {"/tf", "base_scan"};
# rosbag::View view(bag, rosbag::TopicQuery(topics));
# BOOST_FOREACH(rosbag::MessageInstance const msg, view) {
#     if (tf_msg = msg.instantiate<tf2_msgs::TFMessage>())        tf_pub.publish(tf_msg);
#     else if (scan_msg = msg.instantiate<sensor_msgs::LaserScan>()) laser_pub.publish(scan_msg);
#     else ROS_WARN_STREAM("Unsupported message type: " << msg.getTopic());
# }
# ```
#
# You will
#
# 1. open the bundled bag with `robolab.bag`, list its topics and replay it like `processBag`;
# 2. learn the ROS conventions for units and frames (REP-103, REP-105);
# 3. write three functions: `scan_to_cartesian` (a scan's endpoints in the laser frame),
#    `transform_points` (points from one frame into another) and `pose_at` (the robot's
#    pose at a scan's time, between two odometry messages);
# 4. place one scan in three frames, then a minute of scans in the map, once with odometry
#    and once with the true pose, and see why odometry alone does not make a map.
#
# After each exercise a check cell tests your code on a worked example (the grader's
# hidden tests check more, including bad input and the bag itself).

# %%
import matplotlib.pyplot as plt
import numpy as np
from scipy import ndimage

from robolab import DATA_DIR
from robolab.bag import BagReader, laser_pose_in_base
from robolab.geometry import angle_diff, compose, wrap_angle
from robolab.maps import load_map
from robolab.plotting import plot_map
from robolab.plotting.frames import plot_message_timeline, plot_scan_cloud, plot_scan_in_frames
from robolab.validation import as_array, check_positive
from robolab.checks import frames as checks

# %% [markdown]
# ## 1. What is in the bag?
#
# A ROS bag is a log of **messages**, each published on a **topic** (a name such as
# `/base_scan`) with a **type** (such as `sensor_msgs/LaserScan`) and a time. The bundled
# `data/mapping.bag` was written by the workbook's simulator (`robolab.sim`, see
# `data/README.md`): a robot drives 80 s through an office while it records its laser,
# its wheel odometry, its transforms and, because it is a simulation, the true pose.
#
# `BagReader.topics` lists what the bag holds without reading the messages.

# %%
bag = BagReader(DATA_DIR / "mapping.bag")
for name, info in bag.topics.items():
    print(f"{name:15s} {info.msgtype:28s} {info.count:5d} messages")

# %% [markdown]
# The topic list says how many messages, not how often. `bag.messages(topics)` iterates
# over the messages in time order, with the time each was recorded, exactly like
# `rosbag::View`. Read them all once and compute each topic's rate,
# $(N - 1) / (t_{last} - t_{first})$.

# %%
record_times = {}
for topic, stamp, msg in bag.messages():
    record_times.setdefault(topic, []).append(stamp)
record_times = {topic: np.array(times) for topic, times in record_times.items()}

start = min(times[0] for times in record_times.values())
print(f"{'topic':15s} {'messages':>8s} {'first [s]':>10s} {'last [s]':>9s} {'rate [Hz]':>10s}")
for topic, times in sorted(record_times.items()):
    rate = (len(times) - 1) / (times[-1] - times[0])
    print(f"{topic:15s} {len(times):8d} {times[0] - start:10.2f} {times[-1] - start:9.2f} {rate:10.1f}")

# %%
ax = plot_message_timeline(record_times, start=start, duration=0.5,
                           title="The first 0.5 s of mapping.bag, one tick per message")

# %% [markdown]
# `/tf` carries two kinds of transform (we will meet both in section 2), which is why it
# ticks at 20 Hz + 10 Hz = 30 Hz.
#
# Now replay the bag the way `processBag` does: keep `/tf` and `base_scan` (without the
# leading slash, as AMCL's `processBag` writes it: `robolab.bag` matches topic names with or without
# it) and dispatch on each message's type. Instead of re-publishing, count what each
# message carries.

# %%
counts = {"tf2_msgs/msg/TFMessage": 0, "sensor_msgs/msg/LaserScan": 0}
edges = {}
for topic, stamp, msg in bag.messages(["/tf", "base_scan"]):
    if msg.__msgtype__ == "tf2_msgs/msg/TFMessage":        # tf_pub.publish(tf_msg)
        counts[msg.__msgtype__] += 1
        for transform in msg.transforms:
            edge = (transform.header.frame_id, transform.child_frame_id)
            edges[edge] = edges.get(edge, 0) + 1
    elif msg.__msgtype__ == "sensor_msgs/msg/LaserScan":   # laser_pub.publish(scan_msg)
        counts[msg.__msgtype__] += 1
        last_scan = msg
    else:
        print("Unsupported message type:", topic)
print(counts)
for (parent, child), n in edges.items():
    print(f"/tf edge {parent} -> {child}: {n} transforms")
print(f"a LaserScan: frame {last_scan.header.frame_id!r}, {len(last_scan.ranges)} ranges, "
      f"angles {last_scan.angle_min:.3f} .. {last_scan.angle_max:.3f} rad, "
      f"range {last_scan.range_min:.2f} .. {last_scan.range_max:.2f} m")

# %% [markdown]
# Working message by message is how a live node sees the world. For analysis it is easier
# to have whole arrays; `robolab.bag` gives typed views:
#
# - `bag.scans(topic)` → `Scans` with `stamps (T,)`, `ranges (T, B)`, `angles (B,)`,
#   `range_min`, `range_max`, `frame_id`;
# - `bag.odometry(topic)` → `PoseTrack` with `stamps (T,)` and `poses (T, 3)` of
#   `child_frame_id` in `frame_id`;
# - `bag.tf()` → the tree of every transform seen on `/tf`.

# %%
bag.preload()  # read every typed topic in one pass
scans = bag.scans("/base_scan")
odom = bag.odometry("/odom")
truth = bag.odometry("/ground_truth")
tf = bag.tf()
bag.close()

t0 = scans.stamps[0]
print(f"scans: {scans.ranges.shape} ranges in frame {scans.frame_id!r}")
print(f"odom:  {odom.poses.shape} poses of {odom.child_frame_id!r} in {odom.frame_id!r}")
print(f"truth: {truth.poses.shape} poses of {truth.child_frame_id!r} in {truth.frame_id!r}")
print("tf frames:", tf.frames)

# %% [markdown]
# **Question 1.** `processBag` replays only `/tf` and `base_scan`; this bag also has `/odom`
# and `/ground_truth`. Where does AMCL get the robot's motion from, if not from `/odom`?
# Why would replaying `/ground_truth` to a localizer defeat the purpose of the experiment?
#
# *Your answer here.*

# %% [markdown]
# ## 2. Units and frames: REP-103 and REP-105
#
# ROS writes its conventions down as *REPs* (ROS Enhancement Proposals). Two matter here.
#
# **REP-103, standard units and coordinate conventions.**
# SI units: metres, seconds, radians (so a laser's ranges are in metres and its angles in
# radians). Frames are right-handed; on a robot body **x points forward, y to the left,
# z up**. A rotation about z (yaw) is positive **counter-clockwise** seen from above. A
# planar pose is $(x, y, \theta)$; the workbook wraps $\theta$ to $[-\pi, \pi)$.
#
# **REP-105, coordinate frames for mobile platforms.** Three frames form a chain
# `map → odom → base_link`:
#
# - `base_link` is rigidly attached to the robot. Sensors have their own frames fixed to it;
#   here the laser's `base_laser_link` sits 10 cm ahead of `base_link`.
# - `odom` is a world-fixed frame in which the robot's pose comes from **odometry** (wheel
#   encoders, IMU). The pose in `odom` is **continuous** — it never jumps, so it is the right
#   frame for short-term, local decisions — but it **drifts**: every small error in the
#   measured wheel motion is integrated and never corrected.
# - `map` is a world-fixed frame in which the robot's pose should not drift, because a
#   localizer (AMCL, lab 05) corrects it against the map. The price: when a correction
#   arrives, the pose in `map` can **jump**.
#
# Each frame has one parent, so a localizer does not publish `map → base_link`; it publishes
# the correction `map → odom` that makes the chain come out right. This bag has no
# `map → odom` (finding it is localization's job); the simulator started the odometry at the
# robot's true starting pose, so the first `/ground_truth` pose is `odom` in `map`.
#
# A pose *of a child frame in a parent frame* is also the transform that takes points from
# the child into the parent. The laser's mount is the transform `base_link → base_laser_link`
# on `/tf`:

# %%
mount = laser_pose_in_base(tf, scans.frame_id)   # base_link -> base_laser_link
map_from_odom = truth.poses[0]                    # odom in map (see above)
print("laser in base_link:", mount)
print("odom in map:       ", map_from_odom)

# %% [markdown]
# **Question 2.** A robot must stop before an obstacle its laser sees 0.5 m ahead, and later
# drive to a room at the other end of the building. In which frame (`odom` or `map`)
# should it reason about each of the two, and why? What could go wrong with the other choice?
#
# *Your answer here.*

# %% [markdown]
# ## 3. A scan in the laser frame
#
# A `sensor_msgs/LaserScan` is a list of ranges $r_i$ measured along beams at angles
# $\alpha_i = \text{angle\_min} + i \cdot \text{angle\_increment}$, counter-clockwise from the
# laser's x axis. Beam $i$ ends at
#
# $$p_i = \begin{pmatrix} r_i \cos\alpha_i \\ r_i \sin\alpha_i \end{pmatrix}
# \qquad \text{(Probabilistic Robotics, Table 6.3, line 5, with the laser at the origin).}$$
#
# Not every number in `ranges` is a measurement. The message says a reading is valid only
# within `[range_min, range_max]`; drivers report "no return" as `inf` (REP-117: nothing in
# range), as `NaN`, or as `0`. A reading of exactly `range_max` is the scanner saying that
# nothing came back (a *max-range reading*, the beam model's $p_{max}$ of lab 02), not a wall
# at `range_max`: robolab, like AMCL and gmapping, counts it as no return. So a real return
# is finite, positive and within $[\text{range\_min}, \text{range\_max})$. Those must be **dropped, never turned into points**: an `inf`
# turned into a point is a point at infinity, a `0` becomes a wall inside the robot.

# %%
k = 300
r = scans.ranges.ravel()
print(f"scan {k} at t = {scans.stamps[k] - t0:.1f} s: {scans.beams} beams")
print(f"over the whole bag: {np.mean(np.isinf(r)):.1%} inf, {np.mean(np.isnan(r)):.1%} NaN, "
      f"{np.mean(r == 0):.1%} zero, {np.mean(r < scans.range_min):.2%} below range_min, "
      f"{np.mean(r == scans.range_max):.1%} exactly range_max")


# %% [markdown]
# ### Exercise 1 — `scan_to_cartesian(ranges, angles, range_min, range_max)`
#
# Build a boolean mask of the valid beams — finite, positive, within
# $[\text{range\_min}, \text{range\_max})$: a reading equal to `range_min` is a return, one
# equal to `range_max` is not — and compute the endpoints of those beams only,
# without a Python loop over beams (`np.isfinite`, `np.cos`, `np.sin`, `np.column_stack`).
# Comparisons with NaN are `False`, so NaN falls out of the mask by itself (wrap the mask
# in `with np.errstate(invalid="ignore"):` to silence numpy's warning). Raise `ValueError`
# when `angles` does not hold one angle per range or when the limits are not
# $0 \le \text{range\_min} < \text{range\_max}$; `robolab.validation.as_array` and
# `check_positive` help.

# %% tags=["exercise"]
def scan_to_cartesian(ranges, angles, range_min, range_max):
    r"""Endpoints of a laser scan's valid beams, in the laser's own frame.

    Beam :math:`i` with range :math:`r_i` at angle :math:`\alpha_i` ends at

    .. math::

        p_i = (r_i \cos\alpha_i,\; r_i \sin\alpha_i)

    (Probabilistic Robotics, Table 6.3, line 5, with the sensor at the origin).
    As ``sensor_msgs/LaserScan`` specifies, a reading is a real return only if
    it is finite, positive and within ``[range_min, range_max)``; everything
    else (0, ``inf``, NaN, too short, too long) means "no return" and is dropped,
    never turned into a hit. A reading of exactly ``range_max`` is a max-range
    reading (a failed return), not a wall at ``range_max``.

    Parameters
    ----------
    ranges : array_like, shape (B,)
        Measured ranges in metres, raw (may hold 0, ``inf`` and NaN).
    angles : array_like, shape (B,)
        Beam angles in radians, counter-clockwise from the laser's x axis.
    range_min, range_max : float
        The scanner's valid range interval in metres, ``0 <= range_min < range_max``.

    Returns
    -------
    numpy.ndarray, shape (P, 2)
        ``(x, y)`` in metres of the ``P <= B`` valid beams, in beam order;
        shape ``(0, 2)`` when no beam is valid.

    Raises
    ------
    ValueError
        If ``ranges`` is not 1-D, ``angles`` does not have one finite angle per
        range, or the range limits are not finite with ``0 <= range_min < range_max``.
    TypeError
        If an argument is not numeric.
    """
    # YOUR CODE HERE
    raise NotImplementedError


# %%
checks.check_scan_to_cartesian(scan_to_cartesian)


# %% [markdown]
# Why drop a reading of exactly `range_max`? This simulated laser reports a *failed* return
# (a black or glassy surface) as exactly `range_max` — the beam model's $p_{max}$ of lab 02.
# Placed on a map, such a reading would draw a phantom wall 8 m away, through real walls.
# Your `scan_to_cartesian` already drops them; when we build pictures of the world below,
# `usable_ranges` also marks them as no return explicitly, so the pictures do not depend on
# that one comparison:

# %%
def usable_ranges(ranges, range_max):
    # Readings at range_max are failures in this bag: treat them as no return (NaN).
    ranges = np.asarray(ranges, dtype=float)
    return np.where(ranges < range_max, ranges, np.nan)


laser_points = scan_to_cartesian(usable_ranges(scans.ranges[k], scans.range_max), scans.angles,
                                 scans.range_min, scans.range_max)
print(f"scan {k}: {len(laser_points)} of {scans.beams} beams are returns")


# %% [markdown]
# ## 4. From one frame to another
#
# A pose $(x_c, y_c, \theta)$ of a child frame in its parent says where the child's origin is
# and how it is turned. A point $p$ given in the child frame is, in the parent frame,
#
# $$p^{parent} = R(\theta)\, p^{child} + t, \qquad
# R(\theta) = \begin{pmatrix} \cos\theta & -\sin\theta \\ \sin\theta & \cos\theta \end{pmatrix},
# \quad t = \begin{pmatrix} x_c \\ y_c \end{pmatrix}:$$
#
# first rotate (the child's axes are turned by $\theta$), then shift by the child's origin.
# Chaining frames chains transforms: laser → `base_link` with the mount, then `base_link` →
# `odom` with the odometry pose.
#
# ### Exercise 2 — `transform_points(points, pose)`
#
# Write it with numpy only, for all points at once. For `P` points `(P, 2)` and one pose
# `(3,)` the result is `(P, 2)`; for `N` poses `(N, 3)` it is `(N, P, 2)` — the same points
# seen from `N` frames. Broadcasting does both if you keep the pose's angle as a column:
# `np.cos(pose[..., 2])[..., None]` is `(1,)` for one pose and `(N, 1)` for many, and
# `pose[..., 0:1]` likewise. Raise `ValueError` for points that are not `(P, 2)` and poses
# that are not `(3,)` or `(N, 3)`. (`robolab.geometry.transform_points` is the library's
# version; write your own, then compare.)

# %% tags=["exercise"]
def transform_points(points, pose):
    r"""Express points given in a child frame in its parent frame.

    .. math::

        \begin{pmatrix} x' \\ y' \end{pmatrix} =
        \begin{pmatrix} \cos\theta & -\sin\theta \\ \sin\theta & \cos\theta \end{pmatrix}
        \begin{pmatrix} x \\ y \end{pmatrix} +
        \begin{pmatrix} x_c \\ y_c \end{pmatrix}

    where ``pose = (x_c, y_c, theta)`` is the child frame's pose in the parent
    (e.g. the laser in ``base_link``, or ``base_link`` in ``odom``). Rotate
    first, then translate.

    Parameters
    ----------
    points : array_like, shape (P, 2)
        Points in the child frame, metres.
    pose : array_like, shape (3,) or (N, 3)
        The child frame's pose ``(x, y, theta)`` in the parent frame (metres,
        radians); ``N`` poses transform the same points ``N`` times.

    Returns
    -------
    numpy.ndarray, shape (P, 2) for one pose, (N, P, 2) for ``N`` poses
        The points in the parent frame.

    Raises
    ------
    ValueError
        If ``points`` is not ``(P, 2)`` or ``pose`` is not ``(3,)`` or
        ``(N, 3)``, or either holds NaN or infinity.
    TypeError
        If an argument is not numeric.
    """
    # YOUR CODE HERE
    raise NotImplementedError


# %%
checks.check_transform_points(transform_points)


# %% [markdown]
# ## 5. The pose at the scan's time
#
# The laser and the odometry are separate devices: scans come at 10 Hz, odometry at 20 Hz,
# and their stamps need not coincide. To place a scan, we need the robot's pose **at the
# scan's stamp**, interpolated between the two odometry messages around it — that is what
# tf2 does on every `lookupTransform`. For $t_k \le t \le t_{k+1}$ and
# $s = (t - t_k) / (t_{k+1} - t_k)$:
#
# $$x(t) = x_k + s\,(x_{k+1} - x_k), \qquad y(t) = y_k + s\,(y_{k+1} - y_k),$$
#
# $$\theta(t) = \operatorname{wrap}\!\big(\theta_k + s\,\operatorname{wrap}(\theta_{k+1} - \theta_k)\big).$$
#
# The heading needs care: from $\theta_k = 3.1$ to $\theta_{k+1} = -3.1$ the robot turned
# 0.08 rad counter-clockwise across the $\pm\pi$ seam, not 6.2 rad clockwise; interpolating
# the raw numbers would swing it through 0. `wrap` of the difference gives the short way.
# Outside $[t_0, t_{T-1}]$ there is nothing to interpolate: like tf2's
# `ExtrapolationException`, refuse.
#
# ### Exercise 3 — `pose_at(stamps, poses, t)`
#
# Vectorized over many `t`: `np.searchsorted(stamps, t, side="right") - 1` gives, for every
# `t`, the index $k$ of the message before it (clip it to `[0, T - 2]` so that `t = t_{T-1}`
# uses the last interval). Use `robolab.geometry.wrap_angle` and `angle_diff` for the
# heading. Raise `ValueError` when the stamps are not strictly increasing, when `poses` is
# not `(T, 3)`, and when a `t` lies outside the stamps.

# %% tags=["exercise"]
def pose_at(stamps, poses, t):
    r"""Pose at time(s) ``t`` between recorded poses (odometry, TF): linear interpolation.

    For :math:`t_k \le t \le t_{k+1}` and :math:`s = (t - t_k) / (t_{k+1} - t_k)`,

    .. math::

        x(t) &= x_k + s\,(x_{k+1} - x_k), \qquad y(t) = y_k + s\,(y_{k+1} - y_k), \\
        \theta(t) &= \operatorname{wrap}\big(\theta_k + s\,
            \operatorname{wrap}(\theta_{k+1} - \theta_k)\big),

    so the heading turns the short way round: from 3.1 to -3.1 rad it passes
    through :math:`\pi`, not through 0. This is what tf2 does when a scan's
    stamp falls between two ``/tf`` messages. Times outside the recorded span
    raise instead of extrapolating (tf2's ``ExtrapolationException``).

    Parameters
    ----------
    stamps : array_like, shape (T,)
        Times of the recorded poses in seconds, strictly increasing.
    poses : array_like, shape (T, 3)
        Recorded poses ``(x, y, theta)`` in metres and radians.
    t : float or array_like, shape (K,)
        Query time(s) in seconds, within ``[stamps[0], stamps[-1]]``.

    Returns
    -------
    numpy.ndarray, shape (3,) for a scalar ``t``, (K, 3) otherwise
        Interpolated poses, ``theta`` wrapped to ``[-pi, pi)``. At a recorded
        stamp the recorded pose is returned; a track of one pose (``T = 1``) is
        valid, and answers that pose at its stamp.

    Raises
    ------
    ValueError
        If ``stamps`` is empty, not 1-D, not strictly increasing or not finite;
        ``poses`` is not ``(T, 3)`` and finite; ``t`` is not a finite scalar or
        1-D array; or a ``t`` lies outside ``[stamps[0], stamps[-1]]``.
    TypeError
        If an argument is not numeric.
    """
    # YOUR CODE HERE
    raise NotImplementedError


# %%
checks.check_pose_at(pose_at)

# %% [markdown]
# Here is the seam, and the naive interpolation of the raw numbers for comparison:

# %%
seam_stamps = np.array([0.0, 1.0])
seam_poses = np.array([[0.0, 0.0, 3.1], [1.0, 0.0, -3.1]])
t = np.linspace(0.0, 1.0, 101)
fig, ax = plt.subplots(figsize=(7, 3.5))
ax.plot(t, pose_at(seam_stamps, seam_poses, t)[:, 2], label="pose_at: shortest arc (through pi)")
ax.plot(t, np.interp(t, seam_stamps, seam_poses[:, 2]), "--", label="np.interp of raw theta (through 0)")
ax.axhline(np.pi, color="gray", lw=0.5)
ax.axhline(-np.pi, color="gray", lw=0.5)
ax.legend(loc="center left", fontsize="small")
ax.set(title="Interpolating a heading across the seam", xlabel="time t [s]", ylabel="heading theta [rad]");

# %% [markdown]
# The blue curve only *looks* like a jump: at 0.5 s the heading passes $\pi$, which is the same
# direction as $-\pi$, and wrapping to $[-\pi, \pi)$ writes it as $-\pi$. The robot turned
# 0.08 rad. The dashed curve has it spin 6.2 rad clockwise, almost a full turn, in one second.

# %% [markdown]
# ## 6. One scan, three frames
#
# Scan `k` in the laser frame, then in `base_link` (through the mount), then in `odom`
# (through the odometry pose at the scan's stamp). Chaining the two transforms is the
# same as one transform with the composed pose `compose(base_in_odom, mount)`.

# %%
base_in_odom = pose_at(odom.stamps, odom.poses, scans.stamps[k])
base_points = transform_points(laser_points, mount)
odom_points = transform_points(base_points, base_in_odom)
assert np.allclose(odom_points, transform_points(laser_points, compose(base_in_odom, mount)))
print("base_link in odom at the scan:", np.round(base_in_odom, 3))

axes = plot_scan_in_frames(laser_points, base_points, odom_points, mount, base_in_odom,
                           laser_frame=scans.frame_id, stamp=scans.stamps[k] - t0)

# %% [markdown]
# In the laser frame the robot is at the origin looking along x. In `base_link` the points
# shift by the 10 cm mount (hard to see at this scale, but not negligible: section 8). In
# `odom` the whole picture turns by the robot's heading and moves to where odometry believes
# the robot is.
#
# ## 7. A minute of scans, placed with odometry
#
# Now every other scan of the first 60 s: the robot's pose at each scan's stamp from
# odometry, moved into `map` with `map_from_odom`, then the mount; each scan's endpoints go
# through `transform_points`, coloured by time. Next to it the same scans placed with the
# **true** pose, which only a simulator can give. The map underneath is `data/office.yaml`.

# %%
grid = load_map(DATA_DIR / "office.yaml")
DURATION = 60.0
chosen = np.flatnonzero(scans.stamps - t0 <= DURATION)[::2]
stamps = scans.stamps[chosen]

robot_odom = compose(map_from_odom, pose_at(odom.stamps, odom.poses, stamps))  # (K, 3) in map
robot_true = pose_at(truth.stamps, truth.poses, stamps)
laser_odom = compose(robot_odom, mount)
laser_true = compose(robot_true, mount)


def place_scans(laser_poses):
    # The usable endpoints of every chosen scan in the map, and each point's time.
    clouds, times = [], []
    for i, pose in zip(chosen, laser_poses):
        ranges = usable_ranges(scans.ranges[i], scans.range_max)
        points = scan_to_cartesian(ranges, scans.angles, scans.range_min, scans.range_max)
        clouds.append(transform_points(points, pose))
        times.append(np.full(len(points), scans.stamps[i] - t0))
    return np.concatenate(clouds), np.concatenate(times)


cloud_odom, time_odom = place_scans(laser_odom)
cloud_true, time_true = place_scans(laser_true)
print(f"{len(chosen)} scans, {len(cloud_odom)} endpoints")

# %%
fig, (ax_odom, ax_true) = plt.subplots(1, 2, figsize=(13, 5.2))
plot_scan_cloud(cloud_odom, time_odom, ax_odom, grid=grid, path=robot_odom, vmax=DURATION,
                title="Scans placed with raw odometry (first 60 s)")
plot_scan_cloud(cloud_true, time_true, ax_true, grid=grid, path=robot_true, vmax=DURATION,
                title="The same scans placed with the true pose")
fig.tight_layout()

# %% [markdown]
# The walls placed with the true pose are sharp lines on the map's walls. The dots scattered
# over the free space are the laser's *short* and *random* readings (a person walking by, a
# reflection): the beam model of lab 02 is built to expect them.
#
# How far is each endpoint from the nearest wall of the map? `scipy.ndimage.distance_transform_edt`
# gives, for every free cell, the distance to the nearest occupied cell; look it up at the
# cell each endpoint falls in.

# %%
wall_distance = ndimage.distance_transform_edt(~grid.occupied) * grid.resolution  # metres


def near_wall_fraction(points, within=0.1):
    # Fraction of the points whose cell is within `within` metres of a wall cell.
    cells = grid.world_to_cell(points)
    on_map = grid.contains_cell(cells)
    distance = np.full(len(points), np.inf)
    distance[on_map] = wall_distance[cells[on_map, 0], cells[on_map, 1]]
    return np.mean(distance <= within)


for label, cloud, times in [("odometry", cloud_odom, time_odom), ("truth", cloud_true, time_true)]:
    parts = [f"{near_wall_fraction(cloud[(times >= a) & (times < a + 10)]):.0%}" for a in range(0, 60, 10)]
    print(f"{label:9s} endpoints within 10 cm of a wall, per 10 s: {' '.join(parts)}")

# %%
robot_odom_all = compose(map_from_odom, pose_at(odom.stamps, odom.poses, truth.stamps))
position_error = np.hypot(*(robot_odom_all[:, :2] - truth.poses[:, :2]).T)
heading_error = np.degrees(np.abs(np.angle(np.exp(1j * (robot_odom_all[:, 2] - truth.poses[:, 2])))))

fig, ax = plt.subplots(figsize=(9, 3.5))
ax.plot(truth.stamps - t0, position_error, label="position error [m]")
ax.plot(truth.stamps - t0, heading_error / 10, label="heading error [10 deg]")
ax.legend(loc="upper left")
ax.set(title="Raw odometry against ground truth, mapping.bag", xlabel="time since start [s]",
       ylabel="error [m] / [10 deg]");

# %% [markdown]
# **Question 3.** Why does the odometry-placed cloud smear while the true one stays sharp?
# Where in the route does the smear grow fastest? Using the error plot, explain why a small
# heading error does more damage to far walls than a position error of the same size
# (hint: how far does a point at range $r$ move when the heading is off by $\delta\theta$?).
#
# *Your answer here.*

# %% [markdown]
# ## 8. Forgetting the laser's mount
#
# What if the `base_link → base_laser_link` transform is left out, i.e. the scan is treated as
# if the laser sat at the robot's centre? Compare the first 2 s, before odometry has drifted,
# placed with and without the mount.

# %%
early = stamps - t0 <= 2.0
with_mount, _ = place_scans(laser_odom[early])
without_mount, _ = place_scans(robot_odom[early])
for label, cloud in [("with the mount", with_mount), ("without the mount", without_mount)]:
    print(f"{label:18s}: {near_wall_fraction(cloud, within=0.05):.0%} of the endpoints within 5 cm of a wall")

fig, axes = plt.subplots(1, 2, figsize=(14, 5))
for ax, cloud, label in zip(axes, [with_mount, without_mount], ["with", "without"]):
    plot_map(grid, ax, title=f"First 2 s placed {label} the laser mount")
    ax.scatter(cloud[:, 0], cloud[:, 1], s=1, c="tab:red", linewidths=0)
    ax.set_aspect("equal", adjustable="box")
    ax.set_xlim(-0.5, 5.0)
    ax.set_ylim(4.0, 8.0)
fig.tight_layout()

# %% [markdown]
# **Question 4.** What happens if you forget the `base_link → laser` transform? Which walls in
# the figure move and which stay put, and why does it depend on the wall's direction relative
# to the robot's heading? Some robots mount the laser *backwards*: the Neato of Olin College's
# bags has it at $(-0.10, 0, \pi)$. What would forgetting that mount do?
#
# *Your answer here.*

# %% [markdown]
# **Question 5.** Instead of interpolating, one could take the odometry message *nearest* to the
# scan's stamp. With odometry at 20 Hz, how far off in time can that be? For this robot
# (at most 0.6 m/s and 1.5 rad/s), how far can a wall 5 m away then be misplaced? Is
# interpolation worth it here, and when would it matter more?
#
# *Your answer here.*
