"""The rim's extent fitted to the lip: where a container's wall stops being a wall.

The warp (:mod:`pour_gym.warp.transfer`) carries the source's rim band over in normalised
coordinates, so the band it paints is the source's lip stretched by the two containers'
proportions: on a thin-walled bowl it runs millimetres down both walls, on a thick rolled
lip it stops short of the bead's underside. The lip itself is a geometric fact: it is the
top of the wall, above the height where the wall's horizontal cross-section settles to the
wall's own. A round lip narrows to nothing at the top, a rolled one bulges out, a flat one
is cut square, and below each of them the wall's width changes only slowly with height
(a taper, a flare).

So the wall's width is measured along horizontal rays from the axis at depths below the
top; along each ray the lip ends at the deepest depth where the width still changes faster
than a wall's does, and the lip's depth is the median over the rays. The rim is then every
vertex within that depth (and a small margin) of the rim's top at its azimuth, except the
handle's; what the warp called rim below it goes to the container or the outside by the
side its normal faces. Where the lip cannot be told (a mesh too coarse to draw it, a
container too short, rays that disagree, as on a scan whose wall thickens into its lip
over millimetres) the warp's labels stay as they are.

The constants were chosen on ``procedural:train`` (200 containers, labels from their
construction) and the result measured on ``procedural:test``; see docs/procedural/warping.md.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh

from pour_gym.parts import Part
from pour_gym.warp.frame import rim_heights, top_at

# Depths below the top at which the wall's width is measured, every DEPTH_STEP, in m.
DEPTH_STEP = 1e-4
# A lip ends above this depth (m): the procedural family's deepest, a rolled lip on a 6 mm
# wall below a wall that leans in, ends about 10 mm down.
DEEPEST_LIP = 0.012
# The widths are measured down to this depth (m); a ray that misses the wall on more than a
# fifth of the depths between DEEPEST_LIP and here has no wall to compare the lip with.
MEASURED_TO = 0.015
# A wall's horizontal width changes by less than this per unit of depth (a taper, a flare);
# a lip's by more (it narrows to the top, bulges out, is cut square). Measured over
# SLOPE_BASE (m) of depth, centred.
SLOPE = 0.1
SLOPE_BASE = 4e-4
# The rim band reaches this far (m) below the deepest depth where the width still changes
# like a lip's: the lip's last vertex sits at the end of that slope.
MARGIN = 2e-4
# Rays that disagree on the lip's end by more than this (interquartile range, m) show no
# single lip: a scanned wall thickens into its lip over millimetres.
SPREAD = 1.5e-3
# Horizontal rays per depth, evenly spread in azimuth.
RAYS = 72
# A mesh whose median edge is longer than this (m) cannot draw a lip of a few millimetres:
# its top ring of vertices is the lip and the walls' top at once.
MAX_EDGE = 5e-3


@dataclass(frozen=True)
class LipFit:
    """How far down the lip reaches, or why it could not be told.

    Attributes:
        depth: depth of the lip's lower end below the rim's top, in m (None when unknown).
        rays: rays whose wall could be measured.
        reason: why the fit was not used (empty when it was).
    """

    depth: float | None
    rays: int
    reason: str = ""

    def to_dict(self) -> dict:
        """JSON-ready form (depth in m)."""
        return {"depth": self.depth, "rays": self.rays, "reason": self.reason}


def wall_widths(mesh: trimesh.Trimesh, depths: np.ndarray, rays: int = RAYS) -> np.ndarray:
    """Horizontal thickness of an upright container's wall below its top.

    At each depth a horizontal plane cuts the mesh; along each ray from the z axis the
    first crossing is the inner wall and the second the outer one.

    Args:
        mesh: the container, upright, its opening's axis on x = y = 0, in m.
        depths: (D,) depths below the mesh's highest point, in m.
        rays: number of rays, evenly spread in azimuth.

    Returns:
        (D, rays) wall widths in m; NaN where a ray crosses fewer than two surfaces.
    """
    v = np.asarray(mesh.vertices, dtype=float)
    f = np.asarray(mesh.faces)
    top = float(v[:, 2].max())
    # Only the faces that reach the deepest plane take part (a cut of a few per cent).
    near = v[f][:, :, 2].max(axis=1) >= top - float(np.max(depths)) - DEPTH_STEP
    part = trimesh.Trimesh(v, f[near], process=False)
    azimuth = -np.pi + (np.arange(rays) + 0.5) * 2.0 * np.pi / rays
    u = np.column_stack([np.cos(azimuth), np.sin(azimuth)])
    widths = np.full((len(depths), rays), np.nan)
    for k, depth in enumerate(depths):
        segments = trimesh.intersections.mesh_plane(part, [0.0, 0.0, 1.0], [0.0, 0.0, top - depth])
        if len(segments) == 0:
            continue
        a = segments[:, 0, :2]
        e = segments[:, 1, :2] - a
        # The ray s u meets the segment a + t e where t = (u x a) / (e x u).
        u_cross_a = u[:, None, 0] * a[None, :, 1] - u[:, None, 1] * a[None, :, 0]
        e_cross_u = e[None, :, 0] * u[:, None, 1] - e[None, :, 1] * u[:, None, 0]
        with np.errstate(divide="ignore", invalid="ignore"):
            t = u_cross_a / e_cross_u
            s = np.einsum("rsd,rd->rs", a[None] + t[..., None] * e[None], u)
        hit = (t >= 0.0) & (t <= 1.0) & (s > 0.0) & np.isfinite(s)
        s = np.sort(np.where(hit, s, np.inf), axis=1)
        if s.shape[1] >= 2:
            two = np.isfinite(s[:, 1])
            widths[k, two] = s[two, 1] - s[two, 0]
    return widths


def lip_depth(mesh: trimesh.Trimesh) -> LipFit:
    """How far below the top the lip of an upright container reaches.

    Along each ray, the lip ends at the deepest depth above :data:`DEEPEST_LIP` where the
    wall's width still changes faster than :data:`SLOPE`; the median over the rays is the
    lip's depth.

    Args:
        mesh: the container, upright, its opening's axis on x = y = 0, in m.

    Returns:
        The fit; its ``depth`` is None (with the reason) when the mesh is too coarse or
        the container too short, too few rays find a wall, the wall never settles, or the
        rays disagree.
    """
    edge = float(np.median(mesh.edges_unique_length))
    if edge > MAX_EDGE:
        return LipFit(None, 0, f"edges of {edge * 1e3:.1f} mm (median): too coarse to draw a lip")
    height = float(np.ptp(np.asarray(mesh.vertices)[:, 2]))
    if height < 2.0 * MEASURED_TO:
        return LipFit(None, 0, f"{height * 100:.1f} cm tall: too short to tell lip from wall")
    depths = np.arange(DEPTH_STEP / 2.0, MEASURED_TO, DEPTH_STEP)
    widths = wall_widths(mesh, depths)
    lip = depths < DEEPEST_LIP
    h = max(1, round(SLOPE_BASE / DEPTH_STEP / 2.0))
    ends = []
    for w in widths.T:
        if np.count_nonzero(np.isfinite(w[~lip])) < 0.8 * np.count_nonzero(~lip):
            continue
        # Where the ray misses the wall (NaN) the slope is infinite: a lip's, not a wall's.
        slope = np.full(len(w), np.inf)
        slope[h:-h] = np.abs(w[2 * h :] - w[: -2 * h]) / (2 * h * DEPTH_STEP)
        changing = ~(slope <= SLOPE)
        if np.any(changing[~lip][:-h]):
            # Still changing below the deepest lip: the wall this ray sees does not settle
            # where it was measured (a reconstruction's wall thickens over centimetres).
            ends.append(MEASURED_TO)
            continue
        in_lip = np.flatnonzero(lip & changing)
        ends.append(float(depths[in_lip[-1]]) if len(in_lip) else 0.0)
    if len(ends) < RAYS // 2:
        return LipFit(None, len(ends), f"the wall was measured on {len(ends)} of {RAYS} rays")
    q1, depth, q3 = (float(q) for q in np.percentile(ends, [25, 50, 75]))
    if depth + MARGIN >= DEEPEST_LIP - h * DEPTH_STEP:
        return LipFit(
            None, len(ends), f"the wall does not settle within {DEEPEST_LIP * 1e3:.0f} mm"
        )
    if q3 - q1 > SPREAD:
        return LipFit(
            None, len(ends), f"the rays put the lip's end {q1 * 1e3:.1f}-{q3 * 1e3:.1f} mm down"
        )
    return LipFit(depth, len(ends))


def fit_rim(
    mesh: trimesh.Trimesh, labels: np.ndarray, rim_top: np.ndarray | None = None
) -> tuple[np.ndarray, LipFit]:
    """The rim of warped labels made the lip: every vertex down to the lip's lower end.

    Args:
        mesh: the labelled container, upright, its opening's axis on x = y = 0, in m.
        labels: (V,) parts from the warp.
        rim_top: the rim's top per azimuth wedge, as :func:`~pour_gym.warp.frame.rim_heights`
            gives for the mesh's vertices (the canonical frame has it); None: computed here.

    Returns:
        The labels with the rim fitted to the lip (the input's, unchanged, when the lip
        could not be measured) and the fit.
    """
    fit = lip_depth(mesh)
    if fit.depth is None:
        return labels, fit
    v = np.asarray(mesh.vertices, dtype=float)
    top = top_at(v, rim_heights(v) if rim_top is None else rim_top)
    lip = (v[:, 2] >= top - fit.depth - MARGIN) & (labels != Part.HANDLE)
    out = labels.copy()
    # What the warp called rim below the lip is wall: inside or outside by its normal.
    below = (labels == Part.RIM) & ~lip
    normals = np.asarray(mesh.vertex_normals, dtype=float)
    inward = np.einsum("ij,ij->i", normals[:, :2], v[:, :2]) < 0.0
    out[below & inward] = Part.CONTAINER
    out[below & ~inward] = Part.OUTSIDE
    out[lip] = Part.RIM
    return out, fit
