//! Structs shared between Rust and WGSL. Synthesis states hold, per voxel, its triple (3 words)
//! then its value (the mean of its three exemplar pixels, `pixel_words` words): stride
//! 3 + pixel_words.
//!
//! Each struct is `#[repr(C)]` + `Pod` with 4-byte scalar fields, or, first in the four
//! synthesis kernels' uniforms, one [`ExemplarFields`] (32 bytes, so WGSL's 16-byte alignment of
//! a struct member is C's offset 0), so WGSL's uniform layout matches C's. Each has its size
//! asserted at compile time and exposes `layout()` (field names and offsets) that `kernels-tests`
//! compares with naga's layout of the WGSL struct of the same name.

use super::level::LevelPack;
use bytemuck::{Pod, Zeroable};

macro_rules! gpu_struct {
    ($(#[$m:meta])* $name:ident size $size:literal { $($(#[$fm:meta])* $field:ident : $ty:ty),* $(,)? }) => {
        $(#[$m])*
        #[repr(C)]
        #[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
        pub struct $name { $($(#[$fm])* pub $field: $ty),* }
        const _: () = assert!(std::mem::size_of::<$name>() == $size);
        impl $name {
            /// Field names and byte offsets in declaration order.
            #[cfg(any(test, feature = "internals"))]
            pub fn layout() -> Vec<(&'static str, usize)> {
                vec![$((stringify!($field), std::mem::offset_of!($name, $field))),*]
            }
        }
    };
}

gpu_struct! {
    /// Uniforms of `wgsl/project.wgsl`.
    ProjectParams size 48 {
        width: u32, height: u32, channels: u32,
        /// `Border::code()`: 0 wrap, 1 mirror.
        border: u32,
        input_dims: u32, output_dims: u32, shift: u32,
        /// First pixel (row-major index) of this dispatch's chunk.
        first_pixel: u32,
        pixel_count: u32,
        /// u32 words per output vector (output_dims / 4 rounded up).
        words_per_vector: u32,
        /// Threads per row of the 2D dispatch grid.
        grid_stride: u32,
        _pad: u32,
    }
}

gpu_struct! {
    /// A level's exemplar fields, the first member of the four synthesis kernels' uniforms
    /// (`ExemplarFields` in wgsl/lib/synth_common.wgsl): built once per level, by [`Self::of`].
    ExemplarFields size 32 {
        /// Exemplar size in pixels.
        width: u32, height: u32,
        /// `Border::code()`: 0 wrap, 1 mirror.
        border: u32,
        /// Working channels (colour + feature) and u32 words per pixel (channels packed 4 per
        /// word).
        channels: u32, pixel_words: u32,
        /// Word offsets of each exemplar's pixels in the level data.
        pixels0: u32, pixels1: u32, pixels2: u32,
    }
}

impl ExemplarFields {
    /// The fields of `pack`'s level with exemplar border `border` (`Border::code()`).
    pub fn of(pack: &LevelPack, border: u32) -> ExemplarFields {
        ExemplarFields {
            width: pack.width,
            height: pack.height,
            border,
            channels: pack.channels,
            pixel_words: pack.pixel_words,
            pixels0: pack.offsets.pixels[0],
            pixels1: pack.offsets.pixels[1],
            pixels2: pack.offsets.pixels[2],
        }
    }

    /// Each exemplar's pixels' word offset.
    #[cfg(any(test, feature = "internals"))]
    pub fn pixels(&self) -> [u32; 3] {
        [self.pixels0, self.pixels1, self.pixels2]
    }
}

gpu_struct! {
    /// Uniforms of `wgsl/init.wgsl`: tiling of the candidate slab, warped by the jitter field.
    InitParams size 112 {
        ex: ExemplarFields,
        /// The level's stored bricks (word offset of the brick list in the brick index, count)
        /// and the threads per row of the 2D dispatch grid (one thread per voxel).
        list_offset: u32, list_count: u32, grid_stride: u32,
        /// Tileable solids: the level's period in voxels (a multiple of 4; 0: not periodic).
        period: u32,
        /// The source of the triples: 0, exemplar 0's candidate slab (the l_start level); n > 0,
        /// the coarse-level cache, a periodic n^3 volume of triples (binding 5, x fastest), read
        /// at the warped position plus the tile offset, modulo n (`--coarse-cache`, level L-1).
        cache_period: u32,
        seed_lo: u32, seed_hi: u32,
        /// 0: no jitter.
        jitter_on: u32,
        /// Offset added to the warped position before the lookup (slab tiling or cache).
        tile_x: u32, tile_y: u32, tile_z: u32,
        /// Word offset of exemplar 0's slab triples in the level data.
        slab_offset: u32,
        amp0: i32, amp1: i32, amp2: i32, amp3: i32,
        sig0: i32, sig1: i32, sig2: i32, sig3: i32,
    }
}

gpu_struct! {
    /// Uniforms of `wgsl/upsample.wgsl`: coordinate inheritance from the coarser level.
    UpsampleParams size 80 {
        /// The child level's exemplar (for the cached voxel value).
        ex: ExemplarFields,
        /// The parent level's brick grid (origin and size in bricks) and the word offset of its
        /// table, copied into the child's brick index.
        parent_grid_lo_x: i32, parent_grid_lo_y: i32, parent_grid_lo_z: i32,
        parent_grid_x: u32, parent_grid_y: u32, parent_grid_z: u32,
        parent_table: u32,
        /// The child's stored bricks (one thread per voxel).
        list_offset: u32, list_count: u32, grid_stride: u32,
        _r0: u32, _r1: u32,
    }
}

gpu_struct! {
    /// Uniforms of `wgsl/correct.wgsl`: one sub-pass over the voxels of one parity class in a
    /// list of bricks.
    CorrectParams size 208 {
        ex: ExemplarFields,
        /// The level's brick grid (origin and size in bricks) and the word offset of its table.
        grid_lo_x: i32, grid_lo_y: i32, grid_lo_z: i32,
        grid_x: u32, grid_y: u32, grid_z: u32,
        table_offset: u32,
        /// The sub-pass's bricks (8 threads per brick: its voxels of the class).
        list_offset: u32, list_count: u32,
        /// The parity class (x, y, z mod 2) of the voxels updated.
        class_x: u32, class_y: u32, class_z: u32,
        pca_in: u32, pca_out: u32, shift: u32, proj_words: u32,
        k2d: u32, k3d_used: u32, k3d_stride: u32,
        /// 0: 3D candidates (two-step search); 1: 2D candidates only (ablation).
        mode: u32,
        /// 1: one exemplar for all axes; sets 1 and 2 are rotations of set 0.
        shared_sets: u32,
        proj0: u32, proj1: u32, proj2: u32,
        mean0: u32, mean1: u32, mean2: u32,
        weights0: u32, weights1: u32, weights2: u32,
        cand2d0: u32, cand2d1: u32, cand2d2: u32,
        cand3d0: u32, cand3d1: u32, cand3d2: u32,
        counts0: u32, counts1: u32, counts2: u32,
        grid_stride: u32,
        /// Word offset of the sub-pass's voxel masks: one byte per listed brick (bit k: its
        /// class voxel k is needed), four per word.
        mask_offset: u32,
        /// Tileable solids: the level's period in voxels (0: not periodic); reads wrap.
        period: u32,
        /// Padding to a whole 16 bytes, as every uniform struct here.
        _r0: u32, _r1: u32,
    }
}

gpu_struct! {
    /// Uniforms of `wgsl/colorize.wgsl`: voxel colours of a list of bricks.
    ColorizeParams size 96 {
        ex: ExemplarFields,
        /// The finest level's brick grid and table (as in CorrectParams).
        grid_lo_x: i32, grid_lo_y: i32, grid_lo_z: i32,
        grid_x: u32, grid_y: u32, grid_z: u32,
        table_offset: u32,
        /// The output bricks (one thread per voxel; colours in list order, 64 per brick).
        list_offset: u32, list_count: u32, grid_stride: u32,
        /// Word offset of the `--color matched` table in the level data (`lazy::color_match`).
        match_table: u32,
        color_channels: u32,
        /// Per channel c, 4 bits at 4c: 0 the voxel's cached value (mean of its three pixels);
        /// a + 1 exemplar a's pixel; 4 the cached value mapped through the match table; 5 the
        /// fitted weighting of the three pixels (reads neighbours up to [`FITTED_REACH`] away).
        source: u32,
        /// A tileable solid's period (finest-level voxels; 0 for none): neighbours wrap.
        period: u32,
        _r1: u32, _r2: u32,
    }
}

/// How far the fitted colour rule (`ColorizeParams::source` 5) reads around a voxel: the
/// half-width of its 5x5 plane neighbourhoods.
pub const FITTED_REACH: i32 = 2;

gpu_struct! {
    /// Uniforms of `wgsl/tricubic_eval.wgsl`: evaluate a gradient solid at points. Floats are
    /// stored as their bits (`f32::to_bits`).
    TricubicParams size 96 {
        /// Control points per axis and channels.
        dims_x: u32, dims_y: u32, dims_z: u32, channels: u32,
        /// 0: an affine grid of points (origin + i a + j b + k c, i < n_x, j < n_y); 1: a list.
        mode: u32,
        /// Points of this dispatch, the index of its first point, threads per grid row.
        count: u32, first: u32, grid_stride: u32,
        n_x: u32, n_y: u32,
        origin_x: u32, origin_y: u32, origin_z: u32,
        a_x: u32, a_y: u32, a_z: u32,
        b_x: u32, b_y: u32, b_z: u32,
        c_x: u32, c_y: u32, c_z: u32,
        /// 1: write 8-bit values, one word per point (channels <= 4); 0: f32 per channel.
        quantize: u32, _pad1: u32,
    }
}

gpu_struct! {
    /// Uniforms of `wgsl/bucket_accumulate.wgsl`.
    BucketParams size 32 {
        /// Samples (each: voxel, cluster, `channels` values), clusters per voxel, channels.
        samples: u32, clusters: u32, channels: u32,
        /// 0: count samples per (voxel, cluster); 1: find each voxel's two dominant clusters
        /// (a thread per voxel); 2: sum the dominant clusters' samples.
        pass_index: u32,
        /// Threads per grid row; voxels (pass 1's threads).
        grid_stride: u32, voxels: u32, _pad1: u32, _pad2: u32,
    }
}

gpu_struct! {
    /// Uniforms of `wgsl/ptm_relight.wgsl`. Floats are stored as their bits, biases as i32 bits.
    PtmRelightParams size 96 {
        /// Unused (0); pixels of this dispatch, the index of its first, threads per grid row.
        width: u32, count: u32, first: u32, grid_stride: u32,
        /// 0: PTM_FORMAT_RGB, 1: PTM_FORMAT_LRGB; words per texel (5 or 3: texels are padded to
        /// whole words on upload).
        format: u32, texel_words: u32,
        light_u: u32, light_v: u32, light_w: u32, specular: u32,
        /// Per coefficient index: scale / 255 ([`crate::ptm::Ptm::step`]).
        step0: u32, step1: u32, step2: u32, step3: u32, step4: u32, step5: u32,
        bias0: u32, bias1: u32, bias2: u32, bias3: u32, bias4: u32, bias5: u32,
        _pad0: u32, _pad1: u32,
    }
}

/// Every shared struct: (WGSL kernel, struct name, Rust layout, Rust size).
/// Uniforms of the render pipeline `wgsl/lapped_render.wgsl` (floats: no `Eq`, so not through
/// `gpu_struct!`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct RenderParams {
    /// Column-major world-to-clip matrix.
    pub view_proj: [f32; 16],
    /// xyz: eye position.
    pub eye: [f32; 4],
    /// Depth clamps (1) or wraps (0); mask layers; exemplar size; mask size.
    pub flags: [f32; 4],
}
const _: () = assert!(std::mem::size_of::<RenderParams>() == 96);
impl RenderParams {
    #[cfg(any(test, feature = "internals"))]
    pub fn layout() -> Vec<(&'static str, usize)> {
        vec![
            ("view_proj", std::mem::offset_of!(RenderParams, view_proj)),
            ("eye", std::mem::offset_of!(RenderParams, eye)),
            ("flags", std::mem::offset_of!(RenderParams, flags)),
        ]
    }
}

#[cfg(any(test, feature = "internals"))]
pub fn all_layouts() -> Vec<(
    &'static str,
    &'static str,
    Vec<(&'static str, usize)>,
    usize,
)> {
    use std::mem::size_of;
    vec![
        (
            "init",
            "ExemplarFields",
            ExemplarFields::layout(),
            size_of::<ExemplarFields>(),
        ),
        (
            "project",
            "ProjectParams",
            ProjectParams::layout(),
            size_of::<ProjectParams>(),
        ),
        (
            "init",
            "InitParams",
            InitParams::layout(),
            size_of::<InitParams>(),
        ),
        (
            "upsample",
            "UpsampleParams",
            UpsampleParams::layout(),
            size_of::<UpsampleParams>(),
        ),
        (
            "correct",
            "CorrectParams",
            CorrectParams::layout(),
            size_of::<CorrectParams>(),
        ),
        (
            "colorize",
            "ColorizeParams",
            ColorizeParams::layout(),
            size_of::<ColorizeParams>(),
        ),
        (
            "bucket_accumulate",
            "BucketParams",
            BucketParams::layout(),
            size_of::<BucketParams>(),
        ),
        (
            "tricubic_eval",
            "TricubicParams",
            TricubicParams::layout(),
            size_of::<TricubicParams>(),
        ),
        (
            "ptm_relight",
            "PtmRelightParams",
            PtmRelightParams::layout(),
            size_of::<PtmRelightParams>(),
        ),
        (
            "lapped_render",
            "RenderParams",
            RenderParams::layout(),
            size_of::<RenderParams>(),
        ),
    ]
}
