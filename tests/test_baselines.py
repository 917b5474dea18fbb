"""The baselines report: seeds grouped by how they trained, means and intervals over seeds."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest
from scipy.stats import trim_mean

from pour_gym.agents.evaluation.aggregate import mean_interval
from pour_gym.agents.evaluation.baselines import baselines_report
from pour_gym.agents.evaluation.summaries import training_kind
from pour_gym.errors import InputError


def _run(folder, seed, success, algo="sac", mode="features", demos=None, keep_best=False):
    """A finished run directory: config.json, eval.json (red cup trained on, two unseen)."""
    folder.mkdir(parents=True)
    config = {"env": "PourGym/Pour-v1", "algo": algo, "obs_mode": mode, "seed": seed,
              "timesteps": 1000, "objects": "red_cup", "demonstrations": demos,
              "hyperparameters": {"gradient_steps": 1}, "keep_best": keep_best}  # fmt: skip
    rows = [
        {"object": "red_cup", "trained_on": True, "success": success, "amount_error": 4.0,
         "spilled": 0.0},
        {"object": "broad_cup", "trained_on": False, "success": success / 2,
         "amount_error": 10.0, "spilled": 1.0},
        {"object": "high_cup", "trained_on": False, "success": 0.0, "amount_error": 20.0,
         "spilled": 3.0},
    ]  # fmt: skip
    (folder / "config.json").write_text(json.dumps(config))
    (folder / "eval.json").write_text(
        json.dumps({"episodes": 10, "rows": rows, "train_seconds": 600.0 * (seed + 1)})
    )
    (folder / "curve.csv").write_text(f"timesteps,success\n500,0\n1000,{success}\n")


def test_report_groups_seeds_and_gives_intervals_over_them(tmp_path):
    for seed, success in enumerate([0.6, 0.8, 1.0]):
        _run(tmp_path / "runs" / f"sac_s{seed}", seed, success)
    _run(tmp_path / "runs" / "ppo_s0", 0, 0.2, algo="ppo")
    _run(tmp_path / "runs" / "ppo_s0_best", 0, 0.6, algo="ppo", keep_best=True)
    paths = {"summaries": tmp_path / "sum", "report": tmp_path / "b.md",
             "curves": tmp_path / "b" / "curves.png"}  # fmt: skip
    doc = baselines_report([tmp_path / "runs"], **paths)
    rows = {r["algo"]: r for r in doc["rows"] if r["model"] == "last step"}
    sac = rows["sac"]
    assert sac["seeds"] == [0, 1, 2]
    assert sac["trained_success"]["mean"] == pytest.approx(0.8)
    low, high = sac["trained_success"]["interval"]
    assert 0.6 <= low < 0.8 < high <= 1.0
    assert sac["unseen_success"]["mean"] == pytest.approx(0.2)  # (0.4 + 0) / 2 over seeds
    assert sac["unseen_spilled"]["mean"] == pytest.approx(2.0)
    assert sac["wall_minutes"] == [10.0, 20.0, 30.0]
    assert rows["ppo"]["trained_success"]["interval"] is None  # one seed: no interval
    # The same run's best curve point is a row of its own, not a fourth seed.
    (best,) = [r for r in doc["rows"] if r["model"] == "best curve point"]
    assert best["seeds"] == [0] and best["trained_success"]["mean"] == pytest.approx(0.6)
    text = paths["report"].read_text()
    assert (
        "| Pour-v1 | SAC | - | features | reward | last step | red_cup | catalogue (2) | 3 | 0.80 ["
        in text
    )
    assert (
        "| PPO | - | features | reward | best curve point | red_cup | catalogue (2) | 1 | 0.60 |"
        in text
    )
    assert paths["curves"].is_file() and "(b/curves.png)" in text
    # Regenerated from the summaries alone, the same report.
    baselines_report([], **paths)
    assert paths["report"].read_text() == text
    with pytest.raises(InputError, match=r"no finished train\.py run"):
        baselines_report([tmp_path / "sum"], **paths)


def test_runs_of_different_recipes_are_rows_apart_and_overrides_are_named(tmp_path):
    """Two recipes of one algorithm (say ppo/family and ppo/family-schedule) are different
    ways of training, not seeds of one; a run with ``--set`` or ``--env-kwargs`` is a row
    of its own too."""
    runs = (("a_s0", "family", {}, {}), ("a_s1", "family", {}, {}),
            ("b_s0", "family-schedule", {}, {}), ("c_s0", "family", {"target_kl": 0.05}, {}),
            ("d_s0", "family", {}, {"time_weight": 0.004}))  # fmt: skip
    for name, recipe, overrides, env in runs:
        folder = tmp_path / "runs" / name
        _run(folder, int(name[-1]), 0.5, algo="ppo")
        config = json.loads((folder / "config.json").read_text())
        config.update(recipe=recipe, overrides=overrides)
        config["env_kwargs"] = {"obs_mode": "features", **env}
        (folder / "config.json").write_text(json.dumps(config))
    paths = {"summaries": tmp_path / "sum", "report": tmp_path / "b.md",
             "curves": tmp_path / "b" / "curves.png"}  # fmt: skip
    doc = baselines_report([tmp_path / "runs"], **paths)
    seeds = {r["recipe"]: r["seeds"] for r in doc["rows"]}
    assert seeds == {"family": [0, 1], "family-schedule": [0], "family + 1 --set": [0],
                     "family, time_weight=0.004": [0]}  # fmt: skip
    assert "| Pour-v1 | PPO | family-schedule | features | reward |" in paths["report"].read_text()


def test_the_expert_is_a_reference_row_over_the_runs_unseen_containers(tmp_path):
    """``--reference``: the scripted expert's evaluation beside the runs; its red-cup row
    is "trained on", so its unseen means are over the runs' unseen containers."""
    _run(tmp_path / "runs" / "ppo_s0", 0, 1.0, algo="ppo")
    rows = [{"object": name, "trained_on": False, "success": 1.0, "amount_error": error,
             "spilled": 0.0} for name, error in (("red_cup", 9.0), ("broad_cup", 2.0),
                                                 ("high_cup", 4.0))]  # fmt: skip
    expert = tmp_path / "expert.json"
    expert.write_text(json.dumps({"env": "PourGym/Pour-v1", "episodes": 10, "rows": rows}))
    paths = {"summaries": tmp_path / "sum", "report": tmp_path / "b.md",
             "curves": tmp_path / "b" / "curves.png"}  # fmt: skip
    doc = baselines_report([tmp_path / "runs"], reference=expert, **paths)
    (ref,) = [r for r in doc["rows"] if r["algo"] == "scripted"]
    assert ref["unseen_amount_error"]["mean"] == pytest.approx(3.0)  # (2 + 4) / 2
    assert ref["trained_success"]["mean"] == 1.0
    text = paths["report"].read_text()
    assert (
        "| SCRIPTED | - | features | hand-written (reference) | deterministic | - | catalogue (2) "
        "| 1 |" in text
    )
    bad = tmp_path / "bad.json"
    bad.write_text("{}")
    with pytest.raises(InputError, match="pour-gym evaluate scripted"):
        baselines_report([], reference=bad, **paths)


def test_a_family_run_is_a_row_of_its_own_scored_against_references_on_its_members(tmp_path):
    """A run over procedural:train, scored on procedural:test members, is not a seed of the
    red-cup runs; its aggregates come from the references on the same members."""
    _run(tmp_path / "runs" / "ppo_s0", 0, 1.0, algo="ppo")
    family = tmp_path / "runs" / "family_s0"
    _run(family, 0, 1.0, algo="ppo")
    config = json.loads((family / "config.json").read_text())
    (family / "config.json").write_text(json.dumps({**config, "objects": "procedural:train"}))

    def rows(returns):
        return [{"object": f"procedural:test#{k}", "trained_on": False, "success": 1.0,
                 "amount_error": 2.0, "spilled": 0.0, "return": ret}
                for k, ret in enumerate(returns)]  # fmt: skip

    (family / "eval.json").write_text(json.dumps({"episodes": 2, "rows": rows([1.0, 3.0])}))
    sde = tmp_path / "runs" / "family_sde_s0"  # exploring by gSDE: a row of its own
    shutil.copytree(family, sde)
    config = json.loads((sde / "config.json").read_text())
    config["hyperparameters"]["use_sde"] = True
    (sde / "config.json").write_text(json.dumps(config))
    refs = []
    for policy, returns in (("scripted", [2.0, 2.0]), ("random", [0.0, 0.0])):
        refs.append(tmp_path / f"{policy}.json")
        refs[-1].write_text(json.dumps({"env": "PourGym/Pour-v1", "episodes": 2,
                                        "policy": policy, "rows": rows(returns)}))  # fmt: skip
    paths = {"summaries": tmp_path / "sum", "report": tmp_path / "b.md",
             "curves": tmp_path / "b" / "curves.png"}  # fmt: skip
    doc = baselines_report([tmp_path / "runs"], reference=refs, **paths)
    (fam,) = [r for r in doc["rows"] if r["objects"] == "procedural:train" and r["algo"] == "ppo"]
    (fam_sde,) = [r for r in doc["rows"] if r["algo"] == "ppo (gSDE)"]
    assert fam_sde["seeds"] == [0] and fam_sde["iqm"] == fam["iqm"]
    assert fam["scored_on"] == "procedural:test (2)" and fam["seeds"] == [0]
    # Normalised returns 0.5 and 1.5 (random 0, expert 2): one beats the expert, one not.
    assert fam["iqm"][0] == pytest.approx(1.0) and fam["improvement"][0] == pytest.approx(0.5)
    (red,) = [r for r in doc["rows"] if r["algo"] == "ppo" and r["objects"] == "red_cup"]
    assert red["iqm"] is None  # no references on its catalogue containers
    assert (tmp_path / "sum" / "scripted-expert-pour-v1-procedural-test.json").is_file()
    text = paths["report"].read_text()
    assert "| procedural:train | procedural:test (2) | 1 |" in text
    assert "| Pour-v1 | PPO (gSDE) | - | features | reward |" in text


def test_a_family_run_scored_on_the_catalogue_too_gets_references_with_every_one_unseen(
    tmp_path,
):
    """A family run's further evaluation (eval-catalogue.json) is a row of its own over all
    the catalogue containers; the references, which count the red cup as trained on, are
    given again with it unseen, so the row has its reference rows and aggregates."""
    family = tmp_path / "runs" / "family_s0"
    _run(family, 0, 1.0, algo="ppo")
    config = json.loads((family / "config.json").read_text())
    (family / "config.json").write_text(json.dumps({**config, "objects": "procedural:train"}))
    (family / "eval.json").write_text(json.dumps({"episodes": 2, "rows": [
        {"object": "procedural:test#0", "trained_on": False, "success": 1.0,
         "amount_error": 2.0, "spilled": 0.0, "return": 1.0}]}))  # fmt: skip
    names = ("red_cup", "broad_cup", "high_cup")

    def evaluation(returns, trained, policy=None):
        rows = [{"object": o, "trained_on": trained and o == "red_cup", "success": 1.0,
                 "amount_error": 1.0, "spilled": 0.0, "return": r}
                for o, r in zip(names, returns, strict=True)]  # fmt: skip
        return {"env": "PourGym/Pour-v1", "episodes": 10, "rows": rows,
                **({"policy": policy} if policy else {})}  # fmt: skip

    (family / "eval-catalogue.json").write_text(json.dumps(evaluation((1.0, 1.0, 3.0), False)))
    sampled = {**evaluation((2.0, 2.0, 2.0), False), "actions": "sampled"}
    (family / "eval-catalogue-sampled.json").write_text(json.dumps(sampled))
    weighted = {**evaluation((5.0, 5.0, 5.0), False), "env_kwargs": {"spill_weight": 10}}
    (family / "eval-catalogue-spill10.json").write_text(json.dumps(weighted))
    # A checkpoint's evaluation: its own row, at its own steps, its wall time not known.
    policy = str(family / "checkpoints" / "model_850000_steps.zip")
    early = {**evaluation((1.0, 1.0, 1.0), False), "policy": policy, "actions": "mean"}
    (family / "eval-850k-catalogue.json").write_text(json.dumps(early))
    refs = []
    for policy, returns in (("scripted", (2.0, 2.0, 2.0)), ("random", (0.0, 0.0, 0.0))):
        refs.append(tmp_path / f"{policy}.json")
        refs[-1].write_text(json.dumps(evaluation(returns, False, policy)))
    paths = {"summaries": tmp_path / "sum", "report": tmp_path / "b.md",
             "curves": tmp_path / "b" / "curves.png"}  # fmt: skip
    doc = baselines_report([tmp_path / "runs"], reference=refs, **paths)
    rows = {(r["algo"], r["scored_on"], r["model"]): r for r in doc["rows"]}
    cat = rows["ppo", "catalogue (3)", "last step"]
    assert cat["unseen_success"]["mean"] == 1.0
    # Normalised 0.5, 0.5, 1.5 (random 0, expert 2), the red cup among them.
    assert cat["iqm"][0] == pytest.approx(trim_mean([0.5, 0.5, 1.5], 0.25))
    assert cat["improvement"][0] == pytest.approx(1 / 3)
    (by_samples,) = [r for r in doc["rows"] if r["model"] == "last step, sampled actions"]
    assert by_samples["scored_on"] == "catalogue (3)" and by_samples["iqm"][0] == 1.0
    # Evaluated under reward weights of its own: a row apart, with no aggregates (its
    # returns are in other units than the references').
    spill10 = rows["ppo", "catalogue (3)", "last step, spill_weight=10"]
    assert spill10["seeds"] == [0] and spill10["iqm"] is None
    at_850k = rows["ppo", "catalogue (3)", "checkpoint at 850,000 steps"]
    assert at_850k["timesteps"] == [850_000] and at_850k["wall_minutes"] == []
    assert cat["timesteps"] == [1000]  # the run's own end
    scored = {(r["algo"], r["scored_on"]) for r in doc["rows"]}
    assert {("scripted", "catalogue (3)"), ("random", "catalogue (3)"),
            ("scripted", "catalogue (2)")} <= scored  # fmt: skip
    assert (tmp_path / "sum" / "family_s0-catalogue.json").is_file()
    bad = family / "eval-broken.json"
    bad.write_text("{}")
    with pytest.raises(InputError, match="pour-gym evaluate"):
        baselines_report([tmp_path / "runs"], reference=refs, **paths)


def test_intervals_and_kinds():
    assert mean_interval([0.5]) is None and mean_interval([0.3, 0.3]) == (0.3, 0.3)
    low, high = mean_interval([0.0, 1.0, 1.0, 1.0])
    assert 0.0 <= low < np.mean([0.0, 1.0, 1.0, 1.0]) < high <= 1.0
    assert training_kind({"demonstrations": None}) == "reward"
    clone = {"demonstrations": {"episodes": 5}, "hyperparameters": {"gradient_steps": 0}}
    assert training_kind(clone) == "clone"
    clone["hyperparameters"]["gradient_steps"] = 1
    assert training_kind(clone) == "clone + RL"
    residual = {"demonstrations": None, "residual": {"scale": [0.1], "expert": {}}}
    assert training_kind(residual) == "reward, residual on the expert"


def test_the_committed_report_is_what_the_committed_summaries_give(tmp_path):
    from pathlib import Path

    docs = Path(__file__).resolve().parents[1] / "docs"
    committed = sorted((docs / "baselines" / "runs").glob("*.json"))
    assert len(committed) >= 10  # three seeds of the clone's two rows, PPO's runs
    paths = {"summaries": docs / "baselines" / "runs", "report": tmp_path / "baselines.md",
             "curves": tmp_path / "baselines" / "curves.png"}  # fmt: skip
    baselines_report([], **paths)
    assert paths["report"].read_text() == (docs / "baselines.md").read_text()


def test_what_a_row_is_scored_on_names_the_kind_of_container():
    """A user's mesh file is not a catalogue container: the column says which is which."""
    from pour_gym.agents.evaluation.summaries import scored_on

    def rows(*names):
        return [{"object": n, "trained_on": n == "red_cup"} for n in names]

    assert scored_on(rows("red_cup", "broad_cup", "ycb_mug")) == "catalogue (2)"
    assert scored_on(rows("procedural:test#0", "procedural:test#7")) == "procedural:test (2)"
    assert scored_on(rows("thin_cup.stl")) == "user meshes (1)"
    mixed = rows("broad_cup", "procedural:test#0", "meshes/cup.obj")
    assert scored_on(mixed) == "procedural:test + catalogue + user meshes (3)"
