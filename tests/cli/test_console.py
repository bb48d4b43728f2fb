"""The crosshead command that set-up installs (pyproject.toml's console script)."""
import subprocess
import sys
import tomllib
from pathlib import Path

import pipeline

ROOT = Path(__file__).resolve().parents[2]


def test_the_version_is_said_once_and_the_command_prints_it():
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    assert "version" in project["dynamic"]   # read from pipeline.__version__, written once
    p = subprocess.run([sys.executable, "-m", "pipeline", "--version"], cwd=ROOT, capture_output=True, text=True)
    assert p.returncode == 0 and p.stdout.strip() == f"crosshead {pipeline.__version__}"


def test_the_console_script_runs_the_command_line():
    script = Path(sys.executable).parent / "crosshead"
    assert script.is_file(), "set-up (tools/setup.sh) installs the crosshead command into .venv"
    p = subprocess.run([str(script), "--help"], capture_output=True, text=True, cwd="/")
    assert p.returncode == 0 and p.stdout.startswith("usage: crosshead ")
    p = subprocess.run([str(script), "run", "--size", "nope"], capture_output=True, text=True, cwd="/")
    assert p.returncode == 2 and len(p.stderr.strip().splitlines()) == 1
