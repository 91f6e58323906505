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
