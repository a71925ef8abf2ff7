"""Shared fixtures of the Python tests: the CLI, the datasets folder, the module.

ctest sets PYTHONPATH to the built module and BGKMAP_CLI / BGKMAP_DEFAULT_DATASETS_DIR /
BGKMAP_SOURCE_DIR (tests/CMakeLists.txt); without them (pytest on an installed package) the module is
the one installed and the CLI the checkout's build/bgkmap or the one on PATH. The datasets folder is
datasets/locate.py's (BGKMAP_DATASETS first), with the build's default, as for the C++ tests.
"""
import os
import pathlib
import shutil
import subprocess
import sys

import pytest

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[2] / "datasets"))
import locate  # noqa: E402  (datasets/locate.py)


def running_in_ci():
    return os.environ.get("CI") == "true"


@pytest.fixture(scope="session")
def cli():
    """BGKMAP_CLI (ctest sets it), else the checkout's build/bgkmap, else `bgkmap` on PATH."""
    built = pathlib.Path(__file__).resolve().parents[2] / "build" / "bgkmap"
    path = os.environ.get("BGKMAP_CLI") or (str(built) if built.is_file() else shutil.which("bgkmap"))
    if not path:
        message = "no bgkmap CLI: set BGKMAP_CLI, build build/bgkmap or put bgkmap on PATH"
        if running_in_ci():
            pytest.fail(message)
        pytest.skip(message)
    return path


@pytest.fixture(scope="session")
def source_dir():
    return pathlib.Path(os.environ.get("BGKMAP_SOURCE_DIR", pathlib.Path(__file__).resolve().parents[2]))


@pytest.fixture(scope="session")
def datasets():
    folder = locate.datasets_dir(os.environ.get("BGKMAP_DEFAULT_DATASETS_DIR"))
    if not (folder / "sim_structured").is_dir():
        message = f"datasets folder {folder} has no sim_structured/ (set BGKMAP_DATASETS)"
        if running_in_ci():
            pytest.fail(message)
        pytest.skip(message)
    return folder


@pytest.fixture(scope="session")
def scans(datasets):
    """The first four sim_structured scans: enough cells to compare, quick to map."""
    return [str(datasets / "sim_structured" / f"scan_{i:02d}.pcd") for i in range(1, 5)]


# sim_structured's settings (datasets/README.md); the CPU back end on both sides.
SETTINGS = dict(max_range=8, ds=0.1, backend="cpu")
FLAGS = ["--max-range", "8", "--ds", "0.1", "--backend", "cpu"]


@pytest.fixture(scope="module")
def cli_map(cli, scans, tmp_path_factory):
    """The CLI's map of `scans` under SETTINGS."""
    out = tmp_path_factory.mktemp("cli") / "cli.bgk"
    rc, _, err = run_cli(cli, "build", "-q", *scans, "-o", out, *FLAGS)
    assert rc == 0, err
    return out


@pytest.fixture(scope="module")
def mapper(scans):
    """A Mapper of `scans` under SETTINGS."""
    import bgkmap
    m = bgkmap.Mapper(**SETTINGS)
    assert m.insert_file(scans) == len(scans)
    return m


def run_cli(cli, *args):
    """Runs the CLI; returns (exit code, stdout, stderr)."""
    r = subprocess.run([cli, *map(str, args)], capture_output=True, text=True)
    return r.returncode, r.stdout, r.stderr
