#!/usr/bin/env bash
# Build the Khronos OpenXR loader for Windows (openxr_loader.dll, Apache-2.0)
# with MinGW, from the OpenXR-SDK sources that the openxr-sys crate carries
# (so its version is the one Cargo.lock pins: the headers the painter was
# built against). The Windows package ships it beside octopaint.exe.
#
#   painter/packaging/openxr_loader.sh OUT_DIR
#
# Writes OUT_DIR/openxr_loader.dll and OUT_DIR/openxr-sdk/ (its licence
# files and version). Needs cmake and gcc-mingw-w64-x86-64 (g++ included);
# (the posix thread model: the loader uses std::mutex); libstdc++, libgcc
# and winpthreads are linked statically, so the DLL needs
# nothing but Windows' own DLLs. Skips the build when OUT_DIR has a DLL
# built from the same sources.
set -euo pipefail
out=$(realpath -m "$1")
here=$(cd "$(dirname "$0")" && pwd)
manifest=$(cargo metadata --locked --format-version 1 --manifest-path "$here/../Cargo.toml" \
  | python3 -c 'import json,sys; print(next(p["manifest_path"] for p in json.load(sys.stdin)["packages"] if p["name"] == "openxr-sys"))')
sdk=$(dirname "$manifest")/OpenXR-SDK
test -f "$sdk/CMakeLists.txt" || { echo "openxr_loader.sh: no OpenXR-SDK sources in $(dirname "$manifest")" >&2; exit 1; }
version=$(sed -n 's/^## OpenXR SDK \([0-9.]*\).*/\1/p' "$sdk/CHANGELOG.SDK.md" | head -1)
stamp="$(basename "$(dirname "$manifest")"), OpenXR SDK $version"
if [ -f "$out/openxr_loader.dll" ] && [ "$(cat "$out/openxr-sdk/VERSION" 2>/dev/null)" = "$stamp" ]; then
  exit 0
fi
command -v cmake >/dev/null || { echo "openxr_loader.sh: cmake missing (apt-get install cmake)" >&2; exit 1; }
command -v x86_64-w64-mingw32-g++-posix >/dev/null || { echo "openxr_loader.sh: x86_64-w64-mingw32-g++-posix missing (apt-get install gcc-mingw-w64-x86-64 g++-mingw-w64-x86-64)" >&2; exit 1; }
build=$(mktemp -d)
trap 'rm -rf "$build"' EXIT
cat > "$build/mingw.cmake" <<'CMAKE'
set(CMAKE_SYSTEM_NAME Windows)
set(CMAKE_SYSTEM_PROCESSOR x86_64)
set(CMAKE_C_COMPILER x86_64-w64-mingw32-gcc-posix)
set(CMAKE_CXX_COMPILER x86_64-w64-mingw32-g++-posix)
set(CMAKE_RC_COMPILER x86_64-w64-mingw32-windres)
set(CMAKE_FIND_ROOT_PATH /usr/x86_64-w64-mingw32)
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
CMAKE
# Debian 12's MinGW headers predate WINAPI_PARTITION_SYSTEM; on a desktop
# family Windows' own headers make it 0.
partition=-DWINAPI_PARTITION_SYSTEM=0
# Out of tree, so the crate's sources stay untouched; no Python (the SDK's
# generated sources are checked in), no tests, no API layers.
cmake -S "$sdk" -B "$build/b" -G "Unix Makefiles" -DCMAKE_TOOLCHAIN_FILE="$build/mingw.cmake" \
  -DCMAKE_BUILD_TYPE=Release -DDYNAMIC_LOADER=ON -DBUILD_TESTS=OFF -DBUILD_API_LAYERS=OFF \
  -DBUILD_CONFORMANCE_TESTS=OFF -DBUILD_ALL_EXTENSIONS=OFF \
  -DCMAKE_C_FLAGS="$partition" -DCMAKE_CXX_FLAGS="$partition" \
  -DCMAKE_SHARED_LINKER_FLAGS="-static-libgcc -static-libstdc++ -Wl,-Bstatic,--whole-archive -lwinpthread -Wl,--no-whole-archive,-Bdynamic" \
  >"$build/configure.log" 2>&1 || { cat "$build/configure.log" >&2; exit 1; }
make -C "$build/b" -j"$(nproc)" openxr_loader >"$build/make.log" 2>&1 || { tail -40 "$build/make.log" >&2; exit 1; }
dll=$(find "$build/b" -name '*openxr_loader*.dll' | head -1)
test -n "$dll" || { echo "openxr_loader.sh: the build made no openxr_loader.dll" >&2; exit 1; }
# Only Windows' own DLLs may be imported.
imports=$(x86_64-w64-mingw32-objdump -p "$dll" | sed -n 's/^\s*DLL Name: //p' | tr 'A-Z' 'a-z' | sort -u)
for d in $imports; do
  case "$d" in kernel32.dll|advapi32.dll|user32.dll|shell32.dll|ole32.dll|msvcrt.dll|api-ms-win-*|ucrtbase.dll|cfgmgr32.dll|pathcch.dll|shlwapi.dll) ;;
    *) echo "openxr_loader.sh: the DLL imports $d, which Windows does not have" >&2; exit 1 ;; esac
done
mkdir -p "$out/openxr-sdk"
x86_64-w64-mingw32-strip -o "$out/openxr_loader.dll" "$dll"
cp "$sdk/LICENSE" "$sdk/COPYING.adoc" "$out/openxr-sdk/"
cp -r "$sdk/LICENSES" "$out/openxr-sdk/"
echo "$stamp" > "$out/openxr-sdk/VERSION"
echo "openxr_loader.dll ($stamp) in $out"
