"""The fluid's compiled kernel: position-based fluids (Macklin and Mueller 2013) in numba.

Each step of ``dt`` runs in one compiled call, :func:`_advance`, in substeps whose length
follows the CFL bound (no particle and no wall moves farther than ``max_travel`` particle
radii in one substep, and no substep is longer than ``substep``). Each substep: apply
gravity and predict positions; find neighbours in a hashed cell grid; iterate the density
constraint ``C_i = rho_i / rho_0 - 1`` (clamped to compression, so that a free surface has
no artificial cohesion), with the paper's artificial pressure ``s_corr`` against clumping;
project out of the containers' walls through their signed-distance fields, posed at the
substep's end by interpolating each container between its pose at the last step and its
current one (a particle whose path crossed into a wall is put back on the side it came
from, and counted); update velocities from the displacement (of which a push out of a
wall contributes no more than the particle's own motion in the substep plus the fastest
wall's: a particle found deep in a scan's fold is moved out, not flung off), and smooth
them with XSPH viscosity.

This module is the kernel's source only: :mod:`pour_gym.fluid.build` compiles its driver
twice (one thread, parallel loops) on first use, and :class:`pour_gym.fluid.pbf.PBFluid`
calls it. Importing it patches numba's target options (:data:`NOALIAS`), so nothing imports
it before a fluid steps.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from pour_gym.fluid.sdf import FASTMATH, NO_REFCOUNT, PART_CACHE, trilinear

# A substep count no bounded speed reaches (MAX_SPEED over a 0.1 s step at 1.5 radii of 5
# mm particles is about 500): the kernel stops there rather than loop on a broken state.
MAX_SUBSTEPS = 20_000
# The implicit viscosity's Jacobi sweeps leave at most this share of the smoothest mode's
# diffusion undone (5 %), in at most MAX_VISC_SWEEPS sweeps (honey at 5 mm takes ~15).
VISC_TOL = 0.05
MAX_VISC_SWEEPS = 200


def _noalias_option() -> dict:
    """``{"noalias": True}`` where this numba can be told that array arguments never alias.

    Numba gives its parallel loops' outlined bodies LLVM's ``noalias`` on array arguments
    (when it proves them distinct) but has no public option for a plain function, whose
    loops then reload every array's data on each store (1.6x slower on the density pass).
    The compiler flag exists (``Flags.noalias``); this maps a target option onto it. The
    kernel's arrays are distinct allocations.
    """
    try:
        from numba.core.cpu import CPUTargetOptions
        from numba.core.options import TargetOptions

        if not hasattr(CPUTargetOptions, "noalias"):
            CPUTargetOptions.noalias = TargetOptions.Mapping("noalias")
        return {"noalias": True}
    except (ImportError, AttributeError):  # another numba: the kernel is only slower
        return {}


# Array arguments never alias in the kernel's functions (distinct allocations).
NOALIAS = _noalias_option()


@nb.njit(cache=PART_CACHE, **NO_REFCOUNT)
def _slerp_matrix(q0, q1, f, out):
    """Rotation matrix of the slerp from unit quaternion q0 to q1 at fraction f, into out."""
    dot = q0[0] * q1[0] + q0[1] * q1[1] + q0[2] * q1[2] + q0[3] * q1[3]
    sign = 1.0
    if dot < 0.0:  # the shorter way round
        dot, sign = -dot, -1.0
    if dot > 0.9995:
        a, b = 1.0 - f, f
    else:
        theta = np.arccos(min(dot, 1.0))
        st = np.sin(theta)
        a, b = np.sin((1.0 - f) * theta) / st, np.sin(f * theta) / st
    w = a * q0[0] + sign * b * q1[0]
    x = a * q0[1] + sign * b * q1[1]
    y = a * q0[2] + sign * b * q1[2]
    z = a * q0[3] + sign * b * q1[3]
    n = np.sqrt(w * w + x * x + y * y + z * z)
    w, x, y, z = w / n, x / n, y / n, z / n
    out[0, 0] = 1.0 - 2.0 * (y * y + z * z)
    out[0, 1] = 2.0 * (x * y - w * z)
    out[0, 2] = 2.0 * (x * z + w * y)
    out[1, 0] = 2.0 * (x * y + w * z)
    out[1, 1] = 1.0 - 2.0 * (x * x + z * z)
    out[1, 2] = 2.0 * (y * z - w * x)
    out[2, 0] = 2.0 * (x * z - w * y)
    out[2, 1] = 2.0 * (y * z + w * x)
    out[2, 2] = 1.0 - 2.0 * (x * x + y * y)


@nb.njit(cache=PART_CACHE, **NO_REFCOUNT)
def _pose_at(q0, q1, r0, r1, t0, t1, f, rot, trans):
    """A collider's pose at fraction f of the step (the end points exactly as given)."""
    if f <= 0.0 or f >= 1.0:
        end = r0 if f <= 0.0 else r1
        for a in range(3):
            for b in range(3):
                rot[a, b] = end[a, b]
    else:
        _slerp_matrix(q0, q1, f, rot)
    for a in range(3):
        trans[a] = t0[a] + f * (t1[a] - t0[a])


# ---------------------------------------------------------------------- the kernel
@nb.njit(cache=PART_CACHE, fastmath=FASTMATH, error_model="numpy", **NO_REFCOUNT)
def _to_local(rot, trans, x, y, z):
    """World point -> a collider's frame (q = R^T (p - t))."""
    dx, dy, dz = x - trans[0], y - trans[1], z - trans[2]
    return (
        rot[0, 0] * dx + rot[1, 0] * dy + rot[2, 0] * dz,
        rot[0, 1] * dx + rot[1, 1] * dy + rot[2, 1] * dz,
        rot[0, 2] * dx + rot[1, 2] * dy + rot[2, 2] * dz,
    )


@nb.njit(cache=PART_CACHE, fastmath=FASTMATH, error_model="numpy", **NO_REFCOUNT)
def _sample(fvals, fint, fgeo, k, x, y, z):
    """Collider k's signed distance and unit gradient at a point of its frame.

    The colliders' fields travel as one float32 run ``fvals``; ``fint[k]`` is (offset,
    nx, ny, nz) and ``fgeo[k]`` (origin x, y, z, spacing, box top x, y, z, smallest
    value on the box's faces).
    """
    return trilinear(fvals, fint[k, 0], fint[k, 1], fint[k, 2], fint[k, 3], fgeo[k, 0],
                     fgeo[k, 1], fgeo[k, 2], fgeo[k, 3], x, y, z)  # fmt: skip


@nb.njit(cache=PART_CACHE, fastmath=FASTMATH, error_model="numpy", **NO_REFCOUNT)
def _floor_of(fgeo, k, x, y, z):
    """A lower bound of collider k's distance at a point of its frame (no sample needed).

    Outside the field's box the distance is a value on a face of the box (at least
    ``fgeo[k, 7]``) plus the distance along each axis to the box (:func:`trilinear`);
    inside it there is no bound (minus infinity). A collider whose bound is at least what
    a test needs is left unsampled: most particles are far outside every container but
    the one that holds them.
    """
    ex = max(fgeo[k, 0] - x, x - fgeo[k, 4], 0.0)
    ey = max(fgeo[k, 1] - y, y - fgeo[k, 5], 0.0)
    ez = max(fgeo[k, 2] - z, z - fgeo[k, 6], 0.0)
    if ex + ey + ez <= 0.0:
        return -np.inf
    # Less a micrometre: trilinear clamps a hair inside the box (at n - 1.000001 nodes), so
    # the value it interpolates takes a millionth of the next node in.
    return fgeo[k, 7] + ex + ey + ez - 1e-6


@nb.njit(cache=PART_CACHE, **NO_REFCOUNT)
def _sort_cells(p, h, max_cells, keys, order, start, sorted_p, grid):
    """Counting sort of the particles into a dense cell grid over their bounds.

    Cells are numbered z fastest, so the three cells of a column ``(cx, cy, cz-1..cz+1)``
    are one contiguous run of the sorted arrays. The cells are at least h wide, wider when
    the particles spread so far that ``max_cells`` cells of h would not cover them (the
    search stays exact, it checks more pairs). ``grid`` receives (lo x, y, z, cell, nx,
    ny, nz) for :func:`_later_of`.
    """
    n = p.shape[0]
    lx = ly = lz = np.inf
    hx = hy = hz = -np.inf
    for i in range(n):
        lx, hx = min(lx, p[i, 0]), max(hx, p[i, 0])
        ly, hy = min(ly, p[i, 1]), max(hy, p[i, 1])
        lz, hz = min(lz, p[i, 2]), max(hz, p[i, 2])
    lx, ly, lz = lx - 1e-9, ly - 1e-9, lz - 1e-9
    volume = (hx - lx + 1e-9 + h) * (hy - ly + 1e-9 + h) * (hz - lz + 1e-9 + h)
    cell = max(h, (volume / max_cells) ** (1.0 / 3.0))
    nx = int((hx - lx) / cell) + 1
    ny = int((hy - ly) / cell) + 1
    nz = int((hz - lz) / cell) + 1
    while nx * ny * nz > max_cells:  # rounding up the extents can overshoot a little
        cell *= 1.01
        nx = int((hx - lx) / cell) + 1
        ny = int((hy - ly) / cell) + 1
        nz = int((hz - lz) / cell) + 1
    n_cells = nx * ny * nz
    for k in range(n_cells + 1):
        start[k] = 0
    for i in range(n):
        cx = int((p[i, 0] - lx) / cell)
        cy = int((p[i, 1] - ly) / cell)
        cz = int((p[i, 2] - lz) / cell)
        k = (cx * ny + cy) * nz + cz
        keys[i] = k
        start[k + 1] += 1
    for k in range(n_cells):
        start[k + 1] += start[k]
    for i in range(n):
        k = keys[i]
        s = start[k]
        order[s] = i
        sorted_p[s, 0] = p[i, 0]
        sorted_p[s, 1] = p[i, 1]
        sorted_p[s, 2] = p[i, 2]
        start[k] = s + 1
    # Undo the shift the fill loop made: start[k] is again the first slot of cell k.
    for k in range(n_cells, 0, -1):
        start[k] = start[k - 1]
    start[0] = 0
    grid[0], grid[1], grid[2], grid[3] = lx, ly, lz, cell
    grid[4], grid[5], grid[6] = nx, ny, nz


@nb.njit(cache=PART_CACHE, fastmath=FASTMATH, error_model="numpy", **NO_REFCOUNT)
def _later_of(si, h2, grid, order, start, sorted_p, later, n_later):
    """The later neighbours (in sort order) of the particle in sorted slot si.

    Those within sqrt(h2) among the nine column runs around it, in sorted order.
    """
    lx, ly, lz, cell = grid[0], grid[1], grid[2], grid[3]
    nx, ny, nz = int(grid[4]), int(grid[5]), int(grid[6])
    last = later.shape[1] - 1
    px, py, pz = sorted_p[si, 0], sorted_p[si, 1], sorted_p[si, 2]
    cx = int((px - lx) / cell)
    cy = int((py - ly) / cell)
    cz = int((pz - lz) / cell)
    z0 = max(cz - 1, 0)
    z1 = min(cz + 1, nz - 1)
    c = 0
    for ax in range(max(cx - 1, 0), min(cx + 2, nx)):
        for ay in range(max(cy - 1, 0), min(cy + 2, ny)):
            base = (ax * ny + ay) * nz
            for s in range(max(start[base + z0], si + 1), start[base + z1 + 1]):
                rx = px - sorted_p[s, 0]
                ry = py - sorted_p[s, 1]
                rz = pz - sorted_p[s, 2]
                # Branch-free: one candidate in five is a neighbour, which no branch
                # predictor guesses; writing every candidate and advancing the count only
                # for neighbours is 2.5x faster. The last slot takes the overflow.
                later[si, c] = order[s]
                c = min(c + (rx * rx + ry * ry + rz * rz < h2), last)
    n_later[si] = c


@nb.njit(cache=PART_CACHE, fastmath=FASTMATH, error_model="numpy", **NO_REFCOUNT)
def _first_entry(fvals, fint, fgeo, k, sx, sy, sz, qx, qy, qz, radius):
    """Where a straight path from s to q first comes within ``radius`` of collider k's wall.

    Returns the fraction of the path up to there (1.0 when the path never enters the
    material: a path that only grazes the ``radius`` margin is not a crossing), found by
    stepping by the distance to the wall (the field is 1-Lipschitz, so no wall is stepped
    over) and bisecting the last step.
    """
    dx, dy, dz = qx - sx, qy - sy, qz - sz
    length = np.sqrt(dx * dx + dy * dy + dz * dz)
    if length < 1e-12:
        return 1.0
    t = 0.0
    inside = False
    while t < length:
        f = t / length
        d = _sample(fvals, fint, fgeo, k, sx + dx * f, sy + dy * f, sz + dz * f)[0]
        if d < 0.0:
            inside = True
            break
        t += max(d, 2.5e-4)
    if not inside:
        return 1.0
    lo, hi = 0.0, t / length
    for _ in range(20):
        mid = 0.5 * (lo + hi)
        dm = _sample(fvals, fint, fgeo, k, sx + mid * dx, sy + mid * dy, sz + mid * dz)[0]
        if dm > radius:
            lo = mid
        else:
            hi = mid
    return lo


@nb.njit(cache=PART_CACHE, fastmath=FASTMATH, error_model="numpy", **NO_REFCOUNT)
def _collide_one(p, prev, i, k, radius, fvals, fint, fgeo, rot_s, tr_s, rot_e, tr_e, near):
    """Push particle i out of collider k's material; 1 if it had tunnelled into a wall.

    The particle's start-of-substep position is taken into the collider's pose at the
    substep's start, its end into the pose at the end. If the straight path between them
    entered the wall's material from outside (at its end, or on the way through), the
    particle is put back where it entered, on the side it came from: however far it moved,
    it cannot pass through a wall. Then it is pushed along the field's gradient until it is
    a radius off the wall (repeated: one push out of a corner can land near the other wall
    of the corner). A push that carries it out of the far side of a thin wall, or leaves
    it in the material of a crevice too narrow for it, is undone the same way.

    ``near`` is a lower bound of the distance at the particle's end position (from the
    predict pass's sample, less how far the particle has moved since).
    """
    qx, qy, qz = _to_local(rot_e[k], tr_e[k], p[i, 0], p[i, 1], p[i, 2])
    sx, sy, sz = _to_local(rot_s[k], tr_s[k], prev[i, 0], prev[i, 1], prev[i, 2])
    length = np.sqrt((qx - sx) ** 2 + (qy - sy) ** 2 + (qz - sz) ** 2)
    # Far from the wall: nothing to do, and no sample needed (below, d1 would be at least
    # this bound): the fluid inside a container, and everything outside the field's box.
    bound = max(near, _floor_of(fgeo, k, qx, qy, qz))
    if bound >= radius and length < bound:
        return 0
    # With the gradient: a particle near the wall is pushed along it, from this sample.
    d1, gx, gy, gz = _sample(fvals, fint, fgeo, k, qx, qy, qz)
    # Every point of the path is within `length` of its end: a wall farther than that from
    # the end cannot have been crossed (the usual case, decided by one sample).
    if d1 >= radius and length < d1:
        return 0
    tunnelled = 0
    # A path can only have crossed material if its ends are not both far enough from it
    # (Lipschitz again: d0 >= d1 - length, so an end farther out than the path is long
    # rules it out unsampled); a particle that started inside (no side to return to) is
    # only pushed.
    d0 = _sample(fvals, fint, fgeo, k, sx, sy, sz)[0] if d1 <= length else d1
    if d0 > 0.0 and d0 + d1 <= length:
        f = _first_entry(fvals, fint, fgeo, k, sx, sy, sz, qx, qy, qz, radius)
        if f < 1.0:
            qx, qy, qz = sx + f * (qx - sx), sy + f * (qy - sy), sz + f * (qz - sz)
            tunnelled = 1
    if tunnelled:
        d, gx, gy, gz = _sample(fvals, fint, fgeo, k, qx, qy, qz)
    else:
        d = d1
    if d >= radius and tunnelled == 0:
        return 0
    for _ in range(4):
        if d >= radius:
            break
        push = radius - d
        qx, qy, qz = qx + push * gx, qy + push * gy, qz + push * gz
        d, gx, gy, gz = _sample(fvals, fint, fgeo, k, qx, qy, qz)
    span = np.sqrt((qx - sx) ** 2 + (qy - sy) ** 2 + (qz - sz) ** 2)
    if d < 0.0:
        # Pushed from wall to wall in a crevice narrower than a particle (a scan's folds):
        # still in the material, where the gradient may point out of the far side of a
        # thin wall. Stay where the substep started instead, if that was less deep.
        d0 = _sample(fvals, fint, fgeo, k, sx, sy, sz)[0]
        if d0 > d:
            qx, qy, qz = sx, sy, sz
            tunnelled = 1
    elif tunnelled == 0 and span > d:
        # A path that ends inside a thin wall, past its middle, is pushed out of the far
        # side: the push finishes a crossing. Where the path from the start to the pushed
        # position runs through material (only possible if it is at least d0 + d long),
        # the particle is put back where it entered, on the side it came from.
        d0 = _sample(fvals, fint, fgeo, k, sx, sy, sz)[0]
        if d0 > 0.0 and d0 + d <= span:
            f = _first_entry(fvals, fint, fgeo, k, sx, sy, sz, qx, qy, qz, radius)
            if f < 1.0:
                qx, qy, qz = sx + f * (qx - sx), sy + f * (qy - sy), sz + f * (qz - sz)
                tunnelled = 1
    r = rot_e[k]
    t = tr_e[k]
    for a in range(3):
        p[i, a] = r[a, 0] * qx + r[a, 1] * qy + r[a, 2] * qz + t[a]
    return tunnelled


@nb.njit(cache=PART_CACHE, fastmath=FASTMATH, error_model="numpy", **NO_REFCOUNT)
def _wall_term(i, p, wall, floor, has_floor, h, wall_table, fvals, fint, fgeo, rot_e, tr_e,
               near):  # fmt: skip
    """The density the nearest wall stands in for at particle i, and its gradient.

    The wall is a neighbour that does not move, so a particle pressed against it is pushed
    off it by its own constraint (without the gradient a floor layer packs too dense).
    ``wall[i]`` receives (density over rest density, gradient x, y, z), ``near[i, k]`` a
    lower bound of collider k's distance (its sample, or the bound that spared it).
    """
    n_table = wall_table.shape[0]
    w = p[i, 2] - floor if has_floor else 1e9
    nearest = -1
    gx = gy = 0.0
    gz = 1.0
    for k in range(fint.shape[0]):
        lx, ly, lz = _to_local(rot_e[k], tr_e[k], p[i, 0], p[i, 1], p[i, 2])
        # A wall no nearer than the nearest so far, or than the kernel's reach, adds
        # nothing: the bound decides that for most colliders without a sample.
        bound = _floor_of(fgeo, k, lx, ly, lz)
        near[i, k] = bound
        if bound >= min(w, h):
            continue
        dk, ax, ay, az = _sample(fvals, fint, fgeo, k, lx, ly, lz)
        near[i, k] = dk
        if dk < w:
            w, nearest = dk, k
            gx, gy, gz = ax, ay, az
    wall[i, 0] = 0.0
    wall[i, 1] = 0.0
    wall[i, 2] = 0.0
    wall[i, 3] = 0.0
    if w >= h:
        return
    u = max(w, 0.0) / h * (n_table - 1)
    kk = min(int(u), n_table - 2)
    fr = u - kk
    wall[i, 0] = wall_table[kk] * (1.0 - fr) + wall_table[kk + 1] * fr
    if u <= 0.0:  # inside the material the distance gives no slope
        return
    slope = (wall_table[kk + 1] - wall_table[kk]) * (n_table - 1) / h
    nx, ny, nz = 0.0, 0.0, 1.0  # the floor's normal
    if nearest >= 0:
        r = rot_e[nearest]
        nx = r[0, 0] * gx + r[0, 1] * gy + r[0, 2] * gz
        ny = r[1, 0] * gx + r[1, 1] * gy + r[1, 2] * gz
        nz = r[2, 0] * gx + r[2, 1] * gy + r[2, 2] * gz
    wall[i, 1] = slope * nx
    wall[i, 2] = slope * ny
    wall[i, 3] = slope * nz


# ---------------------------------------------------------------------- passes
def _pass_predict(x, v, p, prev, gz, hs, wall_on, wall, floor, has_floor, h, wall_table,
                  fvals, fint, fgeo, rot_e, tr_e, near):  # fmt: skip
    """Gravity, predicted positions (start positions kept), and each particle's wall term."""
    for i in nb.prange(x.shape[0]):
        v[i, 2] += gz * hs
        for a in range(3):
            prev[i, a] = x[i, a]
            p[i, a] = x[i, a] + v[i, a] * hs
        if wall_on:
            _wall_term(i, p, wall, floor, has_floor, h, wall_table, fvals, fint, fgeo, rot_e,
                       tr_e, near)  # fmt: skip
        else:
            for k in range(near.shape[1]):
                near[i, k] = -np.inf


def _pass_neighbours(p, h2, grid, order, start, sorted_p, nbr, nbr_count, later, n_later):
    """Every particle's neighbour list (after :func:`_sort_cells`), each pair tested once.

    A list holds the particle's neighbours in the order of the cell sort (the stencil's
    cells in increasing cell number, each cell's particles in sorted order). Each
    particle's later neighbours in that order are found first (:func:`_later_of`, by
    threads in the parallel build); one thread then enters each such pair in the later
    particle's list, visiting the particles in sorted order, so that every list receives
    its earlier neighbours in order; then the later ones are appended. Both builds make
    the same lists, bit for bit, past the last slot too (which takes an arbitrary
    candidate once a list overflows: a fluid squeezed to twice its density).

    One thread, too, runs it this way rather than entering each pair in both lists as it
    is found (one sweep, which writes two lists and a count at every candidate, four in
    five of which are not neighbours): the pass alone is 1.35x faster at 2000 particles, a
    whole step 1.03x, and the same at 300 (in-process alternations, 2026-12-03).
    """
    n = p.shape[0]
    last = nbr.shape[1] - 1
    for si in nb.prange(n):
        _later_of(si, h2, grid, order, start, sorted_p, later, n_later)
    for i in range(n):
        nbr_count[i] = 0
    for si in range(n):
        i = order[si]
        for q in range(n_later[si]):
            j = later[si, q]
            c = nbr_count[j]
            nbr[j, c] = i
            nbr_count[j] = min(c + 1, last)
    for si in nb.prange(n):
        i = order[si]
        c = nbr_count[i]
        for q in range(n_later[si]):
            nbr[i, c] = later[si, q]
            c = min(c + 1, last)
        nbr_count[i] = c


def _pass_lambda(src, nbr, nbr_count, pair_g, pair_s, lam, wall_on, wall, h, c_poly, c_spiky,
                 inv_wdq, scorr, tension, eps, chunks):  # fmt: skip
    """Each particle's multiplier from its density; keeps the pair terms for the correction.

    The particles are split into ``chunks`` runs (spread over the threads in the parallel
    build), each one call of :func:`_lambda_run`.
    """
    n = src.shape[0]
    for t in nb.prange(chunks):
        _lambda_run(t * n // chunks, (t + 1) * n // chunks, src, nbr, nbr_count, pair_g, pair_s,
                    lam, wall_on, wall, h, c_poly, c_spiky, inv_wdq, scorr, tension,
                    eps)  # fmt: skip


@nb.njit(
    cache=PART_CACHE, fastmath=FASTMATH | {"reassoc"}, error_model="numpy", **NO_REFCOUNT, **NOALIAS
)
def _lambda_run(lo, hi, src, nbr, nbr_count, pair_g, pair_s, lam, wall_on, wall, h, c_poly,
                c_spiky, inv_wdq, scorr, tension, eps):  # fmt: skip
    """The multipliers of particles lo to hi (:func:`_pass_lambda`).

    Compiled with reassociation, the one part of the kernel that is: LLVM vectorises the
    neighbour loop's sums only if it may reorder them. The order it picks is fixed in this
    compiled function, which both builds call, so they agree bit for bit
    (``tests/test_fluid.py`` checks serial against parallel, compiled against cached).
    """
    h2 = h * h
    w0 = c_poly * h2 * h2 * h2
    for i in range(lo, hi):
        m = nbr_count[i]
        xi, yi, zi = src[i, 0], src[i, 1], src[i, 2]
        rho = w0
        gx = 0.0
        gy = 0.0
        gz = 0.0
        sum2 = 0.0
        for q in range(m):
            j = nbr[i, q]
            rx = xi - src[j, 0]
            ry = yi - src[j, 1]
            rz = zi - src[j, 2]
            r2 = rx * rx + ry * ry + rz * rz
            inside = r2 < h2
            d2 = h2 - r2 if inside else 0.0
            w = c_poly * d2 * d2 * d2
            r = np.sqrt(r2)
            g = c_spiky * (h - r) * (h - r) / max(r, 1e-12) if inside else 0.0
            ratio = w * inv_wdq
            ratio2 = ratio * ratio
            pair_g[i, q] = g
            pair_s[i, q] = -scorr * ratio2 * ratio2
            rho += w
            gx += g * rx
            gy += g * ry
            gz += g * rz
            sum2 += g * g * r2
        if wall_on:
            rho += wall[i, 0]
            gx += wall[i, 1]
            gy += wall[i, 2]
            gz += wall[i, 3]
        c = rho - 1.0
        if c < -tension:
            c = -tension  # limited tension: a free surface is not pulled together
        lam[i] = -c / (sum2 + gx * gx + gy * gy + gz * gz + eps)


def _pass_correct(src, dst, nbr, nbr_count, pair_g, pair_s, lam, wall_on, wall, omega,
                  chunks):  # fmt: skip
    """Jacobi correction of every position: read from ``src``, written to ``dst``."""
    n = src.shape[0]
    for t in nb.prange(chunks):
        _correct_run(t * n // chunks, (t + 1) * n // chunks, src, dst, nbr, nbr_count, pair_g,
                     pair_s, lam, wall_on, wall, omega)  # fmt: skip


@nb.njit(cache=PART_CACHE, fastmath=FASTMATH, error_model="numpy", **NO_REFCOUNT, **NOALIAS)
def _correct_run(lo, hi, src, dst, nbr, nbr_count, pair_g, pair_s, lam, wall_on, wall, omega):
    """Particles lo to hi of :func:`_pass_correct`."""
    for i in range(lo, hi):
        dx = 0.0
        dy = 0.0
        dz = 0.0
        li = lam[i]
        for q in range(nbr_count[i]):
            j = nbr[i, q]
            g = pair_g[i, q] * (li + lam[j] + pair_s[i, q])
            dx += g * (src[i, 0] - src[j, 0])
            dy += g * (src[i, 1] - src[j, 1])
            dz += g * (src[i, 2] - src[j, 2])
        if wall_on:
            dx += li * wall[i, 1]
            dy += li * wall[i, 2]
            dz += li * wall[i, 3]
        dst[i, 0] = src[i, 0] + omega * dx
        dst[i, 1] = src[i, 1] + omega * dy
        dst[i, 2] = src[i, 2] + omega * dz


def _pass_collide(p, src, prev, x, v, vn, hs, limit, radius, floor, has_floor, corrected, near,
                  fvals, fint, fgeo, rot_s, tr_s, rot_e, tr_e, wall_speed):  # fmt: skip
    """Positions from ``src`` into ``p``, limited, out of the walls; displacement velocities.

    ``near`` bounds each field's distance at the predicted positions, ``prev + v * hs``
    (the predict pass's).
    """
    wall_travel = wall_speed * hs
    for i in nb.prange(p.shape[0]):
        # The predicted position, as the predict pass computed it (bit for bit).
        px = prev[i, 0] + v[i, 0] * hs
        py = prev[i, 1] + v[i, 1] * hs
        pz = prev[i, 2] + v[i, 2] * hs
        for a in range(3):
            p[i, a] = src[i, a]
        # No particle moves farther than the CFL bound in one substep, pressure or not.
        dx = p[i, 0] - prev[i, 0]
        dy = p[i, 1] - prev[i, 1]
        dz = p[i, 2] - prev[i, 2]
        d = np.sqrt(dx * dx + dy * dy + dz * dz)
        if d > limit:
            f = limit / d
            dx, dy, dz, d = f * dx, f * dy, f * dz, limit
            p[i, 0] = prev[i, 0] + dx
            p[i, 1] = prev[i, 1] + dy
            p[i, 2] = prev[i, 2] + dz
        for k in range(fint.shape[0]):
            # The predict pass sampled each field at the predicted position, in the end
            # pose. A trilinear field of distances changes by at most sqrt(3) times the
            # distance moved (each axis's slope is at most 1), so the distance now is at
            # least that sample less twice how far the particle moved since.
            mx, my, mz = p[i, 0] - px, p[i, 1] - py, p[i, 2] - pz
            bound = near[i, k] - 2.0 * np.sqrt(mx * mx + my * my + mz * mz) - 1e-6
            if bound >= radius:
                # The path in the collider's frame, as _collide_one takes it: a path
                # shorter than the wall is far cannot have touched it (the usual case, a
                # particle well inside a container, ends here without a call).
                r, c = rot_e[k], tr_e[k]
                ex, ey, ez = p[i, 0] - c[0], p[i, 1] - c[1], p[i, 2] - c[2]
                qx = r[0, 0] * ex + r[1, 0] * ey + r[2, 0] * ez
                qy = r[0, 1] * ex + r[1, 1] * ey + r[2, 1] * ez
                qz = r[0, 2] * ex + r[1, 2] * ey + r[2, 2] * ez
                r, c = rot_s[k], tr_s[k]
                ex, ey, ez = prev[i, 0] - c[0], prev[i, 1] - c[1], prev[i, 2] - c[2]
                sx = r[0, 0] * ex + r[1, 0] * ey + r[2, 0] * ez
                sy = r[0, 1] * ex + r[1, 1] * ey + r[2, 1] * ez
                sz = r[0, 2] * ex + r[1, 2] * ey + r[2, 2] * ez
                length = np.sqrt((qx - sx) ** 2 + (qy - sy) ** 2 + (qz - sz) ** 2)
                if length < bound:
                    continue
            corrected[i] += _collide_one(p, prev, i, k, radius, fvals, fint, fgeo, rot_s, tr_s,
                                         rot_e, tr_e, bound)  # fmt: skip
        if has_floor and p[i, 2] < floor + radius:
            p[i, 2] = floor + radius
        # The push out of a wall moves the particle, but gives it no more speed than it
        # came in with plus the wall's: a push out of a fold deeper than its own motion (a
        # scan's wall folds, a crevice) would otherwise fling it out of the container.
        ex = p[i, 0] - prev[i, 0] - dx
        ey = p[i, 1] - prev[i, 1] - dy
        ez = p[i, 2] - prev[i, 2] - dz
        e = np.sqrt(ex * ex + ey * ey + ez * ez)
        most = d + wall_travel
        s = most / e if e > most else 1.0
        vn[i, 0] = (prev[i, 0] + dx + s * ex - x[i, 0]) / hs
        vn[i, 1] = (prev[i, 1] + dy + s * ey - x[i, 1]) / hs
        vn[i, 2] = (prev[i, 2] + dz + s * ez - x[i, 2]) / hs


def _pass_viscosity(vn, v, b, vw, p, nbr, nbr_count, pair_g, lam, h, c_lap, lap_rest, nu_hs,
                    sweeps, no_slip, fvals, fint, fgeo, rot_s, tr_s, rot_e, tr_e, hs, floor,
                    has_floor, near, prev, chunks):  # fmt: skip
    """Implicit viscosity: ``sweeps`` Jacobi sweeps of (1 - nu hs L) v = vn, into ``vn``.

    ``L`` is the SPH Laplacian in Brookshaw's form (:func:`_lap_weight`), ``nu_hs`` the
    kinematic viscosity times the substep (m^2). With ``no_slip`` the walls and the table
    take part as the half-space of fluid beyond them would, moving with the wall (a
    liquid sticks to its container: what makes a viscous pour slow). Each sweep sets a
    particle's velocity to a weighted mean of its own start velocity, its neighbours' last
    iterate and its walls' velocities, so no number of sweeps and no viscosity can make it
    grow: stable from water to honey. ``b``, ``v``, ``vw``, ``pair_g`` and ``lam`` are
    scratch (the start velocities, the next iterate, the walls' weighted velocities, the
    pair weights and the weights' sums). ``near`` bounds each wall's distance at the
    predicted positions ``prev + v hs`` (the predict pass's; ``v`` still holds the
    velocities it predicted with when the weights are made): a wall that cannot be within
    h of where the particle is now is not sampled.
    """
    n = vn.shape[0]
    for t in nb.prange(chunks):
        _visc_weights(t * n // chunks, (t + 1) * n // chunks, vn, b, vw, p, nbr, nbr_count,
                      pair_g, lam, h, c_lap, lap_rest, no_slip, fvals, fint, fgeo, rot_s,
                      tr_s, rot_e, tr_e, hs, floor, has_floor, near, prev, v)  # fmt: skip
    # The iterates alternate between vn and v (no copy a sweep); an odd count ends in v.
    src, dst = vn, v
    for _ in range(sweeps):
        for t in nb.prange(chunks):
            _visc_sweep(t * n // chunks, (t + 1) * n // chunks, src, dst, b, vw, nbr,
                        nbr_count, pair_g, lam, nu_hs)  # fmt: skip
        src, dst = dst, src
    if sweeps % 2 == 1:
        for i in nb.prange(n):
            for a in range(3):
                vn[i, a] = v[i, a]


@nb.njit(cache=PART_CACHE, fastmath=FASTMATH, error_model="numpy", **NO_REFCOUNT)
def _lap_weight(r, h, c_lap):
    """Brookshaw's Laplacian weight of a pair at distance r: -2 W'(r) / r, spiky kernel.

    ``c_lap`` scales it so that the sum over a cubic lattice at the rest spacing gives the
    Laplacian of a quadratic exactly (computed in Python, ``laplacian_scale``); the
    distance is floored at h / 10 (no two particles come that close at any density here).
    """
    if r >= h:
        return 0.0
    d = h - r
    return c_lap * d * d / max(r, 0.1 * h)


@nb.njit(cache=PART_CACHE, fastmath=FASTMATH, error_model="numpy", **NO_REFCOUNT)
def _wall_lap(d, h, lap_rest):
    """The no-slip Laplacian weight of the wall at distance d, towards the wall's velocity.

    The continuum sum of :func:`_lap_weight` over the half-space beyond a wall at distance
    d is ``((h - d) / h)^4`` times half the whole neighbourhood's (``lap_rest``). Fluid
    mirrored beyond the wall moves at ``2 v_wall - v_i`` (Morris, Fox and Zhu 1997, the
    usual no-slip condition of SPH): its pull on ``v_i`` is that of twice the weight
    towards ``v_wall``, so the weight is ``lap_rest ((h - d) / h)^4``.
    """
    if d >= h:
        return 0.0
    u = (h - max(d, 0.0)) / h
    return lap_rest * u * u * u * u


@nb.njit(cache=PART_CACHE, fastmath=FASTMATH, error_model="numpy", **NO_REFCOUNT, **NOALIAS)
def _visc_weights(lo, hi, vn, b, vw, p, nbr, nbr_count, pair_g, lam, h, c_lap, lap_rest,
                  no_slip, fvals, fint, fgeo, rot_s, tr_s, rot_e, tr_e, hs, floor,
                  has_floor, near, prev, v):  # fmt: skip
    """Particles lo to hi of :func:`_pass_viscosity`'s set-up: start velocities, weights."""
    for i in range(lo, hi):
        total = 0.0
        for q in range(nbr_count[i]):
            j = nbr[i, q]
            rx = p[i, 0] - p[j, 0]
            ry = p[i, 1] - p[j, 1]
            rz = p[i, 2] - p[j, 2]
            w = _lap_weight(np.sqrt(rx * rx + ry * ry + rz * rz), h, c_lap)
            pair_g[i, q] = w
            total += w
        wx = 0.0
        wy = 0.0
        wz = 0.0
        if no_slip:
            px, py, pz = p[i, 0], p[i, 1], p[i, 2]
            # How far the particle is from where the predict pass bounded the walls'
            # distances (a field's distance changes by at most twice the way moved).
            mx = px - (prev[i, 0] + v[i, 0] * hs)
            my = py - (prev[i, 1] + v[i, 1] * hs)
            mz = pz - (prev[i, 2] + v[i, 2] * hs)
            moved = 2.0 * np.sqrt(mx * mx + my * my + mz * mz) + 1e-6
            for k in range(fint.shape[0]):
                if near[i, k] - moved >= h:
                    continue
                qx, qy, qz = _to_local(rot_e[k], tr_e[k], px, py, pz)
                if _floor_of(fgeo, k, qx, qy, qz) >= h:
                    continue
                d = _sample(fvals, fint, fgeo, k, qx, qy, qz)[0]
                w = _wall_lap(d, h, lap_rest)
                if w <= 0.0:
                    continue
                # The wall's velocity here: where this point of the container was at the
                # substep's start, and where it is now.
                r, c = rot_s[k], tr_s[k]
                sx = r[0, 0] * qx + r[0, 1] * qy + r[0, 2] * qz + c[0]
                sy = r[1, 0] * qx + r[1, 1] * qy + r[1, 2] * qz + c[1]
                sz = r[2, 0] * qx + r[2, 1] * qy + r[2, 2] * qz + c[2]
                wx += w * (px - sx) / hs
                wy += w * (py - sy) / hs
                wz += w * (pz - sz) / hs
                total += w
            if has_floor:
                total += _wall_lap(pz - floor, h, lap_rest)  # the table stands still
        lam[i] = total
        vw[i, 0] = wx
        vw[i, 1] = wy
        vw[i, 2] = wz
        for a in range(3):
            b[i, a] = vn[i, a]


@nb.njit(cache=PART_CACHE, fastmath=FASTMATH, error_model="numpy", **NO_REFCOUNT, **NOALIAS)
def _visc_sweep(lo, hi, vn, v, b, vw, nbr, nbr_count, pair_g, lam, nu_hs):
    """Particles lo to hi of one Jacobi sweep: ``v`` from ``vn`` (the last iterate)."""
    for i in range(lo, hi):
        sx = vw[i, 0]
        sy = vw[i, 1]
        sz = vw[i, 2]
        for q in range(nbr_count[i]):
            j = nbr[i, q]
            w = pair_g[i, q]
            sx += w * vn[j, 0]
            sy += w * vn[j, 1]
            sz += w * vn[j, 2]
        inv = 1.0 / (1.0 + nu_hs * lam[i])
        v[i, 0] = (b[i, 0] + nu_hs * sx) * inv
        v[i, 1] = (b[i, 1] + nu_hs * sy) * inv
        v[i, 2] = (b[i, 2] + nu_hs * sz) * inv


def _pass_finish(x, v, vn, p, nbr, nbr_count, h, xsph, floor, has_floor, radius, decay, chunks):
    """XSPH-smoothed velocities, positions taken, table friction (:func:`_finish_run`)."""
    n = x.shape[0]
    for t in nb.prange(chunks):
        _finish_run(t * n // chunks, (t + 1) * n // chunks, x, v, vn, p, nbr, nbr_count, h,
                    xsph, floor, has_floor, radius, decay)  # fmt: skip


@nb.njit(cache=PART_CACHE, fastmath=FASTMATH, error_model="numpy", **NO_REFCOUNT, **NOALIAS)
def _finish_run(lo, hi, x, v, vn, p, nbr, nbr_count, h, xsph, floor, has_floor, radius, decay):
    """Particles lo to hi of :func:`_pass_finish`."""
    h2 = h * h
    inv_self = 1.0 / (h2 * h2 * h2)  # poly6 over its value at r = 0
    for i in range(lo, hi):
        sx = 0.0
        sy = 0.0
        sz = 0.0
        for q in range(nbr_count[i]):
            j = nbr[i, q]
            rx = p[i, 0] - p[j, 0]
            ry = p[i, 1] - p[j, 1]
            rz = p[i, 2] - p[j, 2]
            r2 = rx * rx + ry * ry + rz * rz
            d = h2 - r2 if r2 < h2 else 0.0
            w = d * d * d * inv_self
            sx += (vn[j, 0] - vn[i, 0]) * w
            sy += (vn[j, 1] - vn[i, 1]) * w
            sz += (vn[j, 2] - vn[i, 2]) * w
        v[i, 0] = vn[i, 0] + xsph * sx
        v[i, 1] = vn[i, 1] + xsph * sy
        v[i, 2] = vn[i, 2] + xsph * sz
        # x is not read in this pass (vn holds the displacement): it takes p here.
        for a in range(3):
            x[i, a] = p[i, a]
        # Water on a table comes to rest instead of gliding away forever.
        if has_floor and x[i, 2] < floor + radius + 1e-6:
            v[i, 0] *= decay
            v[i, 1] *= decay


def _advance(
    x, v, dt, h_max, limit, gz, floor, floor_decay, h, vol, eps, scorr, w_dq, iterations,
    tension, omega, wall_on, wall_table, radius, xsph, viscosity, c_lap, lap_rest, no_slip,
    fvals, fint, fgeo, q0, q1, r0, r1, t0, t1, wall_speed, p, p2, prev, vn, lam, wall, nbr,
    nbr_count, pair_g, pair_s, keys, order, start, sorted_p, grid, corrected, rot_s, tr_s,
    rot_e, tr_e, chunks, near, later, n_later,
):  # fmt: skip
    """All substeps of one step of ``dt`` s; returns the number of substeps.

    Compiled twice (:data:`_ADVANCE`): calling the serial passes (no threading layer is
    loaded) or their parallel builds. ``floor`` is -inf for none. Colliders: their fields
    (``fvals``, ``fint``, ``fgeo``: see :func:`_sample`) and poses from (``q0``/``r0``,
    ``t0``) to (``q1``/``r1``, ``t1``) over the step, walls moving at most ``wall_speed``
    m/s. ``chunks`` is how many runs the density, correction and velocity passes split the
    particles into. The rest is scratch space sized to the particles.
    """
    n = x.shape[0]
    n_col = fint.shape[0]
    h2 = h * h
    has_floor = floor > -1e300
    # Kernel constants, with the particle volume m / rho_0 folded in.
    c_poly = 315.0 / (64.0 * np.pi * h**9) * vol
    c_spiky = -45.0 / (np.pi * h**6) * vol
    inv_wdq = 1.0 / (w_dq * vol)
    g_abs = abs(gz)
    t = 0.0
    n_sub = 0
    while dt - t > 1e-12 * dt and n_sub < MAX_SUBSTEPS:
        # The CFL bound at this substep's speeds (pressure may speed particles up within
        # a step; a substep count fixed at its start could not follow).
        vmax = 0.0
        for i in range(n):
            s2 = v[i, 0] * v[i, 0] + v[i, 1] * v[i, 1] + v[i, 2] * v[i, 2]
            vmax = max(vmax, s2)
        vmax = max(np.sqrt(vmax) + g_abs * h_max, wall_speed)
        hs = h_max
        if vmax * hs > limit:
            hs = limit / vmax
        rest = dt - t
        # Even substeps to the end of the step, none of them longer than hs.
        hs = rest / np.ceil(rest / hs - 1e-9)
        f0 = t / dt
        f1 = min((t + hs) / dt, 1.0)
        for k in range(n_col):
            _pose_at(q0[k], q1[k], r0[k], r1[k], t0[k], t1[k], f0, rot_s[k], tr_s[k])
            _pose_at(q0[k], q1[k], r0[k], r1[k], t0[k], t1[k], f1, rot_e[k], tr_e[k])
        _pass_predict(x, v, p, prev, gz, hs, wall_on, wall, floor, has_floor, h, wall_table,
                      fvals, fint, fgeo, rot_e, tr_e, near)  # fmt: skip
        _sort_cells(p, h, start.shape[0] - 1, keys, order, start, sorted_p, grid)
        _pass_neighbours(p, h2, grid, order, start, sorted_p, nbr, nbr_count, later, n_later)
        # Jacobi iterations, reading positions from `src` and writing the corrected ones
        # to `dst` (then swapped), so no separate pass applies the corrections.
        src, dst = p, p2
        for _ in range(iterations):
            _pass_lambda(src, nbr, nbr_count, pair_g, pair_s, lam, wall_on, wall, h, c_poly,
                         c_spiky, inv_wdq, scorr, tension, eps, chunks)  # fmt: skip
            _pass_correct(src, dst, nbr, nbr_count, pair_g, pair_s, lam, wall_on, wall, omega,
                          chunks)  # fmt: skip
            src, dst = dst, src
        _pass_collide(p, src, prev, x, v, vn, hs, limit, radius, floor, has_floor, corrected, near,
                      fvals, fint, fgeo, rot_s, tr_s, rot_e, tr_e, wall_speed)  # fmt: skip
        if viscosity > 0.0:
            # Enough Jacobi sweeps that the slowest (smoothest) mode, whose error shrinks
            # by D / (1 + D) a sweep, keeps under VISC_TOL of it (D: the diagonal at rest).
            diag = viscosity * hs * lap_rest
            sweeps = 1
            if diag > 0.0:
                sweeps = int(min(max(np.ceil(np.log(VISC_TOL) / np.log(diag / (1.0 + diag))),
                                     1.0), MAX_VISC_SWEEPS))  # fmt: skip
            # The scratch of the sort (sorted_p) holds the walls' velocities: the neighbour
            # lists are made.
            _pass_viscosity(vn, v, p2, sorted_p, p, nbr, nbr_count, pair_g, lam, h, c_lap,
                            lap_rest, viscosity * hs, sweeps, no_slip, fvals, fint, fgeo,
                            rot_s, tr_s, rot_e, tr_e, hs, floor, has_floor, near, prev,
                            chunks)  # fmt: skip
        _pass_finish(x, v, vn, p, nbr, nbr_count, h, xsph, floor, has_floor, radius,
                     np.exp(-floor_decay * hs), chunks)  # fmt: skip
        t += hs
        n_sub += 1
    return n_sub


@nb.njit(cache=True)
def _wall_distance(p, out, values, nx, ny, nz, origin, spacing, rot, trans):
    """out[i] = min(out[i], signed distance of particle i to one container's material)."""
    for i in range(p.shape[0]):
        qx, qy, qz = _to_local(rot, trans, p[i, 0], p[i, 1], p[i, 2])
        ox, oy, oz = origin[0], origin[1], origin[2]
        d = trilinear(values, 0, nx, ny, nz, ox, oy, oz, spacing, qx, qy, qz)[0]
        if d < out[i]:
            out[i] = d
