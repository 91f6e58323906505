//! `octopaint render` as a user meets it: a turntable writes N PNG frames of
//! the size asked and an animated GIF of the same N frames (read back by
//! the `image` crate's decoder), consecutive frames differ, frame 0 is the
//! default single picture, the CPU port draws what the GPU draws, and bad
//! arguments are refused before anything is written.

use std::path::{Path, PathBuf};
use std::process::Command;

use image::AnimationDecoder;

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn octopaint() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_octopaint"));
    c.env("NODEVICE_SELECT", "1");
    c
}

fn png(path: &Path) -> (u32, u32, Vec<u8>) {
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!(info.color_type, png::ColorType::Rgb);
    buf.truncate(info.buffer_size());
    (info.width, info.height, buf)
}

fn document(scratch: &Path) -> PathBuf {
    let doc = scratch.join("s.octo");
    let res = octopaint().arg("import").arg(repo().join("traces/shapes_modes.jsonl")).arg(&doc).output().unwrap();
    assert!(res.status.success(), "{}", String::from_utf8_lossy(&res.stderr));
    doc
}

/// `octopaint render DOC --size 160x120 ARGS` into `out`: its RGB bytes.
fn small_picture(doc: &Path, out: &Path, args: &[&str]) -> Vec<u8> {
    let res = octopaint().arg("render").arg(doc).args(["--size", "160x120", "--quiet", "--out"]).arg(out).args(args).output().unwrap();
    assert!(res.status.success(), "{args:?}: {}", String::from_utf8_lossy(&res.stderr));
    png(out).2
}

#[test]
fn a_turntable_writes_its_frames_and_a_gif_of_them() {
    let scratch = tempfile::tempdir().unwrap();
    let doc = document(scratch.path());
    let out = scratch.path().join("tt");
    let res = octopaint().arg("render").arg(&doc).args(["--turntable", "6", "--size", "96x64", "--frame-ms", "80", "--out"]).arg(&out).output().unwrap();
    assert!(res.status.success(), "{}", String::from_utf8_lossy(&res.stderr));
    let mut names: Vec<String> = std::fs::read_dir(&out).unwrap().map(|e| e.unwrap().file_name().into_string().unwrap()).collect();
    names.sort();
    assert_eq!(names, ["frame-000.png", "frame-001.png", "frame-002.png", "frame-003.png", "frame-004.png", "frame-005.png", "turntable.gif"]);
    let frames: Vec<Vec<u8>> = (0..6)
        .map(|k| {
            let (w, h, rgb) = png(&out.join(format!("frame-{k:03}.png")));
            assert_eq!((w, h), (96, 64));
            rgb
        })
        .collect();
    // The painting is in the picture (not only background), and it turns.
    let background = &frames[0][..3];
    assert!(frames[0].chunks_exact(3).filter(|p| p != &background).count() > 100);
    for k in 0..6 {
        let (a, b) = (&frames[k], &frames[(k + 1) % 6]);
        let differ = a.chunks_exact(3).zip(b.chunks_exact(3)).filter(|(p, q)| p != q).count();
        assert!(differ > 50, "frames {k} and {} differ in {differ} pixels", (k + 1) % 6);
    }
    // The GIF: 6 frames of 96x64, each shown 80 ms, close to its PNG (a
    // GIF has 256 colours a frame).
    let gif = image::codecs::gif::GifDecoder::new(std::io::BufReader::new(std::fs::File::open(out.join("turntable.gif")).unwrap())).unwrap();
    let decoded = gif.into_frames().collect_frames().unwrap();
    assert_eq!(decoded.len(), 6);
    for (k, f) in decoded.iter().enumerate() {
        assert_eq!(f.buffer().dimensions(), (96, 64));
        assert_eq!(f.delay().numer_denom_ms(), (80, 1));
        let far = f.buffer().pixels().zip(frames[k].chunks_exact(3)).filter(|(g, p)| (0..3).any(|c| (i32::from(g.0[c]) - i32::from(p[c])).abs() > 48)).count();
        assert!(far < 96 * 64 / 50, "GIF frame {k}: {far} pixels far from the PNG");
    }

    // Frame 0 is the default single picture; the CPU port draws it too.
    let one = scratch.path().join("one.png");
    let res = octopaint().arg("render").arg(&doc).args(["--size", "96x64", "--quiet", "--out"]).arg(&one).output().unwrap();
    assert!(res.status.success(), "{}", String::from_utf8_lossy(&res.stderr));
    assert_eq!(png(&one).2, frames[0]);
    let cpu = scratch.path().join("cpu.png");
    let res = octopaint().arg("render").arg(&doc).args(["--size", "96x64", "--renderer", "cpu", "--quiet", "--out"]).arg(&cpu).output().unwrap();
    assert!(res.status.success(), "{}", String::from_utf8_lossy(&res.stderr));
    let off = png(&cpu).2.iter().zip(&frames[0]).map(|(a, b)| (i32::from(*a) - i32::from(*b)).abs()).max().unwrap();
    assert!(off <= 1, "the CPU port is {off} steps from the GPU");
}

#[test]
fn the_ground_grid_draws_behind_the_painting_alike_on_gpu_and_cpu() {
    let scratch = tempfile::tempdir().unwrap();
    let doc = document(scratch.path());
    let shot = |name: &str, args: &[&str]| small_picture(&doc, &scratch.path().join(name), args);
    let plain = shot("plain.png", &[]);
    let grid = shot("grid.png", &["--grid"]);
    let cpu = shot("grid_cpu.png", &["--grid", "--renderer", "cpu"]);
    // The grid lightens background pixels (lines, the floor's tint, the
    // horizon) and leaves the painting's pixels nearly alone.
    let background = [plain[0], plain[1], plain[2]];
    let (mut lit, mut kept) = (0, 0);
    for (p, g) in plain.chunks_exact(3).zip(grid.chunks_exact(3)) {
        if p == background {
            lit += usize::from(g[0] > p[0] + 20);
        } else {
            kept += usize::from(p.iter().zip(g).all(|(a, b)| b.abs_diff(*a) <= 40));
        }
    }
    assert!(lit > 400, "{lit} background pixels show grid lines");
    let painted = plain.chunks_exact(3).filter(|p| *p != background).count();
    assert!(kept * 10 >= painted * 9, "{kept} of {painted} painted pixels kept their colour");
    let off = cpu.iter().zip(&grid).map(|(a, b)| a.abs_diff(*b)).max().unwrap();
    assert!(off <= 1, "the CPU port's grid is {off} steps from the GPU's");
}

#[test]
fn lighting_shades_the_painting_alike_on_gpu_and_cpu() {
    let scratch = tempfile::tempdir().unwrap();
    let doc = document(scratch.path());
    let shot = |name: &str, args: &[&str]| small_picture(&doc, &scratch.path().join(name), args);
    let plain = shot("plain.png", &[]);
    let lit = shot("lit.png", &["--lit"]);
    let shadows = shot("shadows.png", &["--shadows"]);
    let off = shot("off.png", &["--light", r#"{"on": false}"#]);
    let cpu = shot("shadows_cpu.png", &["--shadows", "--renderer", "cpu"]);
    assert_eq!(plain, off, "a light that is off draws the unlit picture");
    let changed = plain.chunks_exact(3).zip(lit.chunks_exact(3)).filter(|(a, b)| a.iter().zip(*b).any(|(x, y)| x.abs_diff(*y) > 8)).count();
    assert!(changed > 200, "lighting changed {changed} pixels");
    // Shadow rays only take light away.
    assert!(lit.iter().zip(&shadows).all(|(a, b)| b <= a), "a shadowed pixel is brighter than lit");
    let worst = cpu.iter().zip(&shadows).map(|(a, b)| a.abs_diff(*b)).max().unwrap();
    assert!(worst <= 2, "the CPU port's lit picture is {worst} steps from the GPU's");
}

#[test]
fn a_camera_from_a_trace_renders_at_its_size() {
    let scratch = tempfile::tempdir().unwrap();
    let doc = document(scratch.path());
    let out = scratch.path().join("cam.png");
    let camera = r#"{"eye": [0.5, 0.5, 2.5], "q": [0, 0, 0, 1], "fov": [-0.4, 0.4, 0.3, -0.3], "size": [40, 30], "background": [1, 0, 0]}"#;
    let res = octopaint().arg("render").arg(&doc).args(["--camera", camera, "--out"]).arg(&out).output().unwrap();
    assert!(res.status.success(), "{}", String::from_utf8_lossy(&res.stderr));
    let (w, h, rgb) = png(&out);
    assert_eq!((w, h), (40, 30));
    // The corner sees the red background.
    assert_eq!(&rgb[..3], &[255, 0, 0]);
}

#[test]
fn bad_arguments_are_refused_before_anything_is_written() {
    let scratch = tempfile::tempdir().unwrap();
    let doc = document(scratch.path());
    let out = scratch.path().join("out");
    let cases: [(&[&str], &str); 12] = [
        (&["--turntable", "0"], "--turntable 0"),
        (&["--turntable", "4000"], "from 1 to 3600"),
        (&["--turntable", "3", "--elevation", "95"], "--elevation 95"),
        (&["--turntable", "3", "--elevation", "NaN"], "--elevation NaN"),
        (&["--turntable", "3", "--frame-ms", "5"], "--frame-ms 5"),
        (&["--size", "0x10"], "--size \"0x10\""),
        (&["--size", "100"], "expected WxH"),
        (&["--camera", "{\"eye\": [0, 0, \"x\"]}"], "--camera: eye"),
        (&["--camera", "{"], "--camera: not JSON"),
        (&["--light", "{\"dir\": [0, 0, 0]}"], "--light: dir: zero"),
        (&["--light", "{\"dir\": [0, 1, 0], \"intensity\": 99}"], "--light: intensity"),
        (&["--light", "[1, 2]"], "--light: expected a JSON object"),
    ];
    for (args, says) in cases {
        let res = octopaint().arg("render").arg(&doc).args(args).arg("--out").arg(&out).output().unwrap();
        let err = String::from_utf8_lossy(&res.stderr);
        assert_eq!(res.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(says), "{args:?}: {err}");
        assert!(!out.exists(), "{args:?} wrote {}", out.display());
    }
    // A missing document, and --camera with --turntable (clap's refusal).
    let res = octopaint().arg("render").arg(scratch.path().join("none.octo")).arg("--out").arg(&out).output().unwrap();
    assert_eq!(res.status.code(), Some(2));
    let res = octopaint().arg("render").arg(&doc).args(["--turntable", "3", "--camera", "{}", "--out"]).arg(&out).output().unwrap();
    assert_eq!(res.status.code(), Some(2));
    // --elevation without --turntable is refused rather than ignored.
    let res = octopaint().arg("render").arg(&doc).args(["--elevation", "10", "--out"]).arg(&out).output().unwrap();
    assert_eq!(res.status.code(), Some(2));
    assert!(!out.exists());
    // A single picture into an existing folder is refused; the folder is untouched.
    std::fs::create_dir(&out).unwrap();
    let res = octopaint().arg("render").arg(&doc).arg("--out").arg(&out).output().unwrap();
    assert_eq!(res.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&res.stderr).contains("is a folder"));
    assert_eq!(std::fs::read_dir(&out).unwrap().count(), 0);
}
