//! The render plugin: one mesh and one material per head, the node buffer handed to the GPU each frame.

use bevy::asset::{RenderAssetUsages, embedded_asset};
use bevy::camera::primitives::Aabb;
use bevy::camera::visibility::{NoAutoAabb, NoFrustumCulling};
use bevy::core_pipeline::prepass::MotionVectorPrepass;
use bevy::ecs::query::QueryState;
use bevy::mesh::{Indices, MeshVertexAttribute, MeshVertexBufferLayoutRef, PrimitiveTopology};
use bevy::pbr::{MaterialPipeline, MaterialPipelineKey, MeshPipelineKey};
use bevy::platform::collections::HashSet;
use bevy::prelude::*;
use bevy::render::render_asset::RenderAssets;
use bevy::render::render_resource::{
    AsBindGroup, CommandEncoder, CommandEncoderDescriptor, Face, RenderPipelineDescriptor, ShaderType,
    SpecializedMeshPipelineError, VertexFormat,
};
use bevy::render::renderer::RenderGraphSystems;
use bevy::render::renderer::{RenderDevice, RenderGraph, RenderQueue};
use bevy::render::storage::{GpuShaderBuffer, ShaderBuffer};
use bevy::render::{ExtractSchedule, MainWorld, Render, RenderApp, RenderStartup, RenderSystems};
use bevy::shader::{ShaderDefVal, ShaderRef};
use bevy::tasks::ComputeTaskPool;

use super::feed::{GpuCollider, GuideUpload, LayoutChanged};
use super::followers::{self, GpuHeads};
use super::{GuideLayout, HairAppearance, HairStrips};
use crate::followers::{FollowerNodes, FollowerPlacement};
use crate::groom::{StrandColors, StrandWidths};
use crate::schedule::HairDrawSystems;
use crate::simulation::{
    CheckedSettings, HairHead, HeadMotion, HeadStrands, PackedStrandPose, SimulatedStrand, SteppedElsewhere,
    StrandColliders, StrandFrames, StrandNodes, StrandOf,
};
use crate::volume::RepresentedHairs;

/// The shader: vertex expansion, hair shading, and the shadow (prepass) vertex stage.
const SHADER: &str = "embedded://bevy_hair_sim/render/draw.wgsl";

/// The template mesh's one vertex attribute (see [`HairStrips::vertices`]).
const ATTRIBUTE_HAIR_VERTEX: MeshVertexAttribute =
    MeshVertexAttribute::new("HairVertex", 0x4841_4952, VertexFormat::Uint32x4);
/// A hair's own colour at the vertex's node, sRGB bytes with alpha 255, or 0 ([`HairStrips::colors`]).
const ATTRIBUTE_HAIR_COLOR: MeshVertexAttribute =
    MeshVertexAttribute::new("HairColor", 0x4841_4943, VertexFormat::Uint32);

/// Draws the hair of every [`HairHead`] as lit, shadowed strands (see the [module documentation](super)).
/// Needs Bevy's renderer and PBR (`DefaultPlugins`); part of [`crate::HairPlugins`] with the crate's
/// `render` feature.
#[derive(Debug, Clone, Copy, Default)]
pub struct HairRenderPlugin;

impl Plugin for HairRenderPlugin {
    fn build(&self, app: &mut App) {
        app.register_type::<HairAppearance>();
        if !app.is_plugin_added::<bevy::pbr::PbrPlugin>() {
            warn!("HairRenderPlugin: Bevy's PbrPlugin is missing (add DefaultPlugins first), so hair is not rendered");
            return;
        }
        // The hair mesh is the head's child: a head with no visibility of its own would hide nothing and
        // warn (B0004). A head spawned with its own `Visibility` keeps it.
        app.register_required_components::<HairHead, Visibility>();
        embedded_asset!(app, "draw.wgsl");
        embedded_asset!(app, "followers.wgsl");
        // The followers are placed where they are drawn unless the app asked for the CPU.
        if !app.world().contains_resource::<FollowerPlacement>() {
            app.insert_resource(FollowerPlacement::Gpu);
        }
        app.add_plugins(MaterialPlugin::<HairMaterial>::default())
            // The hair mesh's transform and bounds, set here, are the ones this frame is culled with.
            .configure_sets(
                PostUpdate,
                HairDrawSystems.before(bevy::camera::visibility::VisibilitySystems::CheckVisibility),
            )
            .add_systems(PostUpdate, (spawn_hair_meshes, prepare_hair_meshes).chain().in_set(HairDrawSystems));
        if let Some(render_app) = app.get_sub_app_mut(RenderApp) {
            render_app
                .init_resource::<HairUploads>()
                .init_resource::<GpuHeads>()
                .add_systems(RenderStartup, followers::init_follower_pipelines)
                .add_systems(ExtractSchedule, (extract_hair_positions, followers::extract_gpu_followers))
                .add_systems(
                    Render,
                    (upload_hair_positions, followers::prepare_gpu_followers).in_set(RenderSystems::PrepareResources),
                )
                .add_systems(RenderGraph, followers::dispatch_gpu_followers.in_set(RenderGraphSystems::Begin));
        }
    }
}

/// The material hair is drawn with: the head's node buffer and its [`HairShading`]. Made and updated by
/// the [`HairRenderPlugin`] from the head's [`HairAppearance`].
#[derive(Asset, TypePath, AsBindGroup, Debug, Clone)]
pub struct HairMaterial {
    /// Node positions, `x y z` per node (world space where the hair was stepped, m; the mesh's transform
    /// carries them onto the head as it is drawn), written every frame.
    #[storage(0, read_only)]
    pub positions: Handle<ShaderBuffer>,
    /// Colours and highlights.
    #[uniform(1)]
    pub shading: HairShading,
    /// The positions drawn the frame before, laid out like `positions`: where the motion-vector prepass
    /// draws each hair from, so that Bevy's temporal anti-aliasing and motion blur follow the hair.
    #[storage(2, read_only)]
    pub previous_positions: Handle<ShaderBuffer>,
}

/// [`HairAppearance`] as the shader reads it (linear colours, highlight shifts and exponents).
#[derive(ShaderType, Debug, Clone, Copy, PartialEq)]
pub struct HairShading {
    /// Linear colour at the root.
    pub root_color: Vec4,
    /// Linear colour at the tip.
    pub tip_color: Vec4,
    /// Primary highlight shift, secondary highlight shift (rad), primary and secondary lobes' squared
    /// angular widths (rad²).
    pub highlights: Vec4,
    /// Specular strength, colour variation, minimum width in pixels, root occlusion.
    pub parameters: Vec4,
    /// Light penetration, m (0: the shadow maps' hard shadows), the highlights' filtering, and two unused.
    pub deep_shadows: Vec4,
}

impl From<&HairAppearance> for HairShading {
    fn from(appearance: &HairAppearance) -> Self {
        let tilt = appearance.cuticle_tilt;
        // A lobe of angular width β is sin(t, h)^p with p = 1/β² (cos^p Δ ≈ exp(−p Δ²/2)); the shader
        // widens it by the pixel's spread of directions first (`HairAppearance::highlight_filtering`).
        let width = appearance.highlight_width.max(1e-3);
        Self {
            root_color: appearance.root_color.to_linear().to_vec4(),
            tip_color: appearance.tip_color.to_linear().to_vec4(),
            highlights: Vec4::new(-2.0 * tilt, 3.0 * tilt, width * width, 4.0 * width * width),
            parameters: Vec4::new(
                appearance.specular,
                appearance.color_variation,
                appearance.min_pixel_width,
                appearance.root_occlusion,
            ),
            deep_shadows: Vec4::new(appearance.light_penetration, appearance.highlight_filtering, 0.0, 0.0),
        }
    }
}

impl Material for HairMaterial {
    fn vertex_shader() -> ShaderRef {
        SHADER.into()
    }

    fn fragment_shader() -> ShaderRef {
        SHADER.into()
    }

    fn prepass_vertex_shader() -> ShaderRef {
        SHADER.into()
    }

    /// A camera's prepasses (depth, normals, motion vectors) on the samples the main pass covers.
    fn prepass_fragment_shader() -> ShaderRef {
        SHADER.into()
    }

    /// Bevy's multisampled pipeline without blending (or a discarding one without MSAA). The shader's
    /// alpha stays 1: coverage goes out as a sample mask of its own (see the module docs).
    fn alpha_mode(&self) -> AlphaMode {
        AlphaMode::AlphaToCoverage
    }

    fn specialize(
        _pipeline: &MaterialPipeline,
        descriptor: &mut RenderPipelineDescriptor,
        layout: &MeshVertexBufferLayoutRef,
        key: MaterialPipelineKey<Self>,
    ) -> Result<(), SpecializedMeshPipelineError> {
        // Both attributes in every pass; the prepasses' shader reads only the first.
        descriptor.vertex.buffers =
            vec![layout.0.get_layout(&[
                ATTRIBUTE_HAIR_VERTEX.at_shader_location(0),
                ATTRIBUTE_HAIR_COLOR.at_shader_location(1),
            ])?];
        // The fragment stage writes its coverage as a sample mask: it needs the sample count (and both
        // stages compile the whole file).
        // Bevy's prepasses do not say whether they are multisampled (`HAIR_MULTISAMPLED`), nor whether
        // they draw for a camera, which takes the hair's coverage like the main pass, or for a shadow map,
        // which takes whole ribbons (`HAIR_CAMERA_PREPASS`; a shadow map is never multisampled, and a
        // camera's prepass without multisampling is told apart by its normals or motion vectors).
        let multisampled = key.mesh_key.msaa_samples() > 1;
        let camera = multisampled
            || key.mesh_key.intersects(MeshPipelineKey::NORMAL_PREPASS | MeshPipelineKey::MOTION_VECTOR_PREPASS);
        let definitions = [
            Some(ShaderDefVal::UInt("HAIR_MSAA_SAMPLES".into(), key.mesh_key.msaa_samples())),
            multisampled.then(|| "HAIR_MULTISAMPLED".into()),
            camera.then(|| "HAIR_CAMERA_PREPASS".into()),
        ];
        descriptor.vertex.shader_defs.extend(definitions.iter().flatten().cloned());
        if let Some(fragment) = descriptor.fragment.as_mut() {
            fragment.shader_defs.extend(definitions.into_iter().flatten());
        }
        // A ribbon faces the eye in the main pass and the light in a shadow pass: never cull it.
        descriptor.primitive.cull_mode = None::<Face>;
        Ok(())
    }
}

/// The entity that draws one head's hair: a child of the head, with the mesh and material the plugin
/// keeps. Hide it (its `Visibility`) to hide the rendered hair; the gizmo lines, off with the renderer,
/// come back with [`HairGizmos::draw_strands`](crate::debug::HairGizmos::draw_strands).
#[derive(Component, Debug, Default)]
#[require(NoAutoAabb)]
pub struct HairMesh {
    strips: HairStrips,
    /// Whether the positions were written this frame (and not yet handed to the GPU).
    fresh: bool,
    /// What the GPU places the followers from ([`FollowerPlacement::Gpu`]).
    pub(super) upload: GuideUpload,
    /// Whether `upload` follows the strips' layout.
    upload_laid_out: bool,
    /// What this frame sends to the GPU's follower placement, if anything (not yet extracted).
    gpu_frame: Option<GpuFrame>,
    /// The fixed clock at the last step packed into `upload`, s.
    packed_at: Option<f64>,
    /// Whether every guide is stepped on the GPU, which hands them to the placement itself
    /// ([`crate::render::HairGpuPlugin`]): nothing is packed on the CPU.
    pub(super) gpu_fed: bool,
    /// The GPU's upload and step count last seen ([`GpuStepCount`]).
    gpu_seen: GpuStepCount,
    /// Bounds of the last two steps' drawn hair, world space where it was stepped (the mesh's own space).
    step_bounds: [Option<(Vec3, Vec3)>; 2],
    /// The appearance drawn (the last valid one asked for).
    appearance: Option<HairAppearance>,
    /// The appearance last asked for, valid or not.
    requested: Option<HairAppearance>,
    pub(super) buffer: Handle<ShaderBuffer>,
    /// What `buffer` held the frame before (copied on the GPU at the start of each frame).
    previous_buffer: Handle<ShaderBuffer>,
}

/// What one frame sends to the GPU's follower placement.
#[derive(Debug, Clone, Copy)]
pub(super) struct GpuFrame {
    /// A new layout ([`GuideUpload::drawn_nodes`], [`GuideUpload::guide_of_node`]).
    pub(super) layout: bool,
    /// A new step (the guides' nodes, frames, words and colliders).
    pub(super) step: bool,
    /// The fraction of the way from the step before to the last to draw.
    pub(super) alpha: f32,
    /// More than one step came since the last frame: nothing to interpolate from.
    pub(super) snap: bool,
}

/// How many uploads and steps the GPU's stepping has sent ([`crate::render::HairGpuPlugin`]), for the
/// drawing to see that its guides moved.
#[derive(Resource, Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(super) struct GpuStepCount {
    pub(super) generation: u32,
    pub(super) steps: u64,
}

impl HairMesh {
    /// The head's hair as laid out for drawing, with this frame's node positions when the CPU writes them
    /// ([`FollowerPlacement::Cpu`]; with the GPU's placement the GPU writes them and these stay as they
    /// were).
    pub fn strips(&self) -> &HairStrips {
        &self.strips
    }

    /// What the GPU places the followers from, as last sent ([`FollowerPlacement::Gpu`]): the step's data
    /// stays here until the render world takes it.
    pub fn upload(&self) -> &GuideUpload {
        &self.upload
    }

    /// The storage buffer the hair material reads its node positions from (`x y z` per node, world
    /// space, m, in the order of [`HairMesh::strips`]): written by the GPU's follower placement
    /// ([`FollowerPlacement::Gpu`]) or uploaded from [`HairStrips`]. Read it back with Bevy's
    /// `Readback::buffer` to see what is drawn.
    pub fn positions_buffer(&self) -> &Handle<ShaderBuffer> {
        &self.buffer
    }

    /// The storage buffer of the positions drawn the frame before, laid out like
    /// [`HairMesh::positions_buffer`]: the GPU copies one into the other at the start of every frame, before
    /// this frame's positions are written, and the motion-vector prepass draws the hair from both.
    pub fn previous_positions_buffer(&self) -> &Handle<ShaderBuffer> {
        &self.previous_buffer
    }

    /// Whether the GPU places the followers and draws the nodes (it has their layout).
    pub(super) fn sends_to_gpu(&self) -> bool {
        self.upload_laid_out
    }

    /// This frame's data for the GPU's placement, once.
    pub(super) fn take_gpu_frame(&mut self) -> Option<GpuFrame> {
        self.gpu_frame.take()
    }
}

/// Marks a head whose [`HairMesh`] child exists.
#[derive(Component)]
struct HasHairMesh;

/// A head with strands and no [`HairMesh`] yet.
type HeadWithoutHairMesh = (With<HairHead>, With<HeadStrands>, Without<HasHairMesh>);

/// Gives every head with strands a [`HairMesh`] child.
fn spawn_hair_meshes(
    mut commands: Commands,
    heads: Query<Entity, HeadWithoutHairMesh>,
    mut materials: ResMut<Assets<HairMaterial>>,
) {
    for head in &heads {
        let material = materials.add(HairMaterial {
            positions: Handle::default(),
            shading: HairShading::from(&HairAppearance::default()),
            previous_positions: Handle::default(),
        });
        commands.entity(head).insert(HasHairMesh);
        commands.spawn((
            Name::new("Hair mesh"),
            HairMesh::default(),
            ChildOf(head),
            // The mesh comes with the first layout.
            Mesh3d::default(),
            MeshMaterial3d(material),
            Aabb::default(),
            Transform::default(),
            Visibility::default(),
        ));
    }
}

/// What [`prepare_hair_meshes`] reads of a head: its strands, where it is this frame, where it was at the
/// last two steps, and its look.
type DrawnHead =
    (Ref<'static, HeadStrands>, &'static GlobalTransform, &'static HeadMotion, Option<&'static HairAppearance>);

/// What [`prepare_hair_meshes`] keeps up to date of a head's [`HairMesh`] entity.
type HairMeshParts = (
    Entity,
    &'static mut HairMesh,
    &'static ChildOf,
    &'static mut Mesh3d,
    &'static MeshMaterial3d<HairMaterial>,
    &'static mut Aabb,
    &'static InheritedVisibility,
    &'static mut GlobalTransform,
);

/// What the renderer reads of each guide it draws, in one lookup: its strand, nodes, followers, the hairs it
/// stands for, its frames and the pose the step packed for it.
pub type DrawnStrand = (
    &'static SimulatedStrand,
    &'static StrandNodes,
    Option<&'static FollowerNodes>,
    Option<&'static RepresentedHairs>,
    &'static StrandFrames,
    Option<&'static PackedStrandPose>,
);

/// The layout of the guide `entity` as it is now, and the pose the step packed for it, if any.
fn guide_now<'a>(
    strands: &'a Query<DrawnStrand>,
    entity: Entity,
) -> Option<(GuideLayout, Option<&'a PackedStrandPose>)> {
    let (strand, nodes, followers, represented, _, pose) = strands.get(entity).ok()?;
    Some((GuideLayout::drawn(entity, strand, nodes, followers, represented), pose))
}

/// Lays out each head's hair when its strands change, rebuilding the mesh and buffer then; writes this
/// frame's node positions (or has the GPU place them); keeps the bounds and the material up to date.
///
/// With the GPU's placement, a head whose strands are all laid out is not looked over every frame: the
/// step's data is checked against the layout guide by guide as it is packed, once per step (a change is
/// seen at the next step), and the whole head again when its list of strands changes.
#[allow(clippy::too_many_arguments)]
fn prepare_hair_meshes(
    mut commands: Commands,
    fixed_time: Res<Time<Fixed>>,
    placement: Option<Res<FollowerPlacement>>,
    checked: Res<CheckedSettings>,
    colliders: StrandColliders,
    mut hair_meshes: Query<HairMeshParts>,
    heads: Query<DrawnHead, Without<HairMesh>>,
    strands: Query<DrawnStrand>,
    (colors, widths): (Query<&StrandColors>, Query<&StrandWidths>),
    gpu_steps: Option<Res<GpuStepCount>>,
    stepped_elsewhere: Query<(), With<SteppedElsewhere>>,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<HairMaterial>>,
    mut buffers: ResMut<Assets<ShaderBuffer>>,
) {
    let alpha = fixed_time.overstep_fraction().clamp(0.0, 1.0);
    let threads = ComputeTaskPool::try_get().map_or(1, |pool| pool.thread_num());
    let on_gpu = placement.is_some_and(|placement| *placement == FollowerPlacement::Gpu);
    let gpu_steps = gpu_steps.map(|count| *count);
    for (entity, mut hair_mesh, child_of, mut mesh, material, mut aabb, visibility, mut carried) in &mut hair_meshes {
        let Ok((head_strands, head_transform, motion, appearance)) = heads.get(child_of.parent()) else { continue };
        if !visibility.get() {
            continue;
        }
        // The nodes are drawn where they were stepped, carried onto the head as it is now (its transform
        // propagated this frame): the mesh's own transform, set over the one propagated from the head.
        *carried = GlobalTransform::from(motion.drawn_to_now(alpha, head_transform));
        // A new appearance is checked once; an invalid one is reported and the last valid one kept.
        let requested = appearance.cloned().unwrap_or_default();
        let mut appearance = hair_mesh.appearance.clone().unwrap_or_default();
        if hair_mesh.requested.as_ref() != Some(&requested) {
            match requested.validate() {
                Ok(()) => appearance = requested.clone(),
                Err(reason) => error!(
                    "hair of head {}: its HairAppearance cannot be drawn ({reason}); it keeps its last look",
                    child_of.parent()
                ),
            }
            hair_mesh.requested = Some(requested);
        }
        let appearance_changed = hair_mesh.appearance.as_ref() != Some(&appearance);
        let layout = || head_strands.strands().iter().filter_map(|&entity| Some(guide_now(&strands, entity)?.0));
        let look_over = !on_gpu
            || !hair_mesh.upload_laid_out
            || head_strands.is_changed()
            || hair_mesh.strips.guides().len() != head_strands.strands().len();
        let mut relaid = look_over && hair_mesh.strips.set_layout(layout());
        // A new set of strands on the GPU: which heads it feeds may have changed.
        if let Some(count) = gpu_steps
            && on_gpu
            && (relaid || count.generation != hair_mesh.gpu_seen.generation)
        {
            let guides = hair_mesh.strips.guides();
            let fed = !guides.is_empty() && guides.iter().all(|guide| stepped_elsewhere.contains(guide.entity));
            if fed != hair_mesh.gpu_fed {
                // Its guides now come from the GPU (or no longer): the bounds are not known on the CPU.
                if fed {
                    commands.entity(entity).insert(NoFrustumCulling);
                } else {
                    commands.entity(entity).remove::<NoFrustumCulling>();
                }
                hair_mesh.gpu_fed = fed;
                hair_mesh.upload_laid_out = false;
            }
            hair_mesh.gpu_seen = GpuStepCount { generation: count.generation, steps: hair_mesh.gpu_seen.steps };
        }
        hair_mesh.gpu_fed &= on_gpu && gpu_steps.is_some();
        let bounds = if on_gpu && hair_mesh.gpu_fed {
            hair_mesh.fresh = false;
            let steps = gpu_steps.map_or(0, |count| count.steps);
            let colliders = colliders.of(Some(&StrandOf(child_of.parent())));
            Ok(send_gpu_fed(&mut hair_mesh, relaid, alpha, steps, colliders, &strands))
        } else if on_gpu {
            hair_mesh.fresh = false;
            let head = StrandOf(child_of.parent());
            let context =
                GpuContext { fixed_time: &fixed_time, alpha, threads, margin: checked.collision_margin as f32 };
            let mut send = |hair_mesh: &mut HairMesh, relaid| {
                send_to_gpu(hair_mesh, relaid, &context, colliders.of(Some(&head)), &strands, &mut commands)
            };
            send(&mut hair_mesh, relaid).or_else(|LayoutChanged| {
                // Laid out again from the same components, the layout holds.
                relaid = hair_mesh.strips.set_layout(layout());
                hair_mesh.upload_laid_out = false;
                send(&mut hair_mesh, relaid)
            })
        } else {
            hair_mesh.upload_laid_out = false;
            let lookup = |entity| strands.get(entity).ok().map(|(_, nodes, followers, ..)| (nodes, followers));
            let bounds = hair_mesh.strips.fill(alpha, threads, lookup);
            hair_mesh.fresh = bounds.is_some();
            Ok(bounds)
        };
        let template_changed = hair_mesh.appearance.as_ref().is_none_or(|old| {
            (old.thickness_scale, old.tip_taper, old.length_variation)
                != (appearance.thickness_scale, appearance.tip_taper, appearance.length_variation)
        });
        if relaid || template_changed {
            let strips = &hair_mesh.strips;
            let mut template = Mesh::new(PrimitiveTopology::TriangleList, RenderAssetUsages::RENDER_WORLD);
            template.insert_attribute(
                ATTRIBUTE_HAIR_VERTEX,
                strips.vertices(
                    (appearance.thickness_scale, appearance.tip_taper, appearance.length_variation),
                    |entity| widths.get(entity).ok(),
                ),
            );
            template.insert_attribute(ATTRIBUTE_HAIR_COLOR, strips.colors(|entity| colors.get(entity).ok()));
            template.insert_indices(Indices::U32(strips.indices()));
            mesh.0 = meshes.add(template);
        }
        if relaid {
            // The buffer lives as long as the layout; each frame's positions go to it directly
            // (`upload_hair_positions`), not through the asset.
            let size = (4 * hair_mesh.strips.positions().len()).max(16);
            hair_mesh.buffer = buffers.add(ShaderBuffer::with_size(size, RenderAssetUsages::RENDER_WORLD));
            hair_mesh.previous_buffer = buffers.add(ShaderBuffer::with_size(size, RenderAssetUsages::RENDER_WORLD));
        }
        if (relaid || appearance_changed)
            && let Some(mut material) = materials.get_mut(&material.0)
        {
            material.positions = hair_mesh.buffer.clone();
            material.previous_positions = hair_mesh.previous_buffer.clone();
            material.shading = HairShading::from(&appearance);
        }
        if appearance_changed {
            hair_mesh.appearance = Some(appearance);
        }
        if let Ok(Some((low, high))) = bounds {
            // The ribbons reach a hair's radius (or a pixel) beyond the nodes: a centimetre covers both.
            *aabb = Aabb::from_min_max(low - Vec3::splat(0.01), high + Vec3::splat(0.01));
        }
    }
}

/// What [`send_to_gpu`] needs of the frame.
struct GpuContext<'a> {
    fixed_time: &'a Time<Fixed>,
    alpha: f32,
    threads: usize,
    /// The collision margin of the last valid settings, m.
    margin: f32,
}

/// Prepares what the GPU's follower placement needs this frame (see [`super::feed`]): the layout when the
/// strips were laid out again (`relaid`) or the upload has none, the guides' data when a step came since
/// the last frame, the interpolation fraction always. Returns the bounds of the last two steps' hair, or
/// [`LayoutChanged`] (before anything is sent) when a guide is no longer as laid out. A new layout gives
/// its guides a [`PackedStrandPose`] for the step to write.
fn send_to_gpu(
    hair_mesh: &mut HairMesh,
    relaid: bool,
    context: &GpuContext,
    colliders: &[crate::rod::MovingCollider],
    strands: &Query<DrawnStrand>,
    commands: &mut Commands,
) -> Result<Option<(Vec3, Vec3)>, LayoutChanged> {
    let HairMesh { strips, upload, .. } = hair_mesh;
    let now = context.fixed_time.elapsed_secs_f64();
    let step = context.fixed_time.timestep().as_secs_f64();
    let steps_since = |packed_at: Option<f64>| packed_at.map(|packed| ((now - packed) / step).round());
    let layout = relaid || !hair_mesh.upload_laid_out;
    if layout {
        let followers_of = |guide: &GuideLayout| strands.get(guide.entity).ok().and_then(|strand| strand.2);
        upload.set_layout(strips.guides().iter().map(|guide| (*guide, followers_of(guide))));
        // Made here in drawing order, the poses lie in memory in the order they are read.
        for guide in strips.guides() {
            if strands.get(guide.entity).is_ok_and(|strand| strand.5.is_none()) {
                commands.entity(guide.entity).try_insert(PackedStrandPose::with_capacity(guide.nodes as usize));
            }
        }
        hair_mesh.upload_laid_out = true;
        hair_mesh.packed_at = None;
    }
    let steps = steps_since(hair_mesh.packed_at);
    let stepped = steps.is_none_or(|steps| steps >= 1.0);
    if stepped {
        let unpacked = |entity, pose: &mut PackedStrandPose| {
            let Ok((strand, nodes, _, _, frames, _)) = strands.get(entity) else { return false };
            pose.write_from_components(nodes, frames, strand.collision_thickness(context.margin));
            true
        };
        // After more than one step (or none packed yet) there is no step before to interpolate from.
        let snap_all = steps.is_none_or(|steps| steps > 1.0);
        let guide_of = |entity| guide_now(strands, entity);
        let bounds = upload.pack(context.threads, colliders, snap_all, guide_of, unpacked)?;
        hair_mesh.step_bounds = [hair_mesh.step_bounds[1], bounds];
        hair_mesh.packed_at = Some(now);
    }
    hair_mesh.gpu_frame = Some(GpuFrame { layout, step: stepped, alpha: context.alpha, snap: false });
    let [before, last] = hair_mesh.step_bounds;
    Ok(match (before, last) {
        (Some((a, b)), Some((c, d))) => Some((a.min(c), b.max(d))),
        (one, other) => one.or(other),
    })
}

/// Prepares what the GPU's follower placement needs this frame for a head whose guides the GPU steps and
/// hands to the placement itself: the layout when it changed, the colliders and whether the GPU stepped
/// since the last frame (`steps`: the steps sent so far). Nothing is packed; the bounds are not known on
/// the CPU (the mesh is not culled).
fn send_gpu_fed(
    hair_mesh: &mut HairMesh,
    relaid: bool,
    alpha: f32,
    steps: u64,
    colliders: &[crate::rod::MovingCollider],
    strands: &Query<DrawnStrand>,
) -> Option<(Vec3, Vec3)> {
    let HairMesh { strips, upload, .. } = hair_mesh;
    let layout = relaid || !hair_mesh.upload_laid_out;
    if layout {
        let followers_of = |guide: &GuideLayout| strands.get(guide.entity).ok().and_then(|strand| strand.2);
        upload.set_layout(strips.guides().iter().map(|guide| (*guide, followers_of(guide))));
        hair_mesh.upload_laid_out = true;
    }
    let new_steps = steps.saturating_sub(hair_mesh.gpu_seen.steps);
    hair_mesh.gpu_seen.steps = steps;
    let stepped = new_steps > 0;
    if stepped {
        upload.colliders.clear();
        upload.colliders.extend(colliders.iter().filter_map(GpuCollider::new));
    }
    hair_mesh.gpu_frame = Some(GpuFrame { layout, step: stepped, alpha, snap: layout || new_steps > 1 });
    None
}

/// This frame's node positions of each head, moved from the main world, with the buffer they go to; and
/// every drawn head's buffers of this frame's and last frame's positions.
#[derive(Resource, Default)]
pub(super) struct HairUploads {
    uploads: Vec<(AssetId<ShaderBuffer>, Vec<f32>)>,
    /// While a camera draws motion vectors, the buffers of this frame's and last frame's positions of each
    /// head whose frame before was kept: last frame's are copied in before this frame's are written.
    drawn: Vec<[AssetId<ShaderBuffer>; 2]>,
    /// The same for each head whose frame before was not kept (a head drawn for the first time, or for the
    /// first time while a camera draws motion vectors): its previous positions are made this frame's once
    /// those are written, so that its first motion vectors are zero rather than from wherever the buffer
    /// last was.
    first_drawn: Vec<[AssetId<ShaderBuffer>; 2]>,
    /// The drawn buffers whose frame before was kept last frame, and this frame's (swapped each frame).
    kept: [HashSet<AssetId<ShaderBuffer>>; 2],
    query: Option<QueryState<&'static mut HairMesh>>,
    cameras: Option<QueryState<(), With<MotionVectorPrepass>>>,
}

/// Swaps each head's freshly written positions with the render world's (equally long) buffer from the
/// frame before, so that no bytes are copied or allocated here; and, while a camera draws motion vectors,
/// lists every head's buffers of this frame's and last frame's positions.
fn extract_hair_positions(mut main_world: ResMut<MainWorld>, mut uploads: ResMut<HairUploads>) {
    let uploads = &mut *uploads;
    let query = uploads.query.get_or_insert_with(|| main_world.query::<&mut HairMesh>());
    let mut count = 0;
    // The frame before is kept only while a camera draws motion vectors.
    let cameras = uploads.cameras.get_or_insert_with(|| main_world.query_filtered());
    let motion_vectors = cameras.iter(&main_world).next().is_some();
    uploads.drawn.clear();
    uploads.first_drawn.clear();
    let [kept_before, kept_now] = &mut uploads.kept;
    std::mem::swap(kept_before, kept_now);
    kept_now.clear();
    for mut hair_mesh in query.iter_mut(&mut main_world) {
        if motion_vectors {
            let pair = [hair_mesh.buffer.id(), hair_mesh.previous_buffer.id()];
            if kept_before.contains(&pair[0]) {
                uploads.drawn.push(pair);
            } else {
                uploads.first_drawn.push(pair);
            }
            kept_now.insert(pair[0]);
        }
        if !std::mem::take(&mut hair_mesh.fresh) || hair_mesh.strips.positions().is_empty() {
            continue;
        }
        let id = hair_mesh.buffer.id();
        if uploads.uploads.len() == count {
            uploads.uploads.push((id, Vec::new()));
        }
        let slot = &mut uploads.uploads[count];
        slot.0 = id;
        let positions = hair_mesh.strips.positions_mut();
        if slot.1.len() != positions.len() {
            slot.1 = positions.clone();
        } else {
            std::mem::swap(&mut slot.1, positions);
        }
        count += 1;
    }
    uploads.uploads.truncate(count);
}

/// Keeps what each head drew last frame (for the motion vectors, while a camera draws them), then writes
/// the heads' new positions into their storage buffers. The copy is submitted on its own, before the
/// writes: a buffer write is carried out at the start of the next submission, so the copy sees last
/// frame's positions, whether the CPU wrote them or the GPU's follower placement did. A head drawn for the
/// first time has no frame before: its positions are copied after the writes instead (and again after the
/// GPU's follower placement, `followers::dispatch_gpu_followers`), so that it starts still.
fn upload_hair_positions(
    uploads: Res<HairUploads>,
    buffers: Res<RenderAssets<GpuShaderBuffer>>,
    device: Res<RenderDevice>,
    queue: Res<RenderQueue>,
) {
    let copy = |pairs: &[[AssetId<ShaderBuffer>; 2]], label: &'static str| {
        if pairs.is_empty() {
            return;
        }
        let mut encoder = device.create_command_encoder(&CommandEncoderDescriptor { label: Some(label) });
        if copy_drawn_to_previous(pairs, &buffers, &mut encoder) {
            queue.submit([encoder.finish()]);
        }
    };
    copy(&uploads.drawn, "hair positions kept");
    for (id, positions) in &uploads.uploads {
        let Some(buffer) = buffers.get(*id) else { continue };
        let bytes: &[u8] = bytemuck::cast_slice(positions);
        if buffer.buffer.size() >= bytes.len() as u64 && !bytes.is_empty() {
            queue.write_buffer(&buffer.buffer, 0, bytes);
        }
    }
    copy(&uploads.first_drawn, "hair positions kept, first frame");
}

/// Records into `encoder` a copy of each pair's drawn positions (`[this frame's, last frame's]` buffers)
/// into its last frame's buffer; returns whether it recorded any.
pub(super) fn copy_drawn_to_previous(
    pairs: &[[AssetId<ShaderBuffer>; 2]],
    buffers: &RenderAssets<GpuShaderBuffer>,
    encoder: &mut CommandEncoder,
) -> bool {
    let mut any = false;
    for [current, previous] in pairs {
        let (Some(current), Some(previous)) = (buffers.get(*current), buffers.get(*previous)) else { continue };
        let size = current.buffer.size();
        if size == previous.buffer.size() {
            encoder.copy_buffer_to_buffer(&current.buffer, 0, &previous.buffer, 0, size);
            any = true;
        }
    }
    any
}

impl HairUploads {
    /// The heads drawn this frame for the first time while a camera draws motion vectors (see
    /// [`HairUploads::first_drawn`]).
    pub(super) fn first_drawn(&self) -> &[[AssetId<ShaderBuffer>; 2]] {
        &self.first_drawn
    }
}
