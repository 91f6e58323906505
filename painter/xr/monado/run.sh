#!/usr/bin/env bash
# Run an octopaint command against Monado's simulated headset (docs/vr.md).
#
#   painter/xr/monado/run.sh xr-info
#   painter/xr/monado/run.sh ARGS...        # any `octopaint ARGS...`
#
# The current folder is bind-mounted at /work inside the chroot and the
# command runs there, so relative paths in ARGS work.
#
# Debian 12 has no usable Monado; Debian 13 ships Monado 25. The first run
# makes a Debian 13 chroot with debootstrap (about a minute; needs root and
# network) with monado-service, the OpenXR loader and Mesa's Vulkan
# drivers, in $OCTOPAINT_XR_CHROOT (default /opt/octopaint-xr/trixie). Each
# run copies the painter built on this host into it, starts monado-service
# with a simulated HMD and controllers and a null compositor on lavapipe
# (XRT_COMPOSITOR_NULL=1 SIMULATED_ENABLE=1), runs the command inside, and
# stops the service. The command's exit status is the script's.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
painter_dir="$(dirname "$(dirname "$here")")"
root="${OCTOPAINT_XR_CHROOT:-/opt/octopaint-xr/trixie}"
bin="$painter_dir/target/release/octopaint"
[ -x "$bin" ] || { echo "build the painter first: cargo build --release (in painter/)" >&2; exit 1; }

if [ ! -x "$root/usr/bin/monado-service" ]; then
    command -v debootstrap >/dev/null || DEBIAN_FRONTEND=noninteractive apt-get install -y -qq debootstrap >/dev/null
    echo "making the Debian 13 chroot in $root (once)" >&2
    mkdir -p "$root"
    debootstrap --variant=minbase trixie "$root" http://deb.debian.org/debian >/dev/null
    chroot "$root" /bin/sh -c 'apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends monado-service libopenxr1-monado libopenxr-loader1 mesa-vulkan-drivers libvulkan1 >/dev/null'
fi

mounted=()
cleanup() {
    [ -n "${monado:-}" ] && kill "$monado" 2>/dev/null && wait "$monado" 2>/dev/null || true
    for m in "${mounted[@]}"; do umount "$m" 2>/dev/null || umount -l "$m" 2>/dev/null || true; done
}
trap cleanup EXIT
for d in proc sys dev dev/shm; do
    mkdir -p "$root/$d"
    if ! mountpoint -q "$root/$d"; then
        mount --bind "/$d" "$root/$d"
        mounted=("$root/$d" "${mounted[@]}")
    fi
done

# The caller's folder is /work inside: relative paths in ARGS work.
mkdir -p "$root/work"
mount --bind "$PWD" "$root/work"
mounted=("$root/work" "${mounted[@]}")
mkdir -p "$root/opt/octopaint"
cp "$bin" "$root/opt/octopaint/octopaint"
run_dir=/run/octopaint-xr
rm -rf "$root$run_dir" && mkdir -p "$root$run_dir" && chmod 0700 "$root$run_dir"
env_common=(XDG_RUNTIME_DIR="$run_dir" NODEVICE_SELECT=1 XR_RUNTIME_JSON=/usr/share/openxr/1/openxr_monado.json)
chroot "$root" env "${env_common[@]}" XRT_COMPOSITOR_NULL=1 SIMULATED_ENABLE=1 XRT_NO_STDIN=1 \
    /usr/bin/monado-service > "$root$run_dir/monado.log" 2>&1 &
monado=$!
for _ in $(seq 1 100); do
    [ -S "$root$run_dir/monado_comp_ipc" ] && break
    kill -0 "$monado" 2>/dev/null || { echo "monado-service stopped:" >&2; cat "$root$run_dir/monado.log" >&2; exit 1; }
    sleep 0.1
done
[ -S "$root$run_dir/monado_comp_ipc" ] || { echo "monado-service did not start:" >&2; cat "$root$run_dir/monado.log" >&2; exit 1; }
set +e
chroot "$root" /bin/sh -c 'cd /work && exec env "$@"' sh "${env_common[@]}" /opt/octopaint/octopaint "$@"
status=$?
set -e
exit $status
