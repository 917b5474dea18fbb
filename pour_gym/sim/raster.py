"""A small CPU rasteriser: triangle meshes and particle spheres into a depth buffer.

The sensors (:mod:`pour_gym.sim.sensors`) draw every observation with it, and the fluid of
every picture (:func:`pour_gym.sim.camera.render`, the README's GIFs) is drawn by
:func:`draw_spheres` and :func:`composite_water`. Pybullet's TinyRenderer costs more per
84 x 84 frame of two scanned cups than a whole Pour-v0 step (docs/sensors.md has the
figures); these loops visit each triangle once and only the pixels of its bounding box,
and the sensors draw copies of the meshes merged to about a pixel
(:func:`cluster_vertices`).

Conventions (OpenGL's, as pybullet's view matrices): eye coordinates look along -z, with y
up; a pixel (row, column) has its centre at (column + 0.5, row + 0.5); depth is the distance
along the viewing axis (z-depth), m, and ``inf`` where nothing was drawn.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def draw_triangles(vertices, faces, modelview, f, cx, cy, near, segment, depth, seg, light, shade):
    """Draw a triangle mesh into the buffers where it is nearer than what they hold.

    Args:
        vertices: (V, 3) float64 vertices in the mesh's own frame, m.
        faces: (F, 3) int64 vertex indices.
        modelview: (4, 4) float64 transform from the mesh's frame to eye coordinates.
        f: focal length, pixels.
        cx: the principal point's column, pixels.
        cy: the principal point's row, pixels.
        near: nearest drawn depth, m (a triangle with a vertex nearer is skipped).
        segment: the id written into ``seg`` where the mesh is drawn.
        depth: (H, W) float32 z-depth buffer, updated in place.
        seg: (H, W) uint8 segment buffer, updated in place.
        light: (3,) unit vector towards the light, eye coordinates.
        shade: (H, W) float32 brightness buffer (two-sided diffuse), updated in place.
    """
    eye = np.empty_like(vertices)
    for i in range(vertices.shape[0]):
        for r in range(3):
            eye[i, r] = (
                modelview[r, 0] * vertices[i, 0]
                + modelview[r, 1] * vertices[i, 1]
                + modelview[r, 2] * vertices[i, 2]
                + modelview[r, 3]
            )
    h, w = depth.shape
    for k in range(faces.shape[0]):
        a, b, c = faces[k, 0], faces[k, 1], faces[k, 2]
        za, zb, zc = -eye[a, 2], -eye[b, 2], -eye[c, 2]
        if za < near or zb < near or zc < near:
            continue
        xa = cx + f * eye[a, 0] / za
        ya = cy - f * eye[a, 1] / za
        xb = cx + f * eye[b, 0] / zb
        yb = cy - f * eye[b, 1] / zb
        xc = cx + f * eye[c, 0] / zc
        yc = cy - f * eye[c, 1] / zc
        area = (xb - xa) * (yc - ya) - (xc - xa) * (yb - ya)
        if area == 0.0:
            continue
        x0 = max(int(np.floor(min(xa, xb, xc) - 0.5)), 0)
        x1 = min(int(np.ceil(max(xa, xb, xc) - 0.5)), w - 1)
        y0 = max(int(np.floor(min(ya, yb, yc) - 0.5)), 0)
        y1 = min(int(np.ceil(max(ya, yb, yc) - 0.5)), h - 1)
        if x0 > x1 or y0 > y1:
            continue
        # Two-sided diffuse light: a cup's inside is seen as well as its outside.
        ux, uy, uz = eye[b, 0] - eye[a, 0], eye[b, 1] - eye[a, 1], eye[b, 2] - eye[a, 2]
        vx, vy, vz = eye[c, 0] - eye[a, 0], eye[c, 1] - eye[a, 1], eye[c, 2] - eye[a, 2]
        nx = uy * vz - uz * vy
        ny = uz * vx - ux * vz
        nz = ux * vy - uy * vx
        norm = np.sqrt(nx * nx + ny * ny + nz * nz)
        lit = 0.0
        if norm > 0.0:
            lit = abs(nx * light[0] + ny * light[1] + nz * light[2]) / norm
        brightness = 0.35 + 0.65 * lit
        inv = 1.0 / area
        for py in range(y0, y1 + 1):
            sy = py + 0.5
            for px in range(x0, x1 + 1):
                sx = px + 0.5
                w0 = ((xb - sx) * (yc - sy) - (xc - sx) * (yb - sy)) * inv
                w1 = ((xc - sx) * (ya - sy) - (xa - sx) * (yc - sy)) * inv
                w2 = 1.0 - w0 - w1
                if w0 < 0.0 or w1 < 0.0 or w2 < 0.0:
                    continue
                # Perspective-correct: 1/z is linear in screen space.
                z = 1.0 / (w0 / za + w1 / zb + w2 / zc)
                if z < depth[py, px]:
                    depth[py, px] = z
                    seg[py, px] = segment
                    shade[py, px] = brightness


@njit(cache=True, nogil=True)
def draw_spheres(eye, radius, f, cx, cy, near, scene, water):
    """Draw spheres (particles) into a water depth buffer, hidden behind the scene.

    Args:
        eye: (N, 3) float64 sphere centres in eye coordinates, m.
        radius: drawn radius, m.
        f: focal length, pixels.
        cx: the principal point's column, pixels.
        cy: the principal point's row, pixels.
        near: nearest drawn depth, m.
        scene: (H, W) z-depth of everything else, m (a sphere behind it is not drawn).
        water: (H, W) float32 z-depth of the nearest sphere surface, updated in place.
    """
    h, w = water.shape
    for k in range(eye.shape[0]):
        z = -eye[k, 2]
        if z - radius < near:
            continue
        px = cx + f * eye[k, 0] / z
        py = cy - f * eye[k, 1] / z
        r = max(f * radius / z, 0.5)
        x0 = max(int(np.floor(px - r)), 0)
        x1 = min(int(np.ceil(px + r)), w - 1)
        y0 = max(int(np.floor(py - r)), 0)
        y1 = min(int(np.ceil(py + r)), h - 1)
        for iy in range(y0, y1 + 1):
            t = (iy + 0.5 - py) / r
            for ix in range(x0, x1 + 1):
                u = (ix + 0.5 - px) / r
                rr = u * u + t * t
                if rr > 1.0:
                    continue
                # The sphere's front surface at this pixel.
                d = z - radius * np.sqrt(1.0 - rr)
                if d < scene[iy, ix] and d < water[iy, ix]:
                    water[iy, ix] = d


# A particle's drawn radius, in particle spacings: neighbours' spheres overlap (they touch at
# 0.5), so that the water reads as one body.
DRAWN_RADIUS = 1.0
WATER_RGB = np.array([0.20, 0.45, 0.90])
WATER_ALPHA = 0.85  # the cup behind the water shows a little


def composite_water(
    rgb: np.ndarray,
    water: np.ndarray,
    f: float,
    smooth_px: float,
    colour: tuple[float, float, float] | np.ndarray = WATER_RGB,
) -> None:
    """Paint the water over a picture as one surface, lit by its smoothed depth.

    Screen-space fluid shading (van der Laan et al. 2009, much simplified): the spheres'
    depth is smoothed across neighbouring particles (a normalised Gaussian, so the edge of
    the water is not pulled towards the background), and the surface normal of the smoothed
    depth lights it, so that the body of water reads as one and separate drops as drops.

    Args:
        rgb: (H, W, 3) uint8 picture, painted in place.
        water: (H, W) z-depth of the water (``inf`` where there is none), m.
        f: focal length, pixels.
        smooth_px: the smoothing's standard deviation, pixels.
        colour: the liquid's RGB in [0, 1] (:attr:`pour_gym.fluid.liquid.Liquid.color`).
    """
    mask = np.isfinite(water)
    if not mask.any():
        return
    filled = np.where(mask, water, 0.0)
    weight = mask.astype(np.float64)
    if smooth_px > 0:
        # Imported on first use: an environment that draws nothing never needs it.
        from scipy import ndimage

        weight = ndimage.gaussian_filter(weight, smooth_px)
        filled = ndimage.gaussian_filter(filled, smooth_px)
    # Beside the water (weight ~0) the depth is held at the water's farthest, so that the
    # gradient at its edge is the water's own, not a jump to the background.
    z = np.where(weight > 1e-3, filled / np.maximum(weight, 1e-3), np.max(water[mask]))
    gy, gx = np.gradient(z)
    # dz per pixel over a pixel's width in metres at that depth (z / f): the normal's slope.
    scale = f / np.maximum(z, 1e-6)
    nx, ny, nz = -gx * scale, gy * scale, np.ones_like(gx)
    norm = np.sqrt(nx * nx + ny * ny + nz * nz)
    light = np.array([-0.3, 0.5, 0.8]) / np.linalg.norm([-0.3, 0.5, 0.8])
    diffuse = np.clip((nx * light[0] + ny * light[1] + nz * light[2]) / norm, 0.0, 1.0)
    # A highlight (Blinn, the viewer along +z) makes the surface read as liquid.
    half = light + np.array([0.0, 0.0, 1.0])
    half /= np.linalg.norm(half)
    spec = np.clip((nx * half[0] + ny * half[1] + nz * half[2]) / norm, 0.0, 1.0) ** 24
    tint = np.asarray(colour, dtype=np.float64)[None, None, :]
    lit = tint * (0.45 + 0.6 * diffuse)[..., None] + 0.6 * spec[..., None]
    lit = np.clip(lit * 255.0, 0.0, 255.0)
    under = rgb[mask].astype(np.float64)
    rgb[mask] = (WATER_ALPHA * lit[mask] + (1.0 - WATER_ALPHA) * under).astype(np.uint8)


def cluster_vertices(
    vertices: np.ndarray, faces: np.ndarray, cell: float, normals: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """A coarser mesh for drawing: vertices merged on a grid (vertex clustering).

    At a sensor's resolution a scanned or reconstructed cup's tens of thousands of faces
    are each far below a pixel; merging the vertices that share a grid cell of about a
    pixel keeps the picture and draws several times faster. With ``normals``, only
    vertices whose normals point the same way (the same dominant axis and sign) merge, so
    that a wall thinner than a cell keeps its two faces (merged, the faces across the
    wall would be drawn dark). Faces that collapse are dropped; the result is for
    pictures, not physics (it may not be watertight).

    Args:
        vertices: (V, 3) float, m.
        faces: (F, 3) int vertex indices.
        cell: the grid's cell size, m.
        normals: (V, 3) vertex normals, or None to merge regardless of direction.

    Returns:
        ``(vertices, faces)``: float64 (V', 3) cell means and int64 (F', 3).
    """
    v = np.asarray(vertices, dtype=np.float64)
    keys = np.floor(v / cell).astype(np.int64)
    if normals is not None:
        n = np.asarray(normals, dtype=np.float64)
        axis = np.argmax(np.abs(n), axis=1)
        side = n[np.arange(len(n)), axis] > 0
        keys = np.c_[keys, 2 * axis + side]
    _, inverse, counts = np.unique(keys, axis=0, return_inverse=True, return_counts=True)
    inverse = inverse.reshape(-1)
    merged = np.zeros((len(counts), 3))
    np.add.at(merged, inverse, v)
    merged /= counts[:, None]
    f = inverse[np.asarray(faces, dtype=np.int64)]
    keep = (f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 0] != f[:, 2])
    f = np.unique(np.sort(f[keep], axis=1), axis=0) if keep.any() else f[keep]
    return np.ascontiguousarray(merged), np.ascontiguousarray(f)
