"""The fluid's particle spacing as an env argument (``spacing=``, issue #41).

A finer or coarser fluid is the same task in millilitres: the amounts sized for 5 mm
particles (T's range, the fill's margin) keep their volume, the fluid's config takes the
spacing, and a spacing the fluid cannot take, or one given twice differently, is refused
by name before any work.
"""

from __future__ import annotations

import pickle

import gymnasium as gym
import pytest

import pour_gym  # noqa: F401 (registers the envs)
from pour_gym.agents.policies.rollout import rollout
from pour_gym.agents.policies.scripted import ScriptedPourPolicy, action_settings
from pour_gym.agents.training.curriculum import TrainingStarts
from pour_gym.envs import POUR_V1
from pour_gym.errors import InputError
from pour_gym.fluid.pbf import PBFConfig


def test_a_finer_spacing_is_the_same_task_in_millilitres():
    """At 3.5 mm a particle is 0.043 ml: T's range and the fill's margin hold 2.9 times the
    particles, the same 12.5-37.5 ml and 12.5 ml as at 5 mm (the curriculum's margins too)."""
    env = gym.make(POUR_V1, objects="red_cup", spacing=0.0035, num_threads=1)
    u = env.unwrapped
    assert u.fluid_config.spacing == 0.0035 and u.fluid_config == PBFConfig(spacing=0.0035)
    per = (0.005 / 0.0035) ** 3
    assert u.amount_range == (round(100 * per), round(300 * per)) == (292, 875)
    for seed in range(3):
        _, info = env.reset(seed=seed)
        assert 12.5 <= info["target_ml"] <= 37.5
        assert info["fill"] - info["target_amount"] == round(100 * per)
        assert len(u.world.particles) == info["fill"]
    again = pickle.loads(pickle.dumps(u))
    assert again.fluid_config.spacing == 0.0035 and again.amount_range == u.amount_range
    # The training curriculum's margins are 5 mm particles too.
    starts = TrainingStarts(env, fill_margin=(20, 20))
    _, info = starts.reset(seed=0)
    assert info["fill"] - info["target_amount"] == round(20 * per) == 58
    env.close()
    default = gym.make(POUR_V1, objects="red_cup").unwrapped
    assert default.amount_range == (100, 300) and default.fluid_config == PBFConfig()
    default.close()


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"spacing": 0.001}, "from 0.0025 .* to 0.007"),
        ({"spacing": 0.008}, "from 0.0025 .* to 0.007"),
        ({"spacing": "5 mm"}, "rest distance in m"),
        ({"spacing": 0.004, "fluid_config": {"spacing": 0.006}}, "differ: give one"),
        ({"spacing": 0.004, "fluid_config": PBFConfig(spacing=0.006)}, "differ: give one"),
        ({"spacing": 0.0035, "liquid": "honey"}, "calibrated at the spacings"),
    ],
)
def test_a_spacing_the_fluid_cannot_take_is_refused_by_name(kwargs, message):
    with pytest.raises(InputError, match=message):
        gym.make(POUR_V1, objects="red_cup", **kwargs)


def test_a_spacing_given_both_ways_alike_is_taken():
    for config in ({"spacing": 0.004, "iterations": 5}, PBFConfig(iterations=5)):
        env = gym.make(POUR_V1, objects="red_cup", spacing=0.004, fluid_config=config)
        assert env.unwrapped.fluid_config == PBFConfig(spacing=0.004, iterations=5)
        env.close()


def test_the_expert_pours_at_a_coarse_spacing():
    """At 7 mm (a third of the particles) the scripted expert still pours the amount."""
    env = gym.make(POUR_V1, objects="red_cup", spacing=0.007, num_threads=1)
    policy = ScriptedPourPolicy(**action_settings(POUR_V1))
    for seed in range(2):
        info = rollout(env, policy, seed=seed).info
        assert info["is_success"] and info["spilled"] == 0, info
    env.close()
