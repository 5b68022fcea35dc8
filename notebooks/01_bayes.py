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
#     lab: bayes
# ---

# %% [markdown]
# # Lab 01 — Bayes: the door problem and the discrete Bayes filter
#
# A robot rarely *knows* the state of the world; it holds a **belief**, a probability
# distribution over the states, and updates it with every measurement and every action.
# This lab builds that machinery from one line of probability theory:
#
# 1. **Bayes' rule** on a door problem: a sensor
#    reports $z = 42$; how likely is the door open?
# 2. **The discrete Bayes filter** (Probabilistic Robotics, Table 2.1 and its discrete
#    form, Table 4.1) on the book's door example of section 2.4.2.
# 3. A **histogram filter** that localizes a robot in a corridor with doors.
#
# You write three functions: `bayes_posterior`, `door_open_posterior` and
# `bayes_filter_step`. After each exercise a check cell tests your code on a worked
# example (the grader's hidden tests check more, including bad input).
# Throughout, a discrete belief is a numpy array of shape `(n,)` that sums to 1.

# %%
from fractions import Fraction

import matplotlib.pyplot as plt
import numpy as np

from robolab import plotting
from robolab.checks import bayes as checks


# %% [markdown]
# ## 1. The door problem, step by step
#
# The robot's sensor either detects a door as open or closed. We are given
#
# $$P(z = 42 \mid open) = \tfrac{2}{3}, \qquad P(z = 42 \mid \neg open) = \tfrac{1}{3}, \qquad P(open) = \tfrac{3}{5},$$
#
# and the door is either open or closed, so $P(\neg open) = 1 - P(open) = \tfrac{2}{5}$.
# We want $P(open \mid z = 42)$.
#
# **Step 1 — Bayes' rule for both states.**
#
# $$P(open \mid z) = \frac{P(z \mid open)\,P(open)}{P(z)}, \qquad
#   P(\neg open \mid z) = \frac{P(z \mid \neg open)\,P(\neg open)}{P(z)}.$$
#
# **Step 2 — eliminate the unknown $P(z)$.** Solving both for $P(z)$:
#
# $$P(z) = \frac{P(z \mid open)\,P(open)}{P(open \mid z)} = \frac{P(z \mid \neg open)\,P(\neg open)}{P(\neg open \mid z)}.$$
#
# **Step 3 — the posterior is a distribution too:** $P(\neg open \mid z) = 1 - P(open \mid z)$. Writing $p = P(open \mid z)$,
#
# $$\frac{1 - p}{p} = \frac{1}{p} - 1 = \frac{P(z \mid \neg open)\,P(\neg open)}{P(z \mid open)\,P(open)}.$$
#
# **Step 4 — solve for $p$.** With $x = P(z \mid \neg open)P(\neg open)$ and $y = P(z \mid open)P(open)$ this reads $\frac{1}{p} = \frac{x}{y} + 1$, so $p = \frac{y}{x + y}$:
#
# $$P(open \mid z) = \frac{P(z \mid open)\,P(open)}{P(z \mid open)\,P(open) + P(z \mid \neg open)\,P(\neg open)}
#   = \frac{\frac{2}{3}\cdot\frac{3}{5}}{\frac{2}{3}\cdot\frac{3}{5} + \frac{1}{3}\cdot\frac{2}{5}}
#   = \frac{6/15}{8/15} = \frac{3}{4}.$$
#
# The denominator is the **total probability** $P(z) = \sum_x P(z \mid x) P(x)$
# (Probabilistic Robotics, eq. 2.12): the normalizer, whose inverse the book calls $\eta$.

# %% [markdown]
# ### Exercise 1 — `bayes_posterior(likelihood, prior)`
#
# The same computation for any number of states $x \in \{0, \dots, n-1\}$ (Probabilistic Robotics, eq. 2.15):
#
# $$p(x_i \mid z) = \eta\, p(z \mid x_i)\, p(x_i), \qquad \eta = \Big(\sum_j p(z \mid x_j)\, p(x_j)\Big)^{-1}.$$
#
# In numpy: multiply elementwise, then divide by the sum. Then make the function
# refuse what is not a valid question, with a `ValueError` that names the argument:
# a prior that is not a probability vector, a negative likelihood, arrays of different
# shapes, and a measurement with $p(z) = 0$ (dividing $0/0$ would return NaN).
# `robolab.validation.check_probability_vector` and `robolab.validation.as_array`
# do most of the checking for you.

# %% tags=["exercise"]
def bayes_posterior(likelihood, prior):
    r"""Posterior of a discrete state after one measurement (Bayes' rule).

    .. math::

        p(x_i \mid z) = \eta \, p(z \mid x_i) \, p(x_i), \qquad
        \eta^{-1} = p(z) = \sum_j p(z \mid x_j) \, p(x_j)

    (Probabilistic Robotics, eq. 2.15, and line 4 of Table 2.1).

    Parameters
    ----------
    likelihood : array_like, shape (n,)
        ``likelihood[i] = p(z | x = i)``: non-negative, finite. It is a function
        of the state, not a distribution over it, so it need not sum to 1.
    prior : array_like, shape (n,)
        ``prior[i] = p(x = i)``: non-negative, sums to 1.

    Returns
    -------
    numpy.ndarray, shape (n,)
        ``p(x = i | z)``: non-negative, sums to 1.

    Raises
    ------
    ValueError
        If ``prior`` is not a probability vector, ``likelihood`` has a negative
        or non-finite entry, the shapes differ or are not 1-D, or ``p(z) = 0``
        (the likelihood is zero wherever the prior is non-zero).
    """
    # YOUR CODE HERE
    raise NotImplementedError


# %%
checks.check_bayes_posterior(bayes_posterior)


# %% [markdown]
# ### Exercise 2 — `door_open_posterior(p_z_given_open, p_z_given_closed, p_open)`
#
# The formula of step 4 for two states, with the three given numbers as arguments:
#
# $$P(open \mid z) = \frac{P(z \mid open)\,P(open)}{P(z \mid open)\,P(open) + P(z \mid \neg open)\,(1 - P(open))}.$$
#
# Write it with plain arithmetic (`*`, `+`, `-`, `/`) so that it works for floats
# *and* for `fractions.Fraction`, where it must give exactly `Fraction(3, 4)`.
# Raise `ValueError` for an argument outside $[0, 1]$ and when $P(z) = 0$.

# %% tags=["exercise"]
def door_open_posterior(p_z_given_open, p_z_given_closed, p_open):
    r"""Probability that the door is open after a measurement ``z`` (the door problem of section 1).

    With the two states open and :math:`\neg` open (closed), Bayes' rule and
    the total probability
    :math:`p(z) = p(z \mid open) p(open) + p(z \mid \neg open) (1 - p(open))` give

    .. math::

        p(open \mid z) = \frac{p(z \mid open) \, p(open)}
                              {p(z \mid open) \, p(open) + p(z \mid \neg open) \, (1 - p(open))}.

    For :math:`p(z \mid open) = 2/3`, :math:`p(z \mid \neg open) = 1/3` and
    :math:`p(open) = 3/5` this is 3/4 (Probabilistic Robotics, section 2.3).

    Parameters
    ----------
    p_z_given_open : float, Fraction or array_like
        :math:`p(z \mid open)`, in [0, 1].
    p_z_given_closed : float, Fraction or array_like
        :math:`p(z \mid \neg open)`, in [0, 1].
    p_open : float, Fraction or array_like
        The prior :math:`p(open)`, in [0, 1].

    Returns
    -------
    float, Fraction or numpy.ndarray
        :math:`p(open \mid z)`. Exact arithmetic is kept: three ``Fraction``
        arguments give a ``Fraction``. Array arguments broadcast.

    Raises
    ------
    ValueError
        If an argument lies outside [0, 1] or is NaN, or if :math:`p(z) = 0`.
    TypeError
        If an argument is not a number.
    """
    # YOUR CODE HERE
    raise NotImplementedError


# %%
checks.check_door_open_posterior(door_open_posterior)

# %% [markdown]
# With fractions the answer is exact, and the two-state formula agrees with the general one:

# %%
exact = door_open_posterior(Fraction(2, 3), Fraction(1, 3), Fraction(3, 5))
print("P(open | z = 42) =", exact)
print("as a vector over (open, closed):", bayes_posterior(np.array([2 / 3, 1 / 3]), np.array([3 / 5, 2 / 5])))

# %% [markdown]
# **Question 1.** The sensor reports $z = 42$ twice as often for an open door as for a
# closed one, yet the posterior is $3/4$, not $2/3$. Where does the difference come from?
# What would $P(open \mid z = 42)$ be with a prior of $1/2$, and with a prior of $0$?
#
# *Your answer here.*

# %% [markdown]
# ## 2. The discrete Bayes filter
#
# A robot also *acts*, and actions change the state. The Bayes filter (Probabilistic
# Robotics, Table 2.1) alternates a **prediction** with the action $u_t$ and a
# **correction** with the measurement $z_t$. For a discrete state (Table 4.1):
#
# $$\overline{bel}(x_t = i) = \sum_j p(x_t = i \mid u_t, x_{t-1} = j)\; bel(x_{t-1} = j) \qquad \text{(prediction)}$$
#
# $$bel(x_t = i) = \eta\; p(z_t \mid x_t = i)\; \overline{bel}(x_t = i) \qquad \text{(correction)}$$
#
# Store the action model as a matrix **indexed `[next, previous]`**:
# `action_model[i, j]` $= p(x_t = i \mid u_t, x_{t-1} = j)$. Column $j$ is the
# distribution of where state $j$ goes, so **every column sums to 1**, and the
# prediction is the matrix–vector product $\overline{bel} = A\, bel$. "Do nothing" is
# the identity. The correction is exactly `bayes_posterior`.
#
# The book's door example (section 2.4.2), with states ordered (open, closed):
#
# | | open | closed |
# |---|---|---|
# | $p(Z = \text{sense\_open} \mid X)$ | 0.6 | 0.2 |
# | $p(Z = \text{sense\_closed} \mid X)$ | 0.4 | 0.8 |
# | $p(X_t = \text{open} \mid \text{push}, X_{t-1})$ | 1 | 0.8 |
# | $p(X_t = \text{closed} \mid \text{push}, X_{t-1})$ | 0 | 0.2 |

# %%
SENSE_OPEN = np.array([0.6, 0.2])    # p(sense_open | open), p(sense_open | closed)
SENSE_CLOSED = np.array([0.4, 0.8])  # p(sense_closed | open), p(sense_closed | closed)
DO_NOTHING = np.eye(2)
PUSH = np.array([[1.0, 0.8],         # row = next state (open), column = previous state
                 [0.0, 0.2]])        # row = next state (closed)
print("column sums of PUSH:", PUSH.sum(axis=0))


# %% [markdown]
# ### Exercise 3 — `bayes_filter_step(belief, action_model, measurement_likelihood)`
#
# One prediction and one correction. Check that the action model is `(n, n)` with
# non-negative columns summing to 1 (a transposed matrix is the classic bug), and raise
# `ValueError` for the same bad inputs as in exercise 1.

# %% tags=["exercise"]
def bayes_filter_step(belief, action_model, measurement_likelihood):
    r"""One discrete Bayes filter step: predict with the action, correct with the measurement.

    Probabilistic Robotics, Table 2.1 (the Bayes filter) in its discrete form,
    Table 4.1 (the discrete Bayes filter):

    .. math::

        \overline{bel}(x_t = i) &= \sum_j p(x_t = i \mid u_t, x_{t-1} = j) \, bel(x_{t-1} = j)
            \quad\text{(prediction)} \\
        bel(x_t = i) &= \eta \, p(z_t \mid x_t = i) \, \overline{bel}(x_t = i)
            \quad\text{(correction)}

    In matrix form, :math:`\overline{bel} = A \, bel` and
    :math:`bel' = \eta \, (l \odot \overline{bel})`.

    Parameters
    ----------
    belief : array_like, shape (n,)
        :math:`bel(x_{t-1})`: non-negative, sums to 1.
    action_model : array_like, shape (n, n)
        The action's transition matrix, **indexed [next, previous]**:
        ``action_model[i, j] = p(x_t = i | u_t, x_{t-1} = j)``. Each *column*
        ``action_model[:, j]`` is the distribution of the next state from
        state ``j``, so every column sums to 1. "Do nothing" is the identity.
    measurement_likelihood : array_like, shape (n,)
        ``measurement_likelihood[i] = p(z_t | x_t = i)``: non-negative, finite;
        need not sum to 1.

    Returns
    -------
    numpy.ndarray, shape (n,)
        :math:`bel(x_t)`: non-negative, sums to 1.

    Raises
    ------
    ValueError
        If ``belief`` is not a probability vector, ``action_model`` is not
        ``(n, n)`` with non-negative columns summing to 1, the likelihood is not
        ``(n,)``, non-negative and finite, or the corrected belief is zero
        everywhere (``p(z_t) = 0``).
    """
    # YOUR CODE HERE
    raise NotImplementedError


# %%
checks.check_bayes_filter_step(bayes_filter_step)

# %% [markdown]
# ### The book's door example
#
# The robot starts knowing nothing, $bel(X_0) = (0.5, 0.5)$. Then $u_1$ = do nothing,
# $z_1$ = sense open; $u_2$ = push, $z_2$ = sense open. By hand:
#
# $$\overline{bel}(X_1) = (0.5,\ 0.5), \qquad bel(X_1) = \eta\,(0.6 \cdot 0.5,\ 0.2 \cdot 0.5) = (0.75,\ 0.25)$$
#
# $$\overline{bel}(X_2) = (1 \cdot 0.75 + 0.8 \cdot 0.25,\ 0 \cdot 0.75 + 0.2 \cdot 0.25) = (0.95,\ 0.05), \qquad
#   bel(X_2) = \eta\,(0.6 \cdot 0.95,\ 0.2 \cdot 0.05) = (0.983,\ 0.017)$$
#
# A likelihood of all ones carries no information, so `bayes_filter_step` with
# `np.ones(2)` returns the prediction $\overline{bel}$ alone.

# %%
bel = np.array([0.5, 0.5])
history = [("bel(X0)", bel.copy())]
for t, (u, z) in enumerate([(DO_NOTHING, SENSE_OPEN), (PUSH, SENSE_OPEN)], start=1):
    predicted = bayes_filter_step(bel, u, np.ones(2))
    bel = bayes_filter_step(bel, u, z)
    history += [(f"bel_bar(X{t})", predicted), (f"bel(X{t})", bel)]
for name, b in history:
    print(f"{name:12s} open = {b[0]:.3f}   closed = {b[1]:.3f}")
assert np.isclose(history[2][1][0], 0.75) and round(history[4][1][0], 3) == 0.983

# %%
fig, axes = plt.subplots(1, len(history), figsize=(12, 2.8), sharey=True)
for ax, (name, b) in zip(axes, history):
    plotting.plot_belief(b, ax=ax, tick_labels=["open", "closed"], title=name)
    ax.set_xlabel("door state")
    ax.set_ylim(0, 1)
axes[0].set_ylabel("probability")
fig.suptitle("Probabilistic Robotics 2.4.2: do nothing, sense open, push, sense open")
fig.tight_layout()

# %% [markdown]
# **Question 2.** Why does pushing raise the belief that the door is open *before*
# the second measurement arrives? If instead the robot never pushes and keeps sensing
# "open", does its belief ever reach 1? How many measurements does it take to exceed 0.99?
#
# *Your answer here.*

# %% [markdown]
# ## 3. A corridor with doors: the histogram filter
#
# The same filter localizes a robot. A cyclic corridor 25 m long is cut into cells of
# 0.5 m; the state is the cell the robot is in. Three doors sit at known places. Each
# step the robot is told to move 1 m forward; its wheels slip, so it moves 0.5, 1.0 or
# 1.5 m with probabilities 0.1, 0.8, 0.1. Its door detector says "door" with probability
# 0.8 in front of a door and 0.1 elsewhere.
#
# The action model is a **circulant** matrix: `action_model[i, j]` is the probability of
# moving from cell $j$ to cell $i = j + k \bmod n$ for $k$ cells of motion.

# %%
CELL = 0.5                                   # m
LENGTH = 25.0                                # m, cyclic
n = int(LENGTH / CELL)
x = (np.arange(n) + 0.5) * CELL              # cell centres, m
DOORS = [(3.0, 4.0), (7.0, 8.0), (17.0, 18.0)]  # door extents, m
at_door = np.zeros(n, dtype=bool)
for lo, hi in DOORS:
    at_door |= (x > lo) & (x < hi)

MOTION = {1: 0.1, 2: 0.8, 3: 0.1}            # cells moved -> probability (commanded 1 m = 2 cells)
move = sum(p * np.roll(np.eye(n), k, axis=0) for k, p in MOTION.items())
assert np.allclose(move.sum(axis=0), 1.0)

P_DOOR = np.where(at_door, 0.8, 0.1)         # p(z = door | x); p(z = wall | x) = 1 - P_DOOR
print(f"{n} cells, {at_door.sum()} of them in front of a door")

# %% [markdown]
# Simulate the robot (the truth the filter never sees) and run the filter: the first
# measurement is taken before any motion, so step 0 uses "do nothing".

# %%
rng = np.random.default_rng(7)
steps = 16
true_cell = 4                                # starts at 2.25 m; the filter does not know
bel = np.full(n, 1.0 / n)
beliefs = [bel.copy()]
truths = [true_cell]
seen = []
for t in range(steps):
    u = np.eye(n) if t == 0 else move
    if t > 0:
        true_cell = (true_cell + rng.choice(list(MOTION), p=list(MOTION.values()))) % n
    z = bool(rng.random() < P_DOOR[true_cell])
    bel = bayes_filter_step(bel, u, P_DOOR if z else 1.0 - P_DOOR)
    beliefs.append(bel)
    truths.append(true_cell)
    seen.append(z)
beliefs = np.array(beliefs)
print("measurements:", ["door" if z else "wall" for z in seen])
print(f"final: true x = {x[truths[-1]]:.2f} m, most likely x = {x[beliefs[-1].argmax()]:.2f} m,"
      f" bel = {beliefs[-1].max():.2f}")

# %%
shown = [0, 1, 2, 3, 5, 8, steps]
fig, axes = plt.subplots(len(shown), 1, figsize=(9, 11), sharex=True)
for ax, t in zip(axes, shown):
    for lo, hi in DOORS:
        ax.axvspan(lo, hi, color="tab:orange", alpha=0.25, lw=0)
    plotting.plot_belief(beliefs[t], positions=x, ax=ax, ylabel="bel(x)",
                         title=f"after step {t}" if t else "prior (uniform)")
    ax.axvline(x[truths[t]], color="k", ls="--", lw=1)
    ax.set_ylabel("bel(x)")
axes[-1].set_xlabel("position along the corridor x [m]")
fig.suptitle("Histogram filter in a corridor (orange: doors, dashed: true position)")
fig.tight_layout()

# %%
ax = plotting.new_axes("Belief over time", xlabel="position along the corridor x [m]",
                       ylabel="step t", equal=False, figsize=(9, 4))
im = ax.imshow(beliefs, origin="lower", aspect="auto", cmap="viridis",
               extent=(0, LENGTH, -0.5, steps + 0.5))
ax.plot(x[truths], np.arange(steps + 1), "w.", ms=5, label="true position")
for lo, hi in DOORS:
    ax.axvspan(lo, hi, color="tab:orange", alpha=0.15, lw=0)
ax.figure.colorbar(im, ax=ax, label="bel(x)")
ax.legend(loc="upper right");

# %% [markdown]
# **Question 3.** After the first "door" the belief has three peaks. Why three, and why
# are they equally high? What breaks the symmetry in the following steps?
#
# *Your answer here.*

# %% [markdown]
# **Question 4.** Between measurements the peaks get wider. Which part of the filter
# does that, and what would the belief look like after many steps of prediction without
# any measurement?
#
# *Your answer here.*

# %% [markdown]
# **Question 5.** Set the detector's false-positive rate $p(z = \text{door} \mid \text{no door})$
# to 0 and let it report a door where there is none. What does `bayes_filter_step` do, and
# why? What does this teach about using probabilities of exactly 0 or 1 in a model?
#
# *Your answer here.*
