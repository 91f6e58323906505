//! Any bytes as a Wavefront OBJ file: a mesh or a clear error, never a panic.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    octopaint_export::fuzz_harness::mesh(data, "obj");
});
