"""Chapter 5.1 features against closed forms."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from pour_gym.features import (
    container_geometry,
    count_volume,
    density_volume,
    fluid_features,
    held_by_tilt,
    inside_container,
    lip_point,
    relative_distance_height,
)


@pytest.fixture(scope="module")
def red(models):
    m = models["red_cup"]
    return m, container_geometry(m.mesh, m.labels)


def test_geometry_of_the_red_cup(red):
    _, g = red
    assert g.rim_radius == pytest.approx(0.040, rel=0.01)
    assert g.height == pytest.approx(0.087, rel=0.02)
    assert g.cavity_volume == pytest.approx(265e-6, rel=0.02)
    # The thesis's convex hull of the container vertices stops at the rim band.
    assert g.container_volume < g.cavity_volume
    assert g.lip_point[2] == pytest.approx(g.rim_vertices[:, 2].min())


def test_f1_f2_closed_forms_in_any_pose(red):
    _, g = red
    rot = Rotation.from_euler("z", 40, degrees=True).as_matrix()
    pos = np.array([0.3, -0.1, 0.7])
    c = rot @ g.rim_center + pos
    pts = np.array(
        [
            c + np.array([g.rim_radius, 0, 0]),  # above the rim: f1 = 1
            c + np.array([0, 0.5 * g.rim_radius, 0.02]),  # above the opening
            c + np.array([0, 3 * g.rim_radius, -g.height]),  # beside the object, at its base
        ]
    )
    f1, f2 = relative_distance_height(g, pts, rot, pos)
    assert f1 == pytest.approx([1.0, 0.5, 3.0])
    assert f2 == pytest.approx([0.0, 0.02 / g.height, -1.0])


def test_lip_point_follows_the_tilt(red):
    _, g = red
    # Tilting about +y by 30 deg lowers the +x side of the rim.
    rot = Rotation.from_euler("y", 30, degrees=True).as_matrix()
    lip = lip_point(g, rot, np.zeros(3))
    local = rot.T @ lip
    assert local[0] == pytest.approx(g.rim_vertices[:, 0].max(), abs=2e-3)


def lattice_in_cavity(g, spacing):
    lo = g.cavity.origin
    hi = lo + np.array(g.cavity.mask.shape) * g.cavity.voxel
    axes = [np.arange(a + spacing / 2, b, spacing) for a, b in zip(lo, hi, strict=True)]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    return grid[g.cavity.contains(grid)]


def test_f3_and_f4_of_a_full_cup(red):
    _, g = red
    h = 0.004
    fluid = lattice_in_cavity(g, h)
    v = h**3
    f3, f4 = fluid_features(g, fluid, np.eye(3), np.zeros(3), v)
    assert f3 == pytest.approx(len(fluid) * v / g.cavity_volume)
    assert f3 == pytest.approx(1.0, abs=0.06)  # a lattice fills the cavity up to its edge
    # Upright, only the water within the lip's own band (the lowest rim vertex is at the
    # bottom of the rounded lip) is above the lip point.
    lip_z = g.lip_point[2]
    assert f4 == pytest.approx(np.count_nonzero(fluid[:, 2] > lip_z) * v / g.cavity_volume)
    assert f4 < 0.1
    rot = Rotation.from_euler("y", 30, degrees=True).as_matrix()
    moved = fluid @ rot.T
    assert np.array_equal(inside_container(g, moved, rot, np.zeros(3)), np.ones(len(fluid), bool))
    f3t, f4t = fluid_features(g, moved, rot, np.zeros(3), v)
    lip_z = lip_point(g, rot, np.zeros(3))[2]
    assert f3t == pytest.approx(f3)
    assert f4t == pytest.approx(np.count_nonzero(moved[:, 2] > lip_z) * v / g.cavity_volume)
    assert f4t > f4 + 0.1  # tilted 30 deg, a full cup has much more fluid above its lip


@pytest.mark.parametrize("shape", [(10, 10, 10), (20, 20, 10)])
def test_density_and_count_volumes_agree_on_resting_fluid(shape):
    h = 0.005
    grid = np.stack(np.meshgrid(*[np.arange(n) * h for n in shape], indexing="ij"), -1)
    pts = grid.reshape(-1, 3)
    counted = count_volume(len(pts), h**3)
    assert density_volume(pts, 0.5 * h) == pytest.approx(counted, rel=0.05)
    # With the thesis's sigma (1 cm, twice this spacing) the estimate is far off.
    assert density_volume(pts, 0.01) > 1.4 * counted


def test_a_sill_raises_the_held_volume_by_the_free_surface_times_its_height(red):
    """Tilted 45 deg, raising the level by s adds the water surface's area times s."""
    from pour_gym.features import cavity_points, held_volume

    _, g = red
    pts = cavity_points(g)
    rot = Rotation.from_euler("y", 45, degrees=True).as_matrix()
    up = rot[2]
    lip = float((g.rim_vertices @ up).min())
    # The free surface's area, from the cavity voxels in a 1 mm slab at the lip level.
    slab = np.count_nonzero(np.abs(pts @ up - (lip + 0.0025)) < 0.0005) * g.cavity.voxel**3
    area = slab / 0.001
    added = held_volume(g, rot, pts, sill=0.005) - held_volume(g, rot, pts)
    assert added == pytest.approx(area * 0.005, rel=0.15)
    assert held_volume(g, rot, pts, sill=0.0) == held_volume(g, rot, pts)


def test_what_a_source_holds_by_tilt_is_its_mouth_volume_at_each_degree(red):
    """Binned once, counted per tilt: the voxels below the mouth as mouth_volume counts them
    (exactly for a tilt about a grid axis, within a voxel's rounding about another)."""
    from pour_gym.envs.holders import SourceFrame
    from pour_gym.features import cavity_points, mouth_volume
    from pour_gym.sim.rotations import about_z

    _, g = red
    pts = cavity_points(g)
    for turn, rel in ((np.pi, 1e-12), (0.7, 2e-3)):
        frame = SourceFrame(about_z(turn), np.zeros(3))
        held = held_by_tilt(g, frame.rotation, 135.0)
        assert held.shape == (136,) and np.all(np.diff(held) <= 0.01 * held[0])
        for tilt in (0, 17, 33, 60, 73, 100):
            exact = mouth_volume(g, frame.rotation(float(tilt)), pts)
            assert held[tilt] == pytest.approx(exact, rel=rel, abs=1e-9), tilt


def test_a_cylinder_holds_what_tan_theta_says_when_tilted(tmp_path):
    """A straight cylinder of radius R and depth H holds pi R^2 (H - R tan(theta)) while the
    water covers its bottom: the onset of a fill h is tan(theta) = (H - h) / R."""
    from pour_gym.assets.containers import resolve_asset
    from pour_gym.envs.actions import onset_tilt
    from pour_gym.envs.holders import SourceFrame
    from pour_gym.objects import cylinder_cup
    from pour_gym.sim.rotations import about_z

    radius, height, base = 0.03, 0.1, 0.006
    # The cylinder of TiltPour-v0's onset test, labelled once for both (cached by content).
    path = tmp_path / "cylinder.stl"
    cylinder_cup(radius, height, 0.004, base).export(path)
    g = resolve_asset(path).geometry
    held = held_by_tilt(g, SourceFrame(about_z(np.pi), np.zeros(3)).rotation, 135.0)
    depth = height - base
    for fill in (0.5, 0.6, 0.7, 0.8):
        volume = np.pi * radius**2 * depth * fill
        analytic = np.degrees(np.arctan(depth * (1.0 - fill) / radius))
        assert onset_tilt(held, volume) == pytest.approx(analytic, abs=1.5), fill
