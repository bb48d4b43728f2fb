"""The process settings of pipeline/runtime/environment.py: what they set, and what they leave to
the user."""
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SHOW = "from pipeline.runtime.environment import configure; import os; configure(); print(os.environ.get('OMPI_MCA_pml'))"


def pml_after_configure(**env: str) -> str:
    """OMPI_MCA_pml as configure() leaves it in a new process whose environment has no
    Open MPI layer choice except ``env``."""
    base = {k: v for k, v in os.environ.items() if k not in ("OMPI_MCA_pml", "OMPI_MCA_mtl")}
    p = subprocess.run([sys.executable, "-c", SHOW], cwd=ROOT, env=dict(base, **env),
                       capture_output=True, text=True, check=True)
    return p.stdout.strip()


def test_open_mpi_is_kept_from_trying_cm_by_default():
    assert pml_after_configure() == "^cm"


@pytest.mark.parametrize("env, expected", [({"OMPI_MCA_pml": "cm"}, "cm"),
                                           ({"OMPI_MCA_pml": "ucx"}, "ucx"),
                                           ({"OMPI_MCA_mtl": "psm2"}, "None")])
def test_a_users_choice_of_message_layer_is_left_alone(env, expected):
    assert pml_after_configure(**env) == expected
