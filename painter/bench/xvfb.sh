# Sourced by the window benchmarks (window_frames.sh, window_engine.sh):
# a virtual X server for this script's life, and a private XDG runtime
# folder for the painter. Needs $out (the run's folder, absolute); sets
# DISPLAY and $runtime, and stops the server and removes the folder on exit.
runtime="$(mktemp -d)"
chmod 700 "$runtime"
Xvfb -displayfd 3 -noreset -screen 0 1280x800x24 -nolisten tcp 3>"$out/display" 2>/dev/null &
xvfb=$!
trap 'kill $xvfb 2>/dev/null; rm -rf "$runtime"' EXIT
for _ in $(seq 100); do [ -s "$out/display" ] && break; sleep 0.1; done
[ -s "$out/display" ] || { echo "Xvfb did not start" >&2; exit 1; }
export DISPLAY=":$(head -1 "$out/display")"
