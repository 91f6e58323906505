//! Octopaint's GPU pipeline on wgpu (docs/spec.md 3.3-3.5, 6, 7): the pools
//! on the GPU as storage buffers split into pages, uploads of staged
//! 65,536-cell blocks, the g3 pass over the regions the neighbour mask
//! marks, and cell-local ray casting into an image.
//!
//! | module | what it holds | shader | CPU port |
//! | --- | --- | --- | --- |
//! | [`context`] | adapter and device | | |
//! | [`pools`] | pools in pages, staged blocks, uploads, g3 read-back | shared/pools.wgsl | octree/src/pool/mod.rs |
//! | [`g3`] | the g3 pass | g3.wgsl | octree/src/g3.rs |
//! | [`raycast`] | the ray caster | raycast.wgsl | tree/src/raycast/ |
//! | [`digest`] | a cast image's 64-bit digest, for frame-by-frame comparisons | digest.wgsl | digest.rs (`rgb_digest`) |
//! | [`frame`] | one frame: uploads, mask, g3 pass, ray cast | | |
//! | [`blit`] | a cast image drawn into a colour target | (in blit.rs) | |
//! | [`image`] | PNG files, texels read back as RGB | | |

pub mod blit;
pub mod context;
pub mod digest;
pub mod frame;
pub mod g3;
pub mod image;
pub mod pools;
pub mod raycast;
pub mod shaders {
    //! The WGSL of every pipeline (validated by build.rs).
    include!("shader_source.rs");
}

pub use blit::Blit;
pub use context::{Backend, Gpu, GpuError};
pub use frame::Renderer;
pub use shaders::Precision;
