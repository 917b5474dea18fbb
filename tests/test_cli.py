"""The command line: JSON on stdout and nothing else, clear errors, working outputs."""

import json
from pathlib import Path

import numpy as np
import pytest

from pour_gym.apps.commands import number_list
from pour_gym.errors import InputError
from pour_gym.mesh.fileio import save_point_cloud
from pour_gym.mesh.scan import ScanConfig, turntable_scan


def test_objects_json_lists_nine_in_si_units(cli):
    doc = json.loads(cli("objects", "--json").stdout)
    assert len(doc) == 9
    red = next(d for d in doc if d["name"] == "red_cup")
    assert red["height"] == pytest.approx(0.087)
    assert red["rim_radius"] == pytest.approx(0.04)
    assert red["volume"] == pytest.approx(265e-6)


def test_unknown_object_is_a_one_line_error(cli):
    proc = cli("reconstruct", "teacup", "--out", "x.obj", check=False)
    assert proc.returncode == 2
    assert "unknown object 'teacup'" in proc.stderr and "red_cup" in proc.stderr
    assert "Traceback" not in proc.stderr


def test_bench_efflux_names_a_spacing_it_cannot_take(cli):
    for bad, words in (("5,x", "particle spacings in mm"), ("9", "from 0.0025 (fine, slow)")):
        proc = cli("bench", "efflux", "--sizes", bad, check=False)
        assert proc.returncode == 2 and words in proc.stderr
        assert "Traceback" not in proc.stderr
    for bad, words in (("1,-2", "vessel scales"), ("9", "from 0.25 to 4")):
        proc = cli("bench", "efflux", "--sizes", "5", "--scales", bad, check=False)
        assert proc.returncode == 2 and words in proc.stderr
        assert "Traceback" not in proc.stderr


def test_bench_names_a_size_that_is_not_a_positive_number(cli):
    proc = cli("bench", "fluid", "--sizes", "300,abc", check=False)
    assert proc.returncode == 2
    assert "'abc' in '300,abc' is not one of particle counts" in proc.stderr
    assert "Traceback" not in proc.stderr
    for bad, kind, named in (
        ("-5", int, "'-5' in '-5'"),
        ("5k", int, "'5k' in '5k'"),
        ("0", int, "'0' in '0'"),
        ("2.5,,3", float, "'' in '2.5,,3'"),
    ):
        with pytest.raises(InputError, match=f"{named} is not one of spacings"):
            number_list(bad, "spacings", kind)
    assert number_list("5,3.5", "spacings", float) == [5.0, 3.5]
    assert number_list("300, 2000", "counts") == [300, 2000]


@pytest.mark.parametrize("command", ["train", "search"])
def test_env_kwargs_that_are_not_a_json_object_are_named(cli, command):
    for bad, words in (("{bad", "not JSON"), ("[1]", "a JSON object {...} is needed")):
        proc = cli(command, "--env-kwargs", bad, check=False)
        assert proc.returncode == 2
        assert "argument --env-kwargs" in proc.stderr and words in proc.stderr
        assert "Traceback" not in proc.stderr


def test_scan_then_reconstruct_a_user_cloud(tmp_path, models, cli):
    cup = models["very_small_cup"]
    cloud = turntable_scan(cup.mesh, cup.labels, ScanConfig(views=12, width=120, height=90))
    # The user's file has no normals and is in millimetres.
    cloud.points *= 1000.0
    cloud.normals = None
    src = save_point_cloud(cloud, tmp_path / "cup_mm.xyz")
    proc = cli(
        "reconstruct",
        "--points",
        str(src),
        "--out",
        str(tmp_path / "cup.obj"),
        "--json",
        check=False,
    )
    assert proc.returncode == 2 and "millimetres" in proc.stderr and proc.stdout == ""
    proc = cli(
        "reconstruct",
        "--points",
        str(src),
        "--scale",
        "0.001",
        "--out",
        str(tmp_path / "cup.obj"),
        "--json",
    )
    doc = json.loads(proc.stdout)  # the whole of stdout is one JSON document
    assert doc["n_points"] == len(cloud.points)
    assert doc["seconds"] > 0
    assert (tmp_path / "cup.obj").exists() and (tmp_path / "cup.json").exists()
    offset = doc["models"]["offset"]
    assert offset["height"] == pytest.approx(0.067, rel=0.05)
    assert offset["volume"] == pytest.approx(170e-6, rel=0.2)


def test_scan_command_writes_a_cloud(tmp_path, cli):
    out = tmp_path / "red.ply"
    doc = json.loads(cli("scan", "red_cup", "--out", str(out), "--views", "6", "--json").stdout)
    assert out.exists() and doc["n_points"] > 1000


def test_measure_needs_a_watertight_mesh(tmp_path, cli):
    import trimesh

    box = trimesh.creation.box([0.05, 0.05, 0.05])
    box.update_faces(np.arange(12) > 0)
    path = tmp_path / "open.stl"
    box.export(path)
    proc = cli("measure", str(path), check=False)
    assert proc.returncode == 2 and "not watertight" in proc.stderr
    doc = json.loads(cli("measure", "standard_bowl", "--json").stdout)
    assert doc["volume"] == pytest.approx(1038e-6, rel=0.01)


def test_evaluate_runs_a_searched_policy_and_rejects_other_json(tmp_path, cli):
    # The packaged red-cup search.
    searched = str(Path(__file__).resolve().parents[1] / "agents/thesis/poc_search_red_cup_20.json")
    doc = json.loads(cli("evaluate", searched, "--objects", "red_cup", "--episodes", "1",
                         "--json").stdout)  # fmt: skip
    row = doc["rows"][0]
    assert row["object"] == "red_cup" and row["trained_on"] is True
    # The command evaluates the searched parameters, at the documented first seed.
    from pour_gym.agents.evaluation.evaluate import evaluate_policy
    from pour_gym.agents.policies.scripted import ScriptedPourPolicy
    from pour_gym.agents.policies.search import load_search

    found = load_search(searched)
    policy = ScriptedPourPolicy(**found["best"])
    here = evaluate_policy(policy, "PourGym/Pour-v0", ["red_cup"], episodes=1, seed=10_000,
                           trained_on=found["sources"])  # fmt: skip
    assert here["rows"] == doc["rows"] and doc["seed"] == 10_000
    # --env-kwargs reaches the env (a larger spill weight costs more per particle spilled;
    # the expert spills nothing, so only the record changes), and a key no env takes is an
    # error that names it, without a traceback.
    weighted = json.loads(cli("evaluate", searched, "--objects", "red_cup", "--episodes", "1",
                              "--env-kwargs", '{"spill_weight": 10}', "--json").stdout)  # fmt: skip
    assert weighted["env_kwargs"] == {"spill_weight": 10}
    proc = cli("evaluate", searched, "--objects", "red_cup", "--env-kwargs", '{"spil": 1}',
               check=False)  # fmt: skip
    assert proc.returncode == 2 and "unknown argument(s) spil" in proc.stderr
    assert "Traceback" not in proc.stderr
    bad = tmp_path / "not_a_search.json"
    bad.write_text("{}")
    proc = cli("evaluate", str(bad), "--objects", "red_cup", check=False)
    assert proc.returncode == 2 and "search.json" in proc.stderr


def test_label_says_how_the_rim_was_drawn(tmp_path, cli):
    text = cli("label", "procedural:train#8", "--out", str(tmp_path / "a")).stdout
    assert "rim fitted to the lip, 4.5 mm deep" in text  # a rolled lip on a 3.6 mm wall
    assert "rim 1.000" in text
    text = cli("label", "ycb_mug", "--out", str(tmp_path / "b")).stdout
    assert "rim as warped (the lip could not be told: the wall does not settle" in text


@pytest.mark.slow
def test_bench_names_its_machine_and_keeps_v_hacd_off_stdout(tmp_path, monkeypatch, cli):
    """A benchmark's table begins with the machine it ran on, and V-HACD's progress (the
    sphere backend decomposes the cup on first use, from C) does not reach stdout."""
    monkeypatch.setenv("POUR_GYM_CACHE", str(tmp_path))  # nothing cached: V-HACD runs
    args = ("bench", "fluid", "--sizes", "300", "--bullet-sizes", "300", "--repeats", "1")
    out = cli(*args).stdout
    assert list(tmp_path.glob("sdf/vhacd_*.obj")), "the decomposition did not run"
    lines = out.splitlines()
    assert lines[0].startswith("machine: ") and lines[0].endswith(" cores"), out[:500]
    assert lines[1].startswith("| backend |"), out[:500]
    assert "V-HACD" not in out and "Voxelization" not in out


def test_the_machine_of_a_benchmark():
    """What ``pour-gym bench`` records of the machine: the processor and numba's target."""
    from pour_gym.apps.bench.machine import machine, machine_line

    info = machine()
    assert info["cpu"] and info["llvm_cpu"] and info["cores"] >= 1
    assert json.loads(json.dumps(info)) == info
    assert (
        machine_line(info) == f"machine: {info['cpu']} ({info['llvm_cpu']}), {info['cores']} cores"
    )
