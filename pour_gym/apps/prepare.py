"""Containers made ready ahead of a run: labelled, their fields computed, in parallel.

An env over a family labels each member (about 1.5 s) and computes its signed-distance
field (3-30 s) when an episode first uses it, and keeps both in the on-disk caches; a
run over ``procedural:train`` would spend its first hour doing that, one member at a time
inside its resets. ``pour-gym build-assets --objects procedural:train`` does it first, a
process per core, with a progress bar; every later env loads each member from the caches
in tens of milliseconds.
"""

from __future__ import annotations

import multiprocessing
import sys
import time
from concurrent.futures import ProcessPoolExecutor, as_completed

from tqdm import tqdm

from pour_gym.io.numba_threads import usable_cores


def prepare_container(name: str, perceive: bool = False, scan_seed: int = 0) -> dict:
    """Label a container and compute its field into the caches (what an env loads).

    Args:
        name: a container spec (catalogue name, family member, mesh or cloud file).
        perceive: also scan, reconstruct and label it as ``perception="scan"`` sees it.
        scan_seed: the scan's noise seed.

    Returns:
        ``{"name", "seconds", "refused"}``: ``refused`` names why the container cannot be
        used (closed, or refused by perception), or is None.
    """
    from pour_gym.assets import check_open, resolve_asset
    from pour_gym.errors import ClosedContainerError
    from pour_gym.perception import PerceptionError
    from pour_gym.sim.world import container_field

    start = time.perf_counter()
    refused = None
    try:
        asset = check_open(resolve_asset(name), name)
        container_field(asset)
        if perceive:
            from pour_gym.perception import perceived_asset

            perceived_asset(asset, scan_seed)
    except (ClosedContainerError, PerceptionError) as exc:
        refused = str(exc)
    return {"name": name, "seconds": time.perf_counter() - start, "refused": refused}


def prepare_containers(
    names: tuple[str, ...], jobs: int | None = None, perceive: bool = False, scan_seed: int = 0
) -> list[dict]:
    """:func:`prepare_container` for each name, ``jobs`` processes at once, with a bar.

    Args:
        names: container specs.
        jobs: processes (default: the cores this process may use).
        perceive: also what ``perception="scan"`` needs.
        scan_seed: the scans' noise seed.

    Returns:
        One :func:`prepare_container` result per name, in the order given.
    """
    jobs = usable_cores() if jobs is None else max(1, int(jobs))
    results: dict[str, dict] = {}
    bar = tqdm(total=len(names), desc="containers", unit="container", file=sys.stderr)
    if jobs == 1:
        for name in names:
            results[name] = prepare_container(name, perceive, scan_seed)
            bar.update()
    else:
        # forkserver: a worker is a clean process (no threads or GNU OpenMP state forked).
        context = multiprocessing.get_context("forkserver")
        with ProcessPoolExecutor(jobs, mp_context=context) as pool:
            futures = [pool.submit(prepare_container, n, perceive, scan_seed) for n in names]
            for future in as_completed(futures):
                result = future.result()
                results[result["name"]] = result
                bar.update()
    bar.close()
    return [results[name] for name in names]
