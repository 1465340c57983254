"""The import contracts of pyproject.toml hold, and breaking one fails ``lint-imports``.

The contracts (``[tool.importlinter]``): layers from the command line down to
the frozen values, filters never importing measurers, only sinks importing
rerun, and no import cycle between the modules of a package, imports inside
functions included.  The negative cases copy ``vidtrack/`` to a temporary
folder, add one bad import to the copy and run ``lint-imports`` on it with the
project's configuration: it must exit non-zero and name the broken contract
and the import.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from conftest import REPO

CONFIG = REPO / "pyproject.toml"
LAYERS = "Layers: entry points on top, frozen values at the bottom"
PIXELS = "Filters estimate boxes and never look at pixels"
CYCLES = "No import cycles between modules of a package"

#: ``lint-imports`` through this interpreter, so the venv's import-linter runs whatever PATH holds.
LINT_IMPORTS = "import sys; from importlinter.cli import lint_imports_command; sys.exit(lint_imports_command())"


def lint_imports(root: Path) -> subprocess.CompletedProcess:
    """``lint-imports`` with the project's contracts on the ``vidtrack`` package found in ``root``."""
    env = {**os.environ, "PYTHONPATH": str(root)}
    return subprocess.run([sys.executable, "-c", LINT_IMPORTS, str(CONFIG), "--no-cache", "--no-logo"],
                          cwd=root, env=env, capture_output=True, text=True, timeout=300)


@pytest.fixture
def copy(tmp_path) -> Path:
    """A copy of the package (sources only) in ``tmp_path``; returns ``tmp_path``."""
    shutil.copytree(REPO / "vidtrack", tmp_path / "vidtrack", ignore=shutil.ignore_patterns("__pycache__"))
    return tmp_path


def add_line(path: Path, line: str) -> None:
    path.write_text(path.read_text() + "\n" + line + "\n")


def test_the_projects_contracts_hold():
    result = lint_imports(REPO)
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-1000:]
    assert "0 broken" in result.stdout
    for name in (LAYERS, PIXELS, CYCLES, "Only the sinks import rerun"):
        assert f"{name} KEPT" in result.stdout


def test_the_copy_is_what_is_linted(copy):
    """The negative cases below lint the copy, not the installed package: a syntax error in it shows."""
    add_line(copy / "vidtrack" / "types.py", "def broken(:")
    result = lint_imports(copy)
    assert result.returncode != 0
    assert str(copy / "vidtrack" / "types.py") in result.stdout + result.stderr


def test_an_upward_import_breaks_the_layers(copy):
    add_line(copy / "vidtrack" / "types.py", "from vidtrack.cli import main  # noqa: E402")
    result = lint_imports(copy)
    assert result.returncode != 0
    assert f"{LAYERS} BROKEN" in result.stdout
    assert "vidtrack.types is not allowed to import vidtrack.cli" in result.stdout


def test_a_filter_importing_a_measurer_breaks_two_contracts(copy):
    add_line(copy / "vidtrack" / "filters" / "kalman.py", "from vidtrack.measure import image  # noqa: E402")
    result = lint_imports(copy)
    assert result.returncode != 0
    assert f"{PIXELS} BROKEN" in result.stdout and f"{LAYERS} BROKEN" in result.stdout
    assert "vidtrack.filters.kalman -> vidtrack.measure.image" in result.stdout


def test_a_cycle_hidden_inside_a_function_is_found(copy):
    # results is imported by running at module level; an import of running inside a function of
    # results closes a cycle that only shows when the function runs
    add_line(copy / "vidtrack" / "eval" / "results.py",
             "def _hidden():\n    from .running import run_jobs\n\n    return run_jobs")
    result = lint_imports(copy)
    assert result.returncode != 0
    assert f"{CYCLES} BROKEN" in result.stdout
    assert "No cycles are allowed in vidtrack.eval." in result.stdout
    assert ".results -> .running" in result.stdout or ".running -> .results" in result.stdout
