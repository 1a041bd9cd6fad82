//! The WGSL sources, embedded, and their validation with naga. Synthesis kernels get the shared
//! prelude `wgsl/lib/synth_common.wgsl` prepended (WGSL has no includes).

macro_rules! with_prelude {
    ($file:literal) => {
        concat!(
            include_str!("../../wgsl/lib/synth_common.wgsl"),
            "\n",
            include_str!($file)
        )
    };
}

/// (kernel name, complete source) of every kernel in `wgsl/`.
pub const KERNELS: &[(&str, &str)] = &[
    ("project", include_str!("../../wgsl/project.wgsl")),
    ("init", with_prelude!("../../wgsl/init.wgsl")),
    ("upsample", with_prelude!("../../wgsl/upsample.wgsl")),
    ("correct", with_prelude!("../../wgsl/correct.wgsl")),
    ("colorize", with_prelude!("../../wgsl/colorize.wgsl")),
    (
        "tricubic_eval",
        include_str!("../../wgsl/tricubic_eval.wgsl"),
    ),
    ("ptm_relight", include_str!("../../wgsl/ptm_relight.wgsl")),
    (
        "bucket_accumulate",
        include_str!("../../wgsl/bucket_accumulate.wgsl"),
    ),
    // A render pipeline (vs_main / fs_main), not a compute kernel.
    (
        "lapped_render",
        include_str!("../../wgsl/lapped_render.wgsl"),
    ),
];

/// The source of kernel `name`.
pub fn source(name: &str) -> &'static str {
    KERNELS
        .iter()
        .find(|(n, _)| *n == name)
        .map(|(_, s)| *s)
        .unwrap_or_else(|| panic!("no kernel named {name}"))
}

/// Parse and validate WGSL with naga; returns the module and its validation info.
#[cfg(any(test, feature = "internals"))]
pub fn validate(name: &str, src: &str) -> Result<(naga::Module, naga::valid::ModuleInfo), String> {
    let module = naga::front::wgsl::parse_str(src)
        .map_err(|e| format!("{name}.wgsl: {}", e.emit_to_string(src)))?;
    let info = naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::empty(),
    )
    .validate(&module)
    .map_err(|e| format!("{name}.wgsl: {}", e.emit_to_string(src)))?;
    Ok((module, info))
}

/// Byte offsets of the members of WGSL struct `struct_name`, as naga lays them out, with its size.
#[cfg(any(test, feature = "internals"))]
pub fn struct_layout(
    module: &naga::Module,
    struct_name: &str,
) -> Option<(Vec<(String, u32)>, u32)> {
    module.types.iter().find_map(|(_, ty)| match &ty.inner {
        naga::TypeInner::Struct { members, span } if ty.name.as_deref() == Some(struct_name) => {
            Some((
                members
                    .iter()
                    .map(|m| (m.name.clone().unwrap_or_default(), m.offset))
                    .collect(),
                *span,
            ))
        }
        _ => None,
    })
}
