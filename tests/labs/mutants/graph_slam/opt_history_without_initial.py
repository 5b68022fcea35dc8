"""Records F only after each step, not of the initial guess.

class: reported-estimate
"""

import numpy as np

from robolab.validation import check_count, check_positive
from solutions.graph_slam import _check_graph, _objective, gauss_newton_step


def optimize_graph(graph, max_iterations=20, tolerance=1e-5):
    g = _check_graph(graph)
    iterations = check_count("max_iterations", max_iterations)
    tol = check_positive("tolerance", tolerance)
    objective, steps, converged = [], [], False
    previous = _objective(g)
    for _ in range(iterations):
        g, dx = gauss_newton_step(g)
        objective.append(_objective(g))
        steps.append(float(np.abs(dx).max(initial=0.0)))
        change = abs(previous - objective[-1])
        converged = change <= tol * previous or change <= tol
        previous = objective[-1]  # relative, or absolute near 0
        if converged:
            break
    history = {"objective": np.array(objective), "step": np.array(steps), "converged": converged}
    return g, history
