"""Running work on Ray: a Ray instance on this machine, or a cluster (the ``ray`` extra).

pour-gym's long jobs are many independent pieces: a policy search's candidates, an
experiment's episodes, a sweep's training runs. With ``--address`` they run as Ray tasks
(Ray Tune trials for sweeps) instead of one after another; without it nothing here is
imported and Ray need not be installed. Every piece is seeded on its own, so the result is
the same whichever worker ran it.

``address``:

- ``"local"``: start a Ray instance on this machine for the command, stopped after it.
- ``"auto"``: join the cluster this machine belongs to (``ray start`` ran here).
- ``"HOST:PORT"``: join the cluster whose head node listens there.
"""

from __future__ import annotations

import re
import sys
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from typing import Any

from tqdm import tqdm

from pour_gym.errors import InputError

RAY_INSTALL = "pip install 'pour-gym[ray]'"
_HOST_PORT = re.compile(r"^[A-Za-z0-9_.\-\[\]:]+:\d{1,5}$")


def require_ray():
    """The ``ray`` module.

    Raises:
        InputError: Ray is not installed (the message names the extra).
    """
    try:
        import ray
    except ImportError:
        raise InputError(f"--address needs Ray, which is not installed: {RAY_INSTALL}") from None
    return ray


def check_address(address: str) -> str:
    """An ``--address`` value as given, once it is ``local``, ``auto`` or ``HOST:PORT``.

    Raises:
        InputError: anything else.
    """
    if address in ("local", "auto") or _HOST_PORT.match(address):
        return address
    raise InputError(
        f"--address must be 'local', 'auto' or HOST:PORT (a Ray head node), not {address!r}"
    )


@contextmanager
def ray_session(address: str | None) -> Iterator[Any]:
    """Connect to Ray for a command; disconnect after it.

    Args:
        address: ``"local"``, ``"auto"``, ``"HOST:PORT"``, or None (no Ray: yields None).

    Yields:
        The ``ray`` module, connected (or None without an address).

    Raises:
        InputError: Ray missing, a malformed address, or no cluster there.
    """
    if address is None:
        yield None
        return
    check_address(address)
    ray = require_ray()
    if ray.is_initialized():  # the caller connected already (e.g. inside a Ray task)
        yield ray
        return
    options = {"include_dashboard": False, "log_to_driver": False}
    try:
        if address == "local":
            ray.init(**options)
        else:
            ray.init(address=address, **options)
    except (ConnectionError, RuntimeError, ValueError) as exc:
        raise InputError(
            f"could not join a Ray cluster at {address!r} ({exc}); start one with "
            "`ray start --head`, or use --address local"
        ) from None
    try:
        yield ray
    finally:
        ray.shutdown()


def map_tasks(
    fn: Callable[[Any], Any],
    items: Sequence[Any],
    ray=None,
    num_cpus: float = 1.0,
    desc: str | None = None,
) -> list[Any]:
    """``[fn(item) for item in items]``, as Ray tasks when ``ray`` is connected.

    Args:
        fn: a module-level function of one argument (Ray ships it to the workers).
        items: the arguments.
        ray: the connected ``ray`` module (from :func:`ray_session`), or None to run here.
        num_cpus: CPUs each task reserves.
        desc: a progress bar's label (None: no bar).

    Returns:
        The results, in the order of ``items`` whatever order the tasks finished in.
    """
    bar = tqdm(total=len(items), desc=desc, file=sys.stderr, disable=desc is None)
    if ray is None:
        results = []
        for item in items:
            results.append(fn(item))
            bar.update()
        bar.close()
        return results
    remote = ray.remote(num_cpus=num_cpus)(fn)
    refs = [remote.remote(item) for item in items]
    pending = list(refs)
    while pending:
        done, pending = ray.wait(pending, num_returns=1)
        bar.update(len(done))
    bar.close()
    return ray.get(refs)


def node_id() -> str | None:
    """The Ray node this code runs on (None outside Ray)."""
    try:
        import ray
    except ImportError:
        return None
    if not ray.is_initialized():
        return None
    return ray.get_runtime_context().get_node_id()
