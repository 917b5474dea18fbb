"""The nine containers of the thesis (Fig. 3.3, Tables 4.1-4.3) as parameter sets.

Each :class:`ObjectSpec` holds the thesis's measured "real" height, rim radius and volume,
the numbers its own pipeline computed for them (Tables 4.1-4.3, kept for reports), and the
free shape parameters that the thesis does not give (wall thickness, base thickness, how the
wall flares, whether the opening is round or square, whether there is a handle). The shape
parameters were chosen to look like the photographs in Fig. 3.3; the builder in
:mod:`pour_gym.objects.build` solves the remaining radii so that the mesh matches the real
height, rim radius and volume.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

from pour_gym.errors import InputError

CM = 0.01
ML = 1e-6


@dataclass(frozen=True)
class ObjectSpec:
    """One thesis object.

    Attributes:
        name: identifier used everywhere (``red_cup`` ...).
        title: the thesis's name for it.
        height: real height from Table 4.1, in m: the lip's top above the base.
        rim_radius: real rim radius from Table 4.2, in m: mean distance of the rim's
            vertices to the rim centre, i.e. the radius of the middle of the lip.
        volume: real volume from Table 4.3, in m^3: what the container holds filled to the
            top of its lip.
        thesis_height: height the thesis's pipeline computed (Table 4.1), in m.
        thesis_rim_radius: radius the thesis's pipeline computed (Table 4.2), in m.
        thesis_volume: volume the thesis's pipeline computed (Table 4.3), in m^3.
        wall: wall thickness, in m (measured along the wall's normal).
        base: thickness of the base, in m.
        flare: exponent p of the inner wall's profile r(s) = a + (b - a) s^p over the
            normalised height s; 1 is a straight taper, below 1 a rounded bowl.
        squareness: exponent n of the superellipse |x|^n + |y|^n = 1 of the cross-section;
            ``None`` for a round container.
        handle: whether the object has a handle.
    """

    name: str
    title: str
    height: float
    rim_radius: float
    volume: float
    thesis_height: float
    thesis_rim_radius: float
    thesis_volume: float
    wall: float
    base: float
    flare: float
    squareness: float | None
    handle: bool

    def to_dict(self) -> dict:
        """The spec as a JSON-serialisable dict (SI units)."""
        return asdict(self)


def _spec(
    name: str,
    title: str,
    real: tuple[float, float, float],
    computed: tuple[float, float, float],
    *,
    wall_mm: float,
    base_mm: float = 6.0,
    flare: float = 1.0,
    squareness: float | None = None,
    handle: bool = True,
) -> ObjectSpec:
    """Build a spec from the thesis's units (cm, cm, ml) and millimetre walls."""
    return ObjectSpec(
        name=name,
        title=title,
        height=real[0] * CM,
        rim_radius=real[1] * CM,
        volume=real[2] * ML,
        thesis_height=computed[0] * CM,
        thesis_rim_radius=computed[1] * CM,
        thesis_volume=computed[2] * ML,
        wall=wall_mm * 1e-3,
        base=base_mm * 1e-3,
        flare=flare,
        squareness=squareness,
        handle=handle,
    )


# Real and computed values: Tables 4.1 (height, cm), 4.2 (radius, cm), 4.3 (volume, ml).
SPECS: dict[str, ObjectSpec] = {
    s.name: s
    for s in (
        _spec("red_cup", "Red cup", (8.70, 4.00, 265), (7.60, 3.70, 153), wall_mm=4.0),
        _spec("broad_cup", "Broad cup", (8.80, 5.00, 452), (8.20, 4.90, 297), wall_mm=4.5),
        _spec("high_cup", "High cup", (10.20, 4.50, 435), (9.10, 4.30, 313), wall_mm=3.5),
        _spec(
            "small_base_broad_rim_cup",
            "Cup with small base and broad rim",
            (10.00, 4.50, 296),
            (9.20, 3.90, 162),
            wall_mm=4.0,
            flare=1.3,
        ),
        _spec("standard_cup", "Standard cup", (8.30, 4.35, 324), (7.00, 4.00, 167), wall_mm=4.5),
        _spec(
            "very_broad_cup",
            "Very broad cup",
            (8.90, 5.60, 450),
            (7.80, 5.10, 280),
            wall_mm=4.0,
            flare=0.8,
        ),
        _spec("very_small_cup", "Very small cup", (6.70, 3.85, 170), (5.60, 3.50, 90), wall_mm=3.5),
        _spec(
            "standard_bowl",
            "Standard bowl",
            (8.00, 8.50, 1038),
            (7.40, 8.00, 532),
            wall_mm=5.0,
            base_mm=7.0,
            flare=0.5,
            handle=False,
        ),
        _spec(
            "square_bowl",
            "Square bowl",
            (6.50, 7.50, 680),
            (5.80, 7.80, 505),
            wall_mm=5.0,
            base_mm=7.0,
            flare=0.6,
            squareness=4.0,
            handle=False,
        ),
    )
}

OBJECT_NAMES: tuple[str, ...] = tuple(SPECS)
CUP_NAMES: tuple[str, ...] = tuple(n for n, s in SPECS.items() if s.handle)


def get_spec(name: str) -> ObjectSpec:
    """Look up a thesis object by name.

    Args:
        name: one of :data:`OBJECT_NAMES`.

    Returns:
        The object's spec.

    Raises:
        InputError: the name is not in the catalogue; the message lists the valid names.
    """
    try:
        return SPECS[name]
    except KeyError:
        raise InputError(
            f"unknown object {name!r}; the thesis objects are: {', '.join(OBJECT_NAMES)}"
        ) from None
