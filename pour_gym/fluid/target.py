"""``POUR_GYM_CPU``: the instruction set the fluid is compiled for, pinned across machines.

numba compiles for the processor it runs on, and the instruction set decides the
particles' last bits (how wide a vector sums a particle's neighbours, where a multiply
and an add fuse); the fluid's chaos carries a last-bit difference into every pour. So by
default an episode is reproducible bit for bit on one machine, and across processors in
distribution only (``docs/fluid.md``). Set ``POUR_GYM_CPU`` to an LLVM processor name
that every machine involved can run, e.g. ``x86-64-v3`` (AVX2, FMA: Intel since 2013, AMD
since 2015) or ``x86-64-v2``, before pour-gym is imported: numba then compiles for that
processor's features alone, the same code on every machine, and the same seeds give the
same episodes wherever the target runs. It is numba's own setting (``NUMBA_CPU_NAME``
with ``NUMBA_CPU_FEATURES=""``) made on import: it holds for every function numba
compiles in the process, the user's too, and numba's cache keeps each target's code
apart.
"""

from __future__ import annotations

import os
import warnings

ENV_SWITCH = "POUR_GYM_CPU"


def pinned_target() -> str | None:
    """The processor ``POUR_GYM_CPU`` names, now numba's target; None if it is unset.

    Call before anything is compiled (``pour_gym.fluid`` calls it on import). If numba has
    already compiled something in this process, its target is fixed: a warning says the
    pin did not take.
    """
    name = os.environ.get(ENV_SWITCH, "").strip()
    if not name:
        return None
    import numba
    from numba.core.registry import cpu_target

    # A cached property: looked up in the instance's dict, not read (reading creates it).
    if "_toplevel_target_context" in vars(cpu_target) and numba.config.CPU_NAME != name:
        warnings.warn(
            f"{ENV_SWITCH}={name} cannot take effect: numba compiled code in this process "
            "before pour_gym was imported. Import pour_gym first, or set "
            f"NUMBA_CPU_NAME={name} NUMBA_CPU_FEATURES='' in the environment.",
            RuntimeWarning,
            stacklevel=2,
        )
        return None
    numba.config.CPU_NAME = name
    numba.config.CPU_FEATURES = ""  # the processor's own features, none of the host's
    return name
