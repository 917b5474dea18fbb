"""pour-gym: Gymnasium environments for learning to pour, with warped part features.

The package follows one direction of data (the design in the README)::

    scan -> mesh -> labels -> features -> asset -> world -> env -> agent

Each stage lives in its own module and works on plain data (numpy arrays, trimesh meshes,
small dataclasses):

- :mod:`pour_gym.objects`: the thesis's nine containers as parametric meshes with labels,
  and meshes made the way users' are (two bodies, thin walls, capped scans).
- :mod:`pour_gym.scan`: a simulated turntable depth scan.
- :mod:`pour_gym.gaussian_field`, :mod:`pour_gym.reconstruct`, :mod:`pour_gym.modelgen`:
  chapter 3, Gaussian-kernel implicit surface, marching cubes, Laplacian smoothing, and
  the report against ground truth.
- :mod:`pour_gym.measure`: container geometry measured from a mesh (height, rim radius,
  holding volume, whether it has an opening, Chamfer distance).
- :mod:`pour_gym.warp`: chapter 4, canonical frame, local features, classifiers, label
  transfer.
- :mod:`pour_gym.features`: chapter 5.1, container geometry and the fluid features f1-f4
  (the one definition the environments use).
- :mod:`pour_gym.assets`: the labelled asset format, labelling, the catalogue;
  :mod:`pour_gym.fileio` reads and writes clouds and meshes; :mod:`pour_gym.cache`.
- :mod:`pour_gym.fluid`: the position-based fluid in numba, signed-distance colliders, the
  rigid-sphere reference backend.
- :mod:`pour_gym.sim`: the pybullet world (a client per world), spawning, census, camera,
  scripted scenes.
- :mod:`pour_gym.envs`: the Gymnasium environments (``PourGym/...``).
- :mod:`pour_gym.agents`: rollouts, scripted and searched policies, the thesis's
  experiments and proof of concept, SB3 training, evaluation, studies.
- :mod:`pour_gym.cli` (the ``pour-gym`` command), :mod:`pour_gym.bench`,
  :mod:`pour_gym.render`, :mod:`pour_gym.video`.
"""

__version__ = "0.1.0"

# Importing the package registers the PourGym/ environments with Gymnasium.
import pour_gym.envs  # noqa: F401
