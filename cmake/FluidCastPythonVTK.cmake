# For `pip install .`: the VTK that CMake found (VTK_DIR) must be the VTK that the installing
# Python imports. The wrapped mapper loads VTK's libraries; a second VTK in one process (pip's
# wheel beside ParaView's libraries, or another build of the same version) crashes on import
# or on first render, so a mismatch is a configure error that says how to fix it.

function (fluidcast_check_python_vtk)
  find_package(Python3 REQUIRED COMPONENTS Interpreter)
  # Without pip's build isolation (PYTHONPATH, PYTHONNOUSERSITE), which hides the site-packages
  # the installed package will see at run time.
  execute_process(
    COMMAND "${CMAKE_COMMAND}" -E env --unset=PYTHONPATH --unset=PYTHONNOUSERSITE
      "${Python3_EXECUTABLE}" -c
      "import os, vtkmodules; print(vtkmodules.__version__); print(os.path.realpath(os.path.dirname(vtkmodules.__file__)))"
    RESULT_VARIABLE _rc OUTPUT_VARIABLE _out ERROR_VARIABLE _err
    OUTPUT_STRIP_TRAILING_WHITESPACE)
  set(_how "Install fluidcast into a Python whose VTK ships CMake development files: \
Debian/Ubuntu's ParaView (`apt install paraview-dev`, then `/usr/bin/python3 -m venv \
--system-site-packages`), or conda-forge's `vtk`; point VTK_DIR at that VTK's CMake config \
if it is not found (`pip install . -Ccmake.define.VTK_DIR=...`). pip's `vtk` wheel has no \
development files. For the pure-Python helpers only: \
-Ccmake.define.FLUIDCAST_PYTHON_MAPPER=OFF.")
  if (NOT _rc EQUAL 0)
    message(FATAL_ERROR "fluidcast: ${Python3_EXECUTABLE} cannot import VTK (${_err}). ${_how}")
  endif ()
  string(REPLACE "\n" ";" _out "${_out}")
  list(GET _out 0 _py_version)
  list(GET _out 1 _py_dir)
  get_filename_component(_vtk_dir "${VTK_PREFIX_PATH}/${VTK_PYTHONPATH}/vtkmodules" REALPATH)
  if (NOT _py_dir STREQUAL _vtk_dir)
    message(FATAL_ERROR "fluidcast: ${Python3_EXECUTABLE} imports VTK ${_py_version} from \
${_py_dir}, but the VTK found for building (${VTK_DIR}, VTK ${VTK_VERSION}) has its Python \
modules in ${_vtk_dir}: the mapper must be built against the VTK it will be loaded with. \
${_how}")
  endif ()
  message(STATUS "fluidcast: building the mapper for VTK ${VTK_VERSION} (${_py_dir})")
endfunction ()
