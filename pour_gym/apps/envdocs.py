"""The environments' documentation pages, made from their docstrings.

Each registered id gets ``docs/environments/<slug>.md``: its GIF (``pour-gym episode
--env ID``) and its docstring's sections (Description, Action Space, Observation Space,
Rewards, Starting State, Episode End, Arguments, Version History), so the docs cannot
say other than the code. ``python -m pour_gym.apps.envdocs [FOLDER]`` writes them;
``tests/test_docs.py`` checks that the committed pages are what it writes.
"""

from __future__ import annotations

import inspect
import re
import sys
from pathlib import Path

from gymnasium.envs.registration import load_env_creator

from pour_gym.envs import ENVS, EnvEntry

DEFAULT_FOLDER = Path("docs/environments")


def _markdown(text: str) -> str:
    """A docstring's reStructuredText roles and literals as markdown code spans."""
    text = re.sub(r":(?:func|class|mod|meth|data|attr):`~?([^`]+)`", r"`\1`", text)
    return re.sub(r"``([^`]+)``", r"`\1`", text)


def env_page(e: EnvEntry) -> str:
    """The markdown page of one environment."""
    documented = load_env_creator(e.doc or e.entry_point)
    doc = inspect.getdoc(documented) or ""
    summary, _, body = doc.partition("\n")
    fixed = ", ".join(f"`{k}={v!r}`" for k, v in e.kwargs.items())
    lines = [
        f"# {e.id}",
        "",
        _markdown(summary),
        "",
        f"![{e.id}]({e.slug}.gif)",
        "",
        f'`gym.make("{e.id}")` makes `{e.entry_point.replace(":", ".")}`'
        + (f" with {fixed}" if fixed else "")
        + f"; episodes are truncated at {e.max_episode_steps} "
        + ("step." if e.max_episode_steps == 1 else "steps."),
        "",
        "<!-- Written by `python -m pour_gym.apps.envdocs` from the docstring: edit that. -->",
        "",
        _markdown(body.strip()),
    ]
    return "\n".join(lines) + "\n"


def write_env_pages(folder: Path = DEFAULT_FOLDER) -> list[Path]:
    """Write every registered environment's page into ``folder``; the paths written."""
    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    for e in ENVS:
        path = folder / f"{e.slug}.md"
        path.write_text(env_page(e))
        paths.append(path)
    return paths


def main(argv: list[str] | None = None) -> int:
    """``python -m pour_gym.apps.envdocs [FOLDER]``."""
    args = sys.argv[1:] if argv is None else argv
    for path in write_env_pages(Path(args[0]) if args else DEFAULT_FOLDER):
        print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
