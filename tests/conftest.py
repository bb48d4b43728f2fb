"""Shared test helpers. Tests run from the repository root with the .venv python."""
import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))


from pipeline.runtime.environment import configure  # noqa: E402

configure()  # the same form cache, BLAS threads and PETSc options as the command line
os.environ.setdefault("CROSSHEAD_NO_CACHE", "1")  # tests exercise the mesher and the pilot themselves
os.environ["CROSSHEAD_DOCUMENT"] = ""  # no title-block defaults file of the user's: the tests' own inputs only
os.environ.setdefault("CROSSHEAD_NO_PDF", "1")  # report.pdf only where a test asks for it (tests/output/test_report.py)

import gmsh  # noqa: E402
import pytest  # noqa: E402


@pytest.fixture
def gmsh_session():
    """A gmsh session for tests that build geometry directly (silent, no config files)."""
    gmsh.initialize(readConfigFiles=False)
    gmsh.option.setNumber("General.Terminal", 0)
    yield
    gmsh.finalize()
