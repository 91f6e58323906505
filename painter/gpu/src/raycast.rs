//! The ray caster (docs/spec.md 6, 7): one invocation per pixel, writing
//! 8-bit sRGB. Shader: shaders/raycast.wgsl (f32, and f16 where the adapter
//! has SHADER_F16); CPU port: painter/tree/src/raycast/, whose
//! [`RayParams`] the host computes for both.

use bytemuck::{Pod, Zeroable};
use octopaint_tree::raycast::RayParams;

use crate::context::{Gpu, GpuError};
use crate::digest::ImageDigest;
use crate::pools::{GpuPools, read_buffer, read_through};
use crate::shaders::{Precision, raycast_source};

/// shaders/raycast.wgsl `RayParams`, as uploaded (a layout test compares
/// them through naga).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct RayParamsGpu {
    pub eye_cell: [u32; 4],
    pub eye_rel: [f32; 4],
    pub roots: [u32; 4],
    pub extent: [f32; 4],
    pub extent_max: [u32; 4],
    pub tan_fov: [f32; 4],
    pub rot0: [f32; 4],
    pub rot1: [f32; 4],
    pub rot2: [f32; 4],
    pub background: [f32; 4],
    pub misc: [u32; 4],
    pub flags: [u32; 4],
    pub grid: [f32; 4],
    pub light: [f32; 4],
    pub shade: [f32; 4],
    pub lod: [f32; 4],
}

impl RayParamsGpu {
    /// The uniform for `p`, with the cells the pages hold.
    pub fn from_params(p: &RayParams, cells_held: u32) -> Self {
        let row = |r: [f32; 3]| [r[0], r[1], r[2], 0.0];
        RayParamsGpu {
            eye_cell: [p.eye_cell[0], p.eye_cell[1], p.eye_cell[2], p.width],
            eye_rel: [p.eye_rel[0], p.eye_rel[1], p.eye_rel[2], p.lattice_unit],
            roots: [p.roots[0], p.roots[1], p.roots[2], p.max_depth],
            extent: [p.extent[0], p.extent[1], p.extent[2], 0.0],
            extent_max: [p.extent_max[0], p.extent_max[1], p.extent_max[2], cells_held],
            tan_fov: p.tan_fov,
            rot0: row(p.rot[0]),
            rot1: row(p.rot[1]),
            rot2: row(p.rot[2]),
            background: [p.background[0], p.background[1], p.background[2], 0.0],
            misc: [p.height, p.max_steps, p.n_roots, u32::from(p.inside)],
            flags: [u32::from(p.skip_invalid), 0, 0, 0],
            grid: p.grid,
            light: p.light,
            shade: [p.ambient, 0.0, 0.0, 0.0],
            lod: [p.forward[0], p.forward[1], p.forward[2], p.lod],
        }
    }
}

/// The most layers a document has (spec 14.1), and the shader's table.
pub const MAX_LAYERS: usize = 16;

/// shaders/raycast.wgsl `LayerTable`: the contributing layers of a document
/// (spec 6.2), whose pools lie one after the other in the pages: per layer
/// its first cell and its opacity (f32 bits); `count[0]` the layers.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct LayerTableGpu {
    pub count: [u32; 4],
    pub at: [[u32; 4]; MAX_LAYERS],
}

impl LayerTableGpu {
    /// The table of layers at `bases` (first cells) with `opacity`.
    pub fn new(bases: &[u32], opacity: &[f32]) -> Self {
        assert!(bases.len() <= MAX_LAYERS && bases.len() == opacity.len());
        let mut t = LayerTableGpu::zeroed();
        t.count[0] = bases.len() as u32;
        for (k, (&b, &o)) in bases.iter().zip(opacity).enumerate() {
            t.at[k] = [b, o.to_bits(), 0, 0];
        }
        t
    }
}

/// Words of one ray's probe record (shaders/raycast.wgsl `PROBE_WORDS`).
pub const PROBE_WORDS: u64 = 20;

/// One ray as the ray caster traced it, from the shader's probe record
/// (docs/precision.md, "The GPU's f16"): where it stopped and why, and
/// where it started. Points are in the frame of their cell (centre 0, edge
/// 1), the shader's `real` values widened to f32 (exactly).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProbeRecord {
    /// Why the ray stopped: 1 left the canvas, 2 opaque, 3 lost, 4 step
    /// limit (shaders/raycast.wgsl).
    pub status: u32,
    /// Cells crossed.
    pub steps: u32,
    /// The last cell crossed, its depth and lattice origin.
    pub cell: u32,
    pub depth: u32,
    pub origin: [u32; 3],
    /// Where the ray left the last cell.
    pub exit: [f32; 3],
    /// The ray's direction as the shader computed it (f32, unit length).
    pub dir: [f32; 3],
    /// The cell the ray started in, and the start point in its frame.
    pub start_depth: u32,
    pub start_origin: [u32; 3],
    pub start: [f32; 3],
}

impl ProbeRecord {
    fn from_words(w: &[u32]) -> Self {
        let u3 = |k: usize| [w[k], w[k + 1], w[k + 2]];
        let f3 = |k: usize| u3(k).map(f32::from_bits);
        ProbeRecord {
            status: w[0],
            steps: w[1],
            cell: w[2],
            depth: w[3],
            origin: u3(4),
            exit: f3(7),
            dir: f3(10),
            start_depth: w[13],
            start_origin: u3(14),
            start: f3(17),
        }
    }
}

/// Precision, lighting mode, layered, level of detail on.
type PipelineKey = (Precision, u32, bool, bool);

pub struct RayCaster {
    /// One shader module per precision the adapter has.
    modules: Vec<(Precision, wgpu::ShaderModule)>,
    layout: wgpu::PipelineLayout,
    page_shift: u32,
    /// Pipelines made so far, per precision, lighting mode (the shader's
    /// `LIT`: 0 unlit, 1 lit, 2 with shadow rays) and entry point (`main`
    /// for one tree, `main_layers` for a document's layers) and whether
    /// it walks a level of detail's cut (`LOD`), each compiled on first use.
    pipelines: Vec<(PipelineKey, wgpu::ComputePipeline)>,
    layout_params: wgpu::BindGroupLayout,
    params: wgpu::Buffer,
    layers: wgpu::Buffer,
    /// The pixel buffers casts write, by slot (made on first use), and
    /// the slot the next cast writes ([`RayCaster::cast_into`]).
    pixels: Vec<Option<(u64, wgpu::Buffer)>>,
    slot: usize,
    /// A mappable buffer images are read back through, kept between
    /// reads (a frame captured at headset size every frame: making one
    /// each time cost more than the copy).
    readback: Option<(u64, wgpu::Buffer)>,
    /// The digest pass, made on first use.
    digest: Option<ImageDigest>,
}

impl RayCaster {
    pub fn new(gpu: &Gpu, pools: &GpuPools) -> RayCaster {
        let uniform = |binding| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::Buffer { ty: wgpu::BufferBindingType::Uniform, has_dynamic_offset: false, min_binding_size: None },
            count: None,
        };
        let layout_params = gpu.device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("ray params"),
            entries: &[
                uniform(0),
                wgpu::BindGroupLayoutEntry {
                    binding: 1,
                    visibility: wgpu::ShaderStages::COMPUTE,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Storage { read_only: false },
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    count: None,
                },
                uniform(2),
            ],
        });
        let layout = gpu.device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("ray caster"),
            bind_group_layouts: &[Some(&pools.layout_cells), Some(&pools.layout_g3_ro), Some(&layout_params)],
            immediate_size: 0,
        });
        let mut modules = Vec::new();
        for precision in [Precision::F32, Precision::F16] {
            if !gpu.supports(precision) {
                continue;
            }
            let module = gpu.device.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some("raycast.wgsl"),
                source: wgpu::ShaderSource::Wgsl(raycast_source(precision).into()),
            });
            modules.push((precision, module));
        }
        let params = gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("ray params"),
            size: std::mem::size_of::<RayParamsGpu>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let layers = gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("layer table"),
            size: std::mem::size_of::<LayerTableGpu>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut caster = RayCaster {
            modules,
            layout,
            page_shift: pools.page_shift,
            pipelines: Vec::new(),
            layout_params,
            params,
            layers,
            pixels: vec![None],
            slot: 0,
            readback: None,
            digest: None,
        };
        // The unlit one-tree pipelines now; others when first asked for.
        for precision in [Precision::F32, Precision::F16] {
            let _ = caster.pipeline(gpu, precision, (0, false, false));
        }
        caster
    }

    /// The pipeline for `precision` and `(lit, layered, lod)`: lighting
    /// mode `lit`, one tree or a document's `layered` march, and a level
    /// of detail's cut or none, compiled on first use.
    fn pipeline(&mut self, gpu: &Gpu, precision: Precision, (lit, layered, lod): (u32, bool, bool)) -> Result<wgpu::ComputePipeline, GpuError> {
        if let Some((_, p)) = self.pipelines.iter().find(|(k, _)| *k == (precision, lit, layered, lod)) {
            return Ok(p.clone());
        }
        let module = self.modules.iter().find(|(p, _)| *p == precision).map(|(_, m)| m).ok_or(GpuError::NoF16)?;
        let pipeline = gpu.device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("ray caster"),
            layout: Some(&self.layout),
            module,
            entry_point: Some(if layered { "main_layers" } else { "main" }),
            compilation_options: wgpu::PipelineCompilationOptions {
                constants: &[("PAGE_SHIFT", f64::from(self.page_shift)), ("LIT", f64::from(lit)), ("LOD", f64::from(u8::from(lod)))],
                zero_initialize_workgroup_memory: false,
            },
            cache: None,
        });
        self.pipelines.push(((precision, lit, layered, lod), pipeline.clone()));
        Ok(pipeline)
    }

    /// The casts that follow write pixel buffer `slot` (0 until this is
    /// called), made on first use: a front end that shows several images
    /// (the headset's two eyes) keeps each one's last cast, to present it
    /// again without casting.
    pub fn cast_into(&mut self, slot: usize) {
        if self.pixels.len() <= slot {
            self.pixels.resize_with(slot + 1, || None);
        }
        self.slot = slot;
    }

    fn pixels(&mut self, gpu: &Gpu, n: u64) -> wgpu::Buffer {
        match &self.pixels[self.slot] {
            Some((size, buf)) if *size >= n * 4 => buf.clone(),
            _ => {
                let buf = gpu.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("pixels"),
                    size: (n * 4).max(4),
                    usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                    mapped_at_creation: false,
                });
                self.pixels[self.slot] = Some((n * 4, buf.clone()));
                buf
            }
        }
    }

    /// Encode the ray cast of one image into `enc`; the pixels stay on the
    /// GPU until [`RayCaster::read_image`].
    pub fn encode(&mut self, gpu: &Gpu, pools: &GpuPools, enc: &mut wgpu::CommandEncoder, params: &RayParams, precision: Precision) -> Result<(), GpuError> {
        self.encode_words(gpu, pools, enc, params, precision, false, None)
    }

    /// [`RayCaster::encode`] for the layers of a document whose pools lie
    /// in the pages as `table` says (spec 6.2): one layer at opacity 1 (at
    /// cell 0) through the one-tree `main` (its image, spec 14.6), any other
    /// set through `main_layers`.
    pub fn encode_layers(
        &mut self,
        gpu: &Gpu,
        pools: &GpuPools,
        enc: &mut wgpu::CommandEncoder,
        params: &RayParams,
        precision: Precision,
        table: &LayerTableGpu,
    ) -> Result<(), GpuError> {
        let one_tree = table.count[0] == 1 && table.at[0][0] == 0 && f32::from_bits(table.at[0][1]) == 1.0;
        self.encode_words(gpu, pools, enc, params, precision, false, (!one_tree).then_some(table))
    }

    #[allow(clippy::too_many_arguments)]
    fn encode_words(
        &mut self,
        gpu: &Gpu,
        pools: &GpuPools,
        enc: &mut wgpu::CommandEncoder,
        params: &RayParams,
        precision: Precision,
        probe: bool,
        table: Option<&LayerTableGpu>,
    ) -> Result<(), GpuError> {
        let pipeline = self.pipeline(gpu, precision, (params.lit, table.is_some(), params.lod > 0.0))?;
        let n = u64::from(params.width) * u64::from(params.height);
        let words = if probe { n * PROBE_WORDS } else { n };
        // One binding holds every pixel (or record): refuse what the device
        // cannot bind before asking it to (wgpu would panic).
        let limits = gpu.device.limits();
        let limit = limits.max_storage_buffer_binding_size.min(limits.max_buffer_size);
        if words * 4 > limit {
            let what = if probe { "probe records" } else { "pixels" };
            return Err(GpuError::TooBig(format!(
                "an image of {}x{} needs {} bytes of {what}; this GPU binds at most {limit} bytes ({:.1} megapixels)",
                params.width,
                params.height,
                words * 4,
                limit as f64 / 4e6 / if probe { PROBE_WORDS as f64 } else { 1.0 }
            )));
        }
        let pixels = self.pixels(gpu, words);
        let held = pools.cells_held().min(u64::from(u32::MAX)) as u32;
        let mut uniform = RayParamsGpu::from_params(params, held);
        uniform.flags[1] = u32::from(probe);
        gpu.queue.write_buffer(&self.params, 0, bytemuck::bytes_of(&uniform));
        gpu.queue.write_buffer(&self.layers, 0, bytemuck::bytes_of(table.unwrap_or(&LayerTableGpu::zeroed())));
        let group = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("ray params"),
            layout: &self.layout_params,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: self.params.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 1, resource: pixels.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 2, resource: self.layers.as_entire_binding() },
            ],
        });
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("ray cast"), timestamp_writes: None });
        pass.set_pipeline(&pipeline);
        pass.set_bind_group(0, &pools.group_cells, &[]);
        pass.set_bind_group(1, &pools.group_g3_ro, &[]);
        pass.set_bind_group(2, &group, &[]);
        pass.dispatch_workgroups(params.width.div_ceil(8), params.height.div_ceil(8), 1);
        Ok(())
    }

    /// Trace every pixel's ray of `params` and read back each ray's probe
    /// record, row by row from the top. Refused (before any GPU work)
    /// when the records would not fit one storage binding of the device.
    pub fn probe(&mut self, gpu: &Gpu, pools: &GpuPools, params: &RayParams, precision: Precision) -> Result<Vec<ProbeRecord>, GpuError> {
        let bytes = u64::from(params.width) * u64::from(params.height) * PROBE_WORDS * 4;
        let mut enc = gpu.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("ray probe") });
        self.encode_words(gpu, pools, &mut enc, params, precision, true, None)?;
        gpu.queue.submit([enc.finish()]);
        let buf = self.cast_pixels()?;
        let raw = read_buffer(gpu, buf, bytes)?;
        let words: Vec<u32> = raw.chunks_exact(4).map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect();
        Ok(words.chunks_exact(PROBE_WORDS as usize).map(ProbeRecord::from_words).collect())
    }

    /// The buffer the last cast wrote, or an error when nothing was cast.
    fn cast_pixels(&self) -> Result<&wgpu::Buffer, GpuError> {
        self.pixel_buffer().ok_or_else(|| GpuError::Readback("nothing was cast".into()))
    }

    /// The buffer the last image was cast into: one u32 per pixel, sRGB
    /// bytes r | g << 8 | b << 16, row 0 at the top (a window draws it).
    pub fn pixel_buffer(&self) -> Option<&wgpu::Buffer> {
        self.pixels[self.slot].as_ref().map(|(_, b)| b)
    }

    /// The digest of the last image cast (`digest::rgb_digest` of what
    /// [`RayCaster::read_image`] would return), computed on the GPU: 8 bytes
    /// a workgroup come back instead of the image.
    pub fn image_digest(&mut self, gpu: &Gpu, width: u32, height: u32) -> Result<u64, GpuError> {
        let buf = self.cast_pixels()?.clone();
        let count = u32::try_from(u64::from(width) * u64::from(height))
            .map_err(|_| GpuError::Readback(format!("an image of {width}x{height} has too many pixels for a digest")))?;
        self.digest.get_or_insert_with(|| ImageDigest::new(gpu)).digest(gpu, &buf, count)
    }

    /// The last image cast, `width·height·3` bytes of sRGB, row 0 at the top.
    pub fn read_image(&mut self, gpu: &Gpu, width: u32, height: u32) -> Result<Vec<u8>, GpuError> {
        let buf = self.cast_pixels()?.clone();
        let size = u64::from(width) * u64::from(height) * 4;
        if size == 0 {
            return Ok(Vec::new());
        }
        let staging = match &self.readback {
            Some((s, b)) if *s >= size => b.clone(),
            _ => {
                let b = gpu.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("image read-back"),
                    size,
                    usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                    mapped_at_creation: false,
                });
                self.readback = Some((size, b.clone()));
                b
            }
        };
        read_through(gpu, &buf, size, &staging, |raw| {
            let mut out = vec![0u8; raw.len() / 4 * 3];
            for (o, p) in out.chunks_exact_mut(3).zip(raw.chunks_exact(4)) {
                o.copy_from_slice(&p[..3]);
            }
            out
        })
    }
}
