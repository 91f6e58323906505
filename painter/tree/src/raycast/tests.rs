use super::*;
use crate::lattice::Lattice;
use crate::trace::Camera;
use crate::trace::Canvas;

fn params() -> RayParams {
    let lat = Lattice::new(&Canvas { roots: [4, 4, 4], max_depth: 25, root_size: 10_000.0, capacity: 1 << 20 });
    let camera = Camera { eye: [0.0; 3], q: [0.0, 0.0, 0.0, 1.0], fov: [-0.5, 0.5, 0.4, -0.4], size: [8, 6], background: [0.1, 0.2, 0.3] };
    RayParams::new(&lat, &camera)
}

#[test]
fn the_grid_spacing_follows_the_eye_height_and_the_eye_is_reduced() {
    assert_eq!(params().grid, [0.0; 4]);
    assert_eq!(params().with_grid([0.25, 1.15, -3.5]).grid, [0.25, 1.15, 6.5, 1.0]);
    assert_eq!(params().with_grid([12_345.625, 40.0, 7.0]).grid, [45.625, 40.0, 7.0, 10.0]);
    let g = params().with_grid([0.0, 0.05, 0.0]).grid;
    assert!((g[3] - 0.01).abs() < 1e-9, "{g:?}");
    // At or below the floor, or not finite: no grid.
    for h in [0.0, -2.0, f64::NAN, f64::INFINITY] {
        assert_eq!(params().with_grid([1.0, h, 1.0]).grid[3], 0.0, "{h}");
    }
}

#[test]
fn without_the_grid_a_ray_leaving_everything_sees_the_background() {
    let p = params();
    for dir in [[0.0, -1.0, 0.0], [0.6, 0.0, -0.8], [0.0, 1.0, 0.0]] {
        assert_eq!(ground(&p, dir), p.background);
    }
    let g = p.with_grid([0.5, 2.0, 0.5]);
    // Straight up: the sky; straight down: the floor, tinted.
    assert_eq!(ground(&g, [0.0, 1.0, 0.0]), g.background);
    let down = ground(&g, [0.0, -1.0, 0.0]);
    assert!(down.iter().zip(g.background).all(|(a, b)| *a > b), "{down:?}");
}

#[test]
fn lod_lists_are_read_and_bad_ones_refused() {
    assert_eq!(parse_lods("0,1,0.5").unwrap(), vec![("0".into(), 0.0), ("1".into(), 1.0), ("0.5".into(), 0.5)]);
    for bad in ["", "abc", "-1", "1,1", "1,1.0", "65", "nan", "inf", "1e3", ".5", "1.", "0x1", "1,,2"] {
        assert!(parse_lods(bad).is_err(), "{bad:?} accepted");
    }
    assert!(check_lod(f64::NAN).is_err() && check_lod(-0.5).is_err() && check_lod(MAX_LOD).is_ok());
}

#[test]
fn lam_follows_the_pixel_pitch_and_is_capped() {
    let lat = Lattice::new(&Canvas { roots: [4, 4, 4], max_depth: 25, root_size: 10_000.0, capacity: 1 << 20 });
    let mut camera = Camera { eye: [0.0; 3], q: [0.0, 0.0, 0.0, 1.0], fov: [-0.5, 0.5, 0.4, -0.4], size: [800, 600], background: [0.0; 3] };
    let p = RayParams::new(&lat, &camera);
    assert_eq!(p.lod, 0.0);
    assert_eq!(p.forward, [0.0, 0.0, -1.0]);
    let alpha = (2.0 * 0.5f64.tan() / 800.0).max(2.0 * 0.4f64.tan() / 600.0);
    assert_eq!(p.with_lod(&camera, 1.0).lod, alpha as f32);
    // Half the resolution: twice the pitch, a coarser cut.
    camera.size = [400, 300];
    assert_eq!(RayParams::new(&lat, &camera).with_lod(&camera, 1.0).lod, (2.0 * alpha) as f32);
    assert_eq!(RayParams::new(&lat, &camera).with_lod(&camera, 0.0).lod, 0.0);
    camera.size = [2, 2];
    assert_eq!(RayParams::new(&lat, &camera).with_lod(&camera, MAX_LOD).lod, 1.0);
}
