"""Perceived containers: what a robot that scanned a container knows of its geometry.

The thesis's robot met an unknown container the way this module does: it scanned it (a
Kinect on a turntable), built a mesh from the points (chapter 3), warped a labelled cup
onto the mesh (chapter 4) and computed its features from those labels (chapter 5.1). An
environment with ``perception="scan"`` reads its features from the asset made here while
its physics keeps the true mesh: the policy sees what a scan tells, the water does what
the real container makes it do.

The perceived asset is in the true asset's frame (the scan is taken of the upright
container where it stands, so the reconstruction needs no alignment), so that its rim,
lip and volumes plug into the features wherever the true ones did. It is a function of
the true asset, the scan's settings and seed, and the pipeline's versions, and is cached
by them (:func:`pour_gym.assets.cached_asset`): a container is scanned once per seed.
"""

from __future__ import annotations

import json
import os
from dataclasses import asdict, dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np

from pour_gym.assets import LABELLING_VERSION, LabelledAsset, cached_asset, label_container
from pour_gym.errors import ClosedContainerError, InputError
from pour_gym.features import container_geometry
from pour_gym.io.cache import keyed_entry

if TYPE_CHECKING:
    from pour_gym.mesh.reconstruct import ReconstructConfig
    from pour_gym.mesh.scan import ScanConfig

# The scan and the reconstruction (trimesh, SciPy, scikit-image) are imported when a
# container is first perceived: an environment that perceives from the cache needs none.

PERCEPTIONS = ("true", "scan")
# Bumped when the same container, settings and seed are perceived otherwise.
PERCEPTION_VERSION = 1


class PerceptionError(InputError):
    """A container the perception pipeline cannot take (its reconstruction is closed, say).

    Args:
        name: the container.
        why: what went wrong.
    """

    def __init__(self, name: str, why: str):
        super().__init__(
            f"perception='scan' cannot take {name}: {why}. Use perception='true' for it, or "
            "leave it out of the containers"
        )
        self.name = name
        self.why = why


def _scan_config() -> ScanConfig:
    from pour_gym.mesh.scan import ScanConfig

    return ScanConfig()


def _reconstruct_config() -> ReconstructConfig:
    from pour_gym.mesh.reconstruct import ReconstructConfig

    return ReconstructConfig()


@dataclass(frozen=True)
class ScanPerception:
    """How a container is perceived: the scan and the reconstruction's settings.

    Attributes:
        scan: the simulated turntable scan (its ``seed`` is replaced by the perception's).
        reconstruct: the reconstruction (chapter 3), with the thesis's kernel width.
        narrower: kernel widths (m) to try, in order, where the surface of the one before
            closes the opening: a kernel of 1 cm bridges the 4-5 cm mouth of a tall,
            narrow container that the scan sees only from outside.
        higher: camera elevations (deg) of a second scan, taken where every kernel closes
            the first scan's opening: a robot that cannot make out a mouth looks from
            higher up. Views from 30 and 60 deg see a thin rim's top that views from 5
            and 30 deg miss (a straight cup with 3 mm walls is closed from the first
            scan and measured from the second), but not the underside of a bowl (11 %
            short from them alone), so they are the second look, not the first.
        source: the labelled cup warped onto the reconstruction.
    """

    scan: ScanConfig = field(default_factory=_scan_config)
    reconstruct: ReconstructConfig = field(default_factory=_reconstruct_config)
    narrower: tuple[float, ...] = (0.006,)
    higher: tuple[float, ...] = (30.0, 60.0)
    source: str = "red_cup"

    def to_dict(self) -> dict:
        """The settings as a JSON-serialisable dict."""
        return asdict(self)


def _first_labelled(asset: LabelledAsset, seed: int, how: ScanPerception):
    """The first look and kernel, in order, whose reconstruction the warp labels.

    Returns:
        (labelled asset, reconstructed mesh, scan settings, point cloud, reconstruction
        settings) of that attempt.

    Raises:
        PerceptionError: every reconstruction is closed at the top (naming the kernels and
            views tried), or the warp refuses one for another reason.
    """
    from pour_gym.mesh.reconstruct import reconstruct
    from pour_gym.mesh.scan import turntable_scan

    name = f"{asset.name} (scan {seed})"
    widths = (how.reconstruct.sigma, *how.narrower)
    looks = [how.scan.elevations_deg] + ([how.higher] if how.higher else [])
    for elevations in looks:
        scan = replace(how.scan, elevations_deg=tuple(elevations), seed=int(seed))
        cloud = turntable_scan(asset.mesh, asset.labels, scan)
        for sigma in widths:
            settings = replace(how.reconstruct, sigma=sigma)
            mesh = reconstruct(cloud, settings).mesh
            try:
                labelled = label_container(mesh, source=how.source, name=name)
                return labelled, mesh, scan, cloud, settings
            except ClosedContainerError as exc:
                closed = exc.problem  # a narrower kernel, or a higher look, if one is left
            except InputError as exc:
                raise PerceptionError(asset.name, str(exc)) from None
    kernels = ", ".join(f"{1000 * w:g}" for w in widths)
    views = " and ".join("/".join(f"{e:g}" for e in elevations) + " deg" for elevations in looks)
    raise PerceptionError(
        asset.name,
        f"its reconstruction is closed with kernels of {kernels} mm from views at {views} "
        f"({closed})",
    )


def perceive(asset: LabelledAsset, seed: int = 0, how: ScanPerception | None = None):
    """The container as a scan sees it: scanned, reconstructed and labelled by warping.

    Args:
        asset: the true container, upright in its frame.
        seed: the scan's noise seed.
        how: the settings (default :class:`ScanPerception`).

    Returns:
        A :class:`~pour_gym.assets.LabelledAsset` whose mesh is the reconstruction, in the
        true asset's frame, with warped labels and the geometry they give; its ``meta``
        holds the perceived geometry beside the true one.

    Raises:
        PerceptionError: the reconstruction cannot be labelled (closed at the top, no
            cavity the warp can map onto).
    """
    how = how or ScanPerception()
    labelled, mesh, scan, cloud, settings = _first_labelled(asset, seed, how)
    # The labels are the reconstruction's vertices', in order: its geometry in the frame
    # the scan was taken in, which is the true asset's.
    geometry = container_geometry(mesh, labelled.labels)
    return LabelledAsset(
        name=labelled.name,
        mesh=mesh,
        labels=labelled.labels,
        geometry=geometry,
        meta={
            "name": labelled.name,
            "labels": labelled.meta["labels"],
            **geometry.to_dict(),
            "perceived_from": asset.name,
            "true": asset.geometry.to_dict(),
            "perception": {
                **how.to_dict(),
                "seed": int(seed),
                "sigma": settings.sigma,
                "elevations_deg": list(scan.elevations_deg),
            },
            "points": len(cloud.points),
            "source": labelled.meta["source"],
        },
    )


def perceived_asset(
    asset: LabelledAsset,
    seed: int = 0,
    how: ScanPerception | None = None,
    cache_dir=None,
) -> LabelledAsset:
    """:func:`perceive`, cached by the container's mesh and labels, the settings and seed.

    A refusal is cached too (``<entry>.refused.json`` beside where the asset would be):
    asked again, the same container is refused at once instead of scanned twice more.

    Raises:
        PerceptionError: as :func:`perceive`.
    """
    from pour_gym.mesh.reconstruct import RECONSTRUCTION_VERSION

    how = how or ScanPerception()
    key = b"".join(
        [
            np.ascontiguousarray(asset.surface.vertices, dtype=np.float64).tobytes(),
            np.ascontiguousarray(asset.surface.faces, dtype=np.int64).tobytes(),
            np.ascontiguousarray(asset.labels).tobytes(),
            repr(sorted(how.to_dict().items())).encode(),
            f"seed {seed} p{PERCEPTION_VERSION} r{RECONSTRUCTION_VERSION}".encode(),
            f" v{LABELLING_VERSION}".encode(),
        ]
    )
    stem = f"{asset.name}_scan{seed}"
    refused = keyed_entry(key, stem, cache_dir).with_suffix(".refused.json")
    if refused.is_file():
        said = json.loads(refused.read_text())
        raise PerceptionError(said["name"], said["why"])
    try:
        return cached_asset(key, stem, lambda: perceive(asset, seed, how), cache_dir)
    except PerceptionError as exc:
        # Written aside and renamed, as assets are: a reader never sees half a file.
        tmp = refused.with_name(f".{refused.name}.{os.getpid()}")
        tmp.write_text(json.dumps({"name": exc.name, "why": exc.why}) + "\n")
        tmp.replace(refused)
        raise


def geometry_error(true: LabelledAsset, seen: LabelledAsset) -> dict[str, float]:
    """How far a perceived container's geometry is from the true one's.

    Returns:
        Relative errors of the rim radius, height, container (hull) and cavity volumes, and
        the rim centre's and lip point's distances in m.
    """
    t, s = true.geometry, seen.geometry
    return {
        "rim_radius": s.rim_radius / t.rim_radius - 1.0,
        "height": s.height / t.height - 1.0,
        "container_volume": s.container_volume / t.container_volume - 1.0,
        "cavity_volume": s.cavity_volume / t.cavity_volume - 1.0,
        "rim_center_m": float(np.linalg.norm(s.rim_center - t.rim_center)),
        "lip_height_m": float(s.lip_point[2] - t.lip_point[2]),
    }
