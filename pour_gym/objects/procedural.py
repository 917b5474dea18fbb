"""A procedural family of containers: hundreds of watertight, labelled cups, glasses and bowls.

Each member is drawn from a few interpretable parameters (:data:`RANGES`) and built by the
same code as the thesis objects (:mod:`pour_gym.objects.build`), so its ground-truth part
labels come from its construction. A member is named by its family and index, and the name
alone rebuilds it bit for bit: member ``k`` of a family draws its parameters from
``numpy.random.default_rng([seed, k])``.

Families (:func:`family_members`):

- ``procedural:train``: 200 members (seed :data:`TRAIN_SEED`);
- ``procedural:test``: 100 members (seed :data:`TEST_SEED`), disjoint from the training
  family by their seed;
- ``procedural:N@SEED``: N members drawn with any other seed.

A member's name is ``procedural:<family>#<k>``: ``procedural:test#7``, ``procedural:5@42#0``.

Example:
    >>> from pour_gym.objects.procedural import build_member, family_members
    >>> names = family_members("procedural:test")
    >>> len(names), names[0]
    (100, 'procedural:test#0')
    >>> build_member(names[0]).mesh.is_watertight
    True
"""

from __future__ import annotations

import re
from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING

import numpy as np

from pour_gym.errors import InputError

if TYPE_CHECKING:
    from pour_gym.objects.build import ContainerModel

PREFIX = "procedural:"
TRAIN_SEED, TRAIN_SIZE = 20_261_202, 200
TEST_SEED, TEST_SIZE = 20_261_203, 100
# Bumped whenever a name would build another mesh (caches of labelled members key on it).
GENERATOR_VERSION = 1

PROFILES = ("straight", "tapered", "flared", "bulged", "bowl")
CROSS_SECTIONS = ("round", "rounded_square", "oval")
LIPS = ("round", "flat", "rolled")

# The ranges each parameter is drawn from (uniformly; lengths in m). A bowl is wider and
# shallower than a cup and has no handle; the rest is shared.
RANGES: dict[str, tuple[float, float]] = {
    "cup_height": (0.06, 0.14),
    "cup_rim_radius": (0.025, 0.055),
    "bowl_height": (0.04, 0.08),
    "bowl_rim_radius": (0.05, 0.085),
    "wall": (0.002, 0.006),
    "base_over_wall": (0.001, 0.004),  # the base is this much thicker than the wall
    # The cavity floor's radius over the rim's, per profile.
    "tapered_floor": (0.6, 0.9),
    "flared_floor": (0.45, 0.75),
    "bulged_floor": (0.8, 1.0),
    "bowl_floor": (0.25, 0.5),
    "flared_flare": (1.5, 2.5),  # the inner wall's exponent p (1: a straight taper)
    "bowl_flare": (0.4, 0.7),
    "bulge": (0.1, 0.3),  # the belly, over the rim's radius
    "squareness": (3.0, 5.0),  # a rounded square's superellipse exponent
    "aspect": (0.7, 0.9),  # an oval's short axis over its long axis
    "bead": (0.5, 1.0),  # how far a rolled lip stands out, over the wall
    "handle_low": (0.2, 0.4),  # the handle's attachments, over the height
    "handle_high": (0.65, 0.85),
    "handle_reach": (0.018, 0.032),
}
# How often each choice is drawn.
SHARES = {
    "profile": (0.2, 0.2, 0.2, 0.2, 0.2),
    "cross_section": (0.6, 0.2, 0.2),
    "lip": (0.5, 0.25, 0.25),
    "handle": 0.5,  # of the cups (bowls have none)
}


@dataclass(frozen=True)
class ProceduralSpec:
    """One member of the procedural family: the parameters it was drawn with.

    Attributes:
        name: its name, ``procedural:<family>#<k>``.
        profile: one of :data:`PROFILES`.
        height: the wall's height over the base (the lip's top for a round lip), m.
        rim_radius: the radius of the middle of the lip along x (the handle's side), m;
            an oval is narrower along y, a rounded square wider at its corners.
        floor_radius: the cavity floor's radius, m.
        wall: wall thickness along x, m (the cross-section scales it: an oval's wall is
            thinner along its short axis by ``aspect``).
        base: base thickness, m.
        flare: the inner wall's exponent p (see :class:`~pour_gym.objects.build.Shape`).
        bulge: the belly halfway up the inner wall, m.
        cross_section: one of :data:`CROSS_SECTIONS`.
        squareness: a rounded square's superellipse exponent (None otherwise).
        aspect: an oval's short axis over its long axis (1 otherwise).
        lip: one of :data:`LIPS`.
        bead: how far a rolled lip stands out of the wall, m (0 otherwise).
        handle: whether it has a handle.
        handle_span: the handle's lower and upper attachment, over the height.
        handle_reach: how far the handle stands off the wall, m.
    """

    name: str
    profile: str
    height: float
    rim_radius: float
    floor_radius: float
    wall: float
    base: float
    flare: float
    bulge: float
    cross_section: str
    squareness: float | None
    aspect: float
    lip: str
    bead: float
    handle: bool
    handle_span: tuple[float, float]
    handle_reach: float

    def to_dict(self) -> dict:
        """The parameters as a JSON-serialisable dict (SI units)."""
        return asdict(self)


def draw_spec(name: str, rng: np.random.Generator) -> ProceduralSpec:
    """Draw one member's parameters from :data:`RANGES` and :data:`SHARES`.

    Every draw is taken whatever the choices, in a fixed order, so that one parameter's
    choice never shifts another's value (a member changes only where its draws say so).

    Args:
        name: the member's name.
        rng: its generator.
    """

    def u(key: str) -> float:
        lo, hi = RANGES[key]
        return float(rng.uniform(lo, hi))

    def pick(options: tuple[str, ...], key: str) -> str:
        return options[int(rng.choice(len(options), p=SHARES[key]))]

    profile = pick(PROFILES, "profile")
    cross_section = pick(CROSS_SECTIONS, "cross_section")
    lip = pick(LIPS, "lip")
    handle_drawn = bool(rng.random() < SHARES["handle"])
    draws = {key: u(key) for key in RANGES}
    bowl = profile == "bowl"
    height = draws["bowl_height" if bowl else "cup_height"]
    rim = draws["bowl_rim_radius" if bowl else "cup_rim_radius"]
    wall = draws["wall"]
    floor_share = {
        "straight": 1.0,
        "tapered": draws["tapered_floor"],
        "flared": draws["flared_floor"],
        "bulged": draws["bulged_floor"],
        "bowl": draws["bowl_floor"],
    }[profile]
    flare = {"flared": draws["flared_flare"], "bowl": draws["bowl_flare"]}.get(profile, 1.0)
    inner_rim = rim - wall / 2.0
    return ProceduralSpec(
        name=name,
        profile=profile,
        height=height,
        rim_radius=rim,
        floor_radius=floor_share * inner_rim,
        wall=wall,
        base=wall + draws["base_over_wall"],
        flare=flare,
        bulge=draws["bulge"] * inner_rim if profile == "bulged" else 0.0,
        cross_section=cross_section,
        squareness=draws["squareness"] if cross_section == "rounded_square" else None,
        aspect=draws["aspect"] if cross_section == "oval" else 1.0,
        lip=lip,
        bead=draws["bead"] * wall if lip == "rolled" else 0.0,
        handle=handle_drawn and not bowl,
        handle_span=(draws["handle_low"], draws["handle_high"]),
        handle_reach=draws["handle_reach"],
    )


_MEMBER = re.compile(r"procedural:(train|test|\d+@\d+)#(\d+)")
_FAMILY = re.compile(r"procedural:(train|test|(\d+)@(\d+))")


def _family(family: str) -> tuple[int, int]:
    """A family's (seed, size), from ``train``, ``test`` or ``N@SEED``."""
    if family == "train":
        return TRAIN_SEED, TRAIN_SIZE
    if family == "test":
        return TEST_SEED, TEST_SIZE
    size, seed = (int(x) for x in family.split("@"))
    return seed, size


def is_family(name: str) -> bool:
    """Whether ``name`` names a procedural family (``procedural:train``, ``procedural:5@1``)."""
    return _FAMILY.fullmatch(str(name)) is not None


def is_member(name: str) -> bool:
    """Whether ``name`` names one procedural member (``procedural:test#7``)."""
    return _MEMBER.fullmatch(str(name)) is not None


def family_members(name: str) -> tuple[str, ...]:
    """The member names of a family, in order.

    Raises:
        InputError: not a family name, or an empty family.
    """
    m = _FAMILY.fullmatch(str(name))
    if m is None:
        raise InputError(
            f"{name!r} is not a procedural family: use procedural:train, procedural:test or "
            "procedural:N@SEED (N members drawn with seed SEED)"
        )
    family = m.group(1)
    _, size = _family(family)
    if size < 1:
        raise InputError(f"{name}: a family has at least one member")
    return tuple(f"{PREFIX}{family}#{k}" for k in range(size))


def member_spec(name: str) -> ProceduralSpec:
    """A member's parameters from its name.

    Raises:
        InputError: not a member's name, or an index beyond its family.
    """
    m = _MEMBER.fullmatch(str(name))
    if m is None:
        raise InputError(
            f"{name!r} is not a procedural container: use procedural:<family>#<k>, e.g. "
            "procedural:test#7 (families: train, test, N@SEED)"
        )
    family, k = m.group(1), int(m.group(2))
    seed, size = _family(family)
    if k >= size:
        raise InputError(f"{name}: procedural:{family} has members #0-#{size - 1}")
    return draw_spec(str(name), np.random.default_rng([seed, k]))


def build_spec(spec: ProceduralSpec) -> ContainerModel:
    """Build a procedural container: its watertight mesh and labels from construction.

    Raises:
        InputError: parameters that admit no such container (named).
        RuntimeError: the built mesh is not watertight.
    """
    from pour_gym.objects.build import build_from_radii, shape_of

    # The rim radius is the lip's middle (along x, where every ring's scale is 1): the
    # inner wall's top is half a wall inside it.
    b = spec.rim_radius - spec.wall / 2.0
    top = spec.height - spec.wall / 2.0
    return build_from_radii(spec, shape_of(spec), spec.floor_radius, b, top)


def build_member(name: str) -> ContainerModel:
    """Build a procedural container from its name (``procedural:test#7``)."""
    return build_spec(member_spec(name))
