//! Any bytes: a trace or a clear error, never a panic.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    octopaint_tree::fuzz_harness::read(data);
});
