"""Builds the Python module gdr with CMake, for pip and python -m build.

The module is the CMake target gdr_python (python/CMakeLists.txt); this file
only drives CMake and copies what it built into the wheel:
  - gdr.<abi>.so, the module itself (one file, no Python package);
  - where CMake found libtorch, the neural reconstructor's plugin and its
    shipped model under gdr-data/, in the same layout as a build tree
    (lib/gdr/libgdr_neural_plugin.so, share/gdr/neural/...), so that the
    plugin finds its model and gdr.load_plugin() finds the plugin.

Environment:
  GDR_CMAKE_BUILD_DIR  an already configured gdr build tree to build the
                       module in (and take it from) instead of a new one; it
                       must be configured for this Python (the module's file
                       name says which).
  GDR_CMAKE_ARGS       extra options for a new tree, e.g. "-DGDR_BUILD_NEURAL=OFF".
  CMAKE_BUILD_PARALLEL_LEVEL  parallel compile jobs (default: all cores).
A new tree compiles through ccache when it is installed, so that a second
build of the same sources (a CI job that built the library already) costs
little.
"""
import os
import re
import shlex
import shutil
import subprocess
import sys
import sysconfig
from pathlib import Path

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

SOURCE_DIR = Path(__file__).resolve().parent
PLUGIN_FILE = "libgdr_neural_plugin.so"


def project_version():
    """The version in the top-level CMakeLists.txt's project() call."""
    text = (SOURCE_DIR / "CMakeLists.txt").read_text()
    m = re.search(r"project\(\s*gdr\s+VERSION\s+([0-9.]+)", text)
    if not m:
        raise RuntimeError("setup.py: no 'project(gdr VERSION x.y.z' in CMakeLists.txt")
    return m.group(1)


class CMakeExtension(Extension):
    """An extension module that CMake builds (no sources of its own for setuptools)."""

    def __init__(self, name, target):
        super().__init__(name, sources=[])
        self.target = target


class CMakeBuild(build_ext):
    """build_ext that configures (or reuses) a CMake tree and builds the module's target there."""

    def run_cmake(self, args):
        print("setup.py:", shlex.join(str(a) for a in args), flush=True)
        subprocess.run([str(a) for a in args], check=True)

    def cmake_tree(self):
        given = os.environ.get("GDR_CMAKE_BUILD_DIR")
        if given:
            tree = Path(given).resolve()
            if not (tree / "CMakeCache.txt").is_file():
                raise RuntimeError(f"GDR_CMAKE_BUILD_DIR={given}: not a configured CMake build tree "
                                   "(no CMakeCache.txt); configure it first, or unset the variable")
            return tree
        tree = Path(self.build_temp).resolve() / "cmake"
        args = ["cmake", "-S", SOURCE_DIR, "-B", tree, "-DCMAKE_BUILD_TYPE=Release",
                f"-DPython3_EXECUTABLE={sys.executable}", "-DGDR_BUILD_TESTS=OFF", "-DGDR_BUILD_BENCHMARKS=OFF"]
        if shutil.which("ccache"):
            args.append("-DCMAKE_CXX_COMPILER_LAUNCHER=ccache")
        args += shlex.split(os.environ.get("GDR_CMAKE_ARGS", ""))
        self.run_cmake(args)
        return tree

    def build_extension(self, ext):
        tree = self.cmake_tree()
        jobs = os.environ.get("CMAKE_BUILD_PARALLEL_LEVEL") or str(os.cpu_count() or 1)
        targets = subprocess.run(["cmake", "--build", str(tree), "--target", "help"], capture_output=True,
                                 text=True).stdout
        has_plugin = re.search(r"\bgdr_neural_plugin\b", targets) is not None
        if not re.search(rf"\b{ext.target}\b", targets):
            raise RuntimeError(f"{tree}: CMake did not make the target {ext.target}: the Python module's "
                               "requirements were not found (see the configure output: pybind11-dev, python3-dev, "
                               "python3-numpy)")
        self.run_cmake(["cmake", "--build", tree, "-j", jobs, "--target", ext.target] +
                       (["gdr_neural_plugin"] if has_plugin else []))

        suffix = sysconfig.get_config_var("EXT_SUFFIX")
        built = tree / "python" / f"gdr{suffix}"
        if not built.is_file():
            found = sorted(p.name for p in (tree / "python").glob("gdr*.so"))
            raise RuntimeError(f"{tree}/python holds {found or 'no module'}, not gdr{suffix}: the tree was configured "
                               f"for another Python; configure it with -DPython3_EXECUTABLE={sys.executable}")
        out = Path(self.get_ext_fullpath(ext.name))
        out.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(built, out)

        data = out.parent / "gdr-data"
        shutil.rmtree(data, ignore_errors=True)
        if has_plugin:
            # The plugin looks for its model at a path relative to itself; the tree's layout keeps it.
            for f in [*tree.glob(f"lib*/**/{PLUGIN_FILE}"), *tree.glob("share/gdr/neural/*.pt")]:
                dest = data / f.relative_to(tree)
                dest.parent.mkdir(parents=True, exist_ok=True)
                shutil.copyfile(f, dest)
                print(f"setup.py: packaged {f.relative_to(tree)}", flush=True)


# egg_info needs its directory to exist.
(SOURCE_DIR / "build-python").mkdir(exist_ok=True)

setup(
    version=project_version(),
    ext_modules=[CMakeExtension("gdr", target="gdr_python")],
    cmdclass={"build_ext": CMakeBuild},
    # Not ./build, which is the CMake build tree of the README and scripts/test.sh.
    options={"build": {"build_base": "build-python"}, "egg_info": {"egg_base": "build-python"}},
    zip_safe=False,
)
