"""Chapter 4: label any container's parts by warping a labelled source onto it.

- :mod:`pour_gym.warp.local_features`: shift to mean, radius scale, ordered eigenvalues.
- :mod:`pour_gym.warp.classifiers`: Newton-Raphson logistic regression and the Gaussian
  generative classifier.
- :mod:`pour_gym.warp.frame`: upright detection and the canonical, normalised frame.
- :mod:`pour_gym.warp.transfer`: the thesis's transfer and the better one.
- :mod:`pour_gym.warp.lip`: the warped rim fitted to the lip's geometry.
"""

from pour_gym.warp.classifiers import GaussianGenerative, LogisticRegression
from pour_gym.warp.frame import ContainerFrame, canonical_frame
from pour_gym.warp.transfer import Transfer, transfer_best, transfer_thesis

__all__ = [
    "ContainerFrame",
    "GaussianGenerative",
    "LogisticRegression",
    "Transfer",
    "canonical_frame",
    "transfer_best",
    "transfer_thesis",
]
