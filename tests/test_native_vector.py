"""The native vector env (Gymnasium's vector API, written as its own tests check it) and
the SB3 adapter: every id, the same episodes as single envs bit for bit, autoreset modes."""

import functools

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import data_equivalence
from gymnasium.vector import AutoresetMode

import pour_gym  # noqa: F401
from pour_gym.envs import ENVS, POUR_V0, POUR_V1, entry
from pour_gym.envs.containers import ContainerStore
from pour_gym.envs.vector import PourVectorEnv, autoreset

QUICK = entry(POUR_V0).quick


def random_actions(space: gym.Space, steps: int, seed: int) -> list:
    space = gym.spaces.Box(space.low, space.high, dtype=space.dtype)
    space.seed(seed)
    return [space.sample() for _ in range(steps)]


def check_vector_env(venv, steps: int = 6) -> None:
    """What Gymnasium's vector API promises, checked as its tests check SyncVectorEnv."""
    n = venv.num_envs
    assert venv.metadata["autoreset_mode"] in AutoresetMode
    assert venv.observation_space == gym.vector.utils.batch_space(venv.single_observation_space, n)
    assert venv.action_space == gym.vector.utils.batch_space(venv.single_action_space, n)
    obs, info = venv.reset(seed=11)
    assert obs in venv.observation_space and isinstance(info, dict)
    again, _ = venv.reset(seed=11)
    assert data_equivalence(obs, again, exact=True), "seeded resets differ"
    venv.action_space.seed(0)
    for _ in range(steps):
        obs, reward, terminated, truncated, info = venv.step(venv.action_space.sample())
        assert obs in venv.observation_space
        for array, dtype in ((reward, np.float64), (terminated, np.bool_), (truncated, np.bool_)):
            assert isinstance(array, np.ndarray) and array.shape == (n,) and array.dtype == dtype
        for key, _value in info.items():
            if not key.startswith("_"):
                assert f"_{key}" in info, f"info[{key!r}] has no mask"
                mask = info[f"_{key}"]
                assert mask.shape == (n,) and mask.dtype == np.bool_
    assert len(venv.get_attr("spec")) == n


@pytest.mark.parametrize("env_id", [e.id for e in ENVS])
def test_make_vec_gives_the_native_vector_env_for_every_id(env_id):
    venv = gym.make_vec(
        env_id, num_envs=2, vectorization_mode="vector_entry_point", **entry(env_id).quick
    )
    assert isinstance(venv.unwrapped, PourVectorEnv)
    assert venv.unwrapped.spec.id == env_id
    assert gym.spec(env_id).to_json()  # a string entry point: specs stay serialisable
    check_vector_env(venv)
    venv.close()
    venv.close()  # twice is fine
    with pytest.raises(RuntimeError, match="closed"):
        venv.step(venv.action_space.sample())


def singles(env_id, seeds, actions, kwargs, max_steps):
    """Each env alone: observations and rewards at every vector step (next-step autoreset)."""
    out = []
    for i, seed in enumerate(seeds):
        env = gym.make(env_id, num_threads=1, max_episode_steps=max_steps, **kwargs)
        obs, _ = env.reset(seed=seed)
        rows, ended = [(obs, 0.0)], False
        for a in actions:
            if ended:
                obs, _ = env.reset()
                rows.append((obs, 0.0))
                ended = False
                continue
            obs, reward, terminated, truncated, _ = env.step(a[i])
            rows.append((obs, reward))
            ended = terminated or truncated
        env.close()
        out.append(rows)
    return out


def test_three_envs_on_two_threads_pour_what_three_single_envs_pour():
    """Bit for bit: observations and rewards of each env, episodes ending (the time limit)
    and starting again by next-step autoreset, more envs than threads."""
    kwargs = {**QUICK, "objects": "red_cup"}
    n, steps, max_steps = 3, 24, 9
    venv = PourVectorEnv(POUR_V1, n, num_threads=2, max_episode_steps=max_steps, **kwargs)
    actions = random_actions(venv.action_space, steps, seed=4)
    obs, _ = venv.reset(seed=[5, 6, 7])
    rows = [(obs, np.zeros(n))]
    for a in actions:
        obs, reward, _terminated, _truncated, _ = venv.step(a)
        rows.append((obs, reward))
    assert len(venv.containers) == 1, "the envs did not share their one container"
    venv.close()
    alone = singles(POUR_V1, [5, 6, 7], actions, kwargs, max_steps)
    for i in range(n):
        for k, (obs, reward) in enumerate(rows):
            assert np.array_equal(obs[i], alone[i][k][0]), f"env {i}, step {k}: observations"
            assert reward[i] == alone[i][k][1], f"env {i}, step {k}: rewards"


def test_same_step_autoreset_gives_the_final_observation_and_info():
    kwargs = {**QUICK, "objects": "red_cup"}
    venv = PourVectorEnv(POUR_V0, 2, autoreset_mode="same-step", max_episode_steps=3, **kwargs)
    assert venv.metadata["autoreset_mode"] == AutoresetMode.SAME_STEP
    venv.reset(seed=1)
    zero = np.zeros((2, 4), dtype=np.float32)
    for _ in range(2):
        _, _, _, truncated, info = venv.step(zero)
        assert not truncated.any() and "final_obs" not in info
    obs, _reward, _terminated, truncated, info = venv.step(zero)
    assert truncated.all() and info["_final_obs"].all()
    assert info["final_obs"][0] in venv.single_observation_space
    assert not np.array_equal(info["final_obs"][0], obs[0]), "the final and new observations"
    assert info["final_info"]["poured"].shape == (2,)
    venv.close()


def test_reset_mask_resets_only_the_envs_it_names_and_disabled_autoreset_says_so():
    kwargs = {**QUICK, "objects": "red_cup"}
    venv = PourVectorEnv(POUR_V0, 2, autoreset_mode="Disabled", max_episode_steps=1, **kwargs)
    _first, _ = venv.reset(seed=3)
    venv.step(np.zeros((2, 4), dtype=np.float32))
    with pytest.raises(RuntimeError, match="reset them first"):
        venv.step(np.zeros((2, 4), dtype=np.float32))
    _obs, info = venv.reset(options={"reset_mask": np.array([True, False])})
    assert info["_target_amount"].tolist() == [True, False]
    with pytest.raises(RuntimeError, match="reset them first"):
        venv.step(np.zeros((2, 4), dtype=np.float32))
    with pytest.raises(ValueError, match="reset_mask"):
        venv.reset(options={"reset_mask": [True, False]})
    with pytest.raises(ValueError, match="one seed per env"):
        venv.reset(seed=[1, 2, 3])
    venv.close()


def test_bad_vector_arguments_are_named():
    with pytest.raises(ValueError, match="autoreset_mode must be one of NextStep"):
        autoreset("sometimes")
    assert autoreset("next-step") == AutoresetMode.NEXT_STEP
    with pytest.raises(ValueError, match="num_envs must be at least 1"):
        PourVectorEnv(POUR_V0, 0)
    with pytest.raises(ValueError, match="unknown reset options"):
        venv = PourVectorEnv(POUR_V0, 1, **QUICK)
        try:
            venv.reset(options={"sideways": True})
        finally:
            venv.close()


def test_the_sb3_adapter_steps_what_sb3s_dummy_vec_env_steps():
    """train.py's native vector env against SB3's own, same seeds and actions: the same
    observations, rewards, dones, terminal observations and episode statistics."""
    from pour_gym.agents.training.curriculum import TrainingStarts
    from pour_gym.agents.training.vector import training_vec_env

    kwargs = {"objects": "red_cup", "amount_range": (40, 80), "max_episode_steps": 8}
    starts = functools.partial(TrainingStarts, near_target=0.5, fill_margin=(0, 40))
    runs = {}
    for vec in ("native", "dummy"):
        venv = training_vec_env(POUR_V1, 2, 5, kwargs, starts, vec)
        rows = [venv.reset()]
        for a in random_actions(venv.action_space, 20, seed=1):
            obs, reward, done, infos = venv.step(np.stack([a, a]) if a.ndim == 1 else a)
            ends = [info.get("terminal_observation") for info in infos]
            stats = [info.get("episode", {}).get("r") for info in infos]
            rows.append((obs, reward, done, ends, stats))
        venv.close()
        runs[vec] = rows
    native, dummy = runs["native"], runs["dummy"]
    assert np.array_equal(native[0], dummy[0])
    assert sum(int(row[2].sum()) for row in native[1:]) == 4, "two episodes per env ended"
    for a, b in zip(native[1:], dummy[1:], strict=True):
        assert a[1].dtype == np.float64  # SubprocVecEnv's; DummyVecEnv's are float32
        for x, y in zip(a[:3], b[:3], strict=True):
            assert np.array_equal(x.astype(y.dtype), y)
        for x, y in zip(a[3], b[3], strict=True):
            assert (x is None and y is None) or np.array_equal(x, y)
        assert a[4] == b[4]


def test_a_store_keeps_the_containers_used_last():
    store = ContainerStore(capacity=2)
    loads = []

    def load(name):
        loads.append(name)
        return name.upper()

    for name in ("a", "b", "a", "c", "a", "b"):
        assert store.get(name, "asset", lambda name=name: load(name)) == name.upper()
    # "b" was evicted by "c" (least recently used), "a" never.
    assert loads == ["a", "b", "c", "b"] and len(store) == 2 and "c" not in store
    shared = ContainerStore(capacity=4)
    shared.adopt(store)  # an env joining a vector env's store brings what it loaded
    assert shared.get("a", "asset", lambda: load("never")) == "A" and len(shared) == 2
    with pytest.raises(ValueError, match="at least one"):
        ContainerStore(0)


def test_a_store_keeps_small_values_of_containers_it_evicted():
    # What a source holds by tilt takes a second to make and a kB to keep: an env over a
    # family meets most sources again after their eviction, and must not make it again.
    store, loads = ContainerStore(capacity=1), []

    def load(name):
        loads.append(name)
        return np.full(3, len(loads))

    for name in ("a", "b", "a", "b"):
        store.get(name, "asset", lambda name=name: name)
        store.get(name, "held", lambda name=name: load(name), small=True)
    assert loads == ["a", "b"] and len(store) == 1  # the assets were evicted, not these
    assert store.get("a", "held", lambda: load("never"), small=True).tolist() == [1, 1, 1]
    shared = ContainerStore(capacity=4)
    shared.adopt(store)
    assert shared.get("b", "held", lambda: load("never"), small=True).tolist() == [2, 2, 2]
    shared.clear()
    assert shared.get("b", "held", lambda: load("b"), small=True).tolist() == [3, 3, 3]
