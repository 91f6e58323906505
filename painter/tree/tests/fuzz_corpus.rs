//! Replays the committed fuzz corpora (painter/fuzz/corpus) through the fuzz
//! targets' bodies on stable Rust: every input the fuzzer kept, crashes it
//! found included, must now read and replay without a panic.

use std::path::Path;

use octopaint_tree::fuzz_harness::{read, replay_bounded};

fn corpus(target: &str) -> Vec<Vec<u8>> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fuzz/corpus").join(target);
    let mut files: Vec<_> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.unwrap().path())
        .collect();
    files.sort();
    files.into_iter().map(|p| std::fs::read(p).unwrap()).collect()
}

#[test]
fn trace_reader_corpus_reads_without_panic() {
    let inputs = corpus("trace_reader");
    assert!(inputs.len() >= 50, "the corpus is missing ({} files)", inputs.len());
    for data in &inputs {
        read(data);
    }
}

#[test]
fn replay_corpus_replays_to_valid_trees() {
    let inputs = corpus("replay");
    assert!(inputs.len() >= 20, "the corpus is missing ({} files)", inputs.len());
    let replayed = inputs.iter().filter(|d| replay_bounded(d)).count();
    assert!(replayed >= 10, "only {replayed} corpus inputs were replayable");
}
