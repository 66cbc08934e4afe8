"""Rendering through the Python module vs the CLI, measured in one run (issue 48).

    .venv-pip/bin/python scripts/bench_module.py FILE ARRAY [WxH] [REPEATS]

Times, minimum of REPEATS (default 5), on the CPU backend:
* CLI: the whole `fluidcast render` process (reading, particles, render, PNG), and the
  render's own time as its --stats say (timings.total_ms: the frame after its particles);
* module, whole: `fluidcast.render(path)` + `Image.save` (reading, particles, render, PNG);
* module, frame: `Scene.render` of particles already built (what an orbit or a movie pays),
  which is what the CLI's own render time measures.
"""
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import fluidcast


def best(f, repeats):
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        f()
        times.append(time.perf_counter() - t)
    return min(times)


def main(path, array, size="1024x768", repeats="5"):
    w, h = (int(v) for v in size.split("x"))
    n = int(repeats)
    cli = Path(sys.executable).parent / "fluidcast"
    out = Path(tempfile.mkdtemp()) / "b.png"
    cmd = [str(cli), "render", path, "--array", array, "--size", size, "--backend", "cpu",
           "-o", str(out)]
    t_cli = best(lambda: subprocess.run(cmd, check=True, capture_output=True), n)
    stats = out.with_suffix(".json")
    own = []
    for _ in range(n):
        subprocess.run([*cmd, "--stats", str(stats)], check=True, capture_output=True)
        own.append(json.loads(stats.read_text())["timings"]["total_ms"] / 1e3)
    t_own = min(own)

    def whole():
        fluidcast.render(path, array, size=(w, h), backend="cpu").save(out)

    t_whole = best(whole, n)
    scene = fluidcast.Scene(fluidcast.read(path), array, backend="cpu")
    t_frame = best(lambda: scene.render(size=(w, h)), n)
    print(f"{path}: {scene.info['particles']} particles at {size}, CPU, min of {n}")
    print(f"  CLI process                  {t_cli * 1e3:8.1f} ms")
    print(f"  module read+render+png       {t_whole * 1e3:8.1f} ms  "
          f"({t_whole / t_cli:.3f}x the CLI process)")
    print(f"  CLI's own render (--stats)   {t_own * 1e3:8.1f} ms")
    print(f"  module frame (Scene.render)  {t_frame * 1e3:8.1f} ms  "
          f"({t_frame / t_own:.3f}x the CLI's render)")


if __name__ == "__main__":
    main(*sys.argv[1:])
