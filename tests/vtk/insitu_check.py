"""Checks scripts/insitu_demo.sh's output: every OUTDIR/insitu_K.png equals
`fluidcast render OUTDIR/step_K.vtu --camera OUTDIR/camera.json --range $(cat range.txt)
--array $(cat array.txt)` at the same size and background within 2/255 per channel.

    python insitu_check.py CLI OUTDIR MIN_IMAGES
Exit code 0 pass, 1 fail.
"""
import os
import subprocess
import sys

from mpi_views import read_png  # tests/vtk, the script's folder
from vtkmodules.vtkIOImage import vtkPNGReader

cli, out, least = sys.argv[1], sys.argv[2], int(sys.argv[3])


def size(path):
    r = vtkPNGReader()
    r.SetFileName(path)
    r.Update()
    return r.GetOutput().GetDimensions()[:2]


def read(name):
    with open(os.path.join(out, name)) as f:
        return f.read().strip()


images = sorted(f for f in os.listdir(out) if f.startswith("insitu_") and f.endswith(".png"))
status = 0 if len(images) >= least else 1
print(f"{len(images)} in-situ images (at least {least} expected)")
for name in images:
    k = name[len("insitu_"):-len(".png")]
    w, h = size(os.path.join(out, name))
    png = os.path.join(out, f"cli_{k}.png")
    subprocess.run([cli, "render", os.path.join(out, f"step_{k}.vtu"), "--camera",
                    os.path.join(out, "camera.json"), "--range", read("range.txt"), "--array",
                    read("array.txt"), "--size", f"{w}x{h}", "-o", png],
                   check=True, stderr=subprocess.DEVNULL)
    a, b = read_png(os.path.join(out, name)), read_png(png)
    worst = int(abs(a - b).max())
    drawn = int((b != 255).any(axis=1).sum())
    ok = worst <= 2 and drawn > w * h // 50
    print(f"step {k}: in situ vs fluidcast render {worst}/255 (allowed 2), {drawn} pixels drawn"
          f"{'' if ok else ': FAIL'}")
    status |= not ok
sys.exit(status)
