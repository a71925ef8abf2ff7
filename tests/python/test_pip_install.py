"""`pip install --no-build-isolation .` into a fresh virtual environment, offline, then the module's
tests against the installed package. Slow (a CMake build of the module): it runs when
BGKMAP_TEST_PIP_INSTALL is set, as ctest's python_pip_install sets it (tests/CMakeLists.txt), with the
build in BGKMAP_TEST_PIP_BUILD_DIR (emptied first) or a temporary folder, never in the sources."""
import os
import pathlib
import shutil
import subprocess
import sys

import pytest

pytestmark = pytest.mark.skipif(not os.environ.get("BGKMAP_TEST_PIP_INSTALL"),
                                reason="set BGKMAP_TEST_PIP_INSTALL=1 (ctest's python_pip_install does)")

# This file and the datasets' recipes (no module) are not the installed package's tests.
NOT_RUN = ("test_pip_install.py", "test_datasets.py")


def run(*args, **kwargs):
    r = subprocess.run([str(a) for a in args], capture_output=True, text=True, **kwargs)
    assert r.returncode == 0, f"{args}: exit {r.returncode}\n{r.stdout[-4000:]}\n{r.stderr[-4000:]}"
    return r.stdout


def test_pip_install_then_pytest_on_the_installed_package(source_dir, tmp_path):
    def source_tree():
        return sorted(p.name for p in source_dir.iterdir()), (source_dir / "build" / "pip").exists()

    before = source_tree()
    venv = tmp_path / "venv"
    run(sys.executable, "-m", "venv", "--system-site-packages", venv)
    python = venv / "bin" / "python"
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    # ctest names a folder of its build tree, the same on every run (and in every checkout beside it)
    # so that the compiler cache finds its objects again.
    build = pathlib.Path(os.environ.get("BGKMAP_TEST_PIP_BUILD_DIR") or tmp_path / "build")
    shutil.rmtree(build, ignore_errors=True)
    env.update(BGKMAP_PIP_BUILD_DIR=str(build), PIP_NO_INDEX="1", PIP_DISABLE_PIP_VERSION_CHECK="1",
               PYTHONDONTWRITEBYTECODE="1")
    run(python, "-m", "pip", "install", "--no-build-isolation", source_dir, env=env)
    installed = run(python, "-c", "import bgkmap, numpy; print(bgkmap.__file__); print(bgkmap.__version__)",
                    cwd=tmp_path, env=env).split()
    assert pathlib.Path(installed[0]).is_relative_to(venv)
    assert installed[1] == run(os.environ["BGKMAP_CLI"], "--version").split()[-1]
    tests = source_dir / "tests" / "python"
    ignored = [f"--ignore={tests / name}" for name in NOT_RUN]
    out = run(python, "-m", "pytest", "-q", "-p", "no:cacheprovider", tests, *ignored, cwd=tmp_path, env=env)
    assert " passed" in out and " failed" not in out
    assert source_tree() == before  # nothing written beside the sources
    run(python, "-m", "pip", "uninstall", "-y", "bgkmap", env=env)
    assert not list((venv / "lib").glob("python3*/site-packages/bgkmap*"))  # the libraries went with it
