//! Any bytes as a voxel set (.npz): a set or a clear error, never a panic.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    octopaint_tree::fuzz_harness::voxels(data);
});
