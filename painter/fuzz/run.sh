#!/usr/bin/env bash
# Every fuzz target under libFuzzer for as long as asked (docs/documents.md,
# "Fuzzing"): `make fuzz-long FUZZ_SECONDS=600` runs this.
#
#   painter/fuzz/run.sh SECONDS [TARGET...]
#
# Installs what it needs the first time: a nightly toolchain (rustup) and
# cargo-fuzz. The seed corpora are generated (conformance/fuzz_seeds.py)
# into painter/fuzz/corpus/TARGET, where libFuzzer keeps what it adds; a
# finding is written to painter/fuzz/artifacts/TARGET. Copy one into
# painter/fuzz/regressions/TARGET/ once fixed: the seed script adds those
# to the seeds, so `octopaint fuzz-smoke` (CI) runs it from then on.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
repo="$(dirname "$(dirname "$here")")"
seconds="${1:?usage: run.sh SECONDS [TARGET...]}"
shift
targets=("$@")
rustup toolchain list | grep -q '^nightly' || rustup toolchain install nightly --profile minimal
cargo +nightly fuzz --version >/dev/null 2>&1 || cargo install --locked cargo-fuzz
py="$repo/.venv/bin/python"; [ -x "$py" ] || py=python3
"$py" "$repo/conformance/fuzz_seeds.py" --painter "$repo/painter/target/release/octopaint" "$here/corpus.new"
# Every target by default: the seed script writes a folder for each.
[ ${#targets[@]} -gt 0 ] || mapfile -t targets < <(ls "$here/corpus.new")
# What libFuzzer added before stays; the seeds are refreshed.
for t in "${targets[@]}"; do
    mkdir -p "$here/corpus/$t"
    cp "$here/corpus.new/$t/"* "$here/corpus/$t/"
done
rm -rf "$here/corpus.new"
cd "$here"
for t in "${targets[@]}"; do
    dict=()
    case $t in trace_reader|replay|journal) dict=(-dict=trace.dict) ;; esac
    echo "== $t, $seconds s"
    cargo +nightly fuzz run "$t" "corpus/$t" -- -max_total_time="$seconds" -max_len=65536 "${dict[@]}"
done
