"""pour-gym: Gymnasium environments for learning to pour, with warped part features.

The package follows one direction of data::

    scan -> mesh -> labels -> features -> asset -> world -> env -> agent -> app

Each stage lives in its own subpackage and works on plain data (numpy arrays, trimesh
meshes, small dataclasses); a package imports only from those below it
(``python tests/test_layers.py`` prints the graph):

- :mod:`pour_gym.apps`: the ``pour-gym`` command line, benchmarks, the soak, the demo.
- :mod:`pour_gym.agents`: rollouts, scripted and searched policies, the thesis's
  experiments and proof of concept, SB3 training, evaluation, studies, Ray.
- :mod:`pour_gym.envs`: the Gymnasium environments (``PourGym/...``), their registry,
  tasks and the holders of the source container.
- :mod:`pour_gym.sim`: the pybullet world (a client per world), spawning, census,
  camera, scripted scenes, the Panda arm; :mod:`pour_gym.perception`: a container as a
  robot's scan sees it (scanned, reconstructed, labelled), for the observations.
- :mod:`pour_gym.fluid`: the position-based fluid in numba, signed-distance colliders,
  the rigid-sphere reference backend.
- :mod:`pour_gym.assets`: the labelled asset format, labelling, the catalogue.
- :mod:`pour_gym.warp` (chapter 4: canonical frame, local features, classifiers, label
  transfer) and :mod:`pour_gym.features` (chapter 5.1: container geometry, f1-f4).
- :mod:`pour_gym.mesh`: chapter 3 (scan, implicit surface, marching cubes, smoothing,
  the report), meshes measured, clouds and meshes read and written.
- :mod:`pour_gym.objects`: the thesis's nine containers as parametric meshes with labels,
  and meshes made the way users' are.
- :mod:`pour_gym.report`: tables, pictures, videos.
- :mod:`pour_gym.io`, :mod:`pour_gym.errors`, :mod:`pour_gym.parts`: the cache folder,
  output redirection, open3d's and TBB's loading, the errors, the part labels.
"""

__version__ = "0.1.0"

# POUR_GYM_CPU pins the processor numba compiles for: set before any compiled function is
# defined (pour_gym.fluid.target).
from pour_gym.fluid.target import pinned_target

pinned_target()

# Importing the package registers the PourGym/ environments with Gymnasium.
import pour_gym.envs  # noqa: E402, F401
