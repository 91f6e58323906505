//! Drawing a cast image into a colour target: a full-screen triangle whose
//! fragment shader reads the ray caster's pixel buffer (one u32 per pixel,
//! sRGB bytes r | g << 8 | b << 16). The desktop window draws it into its
//! surface, the VR session into each eye's swapchain layer. sRGB targets
//! get the bytes decoded (the hardware encodes them again on store); other
//! targets take them as they are.

use crate::Gpu;

const BLIT: &str = r#"
struct Blit { width: u32, height: u32, decode: u32, pad: u32 };
@group(0) @binding(0) var<uniform> blit: Blit;
@group(0) @binding(1) var<storage, read> pixels: array<u32>;

@vertex fn vs(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
    let p = vec2<f32>(f32((i << 1u) & 2u), f32(i & 2u));
    return vec4<f32>(p * 2.0 - 1.0, 0.0, 1.0);
}

fn to_linear(c: f32) -> f32 {
    if c <= 0.04045 { return c / 12.92; }
    return pow((c + 0.055) / 1.055, 2.4);
}

@fragment fn fs(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<f32> {
    let x = min(u32(pos.x), blit.width - 1u);
    let y = min(u32(pos.y), blit.height - 1u);
    let v = pixels[y * blit.width + x];
    var c = vec3<f32>(f32(v & 255u), f32((v >> 8u) & 255u), f32((v >> 16u) & 255u)) / 255.0;
    if blit.decode == 1u { c = vec3<f32>(to_linear(c.r), to_linear(c.g), to_linear(c.b)); }
    return vec4<f32>(c, 1.0);
}
"#;

/// The blit pipeline for one target format.
pub struct Blit {
    pipeline: wgpu::RenderPipeline,
    layout: wgpu::BindGroupLayout,
    format: wgpu::TextureFormat,
}

impl Blit {
    pub fn new(gpu: &Gpu, format: wgpu::TextureFormat) -> Blit {
        let device = &gpu.device;
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor { label: Some("blit"), source: wgpu::ShaderSource::Wgsl(BLIT.into()) });
        let layout = gpu.params_layout("blit", wgpu::ShaderStages::FRAGMENT, true);
        let pl = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor { label: Some("blit"), bind_group_layouts: &[Some(&layout)], immediate_size: 0 });
        let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("blit"),
            layout: Some(&pl),
            vertex: wgpu::VertexState { module: &module, entry_point: Some("vs"), buffers: &[], compilation_options: Default::default() },
            fragment: Some(wgpu::FragmentState {
                module: &module,
                entry_point: Some("fs"),
                targets: &[Some(wgpu::ColorTargetState { format, blend: None, write_mask: wgpu::ColorWrites::ALL })],
                compilation_options: Default::default(),
            }),
            primitive: wgpu::PrimitiveState::default(),
            depth_stencil: None,
            multisample: wgpu::MultisampleState::default(),
            multiview_mask: None,
            cache: None,
        });
        Blit { pipeline, layout, format }
    }

    /// The bind group that draws `pixels` (a `width × height` image).
    pub fn bind(&self, gpu: &Gpu, pixels: &wgpu::Buffer, width: u32, height: u32) -> wgpu::BindGroup {
        let uniform = gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("blit"),
            size: 16,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        gpu.queue.write_buffer(&uniform, 0, bytemuck::cast_slice(&[width, height, u32::from(self.format.is_srgb()), 0]));
        gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("blit"),
            layout: &self.layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: uniform.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 1, resource: pixels.as_entire_binding() },
            ],
        })
    }

    /// Draw into a pass whose target has this pipeline's format.
    pub fn draw(&self, pass: &mut wgpu::RenderPass<'_>, group: &wgpu::BindGroup) {
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, group, &[]);
        pass.draw(0..3, 0..1);
    }
}
