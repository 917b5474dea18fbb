"""pour-gym: Gymnasium environments for learning to pour, with warped part features.

The package follows one direction of data (see DESIGN.md)::

    scan -> mesh -> labels -> features -> asset -> world -> env -> agent

Each stage lives in its own module and works on plain data (numpy arrays, trimesh meshes,
small dataclasses):

- :mod:`pour_gym.objects`: the thesis's nine containers as parametric meshes with labels.
- :mod:`pour_gym.scan`: a simulated turntable depth scan.
- :mod:`pour_gym.reconstruct`: chapter 3, Gaussian-kernel implicit surface, marching cubes,
  Laplacian smoothing.
- :mod:`pour_gym.measure`: container geometry measured from a mesh (height, rim radius,
  holding volume, Chamfer distance).
"""

__version__ = "0.1.0"

# Importing the package registers the PourGym/ environments with Gymnasium.
import pour_gym.envs  # noqa: F401
