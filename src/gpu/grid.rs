//! Hair–hair interaction on the GPU (`grid.wgsl`): each stepped head's hair splatted to a dense grid
//! around it and the grid's velocity smoothing and volume pressure given back to its nodes before the
//! step, the same fields as [`crate::volume`]'s grid on the CPU ([`GpuStrandSolver::set_volume`]).
//!
//! The grid of a head is dense over the box around its hair (one empty point below and two above, as on
//! the CPU), its points on world multiples of the cell, coarsened where the box holds more than the
//! head's share of [`GPU_GRID_POINTS`]. Sums are 64-bit fixed point in two `u32` atomics (WGSL has no
//! float atomics): each is exact, so the fields do not depend on the order the nodes land in, and a
//! node's share is resolved to 2⁻³² of the heaviest node's ([`GpuStrandSolver::set_volume`]).
//!
//! [`GpuStrandSolver::set_volume`]: super::GpuStrandSolver::set_volume

use bevy::math::{DVec3, Vec3};

use super::pipelines::{bind_whole_buffers, compute_layout, compute_pipeline};

/// The most grid points one head's grid may use: hair spread over a larger box coarsens its cells until
/// it fits. 2¹⁹ points, a box of 0.4 m a side at 5 mm, 24 MB of the GPU's memory per head.
pub const GPU_GRID_POINTS: usize = 1 << 19;

/// Words per grid point (`POINT_WORDS` in `grid.wgsl`).
const POINT_WORDS: usize = 12;
/// Words per head (`HEAD_WORDS`).
const HEAD_WORDS: usize = 24;
/// `Params` of `grid.wgsl`: twelve words.
const GRID_PARAMS_BYTES: u64 = 48;
/// Invocations per workgroup (`WORKGROUP`).
const GRID_WORKGROUP: u32 = 64;

/// The hair–hair grid's parameters on the GPU, as [`crate::volume::VolumeParams`] on the CPU (whose
/// module documentation has the equations), the step's length coming from the step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GpuVolume {
    /// Spacing of the grid points `Δx`, m (coarser where a head's hair spreads wider than
    /// [`GPU_GRID_POINTS`] allow).
    pub cell_size: f64,
    /// Velocity smoothing rate `k`, 1/s.
    pub smoothing_rate: f64,
    /// Target hair volume fraction `φ₀`, in (0, 1].
    pub target_fraction: f64,
    /// Pressure stiffness `K`, Pa (0: no pressure).
    pub stiffness: f64,
    /// Whether the pressure measures packing against each node's groomed fraction where that is larger
    /// ([`GpuStrandInput::groomed_fractions`](super::GpuStrandInput::groomed_fractions)).
    pub keep_groomed: bool,
}

impl GpuVolume {
    /// Whether every parameter is in its range: a cell of 0.1 mm to 1 m, a rate and stiffness finite and not
    /// negative, a target fraction in (0, 1].
    pub fn is_valid(&self) -> bool {
        (1e-4..=1.0).contains(&self.cell_size)
            && self.smoothing_rate.is_finite()
            && self.smoothing_rate >= 0.0
            && self.target_fraction > 0.0
            && self.target_fraction <= 1.0
            && self.stiffness.is_finite()
            && self.stiffness >= 0.0
    }
}

/// One grid point after a step ([`GpuGridFields`]).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct GpuGridPoint {
    /// `α u`: the smoothing times the hair's velocity there, m/s.
    pub smoothed_velocity: Vec3,
    /// The smoothing `α`, the share of a node's velocity difference taken in the step.
    pub smoothing: f32,
    /// The hair volume fraction `φ`.
    pub volume_fraction: f32,
    /// The pressure `p`, Pa.
    pub pressure: f32,
}

/// One head's grid as the last step left it ([`GpuStrandSolver::read_grid`](super::GpuStrandSolver::read_grid)).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct GpuGridFields {
    /// Where its first point is, world space, m.
    pub origin: DVec3,
    /// Its spacing, m.
    pub cell_size: f64,
    /// Its points along X, Y and Z (0 when the head was not stepped).
    pub dims: [usize; 3],
    /// Its points, X fastest.
    pub points: Vec<GpuGridPoint>,
    /// Whether the pressure pushed anywhere.
    pub pressed: bool,
    /// The largest volume fraction at a point.
    pub max_volume_fraction: f32,
}

impl GpuGridFields {
    /// The point at grid coordinates `[i, j, k]`, if in the grid.
    pub fn point(&self, [i, j, k]: [usize; 3]) -> Option<&GpuGridPoint> {
        let [nx, ny, nz] = self.dims;
        (i < nx && j < ny && k < nz).then(|| &self.points[i + nx * (j + ny * k)])
    }

    /// Where the point at grid coordinates `c` is, world space, m.
    pub fn position(&self, c: [usize; 3]) -> DVec3 {
        self.origin + self.cell_size * DVec3::new(c[0] as f64, c[1] as f64, c[2] as f64)
    }
}

/// The grid's pipelines, built with the step's ([`super::GpuStepPipelines`]).
pub(super) struct GridPipelines {
    layout: wgpu::BindGroupLayout,
    /// `bounds`, `place`, `clear`, `splat`, `fields`, `respond`.
    passes: [wgpu::ComputePipeline; 6],
}

/// The shader of the hair–hair grid on the GPU.
pub const GRID_SHADER: &str = include_str!("grid.wgsl");

impl GridPipelines {
    pub(super) fn new(device: &wgpu::Device) -> Self {
        // Bindings: parameters; strand words, floats, rest shape (read); state, grid heads, grid points
        // (written).
        let read_only = [true, true, true, false, false, false];
        let layout = compute_layout(device, "hair grid", Some(GRID_PARAMS_BYTES), &read_only);
        let passes = ["bounds", "place", "clear", "splat", "fields", "respond"]
            .map(|entry| compute_pipeline(device, "hair grid", GRID_SHADER, entry, &layout));
        Self { layout, passes }
    }
}

/// One solver's grid: its buffers, and what the last step recorded.
pub(super) struct GpuGrid {
    params: wgpu::Buffer,
    heads: wgpu::Buffer,
    points: wgpu::Buffer,
    bind_group: wgpu::BindGroup,
    head_count: usize,
    points_per_head: usize,
    head_words: Vec<u32>,
    /// Each head's translation before the last step recorded (the origin of its positions then), m, and the
    /// offset of the grid's frame from it.
    frames: Vec<(DVec3, DVec3)>,
}

/// What [`GpuGrid::record`] needs of the solver.
pub(super) struct GridStep<'a> {
    pub(super) volume: &'a GpuVolume,
    /// Each head's translation before the step, and its step's length (0: not stepped now), s.
    pub(super) heads: &'a [(DVec3, f64)],
    pub(super) strands: usize,
    pub(super) total_nodes: usize,
    /// The fixed-point units of mass (kg) and volume (m³).
    pub(super) units: (f64, f64),
}

impl GpuGrid {
    /// The grid's buffers for `head_count` heads, bound with the solver's `strand_words`, `strand_floats`,
    /// `rest` and `state`.
    pub(super) fn new(
        device: &wgpu::Device,
        pipelines: &GridPipelines,
        head_count: usize,
        solver: [&wgpu::Buffer; 4],
    ) -> Self {
        let head_count = head_count.max(1);
        let limit = device.limits().max_storage_buffer_binding_size as usize;
        let points_per_head = GPU_GRID_POINTS.min(limit / (4 * POINT_WORDS * head_count)).max(1);
        let buffer = |label: &str, size: usize, usage: wgpu::BufferUsages| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: size as u64,
                usage: usage | wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            })
        };
        let params = buffer("hair grid parameters", GRID_PARAMS_BYTES as usize, wgpu::BufferUsages::UNIFORM);
        let heads = buffer("hair grid heads", 4 * HEAD_WORDS * head_count, wgpu::BufferUsages::STORAGE);
        let points =
            buffer("hair grid points", 4 * POINT_WORDS * points_per_head * head_count, wgpu::BufferUsages::STORAGE);
        let buffers = [&params, solver[0], solver[1], solver[2], solver[3], &heads, &points];
        let bind_group = bind_whole_buffers(device, "hair grid", &pipelines.layout, &buffers);
        Self {
            params,
            heads,
            points,
            bind_group,
            head_count,
            points_per_head,
            head_words: Vec::new(),
            frames: Vec::new(),
        }
    }

    /// Records the grid's six passes for one step into `encoder`, after writing its parameters and heads.
    pub(super) fn record(
        &mut self,
        queue: &wgpu::Queue,
        encoder: &mut wgpu::CommandEncoder,
        pipelines: &GridPipelines,
        step: &GridStep,
    ) {
        let volume = step.volume;
        let cell = volume.cell_size;
        self.head_words.clear();
        self.frames.clear();
        for &(translation, dt) in step.heads {
            // The head's translation is `k Δx + r`: positions relative to it, shifted by `r`, put the grid's
            // points on world multiples of the cell.
            let offset = translation - (translation / cell).floor() * cell;
            self.frames.push((translation, offset));
            let bits = |value: f64| (value as f32).to_bits();
            self.head_words.extend([bits(offset.x), bits(offset.y), bits(offset.z), bits(dt)]);
            self.head_words.extend([u32::MAX, u32::MAX, u32::MAX, 0, 0, 0, 0, 0]);
            self.head_words.extend([0; HEAD_WORDS - 12]);
        }
        queue.write_buffer(&self.heads, 0, bytemuck::cast_slice(&self.head_words));
        let words: [u32; 12] = [
            (cell as f32).to_bits(),
            (volume.smoothing_rate as f32).to_bits(),
            (volume.target_fraction as f32).to_bits(),
            (volume.stiffness as f32).to_bits(),
            (step.units.0 as f32).to_bits(),
            (step.units.1 as f32).to_bits(),
            u32::from(volume.keep_groomed),
            step.strands as u32,
            step.total_nodes as u32,
            step.heads.len() as u32,
            self.points_per_head as u32,
            0,
        ];
        queue.write_buffer(&self.params, 0, bytemuck::cast_slice(&words));
        let mut pass = encoder
            .begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("hair grid"), timestamp_writes: None });
        pass.set_bind_group(0, &self.bind_group, &[]);
        let strands = super::step::workgroups(step.strands as u32, 1);
        let points = super::step::workgroups((self.points_per_head * step.heads.len()) as u32, GRID_WORKGROUP);
        let heads = super::step::workgroups(step.heads.len() as u32, GRID_WORKGROUP);
        for (pipeline, (x, y)) in pipelines.passes.iter().zip([strands, heads, points, strands, points, strands]) {
            pass.set_pipeline(pipeline);
            pass.dispatch_workgroups(x, y, 1);
        }
    }

    /// The buffer of the heads' words (read back with the strands' status).
    pub(super) fn heads_buffer(&self) -> &wgpu::Buffer {
        &self.heads
    }

    /// The largest volume fraction in the heads' words `words` (as [`GpuGrid::heads_buffer`] holds them).
    pub(super) fn densest(words: &[u32]) -> f32 {
        words.chunks_exact(HEAD_WORDS).map(|head| f32::from_bits(head[20])).fold(0.0, f32::max)
    }

    /// Each head's grid as the last recorded step left it, waiting for the GPU.
    pub(super) fn read(&self, device: &wgpu::Device, queue: &wgpu::Queue) -> Vec<GpuGridFields> {
        let heads: Vec<u32> = read_words(device, queue, &self.heads);
        let points: Vec<u32> = read_words(device, queue, &self.points);
        let float = |word: u32| f32::from_bits(word);
        (0..self.head_count.min(self.frames.len()))
            .map(|head| {
                let at = &heads[head * HEAD_WORDS..(head + 1) * HEAD_WORDS];
                let dims = [at[16], at[17], at[18]].map(|n| n as usize);
                let (translation, offset) = self.frames[head];
                let grid_origin = DVec3::new(float(at[12]).into(), float(at[13]).into(), float(at[14]).into());
                let base = head * self.points_per_head;
                let values = (0..dims.iter().product::<usize>())
                    .map(|point| {
                        let w = &points[(base + point) * POINT_WORDS..(base + point + 1) * POINT_WORDS];
                        GpuGridPoint {
                            smoothed_velocity: Vec3::new(float(w[0]), float(w[1]), float(w[2])),
                            smoothing: float(w[3]),
                            volume_fraction: float(w[4]),
                            pressure: float(w[5]),
                        }
                    })
                    .collect();
                GpuGridFields {
                    origin: translation + grid_origin - offset,
                    cell_size: float(at[15]).into(),
                    dims,
                    points: values,
                    pressed: at[19] != 0,
                    max_volume_fraction: float(at[20]),
                }
            })
            .collect()
    }
}

/// A buffer's words, copied to the CPU, waiting for the GPU.
fn read_words(device: &wgpu::Device, queue: &wgpu::Queue, buffer: &wgpu::Buffer) -> Vec<u32> {
    let staging = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("hair grid read-back"),
        size: buffer.size(),
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("hair grid") });
    encoder.copy_buffer_to_buffer(buffer, 0, &staging, 0, buffer.size());
    queue.submit([encoder.finish()]);
    let slice = staging.slice(..);
    slice.map_async(wgpu::MapMode::Read, |_| {});
    let _ = device.poll(wgpu::PollType::wait_indefinitely());
    let words = bytemuck::cast_slice(&slice.get_mapped_range()).to_vec();
    staging.unmap();
    words
}
