//! The g3 pass (docs/spec.md 3.3-3.5): recompute g3 for every cell of the
//! regions the neighbour mask marks. Shader: shaders/g3.wgsl; CPU port:
//! painter/octree/src/g3.rs.

use bytemuck::{Pod, Zeroable};
use octopaint_tree::dirty::{NeighbourMask, REGIONS, region_cells};

use crate::context::Gpu;
use crate::pools::GpuPools;
use crate::shaders::g3_source;

const WORKGROUP: u32 = 64;

/// shaders/g3.wgsl `G3Params` (a layout test compares them through naga).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct G3Params {
    pub roots: [u32; 3],
    pub region_cells: u32,
    pub n_regions: u32,
    pub chunks: u32,
    pub n_cells: u32,
    pub row: u32,
    pub base: u32,
    pub layer_cells: u32,
    pub _pad: [u32; 2],
}

pub struct G3Pass {
    pipeline: wgpu::ComputePipeline,
    params: wgpu::Buffer,
    regions: wgpu::Buffer,
    group: wgpu::BindGroup,
}

impl G3Pass {
    pub fn new(gpu: &Gpu, pools: &GpuPools) -> G3Pass {
        let module =
            gpu.device.create_shader_module(wgpu::ShaderModuleDescriptor { label: Some("g3.wgsl"), source: wgpu::ShaderSource::Wgsl(g3_source().into()) });
        let layout_params = gpu.params_layout("g3 params", wgpu::ShaderStages::COMPUTE, true);
        let layout = gpu.device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("g3 pass"),
            bind_group_layouts: &[Some(&pools.layout_cells), Some(&pools.layout_g3_rw), Some(&layout_params)],
            immediate_size: 0,
        });
        let page_shift = f64::from(pools.page_shift);
        let pipeline = gpu.device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("g3 pass"),
            layout: Some(&layout),
            module: &module,
            entry_point: Some("main"),
            compilation_options: wgpu::PipelineCompilationOptions { constants: &[("PAGE_SHIFT", page_shift)], zero_initialize_workgroup_memory: false },
            cache: None,
        });
        let params = gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("g3 params"),
            size: std::mem::size_of::<G3Params>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let regions = gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("dirty regions"),
            size: (REGIONS * 4) as u64,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let group = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("g3 params"),
            layout: &layout_params,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: params.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 1, resource: regions.as_entire_binding() },
            ],
        });
        G3Pass { pipeline, params, regions, group }
    }

    /// Encode the pass over the regions `mask` marks (none: nothing is
    /// encoded). `capacity` is the trace's cell budget, which fixes the
    /// region size (spec 3.5). Returns the number of regions processed.
    pub fn encode(&self, gpu: &Gpu, pools: &GpuPools, enc: &mut wgpu::CommandEncoder, mask: &NeighbourMask, capacity: u32, roots: [u32; 3]) -> u32 {
        let all = pools.cells_held().min(u64::from(u32::MAX)) as u32;
        self.encode_layer(gpu, pools, enc, mask, capacity, roots, 0, all)
    }

    /// [`G3Pass::encode`] for a layer of a document whose cells lie at
    /// `base..base + layer_cells` of the pages (spec 6.2). The parameters
    /// are written to one buffer when the queue next submits: one call per
    /// submission.
    #[allow(clippy::too_many_arguments)]
    pub fn encode_layer(
        &self,
        gpu: &Gpu,
        pools: &GpuPools,
        enc: &mut wgpu::CommandEncoder,
        mask: &NeighbourMask,
        capacity: u32,
        roots: [u32; 3],
        base: u32,
        layer_cells: u32,
    ) -> u32 {
        let regions: Vec<u32> = (0..REGIONS as u32).filter(|&r| mask.get(r as usize)).collect();
        if regions.is_empty() {
            return 0;
        }
        let size = region_cells(capacity);
        let chunks = size.div_ceil(WORKGROUP);
        let total = regions.len() as u64 * u64::from(chunks);
        let max = u64::from(gpu.limits.max_compute_workgroups_per_dimension);
        let row = total.min(max) as u32;
        let rows = total.div_ceil(u64::from(row)) as u32;
        let params = G3Params {
            roots,
            region_cells: size,
            n_regions: regions.len() as u32,
            chunks,
            n_cells: pools.cells_held().min(u64::from(u32::MAX)) as u32,
            row,
            base,
            layer_cells,
            _pad: [0; 2],
        };
        gpu.queue.write_buffer(&self.params, 0, bytemuck::bytes_of(&params));
        gpu.queue.write_buffer(&self.regions, 0, bytemuck::cast_slice(&regions));
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("g3 pass"), timestamp_writes: None });
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &pools.group_cells, &[]);
        pass.set_bind_group(1, &pools.group_g3_rw, &[]);
        pass.set_bind_group(2, &self.group, &[]);
        pass.dispatch_workgroups(row, rows, 1);
        regions.len() as u32
    }
}
