"""The sensor observation modes: depth, rgb, points, and their combinations (issue #27)."""

from __future__ import annotations

import pickle
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from stable_baselines3.common.env_checker import check_env as sb3_check_env

import pour_gym  # noqa: F401  (registers the envs)
from pour_gym.agents.policies.scripted import ScriptedPourPolicy
from pour_gym.sim.raster import cluster_vertices
from pour_gym.sim.sensors import SEGMENTS, SensorConfig

# Small pictures keep the tests quick; 40 pixels clears SB3's 36-pixel CnnPolicy minimum.
SMALL = {"width": 40, "height": 40, "points": 128}


def make(env_id: str, obs_mode, **kwargs):
    return gym.make(
        env_id,
        objects="red_cup",
        num_threads=1,
        obs_mode=obs_mode,
        sensor_config=kwargs.pop("sensor_config", SMALL),
        **kwargs,
    )


def no_warnings(check) -> list[str]:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check()
    return [str(w.message) for w in caught]


ONE_STEP = ("PourGym/TiltPour-v0", "PourGym/ParticleDrop-v0")


@pytest.mark.parametrize(
    "env_id, obs_mode",
    [
        (e, m)
        for e in (*ONE_STEP, "PourGym/Pour-v1", "PourGym/PandaPour-v0")
        for m in ("depth", "rgb", "points")
    ]
    + [
        ("PourGym/ParticleDrop-v0", ("features", "depth")),
        ("PourGym/TiltPour-v0", ("state", "rgb")),
        ("PourGym/Pour-v1", ("features", "depth", "rgb", "points")),
        ("PourGym/Pour-v1", ("state", "points")),
    ],
)
def test_every_mode_passes_both_checkers_without_a_warning(env_id, obs_mode):
    env = make(env_id, obs_mode).unwrapped
    assert no_warnings(lambda: check_env(env, skip_render_check=True)) == []
    assert no_warnings(lambda: sb3_check_env(env)) == []
    obs, _ = env.reset(seed=0)
    if isinstance(obs_mode, tuple):
        assert isinstance(env.observation_space, gym.spaces.Dict)
        assert set(obs) == set(obs_mode)
    assert env.observation_space.contains(obs)
    env.close()


def test_same_seed_same_observation_bit_for_bit_with_noise_and_after_pickling():
    config = {**SMALL, "depth_noise": 0.002}
    mode = ("features", "depth", "rgb", "points")
    runs = []
    env = make("PourGym/Pour-v1", mode, sensor_config=config)
    clone = pickle.loads(pickle.dumps(env))
    plain = make("PourGym/Pour-v1", "features")
    for e in (env, clone, plain):
        obs, _ = e.reset(seed=7)
        seq = [obs]
        for a in np.random.default_rng(1).uniform(-1, 1, (4, 4)):
            seq.append(e.step(a.astype(np.float32))[0])
        runs.append(seq)
        e.close()
    for a, b in zip(runs[0], runs[1], strict=True):
        assert a.keys() == b.keys()
        for k in a:
            np.testing.assert_array_equal(a[k], b[k])
    # The sensors' randomness is a stream of its own: the episode is the plain env's.
    for a, b in zip(runs[0], runs[2], strict=True):
        np.testing.assert_array_equal(a["features"], b)
    # The noise is there: two resets with other seeds differ in depth.
    assert not np.array_equal(runs[0][0]["depth"], runs[0][1]["depth"])


@pytest.mark.parametrize("noise", [0.0, 0.002])
def test_the_target_points_lie_on_its_mesh_within_the_noise(noise):
    """Every point the camera saw on the target is on the target's surface (its signed
    distance field): within the drawn mesh's merging (half a pixel) plus the depth noise
    along the ray; the table's points lie on the plane z = 0."""
    config = {"width": 84, "height": 84, "points": 2048, "depth_noise": noise}
    env = make("PourGym/Pour-v1", "points", sensor_config=config).unwrapped
    obs, _ = env.reset(seed=3)
    cloud = obs.reshape(-1, 4)
    target = env._placed["target"]
    on_target = cloud[cloud[:, 3] == SEGMENTS["target"], :3]
    assert len(on_target) > 50
    local = (on_target - target.translation) @ target.rotation
    dist, _ = target.sdf.sample(local)
    tol = env.sensor.cell + 4.0 * noise + 1e-4
    assert np.quantile(np.abs(dist), 0.95) < tol
    on_table = cloud[cloud[:, 3] == SEGMENTS["table"], :3]
    assert len(on_table) > 50
    if noise == 0.0:
        assert np.abs(on_table[:, 2]).max() < 1e-6
    else:  # the noise is along the rays, which meet the table at 20-70 degrees
        assert 0.2 * noise < np.std(on_table[:, 2]) < noise
    env.close()


def test_the_fluid_points_in_the_target_grow_as_it_is_poured():
    env = make("PourGym/Pour-v0", ("features", "points"), sensor_config={"points": 4096}).unwrapped
    obs, info = env.reset(seed=11, options={"target_amount": 150})
    policy = ScriptedPourPolicy(amount=info["target_amount"])
    g = env._placed["target"].asset.geometry

    def fluid_over_target(o) -> int:
        cloud = o["points"].reshape(-1, 4)
        wet = cloud[cloud[:, 3] == SEGMENTS["fluid"], :3]
        centre = env._placed["target"].to_world(g.rim_center)
        near = np.linalg.norm(wet[:, :2] - centre[:2], axis=1) < g.rim_radius
        return int(np.sum(near & (wet[:, 2] < centre[2])))

    seen = [(0, fluid_over_target(obs))]
    for _ in range(250):
        obs, _, terminated, truncated, info = env.step(policy(obs["features"]))
        seen.append((info["poured"], fluid_over_target(obs)))
        if terminated or truncated:
            break
    env.close()
    assert seen[0][1] == 0
    assert info["poured"] > 100
    # Fluid seen in the target once half is poured, and more at the end than then.
    half = next(n for p, n in seen if p >= info["poured"] // 2)
    assert 0 < half < seen[-1][1]


def test_bad_modes_and_configs_are_refused_by_name():
    with pytest.raises(ValueError, match="obs_mode must be one of"):
        make("PourGym/TiltPour-v0", "camera")
    with pytest.raises(ValueError, match=r"one of .* at a time"):
        make("PourGym/TiltPour-v0", ("features", "state"))
    with pytest.raises(ValueError, match="twice"):
        make("PourGym/TiltPour-v0", ("depth", "depth"))
    with pytest.raises(ValueError, match="unknown sensor_config keys \\['size'\\]"):
        make("PourGym/TiltPour-v0", "depth", sensor_config={"size": 64})
    with pytest.raises(ValueError, match="points_frame"):
        SensorConfig(points_frame="lip")


def test_points_in_the_source_frame_are_the_world_points_moved():
    base = {**SMALL, "points": 256}
    world = make("PourGym/Pour-v1", "points", sensor_config=base).unwrapped
    lip = make("PourGym/Pour-v1", "points", sensor_config={**base, "points_frame": "source"})
    lip = lip.unwrapped
    a, _ = world.reset(seed=5)
    b, _ = lip.reset(seed=5)
    a, b = a.reshape(-1, 4), b.reshape(-1, 4)
    np.testing.assert_array_equal(a[:, 3], b[:, 3])
    rot, origin = lip._sensor_frame_pose()
    np.testing.assert_allclose(b[:, :3] @ rot.T + origin, a[:, :3], atol=1e-5)
    world.close()
    lip.close()


def test_merged_mesh_keeps_the_shape_within_a_cell():
    import trimesh

    mesh = trimesh.creation.cylinder(radius=0.04, height=0.1, sections=256)
    v, f = cluster_vertices(mesh.vertices, mesh.faces, 0.004)
    assert len(f) < len(mesh.faces)
    dist = trimesh.proximity.ProximityQuery(mesh).signed_distance(v)
    assert np.abs(dist).max() < 0.004 * np.sqrt(3)


def test_report_sensors_draws_a_sheet_with_fluid_in_view(tmp_path):
    from pour_gym.apps.cli import main
    from pour_gym.apps.sensor_pictures import observe_scene

    obs, caption = observe_scene("PourGym/TiltPour-v0")
    cloud = obs["points"].reshape(-1, 4)
    assert "tilted to 70 degrees" in caption
    # Looking into the tilted mouth: the water is seen, and it lies within the cup's reach.
    wet = cloud[cloud[:, 3] == SEGMENTS["fluid"], :3]
    assert len(wet) > 20 and np.linalg.norm(wet, axis=1).max() < 0.2
    assert main(["report", "sensors", "--out", str(tmp_path)]) == 0
    assert sorted(p.name for p in tmp_path.glob("*.png")) == [
        "pandapour-v0.png",
        "particledrop-v0.png",
        "pour-v0.png",
        "tiltpour-v0.png",
    ]


def test_the_head_camera_sees_the_arm_where_pybullet_draws_it():
    """PandaPour's sensors draw the arm's links (pybullet_data's visual meshes at the
    links' poses): the arm's pixels in the sensor's segments match those of pybullet's
    own renderer at the same camera (intersection over union above 0.9)."""
    import pybullet

    from pour_gym.sim.sensors import SEGMENTS

    env = gym.make(
        "PourGym/PandaPour-v0", objects="red_cup", obs_mode="depth", num_threads=1,
        sensor_config={"width": 160, "height": 120},
    )  # fmt: skip
    env.reset(seed=3)
    for _ in range(3):
        env.step(env.action_space.sample())
    u = env.unwrapped
    arm = u.capture().segment == SEGMENTS["arm"]
    cam = u.sensor.camera
    projection = pybullet.computeProjectionMatrixFOV(
        cam.fov, cam.width / cam.height, cam.near, cam.far
    )
    image = u.world.client.getCameraImage(
        cam.width, cam.height, viewMatrix=cam.view().T.flatten().tolist(),
        projectionMatrix=projection, renderer=pybullet.ER_TINY_RENDERER,
    )  # fmt: skip
    body = np.array(image[4]).reshape(cam.height, cam.width) & ((1 << 24) - 1)
    drawn = body == u.holder.panda().body
    env.close()
    assert arm.sum() > 0.05 * arm.size  # the arm is in view
    assert (arm & drawn).sum() / (arm | drawn).sum() > 0.9


def test_render_draws_the_scene_the_sensors_see():
    """One scene: ``render()`` draws the list the sensors draw (the containers, the arm,
    the table, the fluid). Moved to the head camera at the sensor's image size, the
    picture is the rgb observation, pixel for pixel; at its own camera it shows the arm."""
    env = gym.make(
        "PourGym/PandaPour-v0", objects="red_cup", obs_mode="rgb", num_threads=1,
        render_mode="rgb_array", sensor_config={"width": 96, "height": 72},
    )  # fmt: skip
    env.reset(seed=3)
    for _ in range(3):
        obs, *_ = env.step(env.action_space.sample())
    u = env.unwrapped
    picture = env.render()
    assert picture.shape == (u.camera.height, u.camera.width, 3)
    from pour_gym.sim.sensors import SEGMENTS

    segments = [body.segment for body in u.scene(u.sensor)]
    assert segments[:2] == [SEGMENTS["source"], SEGMENTS["target"]]
    assert segments.count(SEGMENTS["arm"]) >= 8  # the links and fingers
    u.camera = u.sensor.camera
    assert np.array_equal(env.render(), obs)
    env.close()
