#!/usr/bin/env python3
"""Runs the commands of the README and the manual (docs/*.md).

Blocks marked by a line `<!-- test: run -->` right before their opening fence
are run, line by line, in one temporary folder per document; its `scenes`
and `build` link to the repository's, and the blocks marked
`<!-- test: NAME -->` (scene files) of the same document are written into it
first. Lines starting with `gdr `, `build/bin/gdr ` or `./build/bin/gdr ` run
the gdr tool given on the command line; other lines are not commands.
Blocks marked `<!-- test: python -->` run with the Python the module of
PYTHON_DIR was built for, the module on PYTHONPATH (skipped where it is not built).

To keep it quick, every run is made tiny, and this is the only change:
`--spp N` becomes `--spp 2`, `gdr render` gets `--width 32` (unless it sets a
size), and a frame range A:B becomes 0:2; in Python blocks `spp=N` becomes
`spp=4` and set_resolution(W, H) becomes set_resolution(32, 32). A line reading a file of
../shared/ that is absent, and `gdr video` to an MP4 without ffmpeg, are
skipped with a message. Every other failure fails the test.

The C++ blocks of the README are the examples' code: every code line of
them (a trailing // comment aside) must be a line of examples/*/main.cpp,
which ctest builds and runs, so the quick start cannot drift from them.

Usage: doc_commands.py GDR_TOOL SOURCE_DIR [PYTHON_DIR]
"""
import os
import pathlib
import re
import shlex
import shutil
import subprocess
import sys
import tempfile

MARK = re.compile(r"^\s*<!-- test: (.+?) -->\s*$")
PREFIXES = ("gdr ", "build/bin/gdr ", "./build/bin/gdr ")


def blocks(path):
    """(name, text) of every marked block of a markdown file."""
    out, name, lines = [], None, path.read_text().split("\n")
    i = 0
    while i < len(lines):
        m = MARK.match(lines[i])
        if m:
            name = m.group(1)
        elif name and lines[i].strip().startswith("```"):
            body = []
            i += 1
            while i < len(lines) and not lines[i].strip().startswith("```"):
                body.append(lines[i])
                i += 1
            indent = min((len(l) - len(l.lstrip()) for l in body if l.strip()), default=0)
            out.append((name, "\n".join(l[indent:] for l in body) + "\n"))
            name = None
        elif lines[i].strip():
            name = None
        i += 1
    return out


def tiny(args):
    """The command made tiny (see the module's text)."""
    out = []
    for a in args:
        out.append(re.sub(r"^\d+:\d+$", "0:2", a))
    for k, a in enumerate(out):
        if a == "--spp" and k + 1 < len(out):
            out[k + 1] = "2"
    if out[0] == "render" and not {"--width", "--height", "--resolution"} & set(out):
        out += ["--width", "32"]
    return out


def module_python(python_dir):
    """The interpreter the module was built for (the build's Python3_EXECUTABLE), else this one."""
    cache = pathlib.Path(python_dir).parent / "CMakeCache.txt"
    if cache.exists():
        for line in cache.read_text().split("\n"):
            if line.startswith("Python3_EXECUTABLE:"):
                return line.split("=", 1)[1]
    return sys.executable


def code_line(line):
    """A C++ line without its trailing // comment and surrounding blanks."""
    return re.sub(r"\s*//.*$", "", line).strip()


def check_cpp_blocks(source):
    """The README's C++ lines that are in no example (a list of them)."""
    examples = set()
    for f in (source / "examples").glob("*/main.cpp"):
        examples |= {code_line(l) for l in f.read_text().split("\n")}
    missing, inside = [], False
    for line in (source / "README.md").read_text().split("\n"):
        if line.startswith("```"):
            inside = line.strip() == "```cpp"
            continue
        if inside and code_line(line) and code_line(line) not in examples:
            missing.append(line)
    return missing


def main():
    tool, source = os.path.abspath(sys.argv[1]), pathlib.Path(sys.argv[2]).resolve()
    python_dir = sys.argv[3] if len(sys.argv) > 3 else ""
    docs = [source / "README.md"] + sorted((source / "docs").glob("*.md"))
    ran = skipped = 0
    failures = []
    for doc in docs:
        marked = blocks(doc)
        if not any(n in ("run", "python") for n, _ in marked):
            continue
        with tempfile.TemporaryDirectory(prefix="gdr-doc-") as tmp:
            work = pathlib.Path(tmp) / "work"
            work.mkdir()
            (work / "scenes").symlink_to(source / "scenes")
            (work / "build").mkdir()
            (work / "build" / "bin").mkdir()
            (work / "build" / "bin" / "gdr").symlink_to(tool)
            if (source.parent / "shared").exists():
                (pathlib.Path(tmp) / "shared").symlink_to(source.parent / "shared")
            for name, text in marked:
                if name not in ("run", "python"):
                    (work / name).write_text(text)
            for name, text in marked:
                if name != "python":
                    continue
                where = f"{doc.relative_to(source)}: the Python block"
                if not python_dir or not list(pathlib.Path(python_dir).glob("gdr*.so")):
                    print(f"skipped (the Python module is not built): {where}")
                    skipped += 1
                    continue
                code = re.sub(r"spp=\d+", "spp=4", text)
                code = re.sub(r"set_resolution\(\d+, \d+\)", "set_resolution(32, 32)", code)
                env = dict(os.environ, PYTHONPATH=os.path.abspath(python_dir))
                r = subprocess.run([module_python(python_dir), "-c", code], cwd=work, env=env, capture_output=True,
                                   text=True, timeout=600)
                ran += 1
                print(("ok" if r.returncode == 0 else f"FAILED ({r.returncode})") + f": {where}")
                if r.returncode != 0:
                    failures.append(where)
                    print(r.stdout[-2000:], r.stderr[-2000:], sep="\n")
            for name, text in marked:
                if name != "run":
                    continue
                for line in text.split("\n"):
                    if not line.startswith(PREFIXES):
                        continue
                    args = shlex.split(line, comments=True)
                    args = tiny(args[1:])
                    where = f"{doc.relative_to(source)}: {line.strip()}"
                    missing = [a for a in args if a.startswith("../shared/") and not (work / a).exists()]
                    if missing:
                        print(f"skipped (no {missing[0]}): {where}")
                        skipped += 1
                        continue
                    if args[0] == "video" and any(a.endswith(".mp4") for a in args) and not shutil.which("ffmpeg"):
                        print(f"skipped (no ffmpeg): {where}")
                        skipped += 1
                        continue
                    for a in args:  # output folders the text takes for granted (out/, rec/)
                        if "/" in a and not a.startswith(("-", "/", "..", "scenes/", "build/")):
                            (work / a).parent.mkdir(parents=True, exist_ok=True)
                    r = subprocess.run([tool] + args, cwd=work, capture_output=True, text=True, timeout=600)
                    ran += 1
                    status = "ok" if r.returncode == 0 else f"FAILED ({r.returncode})"
                    print(f"{status}: {where}  [ran: gdr {shlex.join(args)}]")
                    if r.returncode != 0:
                        failures.append(where)
                        print(r.stdout[-2000:], r.stderr[-2000:], sep="\n")
    drift = check_cpp_blocks(source)
    for line in drift:
        print(f"FAILED: README.md's C++ line is in no examples/*/main.cpp: {line.strip()}")
    failures += drift
    print(f"doc commands: {ran} ran, {skipped} skipped, {len(failures)} failed")
    if ran == 0:
        print("no command ran: the markers are missing")
        return 1
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
