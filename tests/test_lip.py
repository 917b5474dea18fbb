"""The warped rim fitted to the lip (pour_gym.warp.lip) against labels from construction.

A procedural member's lip is drawn between the tops of its two walls: a half-round of the
wall's thickness (round), a flat cut (flat) or a bead that stands out of the wall (rolled).
Its depth below the rim's top is known from the construction's labels, so the measured
depth, and the rim labelled from it, can be checked against it.
"""

import numpy as np
import pytest
import trimesh

from pour_gym.assets import load_asset, part_iou
from pour_gym.objects import build_object
from pour_gym.objects.procedural import build_member, member_spec
from pour_gym.parts import Part
from pour_gym.warp.lip import MARGIN, fit_rim, lip_depth, wall_widths
from pour_gym.warp.transfer import transfer_best


def constructed_lip_depth(model) -> float:
    """Depth of the construction's lowest rim vertex below the top, in m."""
    v = np.asarray(model.mesh.vertices)
    return float(v[:, 2].max() - v[model.labels == Part.RIM][:, 2].min())


def test_wall_widths_of_a_tube_are_its_thickness():
    # An open tube, 6 cm tall, radii 30 and 34 mm: 4 mm wide at every depth and azimuth.
    outer = trimesh.creation.cylinder(radius=0.034, height=0.06, sections=256)
    inner = trimesh.creation.cylinder(radius=0.030, height=0.07, sections=256)
    tube = outer.difference(inner)
    tube.apply_translation([0.0, 0.0, 0.03])
    widths = wall_widths(tube, np.array([0.001, 0.005, 0.02]), rays=36)
    # A 256-gon's sides lie within r (1 - cos(pi / 256)), 2.6 um, of the circle.
    assert np.abs(widths - 0.004).max() < 5e-6


@pytest.mark.parametrize(
    ("member", "lip"),
    [
        ("procedural:train#0", "round"),  # 4.1 mm wall, tapered
        ("procedural:train#24", "flat"),  # straight
        ("procedural:train#8", "rolled"),  # 3.6 mm wall
        ("procedural:train#16", "rolled"),  # 6 mm wall, bulged: the deepest lip, 10.2 mm
    ],
)
def test_the_lip_depth_is_the_constructions(member, lip):
    assert member_spec(member).lip == lip
    model = build_member(member)
    fit = lip_depth(model.mesh)
    assert fit.reason == "" and fit.rays == 72
    # Within a fifth of a millimetre of where the construction puts the lip's last vertex.
    assert fit.depth == pytest.approx(constructed_lip_depth(model), abs=2e-4)


@pytest.mark.parametrize("member", ["procedural:train#5", "procedural:train#8"])
def test_the_fitted_rim_is_the_constructions(member):
    """The red cup warped onto a bowl and onto a rolled lip: the rim as built."""
    source, target = build_object("red_cup"), build_member(member)
    result = transfer_best(source.mesh, source.labels, target.mesh, target_upright=True)
    assert result.info["lip"]["depth"] is not None
    iou = part_iou(result.labels, target.labels)
    assert iou["rim"] >= 0.95 and iou["container"] >= 0.97 and iou["outside"] >= 0.97
    warp = transfer_best(
        source.mesh, source.labels, target.mesh, target_upright=True, fit_lip=False
    )
    assert "lip" not in warp.info
    # Only rim, container and outside change hands: the handle is the warp's.
    assert np.array_equal(result.labels == Part.HANDLE, warp.labels == Part.HANDLE)


def test_every_rim_vertex_is_within_the_lip():
    model = build_member("procedural:train#8")
    labels, fit = fit_rim(model.mesh, model.labels.copy())
    v = np.asarray(model.mesh.vertices)
    depth = v[:, 2].max() - v[labels == Part.RIM][:, 2]
    assert depth.max() <= fit.depth + MARGIN + 1e-9
    assert np.array_equal(labels, model.labels)  # the construction's labels are a fixed point


@pytest.mark.parametrize(
    ("name", "why"),
    [
        ("ycb_mug", "the wall does not settle"),  # a scanned wall thickens into its lip
        ("ycb_bowl", "the rays put the lip's end"),  # ... over depths that differ by azimuth
        ("pybullet_mug", "too coarse"),  # 446 vertices
    ],
)
def test_where_the_lip_cannot_be_told_the_warp_stays(name, why):
    asset = load_asset(name)
    labels, fit = fit_rim(asset.mesh, asset.labels)
    assert fit.depth is None and why in fit.reason
    assert labels is asset.labels


def test_a_container_too_short_keeps_the_warp():
    cup = build_object("standard_cup").mesh.copy()
    cup.apply_scale(0.3)  # 2.5 cm high
    fit = lip_depth(cup)
    assert fit.depth is None and "too short" in fit.reason
