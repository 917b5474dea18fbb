"""Particle fluid: position-based fluids in numba, colliding with posed containers."""

from pour_gym.fluid.pbf import PBFConfig, PBFluid
from pour_gym.fluid.sdf import SignedDistanceField, build_sdf

__all__ = ["PBFConfig", "PBFluid", "SignedDistanceField", "build_sdf"]
