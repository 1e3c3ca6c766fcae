//! Hair with volume: hair–hair interaction through a grid. Strands never collide with each other one
//! by one (thousands of strands make millions of pairs); as in every real-time hair system, each head's
//! hair is splatted every step to a grid around it ([`VolumeGrid`]), and the grid gives back
//! - **velocity smoothing**: each node's velocity is pulled towards the hair's around it, at
//!   [`HairVolume::velocity_smoothing`] (1/s) where the hair is packed: strands drag each other along,
//!   and long hair swings as a mass, not as strands passing through each other;
//! - **volume pressure**: where hair is packed more densely than [`HairVolume::target_volume_fraction`],
//!   it pushes outwards with [`HairVolume::stiffness`] (Pa): hair rests on hair, and a head of hair has
//!   volume instead of lying in one layer on the skull.
//!
//! [`HairVolumePlugin`] (part of [`crate::HairPlugins`]; off until [`HairVolume::enabled`], since it
//! costs a sixth to a fifth of a step) does this in [`HairSystems::ExternalForces`]: the
//! pressure as a force in [`StrandForces`], the smoothing as a change of velocity at the start of the
//! step ([`StrandForces::velocity_changes`]). Why those two forms: the smoothing is a filter (the
//! velocities it reads are those it changes), which conserves momentum exactly and is stable at any
//! rate, while an implicit drag towards the grid's velocity would not conserve momentum once gravity
//! changes it within the step; the pressure, as a force, is resisted implicitly by the strands'
//! elasticity and contact, like every other load. The grid's equations are in [`grid`]. Strands stepped
//! on the GPU meet each other through the GPU's own grid, the same equations in six compute passes
//! (`gpu::grid`).
//!
//! **Guides stand for more hair.** The grid counts each simulated strand as the hairs it stands for
//! ([`RepresentedHairs`]; by default itself and its followers, and a [`crate::groom::HairGroom`] gives
//! its strands their share of [`crate::groom::HairGroom::hair_count`]), so the volume matches a full
//! head, not the few thousand strands simulated.
//!
//! ```
//! use bevy::prelude::*;
//! use bevy_hair_sim::prelude::*;
//!
//! fn thick_hair(mut settings: ResMut<HairSettings>) {
//!     // Hair that meets hair, moves as one more than by default, and pushes back where it is packed
//!     // beyond 8 % of its volume.
//!     settings.volume.enabled = true;
//!     settings.volume.velocity_smoothing = 10.0;
//!     settings.volume.target_volume_fraction = 0.08;
//!     settings.volume.stiffness = 50.0;
//! }
//! # let mut app = App::new();
//! # app.add_systems(Startup, thick_hair);
//! ```
//!
//! **The groom's packing is at rest.** The grooms lay their hair in thin layers on the skull (a combed
//! groom's layers span 0.4 mm), packed tens of times beyond any target. Measured against the target alone,
//! that hair gains volume but rearranges to get there: a combed groom moves by 1 to 5 cm and the fringe
//! falls over the face. So by default ([`HairVolume::keep_groomed_volume`]) each node remembers how densely
//! the hair was packed where it lay in its groom, and the pressure pushes only where hair is packed beyond
//! both that and the target: a groom rests as it was made, and hair pressed together when the head moves
//! (or piled by a collider) pushes back (`docs/testing.md` has the figures). The pressure is 0 by
//! default: it costs a little more of the grid's time and changes little in motion.
//!
//! Checking settings before using them:
//!
//! ```
//! use bevy::prelude::*;
//! use bevy_hair_sim::prelude::*;
//!
//! let mut settings = HairSettings::default();
//! // Hair meets hair: velocities smoothed, and a push back where hair is packed beyond a tenth of its
//! // volume, resolved by 5 mm cells.
//! settings.volume.enabled = true;
//! settings.volume.stiffness = 50.0;
//! settings.volume.cell_size = 0.005;
//! assert!(settings.validated(1.0 / 60.0).is_ok());
//! ```
pub mod grid;

use bevy::ecs::entity::EntityHashSet;
use bevy::ecs::schedule::InternedScheduleLabel;
use bevy::math::DVec3;
use bevy::platform::collections::HashMap;
use bevy::platform::time::Instant;
use bevy::prelude::*;
use bevy::tasks::ComputeTaskPool;

use crate::followers::HairFollowers;
use crate::parallel::run_in_parallel;
use crate::rod::Rod;
use crate::schedule::HairSystems;
pub use crate::simulation::HairVolume;
use crate::simulation::{
    CheckedSettings, HairSettings, HairStatistics, SimulatedStrand, SteppedElsewhere, StrandForces, StrandOf,
};
pub use grid::{GridParticle, MAX_GRID_BRICKS, VolumeGrid, VolumeParams};

impl HairVolume {
    /// The grid's parameters for a step of `dt` seconds.
    pub fn params(&self, dt: f64) -> VolumeParams {
        VolumeParams {
            cell_size: f64::from(self.cell_size),
            smoothing_rate: f64::from(self.velocity_smoothing),
            target_fraction: f64::from(self.target_volume_fraction),
            stiffness: f64::from(self.stiffness),
            dt,
        }
    }
}

/// How many real hairs a simulated strand stands for in the hair's volume and in the velocity smoothing
/// (its keratin volume and mass on the grid are multiplied by it). Without it, a strand stands for
/// itself and its followers ([`HairFollowers`]); a [`crate::groom::HairGroom`] gives each of its strands
/// its share of [`crate::groom::HairGroom::hair_count`]. 0 leaves the strand out of the grid (it still
/// feels the others).
#[derive(Component, Reflect, Debug, Clone, Copy, PartialEq, Eq)]
#[reflect(Component, Debug, Clone, PartialEq)]
pub struct RepresentedHairs(pub u32);

/// Each head's grid after the last step (and one for the strands without a head), for debugging views
/// and tests: [`HairVolumeGrids::grid`].
#[derive(Resource, Debug, Default)]
pub struct HairVolumeGrids {
    groups: Vec<HeadGrid>,
    index: HashMap<Option<Entity>, usize>,
}

/// One head's grid and the nodes splatted to it this step.
#[derive(Debug, Default)]
struct HeadGrid {
    head: Option<Entity>,
    /// The head's nodes as the grid sees them, strand after strand.
    particles: Vec<GridParticle>,
    grid: VolumeGrid,
    /// Whether the head had hair this step.
    used: bool,
    /// Each strand of the head this step and where its nodes start in `particles`.
    strands: Vec<(Entity, usize)>,
    /// Nodes of the head's strands this step.
    nodes: usize,
    /// The head's step interval at its level of detail, fixed steps: its strands take their turns, each
    /// standing on the grid for the hairs of the fixed steps it steps over.
    step_interval: u32,
    /// The box around the usable particles of each piece the collect cut them into, m.
    piece_bounds: Vec<(DVec3, DVec3)>,
    /// The volume fraction where each node of each strand lay in its groom, measured once per strand
    /// ([`HairVolume::keep_groomed_volume`]).
    groomed: HashMap<Entity, Vec<f64>>,
}

impl HairVolumeGrids {
    /// The grid of `head`'s hair (`None`: of the strands without a head), if it had hair last step.
    pub fn grid(&self, head: Option<Entity>) -> Option<&VolumeGrid> {
        self.index.get(&head).map(|&group| &self.groups[group].grid)
    }

    /// The hair volume fraction at `position` (world space) in `head`'s grid, 0 outside it.
    pub fn volume_fraction_at(&self, head: Option<Entity>, position: Vec3) -> f32 {
        self.grid(head).map_or(0.0, |grid| grid.volume_fraction_at(position.as_dvec3()) as f32)
    }

    /// Starts a step: every group empty and unused, their memory kept.
    fn begin(&mut self) {
        for group in &mut self.groups {
            group.strands.clear();
            group.nodes = 0;
            group.used = false;
        }
    }

    /// The group of `head`'s strands, created on first use.
    fn group(&mut self, head: Option<Entity>) -> &mut HeadGrid {
        let next = self.groups.len();
        let group = *self.index.entry(head).or_insert(next);
        if group == next {
            self.groups.push(HeadGrid { head, ..default() });
        }
        let group = &mut self.groups[group];
        group.used = true;
        group
    }

    /// Forgets the heads that had no hair this step (despawned), keeping the others' memory.
    fn drop_unused(&mut self) {
        if self.groups.iter().all(|group| group.used) {
            return;
        }
        self.groups.retain(|group| group.used);
        self.index.clear();
        self.index.extend(self.groups.iter().enumerate().map(|(group, grid)| (grid.head, group)));
    }

    fn clear(&mut self) {
        self.groups.clear();
        self.index.clear();
    }
}

/// Hair–hair interaction through a grid (see the [module documentation](self)); part of
/// [`crate::HairPlugins`]. Without it (or with [`HairVolume::enabled`] off) strands meet only colliders.
#[derive(Debug, Clone)]
pub struct HairVolumePlugin {
    /// The fixed-timestep schedule the simulation runs in.
    pub schedule: InternedScheduleLabel,
}

impl Plugin for HairVolumePlugin {
    fn build(&self, app: &mut App) {
        app.register_type::<RepresentedHairs>()
            .init_resource::<HairVolumeGrids>()
            .add_systems(self.schedule, interact_through_grid.in_set(HairSystems::ExternalForces));
    }
}

/// The strands as the grid system reads and writes them.
type GridItem = (
    &'static SimulatedStrand,
    &'static mut StrandForces,
    Option<&'static StrandOf>,
    Option<&'static RepresentedHairs>,
    Option<&'static HairFollowers>,
    Entity,
);

/// Splats every head's hair to its grid, then gives each strand's free nodes the grid's velocity change
/// and pressure force, in parallel. Strands [`SteppedElsewhere`] (on the GPU) are left out where all of
/// their head's strands are: the GPU has a grid of its own (`gpu::grid`). A head with strands on both
/// sides meets on this grid alone: its strands on the GPU are splatted as last read back (their head's
/// are read back every step, so a step or two late), and their response goes to the GPU through their
/// [`StrandForces`] (the GPU leaves such a head off its grid).
pub(crate) fn interact_through_grid(
    time: Res<Time>,
    settings: Res<HairSettings>,
    checked: Res<CheckedSettings>,
    mut grids: ResMut<HairVolumeGrids>,
    mut statistics: ResMut<HairStatistics>,
    mut strands: Query<GridItem>,
    (elsewhere, mut heads_with_cpu_strands): (Query<(), With<SteppedElsewhere>>, Local<EntityHashSet>),
) {
    let dt = time.delta_secs_f64();
    // Invalid settings are reported once, by `check_settings`, and hold the hair until they are fixed.
    if !settings.volume.enabled || checked.params.is_none() {
        grids.clear();
        statistics.volume_seconds = 0.0;
        statistics.max_volume_fraction = 0.0;
        return;
    }
    let started = Instant::now();
    let params = settings.volume.params(dt);
    // The heads with strands on the CPU: their strands on the GPU meet here too.
    heads_with_cpu_strands.clear();
    for (_, _, strand_of, _, _, entity) in &strands {
        if let (Some(&StrandOf(head)), false) = (strand_of, elsewhere.contains(entity)) {
            heads_with_cpu_strands.insert(head);
        }
    }
    let heads_with_cpu_strands = &*heads_with_cpu_strands;
    let on_this_grid = |entity: Entity, strand_of: Option<&StrandOf>| {
        !elsewhere.contains(entity) || strand_of.is_some_and(|of| heads_with_cpu_strands.contains(&of.0))
    };
    grids.begin();
    // Where each strand's nodes go in its head's particles, in query order (so the sums are the same
    // from run to run), then the nodes copied there in parallel.
    for (strand, _, strand_of, _, _, entity) in &strands {
        // Only the hair stepped now meets other hair; at a coarser level of detail that is the share of
        // the head's strands whose turn it is, and carried hair never (see `crate::detail`).
        if !strand.steps_now() || !on_this_grid(entity, strand_of) {
            continue;
        }
        let group = grids.group(strand_of.map(|of| of.0));
        group.step_interval = strand.detail_level().step_interval().unwrap_or(1);
        group.strands.push((entity, group.nodes));
        group.nodes += strand.rod().node_count();
    }
    for group in &mut grids.groups {
        // Every slot is written below: this only sizes the list (nothing to do when it is unchanged).
        group.particles.resize(group.nodes, GridParticle::default());
    }
    let threads = ComputeTaskPool::try_get().map_or(1, |pool| pool.thread_num()).max(1);
    let readonly = strands.as_readonly();
    // Only the pressure reads the groomed fractions, and only while it keeps the groom.
    let keep_groomed = settings.volume.keep_groomed_volume && params.stiffness > 0.0;
    if keep_groomed {
        for group in &mut grids.groups {
            let strand_of = |entity: Entity| {
                let (strand, _, _, represented, followers, _) = readonly.get(entity).ok()?;
                Some((strand, hairs_on_the_grid(strand, represented, followers, elsewhere.contains(entity))))
            };
            measure_groomed_fractions(group, strand_of, &params);
        }
    }
    for group in &mut grids.groups {
        // Pieces of about equal numbers of strands, each with the particles they fill.
        let chunk = group.strands.len().div_ceil(threads).max(1);
        let mut pieces = Vec::with_capacity(threads);
        let total = group.particles.len();
        let mut rest = group.particles.as_mut_slice();
        let groomed = keep_groomed.then_some(&group.groomed);
        group.piece_bounds.resize(group.strands.len().div_ceil(chunk), (DVec3::ZERO, DVec3::ZERO));
        let pieces_of_strands = group.strands.chunks(chunk).zip(&mut group.piece_bounds).enumerate();
        for (index, (strands_of_piece, bounds)) in pieces_of_strands {
            let end = group.strands.get((index + 1) * chunk).map_or(total, |next| next.1);
            let (piece, after) = rest.split_at_mut(end - strands_of_piece[0].1);
            rest = after;
            pieces.push((strands_of_piece, piece, bounds));
        }
        run_in_parallel(threads, pieces.into_iter(), |(strands_of_piece, piece, bounds)| {
            let first = strands_of_piece[0].1;
            *bounds = grid::EMPTY_BOX;
            for &(entity, offset) in strands_of_piece {
                let Ok((strand, _, _, represented, followers, _)) = readonly.get(entity) else { continue };
                let hairs = hairs_on_the_grid(strand, represented, followers, elsewhere.contains(entity));
                let rod = strand.rod();
                let moving = if strand.is_quarantined() { 0.0 } else { hairs };
                let density = rod.material().density;
                let nodes = rod.positions().iter().zip(rod.velocities()).zip(rod.masses()).enumerate();
                let slots = &mut piece[offset - first..offset - first + rod.node_count()];
                let groomed = groomed.and_then(|groomed| groomed.get(&entity)).map_or(&[][..], Vec::as_slice);
                for (slot, (node, ((&position, &velocity), &mass))) in slots.iter_mut().zip(nodes) {
                    if grid::usable(position, velocity) {
                        *bounds = grid::enclosing(*bounds, (position, position));
                    }
                    *slot = GridParticle {
                        position,
                        velocity,
                        mass: if rod.is_node_prescribed(node) { 0.0 } else { moving * mass },
                        volume: hairs * mass / density,
                        groomed_fraction: groomed.get(node).copied().unwrap_or(0.0),
                    };
                }
            }
        });
    }
    grids.drop_unused();
    let mut max_fraction = 0.0_f64;
    for group in &mut grids.groups {
        let bounds = group.piece_bounds.iter().fold(grid::EMPTY_BOX, |bounds, &piece| grid::enclosing(bounds, piece));
        // A strand of a head at a coarser level steps over several fixed steps: smoothed over as long.
        let params = VolumeParams { dt: params.dt * f64::from(group.step_interval.max(1)), ..params };
        group.grid.build_within(&group.particles, bounds, &params);
        max_fraction = max_fraction.max(group.grid.max_volume_fraction());
    }

    let grids = &*grids;
    strands.par_iter_mut().for_each(|(strand, mut forces, strand_of, _, _, entity)| {
        let Some(grid) = grids.grid(strand_of.map(|of| of.0)) else { return };
        if strand.is_quarantined() || !strand.steps_now() || !on_this_grid(entity, strand_of) {
            return;
        }
        let rod = strand.rod();
        let (positions, velocities, masses) = (rod.positions(), rod.velocities(), rod.masses());
        let density = rod.material().density;
        forces.add_velocity_changes_and_forces(grid.pressed(), |node| {
            if rod.is_node_prescribed(node) {
                return (DVec3::ZERO, DVec3::ZERO);
            }
            grid.response(positions[node], velocities[node], masses[node] / density)
        });
    });
    statistics.volume_seconds = started.elapsed().as_secs_f64();
    statistics.max_volume_fraction = max_fraction;
}

/// Measures the groomed volume fraction at every node of the strands of `group` that have none yet
/// ([`groomed_fractions`]; all of a head's strands are made together). Forgets the strands gone from the
/// group once they outnumber those in it.
fn measure_groomed_fractions<'a>(
    group: &mut HeadGrid,
    strand_of: impl Fn(Entity) -> Option<(&'a SimulatedStrand, f64)>,
    params: &VolumeParams,
) {
    if group.strands.iter().all(|(entity, _)| group.groomed.contains_key(entity)) {
        return;
    }
    let strands: Vec<(Entity, &Rod, f64)> = group
        .strands
        .iter()
        .filter_map(|&(entity, _)| strand_of(entity).map(|(strand, hairs)| (entity, strand.rod(), hairs)))
        .collect();
    let rods: Vec<(&Rod, f64)> = strands.iter().map(|&(_, rod, hairs)| (rod, hairs)).collect();
    for ((entity, ..), fractions) in strands.iter().zip(groomed_fractions(&rods, params)) {
        group.groomed.entry(*entity).or_insert(fractions);
    }
    if group.groomed.len() > 2 * group.strands.len() {
        let present: bevy::platform::collections::HashSet<Entity> =
            group.strands.iter().map(|(entity, _)| *entity).collect();
        group.groomed.retain(|entity, _| present.contains(entity));
    }
}

/// The groomed volume fraction at every node of `strands` (all of one head, each with the hairs it stands
/// for on the grid): in a grid of the strands as they were made ([`crate::rod::Rod::initial_positions`],
/// the groom), the densest of the grid points around the node (the fraction interpolated there would
/// leave the groom's densest points pressed beyond their nodes' average). The GPU's grid is given them
/// at upload.
pub(crate) fn groomed_fractions(strands: &[(&Rod, f64)], params: &VolumeParams) -> Vec<Vec<f64>> {
    let mut groomed = Vec::with_capacity(strands.iter().map(|(rod, _)| rod.node_count()).sum());
    for &(rod, hairs) in strands {
        let density = rod.material().density;
        groomed.extend(rod.initial_positions().iter().zip(rod.masses()).map(|(&position, &mass)| GridParticle {
            position,
            volume: hairs * mass / density,
            ..default()
        }));
    }
    let mut grid = VolumeGrid::default();
    grid.build(&groomed, &VolumeParams { stiffness: 0.0, smoothing_rate: 0.0, ..*params });
    strands
        .iter()
        .map(|(rod, _)| rod.initial_positions().iter().map(|&node| grid.densest_fraction_around(node)).collect())
        .collect()
}

/// How many hairs a strand stands for on the grid at this fixed step: its [`represented_hairs`] for each
/// fixed step its step spans. At a coarser level of detail `n`, a head's strands take their turns, about
/// one in `n` at each fixed step, each stepping over `n` fixed steps: the head's hair on the grid is as
/// dense as at full detail, sampled by a share of its strands.
fn hairs_on_the_grid(
    strand: &SimulatedStrand,
    represented: Option<&RepresentedHairs>,
    followers: Option<&HairFollowers>,
    stepped_elsewhere: bool,
) -> f64 {
    // A strand stepped on the GPU is never stepped here (its step length would count the fixed steps since
    // it left the CPU): it spans its level's interval, as the GPU steps it.
    let span =
        if stepped_elsewhere { strand.detail_level().step_interval().unwrap_or(1) } else { strand.step_length() };
    represented_hairs(represented, followers) * f64::from(span)
}

/// How many hairs a strand stands for: its [`RepresentedHairs`], or itself and its followers.
pub(crate) fn represented_hairs(represented: Option<&RepresentedHairs>, followers: Option<&HairFollowers>) -> f64 {
    match represented {
        Some(hairs) => f64::from(hairs.0),
        None => 1.0 + followers.map_or(0, |followers| followers.curves.len()) as f64,
    }
}
