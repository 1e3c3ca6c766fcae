//! The wgpu plumbing every compute pass of this crate repeats, for yours too (over
//! [`GpuStrandSolver::state_buffers`](super::GpuStrandSolver::state_buffers), say): one bind group of a
//! uniform and storage buffers, a pipeline of one entry point, the group bound to whole buffers.

use std::num::NonZeroU64;

/// A compute bind group layout: a uniform at binding 0 (of at least `uniform_bytes`, if given), then one
/// storage buffer per entry of `read_only` at bindings 1, 2, … (`true`: read only).
pub fn compute_layout(
    device: &wgpu::Device,
    label: &str,
    uniform_bytes: Option<u64>,
    read_only: &[bool],
) -> wgpu::BindGroupLayout {
    let buffer =
        |binding: u32, ty: wgpu::BufferBindingType, min_binding_size: Option<NonZeroU64>| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::Buffer { ty, has_dynamic_offset: false, min_binding_size },
            count: None,
        };
    let uniform = buffer(0, wgpu::BufferBindingType::Uniform, uniform_bytes.and_then(NonZeroU64::new));
    let storage = read_only
        .iter()
        .enumerate()
        .map(|(index, &read_only)| buffer(index as u32 + 1, wgpu::BufferBindingType::Storage { read_only }, None));
    let entries: Vec<wgpu::BindGroupLayoutEntry> = std::iter::once(uniform).chain(storage).collect();
    device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor { label: Some(label), entries: &entries })
}

/// The compute pipeline of `entry` in the WGSL `source`, with the one bind group `layout`.
pub fn compute_pipeline(
    device: &wgpu::Device,
    label: &str,
    source: &str,
    entry: &str,
    layout: &wgpu::BindGroupLayout,
) -> wgpu::ComputePipeline {
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some(label),
        source: wgpu::ShaderSource::Wgsl(source.into()),
    });
    pipeline_of_module(device, label, &module, entry, layout, &wgpu::PipelineCompilationOptions::default())
}

/// The compute pipeline of `entry` in a compiled `module`, with the one bind group `layout` and `options`
/// (the values of its `override` constants, say).
pub fn pipeline_of_module(
    device: &wgpu::Device,
    label: &str,
    module: &wgpu::ShaderModule,
    entry: &str,
    layout: &wgpu::BindGroupLayout,
    options: &wgpu::PipelineCompilationOptions,
) -> wgpu::ComputePipeline {
    let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some(label),
        bind_group_layouts: &[Some(layout)],
        immediate_size: 0,
    });
    device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some(label),
        layout: Some(&pipeline_layout),
        module,
        entry_point: Some(entry),
        compilation_options: options.clone(),
        cache: None,
    })
}

/// `buffers`, whole, at bindings 0, 1, … of `layout`.
pub fn bind_whole_buffers(
    device: &wgpu::Device,
    label: &str,
    layout: &wgpu::BindGroupLayout,
    buffers: &[&wgpu::Buffer],
) -> wgpu::BindGroup {
    let entries: Vec<wgpu::BindGroupEntry> = buffers
        .iter()
        .enumerate()
        .map(|(binding, buffer)| wgpu::BindGroupEntry { binding: binding as u32, resource: buffer.as_entire_binding() })
        .collect();
    device.create_bind_group(&wgpu::BindGroupDescriptor { label: Some(label), layout, entries: &entries })
}
