"""The particle fluid: collisions, determinism, hydrostatics, pour onset (small counts).

All at the default parameters (4 over-relaxed iterations, substeps of at most 1/240 s).
"""

import json
import os
import subprocess
import sys

import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from pour_gym.errors import InputError
from pour_gym.fluid import PBFConfig, PBFluid, build_sdf
from pour_gym.fluid.validation import (
    BASE,
    COLUMN_HEIGHT,
    ONSET_HEIGHT,
    R_IN,
    WALL,
    cylinder_field,
    pour_onset,
    settled_column,
)
from pour_gym.objects import cylinder_cup

HEIGHT = ONSET_HEIGHT


@pytest.fixture(scope="module")
def cup():
    return cylinder_cup(R_IN, HEIGHT, WALL, BASE)


@pytest.fixture(scope="module")
def cup_sdf(cup, tmp_path_factory):
    return build_sdf(cup, spacing=0.001, cache_dir=tmp_path_factory.mktemp("sdf"))


def column(spacing, height):
    g = np.arange(-R_IN + spacing / 2, R_IN, spacing)
    zs = np.arange(BASE + spacing / 2, BASE + height, spacing)
    pts = np.stack(np.meshgrid(g, g, zs, indexing="ij"), -1).reshape(-1, 3)
    return pts[np.hypot(pts[:, 0], pts[:, 1]) < R_IN - spacing / 2]


def test_sdf_matches_the_analytic_wall(cup_sdf, cup, tmp_path):
    rng = np.random.default_rng(0)
    # Points at mid-height: the distance to the wall material is radial.
    r = rng.uniform(0.0, 0.06, 500)
    a = rng.uniform(0, 2 * np.pi, 500)
    pts = np.column_stack([r * np.cos(a), r * np.sin(a), np.full(500, 0.05)])
    expected = np.where(
        r < R_IN,
        R_IN - r,
        np.where(r > R_IN + WALL, r - R_IN - WALL, -np.minimum(r - R_IN, R_IN + WALL - r)),
    )
    d, grad = cup_sdf.sample(pts)
    # Polygon of 96 sides, 1 mm grid: within a fraction of a millimetre.
    assert np.abs(d - expected).max() < 5e-4
    inside = (r < R_IN - 0.002) & (r > R_IN - 0.01)  # away from the medial axis
    radial = -pts[inside, :2] / r[inside, None]
    assert np.all(np.sum(grad[inside, :2] * radial, axis=1) > 0.95)
    # The cache returns the same field.
    again = build_sdf(cup, spacing=0.001, cache_dir=tmp_path)
    cached = build_sdf(cup, spacing=0.001, cache_dir=tmp_path)
    assert np.array_equal(again.values, cached.values)
    assert len(list(tmp_path.glob("sdf_*.npz"))) == 1


def test_sdf_of_an_open_mesh_gives_every_surface_a_wall():
    box = trimesh.creation.box([0.05, 0.05, 0.05])
    box.update_faces(np.arange(12) > 1)  # an open box: one face (two triangles) removed
    assert not box.is_watertight
    sdf = build_sdf(box, min_wall=0.003)
    # On a face's surface the material is at least half the minimum wall deep.
    d, _ = sdf.sample(np.array([[0.0, 0.0, -0.025], [0.0, 0.025, 0.0]]))
    assert np.all(d <= -0.0014)
    with pytest.raises(InputError, match="no faces"):
        build_sdf(trimesh.Trimesh(np.zeros((3, 3)), np.zeros((0, 3), dtype=int)))


@pytest.fixture(scope="module")
def tall_sdf(tmp_path_factory):
    """A cylinder deep enough to hold a column of 8.6 cm below its rim with room to spare."""
    return cylinder_field(COLUMN_HEIGHT, cache_dir=tmp_path_factory.mktemp("sdf"))


@pytest.mark.slow
@pytest.mark.parametrize("height", [0.025, 0.086])
def test_settled_column_height_and_rest(tall_sdf, height):
    """A column settles to N v / (pi R^2) within 5 % (twice its particles' mean height),
    at a shallow and at a full cup's depth, at rest density in the bulk (mean absolute
    error under 3 % over the last 0.5 s), and comes to rest up to a jitter of a few cm/s."""
    result = settled_column(height, field=tall_sdf)
    assert result.lost == 0
    assert abs(result.height_error) < 0.05
    if height > 0.05:  # a shallow column has no bulk to speak of
        assert result.density_error < 0.03
    assert result.rms_speed < 0.12


def test_rotating_cup_loses_nothing_and_nothing_enters_the_wall(cup_sdf):
    cfg = PBFConfig()
    lift = np.array([0.0, 0.0, 0.12])
    pts = column(cfg.spacing, 0.04) + lift
    fluid = PBFluid(pts, cfg, floor=0.0)
    cup = fluid.add_collider(cup_sdf, translation=lift)
    worst = np.inf
    duration, fps = 4.0, 60
    for k in range(int(duration * fps)):
        t = (k + 1) / fps
        angle = 180.0 * min(t / (duration / 2), 2.0 - t / (duration / 2))
        cup.rotation = Rotation.from_euler("x", angle, degrees=True).as_matrix()
        fluid.step(1 / fps)
        d, _ = cup_sdf.sample((fluid.x - lift) @ cup.rotation)
        worst = min(worst, d.min())
    assert len(fluid.x) == len(pts) and np.isfinite(fluid.x).all()
    assert worst > 0.0  # no particle ever inside the wall's material
    assert fluid.x[:, 2].min() >= cfg.radius - 1e-12  # and none below the table


def test_a_push_out_of_a_wall_gives_no_more_speed_than_the_particle_brought(cup_sdf):
    """A particle found inside a wall (a scan's folds put particles there) is pushed out,
    but the push is not a velocity: at rest, 1.5 mm inside the side wall, the push of 4 mm
    in one 1/240 s substep would fling it off at 1 m/s (the YCB mug lost particles to the
    table this way at 12 deg of tilt). It leaves the wall as slowly as gravity moved it."""
    cfg = PBFConfig()
    start = np.array([[R_IN + 0.0015, 0.0, BASE + 0.03]])
    fluid = PBFluid(start, cfg)
    fluid.add_collider(cup_sdf)
    fluid.step(cfg.substep)
    d, _ = cup_sdf.sample(fluid.x)
    assert d[0] >= cfg.radius - 1e-4  # out of the material, a radius off the wall
    assert fluid.x[0, 0] < R_IN  # on the side of the cavity, where it was nearest
    assert np.linalg.norm(fluid.v[0]) < 0.1  # m/s: gravity's 0.04, not the push's 1


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="the tbb wheel is Linux's")
def test_parallel_loops_run_on_tbb_after_open3d_was_loaded_first():
    """open3d bundles TBB 2021.5, too old for numba: were it the process's first TBB, a
    parallel kernel told to use TBB would raise "No threading layer could be loaded" (as
    it did in a test run that scanned a cup before it evaluated a policy)."""
    script = (
        "import numba, numpy as np\n"
        "import pour_gym\n"
        "from pour_gym.io.open3d_loader import open3d\n"
        "open3d()\n"
        "import pour_gym.fluid\n"
        "@numba.njit(parallel=True, cache=False)\n"
        "def total(a):\n"
        "    s = 0.0\n"
        "    for i in numba.prange(len(a)):\n"
        "        s += a[i]\n"
        "    return s\n"
        "print(total(np.ones(1000)), numba.threading_layer())\n"
    )
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.split() == ["1000.0", "tbb"]


FORK_SCRIPT = """
import json, multiprocessing, warnings
import numba, numpy as np
from pour_gym.fluid import PBFConfig, PBFluid
from pour_gym.mesh.gaussian_field import fit_gaussian_field

def run(start):
    fluid = PBFluid(start, PBFConfig(), num_threads=2)
    fluid.wait_for_kernel()
    for _ in range(5):
        fluid.step(1 / 60)
    return fluid

def child(start, field, queue):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        fluid = run(start)
        values = field(start)
    queue.put((fluid.x, fluid.build, values, [str(w.message) for w in caught]))

if __name__ == "__main__":
    g = np.arange(6) * 0.005
    start = np.stack(np.meshgrid(g, g, g), -1).reshape(-1, 3) + [0.0, 0.0, 0.01]
    parent = run(start)
    field = fit_gaussian_field(start, sigma=0.01)
    values = field(start)
    context = multiprocessing.get_context("fork")
    queue = context.Queue()
    worker = context.Process(target=child, args=(start, field, queue))
    worker.start()
    x, build, child_values, caught = queue.get(timeout=300)
    worker.join(timeout=60)
    print(json.dumps({
        "layer": numba.threading_layer(), "exitcode": worker.exitcode, "build": build,
        "same_particles": bool(np.array_equal(x, parent.x)),
        "same_field": bool(np.array_equal(values, child_values)), "warnings": caught,
    }))
"""


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="fork is Linux's default")
def test_a_child_forked_after_openmp_runs_on_one_thread(tmp_path):
    """GNU OpenMP (numba's layer where the tbb wheel is missing, or by choice) kills a
    forked child at its first parallel loop if the parent used it: such a child runs the
    one-thread builds of the fluid and of the Gaussian field instead, the same numbers,
    after a warning that names the fix."""
    script = tmp_path / "fork.py"
    script.write_text(FORK_SCRIPT)
    env = {**os.environ, "NUMBA_THREADING_LAYER": "omp"}
    done = subprocess.run(
        [sys.executable, str(script)], capture_output=True, text=True, env=env, timeout=900
    )
    assert done.returncode == 0, done.stderr[-2000:]
    result = json.loads(done.stdout.strip().splitlines()[-1])
    assert result["layer"] == "omp"
    assert result["exitcode"] == 0
    assert result["build"] == "serial"
    assert result["same_particles"] and result["same_field"]
    assert len(result["warnings"]) == 2, result["warnings"]
    assert all("forkserver" in m for m in result["warnings"])


@pytest.mark.parametrize("liquid", ["water", "honey"])
def test_same_start_same_particles_bit_for_bit(cup_sdf, liquid):
    """The same start gives the same particles, and so do the serial and parallel builds;
    honey too (its viscosity pass and no-slip walls)."""
    from pour_gym.fluid.liquid import PRESETS

    def run(threads):
        cfg = PRESETS[liquid].fluid_config()
        fluid = PBFluid(column(cfg.spacing, 0.03), cfg, num_threads=threads)
        fluid.add_collider(cup_sdf)
        fluid.wait_for_kernel()  # the parallel build, not the serial one standing in for it
        assert fluid.build == ("parallel" if threads > 1 else "serial")
        for _ in range(20):
            fluid.step(1 / 60)
        return fluid.x.copy()

    first = run(2)
    assert np.array_equal(first, run(2))
    assert np.array_equal(first, run(1))


def test_divergence_is_an_error(cup_sdf):
    fluid = PBFluid(column(0.005, 0.02))
    fluid.add_collider(cup_sdf)
    fluid.v[3] = np.nan
    with pytest.raises(FloatingPointError, match="diverged"):
        fluid.step(1 / 60)


@pytest.mark.slow
@pytest.mark.parametrize("fill", [0.6, 0.7, 0.8])
def test_pour_onset_angle(cup_sdf, fill):
    """A cylinder filled to h, tilted slowly, pours at tan(theta) = (H - h) / R (+-3 deg)."""
    result = pour_onset(fill, field=cup_sdf)
    assert np.isfinite(result.measured_deg)
    assert abs(result.error_deg) < 3.0


def test_a_scanned_mug_with_folds_inside_holds_its_water():
    """The YCB mug's scan has a fold inside its cavity that leaves crevices narrower than a
    particle above a 4 mm bottom. Squeezed there, particles were pushed out of the far side
    of the bottom (75 of 301 gone in 3 s); held still, every particle must stay."""
    import gymnasium as gym

    import pour_gym  # noqa: F401 - registers the environments

    env = gym.make("PourGym/Pour-v0", objects="ycb_mug", num_threads=1)
    _, info = env.reset(seed=1000)
    fill = info["fill"]
    for _ in range(30):  # 3 s, the source held still
        _, _, _, _, info = env.step(np.zeros(4, np.float32))
    env.close()
    assert info["in_source"] == fill and info["spilled"] == 0


def test_scripted_pours_from_the_scanned_mugs_spill_nothing():
    """Pouring from the real scans (the YCB mug with its folds, pybullet's mug), the scripted
    policy spilled 5.7 particles per episode from the YCB mug, kicked off its walls, and
    succeeded in none of 10; every particle must now land in the target."""
    import gymnasium as gym

    import pour_gym  # noqa: F401 - registers the environments
    from pour_gym.agents.policies.rollout import rollout
    from pour_gym.agents.policies.scripted import ScriptedPourPolicy

    env = gym.make("PourGym/Pour-v0", objects="all,real", num_threads=1, max_episode_steps=250)
    for source, seed in (("ycb_mug", 50000), ("pybullet_mug", 50003)):
        info = rollout(env, ScriptedPourPolicy(), seed=seed, options={"source": source}).info
        assert info["spilled"] == 0, (source, info["spilled"])
        assert info["is_success"], (source, info["poured"], info["target_amount"])
    env.close()


def test_the_kernels_named_arguments_are_its_parameters_in_order():
    """``KernelArguments`` flattens to the compiled kernel's 58 positional arguments: its
    groups' fields must be the kernel's parameter names, in the kernel's order."""
    from pour_gym.fluid import build

    assert build.KernelArguments.names() == build.parameters()
    fluid = PBFluid(np.full((4, 3), 0.01))
    args = fluid.kernel_arguments(0.01)
    assert len(args.flat()) == len(build.parameters()) == 58
    assert args.particles.x is fluid.x


@pytest.mark.parametrize("nu, c", [(1.8e-3, 0.09), (1e-2, 0.0), (1e-2, 0.2), (5e-4, 0.0)])
def test_the_viscoelastic_fit_recovers_viscosity_and_wave_speed(nu, c):
    """``fit_viscoelastic`` (the shear wave's fit) recovers the viscosity and the elastic
    wave speed of a Kelvin-Voigt mode sampled as the measurement samples it (the tray's k),
    with noise of 2 % of the start: a soft solid (the method's water), a liquid and a
    viscous solid alike; within 5 % and 5 mm/s."""
    from pour_gym.fluid.validation import TRAY_WIDTH, fit_viscoelastic, viscoelastic_mode

    k = np.pi / TRAY_WIDTH
    t = np.arange(61) * 0.05
    a = viscoelastic_mode(t, k, nu, c)
    assert a[0] == pytest.approx(1.0)
    a[1:] += np.random.default_rng(0).normal(0.0, 0.02, len(t) - 1)
    found_nu, found_c = fit_viscoelastic(t, a, k)
    assert found_nu == pytest.approx(nu, rel=0.05)
    assert found_c == pytest.approx(c, abs=0.005)
    with pytest.raises(ValueError, match="at least 4"):
        fit_viscoelastic(t[:3], a[:3], k)
