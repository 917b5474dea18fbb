"""Liquids in SI units: presets, their fluid parameters, the viscosity they give, the envs.

The viscosity is checked as a physicist would: a shear wave in a tray
(:func:`pour_gym.fluid.validation.shear_wave`) decays at ``nu k^2``, and the ``nu`` fitted
to it must be the liquid's within 20 % (issue #41); the full sweep is ``pour-gym bench
viscosity``.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import pour_gym  # noqa: F401 (registers the envs)
from pour_gym.errors import InputError
from pour_gym.fluid.liquid import CALIBRATION, PRESETS, liquid_of, liquids_of
from pour_gym.fluid.pbf import PBFConfig, PBFluid


def test_presets_are_in_si_units_and_ordered_by_viscosity():
    """Densities in kg/m^3 near water's, viscosities in Pa s from water's 1e-3 up to honey's
    10, each in the order everyone knows; names resolve to the presets."""
    order = ["water", "milk", "oil", "syrup", "honey"]
    mus = [PRESETS[n].viscosity for n in order]
    assert mus == sorted(mus) and mus[0] == pytest.approx(1.0e-3, rel=0.01) and mus[-1] == 10
    for name in order:
        assert 850 <= PRESETS[name].density <= 1500
        assert liquid_of(name) is PRESETS[name]
    assert PRESETS["honey"].kinematic_viscosity == pytest.approx(10 / 1420)
    assert PRESETS["water"].particle_mass(PBFConfig()) == pytest.approx(0.125e-3, rel=0.01)


@pytest.mark.parametrize(
    "value, message",
    [
        ("ketchup", "unknown liquid 'ketchup'; presets: water, milk"),
        ({"density": 1000}, "missing \\['viscosity'\\]"),
        ({"density": 1000, "viscosity": 1, "colour": 1}, "unknown \\['colour'\\]"),
        ({"density": 1000, "viscosity": -1}, "viscosity is a dynamic viscosity in Pa s"),
        ({"density": 1.0, "viscosity": 1}, "density is in kg/m\\^3"),
        ([], "at least one liquid"),
        (3.0, "liquid is a preset name"),
    ],
)
def test_a_bad_liquid_is_refused_by_name(value, message):
    with pytest.raises(InputError, match=message):
        liquids_of(value)


def test_a_range_of_liquids_draws_viscosities_log_uniformly_and_checks_its_ends():
    """``{"viscosity": [lo, hi], "density": rho}``: each draw a liquid within the range, the
    same for the same generator, about as many per decade; bad ranges refused by name."""
    from pour_gym.fluid.liquid import LiquidRange

    (rng_liquid,) = liquids_of({"name": "thick", "viscosity": [2.0, 20.0], "density": 1400})
    assert isinstance(rng_liquid, LiquidRange)
    drawn = [rng_liquid.draw(np.random.default_rng(s)) for s in range(400)]
    mus = np.array([x.viscosity for x in drawn])
    assert mus.min() >= 2.0 and mus.max() <= 20.0 and all(x.density == 1400 for x in drawn)
    assert 0.4 < np.mean(mus < np.sqrt(40.0)) < 0.6  # the geometric middle halves them
    assert drawn[7] == rng_liquid.draw(np.random.default_rng(7))
    assert drawn[0].name.startswith("thick ") and drawn[0].name.endswith(" Pa s")
    with pytest.raises(InputError, match=r"viscosity low 5\.0 above high 2\.0"):
        liquids_of({"viscosity": [5.0, 2.0], "density": 1000})
    with pytest.raises(InputError, match="number or \\[low, high\\]"):
        liquids_of({"viscosity": [1, 2, 3], "density": 1000})


def test_lists_and_strings_of_liquids():
    assert [x.name for x in liquids_of("water, honey")] == ["water", "honey"]
    custom = liquids_of([{"name": "glycerol", "density": 1260, "viscosity": 1.4}, "oil"])
    assert custom[0].name == "glycerol" and custom[1] is PRESETS["oil"]
    assert liquids_of(None) == (PRESETS["water"],)


def test_water_keeps_the_fluid_as_it_was_and_honey_gets_the_viscosity_pass():
    """Water, milk and oil are thinner than the method's own viscosity at 5 mm: their fluid
    is water's, unchanged (Pour-v0's bits). Honey and syrup get no XSPH and the implicit
    pass, honey's stronger; a spacing without a calibration refuses them by name.
    """
    base = PBFConfig()
    for name in ("water", "milk", "oil"):
        assert PRESETS[name].fluid_config(base) == base
        assert not PRESETS[name].resolved(base)
    syrup, honey = PRESETS["syrup"].fluid_config(base), PRESETS["honey"].fluid_config(base)
    assert syrup.xsph == honey.xsph == 0.0
    assert 0.0 < syrup.viscosity < honey.viscosity
    # Where the pass dominates it is set near the liquid's own (the calibration's share).
    assert honey.viscosity == pytest.approx(PRESETS["honey"].kinematic_viscosity, rel=0.2)
    coarse = PBFConfig(spacing=0.007)
    assert PRESETS["water"].fluid_config(coarse) == coarse
    with pytest.raises(InputError, match="calibrated at the spacings 5 mm, not 7 mm"):
        PRESETS["honey"].fluid_config(coarse)


def test_the_calibration_is_monotone():
    """The measured total grows with the pass's value (so it can be inverted)."""
    for values, totals in CALIBRATION.values():
        assert np.all(np.diff(values) > 0) and np.all(np.diff(totals) > 0)
        assert values[0] == 0.0 and totals[0] > 0.0  # the method's own viscosity


def test_honeys_shear_wave_decays_at_honeys_viscosity():
    """A shear wave in honey (the calibrated pass at 5 mm) gives honey's kinematic viscosity
    within 20 %, and no elastic wave worth the name (a liquid's mode does not ring)."""
    from pour_gym.fluid.validation import shear_wave, tray_field

    honey = PRESETS["honey"]
    wave = shear_wave(duration=1.0, config=honey.fluid_config(), num_threads=1,
                      field=tray_field())  # fmt: skip
    assert wave.viscosity == pytest.approx(honey.kinematic_viscosity, rel=0.2)
    assert wave.amplitudes[-1] < 0.1


def test_the_viscosity_pass_is_stable_at_any_viscosity_and_conserves_momentum():
    """A block of fluid in free fall with a random velocity field, no walls: at 1000 times
    honey's viscosity the pass stays bounded (each sweep a weighted mean), the mean velocity
    is what gravity made it (the pass moves momentum between neighbours, never creates it),
    and the spread of velocities is damped, the more so the more viscous."""
    g = np.arange(8) * 0.005
    x = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)
    spreads = []
    for nu in (0.0, 7e-3, 7.0):
        fluid = PBFluid(x, PBFConfig(xsph=0.0, viscosity=nu), floor=None, num_threads=1)
        v0 = np.random.default_rng(0).normal(0.0, 0.05, x.shape)
        v0 -= v0.mean(axis=0)
        fluid.v[:] = v0
        for _ in range(5):
            fluid.step(0.01)
        assert np.isfinite(fluid.v).all() and np.abs(fluid.v).max() < 1.0
        assert fluid.v.mean(axis=0) == pytest.approx([0.0, 0.0, -9.81 * 0.05], abs=2e-3)
        spreads.append(float(np.std(fluid.v - fluid.v.mean(axis=0))))
    assert spreads[0] > spreads[1] > spreads[2]


def test_an_env_pours_honey_and_draws_liquids_per_episode():
    """``liquid=`` on an env: ``info["liquid"]`` names the episode's; a list is drawn from
    per episode, the same for the same seed; water by name is the default bit for bit."""
    kw = {"objects": "red_cup", "source_particles": 300, "num_threads": 1}
    env = gym.make("PourGym/Pour-v0", liquid="water,honey", **kw)
    names = [env.reset(seed=s)[1]["liquid"] for s in range(8)]
    assert set(names) == {"water", "honey"}
    assert names == [env.reset(seed=s)[1]["liquid"] for s in range(8)]
    for _ in range(5):
        *_, info = env.step(env.action_space.sample())
        assert info["liquid"] == names[-1]
    env.close()
    observations = []
    for liquid in (None, "water"):
        env = gym.make("PourGym/Pour-v0", liquid=liquid, **kw)
        obs, _ = env.reset(seed=3)
        for _ in range(5):
            obs, *_ = env.step(np.full(4, 0.5, dtype=np.float32))
        observations.append(obs)
        env.close()
    assert np.array_equal(observations[0], observations[1])
    ranged = {"viscosity": [2.0, 10.0], "density": 1400}
    env = gym.make("PourGym/Pour-v0", liquid=ranged, **kw)
    names = {env.reset(seed=s)[1]["liquid"] for s in range(4)}
    assert len(names) == 4 and all(n.startswith("range ") for n in names)
    env.close()
    env = gym.make("PourGym/Pour-v0", liquid="honey", objects="red_cup", num_threads=1)
    _, info = env.reset(seed=0, options={"target_ml": 20.0})
    assert info["target_amount"] == 160 and info["target_ml"] == pytest.approx(20.0)
    with pytest.raises(InputError, match="target_amount \\(particles\\) or target_ml"):
        env.reset(seed=0, options={"target_ml": 20.0, "target_amount": 100})
    env.close()
    with pytest.raises(InputError, match="need fluid='pbf'"):
        gym.make("PourGym/Pour-v0", liquid="honey", fluid="bullet", **kw)


def test_water_drains_by_torricellis_law_and_honey_slower():
    """A cylinder draining through a hole in its base: the level's square root falls
    linearly (Torricelli's law), so the draining time to 1 cm is the law's with the
    discharge coefficient fitted on the first half of the fall, within 15 % (water: within
    3 % measured); honey drains slower (a smaller coefficient, viscous losses); a finer
    spacing, with more particles across the hole, drains nearer a sharp orifice's 0.6."""
    from pour_gym.fluid.flows import efflux

    water = efflux(num_threads=1)
    assert water.drain_s == pytest.approx(water.torricelli_s, rel=0.15)
    # Measured 0.47 at 5 mm (docs/liquids.md: the opening a particle fluid can pass is
    # the hole less half a spacing all round, 63 % of its area; against it 0.75).
    assert 0.4 < water.discharge < 1.0
    honey = efflux(config=PRESETS["honey"].fluid_config(), num_threads=1)
    assert honey.discharge < 0.8 * water.discharge
    assert honey.drain_s > 1.5 * water.drain_s
    # A finer spacing fills more of the hole: 0.521-0.536 at 3.5 mm measured (0.553-0.558
    # at 2.5 mm, `pour-gym bench efflux`), the draining still Torricelli's.
    from pour_gym.apps.bench.liquids import bench_efflux, efflux_table

    (fine,) = bench_efflux((0.0035,))["rows"]
    assert fine["discharge"] > water.discharge + 0.04
    assert fine["ratio"] == pytest.approx(1.0, abs=0.15)
    assert "| 3.5 | 1 | 7597 | 6.9 |" in efflux_table({"rows": [fine]})
    # What sets the coefficient is the hole's size in spacings: half the vessel at half
    # the spacing (the hole 4.8 spacings across, as at 5 mm) drains as the 5 mm one does
    # (0.475 against 0.469 measured; twice the vessel at 5 mm, 9.6 across, 0.553 against
    # 2.5 mm's 0.558).
    (similar,) = bench_efflux((0.0025,), scales=(0.5,))["rows"]
    assert similar["hole_spacings"] == pytest.approx(4.8)
    assert similar["discharge"] == pytest.approx(water.discharge, abs=0.02)
    assert similar["discharge"] < fine["discharge"] - 0.03


def test_a_dam_break_front_follows_martin_and_moyce():
    """A column a wide and 2a high collapsing along a tank: from T = t sqrt(2 g / a) = 2.5
    to the far wall its front stays within Martin and Moyce's two columns (widened by 5 %
    either way); before, it leads them (a dam removed at once, a floor without friction)
    by at most a third, and Koshizuka and Oka's front of the same column by at most a
    quarter. The column is near rest when the dam goes (0.150 m/s rms measured) but its
    base is squeezed (90th percentile of the density over rest 1.081): the lead follows
    the squeeze, not the motion, so a damped hold that halves the motion leaves the
    squeeze and the lead (docs/liquids.md)."""
    from pour_gym.fluid.flows import KOSHIZUKA_OKA, dam_break

    run = dam_break(num_threads=1)
    assert 0.0 < run.settled_speed < 0.25
    assert 1.03 < run.settled_compression < 1.15
    ko_times, ko_fronts = KOSHIZUKA_OKA
    lead = np.interp(ko_times, run.times, run.fronts) / np.array(ko_fronts)
    assert np.all(lead[1:] < 1.25) and np.all(lead[1:] > 1.0)  # 1.08-1.23 measured
    damped = dam_break(num_threads=1, settle_damping=0.5)
    assert damped.settled_speed < 0.6 * run.settled_speed  # 0.068 against 0.150 m/s
    assert abs(damped.settled_compression - run.settled_compression) < 0.02
    damped_lead = np.interp(ko_times, damped.times, damped.fronts) / np.array(ko_fronts)
    assert np.all(damped_lead[1:] > 1.0) and damped_lead.max() > 1.15  # 1.07-1.25 measured
    late = (run.times >= 2.5) & ~np.isnan(run.band[:, 0])
    assert late.sum() > 10
    z, band = run.fronts[late], run.band[late]
    assert np.all((z >= 0.95 * band[:, 0]) & (z <= 1.05 * band[:, 1]))
    early = (run.times < 2.5) & ~np.isnan(run.band[:, 0])
    assert np.all(run.fronts[early] <= 1.35 * run.band[early, 1])
    assert run.fronts[-1] > 6.5  # it reached the far wall (7 a)


def test_in_half_the_envs_substep_the_dam_breaks_column_holds_and_its_front_follows():
    """The envs' substep (1/240 s) squeezes the column 23 particles deep at its base (the
    solver's density 1.19 there, 1.081 read from the particles alone), a spring that
    pushes the surge off early; half of it (1/480 s) holds the column at water's density
    (1.005 measured) and the front follows Martin and Moyce's from their first point: at
    most 1.04x the band's top before T = 2.5 (1.29x at 1/240 s), 0.93-0.96x its edges
    after (docs/liquids.md)."""
    from dataclasses import asdict

    from pour_gym.apps.bench.liquids import FINE_SUBSTEP, _front_ratios
    from pour_gym.fluid.flows import dam_break
    from pour_gym.fluid.pbf import PBFConfig

    run = dam_break(num_threads=1, config=PBFConfig(substep=FINE_SUBSTEP))
    assert run.substep == FINE_SUBSTEP == 1 / 480
    assert run.settled_compression < 1.02
    lead, low, high = _front_ratios(asdict(run))
    assert lead < 1.10 and 0.90 < low and high < 1.05
    assert run.inside > 0.9  # 0.967 measured: the band widened by 5 % either way
    assert run.fronts[-1] > 6.5


def test_a_floor_with_friction_holds_the_dam_breaks_front_back():
    """On the envs' table (its friction 20/s) the surge reaches the far wall later than on
    a floor that lets it slide, and never leads it by more than a spacing."""
    from pour_gym.fluid.flows import DAM_WIDTH, dam_break

    free, held = dam_break(num_threads=1), dam_break(num_threads=1, floor_friction=20.0)
    assert held.floor_friction == 20.0 and free.floor_friction is None
    assert held.times[-1] > free.times[-1] + 0.3  # T: later by at least 0.02 s
    n = min(len(free.times), len(held.times))
    assert np.all(held.fronts[:n] <= free.fronts[:n] + 0.005 / DAM_WIDTH)
    from dataclasses import asdict

    from pour_gym.apps.bench.liquids import flows_table

    doc = {"efflux": {}, "dam_break": asdict(free), "dam_break_floor": asdict(held), "pours": {}}
    assert "| dam removed at once, a floor with friction (20/s) |" in flows_table(doc)


@pytest.mark.parametrize("speed", [-0.5, float("nan")])
def test_a_dam_break_refuses_a_gate_speed_that_is_no_speed(speed):
    from pour_gym.errors import InputError
    from pour_gym.fluid.flows import dam_break, gate_speed_limit

    with pytest.raises(InputError, match="gate_speed must be a speed of 0 m/s or more"):
        dam_break(gate_speed=speed, fields=(None, None))
    with pytest.raises(InputError, match="floor_friction must be a rate of 0 1/s or more"):
        dam_break(floor_friction=speed, fields=(None, None))
    for damping in (speed, 1.0):
        with pytest.raises(InputError, match="settle_damping is the share of the velocity"):
            dam_break(settle_damping=damping, fields=(None, None))
    from pour_gym.fluid.liquid import PRESETS

    with pytest.raises(InputError, match="for water only"):
        dam_break(config=PRESETS["honey"].fluid_config(), floor_friction=20.0, fields=(None, None))
    # Lauber and Hager's slowest gate for a column 2 a = 11.43 cm deep: sqrt(g h / 2).
    assert gate_speed_limit(0.1143) == pytest.approx(0.7488, abs=1e-4)


def test_honey_pours_later_slower_and_longer_than_water():
    """The red cup tilted at 30 deg/s to 110 deg, held, set upright: honey starts later
    (at a larger tilt), flows at a lower peak rate, leaves some in the cup, and its stream
    runs on after the cup turns back, where water's stops."""
    from pour_gym.sim.liquid_pour import liquid_pour

    water = liquid_pour("water", num_threads=1)
    honey = liquid_pour("honey", num_threads=1)
    assert honey.onset_deg > water.onset_deg + 3.0
    assert honey.peak_flow < 0.8 * water.peak_flow
    assert honey.poured < water.poured
    assert honey.stop_s > water.stop_s
