"""The Python-wrapped vtkFluidCastVolumeMapper in ParaView's Python (pvpython): build a VTK
pipeline by hand, render offscreen, check the mapper drew the particles.

    PYTHONPATH=BUILD_DIR/python pvpython pvpython_mapper.py DATA.vtu
"""
import os
import sys

from fluidcast import vtkFluidCastVolumeMapper
from vtkmodules.util.numpy_support import vtk_to_numpy
from vtkmodules.vtkCommonDataModel import vtkPiecewiseFunction
from vtkmodules.vtkIOXML import vtkXMLUnstructuredGridReader
from vtkmodules.vtkRenderingCore import (
    vtkColorTransferFunction,
    vtkRenderer,
    vtkRenderWindow,
    vtkVolume,
    vtkVolumeProperty,
    vtkWindowToImageFilter,
)

data = sys.argv[1]

reader = vtkXMLUnstructuredGridReader()
reader.SetFileName(data)
mapper = vtkFluidCastVolumeMapper()
mapper.SetInputConnection(reader.GetOutputPort())
mapper.SelectScalarArray("velocity")
mapper.SetScalarModeToUsePointFieldData()
ctf = vtkColorTransferFunction()
ctf.AddRGBPoint(0.38, 0.0, 0.0, 1.0)
ctf.AddRGBPoint(2.03, 1.0, 1.0, 0.0)
otf = vtkPiecewiseFunction()
otf.AddPoint(0.38, 0.1)
otf.AddPoint(2.03, 0.8)
prop = vtkVolumeProperty()
prop.SetColor(ctf)
prop.SetScalarOpacity(otf)
prop.SetScalarOpacityUnitDistance(0.05)
volume = vtkVolume()
volume.SetMapper(mapper)
volume.SetProperty(prop)
ren = vtkRenderer()
ren.AddVolume(volume)
win = vtkRenderWindow()
win.SetOffScreenRendering(1)
win.AddRenderer(ren)
win.SetSize(200, 150)
ren.ResetCamera()
win.Render()
grab = vtkWindowToImageFilter()
grab.SetInput(win)
grab.ShouldRerenderOff()
grab.Update()
img = vtk_to_numpy(grab.GetOutput().GetPointData().GetScalars())
drawn = int((img[:, :3] > 0).any(axis=1).sum())
print(f"{mapper.GetLastParticleCount()} particles, {mapper.GetLastSamples()} samples, "
      f"{drawn} pixels drawn, {mapper.GetLastRenderMilliseconds():.0f} ms")
ok = mapper.GetLastParticleCount() == 6000 and mapper.GetLastSamples() > 0 and drawn > 3000
sys.stdout.flush()
os._exit(0 if ok else 1)
