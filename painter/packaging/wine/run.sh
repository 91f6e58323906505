#!/usr/bin/env bash
# Run a Windows program under Wine, in a prefix made for the painter's tests
# (docs/windows.md):
#
#   painter/packaging/wine/run.sh PROGRAM.exe [ARGS...]
#
# The prefix (OCTOPAINT_WINEPREFIX, default ~/.cache/octopaint-wine: Wine
# wants a prefix its user owns) is made on
# first use (wineboot, ~15 s) and given the bcryptprimitives.dll stand-in
# Rust programs need on Wine 8. Wine's own messages are silenced
# (WINEDEBUG=-all unless set); the program's output, exit status and
# working folder are its own. Needs Debian's wine64 and
# gcc-mingw-w64-x86-64 (make system installs them).
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
wine=${OCTOPAINT_WINE:-/usr/lib/wine/wine64}
export WINEPREFIX=${OCTOPAINT_WINEPREFIX:-${XDG_CACHE_HOME:-$HOME/.cache}/octopaint-wine}
export WINEARCH=win64 WINEDEBUG=${WINEDEBUG:--all}
# No Wine pop-ups asking to install Mono or Gecko (nothing here needs them).
export WINEDLLOVERRIDES=${WINEDLLOVERRIDES:-mscoree,mshtml=}
test -x "$wine" || { echo "run.sh: no Wine at $wine (Debian: apt-get install wine64)" >&2; exit 127; }
shim="$WINEPREFIX/drive_c/windows/system32/bcryptprimitives.dll"
if [ ! -f "$shim" ]; then
  (
    # One maker at a time: tests start several Wine programs at once.
    mkdir -p "$(dirname "$WINEPREFIX")"
    exec 9>"$WINEPREFIX.lock"
    flock 9
    if [ ! -f "$shim" ]; then
      "$wine" wineboot -i >/dev/null 2>&1 || true
      test -d "$WINEPREFIX/drive_c/windows/system32" || { echo "run.sh: wineboot made no prefix in $WINEPREFIX" >&2; exit 1; }
      # The wineserver must finish writing the registry before the next start.
      "$(dirname "$wine")/wineserver" -w 2>/dev/null || wineserver -w 2>/dev/null || true
      x86_64-w64-mingw32-gcc -shared -O2 -o "$shim.tmp" "$here/bcryptprimitives.c" "$here/bcryptprimitives.def" -ladvapi32
      mv "$shim.tmp" "$shim"
    fi
  )
fi
exec "$wine" "$@"
