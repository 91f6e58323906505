"""The Windows painter under Wine, against the Linux painter (docs/windows.md).

`make test-windows` builds both and runs these; nothing here skips: a
missing binary, Wine or display is an error that says what to run.
"""

from __future__ import annotations

import os
import select
import shutil
import subprocess
import sys

import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
CONFORMANCE = os.path.dirname(HERE)
REPO = os.path.dirname(CONFORMANCE)
sys.path.insert(0, CONFORMANCE)
LINUX = os.path.join(REPO, "painter", "target", "release", "octopaint")
WINDOWS = os.environ.get("OCTOPAINT_WINDOWS_EXE") or os.path.join(
    REPO, "painter", "target", "x86_64-pc-windows-gnu", "release", "octopaint.exe"
)
WINE = os.path.join(REPO, "painter", "packaging", "wine", "run.sh")


class Program:
    """One build of the painter, run with the repository as its working
    folder (traces are passed as relative paths, so both builds print the
    same names).

    Under Wine a run that fails with no output at all is started once more:
    the painter never fails silently (every error path prints a message), so
    such a run never reached it. Wine's own messages are silenced, and once,
    in CI on a loaded machine, `info` right after a killed session's
    recovery exited 1 that way and passed when run again; the retry is
    reported on stderr."""

    def __init__(self, argv: list[str], env: dict[str, str], wine: bool = False):
        self.argv = argv
        self.env = env
        self.wine = wine

    def run(self, *args, ok: bool = True, timeout: float = 600, cwd: str = REPO) -> subprocess.CompletedProcess:
        def once():
            return subprocess.run(
                self.argv + [str(a) for a in args],
                cwd=cwd,
                env=self.env,
                capture_output=True,
                text=True,
                timeout=timeout,
            )

        r = once()
        if self.wine and r.returncode != 0 and r.stdout == r.stderr == "":
            print(f"wine: {args} exited {r.returncode} with no output; started once more", file=sys.stderr)
            r = once()
        if ok:
            assert r.returncode == 0, (self.argv[-1:], args, r.returncode, r.stdout, r.stderr)
        return r

    def popen(self, *args, **kw) -> subprocess.Popen:
        return subprocess.Popen(self.argv + [str(a) for a in args], cwd=REPO, env=self.env, **kw)


@pytest.fixture(scope="session")
def display():
    """An X display for Wine. Wine 8 reaches Vulkan only through its X11
    driver (winevulkan asks the graphics driver for its Vulkan functions),
    so the GPU under Wine needs a display even to render off screen; Xvfb
    gives it one."""
    if shutil.which("Xvfb") is None:
        raise FileNotFoundError("Xvfb is missing (apt-get install xvfb; make system installs it)")
    # Xvfb picks a free display number and writes it to stdout once it
    # accepts connections (-displayfd). -noreset: an X server resets when
    # its last client leaves and refuses connections meanwhile, so a Wine
    # program started just as the previous one left could not connect.
    proc = subprocess.Popen(
        ["Xvfb", "-displayfd", "1", "-noreset", "-screen", "0", "1024x768x24", "-nolisten", "tcp"],
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
    )
    ready, _, _ = select.select([proc.stdout], [], [], 20)
    line = proc.stdout.readline().decode().strip() if ready else ""
    if not line.isdigit():
        proc.kill()
        raise RuntimeError(f"Xvfb did not start within 20 s (it wrote {line!r})")
    n = int(line)
    yield f":{n}"
    # SIGTERM: Xvfb removes its lock file and socket, so the number is free
    # for the next run.
    proc.terminate()
    proc.wait()


@pytest.fixture(scope="session")
def linux():
    if not os.path.exists(LINUX):
        raise FileNotFoundError(f"{LINUX} is not built: run `make painter`")
    env = dict(os.environ)
    env.setdefault("NODEVICE_SELECT", "1")
    return Program([LINUX], env)


@pytest.fixture(scope="session")
def windows(display):
    if not os.path.exists(WINDOWS):
        raise FileNotFoundError(f"{WINDOWS} is not built: run `make painter-windows`")
    env = dict(os.environ)
    env["DISPLAY"] = display
    env.pop("XR_RUNTIME_JSON", None)
    program = Program([WINE, WINDOWS], env, wine=True)
    # The first start makes the Wine prefix (about 15 s); do it here, once.
    r = program.run("--version", timeout=300)
    assert r.stdout.startswith("octopaint "), r.stdout
    return program


def windows_path(path) -> str:
    """How a Windows program prints a path it built from a Unix one."""
    return str(path).replace("/", "\\")
