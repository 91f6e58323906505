//! Pages on the GPU grow with the tree: the last page is allocated at a
//! power of two of cells (at least FIRST_PAGE_CELLS) and replaced by a
//! larger copy of itself as the tree grows, so a small painting does not pay
//! for a whole page. What the pages held survives every growth, cells past
//! it read FREE, and a renderer that grew its pages frame by frame holds
//! the same cells, g3 and image as one that uploaded the tree at once.

mod common;

use common::*;
use octopaint_gpu::pools::{FIRST_PAGE_CELLS, GpuCell};
use octopaint_gpu::{Backend, Precision};
use octopaint_tree::g3::g3_table;
use octopaint_tree::paint::Painting;
use octopaint_tree::trace::{Brush, Camera, Canvas, Mode, Sample, Shape};

fn marked(i: u64) -> GpuCell {
    GpuCell { parent: i as u32, first_child: !(i as u32), rgbd: 0x0102_0304 ^ i as u32, sigma: i as f32 * 0.5 }
}

#[test]
fn the_last_page_grows_and_keeps_what_it_held() {
    let r = renderer(Backend::Auto);
    let gpu = &r.gpu;
    let mut pools = octopaint_gpu::pools::GpuPools::new(gpu).unwrap();
    let page = pools.page_cells();
    assert!(page >= 4 * FIRST_PAGE_CELLS, "a page of {page} cells (lavapipe's is 2^23)");

    assert!(pools.ensure(gpu, 1000).unwrap());
    assert_eq!(pools.cells_held(), FIRST_PAGE_CELLS);
    assert_eq!(pools.allocated_bytes(), FIRST_PAGE_CELLS * 32);
    assert!(!pools.ensure(gpu, FIRST_PAGE_CELLS).unwrap(), "it holds that many already");

    // Marked cells at the start and at the end of what the page holds, and
    // g3 rows beside them.
    let head: Vec<GpuCell> = (0..1000).map(marked).collect();
    let tail_at = FIRST_PAGE_CELLS - 7;
    let tail: Vec<GpuCell> = (tail_at..FIRST_PAGE_CELLS).map(marked).collect();
    pools.upload_cells(gpu, 0, &head);
    pools.upload_cells(gpu, tail_at, &tail);
    let rows: Vec<[u32; 4]> = (0..500u32).map(|i| [i, i * 3, !i, i ^ 0x2AAA_AAAA]).collect();
    pools.upload_g3(gpu, 10, &rows);

    // Grow within the first page (queued uploads land before the copy),
    // then past it: page 0 whole, page 1 at FIRST_PAGE_CELLS.
    let n = FIRST_PAGE_CELLS + 10;
    assert!(pools.ensure(gpu, n).unwrap());
    assert_eq!(pools.cells_held(), 2 * FIRST_PAGE_CELLS);
    let check = |pools: &octopaint_gpu::pools::GpuPools, n: u64| {
        let cells = pools.read_cells(gpu, n).unwrap();
        assert_eq!(cells.len() as u64, n);
        assert!(cells[..1000].iter().zip(&head).all(|(a, b)| a == b), "the head was lost");
        assert!(cells[tail_at as usize..FIRST_PAGE_CELLS as usize].iter().zip(&tail).all(|(a, b)| a == b), "the tail was lost");
        assert!(cells[1000..tail_at as usize].iter().chain(&cells[FIRST_PAGE_CELLS as usize..]).all(|c| *c == GpuCell::FREE));
        let g3 = pools.read_rows(gpu, n).unwrap();
        assert!(g3[10..510].iter().zip(&rows).all(|(a, b)| a == b), "the rows were lost");
        let fresh = [u32::MAX, u32::MAX, u32::MAX, octopaint_tree::normals::ZERO];
        assert!(g3[..10].iter().chain(&g3[510..]).all(|r| *r == fresh));
    };
    check(&pools, n);
    let n = page + 5;
    assert!(pools.ensure(gpu, n).unwrap());
    assert_eq!(pools.cells_held(), page + FIRST_PAGE_CELLS);
    check(&pools, n);
    // More than the pages can ever hold is refused, and nothing changes.
    assert!(pools.ensure(gpu, 4 * page + 1).is_err());
    assert_eq!(pools.cells_held(), page + FIRST_PAGE_CELLS);
}

#[test]
fn a_renderer_that_grew_its_pages_holds_what_a_fresh_one_does() {
    // Paint past FIRST_PAGE_CELLS with the renderer following stroke by
    // stroke, so its last page is replaced while it holds the tree.
    let canvas = Canvas { roots: [2, 2, 2], max_depth: 12, root_size: 1.0, capacity: 1 << 22 };
    let mut painting = Painting::new(&canvas);
    let mut r = renderer(Backend::Auto);
    let mut held = Vec::new();
    let mut k = 0;
    while u64::from(painting.tree.n_used()) <= FIRST_PAGE_CELLS + FIRST_PAGE_CELLS / 4 {
        let c = [(k * 37 % 100) as f64 / 100.0, (k * 61 % 100) as f64 / 100.0, 0.4];
        painting.begin_stroke(&Brush::new(Shape::Sphere, Mode::Paint, 0.03, c, 0.8, 0.5));
        for i in 0..20 {
            let u = i as f64 / 19.0;
            painting.add_sample(&Sample::at([0.2 + 1.6 * u, 0.2 + 0.05 * k as f64, 0.3 + 0.02 * k as f64]), 0);
        }
        painting.end_stroke();
        r.sync(&mut painting.tree).unwrap();
        held.push(r.pools.cells_held());
        k += 1;
        assert!(k < 400, "the painting stopped growing at {} cells", painting.tree.n_used());
    }
    assert!(held.first() < held.last(), "the pages never grew: {held:?}");
    let n = u64::from(painting.tree.n_used());
    let camera = Camera { eye: [1.0, 1.0, 3.5], q: [0.0, 0.0, 0.0, 1.0], fov: [-0.5, 0.5, 0.4, -0.4], size: [96, 64], background: [0.1, 0.1, 0.1] };
    let grown_image = r.cast(&painting.tree, &camera, Precision::F32).unwrap();
    let grown_cells = r.pools.read_cells(&r.gpu, n).unwrap();
    assert!(r.read_g3(&mut painting.tree).unwrap() == g3_table(&painting.tree), "g3 after the pages grew");
    let mut fresh = renderer(Backend::Auto);
    assert_eq!(fresh.render(&mut painting.tree, &camera, Precision::F32).unwrap(), grown_image);
    assert!(fresh.pools.read_cells(&fresh.gpu, n).unwrap() == grown_cells);
    assert!(grown_image.chunks(3).any(|p| p != &grown_image[..3]), "the image is one colour");
}
