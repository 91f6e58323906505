//! Any trace: a valid tree after replay, never a panic.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    octopaint_tree::fuzz_harness::replay_bounded(data);
});
