//! Structs shared between Rust and WGSL. Each is `#[repr(C)]` + `Pod`, has its size asserted at
//! compile time, and a test in `kernels-tests` checks every field offset against naga's layout of
//! the WGSL struct of the same name.

use bytemuck::{Pod, Zeroable};

/// Uniforms of `wgsl/project.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct ProjectParams {
    pub width: u32,
    pub height: u32,
    pub channels: u32,
    /// `Border::code()`: 0 wrap, 1 mirror.
    pub border: u32,
    pub input_dims: u32,
    pub output_dims: u32,
    pub shift: u32,
    /// First pixel (row-major index) of this dispatch's chunk.
    pub first_pixel: u32,
    /// Pixels in this chunk.
    pub pixel_count: u32,
    /// u32 words per output vector (output_dims / 4 rounded up).
    pub words_per_vector: u32,
    /// Threads per row of the 2D dispatch grid (workgroups in x times the workgroup size).
    pub grid_stride: u32,
    pub _pad: u32,
}

const _: () = assert!(std::mem::size_of::<ProjectParams>() == 48);

/// Field names and byte offsets, in declaration order, for the naga layout check.
pub fn project_params_layout() -> Vec<(&'static str, usize)> {
    use std::mem::offset_of;
    vec![
        ("width", offset_of!(ProjectParams, width)),
        ("height", offset_of!(ProjectParams, height)),
        ("channels", offset_of!(ProjectParams, channels)),
        ("border", offset_of!(ProjectParams, border)),
        ("input_dims", offset_of!(ProjectParams, input_dims)),
        ("output_dims", offset_of!(ProjectParams, output_dims)),
        ("shift", offset_of!(ProjectParams, shift)),
        ("first_pixel", offset_of!(ProjectParams, first_pixel)),
        ("pixel_count", offset_of!(ProjectParams, pixel_count)),
        (
            "words_per_vector",
            offset_of!(ProjectParams, words_per_vector),
        ),
        ("grid_stride", offset_of!(ProjectParams, grid_stride)),
        ("_pad", offset_of!(ProjectParams, _pad)),
    ]
}
