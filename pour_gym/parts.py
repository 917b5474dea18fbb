"""Part labels of a container's vertices (thesis chapter 4).

The integer values are part of the asset contract: ``labels.npy`` stores them and
``meta.json`` repeats the mapping as ``{"outside": 0, "rim": 1, "handle": 2, "container": 3}``.
"""

from enum import IntEnum


class Part(IntEnum):
    """The part a mesh vertex belongs to.

    Attributes:
        OUTSIDE: the outer surface and the base, which never touches the fluid.
        RIM: the lip over which the fluid pours out.
        HANDLE: the handle of a cup (bowls have none).
        CONTAINER: the inner surface that holds the fluid.
    """

    OUTSIDE = 0
    RIM = 1
    HANDLE = 2
    CONTAINER = 3


PART_NAMES: dict[str, int] = {p.name.lower(): int(p) for p in Part}

# RGB in [0, 1], for pictures of labelled meshes.
PART_COLORS: dict[Part, tuple[float, float, float]] = {
    Part.OUTSIDE: (0.72, 0.72, 0.72),
    Part.RIM: (0.85, 0.15, 0.15),
    Part.HANDLE: (0.15, 0.55, 0.85),
    Part.CONTAINER: (0.95, 0.75, 0.10),
}
