//! Images out of the GPU: 8-bit RGB PNG (spec 6), written atomically like
//! the dumps (replay's renders, the window's screenshots, the headset's
//! captures), and texels read back from a colour target as RGB.

use std::path::Path;

/// Encode `rgb` (`width·height·3` bytes, row 0 at the top) as PNG.
pub fn png_bytes(rgb: &[u8], width: u32, height: u32) -> Vec<u8> {
    let mut out = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut out, width, height);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        let mut writer = enc.write_header().expect("writing to memory cannot fail");
        writer.write_image_data(rgb).expect("the image has width·height·3 bytes");
    }
    out
}

pub fn write_png(path: &Path, rgb: &[u8], width: u32, height: u32) -> std::io::Result<()> {
    octopaint_platform::durable::write(path, &png_bytes(rgb, width, height))
}

/// Rows of 4-byte texels read back from a texture of `format` (each row
/// padded to `row` bytes, as copies to buffers require) as packed RGB.
pub fn texels_to_rgb(raw: &[u8], row: u32, size: [u32; 2], format: wgpu::TextureFormat) -> Vec<u8> {
    let bgra = matches!(format, wgpu::TextureFormat::Bgra8Unorm | wgpu::TextureFormat::Bgra8UnormSrgb);
    let mut out = Vec::with_capacity(size[0] as usize * size[1] as usize * 3);
    for y in 0..size[1] as usize {
        for p in raw[y * row as usize..][..size[0] as usize * 4].chunks_exact(4) {
            out.extend_from_slice(&if bgra { [p[2], p[1], p[0]] } else { [p[0], p[1], p[2]] });
        }
    }
    out
}

/// One layer of a colour target copied into a buffer by a frame's own
/// encoder, to be read back as RGB once that frame is submitted (the
/// window's screenshot, the headset's capture of each eye).
pub struct Capture {
    buffer: wgpu::Buffer,
    /// Bytes per row in the buffer: the texture's rows padded to 256.
    row: u32,
    size: [u32; 2],
    format: wgpu::TextureFormat,
}

impl Capture {
    /// Encode the copy of array layer `layer` of `texture` (`size`, a
    /// 4-byte `format`) into `enc`.
    pub fn encode(
        gpu: &crate::Gpu,
        enc: &mut wgpu::CommandEncoder,
        texture: &wgpu::Texture,
        layer: u32,
        size: [u32; 2],
        format: wgpu::TextureFormat,
    ) -> Capture {
        let row = (size[0] * 4).div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT) * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
        let buffer = gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("capture"),
            size: u64::from(row) * u64::from(size[1]),
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        enc.copy_texture_to_buffer(
            wgpu::TexelCopyTextureInfo { texture, mip_level: 0, origin: wgpu::Origin3d { x: 0, y: 0, z: layer }, aspect: wgpu::TextureAspect::All },
            wgpu::TexelCopyBufferInfo { buffer: &buffer, layout: wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(row), rows_per_image: None } },
            wgpu::Extent3d { width: size[0], height: size[1], depth_or_array_layers: 1 },
        );
        Capture { buffer, row, size, format }
    }

    /// The layer as packed RGB, row 0 at the top; call after the encoder
    /// was submitted.
    pub fn rgb(&self, gpu: &crate::Gpu) -> Result<Vec<u8>, crate::GpuError> {
        let raw = crate::pools::read_buffer(gpu, &self.buffer, u64::from(self.row) * u64::from(self.size[1]))?;
        Ok(texels_to_rgb(&raw, self.row, self.size, self.format))
    }
}
