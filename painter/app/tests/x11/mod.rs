//! What the window's tests share: an X server (Xvfb) of their own, real
//! input through xdotool, the window's process and its frame log.

#![allow(dead_code)]

use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

pub fn octopaint() -> Command {
    Command::new(env!("CARGO_BIN_EXE_octopaint"))
}

pub struct Xvfb(Child, #[allow(dead_code)] std::sync::MutexGuard<'static, ()>);

/// One X server at a time in this process: the tests run in parallel
/// threads, and two software-rendered windows at once on two cores slow
/// each other past their timeouts.
static ONE_AT_A_TIME: std::sync::Mutex<()> = std::sync::Mutex::new(());

impl Drop for Xvfb {
    /// SIGTERM, so that the server removes its socket and lock file
    /// (SIGKILL leaves them in /tmp); SIGKILL after two seconds.
    fn drop(&mut self) {
        let _ = Command::new("kill").arg(self.0.id().to_string()).status();
        let t0 = Instant::now();
        while t0.elapsed() < Duration::from_secs(2) {
            if let Ok(Some(_)) = self.0.try_wait() {
                return;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

pub fn need(tool: &str) {
    let found = std::env::var_os("PATH").is_some_and(|p| std::env::split_paths(&p).any(|d| d.join(tool).is_file()));
    assert!(found, "{tool} is missing: install xvfb and xdotool (make system does)");
}

pub fn wait_for(what: &str, timeout: Duration, mut ok: impl FnMut() -> bool) {
    let t0 = Instant::now();
    while !ok() {
        assert!(t0.elapsed() < timeout, "timed out waiting for {what}");
        std::thread::sleep(Duration::from_millis(100));
    }
}

pub fn xdotool(display: &str, args: &[&str]) -> String {
    let out = Command::new("xdotool").args(args).env("DISPLAY", display).output().unwrap();
    assert!(out.status.success(), "xdotool {args:?}: {}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8_lossy(&out.stdout).trim().to_string()
}

pub fn start_xvfb() -> (Xvfb, String) {
    need("Xvfb");
    need("xdotool");
    let guard = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    // Xvfb picks a free display number itself and writes it to its stdout
    // (-displayfd 1) once it accepts connections. -noreset: by default an X
    // server resets when its last client leaves, and refuses connections
    // meanwhile; a painter that connected just as the test's first
    // `xdotool search` left failed so (1 run in 20).
    let mut child = Command::new("Xvfb")
        .args(["-displayfd", "1", "-noreset", "-screen", "0", "1024x768x24", "-nolisten", "tcp"])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let stdout = child.stdout.take().unwrap();
    let x = Xvfb(child, guard);
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let mut line = String::new();
        let _ = std::io::BufRead::read_line(&mut std::io::BufReader::new(stdout), &mut line);
        let _ = tx.send(line);
    });
    let line = rx.recv_timeout(Duration::from_secs(20)).expect("Xvfb did not start within 20 s");
    let n: u32 = line.trim().parse().unwrap_or_else(|_| panic!("Xvfb wrote {line:?} instead of its display number"));
    (x, format!(":{n}"))
}

/// An 800x600 RGB PNG's pixels.
pub fn read_rgb(path: &std::path::Path) -> Vec<u8> {
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!((info.width, info.height), (800, 600));
    buf
}

/// The X window id of the painter's visible window, once it shows. A
/// painter that exits first, or a window that does not show within a
/// minute, fails the test with everything the painter printed.
pub fn window_of(child: &mut Child, display: &str, what: &str) -> String {
    let t0 = Instant::now();
    loop {
        let out = Command::new("xdotool").args(["search", "--onlyvisible", "--name", "octopaint"]).env("DISPLAY", display).output().unwrap();
        if let Some(id) = String::from_utf8_lossy(&out.stdout).lines().next() {
            return id.to_string();
        }
        let exited = child.try_wait().unwrap();
        if exited.is_none() && t0.elapsed() < Duration::from_secs(60) {
            std::thread::sleep(Duration::from_millis(100));
            continue;
        }
        if exited.is_none() {
            let _ = child.kill();
            let _ = child.wait();
        }
        let all = Command::new("xdotool").args(["search", "--name", "octopaint"]).env("DISPLAY", display).output().unwrap();
        let mut log = String::new();
        let _ = std::io::Read::read_to_string(child.stderr.as_mut().unwrap(), &mut log);
        panic!(
            "no {what} after {:.1} s (painter {}); windows named octopaint, visible or not: {:?}; the painter printed:\n{log}",
            t0.elapsed().as_secs_f64(),
            match exited {
                Some(st) => format!("exited: {st}"),
                None => "still running, killed".to_string(),
            },
            String::from_utf8_lossy(&all.stdout).trim()
        );
    }
}

/// A scratch folder holding a 0700 runtime folder (what a desktop session
/// gives the painter) and a new document of one root, depth 10, `name`.
pub fn scratch_with_document(name: &str) -> (tempfile::TempDir, std::path::PathBuf, std::path::PathBuf) {
    let scratch = tempfile::tempdir().unwrap();
    let runtime = runtime_folder(scratch.path());
    let doc = scratch.path().join(name);
    let res = octopaint().arg("new").arg(&doc).args(["--roots", "1,1,1", "--max-depth", "10", "--root-size", "1", "--capacity", "1048576"]).output().unwrap();
    assert!(res.status.success(), "{}", String::from_utf8_lossy(&res.stderr));
    (scratch, runtime, doc)
}

/// Wait until the window has drawn a frame (its frame log has a line: the
/// event loop runs and the renderer is up) and holds the keyboard focus, so
/// that keys sent next are not lost on a loaded machine.
pub fn ready_for_keys(display: &str, id: &str, frame_log: &std::path::Path) {
    let t0 = Instant::now();
    loop {
        let frames = std::fs::read_to_string(frame_log).map(|l| l.lines().count()).unwrap_or(0);
        if frames >= 1 {
            xdotool(display, &["windowfocus", id]);
            if xdotool(display, &["getwindowfocus"]) == id {
                return;
            }
        }
        assert!(t0.elapsed() < Duration::from_secs(120), "the window drew no frame or took no focus in two minutes");
        std::thread::sleep(Duration::from_millis(100));
    }
}

/// Press M until the frame log's last frame shows the x plane on (its
/// `mirror` column: bit 0), or fail after a minute.
pub fn mirror_on(display: &str, frame_log: &std::path::Path) {
    let t0 = Instant::now();
    let mut sent: Option<Instant> = None;
    loop {
        let log = std::fs::read_to_string(frame_log).unwrap_or_default();
        let last = log.lines().last().and_then(|l| l.split(',').nth(6)).and_then(|m| m.parse::<u8>().ok());
        if last.is_some_and(|m| m & 1 == 1) {
            return;
        }
        assert!(t0.elapsed() < Duration::from_secs(60), "no frame showed the mirror plane a minute after M; frames:\n{log}");
        if sent.is_none_or(|t| t.elapsed() > Duration::from_secs(5)) {
            // A key sent twice toggles twice: send again only when the
            // last frame says it is still off, long after the first.
            xdotool(display, &["key", "m"]);
            sent = Some(Instant::now());
        }
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// Ctrl+Q, then wait (up to a minute) for the window's process to exit.
pub fn close_with_ctrl_q(display: &str, window: &mut Child) {
    xdotool(display, &["key", "ctrl+q"]);
    let t0 = Instant::now();
    while window.try_wait().unwrap().is_none() {
        assert!(t0.elapsed() < Duration::from_secs(60), "the window did not close on Ctrl+Q");
        std::thread::sleep(Duration::from_millis(100));
    }
}

/// A 0700 runtime folder in `scratch`, what a desktop session gives the
/// painter.
pub fn runtime_folder(scratch: &std::path::Path) -> std::path::PathBuf {
    let runtime = scratch.join("runtime");
    std::fs::create_dir(&runtime).unwrap();
    std::fs::set_permissions(&runtime, std::os::unix::fs::PermissionsExt::from_mode(0o700)).unwrap();
    runtime
}

/// `octopaint` on X display `display` with that runtime folder, its
/// errors piped.
pub fn on_display(display: &str, runtime: &std::path::Path) -> Command {
    let mut c = octopaint();
    c.env("DISPLAY", display).env("XDG_RUNTIME_DIR", runtime).env_remove("WAYLAND_DISPLAY").stderr(Stdio::piped());
    c
}
