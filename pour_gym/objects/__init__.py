"""The thesis's nine containers as parametric, labelled, watertight meshes.

Example:
    >>> from pour_gym.objects import build_object
    >>> cup = build_object("red_cup")
    >>> cup.mesh.is_watertight, round(cup.cavity_volume * 1e6)
    (True, 265)
"""

from pour_gym.objects.catalogue import CUP_NAMES, OBJECT_NAMES, SPECS, ObjectSpec, get_spec

# The builders (trimesh, SciPy) load on first use: an environment reads its containers
# from their assets and needs only the catalogue's names and the family's specs.
_BUILD = ("ContainerModel", "build_object", "cylinder_cup")


def __getattr__(name: str):
    if name in _BUILD:
        from pour_gym.objects import build

        return getattr(build, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


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
