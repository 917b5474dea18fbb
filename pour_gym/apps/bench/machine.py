"""The machine a benchmark ran on: every ``pour-gym bench`` result names it.

A ratio between two kernels depends on the processor, not only on its speed (how wide its
vectors are, how fast it gathers, its caches), and this project's build machine is not the
same processor from one day to the next. A figure without its processor cannot be compared
with another.
"""

from __future__ import annotations

import platform

from pour_gym.io.numba_threads import usable_cores


def _cpu_model() -> str:
    """The processor's model name (``/proc/cpuinfo`` on Linux), or what Python knows."""
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            for line in f:
                if line.lower().startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine() or "unknown"


def machine() -> dict:
    """What a benchmark's figures depend on besides the code.

    Returns:
        ``{"cpu": model name, "llvm_cpu": the target numba compiles for (e.g. "znver4"),
        "cores": processors this process may run on, "python": version, "numba":
        version, "threading_layer": numba's configured layer}``.
    """
    import numba
    from llvmlite import binding

    return {
        "cpu": _cpu_model(),
        # numba's target: the host's, unless NUMBA_CPU_NAME names another.
        "llvm_cpu": numba.config.CPU_NAME or binding.get_host_cpu_name(),
        "cores": usable_cores(),
        "python": platform.python_version(),
        "numba": numba.__version__,
        "threading_layer": str(numba.config.THREADING_LAYER),
    }


def machine_line(info: dict) -> str:
    """One line for a benchmark's text output: ``machine: <cpu> (<llvm cpu>), N cores``."""
    return f"machine: {info['cpu']} ({info['llvm_cpu']}), {info['cores']} cores"
