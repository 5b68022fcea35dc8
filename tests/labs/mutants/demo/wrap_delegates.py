"""Calls the library's wrap_angle instead of writing the wrap.

class: delegation
"""

from robolab.geometry import wrap_angle


def wrap(angle):
    return wrap_angle(angle)
