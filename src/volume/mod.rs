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
//! [`HairVolumePlugin`] (part of [`crate::HairPlugin`]; off until [`HairVolume::enabled`], since it
//! costs a sixth to a fifth of a step) does this in [`HairSystems::ExternalForces`]: the
//! pressure as a force in [`StrandForces`], the smoothing as a change of velocity at the start of the
//! step ([`StrandForces::velocity_changes`]). Why those two forms: the smoothing is a filter (the
//! velocities it reads are those it changes), which conserves momentum exactly and is stable at any
//! rate, while an implicit drag towards the grid's velocity would not conserve momentum once gravity
//! changes it within the step; the pressure, as a force, is resisted implicitly by the strands'
//! elasticity and contact, like every other load. The grid's equations are in [`grid`].
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

pub mod grid;

use bevy::ecs::schedule::InternedScheduleLabel;
use bevy::math::DVec3;
use bevy::platform::collections::HashMap;
use bevy::platform::time::Instant;
use bevy::prelude::*;
use bevy::tasks::ComputeTaskPool;

use crate::HairSystems;
use crate::detail::HairDetailLevel;
use crate::followers::HairFollowers;
use crate::head::StrandOf;
use crate::parallel::run_in_parallel;
use crate::rod::RodError;
use crate::settings::{HairSettings, HairStatistics};
use crate::strand::{SimulatedStrand, StrandForces};
pub use grid::{GridParticle, MAX_GRID_BRICKS, VolumeGrid, VolumeParams};

/// The hair–hair interaction's parameters, in [`HairSettings::volume`].
#[derive(Reflect, Debug, Clone, Copy, PartialEq)]
#[reflect(Debug, Default, Clone, PartialEq)]
pub struct HairVolume {
    /// Whether hair interacts with hair. Default false: the grid costs a sixth to a fifth of a step (6 to 7
    /// ms for 2 000 strands × 32 edges on two cores), and what it buys by default, the velocity
    /// smoothing, shows in motion more than at rest.
    pub enabled: bool,
    /// Spacing of the grid's points, m, from 2 mm to 20 cm: smaller resolves thinner layers of hair and
    /// costs more (the grid spans each head's hair). Default 0.005, which resolves a layer of hair for
    /// the pressure; 0.01 costs a third less and is enough for the smoothing alone.
    pub cell_size: f32,
    /// Velocity smoothing rate, 1/s: where hair is packed at its target fraction, a node's velocity
    /// relative to the hair around it decays as `e^{−rate·t}` (less where the hair is sparser; a lone
    /// strand is not smoothed). 0 turns the smoothing off. Default 5.
    pub velocity_smoothing: f32,
    /// The fraction of space that hair at rest fills, in (0, 1]: denser hair pushes back. Loose human
    /// hair fills about a tenth of its volume; lower gives more volume. Default 0.1.
    pub target_volume_fraction: f32,
    /// Pressure of hair packed at twice its target fraction, Pa (the pressure grows linearly from zero
    /// at the target). 0 turns the pressure off. Default 0: the grooms lay their hair in one thin layer,
    /// packed far beyond any target, and the pressure rearranges a combed style to give it volume (see
    /// the README). 50 with 5 mm cells gives a head of 100 000 hairs a layer of 6 mm instead of 1. It is
    /// an explicit force (the grid is built before the step): the stiffer it is, the smaller the cells
    /// and the longer the step, the likelier it jitters; the tests run 50 Pa on 5 mm cells at 60 Hz.
    pub stiffness: f32,
}

impl Default for HairVolume {
    fn default() -> Self {
        Self { enabled: false, cell_size: 0.005, velocity_smoothing: 5.0, target_volume_fraction: 0.1, stiffness: 0.0 }
    }
}

impl HairVolume {
    /// Checks every parameter's range.
    pub fn validate(&self) -> Result<(), RodError> {
        let checks: [(&'static str, f32, f32, f32, &'static str); 4] = [
            ("volume.cell_size", self.cell_size, 0.002, 0.2, "must be from 0.002 to 0.2 m"),
            ("volume.velocity_smoothing", self.velocity_smoothing, 0.0, 1e4, "must be from 0 to 10 000 1/s"),
            ("volume.target_volume_fraction", self.target_volume_fraction, 1e-3, 1.0, "must be from 0.001 to 1"),
            ("volume.stiffness", self.stiffness, 0.0, 1e5, "must be from 0 to 100 000 Pa"),
        ];
        for (parameter, value, low, high, requirement) in checks {
            if !(low..=high).contains(&value) {
                return Err(RodError::InvalidStepParameter { parameter, value: f64::from(value), requirement });
            }
        }
        Ok(())
    }

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
/// [`crate::HairPlugin`]. Without it (or with [`HairVolume::enabled`] off) strands meet only colliders.
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
/// and pressure force, in parallel.
pub(crate) fn interact_through_grid(
    time: Res<Time>,
    settings: Res<HairSettings>,
    mut grids: ResMut<HairVolumeGrids>,
    mut statistics: ResMut<HairStatistics>,
    mut strands: Query<GridItem>,
) {
    let dt = time.delta_secs_f64();
    // Invalid settings are reported once, by the step, which waits for them.
    if !settings.volume.enabled || settings.validated(dt).is_err() {
        grids.clear();
        statistics.volume_seconds = 0.0;
        statistics.max_volume_fraction = 0.0;
        return;
    }
    let started = Instant::now();
    let params = settings.volume.params(dt);
    grids.begin();
    // Where each strand's nodes go in its head's particles, in query order (so the sums are the same
    // from run to run), then the nodes copied there in parallel.
    for (strand, _, strand_of, _, _, entity) in &strands {
        // Only hair at full detail meets other hair (see `crate::detail`).
        if !at_full_detail(strand) {
            continue;
        }
        let group = grids.group(strand_of.map(|of| of.0));
        group.strands.push((entity, group.nodes));
        group.nodes += strand.rod().node_count();
    }
    for group in &mut grids.groups {
        // Every slot is written below: this only sizes the list (nothing to do when it is unchanged).
        group.particles.resize(group.nodes, GridParticle::default());
    }
    let threads = ComputeTaskPool::try_get().map_or(1, |pool| pool.thread_num()).max(1);
    let readonly = strands.as_readonly();
    for group in &mut grids.groups {
        // Pieces of about equal numbers of strands, each with the particles they fill.
        let chunk = group.strands.len().div_ceil(threads).max(1);
        let mut pieces = Vec::with_capacity(threads);
        let total = group.particles.len();
        let mut rest = group.particles.as_mut_slice();
        for (index, strands_of_piece) in group.strands.chunks(chunk).enumerate() {
            let end = group.strands.get((index + 1) * chunk).map_or(total, |next| next.1);
            let (piece, after) = rest.split_at_mut(end - strands_of_piece[0].1);
            rest = after;
            pieces.push((strands_of_piece, piece));
        }
        run_in_parallel(threads, pieces.into_iter(), |(strands_of_piece, piece)| {
            let first = strands_of_piece[0].1;
            for &(entity, offset) in strands_of_piece {
                let Ok((strand, _, _, represented, followers, _)) = readonly.get(entity) else { continue };
                let hairs = represented_hairs(represented, followers);
                let rod = strand.rod();
                let moving = if strand.is_quarantined() { 0.0 } else { hairs };
                let density = rod.material().density;
                let nodes = rod.positions().iter().zip(rod.velocities()).zip(rod.masses()).enumerate();
                let slots = &mut piece[offset - first..offset - first + rod.node_count()];
                for (slot, (node, ((&position, &velocity), &mass))) in slots.iter_mut().zip(nodes) {
                    *slot = GridParticle {
                        position,
                        velocity,
                        mass: if rod.is_node_prescribed(node) { 0.0 } else { moving * mass },
                        volume: hairs * mass / density,
                    };
                }
            }
        });
    }
    grids.drop_unused();
    let mut max_fraction = 0.0_f64;
    for group in &mut grids.groups {
        group.grid.build(&group.particles, &params);
        max_fraction = max_fraction.max(group.grid.max_volume_fraction());
    }

    let grids = &*grids;
    strands.par_iter_mut().for_each(|(strand, mut forces, strand_of, ..)| {
        let Some(grid) = grids.grid(strand_of.map(|of| of.0)) else { return };
        if strand.is_quarantined() || !at_full_detail(strand) {
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

/// Whether `strand` is stepped at this fixed step at full detail (see [`crate::detail`]).
fn at_full_detail(strand: &SimulatedStrand) -> bool {
    strand.steps_now() && strand.detail_level() == HairDetailLevel::FULL
}

/// How many hairs a strand stands for: its [`RepresentedHairs`], or itself and its followers.
fn represented_hairs(represented: Option<&RepresentedHairs>, followers: Option<&HairFollowers>) -> f64 {
    match represented {
        Some(hairs) => f64::from(hairs.0),
        None => 1.0 + followers.map_or(0, |followers| followers.curves.len()) as f64,
    }
}
