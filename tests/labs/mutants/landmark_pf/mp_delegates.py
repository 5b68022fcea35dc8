"""Moves each particle with the library's cRobot.move.

class: delegation
"""

import numpy as np

from robolab.world import cRobot


def move_particles(
    particles, u_rotation, u_translation, forward_noise, turn_noise, rng, world_size=100
):
    out = []
    for x, y, theta in np.asarray(particles, dtype=float):
        robot = cRobot(rng=rng, size=world_size)
        robot.set_noise(forward_noise, turn_noise, 1.0)
        robot.x, robot.y, robot.theta = x, y, theta
        robot.move(u_rotation, u_translation)
        out.append(robot.pose)
    return np.array(out)
