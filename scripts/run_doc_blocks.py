"""Runs every shell block of README.md and docs/*.md marked runnable, so the docs stay true.

A block is marked by the line `<!-- runnable -->` right before its ```sh fence (invisible in
the rendered page). Each runs under `bash -euo pipefail` in a fresh temporary folder holding
a link to the checkout's `examples/` (the shipped data), with the release `fluidcast` first
on the PATH (scripts/test.sh builds it); the test command runs this script.

    python scripts/run_doc_blocks.py [--list]
"""
import os
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MARK = "<!-- runnable -->"


def blocks(path: Path):
    """(line, code) of each marked block of `path`."""
    lines = path.read_text().splitlines()
    for k, line in enumerate(lines):
        if line.strip() != MARK:
            continue
        fence = lines[k + 1].strip() if k + 1 < len(lines) else ""
        if not fence.startswith("```sh"):
            raise SystemExit(f"{path}:{k + 1}: {MARK} must be followed by a ```sh block")
        end = next((j for j in range(k + 2, len(lines)) if lines[j].strip() == "```"), None)
        if end is None:
            raise SystemExit(f"{path}:{k + 2}: the runnable block is not closed")
        yield k + 2, "\n".join(lines[k + 2:end])


def main(argv):
    docs = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
    found = [(p, line, code) for p in docs for line, code in blocks(p)]
    if not found:
        raise SystemExit("no runnable blocks found: the README's quick start should have some")
    if "--list" in argv:
        for p, line, _ in found:
            print(f"{p.relative_to(ROOT)}:{line}")
        return 0
    env = dict(os.environ, PATH=f"{ROOT / 'target' / 'release'}{os.pathsep}{os.environ['PATH']}")
    failed = 0
    for p, line, code in found:
        where = f"{p.relative_to(ROOT)}:{line}"
        with tempfile.TemporaryDirectory() as d:
            os.symlink(ROOT / "examples", Path(d) / "examples")
            r = subprocess.run(["bash", "-euo", "pipefail", "-c", code], cwd=d, env=env,
                               capture_output=True, text=True)
        if r.returncode:
            failed += 1
            print(f"FAILED {where} (exit {r.returncode}):\n{code}\n{r.stderr[-3000:]}")
        else:
            print(f"ok {where}")
    print(f"{len(found) - failed} of {len(found)} runnable blocks ran")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
