"""Label-free container measures against closed forms."""

import numpy as np
import pytest
import trimesh

from pour_gym.errors import InputError
from pour_gym.mesh.measure import chamfer_distance, container_dimensions, holding_volume
from pour_gym.objects import cylinder_cup


def test_holding_volume_of_a_cylinder_cup():
    r, h, w, b = 0.04, 0.09, 0.004, 0.006
    cup = cylinder_cup(r - w, h, w, b, sections=128)
    # Polygon area of 128 sections, times the height of the cavity.
    n = 128
    area = 0.5 * n * (r - w) ** 2 * np.sin(2 * np.pi / n)
    expected = area * (h - b)
    assert holding_volume(cup, voxel=4e-4) == pytest.approx(expected, rel=0.01)


def test_dimensions_of_a_cylinder_cup():
    cup = cylinder_cup(0.036, 0.09)
    d = container_dimensions(cup)
    assert d.height == pytest.approx(0.09, rel=1e-6)
    # The top band is the flat annulus from r = 0.036 to 0.040: its vertices are the two
    # rings, so their mean distance to the centre is the mid radius.
    assert d.rim_radius == pytest.approx(0.038, rel=0.01)


def test_a_closed_box_holds_nothing():
    box = trimesh.creation.box([0.05, 0.05, 0.05])
    assert holding_volume(box) == 0.0


def test_holding_volume_rejects_open_meshes():
    cup = cylinder_cup(0.036, 0.09)
    open_cup = cup.copy()
    open_cup.update_faces(np.arange(len(cup.faces)) % 7 != 0)
    with pytest.raises(InputError, match="not closed"):
        holding_volume(open_cup)


def test_chamfer_distance_of_a_shifted_sphere():
    a = trimesh.creation.icosphere(subdivisions=4, radius=0.05)
    b = a.copy()
    b.apply_translation([0.001, 0, 0])
    assert chamfer_distance(a, a) < 1e-6
    # A sphere shifted by d along x: a point at polar angle t is d*|cos t| off the other
    # surface (to first order); the mean of |cos t| over a sphere is 1/2.
    assert chamfer_distance(a, b) == pytest.approx(0.0005, rel=0.05)
