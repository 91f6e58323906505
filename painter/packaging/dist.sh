#!/usr/bin/env bash
# Assemble the release packages (make dist; docs/windows.md):
#
#   painter/packaging/dist.sh LINUX_BINARY WINDOWS_EXE OUT_DIR
#
# writes OUT_DIR/octopaint-VERSION-linux-x86_64.tar.gz and
# OUT_DIR/octopaint-VERSION-windows-x86_64.zip, each one folder holding the
# stripped binary, the artist's README, example documents, Octopaint's
# licence and every bundled dependency's (cargo-about, from Cargo's
# metadata), and on Windows the Khronos OpenXR loader (openxr_loader.sh)
# with its licences. VERSION is the workspace's (painter/Cargo.toml), the
# one the binaries print with --version. Needs cargo-about, zip, strip and
# MinGW's strip.
set -euo pipefail
linux_bin=$(realpath "$1")
windows_exe=$(realpath "$2")
out=$(realpath -m "$3")
here=$(cd "$(dirname "$0")" && pwd)
repo=$(cd "$here/../.." && pwd)
version=$(sed -n 's/^version = "\(.*\)"$/\1/p' "$repo/painter/Cargo.toml" | head -1)
test -n "$version" || { echo "dist.sh: no version in painter/Cargo.toml" >&2; exit 1; }
# The binary must be this version's (the Windows one is checked under Wine
# by the tests).
got=$("$linux_bin" --version)
test "$got" = "octopaint $version" || { echo "dist.sh: $linux_bin says '$got', not 'octopaint $version'" >&2; exit 1; }
command -v cargo-about >/dev/null || { echo "dist.sh: cargo-about missing (cargo install --locked cargo-about --features cli)" >&2; exit 1; }
command -v zip >/dev/null || { echo "dist.sh: zip missing (apt-get install zip)" >&2; exit 1; }

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
# Shared by both packages: licences, documents, the README.
shared="$work/shared"
mkdir -p "$shared/examples"
# cargo-about reads every package's manifest, for every platform, offline:
# fetch them all first (the builds fetched only their own targets' crates).
cargo fetch --locked --manifest-path "$repo/painter/Cargo.toml" >"$work/fetch.log" 2>&1 || { cat "$work/fetch.log" >&2; exit 1; }
cargo about generate --frozen --fail -m "$repo/painter/Cargo.toml" -c "$here/about.toml" "$here/licenses.hbs" \
  -o "$shared/THIRD-PARTY-LICENSES.txt" 2>"$work/about.log" || { cat "$work/about.log" >&2; exit 1; }
cp "$repo/LICENSE" "$shared/LICENSE.txt"
sed "s/@VERSION@/$version/g" "$here/README-artist.md" > "$shared/README.md"
# Example documents, made by the binary being shipped from checked-in
# traces: the 40 km scene (0.3 mm detail under a km of haze) and a study
# of every brush shape and mode.
for pair in scene:scene shapes_modes:shapes-and-modes; do
  "$linux_bin" import "$repo/traces/${pair%%:*}.jsonl" "$shared/examples/${pair#*:}.octo" >"$work/import.log" 2>&1 \
    || { cat "$work/import.log" >&2; exit 1; }
done
# A document's journal starts empty at import; it is not shipped.
rm -f "$shared/examples/"*.journal

mkdir -p "$out"
# Linux: a tar.gz, LF line ends.
name="octopaint-$version-linux-x86_64"
mkdir -p "$work/$name"
cp -r "$shared/." "$work/$name/"
strip -o "$work/$name/octopaint" "$linux_bin"
rm -f "$out/$name.tar.gz"
tar --owner=0 --group=0 --sort=name -czf "$out/$name.tar.gz.tmp" -C "$work" "$name"
mv "$out/$name.tar.gz.tmp" "$out/$name.tar.gz"
echo "$out/$name.tar.gz"

# Windows: a zip, text files with CRLF for Notepad, the OpenXR loader.
name="octopaint-$version-windows-x86_64"
mkdir -p "$work/$name"
cp -r "$shared/." "$work/$name/"
mv "$work/$name/README.md" "$work/$name/README.txt"
for f in README.txt LICENSE.txt THIRD-PARTY-LICENSES.txt; do
  sed -i 's/\r*$/\r/' "$work/$name/$f"
done
x86_64-w64-mingw32-strip -o "$work/$name/octopaint.exe" "$windows_exe"
"$here/openxr_loader.sh" "$repo/painter/target/openxr-loader"
cp "$repo/painter/target/openxr-loader/openxr_loader.dll" "$work/$name/"
cp -r "$repo/painter/target/openxr-loader/openxr-sdk" "$work/$name/openxr-sdk"
rm -f "$out/$name.zip"
(cd "$work" && zip -q -r -X "$out/$name.zip.tmp" "$name")
mv "$out/$name.zip.tmp" "$out/$name.zip"
echo "$out/$name.zip"
