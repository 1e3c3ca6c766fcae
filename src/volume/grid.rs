//! The grid of hair–hair interaction, free of Bevy's ECS: hair nodes splatted to points `cell_size`
//! apart, the fields computed there, and what each node gets back.
//!
//! **Transfer.** Each hair node (a [`GridParticle`]) is spread over the 8 grid points around it with
//! trilinear weights `w_ic` (summing to 1), and every field comes back to a position with the same
//! weights. So a field's sum over nodes weighted by mass equals its sum over grid points weighted by grid
//! mass, which is what makes the velocity smoothing conserve momentum exactly (below).
//!
//! **Fields at grid point `c`** (cell volume `Δx³`):
//! - mass `M_c = Σ w_ic m_i`, momentum `P_c = Σ w_ic m_i v_i`, velocity `u_c = P_c / M_c`;
//! - hair volume fraction `φ_c = Σ w_ic V_i / Δx³` (`V_i`: the volume of keratin the node stands for);
//! - smoothing fraction `α_c = 1 − exp(−k dt min(φ_c/φ₀, 1))`: the share of a node's velocity difference
//!   from the hair around it that goes in one step at rate `k` (1/s), full where the hair is packed at
//!   its target fraction `φ₀` and fading where it is sparse (a lone strand is not smoothed);
//! - target fraction `φ₀_c = max(φ₀, φ̄_c)`, with `φ̄_c = Σ w_ic V_i φ̄_i / Σ w_ic V_i` the groomed
//!   fraction of the hair there (`φ̄_i`: the fraction where node `i` lay in its groom, measured on the
//!   same grid; 0 where not known). A groom lays its hair in thin layers, packed far beyond any `φ₀`;
//!   measured against its own packing, the pressure leaves a groom at rest as it is and pushes back only
//!   where hair is pressed together more than it was groomed;
//! - pressure `p_c = K max(φ_c/φ₀_c − 1, 0)` (Pa): hair pushes back only when packed more densely than
//!   that; its push per volume of keratin `g_c = ∇p_c / max(φ_c, φ₀_c)` (central differences).
//!
//! **What a node gets back.**
//! - Velocity smoothing (Petrovic, Henne, Anderson 2005): `Δv_i = Σ_c w_ic α_c (u_c − v_i)`. Its momentum
//!   `Σ_i m_i Δv_i = Σ_c α_c (u_c M_c − P_c) = 0`: exactly conserved, and a uniform velocity field is left
//!   as it is. It is a filter on velocities, unconditionally stable (`α_c < 1`), and independent of the
//!   step's length because `α_c` is the exact decay of `k` over `dt`.
//! - Volume pressure (after McAdams, Selle, Ward, Sifakis, Teran 2009, without their global solve):
//!   force `f_i = −V_i Σ_c w_ic g_c`, a node's own keratin volume times the push: hydrostatic
//!   equilibrium of a hair layer, `dp/dn = −φ ρ g`, holds the hair up where it is piled.
//!
//! **Storage.** Hair fills a thin shell around a head, a small part of its bounding box, so the grid is
//! sparse: bricks of 4 × 4 × 4 points, allocated where hair is, found through a dense table over the
//! bounding box (one `u32` per brick). The box is cut into slabs of z layers of bricks, one per thread;
//! each slab owns its part of the table and its own bricks, and splats every node's share that lands in
//! it, allocating bricks as it meets them. No two threads write the same memory, and each grid point
//! receives its sums in the nodes' order, whatever the number of threads.

use std::ops::Range;

use bevy::math::DVec3;
use bevy::tasks::ComputeTaskPool;

use crate::parallel::run_in_parallel;

/// Most bricks in a grid's bounding box: a grid that would need more (hair spread over metres) coarsens
/// its cells until it fits. 2¹⁸ bricks, a box of 256³ points (1 m at 4 mm); the table is 1 MB.
pub const MAX_GRID_BRICKS: usize = 1 << 18;

/// Grid points along each edge of a brick.
const BRICK: usize = 4;
/// Grid points in a brick.
const BRICK_POINTS: usize = BRICK * BRICK * BRICK;
/// A table entry with no brick.
const NO_BRICK: u32 = u32::MAX;

/// A hair node as the grid sees it: where it is, how it moves, and how much hair it stands for.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct GridParticle {
    /// Position, m.
    pub position: DVec3,
    /// Velocity, m/s.
    pub velocity: DVec3,
    /// Mass of the hair it stands for that the smoothing acts on, kg (0 for a node whose motion is
    /// prescribed: it takes part in the volume, not in the smoothing).
    pub mass: f64,
    /// Volume of keratin of the hair it stands for, m³.
    pub volume: f64,
    /// The hair volume fraction where the node lies in its groom (0: not known). The pressure leaves hair
    /// packed up to its groomed fraction alone (see the module documentation).
    pub groomed_fraction: f64,
}

/// The physical parameters of the grid's response.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VolumeParams {
    /// Spacing of the grid points `Δx`, m.
    pub cell_size: f64,
    /// Velocity smoothing rate `k`, 1/s.
    pub smoothing_rate: f64,
    /// Target hair volume fraction `φ₀`, in (0, 1].
    pub target_fraction: f64,
    /// Pressure stiffness `K`, Pa: the pressure of hair packed at twice `φ₀`.
    pub stiffness: f64,
    /// The step's length, s.
    pub dt: f64,
}

/// One grid point. While splatting, `velocity` holds the momentum `P_c` (kg·m/s), `smoothing` the
/// mass `M_c` (kg) and `fraction` the keratin volume (m³); [`VolumeGrid::compute_fields`] turns them
/// into what their names say.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct GridPoint {
    /// `α_c u_c`, m/s.
    velocity: DVec3,
    /// `α_c`.
    smoothing: f64,
    /// `φ_c`.
    fraction: f64,
    /// The fraction beyond which the pressure pushes, `φ₀_c = max(φ₀, φ̄_c)`.
    target: f64,
}

type Brick = [GridPoint; BRICK_POINTS];

/// Where a grid lies: its first point, its spacing, its size in bricks, and the brick layers per slab.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct Placement {
    origin: DVec3,
    cell_size: f64,
    bricks: [usize; 3],
    slab_layers: usize,
}

/// The 8 grid points around a position, x fastest: where each is (its brick's table index, its index
/// within the brick) and its trilinear weight.
#[derive(Debug, Clone, Copy)]
struct Stencil {
    table_indices: [usize; 8],
    local_indices: [usize; 8],
    weights: [f64; 8],
    /// The z layer of bricks of the lower and upper points.
    brick_layers: [usize; 2],
}

/// The bricks of one slab of brick layers, in the order the splat met them.
#[derive(Debug, Default)]
struct Slab {
    /// The bricks in use (the first `used`) and spare ones.
    bricks: Vec<Brick>,
    /// The pressure's push `g_c = ∇p_c / max(φ_c, φ₀_c)` (Pa/m) at each point of each brick in use,
    /// while the grid is `pressed`.
    pushes: Vec<[DVec3; BRICK_POINTS]>,
    /// Coordinates of each brick in use, in bricks.
    coordinates: Vec<[usize; 3]>,
    used: usize,
}

/// A hair grid (one head's), rebuilt every step around its hair, axis-aligned, its points on multiples
/// of the cell size (hair at rest sees the same grid from step to step). All memory is reused from step
/// to step.
#[derive(Debug, Default)]
pub struct VolumeGrid {
    placement: Placement,
    /// Index of each brick of the bounding box (z-major) among its slab's bricks, or [`NO_BRICK`].
    table: Vec<u32>,
    slabs: Vec<Slab>,
    /// Whether the pressure pushes anywhere (a stiffness, and hair packed beyond its target).
    pressed: bool,
    max_fraction: f64,
}

impl VolumeGrid {
    /// Rebuilds the grid around `particles` and computes its fields with `params`. Particles with a
    /// non-finite position or velocity are left out (the mechanics never produce them); a cell that is not
    /// a positive length places an empty grid.
    pub fn build(&mut self, particles: &[GridParticle], params: &VolumeParams) {
        let usable = particles.iter().filter(|particle| usable(particle.position, particle.velocity));
        let bounds =
            usable.fold(EMPTY_BOX, |bounds, particle| enclosing(bounds, (particle.position, particle.position)));
        self.build_within(particles, bounds, params);
    }

    /// [`VolumeGrid::build`], with the box around the usable particles (finite position and velocity)
    /// known: its lowest and highest corner (an empty box, lowest above highest, when there are none).
    /// A cell that is not a positive length places an empty grid (its fields 0 everywhere): coarsening
    /// it would never fit the hair (`HairVolume::validate` refuses such a cell before).
    pub(crate) fn build_within(&mut self, particles: &[GridParticle], bounds: (DVec3, DVec3), params: &VolumeParams) {
        if params.cell_size.is_finite() && params.cell_size > 0.0 {
            self.place(bounds, params.cell_size);
            self.splat(particles);
        } else {
            self.place(EMPTY_BOX, 1.0);
        }
        self.compute_fields(params);
    }

    /// Spacing of the grid points, m: [`VolumeParams::cell_size`], or coarser where the hair spreads
    /// over a box of more than [`MAX_GRID_BRICKS`] bricks.
    pub fn cell_size(&self) -> f64 {
        self.placement.cell_size
    }

    /// Grid points in use (in bricks where there is hair).
    pub fn points(&self) -> usize {
        self.slabs.iter().map(|slab| slab.used).sum::<usize>() * BRICK_POINTS
    }

    /// Whether the pressure pushes anywhere (some hair is packed beyond its target, and the stiffness is
    /// not zero).
    pub fn pressed(&self) -> bool {
        self.pressed
    }

    /// Largest hair volume fraction at a grid point.
    pub fn max_volume_fraction(&self) -> f64 {
        self.max_fraction
    }

    /// The hair volume fraction at `position`, interpolated (0 where there is no hair).
    pub fn volume_fraction_at(&self, position: DVec3) -> f64 {
        let Some(stencil) = self.placement.stencil(position) else { return 0.0 };
        let mut sum = 0.0;
        self.for_each_corner(&stencil, |slab, brick, local, weight| {
            sum += weight * self.slabs[slab].bricks[brick][local].fraction;
        });
        sum
    }

    /// The largest hair volume fraction at the 8 grid points around `position` (0 where there is no
    /// hair): how densely the hair there is packed, at least, wherever in its cell it lies.
    pub fn densest_fraction_around(&self, position: DVec3) -> f64 {
        let Some(stencil) = self.placement.stencil(position) else { return 0.0 };
        let mut densest = 0.0_f64;
        self.for_each_corner(&stencil, |slab, brick, local, _| {
            densest = densest.max(self.slabs[slab].bricks[brick][local].fraction);
        });
        densest
    }

    /// The velocity change `Δv = Σ w α (u − v)` of a node at `position` moving at `velocity` (m/s),
    /// and the pressure's force on a node of keratin volume `volume` (m³), N.
    pub fn response(&self, position: DVec3, velocity: DVec3, volume: f64) -> (DVec3, DVec3) {
        let Some(stencil) = self.placement.stencil(position) else {
            return (DVec3::ZERO, DVec3::ZERO);
        };
        let (mut smoothed, mut smoothing, mut push) = (DVec3::ZERO, 0.0, DVec3::ZERO);
        self.for_each_corner(&stencil, |slab, brick, local, weight| {
            let slab = &self.slabs[slab];
            let point = &slab.bricks[brick][local];
            smoothed += weight * point.velocity;
            smoothing += weight * point.smoothing;
            if self.pressed {
                push += weight * slab.pushes[brick][local];
            }
        });
        (smoothed - smoothing * velocity, -volume * push)
    }

    /// Places the grid around the box `(low, high)` of the usable particles, coarsening the cells if it
    /// would be too large, and cuts it into one slab per thread.
    fn place(&mut self, (mut low, mut high): (DVec3, DVec3), cell_size: f64) {
        if low.x > high.x {
            (low, high) = (DVec3::ZERO, DVec3::ZERO);
        }
        let mut cell = cell_size;
        let (origin, bricks) = loop {
            // One empty point below the lowest particle's and two above the highest's, so that every
            // stencil and its neighbours are in the box.
            let first = (low / cell).floor() - DVec3::ONE;
            let points = (high / cell).floor() - first + DVec3::splat(3.0);
            let bricks = (points / BRICK as f64).ceil();
            if bricks.x * bricks.y * bricks.z <= MAX_GRID_BRICKS as f64 {
                break (first * cell, [bricks.x as usize, bricks.y as usize, bricks.z as usize]);
            }
            cell *= (bricks.x * bricks.y * bricks.z / MAX_GRID_BRICKS as f64).cbrt() * 1.01;
        };
        let threads = ComputeTaskPool::try_get().map_or(1, |pool| pool.thread_num()).clamp(1, bricks[2]);
        let slab_layers = bricks[2].div_ceil(threads);
        self.placement = Placement { origin, cell_size: cell, bricks, slab_layers };
        self.table.clear();
        self.table.resize(bricks.iter().product(), NO_BRICK);
        self.slabs.resize_with(bricks[2].div_ceil(slab_layers), Slab::default);
        for slab in &mut self.slabs {
            slab.used = 0;
            slab.coordinates.clear();
        }
    }

    /// Spreads the particles' momentum, mass and volume over the grid, in parallel over the slabs: each
    /// takes every particle's share that lands in its layers, in the particles' order, allocating its
    /// bricks as it meets them.
    fn splat(&mut self, particles: &[GridParticle]) {
        let placement = self.placement;
        let layer = placement.bricks[0] * placement.bricks[1];
        let slabs = self.slabs.len();
        let tables = self.table.chunks_mut(placement.slab_layers * layer);
        let work = self.slabs.iter_mut().zip(tables).enumerate();
        let splat_slab = |(index, (slab, table)): (usize, (&mut Slab, &mut [u32]))| {
            let layers = index * placement.slab_layers..(index + 1) * placement.slab_layers;
            let first_entry = layers.start * layer;
            for particle in particles.iter().filter(|particle| usable(particle.position, particle.velocity)) {
                let Some(stencil) = placement.stencil_in(particle.position, &layers) else { continue };
                let momentum = particle.mass * particle.velocity;
                for k in 0..8 {
                    if !layers.contains(&stencil.brick_layers[k >> 2]) {
                        continue;
                    }
                    let entry = &mut table[stencil.table_indices[k] - first_entry];
                    if *entry == NO_BRICK {
                        *entry = slab.allocate(placement.brick_coordinates(stencil.table_indices[k]));
                    }
                    let point = &mut slab.bricks[*entry as usize][stencil.local_indices[k]];
                    let weight = stencil.weights[k];
                    point.velocity += weight * momentum;
                    point.smoothing += weight * particle.mass;
                    point.fraction += weight * particle.volume;
                    point.target += weight * particle.volume * particle.groomed_fraction;
                }
            }
        };
        run_in_parallel(slabs, work, splat_slab);
    }

    /// Turns the splatted sums into velocity, smoothing and volume fraction at every grid point, then
    /// computes the pressure's push.
    fn compute_fields(&mut self, params: &VolumeParams) {
        let cell_volume = self.placement.cell_size.powi(3);
        let target = params.target_fraction;
        let rate = params.smoothing_rate * params.dt;
        let (mut max_fraction, mut packed) = (0.0_f64, false);
        for slab in &mut self.slabs {
            for point in slab.bricks[..slab.used].iter_mut().flatten() {
                let (momentum, mass) = (point.velocity, point.smoothing);
                if point.fraction == 0.0 {
                    continue;
                }
                point.target = (point.target / point.fraction).max(target);
                point.fraction /= cell_volume;
                max_fraction = max_fraction.max(point.fraction);
                packed |= point.fraction > point.target;
                (point.velocity, point.smoothing) = if mass > 0.0 && rate > 0.0 {
                    let smoothing = 1.0 - (-rate * (point.fraction / target).min(1.0)).exp();
                    (smoothing * momentum / mass, smoothing)
                } else {
                    (DVec3::ZERO, 0.0)
                };
            }
        }
        self.max_fraction = max_fraction;
        self.pressed = params.stiffness > 0.0 && packed;
        if !self.pressed {
            return;
        }
        for index in 0..self.slabs.len() {
            let mut pushes = std::mem::take(&mut self.slabs[index].pushes);
            pushes.resize(self.slabs[index].used.max(pushes.len()), [DVec3::ZERO; BRICK_POINTS]);
            self.compute_pushes(index, &mut pushes, params);
            self.slabs[index].pushes = pushes;
        }
    }

    /// The pressure's push at every point of slab `index`'s bricks, from each brick's pressures with a
    /// layer of its face neighbours' around them.
    fn compute_pushes(&self, index: usize, pushes: &mut [[DVec3; BRICK_POINTS]], params: &VolumeParams) {
        let half_over_cell = 0.5 / self.placement.cell_size;
        let pressure = |point: &GridPoint| {
            if point.fraction > point.target { params.stiffness * (point.fraction / point.target - 1.0) } else { 0.0 }
        };
        const PADDED: usize = BRICK + 2;
        let mut padded = [[[0.0_f64; PADDED]; PADDED]; PADDED];
        let slab = &self.slabs[index];
        let bricks = slab.bricks[..slab.used].iter().zip(&slab.coordinates);
        for ((brick, &coordinates), pushes) in bricks.zip(pushes.iter_mut()) {
            for (local, point) in brick.iter().enumerate() {
                let [x, y, z] = local_coordinates(local);
                padded[x + 1][y + 1][z + 1] = pressure(point);
            }
            for axis in 0..3 {
                for (side, padded_layer, neighbour_layer) in [(-1, 0, BRICK - 1), (1, BRICK + 1, 0)] {
                    let neighbour = self.neighbour_brick(coordinates, axis, side);
                    for a in 0..BRICK {
                        for b in 0..BRICK {
                            // The face's two other axes, in order.
                            let mut local = [0; 3];
                            let mut padded_at = [0; 3];
                            let others = [(axis + 1) % 3, (axis + 2) % 3];
                            (local[others[0]], local[others[1]]) = (a, b);
                            (padded_at[others[0]], padded_at[others[1]]) = (a + 1, b + 1);
                            local[axis] = neighbour_layer;
                            padded_at[axis] = padded_layer;
                            let value = neighbour.map_or(0.0, |neighbour| pressure(&neighbour[local_index(local)]));
                            padded[padded_at[0]][padded_at[1]][padded_at[2]] = value;
                        }
                    }
                }
            }
            for (local, push) in pushes.iter_mut().enumerate() {
                let GridPoint { fraction, target, .. } = brick[local];
                if fraction == 0.0 {
                    *push = DVec3::ZERO;
                    continue;
                }
                let [x, y, z] = local_coordinates(local).map(|coordinate| coordinate + 1);
                let gradient = DVec3::new(
                    padded[x + 1][y][z] - padded[x - 1][y][z],
                    padded[x][y + 1][z] - padded[x][y - 1][z],
                    padded[x][y][z + 1] - padded[x][y][z - 1],
                ) * half_over_cell;
                *push = gradient / fraction.max(target);
            }
        }
    }

    /// The brick in use beside the brick at `coordinates` on `side` (±1) along `axis`, if any.
    fn neighbour_brick(&self, coordinates: [usize; 3], axis: usize, side: isize) -> Option<&Brick> {
        let mut neighbour = coordinates;
        neighbour[axis] = neighbour[axis].checked_add_signed(side)?;
        if neighbour[axis] >= self.placement.bricks[axis] {
            return None;
        }
        let [bx, by, _] = self.placement.bricks;
        let entry = neighbour[0] + bx * (neighbour[1] + by * neighbour[2]);
        match self.table[entry] {
            NO_BRICK => None,
            brick => Some(&self.slabs[neighbour[2] / self.placement.slab_layers].bricks[brick as usize]),
        }
    }

    /// Calls `visit(slab, brick, index within it, weight)` for those of the 8 grid points of `stencil`
    /// that are in bricks (all of them for a particle's stencil; a position with no hair near meets
    /// fewer).
    fn for_each_corner(&self, stencil: &Stencil, mut visit: impl FnMut(usize, usize, usize, f64)) {
        for k in 0..8 {
            let brick = self.table[stencil.table_indices[k]];
            if brick != NO_BRICK {
                let slab = stencil.brick_layers[k >> 2] / self.placement.slab_layers;
                visit(slab, brick as usize, stencil.local_indices[k], stencil.weights[k]);
            }
        }
    }
}

impl Slab {
    /// A zeroed brick for the brick at `coordinates`, reusing memory: its index.
    fn allocate(&mut self, coordinates: [usize; 3]) -> u32 {
        if self.used == self.bricks.len() {
            self.bricks.push([GridPoint::default(); BRICK_POINTS]);
        } else {
            self.bricks[self.used] = [GridPoint::default(); BRICK_POINTS];
        }
        self.coordinates.push(coordinates);
        self.used += 1;
        (self.used - 1) as u32
    }
}

impl Placement {
    /// The 8 grid points around `position`, if they are in the box.
    fn stencil(&self, position: DVec3) -> Option<Stencil> {
        let (corner, local) = self.corner(position)?;
        Some(self.stencil_at(corner, local))
    }

    /// The stencil of the position `local` (in grid units) whose lowest grid point is `corner`.
    fn stencil_at(&self, corner: [usize; 3], local: DVec3) -> Stencil {
        // Along each axis: the lower and upper point's brick, index within it, and weight.
        let along = |axis: usize| {
            let (low, high) = (corner[axis], corner[axis] + 1);
            let fraction = local[axis] - low as f64;
            ([low / BRICK, high / BRICK], [low % BRICK, high % BRICK], [1.0 - fraction, fraction])
        };
        let ((bx, lx, wx), (by, ly, wy), (bz, lz, wz)) = (along(0), along(1), along(2));
        let [stride_x, stride_y, _] = self.bricks;
        let (ty, tz) = (by.map(|b| stride_x * b), bz.map(|b| stride_x * stride_y * b));
        let (ly, lz) = (ly.map(|l| BRICK * l), lz.map(|l| BRICK * BRICK * l));
        let mut stencil = Stencil { table_indices: [0; 8], local_indices: [0; 8], weights: [0.0; 8], brick_layers: bz };
        for k in 0..8 {
            let (i, j, l) = (k & 1, (k >> 1) & 1, k >> 2);
            stencil.table_indices[k] = bx[i] + ty[j] + tz[l];
            stencil.local_indices[k] = lx[i] + ly[j] + lz[l];
            stencil.weights[k] = wx[i] * wy[j] * wz[l];
        }
        stencil
    }

    /// The lowest of the 8 grid points around `position` and the position in grid units, if the 8 are
    /// in the box.
    fn corner(&self, position: DVec3) -> Option<([usize; 3], DVec3)> {
        let local = (position - self.origin) * (1.0 / self.cell_size);
        // Truncation is the floor here: the box starts below every particle.
        let corner = [local.x as usize, local.y as usize, local.z as usize];
        let inside = local.cmpge(DVec3::ZERO).all() && (0..3).all(|axis| corner[axis] + 1 < self.bricks[axis] * BRICK);
        inside.then_some((corner, local))
    }

    /// [`Placement::stencil`], for a position with grid points in the brick `layers` (`None` for the
    /// others, cheaply).
    fn stencil_in(&self, position: DVec3, layers: &Range<usize>) -> Option<Stencil> {
        let (corner, local) = self.corner(position)?;
        let z = corner[2];
        if !(layers.contains(&(z / BRICK)) || layers.contains(&((z + 1) / BRICK))) {
            return None;
        }
        Some(self.stencil_at(corner, local))
    }

    /// Coordinates, in bricks, of the brick at `entry` in the table.
    fn brick_coordinates(&self, entry: usize) -> [usize; 3] {
        let [bx, by, _] = self.bricks;
        [entry % bx, entry / bx % by, entry / (bx * by)]
    }
}

/// Coordinates within its brick of the point `local` of a brick.
fn local_coordinates(local: usize) -> [usize; 3] {
    [local % BRICK, local / BRICK % BRICK, local / (BRICK * BRICK)]
}

/// Index of grid point `point` within its brick.
fn local_index(point: [usize; 3]) -> usize {
    point[0] % BRICK + BRICK * (point[1] % BRICK + BRICK * (point[2] % BRICK))
}

/// A box around nothing (its lowest corner above its highest), to grow with [`enclosing`].
pub(crate) const EMPTY_BOX: (DVec3, DVec3) = (DVec3::INFINITY, DVec3::NEG_INFINITY);

/// The smallest box around the boxes `a` and `b` (each its lowest and highest corner).
pub(crate) fn enclosing(a: (DVec3, DVec3), b: (DVec3, DVec3)) -> (DVec3, DVec3) {
    (a.0.min(b.0), a.1.max(b.1))
}

/// Whether the grid takes a particle at `position` moving at `velocity`: both finite.
pub(crate) fn usable(position: DVec3, velocity: DVec3) -> bool {
    position.is_finite() && velocity.is_finite()
}
