//! Every struct the GPU reads exists once in WGSL and once in Rust: their
//! sizes and member offsets must agree (naga computes the WGSL layout).

use octopaint_gpu::g3::G3Params;
use octopaint_gpu::pools::{GpuCell, GpuRow};
use octopaint_gpu::raycast::RayParamsGpu;
use octopaint_gpu::shaders::{Precision, g3_source, raycast_source};

/// (size, member offsets) of a WGSL struct.
fn wgsl_layout(source: &str, name: &str) -> (u32, Vec<(String, u32)>) {
    let module = naga::front::wgsl::parse_str(source).unwrap();
    let mut layouter = naga::proc::Layouter::default();
    layouter.update(module.to_ctx()).unwrap();
    for (handle, ty) in module.types.iter() {
        if ty.name.as_deref() == Some(name)
            && let naga::TypeInner::Struct { members, span } = &ty.inner
        {
            let offsets = members.iter().map(|m| (m.name.clone().unwrap(), m.offset)).collect();
            assert_eq!(layouter[handle].size, *span);
            return (*span, offsets);
        }
    }
    panic!("no struct {name}");
}

macro_rules! offsets {
    ($t:ty, $($f:ident),*) => {
        vec![$((stringify!($f).to_string(), std::mem::offset_of!($t, $f) as u32)),*]
    };
}

#[test]
fn cell_layout_agrees() {
    let (size, offsets) = wgsl_layout(&g3_source(), "Cell");
    assert_eq!(size as usize, std::mem::size_of::<GpuCell>());
    assert_eq!(offsets, offsets!(GpuCell, parent, first_child, rgbd, sigma));
}

#[test]
fn row_layout_agrees() {
    // g3 and the shading vector's word beside every cell: the array stride
    // of the row pages, in the g3 pass that writes them and the ray cast
    // that reads them.
    for source in [g3_source(), raycast_source(Precision::F32), raycast_source(Precision::F16)] {
        let (size, offsets) = wgsl_layout(&source, "Row");
        assert_eq!(size as usize, std::mem::size_of::<GpuRow>());
        assert_eq!(offsets, offsets!(GpuRow, g3, shade));
    }
}

#[test]
fn g3_params_layout_agrees() {
    let (size, offsets) = wgsl_layout(&g3_source(), "G3Params");
    assert_eq!(size as usize, std::mem::size_of::<G3Params>());
    assert_eq!(offsets, offsets!(G3Params, roots, region_cells, n_regions, chunks, n_cells, row, base, layer_cells));
}

#[test]
fn ray_params_layout_agrees() {
    for precision in [Precision::F32, Precision::F16] {
        let (size, offsets) = wgsl_layout(&raycast_source(precision), "RayParams");
        assert_eq!(size as usize, std::mem::size_of::<RayParamsGpu>());
        assert_eq!(
            offsets,
            offsets!(RayParamsGpu, eye_cell, eye_rel, roots, extent, extent_max, tan_fov, rot0, rot1, rot2, background, misc, flags, grid, light, shade, lod)
        );
    }
}

#[test]
fn layer_table_layout_agrees() {
    for precision in [Precision::F32, Precision::F16] {
        let (size, offsets) = wgsl_layout(&raycast_source(precision), "LayerTable");
        assert_eq!(size as usize, std::mem::size_of::<octopaint_gpu::raycast::LayerTableGpu>());
        assert_eq!(offsets, offsets!(octopaint_gpu::raycast::LayerTableGpu, count, at));
    }
}

#[test]
fn the_blit_shader_is_valid_wgsl() {
    let module =
        naga::front::wgsl::parse_str(octopaint_gpu::blit::BLIT_WGSL).unwrap_or_else(|e| panic!("{}", e.emit_to_string(octopaint_gpu::blit::BLIT_WGSL)));
    naga::valid::Validator::new(naga::valid::ValidationFlags::all(), naga::valid::Capabilities::empty()).validate(&module).unwrap();
}
