"""The thesis's nine containers as parametric, labelled, watertight meshes.

Example:
    >>> from pour_gym.objects import build_object
    >>> cup = build_object("red_cup")
    >>> cup.mesh.is_watertight, round(cup.cavity_volume * 1e6)
    (True, 265)
"""

from pour_gym.objects.build import ContainerModel, build_object, cylinder_cup
from pour_gym.objects.catalogue import CUP_NAMES, OBJECT_NAMES, SPECS, ObjectSpec, get_spec

__all__ = [
    "CUP_NAMES",
    "OBJECT_NAMES",
    "SPECS",
    "ContainerModel",
    "ObjectSpec",
    "build_object",
    "cylinder_cup",
    "get_spec",
]
