//! Any bytes as the journal of an empty document: recovered or refused, never a panic.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    octopaint_doc::fuzz_harness::journal(data);
});
