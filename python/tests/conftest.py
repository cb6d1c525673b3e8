"""Fixtures of the Python package's tests: the strut binary (STRUT_BINARY, set by ctest) and sessions
it records on the simulated rig, so every comparison is with what the CLI itself does."""
import os
import subprocess

import pytest


def strut_binary():
    path = os.environ.get("STRUT_BINARY")
    if not path:
        pytest.fail("STRUT_BINARY is not set: run the tests through ctest (python/CMakeLists.txt)")
    return path


def run_strut(*words, check=True):
    """The strut binary run with `words`; its CompletedProcess (stdout and stderr as text)."""
    r = subprocess.run([strut_binary(), *map(str, words)], capture_output=True, text=True)
    if check and r.returncode not in (0, 3):  # 3: converged above the noise floor, still a fit
        raise AssertionError(f"strut {' '.join(map(str, words))} exited {r.returncode}:\n{r.stderr}")
    return r


@pytest.fixture(scope="session")
def lab(tmp_path_factory):
    """A folder with the QC matrix and reference (strut qc plan) and a drawn unit's QC session
    (strut sim matrix --draw 12): four experiments, quick to fit."""
    folder = tmp_path_factory.mktemp("lab")
    run_strut("qc", "plan", "-o", folder / "qc.toml", "--write-reference", folder / "ref.toml")
    run_strut("sim", "matrix", "--draw", 12, "--matrix", folder / "qc.toml", "-o", folder / "unit12.h5")
    return folder
