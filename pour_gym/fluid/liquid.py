"""Liquids in SI units: density, dynamic viscosity, and the fluid parameters that give them.

A :class:`Liquid` is what a user names (``liquid="honey"`` on any env); its
:meth:`Liquid.fluid_config` is what the kernel runs. The position-based fluid has a
viscosity of its own (its density projection damps shear flow; ``docs/liquids.md``
measures it with :func:`pour_gym.fluid.validation.shear_wave`): at the default 5 mm
spacing 1.35e-3 m^2/s with XSPH and 1.7e-3 without, what a liquid of 1.4-1.7 Pa s at
water's density has. A liquid less viscous than that (water, milk, oil) flows as the
method's water does, and the config is water's (bit for bit Pour-v0's); a more viscous
one (syrup, honey) gets the
implicit viscosity pass (:func:`pour_gym.fluid.kernel._pass_viscosity`) set so that the
fluid's total, as the shear wave measures it, is the liquid's: the pass's value is read
off :data:`CALIBRATION`, the measured total against the value set.

Presets, at 20 C (the viscosity of foods varies with their make; these are typical):

- ``water``: 998.2 kg/m^3, 1.002e-3 Pa s (IAPWS-2008 viscosity formulation; CRC Handbook
  of Chemistry and Physics).
- ``milk`` (whole): 1030 kg/m^3, 2.0e-3 Pa s (Walstra, Wouters and Geurts, Dairy Science
  and Technology, 2nd ed., 2006, ch. 8).
- ``oil`` (olive): 910 kg/m^3, 0.080 Pa s (Diamante and Lan, J. Food Processing 2014,
  234583: absolute viscosities of vegetable oils, 20 C).
- ``syrup`` (light corn syrup): 1380 kg/m^3, 2.5 Pa s (typical of glucose syrups of about
  80 % solids at 20 C; makers give 2-5 Pa s).
- ``honey``: 1420 kg/m^3, 10 Pa s (Yanniotis, Skaltsi and Karaburnioti, J. Food
  Engineering 72, 2006: honeys of 17 % moisture at 20 C).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from pour_gym.errors import InputError
from pour_gym.fluid.pbf import PBFConfig

# The fluid's total kinematic viscosity (m^2/s) measured by the shear wave
# (pour_gym.fluid.validation.shear_wave: tray 12 cm wide, A = 1 cm/s, 3 s, xsph 0) against
# the implicit pass's value, by spacing (m). Made by `pour-gym bench viscosity`
# (2026-12-04); tests/test_liquid.py checks a point of it.
CALIBRATION: dict[float, tuple[tuple[float, ...], tuple[float, ...]]] = {
    0.005: (
        (0, 0.0005, 0.001, 0.002, 0.003, 0.005, 0.007, 0.01, 0.014),
        (0.001708, 0.001719, 0.001963, 0.002862, 0.003678, 0.005465, 0.006694, 0.008773, 0.0131),
    ),
}
# A liquid this thin (m^2/s; water 1e-6, milk 2e-6) is below the method's own viscosity at
# any spacing measured (the least: 5.3e-4 m^2/s, at 3.5 mm): at a spacing with no
# calibration it flows as the method's water, where a thicker one is refused.
WATER_LIKE = 1e-5


@dataclass(frozen=True)
class Liquid:
    """A Newtonian liquid.

    Attributes:
        name: what it is called (a preset's name, or the user's).
        density: kg/m^3.
        viscosity: dynamic viscosity, Pa s.
        color: RGB in [0, 1], for pictures.
    """

    name: str
    density: float
    viscosity: float
    color: tuple[float, float, float] = (0.20, 0.45, 0.90)

    def __post_init__(self) -> None:
        if not (np.isfinite(self.density) and 100.0 <= self.density <= 20_000.0):
            raise InputError(
                f"liquid {self.name!r}: density is in kg/m^3 (water 998), not {self.density}"
            )
        if not (np.isfinite(self.viscosity) and 0.0 < self.viscosity <= 1000.0):
            raise InputError(
                f"liquid {self.name!r}: viscosity is a dynamic viscosity in Pa s, above 0 "
                f"and at most 1000 (water 1e-3, honey 10), not {self.viscosity}"
            )
        color = tuple(float(c) for c in self.color)
        if len(color) != 3 or not all(0.0 <= c <= 1.0 for c in color):
            raise InputError(f"liquid {self.name!r}: color is RGB in [0, 1], not {self.color}")
        object.__setattr__(self, "color", color)

    @property
    def kinematic_viscosity(self) -> float:
        """Dynamic viscosity over density, m^2/s."""
        return self.viscosity / self.density

    def particle_mass(self, config: PBFConfig) -> float:
        """The mass a particle of this liquid stands for, kg (its volume times the density)."""
        return config.particle_volume * self.density

    def fluid_config(self, base: PBFConfig | None = None) -> PBFConfig:
        """The fluid's parameters for this liquid, from ``base`` (water's, by default).

        Below the method's own viscosity at the spacing, ``base`` itself (the liquid
        flows as the method's water); above it, no XSPH and the implicit pass set so that
        the measured total is this liquid's (:data:`CALIBRATION`).

        Raises:
            InputError: a spacing with no calibration, for a liquid thicker than
                :data:`WATER_LIKE`.
        """
        base = base or PBFConfig()
        nu = self.kinematic_viscosity
        table = CALIBRATION.get(round(base.spacing, 6))
        if table is None and nu <= WATER_LIKE:
            return base
        if table is None:
            known = ", ".join(f"{s * 1000:g} mm" for s in sorted(CALIBRATION))
            raise InputError(
                f"liquids are calibrated at the spacings {known}, not "
                f"{base.spacing * 1000:g} mm: run `pour-gym bench viscosity --spacing "
                f"{base.spacing}` and add its table to pour_gym.fluid.liquid.CALIBRATION"
            )
        set_values, totals = (np.asarray(t, dtype=np.float64) for t in table)
        if nu <= totals[0]:
            return base
        if nu > totals[-1]:
            # Past the table the pass adds what it is set to (the last interval's slope).
            slope = (totals[-1] - totals[-2]) / (set_values[-1] - set_values[-2])
            value = set_values[-1] + (nu - totals[-1]) / slope
        else:
            value = float(np.interp(nu, totals, set_values))
        return dataclasses.replace(base, xsph=0.0, viscosity=float(value))

    def resolved(self, base: PBFConfig | None = None) -> bool:
        """Whether the fluid carries this liquid's viscosity at ``base``'s spacing.

        False where the method's own viscosity is larger (the liquid flows as water does).
        """
        return self.fluid_config(base).viscosity > 0.0


PRESETS: dict[str, Liquid] = {
    "water": Liquid("water", 998.2, 1.002e-3, (0.20, 0.45, 0.90)),
    "milk": Liquid("milk", 1030.0, 2.0e-3, (0.93, 0.93, 0.90)),
    "oil": Liquid("oil", 910.0, 0.080, (0.80, 0.70, 0.15)),
    "syrup": Liquid("syrup", 1380.0, 2.5, (0.75, 0.42, 0.10)),
    "honey": Liquid("honey", 1420.0, 10.0, (0.85, 0.55, 0.05)),
}


def liquid_of(value: str | Liquid | dict) -> Liquid:
    """A liquid from a preset's name, a :class:`Liquid`, or a dict of its fields.

    Raises:
        InputError: an unknown name, or a dict that is not a liquid.
    """
    if isinstance(value, Liquid):
        return value
    if isinstance(value, str):
        if value not in PRESETS:
            raise InputError(
                f"unknown liquid {value!r}; presets: {', '.join(PRESETS)} (or a Liquid, or "
                "a dict with name, density in kg/m^3 and viscosity in Pa s)"
            )
        return PRESETS[value]
    if isinstance(value, dict):
        names = {f.name for f in dataclasses.fields(Liquid)}
        unknown = sorted(set(value) - names)
        missing = sorted({"density", "viscosity"} - set(value))
        if unknown or missing:
            raise InputError(
                f"a liquid as a dict has density (kg/m^3), viscosity (Pa s) and optionally "
                f"name and color; unknown {unknown}, missing {missing}"
            )
        return Liquid(**{"name": "custom", **value})
    raise InputError(
        f"liquid is a preset name ({', '.join(PRESETS)}), a Liquid or a dict, not {value!r}"
    )


@dataclass(frozen=True)
class LiquidRange:
    """Liquids drawn per episode: a viscosity log-uniform in a range, a density uniform.

    Attributes:
        name: what the drawn liquids are called (``info["liquid"]`` is the name and the
            viscosity drawn, e.g. ``"range 3.2 Pa s"``).
        viscosity: (low, high) dynamic viscosity, Pa s.
        density: (low, high) kg/m^3 (equal ends for one density).
        color: RGB in [0, 1], for pictures.
    """

    name: str
    viscosity: tuple[float, float]
    density: tuple[float, float]
    color: tuple[float, float, float] = (0.75, 0.42, 0.10)

    def __post_init__(self) -> None:
        for key in ("viscosity", "density"):
            low, high = getattr(self, key)
            if not low <= high:
                raise InputError(f"liquid range {self.name!r}: {key} low {low} above high {high}")
        for mu, rho in ((self.viscosity[0], self.density[0]), (self.viscosity[1],
                                                               self.density[1])):  # fmt: skip
            Liquid(self.name, rho, mu, self.color)  # each end a liquid (checked there)

    def draw(self, rng: np.random.Generator) -> Liquid:
        """One liquid of the range, from ``rng``."""
        low, high = np.log(self.viscosity[0]), np.log(self.viscosity[1])
        mu = float(np.exp(rng.uniform(low, high))) if high > low else self.viscosity[0]
        rho = float(rng.uniform(*self.density)) if self.density[1] > self.density[0] else (
            self.density[0])  # fmt: skip
        return Liquid(f"{self.name} {mu:.3g} Pa s", rho, mu, self.color)

    def ends(self) -> tuple[Liquid, Liquid]:
        """The range's least and most viscous liquids (for checks ahead of the episodes)."""
        return (Liquid(self.name, self.density[0], self.viscosity[0], self.color),
                Liquid(self.name, self.density[1], self.viscosity[1], self.color))  # fmt: skip


def _range_of(value: dict) -> LiquidRange:
    """A :class:`LiquidRange` from a dict whose viscosity (or density) is a [low, high]."""
    names = {"name", "viscosity", "density", "color"}
    unknown = sorted(set(value) - names)
    if unknown or "viscosity" not in value or "density" not in value:
        raise InputError(
            "a liquid range has viscosity (Pa s) and density (kg/m^3), each a number or "
            f"[low, high], and optionally name and color; unknown {unknown}"
        )

    def pair(x, key) -> tuple[float, float]:
        if isinstance(x, (int, float)):
            return float(x), float(x)
        if isinstance(x, (list, tuple)) and len(x) == 2:
            return float(x[0]), float(x[1])
        raise InputError(f"a liquid range's {key} is a number or [low, high], not {x!r}")

    extra = {"color": value["color"]} if "color" in value else {}
    return LiquidRange(str(value.get("name", "range")), pair(value["viscosity"], "viscosity"),
                       pair(value["density"], "density"), **extra)  # fmt: skip


def liquids_of(
    value: str | Liquid | dict | Sequence | None,
) -> tuple[Liquid | LiquidRange, ...]:
    """The liquids an env draws its episodes' liquid from (one: every episode's).

    Args:
        value: one liquid (see :func:`liquid_of`), a range (a dict whose ``viscosity`` is
            [low, high] Pa s, drawn log-uniformly per episode; its ``density`` a number or
            [low, high]), a comma-separated string of presets (``"water,honey"``), or a
            list of these; None for water.

    Raises:
        InputError: an empty list, or an entry that is not a liquid.
    """
    if value is None:
        return (PRESETS["water"],)
    if isinstance(value, str) and "," in value:
        value = [v.strip() for v in value.split(",") if v.strip()]
    if isinstance(value, (list, tuple)):
        if not value:
            raise InputError("liquid is a list of at least one liquid, not an empty one")
        return tuple(x for v in value for x in liquids_of(v))
    if isinstance(value, LiquidRange):
        return (value,)
    if isinstance(value, dict) and any(
        isinstance(value.get(k), (list, tuple)) for k in ("viscosity", "density")
    ):
        return (_range_of(value),)
    return (liquid_of(value),)
