"""Runs every block of README.md and docs/*.md marked runnable, so the docs stay true.

A block is marked by a line right before its fence (invisible in the rendered page):
- `<!-- runnable -->` before ```sh: run under `bash -euo pipefail`;
- `<!-- runnable -->` before ```python: run by the `--python` interpreter (a venv with the
  package installed by pip: the README's pyvista lines), with PYVISTA_OFF_SCREEN=true so that
  `plotter.show()` renders and returns;
- `<!-- runnable: pvbatch -->` before ```python: run by `--pvbatch` (ParaView's, with the
  plugin's expat shim preloaded where it was built: Debian 12).
Each runs in a fresh temporary folder holding links to the checkout's `examples/` (the
shipped data) and `build/` (the plugin), with the release `fluidcast` first on the PATH
(scripts/test.sh builds it). Every PNG a block writes must hold more than one colour (an
empty view is a failure, not a picture). The test command runs this script.

    python scripts/run_doc_blocks.py [--list] [--python PY] [--pvbatch PVBATCH]
"""
import argparse
import os
import subprocess
import sys
import tempfile
from pathlib import Path

from PIL import Image

ROOT = Path(__file__).resolve().parents[1]
# The mark, the fence it must precede, and the runner of such blocks.
MARKS = {"<!-- runnable -->": {"```sh": "sh", "```python": "python"},
         "<!-- runnable: pvbatch -->": {"```python": "pvbatch"}}


def blocks(path: Path):
    """(line, runner, code) of each marked block of `path`."""
    lines = path.read_text().splitlines()
    for k, line in enumerate(lines):
        if line.strip() not in MARKS:
            continue
        fence = lines[k + 1].strip() if k + 1 < len(lines) else ""
        runner = MARKS[line.strip()].get(fence)
        if runner is None:
            raise SystemExit(f"{path}:{k + 1}: {line.strip()} must be followed by one of "
                             f"{', '.join(MARKS[line.strip()])}")
        end = next((j for j in range(k + 2, len(lines)) if lines[j].strip() == "```"), None)
        if end is None:
            raise SystemExit(f"{path}:{k + 2}: the runnable block is not closed")
        yield k + 2, runner, "\n".join(lines[k + 2:end])


def command(runner: str, code: str, args) -> list[str]:
    """The command line that runs `code` (also in block.py) with `runner`."""
    if runner == "sh":
        return ["bash", "-euo", "pipefail", "-c", code]
    interpreter = args.python if runner == "python" else args.pvbatch
    if not interpreter:
        raise SystemExit(f"a runnable {runner} block needs --{runner}")
    return [interpreter, "block.py"]


def blank_images(folder: Path) -> list[str]:
    """The PNGs under `folder` that hold a single colour."""
    out = []
    for top, _, files in os.walk(folder):  # not into the links to examples/ and build/
        for png in sorted(Path(top) / f for f in files if f.endswith(".png")):
            with Image.open(png) as im:
                if len(im.convert("RGBA").getcolors(maxcolors=2) or [None] * 2) < 2:
                    out.append(png.name)
    return out


def run(runner: str, code: str, args, env) -> tuple[int, str]:
    """Runs one block in a fresh folder: (exit code, what went wrong)."""
    with tempfile.TemporaryDirectory() as d:
        for name in ("examples", "build"):
            os.symlink(ROOT / name, Path(d) / name)
        (Path(d) / "block.py").write_text(code)
        r = subprocess.run(command(runner, code, args), cwd=d, env=env, capture_output=True,
                           text=True)
        if r.returncode:
            return r.returncode, r.stderr[-3000:]
        if blank := blank_images(Path(d)):
            return 1, f"images of one colour: {', '.join(blank)}"
    return 0, ""


def main(argv):
    ap = argparse.ArgumentParser()
    ap.add_argument("--list", action="store_true")
    ap.add_argument("--python", help="the interpreter of ```python blocks")
    ap.add_argument("--pvbatch", help="ParaView's pvbatch, for the pvbatch blocks")
    args = ap.parse_args(argv)
    if args.python and os.sep in args.python:  # blocks run elsewhere: a path from here
        args.python = os.path.abspath(args.python)
    docs = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
    found = [(p, line, runner, code) for p in docs for line, runner, code in blocks(p)]
    if not found:
        raise SystemExit("no runnable blocks found: the README's quick start should have some")
    if args.list:
        for p, line, runner, _ in found:
            print(f"{p.relative_to(ROOT)}:{line} ({runner})")
        return 0
    env = dict(os.environ, PATH=f"{ROOT / 'target' / 'release'}{os.pathsep}{os.environ['PATH']}",
               PYVISTA_OFF_SCREEN="true")
    shim = ROOT / "build" / "lib" / "libfluidcast_expat_fix.so"
    failed = 0
    for p, line, runner, code in found:
        where = f"{p.relative_to(ROOT)}:{line}"
        block_env = dict(env, LD_PRELOAD=str(shim)) if runner == "pvbatch" and shim.exists() \
            else env
        status, why = run(runner, code, args, block_env)
        if status:
            failed += 1
            print(f"FAILED {where} ({runner}, exit {status}):\n{code}\n{why}")
        else:
            print(f"ok {where} ({runner})")
    print(f"{len(found) - failed} of {len(found)} runnable blocks ran")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
