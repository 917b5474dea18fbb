"""Ray: the same results as the serial runs, a sweep of trials, a two-node cluster."""

import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pytest

from pour_gym.agents.cluster import check_address
from pour_gym.apps.cli import main
from pour_gym.errors import InputError

CLI = [sys.executable, "-m", "pour_gym.apps.cli"]


def test_address_without_ray_names_the_extra(monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "ray", None)  # import ray now raises ImportError
    assert main(["search", "--generations", "1", "--population", "2", "--address", "local"]) == 2
    err = capsys.readouterr().err
    assert "pour-gym[ray]" in err and "Traceback" not in err


def test_addresses_are_checked():
    for good in ("local", "auto", "10.0.0.5:6379", "head.example.org:6380"):
        assert check_address(good) == good
    for bad in ("", "cluster", "10.0.0.5", "http://x:1/"):
        with pytest.raises(InputError, match="HOST:PORT"):
            check_address(bad)


def test_sweep_files_are_checked_and_expand_to_a_grid(tmp_path):
    from pour_gym.agents.training.sweep import load_spec, trials

    spec = tmp_path / "s.yaml"
    spec.write_text("algo: ppo\ntimesteps: 100\ngrid:\n  seed: [0, 1, 2]\n  obs_mode: [state]\n")
    fixed, grid = load_spec(spec)
    configs = trials(fixed, grid, tmp_path / "out")
    assert [(c.seed, c.obs_mode, c.algo) for c in configs] == [
        (0, "state", "ppo"), (1, "state", "ppo"), (2, "state", "ppo")
    ]  # fmt: skip
    assert len({c.out for c in configs}) == 3
    assert all(Path(c.out).parent == (tmp_path / "out").resolve() for c in configs)
    for text, match in [
        ("algo: ppo\nout: x\n", "--out decides"),
        ("algo: ppo\nlearning_rate: 0.1\n", "unknown fields"),
        ("grid:\n  seed: []\n", "non-empty list"),
    ]:
        spec.write_text(text)
        with pytest.raises(InputError, match=match):
            load_spec(spec)
    with pytest.raises(InputError, match="no sweep file"):
        load_spec(tmp_path / "missing.yaml")


@pytest.fixture(scope="module")
def ray_local():
    """One local Ray instance for this module's tests (the commands join it)."""
    ray = pytest.importorskip("ray")
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    yield ray
    ray.shutdown()


@pytest.mark.slow
def test_search_on_ray_equals_the_serial_search(ray_local):
    from pour_gym.agents.policies.search import search

    kwargs = {
        "objects": "red_cup",
        "generations": 2,
        "population": 3,
        "episodes": 1,
        "seed": 4,
        "env_kwargs": {"amount_range": (100, 120)},
    }
    serial = search(**kwargs)
    on_ray = search(**kwargs, address="local")  # joins the module's instance
    # The same search, every number but how long it took.
    assert on_ray.pop("wall_seconds") > 0 and serial.pop("wall_seconds") > 0
    assert on_ray == serial


@pytest.mark.slow
def test_experiment_on_ray_equals_the_serial_experiment(ray_local):
    from pour_gym.agents.thesis.experiments import collect

    objects = ("red_cup", "standard_bowl")
    whole = collect("tilt", objects, 5, seed=11, chunk=5)
    chunked = collect("tilt", objects, 5, seed=11, chunk=2)
    on_ray = collect("tilt", objects, 5, seed=11, chunk=2, address="local")
    for data in (chunked, on_ray):
        assert np.array_equal(data.features, whole.features)
        assert np.array_equal(data.labels, whole.labels)
        assert list(data.objects) == list(whole.objects)
    assert list(whole.objects) == ["red_cup"] * 5 + ["standard_bowl"] * 5


def _sweep_spec(path: Path, seeds: list[int]) -> Path:
    path.write_text(
        "env: PourGym/TiltPour-v0\n"
        "algo: ppo\n"
        "timesteps: 256\n"
        "objects: red_cup\n"
        "eval_objects: red_cup\n"
        "eval_episodes: 2\n"
        "checkpoint_every: 256\n"
        "overrides: {n_envs: 1, n_steps: 128, batch_size: 64}\n"
        "grid:\n"
        f"  seed: {seeds}\n"
        "  obs_mode: [features, state]\n"
    )
    return path


@pytest.mark.slow
def test_sweep_runs_four_trials_on_ray_and_resumes(tmp_path, ray_local):
    from pour_gym.agents.training.sweep import sweep

    spec = _sweep_spec(tmp_path / "sweep.yaml", [0, 1])
    doc = sweep(spec, tmp_path / "out", address="local")
    assert len(doc["trials"]) == 4
    configs = [(t["config"]["seed"], t["config"]["obs_mode"]) for t in doc["trials"]]
    assert configs == [(0, "features"), (0, "state"), (1, "features"), (1, "state")]
    for trial in doc["trials"]:
        run = Path(trial["run_dir"])
        assert (run / "model.zip").is_file() and trial["node_id"]
        assert trial["eval"] == json.loads((run / "eval.json").read_text())
        assert trial["eval"]["mean"]["success"] in (0.0, 0.5, 1.0)  # 2 one-step episodes

    def stamps(d: dict) -> list[int]:
        return [(Path(t["run_dir"]) / "eval.json").stat().st_mtime_ns for t in d["trials"]]

    again = sweep(spec, tmp_path / "out", address="local")  # finished trials are not re-run
    assert stamps(again) == stamps(doc)
    assert again == doc


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _ray_processes(temp: Path, port: int) -> list[str]:
    """Processes of the nodes this test started: the head's (its temp dir in their command
    line) and every node's (raylets and workers name the head's GCS address)."""
    pattern = f"({temp}|gcs[-_]address[= ][^ ]*:{port}( |$)|gcs_server_port={port})"
    out = subprocess.run(["pgrep", "-af", pattern], capture_output=True, text=True).stdout
    return [line for line in out.splitlines() if "pgrep" not in line]


@pytest.mark.slow
def test_a_sweep_trial_with_worker_processes_runs_on_ray(tmp_path):
    """The shipped PPO recipe of TiltPour-v0 steps two envs in SubprocVecEnv workers; inside
    a Ray trial those workers never imported pour-gym, and every trial failed with
    NamespaceNotFound until the envs were made through pour_gym.envs.make."""
    spec = tmp_path / "sweep.yaml"
    spec.write_text(
        "env: PourGym/TiltPour-v0\nalgo: ppo\ntimesteps: 256\nobjects: red_cup\n"
        "eval_objects: red_cup\neval_episodes: 2\ncheckpoint_every: 256\n"
        "overrides: {n_steps: 128, batch_size: 64}\ngrid:\n  seed: [0]\n"
    )
    done = subprocess.run(
        [*CLI, "sweep", str(spec), "--out", str(tmp_path / "out"), "--address", "local",
         "--json"],
        capture_output=True, text=True, env={**os.environ, "RAY_USAGE_STATS_ENABLED": "0"},
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]
    (trial,) = json.loads(done.stdout)["trials"]
    assert trial["config"]["seed"] == 0 and trial["eval"]["episodes"] == 2
    config = json.loads((Path(trial["run_dir"]) / "config.json").read_text())
    assert config["n_envs"] == 2  # the recipe's two workers


def _accepts(port: int) -> bool:
    """Whether something listens on this loopback port."""
    try:
        with socket.create_connection(("127.0.0.1", port), timeout=0.5):
            return True
    except OSError:
        return False


@pytest.mark.slow
def test_sweep_on_a_two_node_cluster_uses_both_nodes(tmp_path):
    pytest.importorskip("ray")
    ray_bin = shutil.which("ray", path=str(Path(sys.executable).parent))
    assert ray_bin, "the ray command is installed with the ray extra"
    port = _free_port()
    # Short (Ray's socket paths have a length limit, which pytest's tmp_path can pass).
    temp = Path(tempfile.mkdtemp(prefix="pgray"))
    env = {**os.environ, "RAY_USAGE_STATS_ENABLED": "0"}
    common = ["--num-cpus", "1", "--block", "--disable-usage-stats"]
    head = subprocess.Popen(
        [ray_bin, "start", "--head", "--port", str(port), "--temp-dir", str(temp),
         "--include-dashboard", "false", *common],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env, start_new_session=True,
    )  # fmt: skip
    nodes = [head]
    try:
        address = f"127.0.0.1:{port}"
        deadline = time.time() + 60
        while not _accepts(port) and time.time() < deadline:  # the head's GCS is up
            time.sleep(0.2)
        assert _accepts(port), "the Ray head did not start within 60 s"
        worker = subprocess.Popen(
            [ray_bin, "start", "--address", address, *common],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env, start_new_session=True,
        )  # fmt: skip
        nodes.append(worker)
        check = (
            "import ray, time\n"
            f"ray.init(address='{address}', include_dashboard=False, log_to_driver=False)\n"
            "for _ in range(60):\n"
            "    if len([n for n in ray.nodes() if n['Alive']]) == 2: break\n"
            "    time.sleep(1)\n"
            "print(len([n for n in ray.nodes() if n['Alive']]))\n"
        )
        alive = subprocess.run([sys.executable, "-c", check], capture_output=True, text=True)
        assert alive.stdout.strip().endswith("2"), alive.stderr[-2000:]
        spec = _sweep_spec(tmp_path / "sweep.yaml", [0])
        done = subprocess.run(
            [*CLI, "sweep", str(spec), "--out", str(tmp_path / "out"), "--address", address,
             "--json"],
            capture_output=True, text=True, env=env,
        )  # fmt: skip
        assert done.returncode == 0, done.stderr[-3000:]
        trials = json.loads(done.stdout)["trials"]
        assert len(trials) == 2
        # Two one-CPU trials on two one-CPU nodes run at the same time, one on each.
        assert len({t["node_id"] for t in trials}) == 2
    finally:
        for proc in reversed(nodes):
            os.killpg(proc.pid, signal.SIGTERM)
        for proc in reversed(nodes):
            try:
                proc.wait(timeout=60)
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()
        deadline = time.time() + 30
        while _ray_processes(temp, port) and time.time() < deadline:
            time.sleep(1)
        left = _ray_processes(temp, port)
        shutil.rmtree(temp, ignore_errors=True)
    assert not left, left


def test_study_report_keeps_every_seed_of_a_sweep(tmp_path):
    """Runs of one env and mode with different seeds (a sweep's) are averaged, with their
    spread; none overwrites another."""
    from pour_gym.agents.evaluation.generalisation import study_report

    unseen = {0: (0.2, 0.4), 1: (0.6, 0.8), 2: (1.0, 1.0)}  # standard_cup, high_cup per seed
    runs = tmp_path / "runs"
    for mode, seeds in (("features", [2, 0, 1]), ("state", [0])):
        for seed in seeds:
            run = runs / f"seed-{seed}_obs_mode-{mode}"
            run.mkdir(parents=True)
            config = {"env": "PourGym/TiltPour-v0", "obs_mode": mode, "algo": "ppo",
                      "timesteps": 256, "seed": seed, "objects": "red_cup"}  # fmt: skip
            a, b = unseen[seed]
            rows = [
                {"object": "red_cup", "trained_on": True, "success": 1.0},
                {"object": "standard_cup", "trained_on": False, "success": a},
                {"object": "high_cup", "trained_on": False, "success": b},
            ]
            (run / "config.json").write_text(json.dumps(config))
            (run / "eval.json").write_text(json.dumps({"episodes": 5, "rows": rows}))
    summary = study_report(runs, tmp_path / "report")["PourGym/TiltPour-v0"]
    features = summary["features"]
    assert features["seeds"] == [0, 1, 2]
    assert features["unseen_per_seed"] == pytest.approx([0.3, 0.7, 1.0])
    assert features["unseen"] == pytest.approx(2.0 / 3.0)
    assert features["unseen_std"] == pytest.approx(np.std([0.3, 0.7, 1.0], ddof=1))
    assert summary["state"]["unseen"] == pytest.approx(0.3)
    assert summary["state"]["unseen_std"] is None
    report = (tmp_path / "report" / "report.md").read_text()
    assert "seeds 0, 1, 2" in report and "0.60 ± 0.40" in report  # standard_cup, features
    assert (tmp_path / "report" / "TiltPour-v0.png").is_file()
