"""A long frame can be interrupted as VTK's own ray casters can: the mapper renders on a worker
thread and polls the render window's abort check (an interactor with pending events sets
AbortRender), reporting progress meanwhile (ProgressEvent)."""
import fluidcast
import numpy as np
import pyvista as pv
from vtkmodules.vtkCommonCore import vtkCommand


def slow_particles():
    """A lattice whose support radius makes a frame take a second or more."""
    g = np.stack(np.meshgrid(*[np.arange(12) * 0.05] * 3, indexing="ij"), -1).reshape(-1, 3)
    mesh = pv.PolyData(g)
    mesh["q"] = np.linspace(0.0, 1.0, mesh.n_points)
    return mesh


def test_an_abort_stops_the_frame_without_an_error_and_the_next_renders():
    p = pv.Plotter(off_screen=True, window_size=[400, 300])
    p.set_background("white")
    volume = fluidcast.add_particles(p, slow_particles(), "q", support_radius=0.4,
                                     error_tolerance=0.0, show_scalar_bar=False, render=False)
    mapper = volume.mapper
    progress = []
    mapper.AddObserver(vtkCommand.ProgressEvent, lambda o, e: progress.append(o.GetProgress()))
    window = p.ren_win
    checks = []

    def abort(win, _event):
        checks.append(True)
        win.SetAbortRender(1)

    tag = window.AddObserver(vtkCommand.AbortCheckEvent, abort)
    aborted = p.screenshot(return_img=True)  # renders the frame
    assert checks, "the mapper never polled the abort check"
    assert mapper.GetLastError() == ""
    assert not (aborted != 255).any(), "an aborted frame drew"
    window.RemoveObserver(tag)
    window.SetAbortRender(0)
    progress.clear()
    window.Render()
    drawn = p.screenshot(return_img=True)
    assert mapper.GetLastError() == ""
    assert (drawn != 255).any()
    assert progress and max(progress) > 0.5, progress
    p.close()
