# For `pip install .`: the Python extension module fluidcast._core (rust/fluidcast-python, PyO3
# with the abi3 stable ABI: one build serves CPython 3.9 and later) and the `fluidcast` CLI,
# built by cargo and installed into the package and beside the interpreter. Neither needs
# VTK; the VTK mapper is built after them only where VTK's development files are found.

function (fluidcast_python_module)
  find_package(Python3 REQUIRED COMPONENTS Interpreter)
  find_program(CARGO cargo)
  if (NOT CARGO)
    message(FATAL_ERROR "fluidcast: cargo (Rust's build tool) is not on the PATH; the Python \
module is built from Rust: install Rust with https://rustup.rs, then run pip again")
  endif ()
  set(_target_dir "${CMAKE_SOURCE_DIR}/target")
  set(_module "${_target_dir}/release/libfluidcast_python.so")
  set(_cli "${_target_dir}/release/fluidcast")
  file(GLOB_RECURSE _rust_sources CONFIGURE_DEPENDS
    "${CMAKE_SOURCE_DIR}/rust/*.rs" "${CMAKE_SOURCE_DIR}/rust/*/Cargo.toml")
  add_custom_command(
    OUTPUT "${_module}" "${_cli}"
    COMMAND "${CMAKE_COMMAND}" -E env "CARGO_TARGET_DIR=${_target_dir}"
      "PYO3_PYTHON=${Python3_EXECUTABLE}"
      "${CARGO}" build --release -p fluidcast-python -p fluidcast-cli
    WORKING_DIRECTORY "${CMAKE_SOURCE_DIR}"
    DEPENDS ${_rust_sources} "${CMAKE_SOURCE_DIR}/Cargo.toml"
    COMMENT "cargo build: the Python module fluidcast._core and the fluidcast CLI"
    USES_TERMINAL)
  add_custom_target(fluidcast_python_module ALL DEPENDS "${_module}" "${_cli}")
  install(FILES "${_module}" DESTINATION "fluidcast" RENAME "_core.abi3.so")
  # The CLI beside the interpreter (venv/bin/fluidcast), without its debug information.
  install(PROGRAMS "${_cli}" DESTINATION "${SKBUILD_SCRIPTS_DIR}")
  if (CMAKE_STRIP)
    install(CODE "execute_process(COMMAND \"${CMAKE_STRIP}\" \"${SKBUILD_SCRIPTS_DIR}/fluidcast\")")
  endif ()
endfunction ()
