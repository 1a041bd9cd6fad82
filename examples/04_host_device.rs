//! An application's own GPU device handed to the engine: the application opens wgpu as it
//! would for its renderer, the engine synthesizes a box on that device, the application copies
//! the voxels into a storage buffer it owns and reads them back, and they equal the CPU
//! backend's bytes. `cargo run --release --example 04_host_device` (needs a Vulkan adapter:
//! lavapipe works; without one it says so and exits 0, unless CI is set).
use solidsynth::Compute;
use solidsynth::{Box3, Solid};
use solidsynth::{GpuContext, GpuOptions};
use std::sync::Arc;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    // The application's device, with the limits the engine needs.
    let instance = wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle());
    let adapters = pollster::block_on(instance.enumerate_adapters(wgpu::Backends::VULKAN));
    let Some(adapter) = adapters.into_iter().next() else {
        if std::env::var_os("CI").is_some() {
            return Err("CI is set but no Vulkan adapter is usable".into());
        }
        println!("no Vulkan adapter: nothing to show");
        return Ok(());
    };
    let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
        label: Some("the application's device"),
        required_limits: adapter.limits(),
        ..Default::default()
    }))?;
    let context = GpuContext::from_device(
        device.clone(),
        queue.clone(),
        adapter.get_info(),
        &GpuOptions::default(),
    )?;
    let on_device = Compute::Gpu(Arc::new(context));

    let b = Box3::new([-8, 0, 4], [24, 16, 20]);
    let analysis = Solid::builder().cpu().analyze()?;
    let mut solid = Solid::builder()
        .seed(9)
        .shared_analysis(analysis.clone())
        .compute(on_device)
        .build()?;
    let volume = solid.region(b)?;

    // Into a buffer the application owns, and back (as a renderer would upload a 3D texture).
    use wgpu::util::DeviceExt;
    let padded = volume.data.len().next_multiple_of(4);
    let mut bytes = volume.data.clone();
    bytes.resize(padded, 0);
    let owned = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("application storage"),
        contents: &bytes,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
    });
    let readback = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("readback"),
        size: padded as u64,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let mut encoder = device.create_command_encoder(&Default::default());
    encoder.copy_buffer_to_buffer(&owned, 0, &readback, 0, Some(padded as u64));
    queue.submit([encoder.finish()]);
    readback.map_async(wgpu::MapMode::Read, .., |r| r.expect("mapped"));
    let wait = Some(std::time::Duration::from_secs(60));
    device.poll(wgpu::PollType::Wait {
        submission_index: None,
        timeout: wait,
    })?;
    let read = readback.get_mapped_range(..)?.to_vec();

    let mut on_cpu = Solid::builder()
        .seed(9)
        .shared_analysis(analysis)
        .cpu()
        .build()?;
    let reference = on_cpu.region(b)?;
    assert_eq!(
        &read[..volume.data.len()],
        &reference.data[..],
        "device and CPU differ"
    );
    println!(
        "{:?}: {} voxels on {}, equal to the CPU backend's",
        b.size(),
        b.voxels(),
        adapter.get_info().name
    );
    Ok(())
}
