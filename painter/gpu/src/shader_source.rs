// The WGSL each pipeline compiles, assembled from shaders/ (one file per
// stage, shared structs in shaders/shared/). Included by build.rs, which
// validates every variant with naga so that a shader error fails the build,
// and by the crate, which compiles the same text.

/// The ray caster's precision for positions and exit distances.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Precision {
    F32,
    F16,
}

pub const POOLS_WGSL: &str = include_str!("../../../shaders/shared/pools.wgsl");
pub const G3_WGSL: &str = include_str!("../../../shaders/g3.wgsl");
pub const RAYCAST_WGSL: &str = include_str!("../../../shaders/raycast.wgsl");
pub const DIGEST_WGSL: &str = include_str!("../../../shaders/digest.wgsl");

/// The g3 pass: the pools, then the stage.
pub fn g3_source() -> String {
    format!("{POOLS_WGSL}\n{G3_WGSL}")
}

/// The ray caster in a precision: a prelude naming `real`, the pools, the
/// stage.
pub fn raycast_source(precision: Precision) -> String {
    let prelude = match precision {
        Precision::F32 => "alias real = f32;\n",
        Precision::F16 => "enable f16;\nalias real = f16;\n",
    };
    format!("{prelude}{POOLS_WGSL}\n{RAYCAST_WGSL}")
}
