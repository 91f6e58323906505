//! Voxel sets (spec 15.1): voxels at one depth with their colour and
//! density, as an `import` event carries them. Reading and writing their
//! `.npz` files is octopaint-trace's; painting them, the tree's.

/// The most voxels one set may hold (spec 15.1).
pub const MAX_VOXELS: u64 = 1 << 26;

/// A voxel set (spec 15.1): voxels at depth `depth`, in any order.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct VoxelSet {
    pub depth: u32,
    pub ijk: Vec<[u32; 3]>,
    pub rgb: Vec<[u8; 3]>,
    pub sigma: Vec<f32>,
}

impl VoxelSet {
    pub fn len(&self) -> usize {
        self.ijk.len()
    }

    pub fn is_empty(&self) -> bool {
        self.ijk.is_empty()
    }
}
