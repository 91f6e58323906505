# Octopaint: the two commands of the README.
#   make demo   set up, replay the scene trace with the reference (images and
#               tree dumps) and with the painter (tree dumps), compare them,
#               export the scene's detail to OpenVDB and glTF (out/export)
#   make check  the fast lane, first in `make test`: formatting (rustfmt),
#               lints (clippy with warnings denied, ruff), module circles,
#               the core crates' and the reference's unit tests
#   make test   set up, run `make check`, then every test: the painter's (cargo), the
#               reference's and the conformance driver's (pytest),
#               conformance on every trace, the VR session against
#               Monado's simulated headset (test-vr), the Windows build
#               under Wine and the release packages (test-windows), and
#               the macOS type-check (check-macos); in two lanes at once
#               (see "Two lanes" below)
#   make dist   the release packages: dist/octopaint-VERSION-linux-x86_64.tar.gz
#               and dist/octopaint-VERSION-windows-x86_64.zip (docs/windows.md)
# Setup is Mesa's CPU drivers for Vulkan and GL (lavapipe, llvmpipe: the GPU
# tests and renders run on them when the machine has no GPU), Debian's
# OpenVDB Python module (the export tests read .vdb files with it), a virtual
# environment in .venv with the reference package (reference/pyproject.toml)
# installed in editable mode, and the painter built in release mode
# (painter/target/release/octopaint). Needs python3, cargo, apt-get (as root,
# only when the drivers are missing) and network access to Debian, PyPI and
# crates.io.

VENV := .venv
# The Python linter of `make check` (ruff.toml), pinned: a newer ruff may
# add rules.
RUFF_VERSION := 0.17.6
PY := $(VENV)/bin/python
OUT := out
PAINTER := painter/target/release/octopaint
# Cargo keeps its own count of jobs (all cores), not make's job server.
CARGO := env -u MAKEFLAGS -u MFLAGS -u CARGO_MAKEFLAGS cargo
export NODEVICE_SELECT := 1

.PHONY: demo test test-lanes check check-circles setup system painter paint test-vr test-painter test-reference test-conformance conformance fuzz fuzz-smoke fuzz-long precision examples bench-gpu bench-realtime bench-soak bench-export gpu-campaign clean \
	system-windows painter-windows check-macos tools dist test-windows test-windows-package test-windows-crates

setup: system $(VENV)/.installed

# The Vulkan loader and Mesa's drivers; a machine with a GPU driver of its
# own keeps it (wgpu prefers a discrete or integrated GPU to lavapipe).
# OpenVDB's own Python module for Debian's python3: the export tests open
# the painter's .vdb files with it (conformance/vdb_probe.py). Xvfb and
# xdotool: the desktop window's test runs it on a virtual X server and
# drives it with real input events. OpenVDB's headers and g++: the core's
# benchmark against OpenVDB (painter/bench/tree_vs_openvdb.sh) builds its
# peer with them, and conformance/tests/test_bench_tools.py runs it.
MESA_PACKAGES := mesa-vulkan-drivers libvulkan1 libegl1 libegl-mesa0 libgl1-mesa-dri
SYSTEM_PACKAGES := $(MESA_PACKAGES) python3-openvdb python3-numpy xvfb xdotool libopenvdb-dev libboost-dev g++ strace
system:
	@if ! ls /usr/share/vulkan/icd.d/lvp_icd.*.json >/dev/null 2>&1 || ! ldconfig -p | grep -q libEGL_mesa \
	    || ! /usr/bin/python3 -c 'import pyopenvdb, numpy' >/dev/null 2>&1 \
	    || ! command -v Xvfb >/dev/null || ! command -v xdotool >/dev/null \
	    || ! [ -e /usr/include/openvdb/openvdb.h ] || ! [ -e /usr/include/boost/version.hpp ] || ! command -v g++ >/dev/null \
	    || ! command -v strace >/dev/null; then \
	  echo "installing $(SYSTEM_PACKAGES)"; \
	  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $(SYSTEM_PACKAGES) >/dev/null || \
	  { apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $(SYSTEM_PACKAGES) >/dev/null; }; \
	fi

$(VENV)/.installed: reference/pyproject.toml
	@python3 -m venv $(VENV) 2>/dev/null || { \
	  echo "python3 -m venv failed: installing python3-venv"; \
	  apt-get update -qq && apt-get install -y -qq python3-venv && python3 -m venv $(VENV); }
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e ./reference
	$(PY) -m pip install --quiet ruff==$(RUFF_VERSION)
	@touch $@

# Cargo decides what to rebuild; --locked keeps the dependency versions of Cargo.lock.
painter:
	@command -v cargo >/dev/null || { echo "cargo is missing: install Rust (https://rustup.rs)"; exit 1; }
	$(CARGO) build --release --locked --manifest-path painter/Cargo.toml

demo: setup painter
	$(VENV)/bin/octopaint-ref replay traces/scene.jsonl --out $(OUT)/reference
	$(VENV)/bin/octopaint-ref check $(OUT)/reference/*.npz
	$(PAINTER) replay traces/scene.jsonl --out $(OUT)/painter
	$(PY) conformance/driver.py traces/scene.jsonl --painter $(PAINTER) --report $(OUT)/conformance --generated 200 --require-images
	mkdir -p $(OUT)/export
	$(PAINTER) export traces/scene.jsonl --region $(DETAIL) --vdb $(OUT)/export/scene_detail.vdb --gltf $(OUT)/export/scene_detail.glb
	rm -f $(OUT)/export/scene_detail.octo $(OUT)/export/scene_detail.octo.journal
	$(PAINTER) new $(OUT)/export/scene_detail.octo --like traces/scene.jsonl
	$(PAINTER) import-vdb $(OUT)/export/scene_detail.vdb $(OUT)/export/scene_detail.octo --layer detail --depth 21

# The scene's finest strokes (radius 3 to 60 mm on a 40 km canvas), in
# canvas units: the box `make demo` exports and docs/export.md renders.
DETAIL := 19999.6,19999.7,19999.5,20000.6,20000.5,20000.3

test-painter: system
	$(CARGO) test --release --locked --manifest-path painter/Cargo.toml

# No new module circle inside a crate (painter/tools/module_circles.baseline).
check-circles:
	python3 painter/tools/test_module_circles.py
	python3 painter/tools/module_circles.py

# The fast lane: what fails in minutes fails first. rustfmt and clippy come
# with rustup's default profile; `rustup component add` is for a minimal one.
# Clippy's allowances are in painter/Cargo.toml ([workspace.lints]), each
# with its reason. The unit tests: the model, trace, octree, paint and tree crates' own
# (`--lib`; the tree's integration tests run in test-painter) and the
# reference's fast files (REFERENCE_UNIT; test-reference runs the rest).
REFERENCE_UNIT := tests/test_arith.py tests/test_brush.py tests/test_trace.py tests/test_tree.py tests/test_prefilter.py tests/test_layers.py tests/test_imports.py tests/test_mirror.py
check: setup check-circles
	@rustup component list --installed 2>/dev/null | grep -q '^rustfmt' || rustup component add rustfmt
	@rustup component list --installed 2>/dev/null | grep -q '^clippy' || rustup component add clippy
	cd painter && cargo fmt --all -- --check
	cd painter && cargo fmt --manifest-path fuzz/Cargo.toml -- --check
	$(VENV)/bin/ruff check .
	$(CARGO) clippy --release --locked --manifest-path painter/Cargo.toml --workspace --all-targets -- -D warnings
	$(CARGO) test --release --locked --manifest-path painter/Cargo.toml -p octopaint-model -p octopaint-trace -p octopaint-octree -p octopaint-paint -p octopaint-tree --lib
	cd reference && ../$(PY) -m pytest -q -p no:cacheprovider --durations=10 $(REFERENCE_UNIT)

# The reference's own tests need no painter.
test-reference: setup
	cd reference && ../$(PY) -m pytest -q -p no:cacheprovider --durations=15 tests $(REFERENCE_UNIT:%=--ignore=%)

test-conformance: setup painter
	$(PY) -m pytest -q -p no:cacheprovider --durations=15 conformance/tests

conformance: setup painter
	$(PY) conformance/driver.py --painter $(PAINTER) --report $(OUT)/conformance --require-images

# Random traces replayed by both implementations (conformance/README.md):
# `make fuzz SEEDS=500 FIRST=1000`; differing traces stay in out/fuzz.
SEEDS ?= 200
FIRST ?= 0
fuzz: setup painter
	$(PY) conformance/fuzz.py --painter $(PAINTER) --first $(FIRST) --seeds $(SEEDS) --out $(OUT)/fuzz

# The readers' fuzz targets (docs/documents.md, "Fuzzing"). fuzz-smoke: each
# target's body on its generated seeds and FUZZ_RUNS variants, on stable
# Rust (CI runs it through conformance/tests/test_fuzz_smoke.py);
# fuzz-long: every target under libFuzzer for FUZZ_SECONDS each (installs a
# nightly toolchain and cargo-fuzz the first time).
FUZZ_RUNS ?= 20000
FUZZ_SECONDS ?= 300
fuzz-smoke: setup painter
	$(PY) conformance/fuzz_seeds.py --painter $(PAINTER) $(OUT)/fuzz-seeds
	$(PAINTER) fuzz-smoke $(OUT)/fuzz-seeds --runs $(FUZZ_RUNS) --crashes $(OUT)/fuzz-crashes
fuzz-long: setup painter
	painter/fuzz/run.sh $(FUZZ_SECONDS)

# The VR session against Monado's simulated headset in a Debian 13 chroot
# (docs/vr.md): needs root, and network the first time (debootstrap and
# Monado's packages, about 2 minutes; then seconds).
test-vr: setup painter
	painter/xr/monado/test.sh $(PY)

test:
	@$(MAKE) --no-print-directory check
	@$(MAKE) --no-print-directory -j2 --output-sync=target test-lanes

# Two lanes: `make test` runs two chains of targets at once, one a core on
# CI's two. The cargo lane (the builds and the crates' tests share
# painter/target and its lock, so they go one after another) and the
# Python lane (the reference's pytest during the Linux build; once the
# painter is built, the conformance pytest, the driver and the VR session;
# once the Windows build is done, the packages and their tests under
# Wine). The order-only prerequisites below exist only for `make test`:
# they keep each lane in order, and apt-get (system, system-windows, the
# Monado chroot's debootstrap) to one at a time. The cargo lane: painter,
# painter-windows, test-painter, check-macos, test-windows-crates. The
# Python lane: test-reference, test-conformance, conformance, test-vr,
# tools, dist, test-windows-package. Each target's output is
# printed whole when it ends; a failure stops both lanes after their
# current target. Cargo runs outside make's job server (CARGO above), so a
# build takes both cores whenever the other lane is idle.
test-lanes: test-painter test-reference test-conformance conformance test-vr test-windows check-macos
ifneq ($(filter test-lanes,$(MAKECMDGOALS)),)
system-windows: | system
painter: | system-windows
painter-windows: | painter
test-painter: | painter-windows
check-macos: | test-painter
test-windows-crates: | check-macos
test-conformance: | test-reference
conformance: | test-conformance
test-vr: | conformance
tools: | test-vr
endif

# Windows, cross-built here (docs/windows.md): MinGW links it, Wine runs it
# for the tests, zip packs it. The Windows build shares the Linux build's
# target folder, so build scripts and proc macros compile once.
WINDOWS_TARGET := x86_64-pc-windows-gnu
WINDOWS_EXE := painter/target/$(WINDOWS_TARGET)/release/octopaint.exe
WINDOWS_PACKAGES := gcc-mingw-w64-x86-64 g++-mingw-w64-x86-64 wine64 zip cmake
# Without the line tables the Linux build keeps for perf: the package's
# exe is stripped anyway, and the build takes about a tenth less CPU. Build
# scripts and proc macros (host code) keep them, so they stay the Linux
# build's; the crates' tests under Wine use the same settings, so they
# reuse the Windows build's crates.
WINDOWS_CARGO := CARGO_PROFILE_RELEASE_DEBUG=false CARGO_PROFILE_RELEASE_BUILD_OVERRIDE_DEBUG=line-tables-only $(CARGO)
system-windows:
	@if ! command -v x86_64-w64-mingw32-gcc >/dev/null || ! command -v x86_64-w64-mingw32-g++-posix >/dev/null \
	    || ! command -v cmake >/dev/null \
	    || ! test -x /usr/lib/wine/wine64 || ! command -v zip >/dev/null; then \
	  echo "installing $(WINDOWS_PACKAGES)"; \
	  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $(WINDOWS_PACKAGES) >/dev/null || \
	  { apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $(WINDOWS_PACKAGES) >/dev/null; }; \
	fi
	@rustup target list --installed | grep -qx $(WINDOWS_TARGET) || rustup target add $(WINDOWS_TARGET)

painter-windows: system-windows
	$(WINDOWS_CARGO) build --release --locked --target $(WINDOWS_TARGET) --manifest-path painter/Cargo.toml -p octopaint-app

# macOS gets the desktop window (no OpenXR runtime exists there): the whole
# binary type-checks for Apple silicon so it does not rot; nothing links.
check-macos:
	@rustup target list --installed | grep -qx aarch64-apple-darwin || rustup target add aarch64-apple-darwin
	$(CARGO) check --release --locked --target aarch64-apple-darwin --manifest-path painter/Cargo.toml -p octopaint-app

# cargo-about writes the packages' third-party licences from Cargo's metadata.
CARGO_ABOUT_VERSION := 0.9.3
tools:
	@cargo-about --version 2>/dev/null | grep -qx "cargo-about $(CARGO_ABOUT_VERSION)" || \
	  $(CARGO) install --locked --quiet cargo-about --version $(CARGO_ABOUT_VERSION) --features cli

dist: system system-windows painter painter-windows tools
	painter/packaging/dist.sh $(PAINTER) $(WINDOWS_EXE) dist

# The Windows build under Wine against the Linux build, and the packages
# unpacked into empty folders (conformance/windows/), then the platform
# and document crates' own tests run under Wine (durable saves through
# MoveFileExW, journals, crash recovery).
test-windows: test-windows-package test-windows-crates

test-windows-package: setup dist
	$(PY) -m pytest -q -p no:cacheprovider conformance/windows

test-windows-crates: system-windows
	CARGO_TARGET_X86_64_PC_WINDOWS_GNU_RUNNER=$(CURDIR)/painter/packaging/wine/run.sh \
	  $(WINDOWS_CARGO) test --release --locked --target $(WINDOWS_TARGET) --manifest-path painter/Cargo.toml -p octopaint-platform -p octopaint-doc

# GPU pipeline figures: upload MB/s per block size, g3 pass and ray casting
# ms per frame at 1280x720 on the scene trace (docs/benchmarks.md).
bench-gpu: setup painter
	$(PAINTER) bench gpu traces/scene.jsonl

# Every GPU figure in one run (docs/benchmarks.md, "On a real GPU"):
# out/gpu/summary.md and JSON; on a GPU machine about 7 minutes, on lavapipe
# use painter/bench/gpu_campaign.sh out/gpu --small.
gpu-campaign: setup painter
	painter/bench/gpu_campaign.sh $(OUT)/gpu

# The real-time pipeline's experiments (the paper's Table 1, Fig. 8, Fig. 9,
# latency; about 7 minutes on 2 cores): out/realtime/results.json, then the
# plots into docs/realtime/ (docs/benchmarks.md).
bench-realtime: setup painter
	$(PAINTER) bench realtime traces/scene.jsonl --out $(OUT)/realtime
	$(PY) painter/bench/plot_realtime.py $(OUT)/realtime/results.json docs/realtime

# A million stamps through the window's engine, memory sampled (docs/benchmarks.md,
# "The soak"; 30 to 40 minutes on 2 cores, 4 GiB of memory on lavapipe); the figure
# goes to docs/soak/rss.png.
SOAK_STAMPS ?= 1000000
SOAK_UNDO_MIB ?= 256
bench-soak: setup painter
	$(PAINTER) bench soak --stamps $(SOAK_STAMPS) --undo-mib $(SOAK_UNDO_MIB) --out $(OUT)/soak
	$(PY) painter/bench/plot_soak.py $(OUT)/soak/soak.json docs/soak/rss.png

# Paint in the desktop window on the scene (imported into out/scene.octo
# the first time); needs a display.
paint: setup painter
	@test -n "$$DISPLAY$$WAYLAND_DISPLAY" || { echo "make paint needs a display (DISPLAY or WAYLAND_DISPLAY); make demo runs without one"; exit 1; }
	mkdir -p $(OUT)
	test -e $(OUT)/scene.octo || $(PAINTER) import traces/scene.jsonl $(OUT)/scene.octo
	$(PAINTER) window $(OUT)/scene.octo

# Export timings against OpenVDB's own writer (docs/benchmarks.md, "Exports");
# Debian's python3 for its OpenVDB module.
bench-export: setup painter
	/usr/bin/python3 painter/bench/export_vs_openvdb.py

# The precision study's figures and tables (about 12 minutes), docs/precision/: the
# study in the reference, then the painter's GPU ray caster ray by ray.
precision: setup painter
	$(PY) -m octopaint_ref.precision --out docs/precision
	$(PY) -m octopaint_ref.cli gpu-probe --painter $(PAINTER) --out docs/precision
	$(PY) -m octopaint_ref.cli lit-precision --out docs/precision --lod 0,1,2 --scale 1,4

# The differentiable-rendering examples and their images, docs/examples/.
examples: setup
	$(PY) reference/examples/fit_leaves.py --out docs/examples
	$(PY) reference/examples/inverse_paint.py --out docs/examples

clean:
	rm -rf $(VENV) $(OUT) dist
