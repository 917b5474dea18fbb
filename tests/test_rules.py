"""The pouring task's rules and its actions' encoding: one definition each, read by the env,
the task and the expert."""

import numpy as np
import pytest

from pour_gym.envs.actions import (
    FLOW_REACH,
    FLOW_STOP,
    ONSET_REACH,
    UPRIGHT_BAND,
    check_motion,
    flow_action,
    flow_step,
    flow_wanted,
    next_lip,
    next_tilt,
    onset_goal,
    onset_tilt,
    tilt_action,
    tilt_goal,
)
from pour_gym.envs.rules import (
    FILL_MARGIN,
    POUR_OUTCOMES,
    RESTING_SPEED,
    PourTally,
    amount_terms,
    check_amounts,
    episode_amounts,
    episode_end,
    outcome,
    pour_counts,
    running_rise,
    succeeded,
    tolerance,
)
from pour_gym.errors import InputError
from pour_gym.sim.census import Census


def _counts(in_source=0, poured=0, in_flight=0, spilled=0):
    return {"in_source": in_source, "poured": poured, "in_flight": in_flight, "spilled": spilled}


def test_tolerance_and_success():
    assert [tolerance(t) for t in (30, 100, 188, 300)] == [5, 10, 19, 30]
    assert succeeded(180, 0, 2.9, 188, 19) and succeeded(207, 0, 0.0, 188, 19)
    assert not succeeded(168, 0, 0.0, 188, 19)  # 20 short of 188, the tolerance 19
    assert not succeeded(188, 1, 0.0, 188, 19)  # one particle spilled
    assert not succeeded(188, 0, 3.0, 188, 19)  # not upright: 3 deg is the bound


def test_an_episode_ends_settled_upright_after_a_pour_or_empty_or_on_failure():
    end = episode_end
    assert end(_counts(50, 150), 1.0, True, None, 150, 15) == (True, True)
    assert end(_counts(50, 150, in_flight=3), 1.0, True, None, 150, 15) == (False, False)
    assert end(_counts(50, 150), 10.0, True, None, 150, 15) == (False, False)  # tilted
    assert end(_counts(200, 0), 1.0, False, None, 150, 15) == (False, False)  # never poured
    assert end(_counts(0, 100), 80.0, True, None, 150, 15) == (True, False)  # empty, short
    assert end(_counts(50, 150), 1.0, True, "hit the target", 150, 15) == (True, False)


def test_the_amount_terms_sum_to_the_change_of_the_error():
    prev, now = _counts(poured=140), _counts(poured=160, spilled=2)
    terms = amount_terms(prev, now, 150, False)
    assert terms["progress"] == pytest.approx(10 / 150)
    assert terms["overshoot"] == pytest.approx(-10 / 150)
    assert terms["spill"] == pytest.approx(-2 / 150) and terms["success"] == 0.0


def test_outcomes_first_match_wins():
    base = {"is_success": False, "spilled": 0, "poured": 150, "target_amount": 150,
            "tolerance": 15, "poured_any": True}  # fmt: skip
    assert outcome({**base, "is_success": True, "spilled": 3}) == "success"
    assert outcome({**base, "spilled": 3, "poured": 400}) == "spilled"
    assert outcome({**base, "poured": 166}) == "overshot"
    assert outcome({**base, "poured": 0, "poured_any": False}) == "never_poured"
    assert outcome({**base, "poured": 134}) == "under_poured"
    assert outcome(base) == "unfinished"
    assert set(POUR_OUTCOMES) == {"success", "spilled", "overshot", "never_poured",
                                  "under_poured", "unfinished"}  # fmt: skip


def test_the_tilt_encoding_and_its_inverse():
    assert tilt_goal(-1.0, 135.0) == -UPRIGHT_BAND and tilt_goal(1.0, 135.0) == 135.0
    assert tilt_goal(0.0, 135.0) == pytest.approx(57.5)  # a zero action holds 57.5 deg
    for a in np.linspace(-1.0, 1.0, 21):
        assert tilt_action(tilt_goal(a, 135.0), 135.0) == pytest.approx(a, abs=1e-12)


def test_the_onset_is_where_what_the_source_holds_falls_to_its_fill():
    held = np.array([400.0, 380.0, 300.0, 301.0, 100.0, 0.0])  # 301: a voxel's noise
    assert onset_tilt(held, 340.0) == pytest.approx(1.5)  # halfway from 380 to 300
    assert onset_tilt(held, 300.0) == pytest.approx(2.0)
    assert onset_tilt(held, 200.0) == pytest.approx(3.5)  # 3 holds 300 as 2 does, not 301
    assert onset_tilt(held, 500.0) == 0.0  # more than it holds upright: pours at once
    assert onset_tilt(held, 0.0) == 5.0  # held at every tilt: the last


def test_an_onset_action_names_upright_the_onset_and_beyond():
    assert onset_goal(-1.0, 70.0, 135.0) == -UPRIGHT_BAND
    assert onset_goal(0.0, 70.0, 135.0) == 70.0
    assert onset_goal(-0.5, 70.0, 135.0) == pytest.approx(25.0)
    assert onset_goal(1.0, 70.0, 135.0) == 70.0 + ONSET_REACH
    assert onset_goal(1.0, 120.0, 135.0) == 135.0  # never past the largest tilt
    held = np.linspace(1000.0, 0.0, 136)  # 1000 particles upright, none at 135 deg
    # From 30 deg, at most 2 deg a step, towards the onset of 500 particles (67.5 deg).
    assert next_tilt("onset", 0.0, 30.0, 2.0, 135.0, held, 500.0) == 32.0
    assert next_tilt("onset", 0.0, 67.0, 2.0, 135.0, held, 500.0) == pytest.approx(67.5)
    assert next_tilt("onset", -1.0, 1.0, 2.0, 135.0, held, 500.0) == 0.0


def test_a_flow_action_names_a_stream_and_below_its_stop_none():
    """From FLOW_STOP to 1: 0 to FLOW_REACH target amounts a second (0.1 s steps)."""
    assert flow_wanted(1.0, 0.1) == pytest.approx(FLOW_REACH * 0.1)
    assert flow_wanted(0.0, 0.1) == pytest.approx(FLOW_REACH * 0.1 / 3.0)  # -0.5 to 1
    assert flow_wanted(FLOW_STOP, 0.1) == 0.0 and flow_wanted(-1.0, 0.1) == 0.0
    for a in (-0.4, 0.0, 0.7, 1.0):
        assert flow_action(flow_wanted(a, 0.1), 0.1) == pytest.approx(a)
    assert flow_action(10.0, 0.1) == 1.0  # beyond the reach: the most


def test_the_flow_regulator_tilts_on_while_short_and_back_while_over():
    """The scripted expert's law: 2 x the rate on x the relative error, within its rates."""
    assert flow_step(0.05, 0.0, 0.36, 1.8) == 0.36  # nothing flows: on at its most
    assert flow_step(0.05, 0.04, 0.36, 1.8) == pytest.approx(2 * 0.36 * 0.2)
    assert flow_step(0.05, 0.05, 0.36, 1.8) == 0.0
    assert flow_step(0.05, 0.5, 0.36, 1.8) == -1.8  # ten times over: back at its most
    held = np.linspace(1000.0, 0.0, 136)  # 500 particles reach the mouth at 67.5 deg
    args = (135.0, held, 500.0)
    # Nothing flowing below the onset: on at the env's rate (2 deg a step), not past it.
    assert next_tilt("flow", 0.0, 30.0, 2.0, *args, back=6.0) == 32.0
    assert next_tilt("flow", 0.0, 67.0, 2.0, *args, back=6.0) == pytest.approx(67.5)
    # At the onset with nothing flowing yet: on at the regulator's 3.6 deg/s.
    assert next_tilt("flow", 0.0, 70.0, 2.0, *args, back=6.0) == pytest.approx(70.36)
    # Flowing at twice the 0.05 T a step asked for: back by 2 x 0.36, within 1.8.
    assert next_tilt("flow", 0.0, 70.0, 2.0, *args, back=6.0, flow=0.1) == pytest.approx(69.28)
    # The stop: upright at the rate back, whatever flows.
    assert next_tilt("flow", FLOW_STOP, 70.0, 2.0, *args, back=6.0, flow=0.1) == 64.0
    assert next_tilt("flow", -1.0, 4.0, 2.0, *args, back=6.0) == 0.0
    with pytest.raises(InputError, match="need held"):
        next_tilt("flow", 0.0, 30.0, 2.0, 135.0)


def test_the_rate_and_angle_actions_move_the_tilt_as_they_did():
    for a, tilt in ((0.3, 10.0), (-1.0, 1.0), (1.0, 134.0)):
        assert next_tilt("rate", a, tilt, 6.0, 135.0) == float(np.clip(tilt + a * 6.0, 0, 135))
        goal = tilt_goal(a, 135.0)
        step = tilt + np.clip(goal - tilt, -6.0, 6.0)
        assert next_tilt("angle", a, tilt, 6.0, 135.0) == float(np.clip(step, 0, 135))


def test_a_faster_tilt_back_moves_only_towards_upright():
    """``back`` (max_untilt_rate's step) bounds the steps back; the steps on keep ``most``."""
    held = np.linspace(1000.0, 0.0, 136)
    for control in ("rate", "angle", "onset"):
        assert next_tilt(control, 1.0, 60.0, 2.0, 135.0, held, 500.0, back=6.0) == 62.0
        assert next_tilt(control, -1.0, 60.0, 2.0, 135.0, held, 500.0, back=6.0) == 54.0
        assert next_tilt(control, -1.0, 4.0, 2.0, 135.0, held, 500.0, back=6.0) == 0.0
    # From 60 deg towards 57.5 deg (a zero angle action): the goal is nearer than a step.
    assert next_tilt("angle", 0.0, 60.0, 2.0, 135.0, back=6.0) == pytest.approx(57.5)
    assert next_tilt("rate", -0.5, 60.0, 2.0, 135.0, back=6.0) == 57.0


def test_a_tilt_named_well_below_the_onset_stands_the_source_up():
    """``stand_below`` (Pour-v4's 0.5): a goal below that fraction of the onset is upright."""
    held = np.linspace(1000.0, 0.0, 136)  # 500 particles reach the mouth at 67.5 deg
    assert onset_tilt(held, 500.0) == pytest.approx(67.5)
    named_30 = tilt_action(30.0, 135.0)  # below 33.75 deg, half the onset
    for stand, after in ((None, 30.0), (0.5, 26.0)):
        assert next_tilt("angle", named_30, 32.0, 2.0, 135.0, held, 500.0, 6.0, stand) == after
    # Above half the onset a goal is as named; so is every goal without the onset's table.
    assert (
        next_tilt("angle", tilt_action(40.0, 135.0), 32.0, 2.0, 135.0, held, 500.0, 6.0, 0.5)
        == 34.0
    )
    assert next_tilt("angle", named_30, 32.0, 2.0, 135.0, back=6.0) == 30.0
    # The onset form: -0.5 names 23.75 deg here, so it stands up; 0 names the onset.
    assert next_tilt("onset", -0.5, 20.0, 2.0, 135.0, held, 500.0, 6.0, 0.5) == 14.0
    assert next_tilt("onset", 0.0, 66.0, 2.0, 135.0, held, 500.0, 6.0, 0.5) == pytest.approx(67.5)
    # A fuller source reaches its mouth sooner: its half onset is lower.
    assert next_tilt("angle", named_30, 32.0, 2.0, 135.0, held, 700.0, 6.0, 0.5) == 30.0
    for bad, match in ((0.0, r"in \(0, 1\]"), (1.5, r"in \(0, 1\]")):
        with pytest.raises(InputError, match=match):
            check_motion(0.15, 60.0, 135.0, "angle", "velocity", stand_below=bad)
    for control in ("rate", "flow"):
        with pytest.raises(InputError, match="tilt_control='angle' or 'onset'"):
            check_motion(0.15, 60.0, 135.0, control, "velocity", stand_below=0.5)
    with pytest.raises(InputError, match="need held"):
        next_tilt("angle", named_30, 32.0, 2.0, 135.0, back=6.0, stand_below=0.5)


def test_the_episode_amounts_fit_both_containers():
    rng = np.random.default_rng(0)
    # Sized to the task: the amount drawn within the range and both capacities, the fill
    # the amount plus the margin, capped by the source's capacity.
    for _ in range(50):
        fill, amount = episode_amounts(400, 250, (50, 300), None, rng)
        assert 50 <= amount <= 250 and fill == min(amount + FILL_MARGIN, 400)
    # A fixed fill leaves 50 particles in the source at the largest amount.
    amounts = {episode_amounts(2000, 2000, (1, 10_000), 600, rng)[1] for _ in range(200)}
    assert max(amounts) <= 550
    assert episode_amounts(2000, 2000, (50, 300), None, rng, amount=120, margin=30) == (150, 120)
    with pytest.raises(InputError, match="fill_margin"):
        episode_amounts(2000, 2000, (50, 300), 600, rng, margin=30)
    with pytest.raises(InputError, match=r"target_amount must be in \[1, 400\]"):
        episode_amounts(400, 2000, (50, 300), None, rng, amount=401)


def test_a_particle_in_no_container_has_spilled_once_it_rests():
    where = np.array([0, 0, 1, -1, -1, -1])
    speed = np.array([0.0, 0.0, 0.0, 2.0, RESTING_SPEED * 1.01, RESTING_SPEED * 0.99])
    v = np.zeros((6, 3))
    v[:, 2] = -speed
    census = Census(where=where, counts=np.array([2, 1]), elsewhere=3)
    c = pour_counts(census, v, source=0, target=1)
    assert {k: c[k] for k in ("in_source", "poured", "in_flight", "spilled")} == {
        "in_source": 2, "poured": 1, "in_flight": 2, "spilled": 1}  # fmt: skip


def test_pour_profile_times_the_stream_and_its_peak():
    """A stream that lets 10, 30, 0, 20 particles out on steps 3-6 of 8 (0.1 s each, T =
    100): it ran 0.4 s and peaked at 30 particles in a step, 3 T/s. A particle that
    flickers back into the source does not make a negative flow or a second stream."""
    from pour_gym.envs.task import POUR, pour_profile

    def infos(outs):
        return [{"poured": n, "in_flight": 0, "spilled": 0, "target_amount": 100} for n in outs]

    profile = pour_profile(infos([0, 0, 10, 40, 40, 60, 60, 60]), dt=0.1)
    assert profile["pour_seconds"] == pytest.approx(0.4)
    assert profile["peak_flow"] == pytest.approx(3.0)
    flicker = pour_profile(infos([0, 1, 0, 1, 1]), dt=0.1)
    assert flicker == {"pour_seconds": pytest.approx(0.1), "peak_flow": pytest.approx(0.1)}
    assert pour_profile(infos([0, 0]), dt=0.1) == {"pour_seconds": 0.0, "peak_flow": 0.0}
    assert POUR.profile(infos([0, 5]), dt=0.1)["pour_seconds"] == pytest.approx(0.1)


def test_the_tally_counts_a_flickering_particle_once_and_a_pour_after_its_steps():
    tally = PourTally(threshold=5, steps=3, most=0)
    outs = [0, 4, 6, 5, 6, 7, 7, 20]  # a particle in and out across the rim at 6, 5, 6
    flows, poured = [], []
    for out in outs:
        tally.update(out, 100)
        flows.append(round(tally.flow * 100))
        poured.append(tally.poured_any)
    assert flows == [0, 4, 2, 0, 0, 1, 0, 13]  # the rise of the running most
    assert sum(flows) == max(outs)
    # 6, 5, 6 are three steps at or above 5 out: the pour has happened at the third.
    assert poured == [False, False, False, False, True, True, True, True]
    assert running_rise(3.0, 5.0) == (0.0, 5.0) and running_rise(7.5, 5.0) == (2.5, 7.5)


def test_amounts_and_the_pour_rule_are_checked_with_a_message():
    assert check_amounts(None, None, 1.0, 5, 3) == (100, 300)
    # At 3.5 mm particles the default range keeps its millilitres: 2.915x the particles.
    assert check_amounts(None, None, (5 / 3.5) ** 3, 5, 3) == (292, 875)
    with pytest.raises(InputError, match="source_particles must be at least 100"):
        check_amounts(50, None, 1.0, 5, 3)
    with pytest.raises(InputError, match="amount_range"):
        check_amounts(None, (300, 100), 1.0, 5, 3)
    with pytest.raises(InputError, match="pour_steps"):
        check_amounts(None, None, 1.0, 5, 0)


def test_the_lip_moves_at_most_its_speed_and_stays_in_the_box():
    lip = np.array([0.0, 0.0, 0.2])
    # A velocity: 0.15 m/s for 0.1 s at action 1.
    moved = next_lip(np.array([1.0, -0.5, 0.0]), lip, 0.1, 0.15, 0.1, None)
    assert np.allclose(moved, [0.015, -0.0075, 0.2])
    # Towards a goal 1 m away along x: one step's reach, and the lowest height holds.
    moved = next_lip(np.zeros(3), lip, 0.25, 0.15, 0.1, np.array([1.0, 0.0, 0.2]))
    assert np.allclose(moved, [0.015, 0.0, 0.25])
    # The box over the table: x at most 0.45 m.
    assert next_lip(np.ones(3), np.array([0.449, 0.0, 0.3]), 0.1, 0.15, 0.1, None)[0] == 0.45
