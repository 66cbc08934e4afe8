//! Builds the cxx bridge's C++ side (headers and glue) for the VTK mapper.

fn main() {
    // Generates the C++ side of the bridge. The headers land in
    // $CARGO_TARGET_DIR/cxxbridge/ (fluidcast-cxx/src/lib.rs.h and rust/cxx.h), where the
    // top-level CMakeLists.txt picks them up; the glue code is compiled into this staticlib.
    cxx_build::bridge("src/lib.rs")
        .std("c++17")
        .compile("fluidcast_cxx_glue");
    println!("cargo:rerun-if-changed=src/lib.rs");
}
