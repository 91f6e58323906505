//! Any bytes as a document (.octo, every format version): a document or a clear error, never a panic.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    octopaint_doc::fuzz_harness::document(data);
});
