"""The import graph of pour-gym: layers that only look down, and no cycle.

Data flows one way (scan -> mesh -> labels -> features -> asset -> world -> env -> agent ->
app), and so do imports: a module imports only from its own package or from a layer below
its own, imports made inside functions included. ``python tests/test_layers.py`` prints
the graph between the packages, the layers and any violation.

The graph is read from the source files (``ast``), with the ``package-dir`` mapping of
``pyproject.toml`` (``envs/`` is ``pour_gym.envs``, ``agents/`` is ``pour_gym.agents``),
so it needs no import of the package and sees what an import tracer would miss: imports in
functions that a run never reaches. Imports under ``if TYPE_CHECKING:`` are for type hints
and never run: they are not edges.
"""

from __future__ import annotations

import ast
import sys
from pathlib import Path

import tomllib

ROOT = Path(__file__).resolve().parents[1]
# Highest first. Packages on one line are siblings: neither imports the other.
LAYERS: tuple[tuple[str, ...], ...] = (
    ("pour_gym.apps",),
    ("pour_gym.agents",),
    ("pour_gym",),  # the package's __init__: it registers the environments
    ("pour_gym.envs",),
    ("pour_gym.sim", "pour_gym.perception"),
    ("pour_gym.fluid", "pour_gym.assets"),
    ("pour_gym.warp", "pour_gym.features"),
    ("pour_gym.mesh",),
    ("pour_gym.objects",),
    ("pour_gym.report",),
    ("pour_gym.io", "pour_gym.errors", "pour_gym.parts", "pour_gym.asset_files"),
)


def module_files() -> dict[str, Path]:
    """Every module of the package by its dotted name, through pyproject's package-dir."""
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    mapping: dict[str, str] = config["package-dir"]
    modules: dict[str, Path] = {}
    for package in config["packages"]:
        base, rest = package, ""
        while base not in mapping:
            base, _, tail = base.rpartition(".")
            rest = f"{tail}.{rest}" if rest else tail
        folder = ROOT / mapping[base] / rest.replace(".", "/")
        for path in sorted(folder.glob("*.py")):
            name = package if path.stem == "__init__" else f"{package}.{path.stem}"
            modules[name] = path
    return modules


def imports(path: Path, name: str, known: set[str]) -> set[str]:
    """The package's own modules that a module imports, anywhere in its body."""
    found: set[str] = set()
    package = name if path.stem == "__init__" else name.rpartition(".")[0]
    for node in _runtime_nodes(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parent = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join(parent + ([base] if base else []))
            targets = [f"{base}.{a.name}" for a in node.names] + [base]
        else:
            continue
        for target in targets:
            # The longest known module the target names (a name imported from a module
            # is the module).
            while target and target not in known:
                target = target.rpartition(".")[0]
            if target and target != name:
                found.add(target)
    return found


def _runtime_nodes(tree: ast.AST):
    """Every node but those under ``if TYPE_CHECKING:`` (imports for type hints never run)."""
    stack = [tree]
    while stack:
        node = stack.pop()
        yield node
        for child in ast.iter_child_nodes(node):
            test = getattr(child, "test", None) if isinstance(child, ast.If) else None
            if test is not None and "TYPE_CHECKING" in ast.unparse(test):
                stack.extend(child.orelse)
                continue
            stack.append(child)


def graph() -> dict[str, set[str]]:
    """Module -> the package's modules it imports."""
    files = module_files()
    known = set(files)
    return {name: imports(path, name, known) for name, path in files.items()}


def layer_of(module: str) -> tuple[int, str]:
    """(layer index, the layer's package) of a module: the longest package that holds it."""
    best = (-1, "")
    for index, packages in enumerate(LAYERS):
        for package in packages:
            # The root package's layer holds its __init__ alone.
            holds = module == package or (
                package != "pour_gym" and module.startswith(package + ".")
            )
            if holds and len(package) > len(best[1]):
                best = (index, package)
    return best


def violations(edges: dict[str, set[str]]) -> list[str]:
    """Imports that go up a layer, or sideways into a sibling package."""
    out = []
    for module, targets in sorted(edges.items()):
        layer, package = layer_of(module)
        for target in sorted(targets):
            t_layer, t_package = layer_of(target)
            if t_layer < layer or (t_layer == layer and t_package != package):
                out.append(f"{module} imports {target} ({package} may not import {t_package})")
    return out


def cycles(edges: dict[str, set[str]]) -> list[list[str]]:
    """Groups of modules that import each other, directly or through others (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []
    sys.setrecursionlimit(10_000)

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in edges.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            group = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                group.append(w)
                if w == v:
                    break
            if len(group) > 1:
                found.append(sorted(group))

    for v in sorted(edges):
        if v not in index:
            visit(v)
    return found


def test_every_module_is_in_a_layer():
    assert [m for m in module_files() if layer_of(m)[0] < 0] == []


def test_imports_only_go_down_the_layers():
    assert violations(graph()) == []


def test_no_import_cycle():
    assert cycles(graph()) == []


# Modules a newcomer reads in one sitting: none longer than this, but the fluid's kernel
# (one compiled function and its passes, kept together so numba inlines them).
MAX_LINES = 600
LONG_ON_PURPOSE = {"pour_gym.fluid.kernel"}


def test_no_module_is_over_600_lines_but_the_fluid_kernel():
    long = {
        name: n
        for name, path in module_files().items()
        if (n := len(path.read_text().splitlines())) > MAX_LINES and name not in LONG_ON_PURPOSE
    }
    assert long == {}


def test_the_checks_catch_what_they_look_for():
    edges = {"pour_gym.sim.world": {"pour_gym.envs.pour"}, "pour_gym.envs.pour": set()}
    assert violations(edges) == [
        "pour_gym.sim.world imports pour_gym.envs.pour (pour_gym.sim may not import pour_gym.envs)"
    ]
    assert violations({"pour_gym.fluid.pbf": {"pour_gym.assets"}})  # siblings
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


if __name__ == "__main__":
    edges = graph()
    packages: dict[str, set[str]] = {}
    for module, targets in edges.items():
        for target in targets:
            a, b = layer_of(module)[1], layer_of(target)[1]
            if a != b:
                packages.setdefault(a, set()).add(b)
    print("layers, highest first:")
    for packages_ in LAYERS:
        print("  " + "  |  ".join(packages_))
    print("\nimports between packages:")
    for package in sorted(packages, key=lambda p: layer_of(p)[0]):
        print(f"  {package} -> {', '.join(sorted(packages[package]))}")
    bad, loops = violations(edges), cycles(edges)
    print(f"\n{len(edges)} modules; {len(bad)} imports against the layers; {len(loops)} cycles")
    for line in bad:
        print("  " + line)
    for loop in loops:
        print("  cycle: " + " -> ".join(loop))
    sys.exit(1 if bad or loops else 0)


def test_an_env_on_cached_assets_imports_no_labelling():
    # A worker that pours needs the fluid, pybullet and its containers' cached numbers:
    # not trimesh, scipy.spatial, the warp or the reconstruction (some 60 MB per process).
    import subprocess
    import sys

    script = (
        "import sys, gymnasium as gym, pour_gym\n"
        "env = gym.make('PourGym/Pour-v1', objects='red_cup', num_threads=1)\n"
        "env.reset(seed=0)\n"
        "for _ in range(3):\n"
        "    env.step(env.action_space.sample())\n"
        "env.close()\n"
        "heavy = ('trimesh', 'scipy.spatial', 'scipy.ndimage', 'skimage', 'open3d', 'torch',\n"
        "         'pour_gym.warp', 'pour_gym.mesh.reconstruct', 'pour_gym.objects.build')\n"
        "print(sorted(m for m in sys.modules if m.startswith(heavy)))\n"
    )
    run = [sys.executable, "-W", "ignore", "-c", script]
    subprocess.run(run, check=True, capture_output=True)  # fills the caches
    done = subprocess.run(run, check=True, capture_output=True, text=True)
    assert done.stdout.strip().splitlines()[-1] == "[]"


def test_importing_the_package_compiles_nothing_and_loads_no_threading_library():
    # A process that imports pour_gym and never steps a fluid (a report, a labelling run,
    # a user's own numba code) gets no fluid kernel, no patched numba options and no TBB
    # or OpenMP: the kernel's build loads them when a fluid first needs it.
    import json
    import subprocess
    import sys

    script = (
        "import json, sys, numba\n"
        "import pour_gym, pour_gym.fluid\n"
        "from numba.core.cpu import CPUTargetOptions\n"
        "from numba.core.registry import CPUDispatcher\n"
        "maps = open('/proc/self/maps').read()\n"
        "compiled = sorted(f'{m.__name__}.{n}' for m in list(sys.modules.values())\n"
        "                  if getattr(m, '__name__', '').startswith('pour_gym')\n"
        "                  for n, f in vars(m).items()\n"
        "                  if isinstance(f, CPUDispatcher) and f.signatures)\n"
        "print(json.dumps({'threading': [l for l in ('libtbb', 'libgomp', 'libiomp', 'libomp')\n"
        "                                if l in maps],\n"
        "                  'kernel': 'pour_gym.fluid.kernel' in sys.modules,\n"
        "                  'noalias_patched': hasattr(CPUTargetOptions, 'noalias'),\n"
        "                  'compiled': compiled}))\n"
    )
    done = subprocess.run(
        [sys.executable, "-W", "ignore", "-c", script], check=True, capture_output=True, text=True
    )
    facts = json.loads(done.stdout.strip().splitlines()[-1])
    assert facts == {"threading": [], "kernel": False, "noalias_patched": False, "compiled": []}
