//! Offscreen render of an LST model's surface (`wgsl/lapped_render.wgsl`, paper 5.1): a depth
//! pre-pass of the boundary triangles, then every boundary triangle once per layer of its tet,
//! sorted by patch so each pixel composites its layers in paste order, alpha blended into an
//! RGBA8 target; the host divides by the accumulated coverage. The exemplar is a 3D texture
//! (trilinear, repeating), the masks one 3D texture with the layers stacked along z.
//! CPU reference: [`crate::cpu::lapped_render::reference_pixel`].

use super::context::GpuContext;
use crate::contract::lapped::{Camera, RenderScene, VERTEX_FLOATS};
use crate::contract::uniforms::RenderParams;
use crate::error::{Error, Result};

/// Largest image side.
pub const MAX_RENDER_SIZE: u32 = 4096;

/// Render the scene from `camera` into a size x size RGBA image (transparent off the model).
pub fn render(
    gpu: &GpuContext,
    scene: &RenderScene,
    camera: &Camera,
    size: u32,
) -> Result<image::RgbaImage> {
    if !(16..=MAX_RENDER_SIZE).contains(&size) {
        return Err(Error::invalid(
            format!("--size {size}"),
            format!("must be 16..={MAX_RENDER_SIZE}"),
        ));
    }
    if gpu.render_pipelines_crash() {
        return Err(Error::Gpu(format!(
            "{} crashes compiling render pipelines at 512-bit vectors; run this process with \
             LP_NATIVE_VECTOR_WIDTH=256 (the `solidsynth lapped render` command sets it unless \
             the variable is set; a program calls \
             `prepare_driver_environment_for(DriverUse::Rendering)` before its first GPU context)",
            gpu.info.name
        )));
    }
    gpu.checked("lapped render", || render_inner(gpu, scene, camera, size))
}

fn texture_3d(
    gpu: &GpuContext,
    label: &str,
    format: wgpu::TextureFormat,
    size: [u32; 3],
    bytes_per_texel: u32,
    data: &[u8],
) -> wgpu::TextureView {
    let extent = wgpu::Extent3d {
        width: size[0],
        height: size[1],
        depth_or_array_layers: size[2],
    };
    let texture = gpu.device.create_texture(&wgpu::TextureDescriptor {
        label: Some(label),
        size: extent,
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D3,
        format,
        usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        view_formats: &[],
    });
    gpu.queue.write_texture(
        wgpu::TexelCopyTextureInfo {
            texture: &texture,
            mip_level: 0,
            origin: wgpu::Origin3d::ZERO,
            aspect: wgpu::TextureAspect::All,
        },
        data,
        wgpu::TexelCopyBufferLayout {
            offset: 0,
            bytes_per_row: Some(size[0] * bytes_per_texel),
            rows_per_image: Some(size[1]),
        },
        extent,
    );
    texture.create_view(&wgpu::TextureViewDescriptor::default())
}

fn render_inner(
    gpu: &GpuContext,
    scene: &RenderScene,
    camera: &Camera,
    size: u32,
) -> Result<image::RgbaImage> {
    let device = &gpu.device;
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("lapped_render"),
        source: wgpu::ShaderSource::Wgsl(super::shaders::source("lapped_render").into()),
    });
    let attributes = wgpu::vertex_attr_array![
        0 => Float32x3, 1 => Float32x3, 2 => Float32x3, 3 => Float32
    ];
    let buffers = [Some(wgpu::VertexBufferLayout {
        array_stride: (VERTEX_FLOATS * 4) as u64,
        step_mode: wgpu::VertexStepMode::Vertex,
        attributes: &attributes,
    })];
    let primitive = wgpu::PrimitiveState {
        topology: wgpu::PrimitiveTopology::TriangleList,
        cull_mode: Some(wgpu::Face::Back),
        ..Default::default()
    };
    let depth_format = wgpu::TextureFormat::Depth32Float;
    let pipeline = |label: &str, fragment: bool| {
        let blend = wgpu::BlendState {
            color: wgpu::BlendComponent {
                src_factor: wgpu::BlendFactor::SrcAlpha,
                dst_factor: wgpu::BlendFactor::OneMinusSrcAlpha,
                operation: wgpu::BlendOperation::Add,
            },
            alpha: wgpu::BlendComponent {
                src_factor: wgpu::BlendFactor::One,
                dst_factor: wgpu::BlendFactor::OneMinusSrcAlpha,
                operation: wgpu::BlendOperation::Add,
            },
        };
        let targets = [Some(wgpu::ColorTargetState {
            format: wgpu::TextureFormat::Rgba8Unorm,
            blend: Some(blend),
            write_mask: if fragment {
                wgpu::ColorWrites::ALL
            } else {
                wgpu::ColorWrites::empty()
            },
        })];
        device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some(label),
            layout: None,
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some("vs_main"),
                compilation_options: Default::default(),
                buffers: &buffers,
            },
            primitive,
            depth_stencil: Some(wgpu::DepthStencilState {
                format: depth_format,
                depth_write_enabled: Some(!fragment),
                depth_compare: Some(if fragment {
                    wgpu::CompareFunction::LessEqual
                } else {
                    wgpu::CompareFunction::Less
                }),
                stencil: Default::default(),
                bias: Default::default(),
            }),
            multisample: Default::default(),
            fragment: Some(wgpu::FragmentState {
                module: &module,
                entry_point: Some(if fragment { "fs_main" } else { "fs_depth" }),
                compilation_options: Default::default(),
                targets: &targets,
            }),
            multiview_mask: None,
            cache: None,
        })
    };
    let depth_pipeline = pipeline("lapped depth pre-pass", false);
    let layer_pipeline = pipeline("lapped layers", true);

    let e = scene.exemplar_size;
    let exemplar = texture_3d(
        gpu,
        "exemplar",
        wgpu::TextureFormat::Rgba8Unorm,
        [e, e, e],
        4,
        scene.exemplar_rgba,
    );
    let m = scene.mask_size;
    let masks = texture_3d(
        gpu,
        "masks",
        wgpu::TextureFormat::R8Unorm,
        [m, m, m * scene.mask_count],
        1,
        &scene.mask_alpha,
    );
    let sampler = |mode: wgpu::AddressMode| {
        device.create_sampler(&wgpu::SamplerDescriptor {
            address_mode_u: mode,
            address_mode_v: mode,
            address_mode_w: mode,
            mag_filter: wgpu::FilterMode::Linear,
            min_filter: wgpu::FilterMode::Linear,
            ..Default::default()
        })
    };
    let repeat = sampler(wgpu::AddressMode::Repeat);
    let clamp = sampler(wgpu::AddressMode::ClampToEdge);
    let eye = camera.eye.as_vec3();
    let params = RenderParams {
        view_proj: camera.view_proj_f32().to_cols_array(),
        eye: [eye.x, eye.y, eye.z, 1.0],
        flags: [
            if scene.depth_varying { 1.0 } else { 0.0 },
            scene.mask_count as f32,
            e as f32,
            m as f32,
        ],
    };
    let uniforms = gpu.uniform_buffer("render params", &params);
    let layer_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("lapped layers"),
        layout: &layer_pipeline.get_bind_group_layout(0),
        entries: &[
            wgpu::BindGroupEntry {
                binding: 0,
                resource: uniforms.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 1,
                resource: wgpu::BindingResource::TextureView(&exemplar),
            },
            wgpu::BindGroupEntry {
                binding: 2,
                resource: wgpu::BindingResource::TextureView(&masks),
            },
            wgpu::BindGroupEntry {
                binding: 3,
                resource: wgpu::BindingResource::Sampler(&repeat),
            },
            wgpu::BindGroupEntry {
                binding: 4,
                resource: wgpu::BindingResource::Sampler(&clamp),
            },
        ],
    });
    let depth_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("lapped depth"),
        layout: &depth_pipeline.get_bind_group_layout(0),
        entries: &[wgpu::BindGroupEntry {
            binding: 0,
            resource: uniforms.as_entire_binding(),
        }],
    });

    let (prepass, layered) = (&scene.prepass, &scene.layered);
    let vertex_buffer = |label: &str, data: &[f32]| {
        let buffer = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size: (data.len() * 4).max(4) as u64,
            usage: wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        gpu.queue
            .write_buffer(&buffer, 0, bytemuck::cast_slice(data));
        buffer
    };
    let prepass_buffer = vertex_buffer("depth pre-pass vertices", prepass);
    let layer_buffer = vertex_buffer("layer vertices", layered);

    let target_extent = wgpu::Extent3d {
        width: size,
        height: size,
        depth_or_array_layers: 1,
    };
    let target = device.create_texture(&wgpu::TextureDescriptor {
        label: Some("render target"),
        size: target_extent,
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: wgpu::TextureFormat::Rgba8Unorm,
        usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
        view_formats: &[],
    });
    let depth = device.create_texture(&wgpu::TextureDescriptor {
        label: Some("depth"),
        size: target_extent,
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: depth_format,
        usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
        view_formats: &[],
    });
    let target_view = target.create_view(&Default::default());
    let depth_view = depth.create_view(&Default::default());
    let row_bytes = (size * 4).div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT)
        * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
    let readback = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("render readback"),
        size: (row_bytes * size) as u64,
        usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    });

    let mut encoder = device.create_command_encoder(&Default::default());
    {
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("lapped render"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: &target_view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &depth_view,
                depth_ops: Some(wgpu::Operations {
                    load: wgpu::LoadOp::Clear(1.0),
                    store: wgpu::StoreOp::Store,
                }),
                stencil_ops: None,
            }),
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_pipeline(&depth_pipeline);
        pass.set_bind_group(0, &depth_group, &[]);
        pass.set_vertex_buffer(0, prepass_buffer.slice(..));
        pass.draw(0..(prepass.len() / VERTEX_FLOATS) as u32, 0..1);
        pass.set_pipeline(&layer_pipeline);
        pass.set_bind_group(0, &layer_group, &[]);
        pass.set_vertex_buffer(0, layer_buffer.slice(..));
        pass.draw(0..(layered.len() / VERTEX_FLOATS) as u32, 0..1);
    }
    encoder.copy_texture_to_buffer(
        wgpu::TexelCopyTextureInfo {
            texture: &target,
            mip_level: 0,
            origin: wgpu::Origin3d::ZERO,
            aspect: wgpu::TextureAspect::All,
        },
        wgpu::TexelCopyBufferInfo {
            buffer: &readback,
            layout: wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(row_bytes),
                rows_per_image: Some(size),
            },
        },
        target_extent,
    );
    gpu.submit_and_wait(encoder)?;
    let words = gpu.read_words(&readback, (row_bytes * size / 4) as usize)?;
    let bytes: &[u8] = bytemuck::cast_slice(&words);
    let mut out = image::RgbaImage::new(size, size);
    for y in 0..size {
        for x in 0..size {
            let o = (y * row_bytes + x * 4) as usize;
            let a = bytes[o + 3];
            if a == 0 {
                continue;
            }
            let unpremultiply = |c: u8| ((c as f32 * 255.0 / a as f32).round()).min(255.0) as u8;
            out.put_pixel(
                x,
                y,
                image::Rgba([
                    unpremultiply(bytes[o]),
                    unpremultiply(bytes[o + 1]),
                    unpremultiply(bytes[o + 2]),
                    255,
                ]),
            );
        }
    }
    Ok(out)
}
