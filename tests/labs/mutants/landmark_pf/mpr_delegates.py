"""Builds a cRobot per particle and calls its measurement_probability.

class: delegation
"""

import numpy as np

from robolab.world import cRobot, cWorld


def measurement_probability(measured_ranges, particles, landmarks, sensor_noise):
    world = cWorld(landmarks=np.asarray(landmarks, dtype=float))
    out = []
    for x, y, theta in np.asarray(particles, dtype=float):
        robot = cRobot()
        robot.set_noise(0.0, 0.0, sensor_noise)
        robot.x, robot.y, robot.theta = x, y, theta
        out.append(robot.measurement_probability(measured_ranges, world))
    return np.array(out)
