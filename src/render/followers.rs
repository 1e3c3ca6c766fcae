//! The render world's side of GPU followers: each head's buffers, the compute passes of `followers.wgsl`
//! (`frames` and `place` once per step, `draw` every frame), dispatched before the cameras draw.

use std::borrow::Cow;
use std::num::NonZeroU64;

use bevy::asset::AssetId;
use bevy::ecs::query::QueryState;
use bevy::platform::collections::HashMap;
use bevy::prelude::*;
use bevy::render::MainWorld;
use bevy::render::render_asset::RenderAssets;
use bevy::render::render_resource::binding_types::{
    storage_buffer_read_only_sized, storage_buffer_sized, uniform_buffer_sized,
};
use bevy::render::render_resource::{
    BindGroup, BindGroupEntries, BindGroupLayoutDescriptor, BindGroupLayoutEntries, Buffer, BufferDescriptor,
    BufferInitDescriptor, BufferUsages, CachedComputePipelineId, ComputePassDescriptor, ComputePipelineDescriptor,
    PipelineCache, ShaderStages,
};
use bevy::render::renderer::{RenderContext, RenderDevice, RenderQueue};
use bevy::render::storage::{GpuShaderBuffer, ShaderBuffer};

use super::HairMesh;
use super::feed::{FRAME_CODE_BYTES, GpuCollider};

/// The compute shader.
pub(super) const SHADER: &str = "embedded://bevy_hair_sim/render/followers.wgsl";

/// Invocations per workgroup (`WORKGROUP` in the shader).
const WORKGROUP: u32 = 64;

/// Most workgroups along one dimension of a dispatch (WebGPU's limit).
const MAX_GROUPS: u32 = 65_535;

/// `Params` of the shader: eight words.
const PARAMS_BYTES: u64 = 32;

/// The three pipelines and their layouts (`frames` and `place` share one).
#[derive(Resource)]
pub(super) struct FollowerPipelines {
    place_layout: BindGroupLayoutDescriptor,
    draw_layout: BindGroupLayoutDescriptor,
    frames: CachedComputePipelineId,
    place: CachedComputePipelineId,
    draw: CachedComputePipelineId,
}

/// Queues the three compute pipelines (in `RenderStartup`).
pub(super) fn init_follower_pipelines(
    mut commands: Commands,
    asset_server: Res<AssetServer>,
    pipeline_cache: Res<PipelineCache>,
) {
    let read = || storage_buffer_read_only_sized(false, None);
    let place_layout = BindGroupLayoutDescriptor::new(
        "hair follower placement",
        &BindGroupLayoutEntries::sequential(
            ShaderStages::COMPUTE,
            (
                uniform_buffer_sized(false, NonZeroU64::new(PARAMS_BYTES)),
                read(),
                read(),
                read(),
                read(),
                storage_buffer_sized(false, None),
                storage_buffer_sized(false, None),
                read(),
                storage_buffer_sized(false, None),
            ),
        ),
    );
    let draw_layout = BindGroupLayoutDescriptor::new(
        "hair drawn nodes",
        &BindGroupLayoutEntries::sequential(
            ShaderStages::COMPUTE,
            (
                uniform_buffer_sized(false, NonZeroU64::new(PARAMS_BYTES)),
                read(),
                read(),
                storage_buffer_sized(false, None),
            ),
        ),
    );
    let shader = asset_server.load(SHADER);
    let pipeline = |label: &'static str, layout: &BindGroupLayoutDescriptor, entry: &'static str| {
        pipeline_cache.queue_compute_pipeline(ComputePipelineDescriptor {
            label: Some(label.into()),
            layout: vec![layout.clone()],
            shader: shader.clone(),
            entry_point: Some(Cow::Borrowed(entry)),
            ..default()
        })
    };
    let frames = pipeline("hair guide frames", &place_layout, "frames");
    let place = pipeline("hair follower placement", &place_layout, "place");
    let draw = pipeline("hair drawn nodes", &draw_layout, "draw");
    commands.insert_resource(FollowerPipelines { place_layout, draw_layout, frames, place, draw });
}

/// What one head sends this frame: the layout when it changed, the step's data when a step came, the
/// interpolation fraction always.
#[derive(Default)]
struct HeadFeed {
    /// The buffer the hair material reads.
    drawn: AssetId<ShaderBuffer>,
    /// A new layout: per drawn node, per guide node, and where each guide starts.
    layout: Option<GuideLayoutData>,
    /// Whether `positions` … `colliders` hold a new step (only `colliders` when the GPU steps the guides).
    stepped: bool,
    /// The GPU steps the guides and hands them to the placement itself (`gather`).
    gpu_fed: bool,
    /// More than one step since the last frame: nothing to interpolate from.
    snap: bool,
    positions: Vec<f32>,
    frames: Vec<u8>,
    guides: Vec<[u32; 2]>,
    colliders: Vec<GpuCollider>,
    alpha: f32,
}

/// A layout as the GPU keeps it: [`GuideUpload::drawn_nodes`], [`GuideUpload::guide_of_node`],
/// [`GuideUpload::guide_starts`].
///
/// [`GuideUpload::drawn_nodes`]: super::feed::GuideUpload::drawn_nodes
/// [`GuideUpload::guide_of_node`]: super::feed::GuideUpload::guide_of_node
/// [`GuideUpload::guide_starts`]: super::feed::GuideUpload::guide_starts
struct GuideLayoutData {
    drawn_nodes: Vec<[u32; 4]>,
    guide_of_node: Vec<u32>,
    guide_starts: Vec<u32>,
    /// The guides' entities, when the GPU steps them.
    guides: Vec<Entity>,
}

/// One head's buffers on the GPU.
struct HeadBuffers {
    drawn_nodes: Buffer,
    guide_of_node: Buffer,
    guide_starts: Buffer,
    /// The director `m1` of each guide node's edge, made by `frames` each step.
    guide_frames: Buffer,
    guide_data: Buffer,
    colliders: Buffer,
    /// This step's and the step before's placements, alternating.
    placed: [Buffer; 2],
    params: Buffer,
    drawn_count: u32,
    guide_nodes: u32,
    guides: u32,
    colliders_capacity: usize,
}

/// `[parity] = (place, draw)`: the bind groups of the two passes for each way round of the placements.
type ParityBindGroups = [(BindGroup, BindGroup); 2];

/// One head in the render world.
#[derive(Default)]
struct GpuHead {
    feed: HeadFeed,
    buffers: Option<HeadBuffers>,
    /// Which of `placed` holds the last step.
    parity: usize,
    /// A step uploaded and not yet placed.
    place_due: bool,
    /// Whether a placement ran since the buffers were made.
    placed_once: bool,
    /// The next placement is written as the step before too (a placement was missed, or none ran yet).
    snap_all: bool,
    /// Colliders this step.
    collider_count: u32,
    /// The bind groups, made for the drawn buffer of this id.
    bind_groups: Option<(ParityBindGroups, AssetId<ShaderBuffer>)>,
    /// The guides' entities, when the GPU steps them.
    gpu_guides: Vec<Entity>,
    /// Where the GPU's stepped strands are gathered into this head's buffers: the target, the upload it
    /// was made for, and the head's index in it.
    #[cfg(feature = "gpu")]
    gather: Option<(crate::gpu::GpuGatherTarget, u32, usize)>,
    /// A step to gather before the placement.
    gather_due: bool,
    /// Seen in this frame's extraction.
    seen: bool,
}

/// Every head drawn with GPU followers, by its hair mesh entity in the main world.
#[derive(Resource, Default)]
pub(super) struct GpuHeads {
    heads: HashMap<Entity, GpuHead>,
    query: Option<QueryState<(Entity, &'static mut HairMesh)>>,
}

/// Moves each head's new layout and step from the main world (swapping the step's vectors, which are as
/// long on both sides, so nothing is copied).
pub(super) fn extract_gpu_followers(mut main_world: ResMut<MainWorld>, mut gpu: ResMut<GpuHeads>) {
    let gpu = &mut *gpu;
    let query = gpu.query.get_or_insert_with(|| main_world.query::<(Entity, &mut HairMesh)>());
    for head in gpu.heads.values_mut() {
        head.seen = false;
    }
    for (entity, mut hair_mesh) in query.iter_mut(&mut main_world) {
        // A head whose buffers the GPU keeps (hidden this frame, say) stays.
        if let Some(head) = gpu.heads.get_mut(&entity) {
            head.seen = hair_mesh.sends_to_gpu();
        }
        let Some(sent) = hair_mesh.take_gpu_frame() else { continue };
        let head = gpu.heads.entry(entity).or_default();
        head.seen = true;
        let drawn = hair_mesh.buffer.id();
        let feed = &mut head.feed;
        feed.drawn = drawn;
        feed.alpha = sent.alpha;
        feed.gpu_fed = hair_mesh.gpu_fed;
        if sent.layout {
            let guides = if hair_mesh.gpu_fed {
                hair_mesh.strips().guides().iter().map(|guide| guide.entity).collect()
            } else {
                Vec::new()
            };
            let upload = &mut hair_mesh.upload;
            feed.layout = Some(GuideLayoutData {
                drawn_nodes: std::mem::take(&mut upload.drawn_nodes),
                guide_of_node: std::mem::take(&mut upload.guide_of_node),
                guide_starts: upload.guide_starts(),
                guides,
            });
        }
        let upload = &mut hair_mesh.upload;
        if sent.step && feed.gpu_fed {
            feed.stepped = true;
            feed.snap |= sent.snap;
            feed.colliders.clone_from(&upload.colliders);
        } else if sent.step {
            feed.stepped = true;
            swap_or_copy(&mut feed.positions, &mut upload.positions);
            swap_or_copy(&mut feed.frames, &mut upload.frames);
            swap_or_copy(&mut feed.guides, &mut upload.guides);
            feed.colliders.clone_from(&upload.colliders);
        }
    }
    gpu.heads.retain(|_, head| head.seen);
}

/// Takes `main`'s contents into `render`: a swap when they are as long, so neither allocates.
fn swap_or_copy<T: Clone>(render: &mut Vec<T>, main: &mut Vec<T>) {
    if render.len() == main.len() {
        std::mem::swap(render, main);
    } else {
        render.clone_from(main);
    }
}

/// Makes each head's buffers for a new layout, writes a new step into them, and makes the bind groups.
pub(super) fn prepare_gpu_followers(
    mut gpu: ResMut<GpuHeads>,
    device: Res<RenderDevice>,
    queue: Res<RenderQueue>,
    pipelines: Option<Res<FollowerPipelines>>,
    pipeline_cache: Res<PipelineCache>,
    drawn_buffers: Res<RenderAssets<GpuShaderBuffer>>,
    #[cfg(feature = "gpu")] stepping: Option<Res<super::gpu_step::GpuHairRender>>,
) {
    let Some(pipelines) = pipelines else { return };
    for head in gpu.heads.values_mut() {
        if let Some(layout) = head.feed.layout.take() {
            head.buffers = Some(HeadBuffers::new(&device, &layout));
            head.bind_groups = None;
            (head.place_due, head.placed_once) = (false, false);
            head.gpu_guides = layout.guides;
            #[cfg(feature = "gpu")]
            {
                head.gather = None;
            }
        }
        #[cfg(feature = "gpu")]
        if let Some(stepping) = stepping.as_deref() {
            prepare_gather(head, stepping, &device);
        }
        let Some(buffers) = head.buffers.as_mut() else { continue };
        let feed = &mut head.feed;
        if feed.gpu_fed && std::mem::take(&mut feed.stepped) {
            // The guides are gathered on the GPU; only the colliders come from the CPU.
            if feed.colliders.len() > buffers.colliders_capacity {
                buffers.colliders_capacity = feed.colliders.len().next_power_of_two();
                buffers.colliders = colliders_buffer(&device, buffers.colliders_capacity);
                head.bind_groups = None;
            }
            if !feed.colliders.is_empty() {
                queue.write_buffer(&buffers.colliders, 0, bytemuck::cast_slice(&feed.colliders));
            }
            head.collider_count = feed.colliders.len() as u32;
            head.snap_all |= head.place_due || !head.placed_once || std::mem::take(&mut feed.snap);
            head.parity ^= 1;
            head.place_due = true;
            head.gather_due = true;
        } else if std::mem::take(&mut feed.stepped) {
            let words = step_words(feed.positions.len(), feed.frames.len(), feed.guides.len());
            if feed.positions.len() != 3 * buffers.guide_nodes as usize || feed.guides.len() != buffers.guides as usize
            {
                // A step for another layout than the buffers': wait for the layout.
                continue;
            }
            if feed.colliders.len() > buffers.colliders_capacity {
                buffers.colliders_capacity = feed.colliders.len().next_power_of_two();
                buffers.colliders = colliders_buffer(&device, buffers.colliders_capacity);
                head.bind_groups = None;
            }
            queue.write_buffer(&buffers.guide_data, 0, bytemuck::cast_slice(&feed.positions));
            queue.write_buffer(&buffers.guide_data, 4 * words.frames as u64, bytemuck::cast_slice(&feed.frames));
            queue.write_buffer(&buffers.guide_data, 4 * words.guides as u64, bytemuck::cast_slice(&feed.guides));
            if !feed.colliders.is_empty() {
                queue.write_buffer(&buffers.colliders, 0, bytemuck::cast_slice(&feed.colliders));
            }
            head.collider_count = feed.colliders.len() as u32;
            // A step that was not placed leaves nothing to interpolate from.
            head.snap_all |= head.place_due || !head.placed_once;
            head.parity ^= 1;
            head.place_due = true;
        }
        let words = step_words(3 * buffers.guide_nodes as usize, guide_frames(buffers.guide_nodes), 0);
        let params = [
            buffers.drawn_count,
            buffers.guide_nodes,
            buffers.guides,
            head.collider_count,
            words.frames,
            words.guides,
            feed.alpha.to_bits(),
            u32::from(head.snap_all),
        ];
        queue.write_buffer(&buffers.params, 0, bytemuck::cast_slice(&params));
        let drawn_id = feed.drawn;
        if head.bind_groups.as_ref().is_some_and(|(_, id)| *id != drawn_id) {
            head.bind_groups = None;
        }
        if head.bind_groups.is_none()
            && let Some(drawn) = drawn_buffers.get(drawn_id)
            && drawn.buffer.size() >= 12 * u64::from(buffers.drawn_count)
        {
            let place_layout = pipeline_cache.get_bind_group_layout(&pipelines.place_layout);
            let draw_layout = pipeline_cache.get_bind_group_layout(&pipelines.draw_layout);
            let groups = [0, 1].map(|parity| {
                let (now, before) = (&buffers.placed[parity], &buffers.placed[1 - parity]);
                let place = device.create_bind_group(
                    "hair follower placement",
                    &place_layout,
                    &BindGroupEntries::sequential((
                        buffers.params.as_entire_binding(),
                        buffers.drawn_nodes.as_entire_binding(),
                        buffers.guide_of_node.as_entire_binding(),
                        buffers.guide_data.as_entire_binding(),
                        buffers.colliders.as_entire_binding(),
                        now.as_entire_binding(),
                        before.as_entire_binding(),
                        buffers.guide_starts.as_entire_binding(),
                        buffers.guide_frames.as_entire_binding(),
                    )),
                );
                let draw = device.create_bind_group(
                    "hair drawn nodes",
                    &draw_layout,
                    &BindGroupEntries::sequential((
                        buffers.params.as_entire_binding(),
                        before.as_entire_binding(),
                        now.as_entire_binding(),
                        drawn.buffer.as_entire_binding(),
                    )),
                );
                (place, draw)
            });
            head.bind_groups = Some((groups, drawn_id));
        }
    }
}

/// Makes `head`'s gather target when the GPU steps its guides and there is none for the current upload:
/// each guide's strand and first node (a head with a guide not on the GPU gets none, and is not placed).
#[cfg(feature = "gpu")]
fn prepare_gather(head: &mut GpuHead, stepping: &super::gpu_step::GpuHairRender, device: &RenderDevice) {
    let (Some(solver), Some(buffers)) = (&stepping.solver, &head.buffers) else {
        head.gather = None;
        return;
    };
    if head.gpu_guides.is_empty()
        || head.gather.as_ref().is_some_and(|(_, generation, _)| *generation == stepping.generation)
    {
        return;
    }
    head.gather = None;
    let mut guides = Vec::with_capacity(head.gpu_guides.len() + 1);
    let mut first = 0_u32;
    let mut index = 0;
    for &entity in &head.gpu_guides {
        let Some(&strand) = stepping.index.get(&entity) else { return };
        index = stepping.strand_heads[strand as usize];
        guides.push([strand, first]);
        first += solver.node_count(strand as usize) as u32;
    }
    guides.push([0, first]);
    if first != buffers.guide_nodes {
        return;
    }
    let target = solver.gather_target(device.wgpu_device(), &guides, &buffers.guide_data, &buffers.guide_frames);
    head.gather = Some((target, stepping.generation, index));
}

/// Where the parts of a step's data start in the guide data buffer, in words, and its length.
struct StepWords {
    frames: u32,
    guides: u32,
    total: u32,
}

/// The layout of a step's data: `positions` floats, then `frame_bytes` bytes of frame codes (whole
/// words), then `guides` pairs of words.
fn step_words(positions: usize, frame_bytes: usize, guides: usize) -> StepWords {
    let frames_start = positions;
    let guides_start = frames_start + frame_bytes.div_ceil(4);
    StepWords { frames: frames_start as u32, guides: guides_start as u32, total: (guides_start + 2 * guides) as u32 }
}

/// Bytes of frame codes sent for `guide_nodes` nodes (padded to whole words).
fn guide_frames(guide_nodes: u32) -> usize {
    (FRAME_CODE_BYTES * guide_nodes as usize).next_multiple_of(4)
}

/// A storage buffer for `capacity` colliders (at least one, so that it can be bound).
fn colliders_buffer(device: &RenderDevice, capacity: usize) -> Buffer {
    device.create_buffer(&BufferDescriptor {
        label: Some("hair colliders"),
        size: (std::mem::size_of::<GpuCollider>() * capacity.max(1)) as u64,
        usage: BufferUsages::STORAGE | BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}

impl HeadBuffers {
    fn new(device: &RenderDevice, layout: &GuideLayoutData) -> Self {
        let GuideLayoutData { drawn_nodes, guide_of_node, guide_starts, .. } = layout;
        let guide_nodes = guide_of_node.len();
        let guides = guide_starts.len().saturating_sub(1);
        let with_data = |label: &'static str, contents: &[u8]| {
            // A binding may not be empty.
            let contents = if contents.is_empty() { &[0; 16][..] } else { contents };
            device.create_buffer_with_data(&BufferInitDescriptor {
                label: Some(label),
                contents,
                usage: BufferUsages::STORAGE,
            })
        };
        let empty = |label: &'static str, size: u64, usage: BufferUsages| {
            device.create_buffer(&BufferDescriptor {
                label: Some(label),
                size: size.max(16),
                usage,
                mapped_at_creation: false,
            })
        };
        let words = step_words(3 * guide_nodes, guide_frames(guide_nodes as u32), guides);
        let placed_bytes = 12 * drawn_nodes.len() as u64;
        Self {
            drawn_nodes: with_data("hair drawn node offsets", bytemuck::cast_slice(drawn_nodes)),
            guide_of_node: with_data("hair guide of each node", bytemuck::cast_slice(guide_of_node)),
            guide_starts: with_data("hair guide starts", bytemuck::cast_slice(guide_starts)),
            guide_frames: empty("hair guide frames", 16 * guide_nodes as u64, BufferUsages::STORAGE),
            guide_data: empty(
                "hair guide data",
                4 * u64::from(words.total),
                BufferUsages::STORAGE | BufferUsages::COPY_DST,
            ),
            colliders: colliders_buffer(device, 1),
            placed: [0, 1].map(|_| empty("hair follower placement", placed_bytes, BufferUsages::STORAGE)),
            params: empty("hair follower parameters", PARAMS_BYTES, BufferUsages::UNIFORM | BufferUsages::COPY_DST),
            drawn_count: drawn_nodes.len() as u32,
            guide_nodes: guide_nodes as u32,
            guides: guides as u32,
            colliders_capacity: 1,
        }
    }
}

/// The workgroups of a dispatch over `invocations`: along X up to the limit, then rows along Y.
fn workgroups(invocations: u32) -> (u32, u32) {
    let groups = invocations.div_ceil(WORKGROUP);
    if groups <= MAX_GROUPS { (groups.max(1), 1) } else { (MAX_GROUPS, groups.div_ceil(MAX_GROUPS)) }
}

/// Walks each head's guide frames and places its followers when a step came, and writes every drawn node
/// for this frame (in the render graph, before the cameras draw).
#[allow(clippy::too_many_arguments)]
pub(super) fn dispatch_gpu_followers(
    mut render_context: RenderContext,
    mut gpu: ResMut<GpuHeads>,
    pipelines: Option<Res<FollowerPipelines>>,
    pipeline_cache: Res<PipelineCache>,
    #[cfg(feature = "gpu")] stepping: Option<Res<super::gpu_step::GpuHairRender>>,
    #[cfg(feature = "gpu")] queue: Res<RenderQueue>,
    uploads: Res<super::draw::HairUploads>,
    buffers: Res<RenderAssets<GpuShaderBuffer>>,
) {
    let Some(pipelines) = pipelines else { return };
    let pipeline = |id| pipeline_cache.get_compute_pipeline(id);
    let (Some(frames), Some(place), Some(draw)) =
        (pipeline(pipelines.frames), pipeline(pipelines.place), pipeline(pipelines.draw))
    else {
        return;
    };
    if !gpu.heads.values().any(|head| head.buffers.is_some() && head.bind_groups.is_some()) {
        return;
    }
    // The GPU's stepped strands gathered into the heads they feed, before their placement.
    for head in gpu.heads.values_mut() {
        if !std::mem::take(&mut head.gather_due) {
            continue;
        }
        #[cfg(feature = "gpu")]
        if let (Some(stepping), Some((target, _, index)), Some(buffers)) =
            (stepping.as_deref(), &head.gather, &head.buffers)
            && let Some(solver) = &stepping.solver
        {
            let words = step_words(3 * buffers.guide_nodes as usize, guide_frames(buffers.guide_nodes), 0);
            solver.record_gather(&queue, render_context.command_encoder(), target, *index, words.guides);
            continue;
        }
        // Nothing to gather from: not placed.
        head.place_due = false;
    }
    let mut pass = render_context
        .command_encoder()
        .begin_compute_pass(&ComputePassDescriptor { label: Some("hair followers"), ..default() });
    for head in gpu.heads.values_mut() {
        let (Some(buffers), Some((groups, _))) = (&head.buffers, &head.bind_groups) else { continue };
        if buffers.drawn_count == 0 {
            continue;
        }
        let (x, y) = workgroups(buffers.drawn_count);
        let (place_group, draw_group) = &groups[head.parity];
        if std::mem::take(&mut head.place_due) {
            (head.placed_once, head.snap_all) = (true, false);
            // The guides' frames, walked from each root (gathered with them when the GPU steps them), then
            // the followers placed in them.
            pass.set_bind_group(0, place_group, &[]);
            if !head.feed.gpu_fed {
                let (guides_x, guides_y) = workgroups(buffers.guides);
                pass.set_pipeline(frames);
                pass.dispatch_workgroups(guides_x, guides_y, 1);
            }
            pass.set_pipeline(place);
            pass.dispatch_workgroups(x, y, 1);
        }
        pass.set_pipeline(draw);
        pass.set_bind_group(0, draw_group, &[]);
        pass.dispatch_workgroups(x, y, 1);
    }
    drop(pass);
    // A head drawn for the first time while a camera draws motion vectors starts still: its frame before
    // is what was just drawn (see `upload_hair_positions`).
    super::draw::copy_drawn_to_previous(uploads.first_drawn(), &buffers, render_context.command_encoder());
}
