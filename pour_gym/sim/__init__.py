"""The pybullet world: a table, containers from labelled assets, and a particle fluid.

- :mod:`pour_gym.sim.world`: :class:`World` (a pybullet client per world), containers.
- :mod:`pour_gym.sim.spawn`: lattice blocks and container fills.
- :mod:`pour_gym.sim.census`: which container each particle is in.
- :mod:`pour_gym.sim.camera`: pictures of a world with its particles.
- :mod:`pour_gym.sim.raster`: the CPU rasteriser the sensors and the pictures' water use.
- :mod:`pour_gym.sim.sensors`: a head camera's depth, colour and point-cloud observations.
"""

from pour_gym.sim.camera import Camera
from pour_gym.sim.census import Census, take_census
from pour_gym.sim.world import FLUIDS, Container, World

__all__ = ["FLUIDS", "Camera", "Census", "Container", "World", "take_census"]
