"""Calls the library's robolab.geometry.transform_points.

class: delegation
"""

from robolab.geometry import transform_points as library_transform


def transform_points(points, pose):
    return library_transform(points, pose)
