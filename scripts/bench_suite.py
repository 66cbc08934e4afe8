"""The default against full rate over a suite of scenes: `fluidcast bench` on every scene at
every size, off and the default tolerance in one run (each view rendered both ways in turn),
then one table per half of the suite (the scenes developed on, and the held-out ones, reported
apart: a gain only on the first half is not a gain) with each half's largest loss.

    python scripts/bench_suite.py SUITE.json [--sizes 320x240,1024x768,1920x1080] [--views 3]
        [--limit] [--json OUT.json]
    python scripts/bench_suite.py SUITE.json --whole [--before OLD_FLUIDCAST] [--sizes ...]

`--whole` times whole `fluidcast render` processes instead (what a user waits for: reading,
the surface flags and the plan included), best of 2, off and the default, and with `--before`
another build's off and default too, and its own ratio (new against old in one run).

SUITE.json lists the scenes, none of them committed (docs/performance.md says how each was
made):

    [{"name": "three-phase 72k", "file": "/data/threephase_0004.vtu", "half": "held-out",
      "args": ["--array", "phase_id"]}, ...]

`args` are `fluidcast bench`'s render options for the scene (array, support radius,
camera). The ratio reported is full rate's total time over the default's (>1: the default is
faster), the median over the views, from the bench's JSON; in process, each row also gives
the share of the default's pixels further than E_I from full rate's (the 0.05 % rule).
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
HALVES = ("tuned", "held-out")


def bench(exe: str, scene: dict, size: str, views: int, limit: bool) -> dict:
    """One `fluidcast bench` of `scene` at `size`: its JSON rows by tolerance (off, default)."""
    with tempfile.TemporaryDirectory() as d:
        out = Path(d) / "bench.json"
        cmd = [exe, "bench", scene["file"], *scene.get("args", []), "--size", size,
               "--views", str(views), "--tolerances", "0.004", "--no-reference",
               "--json", str(out), *(["--limit"] if limit else [])]
        r = subprocess.run(cmd, capture_output=True, text=True)
        if r.returncode:
            raise SystemExit(f"{scene['name']} at {size}: {' '.join(cmd)}\n{r.stderr[-2000:]}")
        data = json.loads(out.read_text())
    rows = {r.get("error_tolerance"): r for r in data["rows"] if r.get("mode") == "adaptive"}
    off, default = rows[None], rows[0.004]
    return {"scene": scene["name"], "half": scene["half"], "size": size,
            "particles": data["particles"], "timed": "in process", "off_ms": off["total_ms"],
            "default_ms": default["total_ms"], "ratio": off["total_ms"] / default["total_ms"],
            "default_times_limit": default.get("times_limit"),
            "percent_above": default.get("percent_pixels_above")}


def whole(exe: str, before: str | None, scene: dict, size: str) -> dict:
    """Whole `fluidcast render` processes of `scene` at `size`: off and the default, best of 2
    each, in milliseconds; with `before`, that build's off and default too, and its own ratio
    (its full rate over its default: a ratio as it was, not this build's full rate over the
    old default)."""
    def best(binary: str, tolerance: str) -> float:
        times = []
        with tempfile.TemporaryDirectory() as d:
            cmd = [binary, "render", scene["file"], *scene.get("args", []), "--size", size,
                   "--error-tolerance", tolerance, "-o", str(Path(d) / "f.png")]
            for _ in range(2):
                t = time.perf_counter()
                r = subprocess.run(cmd, capture_output=True, text=True)
                if r.returncode:
                    raise SystemExit(f"{' '.join(cmd)}\n{r.stderr[-2000:]}")
                times.append(time.perf_counter() - t)
        return 1e3 * min(times)
    off, default = best(exe, "off"), best(exe, "0.004")
    out = {"scene": scene["name"], "half": scene["half"], "size": size, "particles": None,
           "timed": "whole processes",
           "off_ms": off, "default_ms": default, "ratio": off / default}
    if before:
        out["before_off_ms"] = best(before, "off")
        out["before_ms"] = best(before, "0.004")
        out["before_ratio"] = out["before_off_ms"] / out["before_ms"]
    return out


def table(results: list[dict], half: str) -> None:
    rows = [r for r in results if r["half"] == half]
    if not rows:
        return
    print(f"\n{half} scenes: full rate / default, {rows[0]['timed']} (>1: the default is "
          "faster)")
    print(f"{'scene':<28} {'size':>10} {'particles':>10} {'off ms':>9} {'default ms':>11} "
          f"{'ratio':>7}" + ("  % px > E_I" if "percent_above" in rows[0] else "")
          + ("  before: off, default ms (ratio)" if "before_ms" in rows[0] else ""))
    for r in rows:
        before = (f"  {r['before_off_ms']:9.1f} {r['before_ms']:9.1f} ({r['before_ratio']:.2f})"
                  if "before_ms" in r else "")
        above = (f"  {r['percent_above']:>10.4f}" if r.get("percent_above") is not None
                 else "")
        print(f"{r['scene']:<28} {r['size']:>10} {str(r['particles'] or '-'):>10} "
              f"{r['off_ms']:>9.1f} {r['default_ms']:>11.1f} {r['ratio']:>7.2f}{above}{before}")
    worst = min(rows, key=lambda r: r["ratio"])
    print(f"largest loss ({half}): {worst['ratio']:.2f} ({worst['scene']}, {worst['size']})")


def main(argv):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("suite")
    ap.add_argument("--sizes", default="320x240,1024x768,1920x1080")
    ap.add_argument("--views", type=int, default=3)
    ap.add_argument("--limit", action="store_true", help="also each default time over the "
                    "machine's kernel-evaluation limit (fluidcast bench --limit)")
    ap.add_argument("--whole", action="store_true", help="time whole render processes")
    ap.add_argument("--before", help="with --whole: another build's fluidcast, its default too")
    ap.add_argument("--json")
    ap.add_argument("--exe", default=str(ROOT / "target" / "release" / "fluidcast"))
    args = ap.parse_args(argv)
    scenes = json.loads(Path(args.suite).read_text())
    for s in scenes:
        if s.get("half") not in HALVES or not os.path.exists(s.get("file", "")):
            raise SystemExit(f"{args.suite}: scene {s.get('name')}: needs a file that exists "
                             f"and a half, one of {HALVES}")
    results, failed = [], []
    for s in scenes:
        for size in args.sizes.split(","):
            print(f"{s['name']} at {size} ...", file=sys.stderr, flush=True)
            try:
                results.append(whole(args.exe, args.before, s, size) if args.whole
                               else bench(args.exe, s, size, args.views, args.limit))
            except SystemExit as e:  # one refused view does not lose the others' rows
                print(f"failed: {e}", file=sys.stderr, flush=True)
                failed.append(f"{s['name']} at {size}")
    for half in HALVES:
        table(results, half)
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=1))
    if failed:
        print(f"\nfailed ({len(failed)}): {'; '.join(failed)}", file=sys.stderr)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
