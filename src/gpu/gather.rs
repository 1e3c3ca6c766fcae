//! The gather (`gather.wgsl`): after the step, one head's guides copied from the step's buffers into
//! what the follower placement reads, on the GPU.

use wgpu::util::DeviceExt;

use super::pipelines::{bind_whole_buffers, compute_layout, compute_pipeline};

/// Invocations per workgroup of the gather (`WORKGROUP` in `gather.wgsl`).
pub(super) const GATHER_WORKGROUP: u32 = 64;

/// `Params` of `gather.wgsl`: eight words.
pub(super) const GATHER_PARAMS_BYTES: u64 = 32;

/// The pipeline of `gather.wgsl`.
pub(super) struct Gather {
    layout: wgpu::BindGroupLayout,
    pub(super) pipeline: wgpu::ComputePipeline,
}

/// One head's guides as [`GpuStrandSolver::record_gather`](super::GpuStrandSolver::record_gather) writes
/// them for the follower placement.
pub struct GpuGatherTarget {
    pub(super) params: wgpu::Buffer,
    pub(super) bind_group: wgpu::BindGroup,
    /// The last guide's index: guides − 1.
    pub(super) guides: u32,
}

/// The shader that hands strands to the follower placement.
pub const GATHER_SHADER: &str = include_str!("gather.wgsl");

impl Gather {
    pub(super) fn new(device: &wgpu::Device) -> Self {
        // Bindings: parameters; strand words, floats, state, status, guide list (read); guide data, frames
        // (written).
        let read_only = [true, true, true, true, true, false, false];
        let layout = compute_layout(device, "hair guides gathered", Some(GATHER_PARAMS_BYTES), &read_only);
        let pipeline = compute_pipeline(device, "hair guides gathered", GATHER_SHADER, "gather", &layout);
        Self { layout, pipeline }
    }

    pub(super) fn target(
        &self,
        device: &wgpu::Device,
        solver: [&wgpu::Buffer; 4],
        guides: &[[u32; 2]],
        guide_data: &wgpu::Buffer,
        guide_frames: &wgpu::Buffer,
    ) -> GpuGatherTarget {
        let params = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("hair guides gathered"),
            size: GATHER_PARAMS_BYTES,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let contents: &[u8] = if guides.is_empty() { &[0; 16] } else { bytemuck::cast_slice(guides) };
        let map = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("hair guide strands"),
            contents,
            usage: wgpu::BufferUsages::STORAGE,
        });
        let buffers = [&params, solver[0], solver[1], solver[2], solver[3], &map, guide_data, guide_frames];
        let bind_group = bind_whole_buffers(device, "hair guides gathered", &self.layout, &buffers);
        GpuGatherTarget { params, bind_group, guides: guides.len().saturating_sub(1) as u32 }
    }
}
