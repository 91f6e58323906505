//! Drawing a cast image into a colour target: a full-screen triangle whose
//! fragment shader reads the ray caster's pixel buffer (one u32 per pixel,
//! sRGB bytes r | g << 8 | b << 16). The desktop window draws it into its
//! surface, the VR session into each eye's swapchain layer. sRGB targets
//! get the bytes decoded (the hardware encodes them again on store); other
//! targets take them as they are.

use crate::Gpu;

/// The blit shader (validated by the layout tests with naga).
pub const BLIT_WGSL: &str = r#"
struct Blit { width: u32, height: u32, decode: u32, pad: u32, dest: vec2<f32>, pad2: vec2<f32> };
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

fn texel(x: i32, y: i32) -> vec3<f32> {
    let cx = u32(clamp(x, 0, i32(blit.width) - 1));
    let cy = u32(clamp(y, 0, i32(blit.height) - 1));
    let v = pixels[cy * blit.width + cx];
    return vec3<f32>(f32(v & 255u), f32((v >> 8u) & 255u), f32((v >> 16u) & 255u)) / 255.0;
}

// The image stretched over the target, bilinear between texel centres
// (an image of the target's size maps texel for texel: the weights are 0).
@fragment fn fs(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<f32> {
    let f = pos.xy * vec2<f32>(f32(blit.width), f32(blit.height)) / blit.dest - 0.5;
    let i = vec2<i32>(floor(f));
    let w = f - floor(f);
    let top = mix(texel(i.x, i.y), texel(i.x + 1, i.y), w.x);
    let bottom = mix(texel(i.x, i.y + 1), texel(i.x + 1, i.y + 1), w.x);
    var c = mix(top, bottom, w.y);
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
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor { label: Some("blit"), source: wgpu::ShaderSource::Wgsl(BLIT_WGSL.into()) });
        let layout = gpu.params_layout("blit", wgpu::ShaderStages::FRAGMENT, true);
        let pl =
            device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor { label: Some("blit"), bind_group_layouts: &[Some(&layout)], immediate_size: 0 });
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

    /// The bind group that draws `pixels` (a `width × height` image) onto
    /// a target of the same size.
    pub fn bind(&self, gpu: &Gpu, pixels: &wgpu::Buffer, width: u32, height: u32) -> wgpu::BindGroup {
        self.bind_scaled(gpu, pixels, [width, height], [width, height])
    }

    /// The bind group that draws `pixels` (an image of `size`) stretched
    /// over a target of `target` pixels (the window's dynamic resolution).
    pub fn bind_scaled(&self, gpu: &Gpu, pixels: &wgpu::Buffer, size: [u32; 2], target: [u32; 2]) -> wgpu::BindGroup {
        let uniform = gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("blit"),
            size: 32,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut words = [size[0], size[1], u32::from(self.format.is_srgb()), 0, 0, 0, 0, 0];
        words[4] = (target[0].max(1) as f32).to_bits();
        words[5] = (target[1].max(1) as f32).to_bits();
        gpu.queue.write_buffer(&uniform, 0, bytemuck::cast_slice(&words));
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
