"""The Python module as a package: `pip install --no-build-isolation .` builds the CMake target
bgkmap_python alone, for the interpreter running pip, and packs it with the bgkmap libraries it loads.

Environment: BGKMAP_PIP_BUILD_DIR, the folder for the CMake tree and setuptools' files (default
build/pip in the source tree); CMAKE_ARGS, more arguments for CMake's configure (e.g.
-DCMAKE_CXX_COMPILER_LAUNCHER=ccache); CMAKE_BUILD_PARALLEL_LEVEL, the compile jobs (default: the cores).
"""
import os
import pathlib
import re
import shlex
import subprocess
import sys

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

SOURCE = pathlib.Path(__file__).resolve().parent
BUILD = pathlib.Path(os.environ.get("BGKMAP_PIP_BUILD_DIR") or SOURCE / "build" / "pip").resolve()


def project_version():
    """The version CMake's project() declares, so the package and `bgkmap --version` agree."""
    match = re.search(r"project\(bgkmap VERSION ([0-9.]+)", (SOURCE / "CMakeLists.txt").read_text())
    return match.group(1)


class CMakeBuild(build_ext):
    """Configures, builds and installs (component `python`) the module into the wheel's folder."""

    def build_extension(self, ext):
        tree = BUILD / "cmake"
        package = pathlib.Path(self.get_ext_fullpath(ext.name)).resolve().parent
        configure = [
            "cmake", "-S", str(SOURCE), "-B", str(tree), "-DCMAKE_BUILD_TYPE=Release",
            f"-DPYTHON_EXECUTABLE={sys.executable}", f"-DPython_EXECUTABLE={sys.executable}",
            "-DBGKMAP_BUILD_PYTHON=ON", "-DBGKMAP_BUILD_TESTS=OFF", "-DBGKMAP_BUILD_BENCHMARKS=OFF",
            # The module at the top of site-packages, its libraries in bgkmap.libs/ (its RPATH).
            "-DBGKMAP_PYTHON_INSTALL_DIR=.", "-DCMAKE_INSTALL_LIBDIR=bgkmap.libs",
            *shlex.split(os.environ.get("CMAKE_ARGS", "")),
        ]
        jobs = os.environ.get("CMAKE_BUILD_PARALLEL_LEVEL") or str(os.cpu_count() or 1)
        subprocess.run(configure, check=True)
        subprocess.run(["cmake", "--build", str(tree), "--target", "bgkmap_python", "--parallel", jobs], check=True)
        subprocess.run(["cmake", "--install", str(tree), "--component", "python", "--prefix", str(package)], check=True)
        # A wheel holds no links: each library once, under the name the module asks for (its soname).
        for link in (package / "bgkmap.libs").iterdir():
            if link.is_symlink():
                target = link.resolve()
                link.unlink()
                target.rename(link)


BUILD.mkdir(parents=True, exist_ok=True)
setup(
    version=project_version(),
    ext_modules=[Extension("bgkmap", sources=[])],
    cmdclass={"build_ext": CMakeBuild},
    # setuptools' own files (build/, *.egg-info) go to the build folder too, not beside the sources.
    options={"build": {"build_base": str(BUILD / "setuptools")}, "egg_info": {"egg_base": str(BUILD)}},
    zip_safe=False,
)
