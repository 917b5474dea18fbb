"""The procedural container family: reproducible from names, watertight, labelled by
construction, with the volumes geometry says, and usable wherever a container is."""

import hashlib
import json

import numpy as np
import pytest
import trimesh

from pour_gym.assets import expand_containers, resolve_asset
from pour_gym.errors import InputError
from pour_gym.objects.procedural import (
    CROSS_SECTIONS,
    LIPS,
    PROFILES,
    RANGES,
    ProceduralSpec,
    build_member,
    build_spec,
    family_members,
    member_spec,
)
from pour_gym.parts import Part


def _digest(model) -> str:
    mesh = model.mesh
    data = np.asarray(mesh.vertices).tobytes() + np.asarray(mesh.faces).tobytes()
    return hashlib.sha256(data + model.labels.tobytes()).hexdigest()


def _one_of_each() -> list[str]:
    """Test-family members that between them have every profile, section, lip and handle."""
    wanted = {*PROFILES, *(f"x-{c}" for c in CROSS_SECTIONS), *(f"l-{lip}" for lip in LIPS)}
    wanted |= {"handle", "no handle"}
    chosen = []
    for name in family_members("procedural:test"):
        s = member_spec(name)
        keys = {s.profile, f"x-{s.cross_section}", f"l-{s.lip}"}
        keys.add("handle" if s.handle else "no handle")
        if keys & wanted:
            chosen.append(name)
            wanted -= keys
        if not wanted:
            return chosen
    raise AssertionError(f"the test family lacks {wanted}")


SAMPLE = _one_of_each()


@pytest.fixture(scope="module")
def built():
    return {name: build_member(name) for name in SAMPLE}


def test_families_have_their_sizes_and_are_disjoint():
    train, test = family_members("procedural:train"), family_members("procedural:test")
    assert (len(train), len(test)) == (200, 100)
    assert expand_containers("procedural:3@7") == ("procedural:3@7#0", "procedural:3@7#1",
                                                   "procedural:3@7#2")  # fmt: skip
    shapes = {tuple(sorted(member_spec(n).to_dict().items()))[1:] for n in train}
    assert not shapes & {tuple(sorted(member_spec(n).to_dict().items()))[1:] for n in test}
    # A comma-separated list longer than a file name may be (255 characters) is a list,
    # not a lookup the system refuses.
    many = ",".join(test[25:50])
    assert len(many) > 255 and expand_containers(many) == test[25:50]


def test_a_member_is_rebuilt_bit_for_bit_from_its_name(built):
    name = SAMPLE[-1]
    # Other members drawn first change nothing: a member's draws are its own.
    family_members("procedural:train") and build_member("procedural:train#5")
    assert _digest(build_member(name)) == _digest(built[name])
    assert member_spec(name) == member_spec(name)


def test_every_choice_and_range_is_drawn_over_the_test_family():
    specs = [member_spec(n) for n in family_members("procedural:test")]
    assert {s.profile for s in specs} == set(PROFILES)
    assert {s.cross_section for s in specs} == set(CROSS_SECTIONS)
    assert {s.lip for s in specs} == set(LIPS)
    assert 20 < sum(s.handle for s in specs) < 60
    for s in specs:
        lo, hi = RANGES["bowl_height" if s.profile == "bowl" else "cup_height"]
        assert lo <= s.height <= hi
        assert RANGES["wall"][0] <= s.wall <= RANGES["wall"][1] and s.base > s.wall
        assert 0 < s.floor_radius <= s.rim_radius
        assert not (s.profile == "bowl" and s.handle)


@pytest.mark.parametrize("name", SAMPLE)
def test_members_are_watertight_with_the_cavity_geometry_says(built, name):
    model = built[name]
    assert model.mesh.is_watertight and model.mesh.is_winding_consistent
    assert model.mesh.volume > 0
    # The exact faceted volume against trimesh's integral over the closed cavity surface.
    assert model.cavity_volume == pytest.approx(model.cavity_mesh().volume, rel=1e-9)
    s = model.spec
    if s.profile == "straight" and s.cross_section == "round":
        # A cylinder of the inner radius up to the lip's top, less the polygon's corners.
        b = s.rim_radius - s.wall / 2.0
        top = model.profile.cavity[:, 1].max()
        assert model.cavity_volume == pytest.approx(np.pi * b**2 * (top - s.base), rel=0.03)


@pytest.mark.parametrize("name", SAMPLE)
def test_labels_come_from_construction(built, name):
    model = built[name]
    s, v, labels = model.spec, model.mesh.vertices, model.labels
    counts = np.bincount(labels, minlength=4)
    assert counts[Part.RIM] > 0 and counts[Part.CONTAINER] > 0 and counts[Part.OUTSIDE] > 0
    assert (counts[Part.HANDLE] > 0) == s.handle
    # The rim is the top; the cavity's floor is the base's top; the handle points along +x.
    assert v[labels == Part.RIM][:, 2].max() == pytest.approx(v[:, 2].max())
    assert v[labels == Part.CONTAINER][:, 2].min() == pytest.approx(s.base, abs=1e-6)
    if s.handle:
        assert v[labels == Part.HANDLE][:, 0].min() > 0
    # The wall is as thick as drawn (the outer wall offsets the inner), times the
    # cross-section's scale: an oval's is thinner along its short axis.
    faces = labels[model.mesh.faces]
    inner = model.mesh.submesh([np.flatnonzero((faces == Part.CONTAINER).all(axis=1))])[0]
    outer = model.mesh.submesh([np.flatnonzero((faces == Part.OUTSIDE).all(axis=1))])[0]
    points, _ = trimesh.sample.sample_surface(inner, 2000, seed=0)
    _, distance, _ = trimesh.proximity.closest_point(outer, points)
    assert distance.min() >= 0.95 * s.wall * model.ring_scale.min()


def test_bad_names_are_refused_with_what_to_use():
    with pytest.raises(InputError, match="#0-#99"):
        member_spec("procedural:test#100")
    with pytest.raises(InputError, match="procedural:train, procedural:test"):
        family_members("procedural:big")
    with pytest.raises(InputError, match="procedural:<family>#<k>"):
        expand_containers("procedural:test#x")


def test_parameters_no_container_admits_are_named():
    spec = member_spec("procedural:test#0")
    thin_base = ProceduralSpec(**{**spec.to_dict(), "base": spec.wall / 4, "name": "thin"})
    with pytest.raises(InputError, match="thin: the base"):
        build_spec(thin_base)


def test_a_member_is_labelled_by_warping_and_cached(tmp_path):
    straight = next(
        n for n in family_members("procedural:test")
        if member_spec(n).profile == "straight" and member_spec(n).cross_section == "round"
    )  # fmt: skip
    asset = resolve_asset(straight, cache_dir=tmp_path)
    assert asset.meta["procedural"]["profile"] == "straight"
    assert asset.meta["iou"]["container"] >= 0.9 and asset.meta["iou"]["rim"] >= 0.7
    assert len(list(tmp_path.iterdir())) == 1
    again = resolve_asset(straight, cache_dir=tmp_path)
    assert np.array_equal(again.labels, asset.labels)


@pytest.mark.slow
def test_the_scripted_policy_pours_between_procedural_members():
    from pour_gym.agents.policies.rollout import rollout
    from pour_gym.agents.policies.scripted import ScriptedPourPolicy
    from pour_gym.envs import POUR, POUR_V0, make

    env = make(POUR_V0, source_objects=["procedural:test#2"], target_objects=["procedural:test#3"])
    episode = rollout(env, ScriptedPourPolicy(), seed=1)
    env.close()
    info = episode.info
    assert POUR.outcome(info) == "success", info
    assert abs(info["poured"] - info["target_amount"]) <= info["tolerance"]


def test_objects_command_builds_a_family_and_draws_it(cli, tmp_path):
    sheet = tmp_path / "sheet.png"
    doc = json.loads(cli("objects", "--procedural", "procedural:3@11", "--png", str(sheet),
                         "--json").stdout)  # fmt: skip
    assert [d["name"] for d in doc] == [f"procedural:3@11#{k}" for k in range(3)]
    assert all(d["watertight"] and d["volume"] > 0 for d in doc)
    assert sheet.stat().st_size > 10_000


def test_results_group_by_shape_parameter_buckets():
    from pour_gym.report.family import bucket_of, by_bucket

    specs = [member_spec(n).to_dict() for n in family_members("procedural:test")[:20]]
    rows = [{"spec": s, "score": float(s["height"] > 0.1), "rare": None} for s in specs]
    summary = by_bucket(rows, ("score", "rare"))
    for buckets in summary.values():
        assert sum(b["members"] for b in buckets.values()) == len(rows)
    # Heights bin by 2 cm: everything over 10 cm scores 1, everything under 0.
    for bucket, b in summary["height"].items():
        assert b["score"] == (1.0 if float(bucket.split("-")[0]) >= 10 else 0.0)
        assert b["rare"] is None
    assert bucket_of({"wall": 0.0025}, "wall") == "2-3 mm"
    assert bucket_of({"handle": False}, "handle") == "no handle"


def test_an_evaluation_over_a_family_is_tabled_by_shape_too():
    """A family's evaluation table (eval.md, ``pour-gym evaluate``) groups its members by
    shape: each bucket's success (with its Wilson interval) and failures by why; a
    catalogue's or a source x target matrix's table has no such section."""
    from pour_gym.agents.evaluation.evaluate import evaluation_table

    names = family_members("procedural:test")[:12]

    def row(name, success, source=None):
        return {"object": name, "source": source or name, "target": name, "trained_on": False,
                "success": success, "return": 1.0, "amount_error": 4.0, "spilled": 0.0,
                "outcome_success": success, "outcome_overshot": 1.0 - success}  # fmt: skip

    # Members taller than 10 cm succeed, the others overshoot.
    rows = [row(n, float(member_spec(n).height > 0.1)) for n in names]
    mean = {k: float(np.mean([r[k] for r in rows])) for k in rows[0] if k not in
            ("object", "source", "target", "trained_on")}  # fmt: skip
    result = {"env": "PourGym/Pour-v2", "episodes": 2, "rows": rows, "mean": mean}
    text = evaluation_table(result)
    section = text[text.index("## By shape") :]
    assert "### by profile" in section and "### by wall" in section
    assert "| height | members | success | amount error | spilled | overshot (share) |" in section
    for line in section[section.index("### by height") :].split("\n")[4:]:
        if not line.startswith("| "):
            break
        bucket, _, success, _, _, overshot, under, spill = [
            c.strip() for c in line.strip("|").split("|")
        ]
        tall = float(bucket.split("-")[0]) >= 10
        assert success.startswith("1.000 [" if tall else "0.000 [")
        assert overshot == ("0.000" if tall else "1.000")
        assert under == spill == "-"  # outcomes these rows do not record
        lo, hi = (float(x) for x in success[7:].strip(" []").split(","))
        assert lo <= float(success[:5]) <= hi and (hi - lo) > 0.1  # 2 x members episodes
    catalogue = {**result, "rows": [{**r, "object": "red_cup", "source": "red_cup",
                                     "target": "red_cup"} for r in rows[:1]]}  # fmt: skip
    assert "## By shape" not in evaluation_table(catalogue)
    matrix = {**result, "rows": [row(names[0], 1.0, source=names[1])]}
    assert "## By shape" not in evaluation_table(matrix)


def test_warping_over_a_family_reports_iou_per_bucket():
    from pour_gym.agents.evaluation.family import family_warping, family_warping_report

    doc = family_warping("procedural:2@11")
    assert len(doc["members"]) + len(doc["refused"]) == 2
    for row in doc["members"]:
        assert 0.0 <= row["iou_container"] <= 1.0 and 0.0 <= row["iou_rim"] <= 1.0
        assert (row["iou_handle"] is not None) == row["spec"]["handle"]
        # The rim is fitted to each member's lip: its depth is a few millimetres.
        assert 0.0 <= row["lip_depth"] < 0.012 and row["lip_reason"] == ""
    text = family_warping_report(doc)
    assert "### by profile" in text and "### by wall" in text
    assert "fitted to the lip (`pour_gym.warp.lip`) on 2 of 2 members" in text


def test_wilson_interval_matches_the_textbook():
    from pour_gym.agents.evaluation.aggregate import wilson_interval

    lo, hi = wilson_interval(5, 10)
    assert (lo, hi) == pytest.approx((0.2366, 0.7634), abs=1e-4)
    assert wilson_interval(10, 10)[1] == 1.0 and wilson_interval(0, 10)[0] == 0.0
    for n in range(1, 300):  # the interval holds the rate, rounding included
        for k in (0, n):
            lo, hi = wilson_interval(k, n)
            assert lo <= k / n <= hi


@pytest.mark.slow
def test_generalisation_study_over_a_family(cli, tmp_path):
    out = tmp_path / "study"
    args = ["--family", "procedural:2@11", "--policies", "scripted", "--episodes", "1"]
    doc = json.loads(cli("report", "generalisation", *args, "--out", str(out), "--json").stdout)
    scripted = doc["policies"]["scripted"]
    assert len(scripted["members"]) + len(doc["refused"]) == 2
    lo, hi = scripted["mean"]["success_interval"]
    assert lo <= scripted["mean"]["success"] <= hi
    by_profile = scripted["buckets"]["profile"]
    assert sum(b["members"] for b in by_profile.values()) == len(scripted["members"])
    assert (out / "success.png").stat().st_size > 10_000
    assert "## `scripted` by shape" in (out / "report.md").read_text()


@pytest.mark.slow
def test_generalisation_study_over_liquids(cli, tmp_path):
    out = tmp_path / "study"
    args = ["--family", "procedural:1@11", "--policies", "scripted", "--episodes", "1",
            "--liquids", "water,honey", "--workers", "2"]  # fmt: skip
    doc = json.loads(cli("report", "generalisation", *args, "--out", str(out), "--json").stdout)
    assert doc["liquids"] == ["water", "honey"]
    water, honey = doc["policies"]["scripted [water]"], doc["policies"]["scripted [honey]"]
    assert (water["liquid"], honey["liquid"]) == ("water", "honey")
    # The same member and episode seed: honey, 1000x water's viscosity, pours at a lower
    # peak rate (docs/liquids.md: 63 % of water's from the red cup).
    assert water["members"][0]["object"] == honey["members"][0]["object"]
    assert honey["members"][0]["peak_flow"] < 0.9 * water["members"][0]["peak_flow"]
    assert honey["mean"]["pour_seconds"] > water["mean"]["pour_seconds"]  # and longer
    report = (out / "report.md").read_text()
    assert "--liquids water,honey" in report
    assert "water: success; error; spilled" in report and "honey: success" in report
    assert "honey: pour, s; peak flow, T/s" in report
    assert "| spilled | failures |" in report  # the failures by why, a column
