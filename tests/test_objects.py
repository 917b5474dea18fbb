"""The thesis objects: dimensions against Tables 4.1-4.3, watertightness, walls, labels."""

import numpy as np
import pytest
import trimesh

from pour_gym.errors import InputError
from pour_gym.mesh.measure import container_dimensions
from pour_gym.objects import CUP_NAMES, OBJECT_NAMES, SPECS, build_object, get_spec
from pour_gym.parts import Part

# Thesis Tables 4.1-4.3, real values (cm, cm, ml), typed in again here on purpose.
THESIS_REAL = {
    "red_cup": (8.70, 4.00, 265),
    "broad_cup": (8.80, 5.00, 452),
    "high_cup": (10.20, 4.50, 435),
    "small_base_broad_rim_cup": (10.0, 4.50, 296),
    "standard_cup": (8.30, 4.35, 324),
    "very_broad_cup": (8.90, 5.60, 450),
    "very_small_cup": (6.70, 3.85, 170),
    "standard_bowl": (8.00, 8.5, 1038),
    "square_bowl": (6.50, 7.50, 680),
}


def test_catalogue_is_the_thesis_nine():
    assert set(OBJECT_NAMES) == set(THESIS_REAL)
    assert set(CUP_NAMES) == set(OBJECT_NAMES) - {"standard_bowl", "square_bowl"}


@pytest.mark.parametrize("name", OBJECT_NAMES)
def test_dimensions_match_thesis_within_2_percent(models, name):
    model = models[name]
    h_cm, r_cm, v_ml = THESIS_REAL[name]
    labels, v = model.labels, model.mesh.vertices
    # Thesis 5.1: rim centre = mean of rim vertices, radius = mean distance to it,
    # height = rim centre above the lowest vertex (within half a wall of the lip's top).
    rim = v[labels == Part.RIM]
    centre = rim.mean(axis=0)
    radius = np.linalg.norm(rim - centre, axis=1).mean()
    assert radius == pytest.approx(r_cm / 100, rel=0.02)
    assert v[:, 2].max() - v[:, 2].min() == pytest.approx(h_cm / 100, rel=0.02)
    assert centre[2] - v[:, 2].min() == pytest.approx(h_cm / 100, rel=0.02)
    # Volume three ways: exact for the faceted profile, the closed cavity surface, and the
    # label-free flood fill of the solid.
    assert model.cavity_volume == pytest.approx(v_ml * 1e-6, rel=0.02)
    cavity = model.cavity_mesh()
    assert cavity.is_watertight
    assert cavity.volume == pytest.approx(v_ml * 1e-6, rel=0.02)
    dims = container_dimensions(model.mesh)
    assert dims.volume == pytest.approx(v_ml * 1e-6, rel=0.02)
    assert dims.height == pytest.approx(h_cm / 100, rel=0.02)
    assert dims.rim_radius == pytest.approx(r_cm / 100, rel=0.02)


@pytest.mark.parametrize("name", OBJECT_NAMES)
def test_mesh_is_a_watertight_solid_in_metres(models, name):
    mesh = models[name].mesh
    assert mesh.is_watertight and mesh.is_winding_consistent
    assert mesh.volume > 0
    assert 0.05 < np.ptp(mesh.vertices, axis=0).max() < 0.25  # metres, not mm
    assert mesh.vertices[:, 2].min() == pytest.approx(0.0, abs=1e-9)


@pytest.mark.parametrize("name", OBJECT_NAMES)
def test_walls_at_least_3mm_thick(models, name):
    model = models[name]
    mesh, labels = model.mesh, model.labels
    face_labels = labels[mesh.faces]
    inner = mesh.submesh([np.flatnonzero((face_labels == Part.CONTAINER).all(axis=1))], append=True)
    outer = mesh.submesh([np.flatnonzero((face_labels == Part.OUTSIDE).all(axis=1))], append=True)
    points, _ = trimesh.sample.sample_surface(inner, 3000, seed=0)
    _, distance, _ = trimesh.proximity.closest_point(outer, points)
    assert distance.min() >= 0.003 - 1e-5
    assert distance.min() >= model.spec.wall * 0.95


@pytest.mark.parametrize("name", OBJECT_NAMES)
def test_labels_are_plausible(models, name):
    model = models[name]
    v, labels = model.mesh.vertices, model.labels
    assert labels.shape == (len(v),)
    counts = np.bincount(labels, minlength=4)
    assert counts[Part.RIM] > 0 and counts[Part.CONTAINER] > 0 and counts[Part.OUTSIDE] > 0
    assert (counts[Part.HANDLE] > 0) == SPECS[name].handle
    height = v[:, 2].max()
    # The rim is the top of the object.
    assert v[labels == Part.RIM][:, 2].min() > height - 1.5 * model.spec.wall
    # The container surface is inside: closer to the axis than the outside at its height,
    # and never below the base.
    inner = v[labels == Part.CONTAINER]
    assert inner[:, 2].min() == pytest.approx(model.spec.base, abs=1e-6)
    r_inner = np.hypot(inner[:, 0], inner[:, 1])
    r_outer_at = np.interp(inner[:, 2], model.profile.outer[:, 1], model.profile.outer[:, 0])
    assert np.all(r_inner < r_outer_at * 1.2)  # square bowl rings scale by up to 2**0.25
    if SPECS[name].handle:
        handle = v[labels == Part.HANDLE]
        assert handle[:, 0].min() > 0  # the handle points along +x
        assert np.hypot(handle[:, 0], handle[:, 1]).max() > SPECS[name].rim_radius + 0.02


def test_unknown_object_names_the_valid_ones():
    with pytest.raises(InputError, match="red_cup"):
        get_spec("mug")
    with pytest.raises(InputError, match="square_bowl"):
        build_object("teapot")


def test_build_is_deterministic():
    a, b = build_object("red_cup"), build_object("red_cup")
    assert np.array_equal(a.mesh.vertices, b.mesh.vertices)
    assert np.array_equal(a.mesh.faces, b.mesh.faces)
    assert np.array_equal(a.labels, b.labels)
