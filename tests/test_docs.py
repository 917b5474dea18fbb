"""The documentation: the site builds strictly, the environment pages are the docstrings'."""

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from pour_gym.apps.envdocs import env_page
from pour_gym.envs import ENVS

ROOT = Path(__file__).resolve().parents[1]
# Not --quiet: it hides the warnings that --strict turns into a failure.
MKDOCS = [sys.executable, "-m", "mkdocs", "build", "--strict"]


def _build(config: Path, site: Path) -> subprocess.CompletedProcess:
    env = {**os.environ, "NO_MKDOCS_2_WARNING": "1"}
    return subprocess.run([*MKDOCS, "-f", str(config), "-d", str(site)], capture_output=True,
                          text=True, env=env)  # fmt: skip


def test_the_site_builds_strictly(tmp_path):
    pytest.importorskip("mkdocs")
    done = _build(ROOT / "mkdocs.yml", tmp_path / "site")
    assert done.returncode == 0, done.stderr[-3000:]
    assert (tmp_path / "site" / "environments" / "pour-v0" / "index.html").is_file()


def test_a_broken_link_fails_the_build(tmp_path):
    pytest.importorskip("mkdocs")
    shutil.copytree(ROOT / "docs", tmp_path / "docs")
    shutil.copy(ROOT / "mkdocs.yml", tmp_path / "mkdocs.yml")
    page = tmp_path / "docs" / "contributing.md"
    page.write_text(page.read_text() + "\nSee [the missing page](missing.md).\n")
    done = _build(tmp_path / "mkdocs.yml", tmp_path / "site")
    assert done.returncode != 0 and "missing.md" in done.stderr


@pytest.mark.parametrize("e", ENVS, ids=[e.id for e in ENVS])
def test_environment_pages_are_their_docstrings(e):
    """docs/environments/<slug>.md is what `python -m pour_gym.apps.envdocs` writes."""
    page = ROOT / "docs" / "environments" / f"{e.slug}.md"
    assert page.read_text() == env_page(e), "run python -m pour_gym.apps.envdocs"
    assert (page.parent / f"{e.slug}.gif").is_file(), f"pour-gym episode --env {e.id}"


def test_the_readme_is_one_page_with_the_two_commands():
    text = (ROOT / "README.md").read_text()
    assert len(text.splitlines()) <= 300
    assert "make demo" in text and "make test" in text


def test_the_readme_quick_start_runs_as_printed():
    # A newcomer's first minute: the block under "Quick start", run as it stands, shows a
    # shipped policy succeeding on containers it never saw.
    text = (ROOT / "README.md").read_text()
    quick = text[text.index("## Quick start") :]
    code = quick[quick.index("```python\n") + len("```python\n") :]
    code = code[: code.index("```")]
    probe = code + "assert result['mean']['success'] > 0, result['mean']\n"
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr[-3000:]
    assert "'success': " in done.stdout
