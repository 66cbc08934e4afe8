# For `pip install .`: the VTK that CMake found (VTK_DIR) must be the VTK that the installing
# Python imports. The wrapped mapper loads VTK's libraries; a second VTK in one process (pip's
# wheel beside ParaView's libraries, or another build of the same version) crashes on import
# or on first render, so a mismatch leaves the mapper out, with a note that says how to get it.

# Sets `why` to the reason the mapper cannot be built for the installing Python (empty when it
# can): turned off, no VTK development files found, or a VTK other than the one this Python
# imports.
function (fluidcast_python_vtk_found why)
  set(_how "Install fluidcast into a Python whose VTK ships CMake development files for the \
mapper too: Debian/Ubuntu's ParaView (`apt install paraview-dev`, then `/usr/bin/python3 -m \
venv --system-site-packages`), or conda-forge's `vtk`; point VTK_DIR at that VTK's CMake config \
if it is not found (`pip install . -Ccmake.define.VTK_DIR=...`). pip's `vtk` wheel has no \
development files.")
  if (FLUIDCAST_PYTHON_MAPPER STREQUAL "OFF")
    set(${why} "FLUIDCAST_PYTHON_MAPPER=OFF" PARENT_SCOPE)
    return()
  endif ()
  find_package(VTK QUIET COMPONENTS CommonCore RenderingOpenGL2 Python)
  if (NOT VTK_FOUND)
    set(${why} "no VTK development files were found. ${_how}" PARENT_SCOPE)
    return()
  endif ()
  find_package(Python3 REQUIRED COMPONENTS Interpreter)
  # Without pip's build isolation (PYTHONPATH, PYTHONNOUSERSITE), which hides the site-packages
  # the installed package will see at run time.
  execute_process(
    COMMAND "${CMAKE_COMMAND}" -E env --unset=PYTHONPATH --unset=PYTHONNOUSERSITE
      "${Python3_EXECUTABLE}" -c
      "import os, vtkmodules; print(vtkmodules.__version__); print(os.path.realpath(os.path.dirname(vtkmodules.__file__)))"
    RESULT_VARIABLE _rc OUTPUT_VARIABLE _out ERROR_VARIABLE _err
    OUTPUT_STRIP_TRAILING_WHITESPACE)
  if (NOT _rc EQUAL 0)
    set(${why} "${Python3_EXECUTABLE} cannot import VTK. ${_how}" PARENT_SCOPE)
    return()
  endif ()
  string(REPLACE "\n" ";" _out "${_out}")
  list(GET _out 0 _py_version)
  list(GET _out 1 _py_dir)
  get_filename_component(_vtk_dir "${VTK_PREFIX_PATH}/${VTK_PYTHONPATH}/vtkmodules" REALPATH)
  if (NOT _py_dir STREQUAL _vtk_dir)
    set(${why} "${Python3_EXECUTABLE} imports VTK ${_py_version} from ${_py_dir}, but the VTK \
found for building (${VTK_DIR}, VTK ${VTK_VERSION}) has its Python modules in ${_vtk_dir}: the \
mapper must be built against the VTK it will be loaded with. ${_how}" PARENT_SCOPE)
    return()
  endif ()
  message(STATUS "fluidcast: building the mapper for VTK ${VTK_VERSION} (${_py_dir})")
  set(${why} "" PARENT_SCOPE)
endfunction ()
