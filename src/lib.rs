//! Real-time hair simulation for the [Bevy](https://bevy.org) game engine, built on *Discrete Elastic
//! Rods* (Bergou, Wardetzky, Robinson, Audoly, Grinspun, SIGGRAPH 2008): strands that hang under gravity,
//! keep their style and curls, twist, follow their head, rest on colliders, move in the wind and never
//! explode, from material parameters in SI units. Add one plugin, put a groom on a head, and the hair moves
//! with it.
//!
//! # Contents
//! - [Getting started](#getting-started): a head of hair in a game, and in a headless app
//! - [Concepts](#concepts): where each part of the hair is explained
//! - [Plugins](#plugins): one per concern, and the group that adds them all
//! - [Scheduling](#scheduling): the sets to order your systems against
//! - [Feature flags](#feature-flags)
//! - [Architecture](#architecture): the folders and which may use which
//! - [When input is bad](#when-input-is-bad): errors, faults and quarantine
//! - [FAQ](#faq)
//!
//! # Getting started
//! Add [`HairPlugins`] after Bevy's plugins, spawn a [`HairHead`](simulation::HairHead) with a
//! [`HairGroom`](groom::HairGroom) and something for the hair to rest on:
//!
//! ```no_run
//! use bevy::prelude::*;
//! use bevy_hair_sim::prelude::*;
//!
//! fn main() {
//!     App::new()
//!         .add_plugins((
//!             // Strands are stepped in parallel on Bevy's compute pool; this gives it every core.
//!             DefaultPlugins.set(TaskPoolPlugin { task_pool_options: HairPlugins::task_pool_options() }),
//!             HairPlugins::default(),
//!         ))
//!         .add_systems(Startup, spawn_head)
//!         .run();
//! }
//!
//! fn spawn_head(mut commands: Commands) {
//!     // 2 000 curly strands of human hair over a 10 cm skull (the face, −Z, is left bare)...
//!     let groom = HairGroom { style: HairStyle::Curly, ..default() };
//!     let head = commands.spawn((HairHead, groom, Transform::from_xyz(0.0, 1.6, 0.0))).id();
//!     // ...resting on the skull, and on a floor that every strand meets.
//!     commands.spawn((HairCollider::sphere(0.1), HairColliderOf(head), ChildOf(head)));
//!     commands.spawn(HairCollider::plane().with_friction(0.6));
//!
//!     // Or strands of your own, in the head's local space: their roots follow the head's Transform.
//!     commands.spawn((HairHead, Transform::from_xyz(1.0, 1.6, 0.0))).with_related_entities::<StrandOf>(|head| {
//!         for i in 0..500 {
//!             let angle = i as f32 * 2.4;
//!             let normal = Vec3::new(0.6 * angle.cos(), 0.8, 0.6 * angle.sin()).normalize();
//!             // 20 cm of human hair in 16 edges, rooted on a 10 cm scalp, growing outwards.
//!             head.spawn(HairStrand::straight(0.1 * normal, normal, 0.2, 16));
//!         }
//!     });
//! }
//! ```
//!
//! Move the head's `Transform` (or its parent's) and the hair follows; despawn it and its strands go too.
//! Changing a `HairGroom` regrows the hair (strands you added yourself stay). [`HairPause`](simulation::HairPause)
//! pauses the simulation or runs it one step at a time. With the `render` feature the hair is drawn as lit,
//! shadowed strands ([`render`]); without it, as gizmo lines ([`debug`](mod@debug)).
//!
//! **On a glTF character**, put [`HairOnCharacter`](scalp::HairOnCharacter) on the scene's root: once the
//! scene has spawned it finds the head joint, the scalp mesh and the face by name, fits the groom's skull
//! to the joint's skinned vertices, grows the groom on the scalp turned onto the joint's own axes (read
//! off its bind pose: glTF models stand `+Y` up facing `+Z`) and sized in metres whatever the character's
//! scale, binds every root to its scalp triangle, and bakes the face into a collider. The crate's own
//! humanoid, `assets/models/Mannequin.glb`, takes nothing measured by hand (`examples/gltf_character.rs`;
//! the fit takes in whatever the head joint skins, so an animal's snout and ears make it a size too large):
//!
//! ```no_run
//! # use bevy::prelude::*;
//! # use bevy_hair_sim::prelude::*;
//! fn spawn_character(mut commands: Commands, assets: Res<AssetServer>) {
//!     commands.spawn((
//!         WorldAssetRoot(assets.load(GltfAssetLabel::Scene(0).from_asset("models/Mannequin.glb"))),
//!         Transform::from_scale(Vec3::splat(0.01)), // modelled in centimetres
//!         HairOnCharacter::new("Head", CharacterHair::Groom(HairGroom::default()))
//!             .with_gltf_head_axes()
//!             .with_scalp_fitted_to_head()
//!             .with_scalp_mesh("Scalp")
//!             .with_collider_meshes(["Face"]),
//!     ));
//! }
//! ```
//!
//! **Headless apps** (servers, tests, tools) use `MinimalPlugins`. The app's first `update()` only starts
//! Bevy's clocks and runs no fixed step, and the plugin's warnings and errors are logged through
//! `tracing`, which prints nothing without Bevy's `LogPlugin` (not in `MinimalPlugins`). With
//! `TimeUpdateStrategy::FixedTimesteps(1)` every update after the first runs exactly one fixed step:
//!
//! ```
//! use bevy::prelude::*;
//! use bevy::time::TimeUpdateStrategy;
//! use bevy_hair_sim::prelude::*;
//!
//! let mut app = App::new();
//! app.add_plugins((MinimalPlugins, HairPlugins::default())) // and bevy::log::LogPlugin::default() to see errors
//!     .insert_resource(Time::<Fixed>::from_hz(60.0))
//!     .insert_resource(TimeUpdateStrategy::FixedTimesteps(1));
//! let strand = app.world_mut().spawn(HairStrand::straight(Vec3::ZERO, Vec3::X, 0.2, 16)).id();
//! app.update(); // starts the clocks, no step
//! assert_eq!(app.world().resource::<HairStatistics>().steps, 0);
//! for _ in 0..30 {
//!     app.update(); // one step each
//! }
//! assert_eq!(app.world().resource::<HairStatistics>().steps, 30);
//! let tip = app.world().get::<StrandNodes>(strand).unwrap().positions[16];
//! assert!(tip.y < -0.01, "a free strand falls");
//! ```
//!
//! # Concepts
//! | you spawn (authored) | the plugin adds (simulated; query it) | explained in |
//! |---|---|---|
//! | [`HairHead`](simulation::HairHead) on any entity with a `Transform` | [`HeadMotion`](simulation::HeadMotion), [`HeadStrands`](simulation::HeadStrands), [`HairDetail`](detail::HairDetail) | [`simulation`] |
//! | [`HairStrand`](simulation::HairStrand) with [`StrandOf`](simulation::StrandOf)`(head)` | [`SimulatedStrand`](simulation::SimulatedStrand), [`StrandNodes`](simulation::StrandNodes), [`StrandFrames`](simulation::StrandFrames), [`StrandRestShape`](simulation::StrandRestShape), or [`StrandRejected`](simulation::StrandRejected) | [`simulation`] |
//! | [`HairGroom`](groom::HairGroom) or [`HairGroomFile`](groom::HairGroomFile) on a head | the groom's strands, regrown when it changes | [`groom`] |
//! | [`HairFollowers`](followers::HairFollowers) beside a strand | [`FollowerNodes`](followers::FollowerNodes) | [`followers`] |
//! | [`HairCollider`](collision::HairCollider), with [`HairColliderOf`](collision::HairColliderOf)`(head)` or none | [`ColliderMotion`](collision::ColliderMotion) | [`collision`] |
//! | [`HairColliderFromMesh`](collision::HairColliderFromMesh) beside a `Mesh3d` | its [`HairCollider`](collision::HairCollider), baked | [`collision::mesh`] |
//! | [`HairScalpMesh`](scalp::HairScalpMesh)`(mesh)` on a head | [`ScalpRootBinding`](scalp::ScalpRootBinding) on its strands; [`GroomSurface`](groom::GroomSurface) on the head, which its groom grows on | [`scalp`], [`groom`] |
//! | [`StrandColors`](groom::StrandColors) on a strand (a groom file's colours) | its hairs drawn in them | [`groom`], [`render`] |
//! | [`StrandWidths`](groom::StrandWidths) on a strand (a groom's hairline thinning it) | its hairs drawn that much thinner, or left out | [`groom`], [`render`] |
//! | [`HairOnCharacter`](scalp::HairOnCharacter) on a character's scene root | [`HairHead`](simulation::HairHead), [`HairScalpMesh`](scalp::HairScalpMesh), the groom and colliders on its head joint | [`scalp`] |
//! | [`StrandForces`](simulation::StrandForces) on a strand, [`HairWind`](wind::HairWind), [`HairWindSource`](wind::HairWindSource) | (cleared after each step) | [`simulation`], [`wind`] |
//! | [`HairSettings::volume`](simulation::HairSettings::volume), [`RepresentedHairs`](volume::RepresentedHairs) | [`HairVolumeGrids`](volume::HairVolumeGrids) | [`volume`] |
//! | [`HairSettings::style_hold`](simulation::HairSettings::style_hold) | rooted strands drawn towards their groomed shape near the root | [`simulation`] |
//! | [`HairDetailSettings`](detail::HairDetailSettings), [`HairDetail::fixed`](detail::HairDetail::fixed) | each head's level of detail | [`detail`] |
//! | [`HairAppearance`](render::HairAppearance) on a head (`render` feature) | `HairMesh`, a child of the head | [`render`] |
//!
//! Every parameter has its unit, default and range on its field. The mechanics behind it all, usable on
//! its own without an `App`, is [`rod`]: [`Rod`](rod::Rod) is one strand.
//!
//! # Plugins
//! [`HairPlugins`] adds them all; leave one out with
//! `HairPlugins::default().build().disable::<HairWindPlugin>()`.
//!
//! | plugin | what it does | without it |
//! |---|---|---|
//! | [`HairSimulationPlugin`] | heads, strands, their data, [`HairSettings`](simulation::HairSettings), [`HairStatistics`](simulation::HairStatistics), the step; configures the [sets](schedule) | no hair |
//! | [`HairCollisionPlugin`] | tracks [`HairCollider`](collision::HairCollider)s and gathers each head's set | hair passes through everything |
//! | [`HairScalpPlugin`] | roots bound to a scalp mesh, rigid or skinned ([`HairScalpMesh`](scalp::HairScalpMesh)) | roots follow their head only |
//! | [`HairDetailPlugin`] | levels of detail from the cameras, and the CPU budget ([`HairCpuBudget`](detail::HairCpuBudget)) | every head at full detail, no budget |
//! | [`HairFollowersPlugin`] | binds and places follower hairs | followers ignored |
//! | [`HairVolumePlugin`] | hair–hair interaction through a grid, when [`HairVolume::enabled`](simulation::HairVolume::enabled) | strands meet only colliders |
//! | [`HairWindPlugin`] | [`HairWind`](wind::HairWind) and [`HairWindSource`](wind::HairWindSource)s | still air |
//! | [`HairGroomPlugin`] | procedural grooms and groom files (`.tfx`, `.hair`; needs Bevy's `AssetPlugin`) | grooms ignored |
//! | [`HairGizmoPlugin`] | strands and colliders as gizmo lines (needs Bevy's `GizmoPlugin`; off under the renderer until asked for) | no lines |
//! | `HairRenderPlugin` (`render` feature) | hair drawn in Bevy's PBR pipeline (needs Bevy's `PbrPlugin`) | lines only |
//! | `HairGpuPlugin` (`gpu` feature) | the strands stepped on the GPU where the app can (else the CPU, said once in `HairGpuStatus::error`), followers placed and hair drawn from there, read back into the components | the CPU steps every strand |
//! | `HairPanelPlugin` (`egui` feature; not in the group) | a live panel of settings and statistics | – |
//! | [`HairDiagnosticsPlugin`](debug::HairDiagnosticsPlugin) (not in the group) | the hair's statistics in Bevy's `DiagnosticsStore` ([`HairDiagnostics`](debug::HairDiagnostics)) | – |
//!
//! # Scheduling
//! The simulation runs in [`FixedUpdate`] (or the fixed-timestep schedule given to [`HairPlugins::new`]) at
//! Bevy's `Time<Fixed>` rate (64 Hz unless set; any rate is stable), in the chained sets of
//! [`HairSystems`]; each concern puts its systems in them or in their sub-sets ([`schedule`]):
//!
//! | set | what runs there | yours |
//! |---|---|---|
//! | [`Prepare`](HairSystems::Prepare) (always runs) | grooms grown, strands built, followers bound, settings and rest-shape edits applied, the step budget decided ([`HairPrepareSystems`](schedule::HairPrepareSystems)) | edit strands here or before |
//! | [`PinRoots`](HairSystems::PinRoots) | heads tracked, levels of detail chosen, roots clamped, colliders gathered ([`HairPinSystems`](schedule::HairPinSystems)) | |
//! | [`ExternalForces`](HairSystems::ExternalForces) | wind, the hair–hair grid | add [`StrandForces`](simulation::StrandForces) |
//! | [`Step`](HairSystems::Step) | every strand's implicit step in parallel, then the followers ([`HairStepSystems`](schedule::HairStepSystems)) | |
//! | [`PostStep`](HairSystems::PostStep) | – | read the new state, add checks and constraints |
//!
//! [`HairDrawSystems`](schedule::HairDrawSystems) (in `PostUpdate`, after transform propagation) draws the
//! gizmo lines and prepares the rendered hair. Hair is stepped where its head was at the fixed step, and
//! drawn carried onto the head where it is in the frame ([`HeadMotion::drawn_to_now`](simulation::HeadMotion::drawn_to_now)),
//! so heads may be moved and animated anywhere before transform propagation (`Update`, an animation in
//! `PostUpdate`) without the scalp showing through hair that trails it. Bevy gives its compute pool only the cores its IO and async
//! pools leave (one thread of two on a 2-core machine); [`HairPlugins::task_pool_options`] gives it every
//! core.
//!
//! # Feature flags
//! | feature | what it adds | default |
//! |---|---|---|
//! | `render` | the hair renderer, `HairRenderPlugin`, with the followers placed and drawn on the GPU (Bevy's `bevy_render`, `bevy_core_pipeline`, `bevy_pbr`; no window, platform or image format) | **on** |
//! | `gpu` | `render` and the strand step in a compute shader ([`gpu`]), checked against the CPU's step, run in the app by `HairGpuPlugin` (in the group: the GPU steps the hair by default) | **on** |
//! | `egui` | `render` and `HairPanelPlugin`, the live panel (bevy_egui) | off |
//! | `examples` | `render` and what the examples need besides: a window (winit, X11), gizmo lines drawn, tonemapping tables, PNG screenshots | off |
//! | `avian` | avian3d's colliders as hair colliders: `AvianHairCollider` beside a `Collider` (`collision::avian`) | off |
//!
//! The simulation needs none of them: with `default-features = false` it uses Bevy's ECS, math, assets
//! and gizmo API only, and builds no renderer (a server, a tool).
//!
//! **Where followers are placed** ([`FollowerPlacement`](followers::FollowerPlacement)): with the renderer,
//! on the GPU where they are drawn (the CPU sends the guides' nodes and frames once per step; see
//! [`render::feed`]), and [`FollowerNodes`](followers::FollowerNodes) stays empty unless a head or guide is
//! marked [`PlaceFollowersOnCpu`](followers::PlaceFollowersOnCpu); without it, on the CPU.
//!
//! # Architecture
//! Two layers. The **mechanics core**, [`rod`], is free of Bevy's ECS: plain structs on glam's `f64`
//! vectors (through `bevy::math`) in SI units, usable, tested and benchmarked without an `App`. The **ECS
//! layer** around it is a folder per concern, each with its plugin beside its data:
//!
//! | folder | what it holds | may use |
//! |---|---|---|
//! | [`rod`] | the mechanics core | – |
//! | [`schedule`] | the system sets every concern runs in | – |
//! | `gpu` (`gpu` feature) | the strand step in a compute shader, on a plain wgpu device | `rod` |
//! | [`simulation`] | heads, strands, their components, settings, the step, the step cadence, the contact slots | `rod`, `schedule` |
//! | [`collision`], [`detail`], [`followers`], [`wind`] | one concern each | `rod`, `schedule`, `simulation` |
//! | [`volume`] | the hair–hair grid | the above, and `followers` |
//! | [`groom`] | procedural grooms and groom files | the above |
//! | [`scalp`] | roots bound to a scalp mesh, hair put on a character | the above |
//! | [`render`] | the hair renderer | the above |
//! | [`debug`](mod@debug) | gizmo lines, the panel | the above |
//! | `lib.rs` | [`HairPlugins`], the [`prelude`] | everything |
//!
//! Dependencies point down this table only: a concern never imports one below it, and the sets live at
//! the bottom so that nobody reaches up for them. The core owns every slot the step reads (the forces,
//! the colliders each head meets), and the concerns above fill them; a concern attaches its own
//! components to the core's types (`register_required_components`), so the core never names it. The
//! layer speaks Bevy's `f32` types for positions, directions and forces; the core computes in `f64`.
//! How the step is made, part by part, and what it costs: `docs/architecture.md` and
//! `docs/performance.md` in the repository.
//!
//! # When input is bad
//! Bad input is stopped with an error that says what is wrong, never a panic; a strand that cannot be
//! stepped is reported once, held and retried, and the rest of the hair goes on (errors are logged through
//! `tracing`: headless apps see them only with Bevy's `LogPlugin`):
//!
//! | input | what happens |
//! |---|---|
//! | an invalid [`HairStrand`](simulation::HairStrand) (fewer than 3 nodes, a non-finite node, a zero-length edge, a turn past [`MAX_TURNING_ANGLE`](rod::MAX_TURNING_ANGLE), a material out of [`MATERIAL_RANGES`](rod::MATERIAL_RANGES), …) | one error line naming the entity and the reason, and a [`StrandRejected`](simulation::StrandRejected); changing its `HairStrand` tries again |
//! | a strand whose head's transform is not finite or has zero scale | waits ([`StrandRejected::waits_for_head`](simulation::StrandRejected::waits_for_head)), built once the head is usable |
//! | invalid [`HairSettings`](simulation::HairSettings) | one error line; until they are fixed the hair is held: not simulated, drawn carried rigidly with its heads (roots on the head however it moves), its clocks stopped; it resumes with its heads' motion; [`HairStatistics::settings_error`](simulation::HairStatistics::settings_error) says why |
//! | invalid [`HairDetailSettings`](detail::HairDetailSettings) | one error line; every head at full detail until they are fixed |
//! | an invalid [`HairWind`](wind::HairWind) or [`HairWindSource`](wind::HairWindSource) (a speed that is not finite or past [`MAX_WIND_SPEED`](wind::MAX_WIND_SPEED), a radius or range that is not positive, a non-finite transform) | one error line naming the source; it blows no air until fixed |
//! | invalid [`HairFollowers`](followers::HairFollowers) (a curve of another node count than its guide, a non-finite node, a clumping or its variation outside 0 to 1, a negative or non-finite scatter) | one error line; none of the guide's followers is placed until they are changed ([`FollowerNodes::rejection`](followers::FollowerNodes::rejection)) |
//! | an invalid [`HairCollider`](collision::HairCollider) | one error line; left out until fixed |
//! | a non-finite [`StrandForces`](simulation::StrandForces) | that strand's step is skipped (it is carried with its head for that step), with a [`StrandFault`](simulation::StrandFault) |
//! | a rod state written through [`SimulatedStrand::rod_mut`](simulation::SimulatedStrand::rod_mut) that cannot be stepped (a non-finite node, nodes on top of each other) | found before the strand is next drawn, stepped or not (carried, at a coarser level of detail, held): it is put back in its rest pose on its head, with a [`StrandFault`](simulation::StrandFault) |
//! | a step that fails anyway | the strand is rolled back and reported; one that fails again within [`QUARANTINE_WINDOW`](simulation::QUARANTINE_WINDOW) is quarantined, retried after [`FIRST_QUARANTINE`](simulation::FIRST_QUARANTINE), then at doubling intervals up to [`MAX_QUARANTINE`](simulation::MAX_QUARANTINE) |
//! | an edit of [`StrandRestShape`](simulation::StrandRestShape) the rod cannot take | one error line; the edit is undone |
//! | a head that jumps farther than [`teleport_distance`](simulation::HairSettings::teleport_distance) in one step | its hair is carried along rigidly |
//! | a long frame hitch | at most [`max_steps_per_frame`](simulation::HairSettings::max_steps_per_frame) steps run, the rest are skipped |
//! | a truncated or corrupt groom file | a [`GroomFileError`](groom::GroomFileError), never a panic or a huge allocation |
//!
//! The log stays readable: each strand's first failure of an episode gets a warning of its own (at most 4 a
//! second), everything else one summary line a second at most.
//!
//! # FAQ
//! **Nothing moves.** The hair is simulated in `FixedUpdate`: an app needs Bevy's `TimePlugin` (in
//! `DefaultPlugins` and `MinimalPlugins`), and a headless app's first `update()` runs no fixed step. Strands
//! need at least 3 nodes; a rejected one has a [`StrandRejected`](simulation::StrandRejected) saying why.
//!
//! **I see no errors, but strands are missing.** Errors are logged through `tracing`; without Bevy's
//! `LogPlugin` they go nowhere. [`StrandRejected`](simulation::StrandRejected),
//! [`StrandFault`](simulation::StrandFault) messages and
//! [`HairStatistics::settings_error`](simulation::HairStatistics::settings_error) carry the same reasons.
//!
//! **Can I use it with avian or bevy_rapier?** Yes: the names of this crate's prelude do not clash with
//! theirs (a test glob-imports ours beside stand-ins for both). Put a [`HairCollider`](collision::HairCollider)
//! on the bodies hair should rest on (next to avian's `Collider` on one entity is fine); or, with the
//! `avian` feature, put `AvianHairCollider` beside avian's `Collider` and the hair meets that very shape
//! (balls, capsules, cuboids, half-spaces and compounds of them; `collision::avian`). The hair does not
//! push those bodies back.
//!
//! **How do I save and load hair?** [`StrandSnapshot`](simulation::StrandSnapshot) copies a strand's data out;
//! inserting it back resumes the strand bit for bit. The components are `Reflect`, for Bevy's scene tools.
//!
//! **Why is the core in `f64`?** Hair is a stiff system: over an edge of 1 cm, a 40 µm fibre resists
//! stretching `4l²/r²` = 250 000 times more than bending, and the implicit solve and the length projection
//! need the digits `f32` does not have. The components a game reads are `f32`.
//!
//! **How fast is it?** Linear in strands and edges: 9–12 ms per step for 2 000 strands × 32 edges on
//! two cores at full detail, 4.5 ms for 1 000 × 16 on the CPU; stepped on the GPU (`HairGpuPlugin`, the
//! default where the app has Bevy's renderer and a device with compute) the CPU's share is a fraction of a
//! millisecond. Build in release, give the compute pool every core
//! ([`HairPlugins::task_pool_options`]), use followers for density and let levels of detail step far heads
//! less often and carry hidden ones ([`detail`]). The figures and their history are in
//! `docs/performance.md` in the repository.
#![warn(missing_docs)]

pub mod collision;
pub mod debug;
pub mod detail;
pub mod followers;
#[cfg(feature = "gpu")]
pub mod gpu;
pub mod groom;
mod parallel;
pub mod render;
pub mod rod;
pub mod scalp;
pub mod schedule;
pub mod simulation;
pub mod volume;
pub mod wind;

use bevy::app::PluginGroupBuilder;
use bevy::ecs::schedule::{InternedScheduleLabel, ScheduleLabel};
use bevy::prelude::*;

pub use schedule::HairSystems;
pub use simulation::HairSimulationPlugin;

use collision::HairCollisionPlugin;
use debug::HairGizmoPlugin;
use detail::HairDetailPlugin;
use followers::HairFollowersPlugin;
use groom::HairGroomPlugin;
use scalp::HairScalpPlugin;
use volume::HairVolumePlugin;
use wind::HairWindPlugin;

/// Everything a game needs for hair, one plugin per concern: simulation ([`HairSimulationPlugin`]),
/// collisions ([`HairCollisionPlugin`]), levels of detail for crowds ([`HairDetailPlugin`]), follower hairs
/// ([`HairFollowersPlugin`]), hair–hair interaction ([`HairVolumePlugin`]), wind ([`HairWindPlugin`]),
/// grooms, procedural and from files ([`HairGroomPlugin`]), debug lines ([`HairGizmoPlugin`]) and, with the
/// crate's `render` feature, hair drawn with Bevy's PBR (`HairRenderPlugin`). Add it once, after Bevy's
/// plugins:
///
/// ```no_run
/// # use bevy::prelude::*;
/// # use bevy_hair_sim::prelude::*;
/// App::new().add_plugins((MinimalPlugins, HairPlugins::default()));
/// ```
///
/// Simulation runs in [`FixedUpdate`] unless [`HairPlugins::new`] names another fixed-timestep schedule;
/// its rate is Bevy's `Time<Fixed>` (64 Hz by default; `Time::<Fixed>::from_hz(60.0)` for 60). Leave a
/// concern out with Bevy's `PluginGroupBuilder::disable`, e.g.
/// `HairPlugins::default().build().disable::<HairWindPlugin>()`.
#[derive(Debug, Clone)]
pub struct HairPlugins {
    schedule: InternedScheduleLabel,
}

impl HairPlugins {
    /// Simulates hair in `schedule`, which must run inside Bevy's fixed main loop (`FixedUpdate`,
    /// `FixedPreUpdate`, `FixedPostUpdate` or one of your own run from it).
    pub fn new(schedule: impl ScheduleLabel) -> Self {
        Self { schedule: schedule.intern() }
    }

    /// Task pools that give Bevy's compute pool, where strands are stepped in parallel, every core. Bevy's
    /// default gives it what its IO and async pools leave: a single thread on a 2-core machine, 2 of 4.
    /// The IO and async threads sleep while idle, so sharing cores with them costs little.
    ///
    /// ```no_run
    /// # use bevy::prelude::*;
    /// # use bevy_hair_sim::prelude::*;
    /// App::new().add_plugins((
    ///     DefaultPlugins.set(TaskPoolPlugin { task_pool_options: HairPlugins::task_pool_options() }),
    ///     HairPlugins::default(),
    /// ));
    /// ```
    pub fn task_pool_options() -> TaskPoolOptions {
        Self::task_pool_options_with_threads(bevy::tasks::available_parallelism())
    }

    /// [`HairPlugins::task_pool_options`] with `threads` compute threads.
    pub fn task_pool_options_with_threads(threads: usize) -> TaskPoolOptions {
        let mut options = TaskPoolOptions::default();
        options.compute.min_threads = threads.max(1);
        options.compute.max_threads = threads.max(1);
        options
    }
}

impl Default for HairPlugins {
    fn default() -> Self {
        Self::new(FixedUpdate)
    }
}

impl PluginGroup for HairPlugins {
    fn build(self) -> PluginGroupBuilder {
        let schedule = self.schedule;
        let group = PluginGroupBuilder::start::<Self>()
            .add(HairSimulationPlugin { schedule })
            .add(HairCollisionPlugin { schedule })
            .add(HairScalpPlugin { schedule })
            .add(HairDetailPlugin { schedule })
            .add(HairFollowersPlugin { schedule })
            .add(HairVolumePlugin { schedule })
            .add(HairWindPlugin { schedule })
            .add(HairGroomPlugin { schedule })
            .add(HairGizmoPlugin);
        #[cfg(feature = "render")]
        let group = group.add(render::HairRenderPlugin);
        #[cfg(feature = "gpu")]
        let group = group.add(render::HairGpuPlugin { schedule });
        group
    }
}

/// Each concern's plugin, by default in [`FixedUpdate`] (as [`HairPlugins::default`] adds them).
macro_rules! in_fixed_update_by_default {
    ($($plugin:ty),* $(,)?) => {
        $(impl Default for $plugin {
            fn default() -> Self {
                Self { schedule: FixedUpdate.intern() }
            }
        })*
    };
}

#[cfg(feature = "gpu")]
in_fixed_update_by_default!(render::HairGpuPlugin);

in_fixed_update_by_default!(
    HairSimulationPlugin,
    HairCollisionPlugin,
    HairScalpPlugin,
    HairDetailPlugin,
    HairFollowersPlugin,
    HairVolumePlugin,
    HairWindPlugin,
    HairGroomPlugin,
);

/// What a game spawns and configures: the plugins, the components put on heads, strands and colliders,
/// the settings and statistics resources, the messages, and the system sets to order systems by. The
/// mechanics core ([`rod`], [`gpu`]) and what the plugin builds for itself stay in their modules.
pub mod prelude {
    pub use crate::HairPlugins;
    #[cfg(feature = "avian")]
    pub use crate::collision::AvianHairCollider;
    pub use crate::collision::{
        HairCollider, HairColliderFromMesh, HairColliderOf, HairCollisionFilter, HairCollisionPlugin, HeadColliders,
        MeshColliderSettings, SharedHairCollider,
    };
    #[cfg(feature = "egui")]
    pub use crate::debug::HairPanelPlugin;
    pub use crate::debug::{HairDiagnosticsPlugin, HairGizmoPlugin, HairGizmos};
    pub use crate::detail::{HairCpuBudget, HairDetail, HairDetailLevel, HairDetailPlugin, HairDetailSettings};
    pub use crate::followers::{
        FollowerNodes, FollowerPlacement, HairFollowers, HairFollowersPlugin, PlaceFollowersOnCpu,
    };
    pub use crate::groom::{
        Combing, GroomFile, GroomPlacement, GroomSurface, HairGroom, HairGroomFile, HairGroomPlugin, HairStyle,
        HeadAxes, Scalp, StrandColors, StrandWidths, UpAxis,
    };
    pub use crate::render::HairAppearance;
    #[cfg(feature = "gpu")]
    pub use crate::render::{GpuReadBackRate, HairGpuPlugin, HairGpuSettings, HairGpuStatus};
    #[cfg(feature = "render")]
    pub use crate::render::{HairMesh, HairRenderPlugin};
    pub use crate::rod::RodMaterial;
    pub use crate::scalp::{
        CharacterHair, HairOnCharacter, HairOnCharacterStatus, HairScalpMesh, HairScalpPlugin, ScalpWhereHeadSkins,
    };
    pub use crate::schedule::{HairDrawSystems, HairPinSystems, HairPrepareSystems, HairStepSystems, HairSystems};
    pub use crate::simulation::{
        HairHead, HairPause, HairSettings, HairSimulationPlugin, HairStatistics, HairStrand, HairStyleHold,
        HeadStrands, StrandFault, StrandForces, StrandFrames, StrandNodes, StrandOf, StrandRejected, StrandRestShape,
        StrandSnapshot, StrandSnapshotData,
    };
    pub use crate::volume::{HairVolume, HairVolumePlugin};
    pub use crate::wind::{HairWind, HairWindPlugin, HairWindSource};
}

/// The README's code, compiled and run as doctests so that it never goes stale.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
pub struct ReadmeDoctests;
