//! Images at `render` events: 8-bit RGB PNG (spec 6), written atomically
//! like the dumps.

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
    octopaint_tree::dump::write_atomic(path, &png_bytes(rgb, width, height))
}
