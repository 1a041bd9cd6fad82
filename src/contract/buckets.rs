//! What the `bucket_accumulate` kernel returns (both backends, and the CPU's streaming path).

/// Per voxel and for each of its two dominant clusters: the sample count and the channel sums in
/// 8.8 fixed point (value << 8).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Buckets {
    pub counts: Vec<u32>,
    pub sums: Vec<u32>,
}
