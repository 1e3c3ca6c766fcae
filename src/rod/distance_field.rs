//! Signed distance fields baked from closed triangle meshes: a face, ears, shoulders or a whole body as a
//! collider. The distance is sampled on a regular grid once and read back by trilinear interpolation, so
//! the collider's surface is the zero level set of that interpolation (within a fraction of a cell of
//! the mesh, closer where the mesh is smooth).
//!
//! Baking (Bridson's `makelevelset3`, as in Batty's SDFGen): exact point–triangle distances in a band
//! of [`EXACT_BAND_CELLS`] cells around each triangle, spread to the rest of the grid by sweeping each
//! sample's nearest triangle to its neighbours, and the sign from the winding number along rows of
//! samples in X, Y and Z (inside where at least two of the three agree, which forgives small holes). The
//! winding number counts a crossing into the mesh +1 and out of it −1 (by the triangle's facing): a face
//! with ears, eyes or a nose as closed shells of their own, overlapping it, is inside wherever any shell
//! is, as it is drawn (the parity of crossings would call the overlaps outside).

use bevy::math::DVec3;
use bevy::reflect::TypePath;
use thiserror::Error;

/// Cells around each triangle whose samples get the exact distance to it before the sweeps.
pub const EXACT_BAND_CELLS: f64 = 2.0;

/// Cells of empty space kept around the mesh, so that a point approaching it is seen a few cells away.
pub const MARGIN_CELLS: f64 = 3.0;

/// The most samples a field may have (8 M samples, 32 MB): a bound on what a typo in a resolution asks.
pub const MAX_SAMPLES: usize = 8 << 20;

/// Why a mesh could not be baked into a [`DistanceField`].
#[derive(Debug, Clone, PartialEq, Error)]
pub enum DistanceFieldError {
    /// The mesh has no triangles.
    #[error("the mesh has no triangles")]
    NoTriangles,
    /// A triangle names a vertex that does not exist.
    #[error("triangle {triangle} names vertex {vertex}, but the mesh has {vertices} vertices")]
    IndexOutOfRange {
        /// The triangle's index.
        triangle: usize,
        /// The vertex index it names.
        vertex: u32,
        /// How many vertices there are.
        vertices: usize,
    },
    /// A vertex has a NaN or infinite coordinate.
    #[error("vertex {vertex} is not finite: {position}")]
    NonFiniteVertex {
        /// The vertex's index.
        vertex: usize,
        /// Its position, m.
        position: DVec3,
    },
    /// The cell size is not a positive finite length.
    #[error("the cell size must be a positive finite length in metres, got {0}")]
    InvalidCellSize(f64),
    /// The grid would have more than [`MAX_SAMPLES`](super::MAX_DISTANCE_FIELD_SAMPLES) samples.
    #[error("a grid of {samples} samples was asked for, more than the {MAX_SAMPLES} allowed: use larger cells")]
    TooManySamples {
        /// The samples the mesh and the cell size need.
        samples: usize,
    },
}

/// A signed distance field on a regular grid of samples, m: negative inside the mesh, positive outside.
#[derive(Debug, Clone, PartialEq, TypePath)]
pub struct DistanceField {
    /// The first sample's position, m.
    min: DVec3,
    /// The distance between neighbouring samples, m.
    cell: f64,
    /// Samples along X, Y and Z (each at least 2).
    counts: [usize; 3],
    /// Signed distances, m, X fastest.
    values: Vec<f32>,
    /// Edges of the mesh (its vertices welded by position) used by one triangle, or by three or more.
    open_edges: usize,
}

impl DistanceField {
    /// Bakes the mesh made of `triangles` (indices into `positions`, m) on a grid of cubic cells of
    /// `cell_size` m. The mesh should be closed; where it is not, the sign is taken from the majority of
    /// three directions and [`DistanceField::open_edges`] counts its open edges.
    pub fn bake(positions: &[DVec3], triangles: &[[u32; 3]], cell_size: f64) -> Result<Self, DistanceFieldError> {
        if triangles.is_empty() {
            return Err(DistanceFieldError::NoTriangles);
        }
        if !(cell_size.is_finite() && cell_size > 0.0) {
            return Err(DistanceFieldError::InvalidCellSize(cell_size));
        }
        for (triangle, indices) in triangles.iter().enumerate() {
            if let Some(&vertex) = indices.iter().find(|&&vertex| vertex as usize >= positions.len()) {
                return Err(DistanceFieldError::IndexOutOfRange { triangle, vertex, vertices: positions.len() });
            }
        }
        let used = || triangles.iter().flatten().map(|&vertex| vertex as usize);
        if let Some(vertex) = used().find(|&vertex| !positions[vertex].is_finite()) {
            return Err(DistanceFieldError::NonFiniteVertex { vertex, position: positions[vertex] });
        }
        let (low, high) = used().fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(low, high), vertex| {
            (low.min(positions[vertex]), high.max(positions[vertex]))
        });
        let margin = MARGIN_CELLS * cell_size;
        let min = low - DVec3::splat(margin);
        let span = (high - low + DVec3::splat(2.0 * margin)) / cell_size;
        let counts = span.to_array().map(|cells| cells.ceil() as usize + 1);
        let samples = counts.iter().try_fold(1_usize, |product, &count| product.checked_mul(count));
        match samples {
            Some(samples) if samples <= MAX_SAMPLES => {}
            samples => return Err(DistanceFieldError::TooManySamples { samples: samples.unwrap_or(usize::MAX) }),
        }
        let mut baker = Baker::new(positions, triangles, min, cell_size, counts);
        baker.exact_band();
        baker.sweep();
        let inside = baker.inside();
        let values = baker
            .distance
            .iter()
            .zip(&inside)
            .map(|(&distance, &inside)| if inside { -distance as f32 } else { distance as f32 })
            .collect();
        Ok(Self { min, cell: cell_size, counts, values, open_edges: open_edges(positions, triangles) })
    }

    /// The distance between neighbouring samples, m.
    pub fn cell_size(&self) -> f64 {
        self.cell
    }

    /// Samples along X, Y and Z.
    pub fn sample_counts(&self) -> [usize; 3] {
        self.counts
    }

    /// The box the samples span, `(min, max)`, m.
    pub fn bounds(&self) -> (DVec3, DVec3) {
        let span = DVec3::new(self.counts[0] as f64, self.counts[1] as f64, self.counts[2] as f64) - DVec3::ONE;
        (self.min, self.min + span * self.cell)
    }

    /// The signed distances at the samples, m, X fastest: sample `(x, y, z)` at `x + n_x (y + n_y z)`
    /// ([`DistanceField::sample_counts`]), at `min + cell (x, y, z)` ([`DistanceField::bounds`]).
    pub fn samples(&self) -> &[f32] {
        &self.values
    }

    /// Edges of the mesh that do not join exactly two triangles (its vertices welded by position): 0 for
    /// a closed mesh.
    pub fn open_edges(&self) -> usize {
        self.open_edges
    }

    /// The interpolated signed distance at `point` and its gradient, m and dimensionless. Outside the
    /// grid: a lower bound on the distance (the mesh lies inside the grid), pointing away from it.
    pub fn distance_and_gradient(&self, point: DVec3) -> (f64, DVec3) {
        let (low, high) = self.bounds();
        let inner = point.clamp(low, high);
        let (at_inner, gradient) = self.interpolate(inner);
        let away = point - inner;
        let gap = away.length();
        if gap == 0.0 {
            return (at_inner, gradient);
        }
        // `|d(p) − d(c)| ≤ |p − c|`, and the mesh lies inside the grid, so `d(p) ≥ |p − c|`.
        (gap.max(at_inner - gap), away / gap)
    }

    /// Trilinear interpolation of the samples around `point` (which lies within the grid), with its
    /// gradient.
    fn interpolate(&self, point: DVec3) -> (f64, DVec3) {
        let local = (point - self.min) / self.cell;
        let mut corner = [0_usize; 3];
        let mut fraction = DVec3::ZERO;
        for axis in 0..3 {
            let cell = (local[axis].floor().max(0.0) as usize).min(self.counts[axis] - 2);
            corner[axis] = cell;
            fraction[axis] = (local[axis] - cell as f64).clamp(0.0, 1.0);
        }
        let value = |dx: usize, dy: usize, dz: usize| {
            f64::from(self.values[self.index(corner[0] + dx, corner[1] + dy, corner[2] + dz)])
        };
        let (fx, fy, fz) = (fraction.x, fraction.y, fraction.z);
        let lerp = |a: f64, b: f64, t: f64| a + (b - a) * t;
        // Along X on the cell's four X edges, then Y, then Z.
        let edge = |dy, dz| (value(0, dy, dz), value(1, dy, dz));
        let [(a00, b00), (a10, b10), (a01, b01), (a11, b11)] = [edge(0, 0), edge(1, 0), edge(0, 1), edge(1, 1)];
        let (x00, x10, x01, x11) = (lerp(a00, b00, fx), lerp(a10, b10, fx), lerp(a01, b01, fx), lerp(a11, b11, fx));
        let (y0, y1) = (lerp(x00, x10, fy), lerp(x01, x11, fy));
        let distance = lerp(y0, y1, fz);
        let along_x = lerp(lerp(b00 - a00, b10 - a10, fy), lerp(b01 - a01, b11 - a11, fy), fz);
        let along_y = lerp(x10 - x00, x11 - x01, fz);
        let along_z = y1 - y0;
        (distance, DVec3::new(along_x, along_y, along_z) / self.cell)
    }

    fn index(&self, x: usize, y: usize, z: usize) -> usize {
        x + self.counts[0] * (y + self.counts[1] * z)
    }
}

/// The grid while it is baked: unsigned distances and each sample's nearest triangle so far.
struct Baker<'a> {
    positions: &'a [DVec3],
    triangles: &'a [[u32; 3]],
    min: DVec3,
    cell: f64,
    counts: [usize; 3],
    distance: Vec<f64>,
    nearest: Vec<u32>,
}

const NO_TRIANGLE: u32 = u32::MAX;

impl<'a> Baker<'a> {
    fn new(positions: &'a [DVec3], triangles: &'a [[u32; 3]], min: DVec3, cell: f64, counts: [usize; 3]) -> Self {
        let samples = counts.iter().product();
        Self {
            positions,
            triangles,
            min,
            cell,
            counts,
            distance: vec![f64::INFINITY; samples],
            nearest: vec![NO_TRIANGLE; samples],
        }
    }

    fn sample(&self, x: usize, y: usize, z: usize) -> DVec3 {
        self.min + DVec3::new(x as f64, y as f64, z as f64) * self.cell
    }

    fn index(&self, x: usize, y: usize, z: usize) -> usize {
        x + self.counts[0] * (y + self.counts[1] * z)
    }

    fn corners(&self, triangle: u32) -> [DVec3; 3] {
        self.triangles[triangle as usize].map(|vertex| self.positions[vertex as usize])
    }

    /// The samples within a range of cells along each axis, clamped to the grid.
    fn sample_range(&self, low: DVec3, high: DVec3, axis: usize) -> std::ops::Range<usize> {
        let count = self.counts[axis] as f64;
        let first = ((low[axis] - self.min[axis]) / self.cell).ceil().clamp(0.0, count) as usize;
        let past = (((high[axis] - self.min[axis]) / self.cell).floor() + 1.0).clamp(0.0, count) as usize;
        first.min(past)..past
    }

    /// Exact distances to each triangle at the samples within [`EXACT_BAND_CELLS`] of its bounding box.
    fn exact_band(&mut self) {
        let band = DVec3::splat(EXACT_BAND_CELLS * self.cell);
        for triangle in 0..self.triangles.len() as u32 {
            let [a, b, c] = self.corners(triangle);
            let (low, high) = (a.min(b).min(c) - band, a.max(b).max(c) + band);
            for z in self.sample_range(low, high, 2) {
                for y in self.sample_range(low, high, 1) {
                    for x in self.sample_range(low, high, 0) {
                        self.offer(self.index(x, y, z), self.sample(x, y, z), triangle);
                    }
                }
            }
        }
    }

    /// Keeps `triangle` as the sample's nearest if it is nearer than the one it has.
    fn offer(&mut self, index: usize, sample: DVec3, triangle: u32) {
        let [a, b, c] = self.corners(triangle);
        let distance = sample.distance(closest_point_on_triangle(sample, a, b, c));
        if distance < self.distance[index] {
            self.distance[index] = distance;
            self.nearest[index] = triangle;
        }
    }

    /// Spreads nearest triangles from each sample to its neighbours, sweeping the grid in all eight
    /// diagonal directions.
    fn sweep(&mut self) {
        let [nx, ny, nz] = self.counts;
        for direction in 0..8 {
            let step = [direction & 1, direction & 2, direction & 4].map(|bit| if bit == 0 { 1_isize } else { -1 });
            let order = |count: usize, step: isize| -> Vec<usize> {
                if step > 0 { (0..count).collect() } else { (0..count).rev().collect() }
            };
            let (xs, ys, zs) = (order(nx, step[0]), order(ny, step[1]), order(nz, step[2]));
            for &z in &zs {
                for &y in &ys {
                    for &x in &xs {
                        let index = self.index(x, y, z);
                        let sample = self.sample(x, y, z);
                        let behind = [
                            x.checked_add_signed(-step[0]).filter(|&x| x < nx).map(|x| self.index(x, y, z)),
                            y.checked_add_signed(-step[1]).filter(|&y| y < ny).map(|y| self.index(x, y, z)),
                            z.checked_add_signed(-step[2]).filter(|&z| z < nz).map(|z| self.index(x, y, z)),
                        ];
                        for neighbour in behind.into_iter().flatten() {
                            let triangle = self.nearest[neighbour];
                            if triangle != NO_TRIANGLE && triangle != self.nearest[index] {
                                self.offer(index, sample, triangle);
                            }
                        }
                    }
                }
            }
        }
    }

    /// Whether each sample is inside: a winding number other than zero along rows in X, Y and Z (each
    /// crossing before it counted +1 where the triangle faces back along the row, into the mesh, and −1
    /// where it faces along it), by a majority of the three. Shells wound inside out count −1 and are
    /// inside all the same.
    fn inside(&self) -> Vec<bool> {
        let mut votes = vec![0_u8; self.distance.len()];
        for axis in 0..3 {
            let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
            let (count, count_u, count_v) = (self.counts[axis], self.counts[u], self.counts[v]);
            // Signed crossings per row, at the first sample past each crossing.
            let mut crossings = vec![0_i16; self.distance.len()];
            let row_index = |along: usize, iu: usize, iv: usize| {
                let mut cell = [0; 3];
                cell[axis] = along;
                cell[u] = iu;
                cell[v] = iv;
                self.index(cell[0], cell[1], cell[2])
            };
            for triangle in 0..self.triangles.len() as u32 {
                let corners = self.corners(triangle);
                let flat = corners.map(|corner| [corner[u], corner[v]]);
                // The triangle's normal along the row is its flat area's sign (u, v, axis right-handed):
                // facing back along the row, the row enters the mesh through it.
                let into = if orient(flat[0], flat[1], flat[2]) < 0.0 { 1 } else { -1 };
                let (low, high) =
                    (corners[0].min(corners[1]).min(corners[2]), corners[0].max(corners[1]).max(corners[2]));
                for iv in self.sample_range(low, high, v) {
                    for iu in self.sample_range(low, high, u) {
                        let point = [self.min[u] + iu as f64 * self.cell, self.min[v] + iv as f64 * self.cell];
                        let Some(weights) = barycentric_with_ties(point, flat) else {
                            continue;
                        };
                        let along = weights[0] * corners[0][axis]
                            + weights[1] * corners[1][axis]
                            + weights[2] * corners[2][axis];
                        let first_past = ((along - self.min[axis]) / self.cell).floor() as isize + 1;
                        if (0..count as isize).contains(&first_past) {
                            let index = row_index(first_past as usize, iu, iv);
                            crossings[index] = crossings[index].saturating_add(into);
                        }
                    }
                }
            }
            for iv in 0..count_v {
                for iu in 0..count_u {
                    let mut winding = 0_i32;
                    for along in 0..count {
                        let index = row_index(along, iu, iv);
                        winding += i32::from(crossings[index]);
                        votes[index] += u8::from(winding != 0);
                    }
                }
            }
        }
        votes.into_iter().map(|votes| votes >= 2).collect()
    }
}

/// The barycentric weights of `point` in the flat triangle `corners` if the point lies in it, by a
/// rule that gives a point on an edge or a vertex shared by triangles of a closed surface to exactly one
/// of them (edges taken counter-clockwise; a point on an edge belongs to the triangle to the edge's left
/// when the edge points up, or right along a horizontal edge).
fn barycentric_with_ties(point: [f64; 2], corners: [[f64; 2]; 3]) -> Option<[f64; 3]> {
    let area = orient(corners[0], corners[1], corners[2]);
    if area == 0.0 {
        return None;
    }
    let corners = if area < 0.0 { [corners[0], corners[2], corners[1]] } else { corners };
    let mut weights = [0.0; 3];
    for i in 0..3 {
        let (from, to) = (corners[(i + 1) % 3], corners[(i + 2) % 3]);
        let side = orient(from, to, point);
        let owns_edge = to[1] > from[1] || (to[1] == from[1] && to[0] < from[0]);
        if side < 0.0 || (side == 0.0 && !owns_edge) {
            return None;
        }
        weights[i] = side;
    }
    let total = weights[0] + weights[1] + weights[2];
    let weights = weights.map(|weight| weight / total);
    Some(if area < 0.0 { [weights[0], weights[2], weights[1]] } else { weights })
}

/// Twice the signed area of the flat triangle `a`, `b`, `c` (positive counter-clockwise).
fn orient(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> f64 {
    (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
}

/// The barycentric coordinates of `point` (in the triangle's plane) in the triangle `a`, `b`, `c`.
pub fn barycentric(point: DVec3, a: DVec3, b: DVec3, c: DVec3) -> DVec3 {
    let (ab, ac, ap) = (b - a, c - a, point - a);
    let (d00, d01, d11) = (ab.dot(ab), ab.dot(ac), ac.dot(ac));
    let (d20, d21) = (ap.dot(ab), ap.dot(ac));
    let denominator = d00 * d11 - d01 * d01;
    let v = (d11 * d20 - d01 * d21) / denominator;
    let w = (d00 * d21 - d01 * d20) / denominator;
    DVec3::new(1.0 - v - w, v, w)
}

/// The point of triangle `a`, `b`, `c` closest to `point` (Ericson, "Real-Time Collision Detection",
/// 5.1.5: the Voronoi region of `point` among the corners, edges and face).
pub fn closest_point_on_triangle(point: DVec3, a: DVec3, b: DVec3, c: DVec3) -> DVec3 {
    let (ab, ac, ap) = (b - a, c - a, point - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = point - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return a + ab * (d1 / (d1 - d3));
    }
    let cp = point - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return a + ac * (d2 / (d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0 {
        return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    }
    let denominator = va + vb + vc;
    if denominator == 0.0 {
        // A degenerate (flat) triangle: the nearest of its edges' points.
        return [(a, b), (b, c), (c, a)]
            .map(|(from, to)| {
                let along = to - from;
                let t = if along == DVec3::ZERO {
                    0.0
                } else {
                    ((point - from).dot(along) / along.length_squared()).clamp(0.0, 1.0)
                };
                from + along * t
            })
            .into_iter()
            .min_by(|x, y| x.distance_squared(point).total_cmp(&y.distance_squared(point)))
            .unwrap_or(a);
    }
    a + ab * (vb / denominator) + ac * (vc / denominator)
}

/// Edges used by other than two triangles, with vertices welded by position to a millionth of the mesh's
/// extent (a UV seam's twin vertices, computed at angles 0 and 2π, differ in their last bits).
fn open_edges(positions: &[DVec3], triangles: &[[u32; 3]]) -> usize {
    use std::collections::HashMap;
    let (low, high) = triangles
        .iter()
        .flatten()
        .map(|&vertex| positions[vertex as usize])
        .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(low, high), p| (low.min(p), high.max(p)));
    let weld = ((high - low).max_element() * 1e-6).max(f64::MIN_POSITIVE);
    let key = |vertex: u32| ((positions[vertex as usize] - low) / weld).round().to_array().map(|v| v as i64);
    let mut uses: HashMap<([i64; 3], [i64; 3]), u32> = HashMap::new();
    for triangle in triangles {
        for i in 0..3 {
            let (from, to) = (key(triangle[i]), key(triangle[(i + 1) % 3]));
            if from != to {
                *uses.entry(if from < to { (from, to) } else { (to, from) }).or_default() += 1;
            }
        }
    }
    uses.values().filter(|&&count| count != 2).count()
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A UV sphere of `radius` m with `rings` rings and `2 rings` segments, closed (shared poles).
    pub(crate) fn uv_sphere(radius: f64, rings: u32) -> (Vec<DVec3>, Vec<[u32; 3]>) {
        star_shaped(|_| radius, rings)
    }

    /// A closed UV-sphere mesh whose surface in direction `d` lies at `radius(d)` m from the origin: the
    /// support crate's, which the integration tests bake too.
    pub(crate) use hair_sim_support::star_shaped;

    /// A head with ears: a 9 × 11 × 10 cm ellipsoid with a 3 cm bump on either side (not convex).
    pub(crate) fn head_with_ears(rings: u32) -> (Vec<DVec3>, Vec<[u32; 3]>) {
        star_shaped(
            |d| {
                let skull = 1.0 / (d / DVec3::new(0.09, 0.11, 0.1)).length();
                let ear = 0.03 * (-(d - DVec3::X).length_squared() / 0.02).exp()
                    + 0.03 * (-(d + DVec3::X).length_squared() / 0.02).exp();
                skull + ear
            },
            rings,
        )
    }

    /// An axis-aligned box with half extents `half` m, its faces split in two triangles.
    pub(crate) fn box_mesh(half: DVec3) -> (Vec<DVec3>, Vec<[u32; 3]>) {
        let positions = (0..8)
            .map(|i| {
                DVec3::new(
                    if i & 1 == 0 { -1.0 } else { 1.0 },
                    if i & 2 == 0 { -1.0 } else { 1.0 },
                    if i & 4 == 0 { -1.0 } else { 1.0 },
                ) * half
            })
            .collect();
        let faces = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]];
        let triangles = faces.iter().flat_map(|&[a, b, c, d]| [[a, b, c], [a, c, d]]).collect();
        (positions, triangles)
    }

    /// Points spread through a box of half size `half` m.
    fn probes(half: f64, count: usize) -> impl Iterator<Item = DVec3> {
        (0..count).map(move |i| {
            let t = i as f64;
            (DVec3::new((t * 0.618_034).fract(), (t * 0.754_878).fract(), (t * 0.569_840).fract()) * 2.0 - DVec3::ONE)
                * half
        })
    }

    #[test]
    fn closest_points_on_a_triangle_are_closest() {
        let (a, b, c) = (DVec3::new(0.0, 0.0, 0.0), DVec3::new(1.0, 0.0, 0.0), DVec3::new(0.2, 0.8, 0.1));
        for point in probes(2.0, 3000) {
            let closest = closest_point_on_triangle(point, a, b, c);
            let distance = closest.distance(point);
            // No point of a fine sampling of the triangle is closer.
            for i in 0..=40 {
                for j in 0..=40 - i {
                    let (s, t) = (f64::from(i) / 40.0, f64::from(j) / 40.0);
                    let on = a + (b - a) * s + (c - a) * t;
                    assert!(on.distance(point) >= distance - 1e-12, "{point}: {closest} is not closest");
                }
            }
        }
    }

    #[test]
    fn a_baked_sphere_and_box_have_their_distances() {
        let (positions, triangles) = uv_sphere(0.1, 48);
        let field = DistanceField::bake(&positions, &triangles, 0.004).unwrap();
        assert_eq!(field.open_edges(), 0);
        // The mesh is a polyhedron inscribed in the sphere: its faces lie up to `r (1 − cos(π/48))` inside.
        let facets = 0.1 * (1.0 - (std::f64::consts::PI / 48.0).cos());
        let mut worst: f64 = 0.0;
        let within = |field: &DistanceField, point: DVec3| {
            point.cmpge(field.bounds().0).all() && point.cmple(field.bounds().1).all()
        };
        for point in probes(0.16, 4000).filter(|point| within(&field, *point)) {
            let expected = point.length() - 0.1;
            let (distance, gradient) = field.distance_and_gradient(point);
            worst = worst.max((distance - expected).abs());
            assert!(
                (distance - expected).abs() < facets + 0.15 * field.cell_size(),
                "{point}: {distance} against {expected}"
            );
            if expected.abs() < 0.03 {
                assert!(gradient.angle_between(point) < 0.2, "{point}: gradient {gradient}");
            }
        }
        assert!(worst > 0.0);
        let (positions, triangles) = box_mesh(DVec3::new(0.1, 0.05, 0.08));
        let field = DistanceField::bake(&positions, &triangles, 0.005).unwrap();
        assert_eq!(field.open_edges(), 0);
        for point in probes(0.15, 4000).filter(|point| within(&field, *point)) {
            let q = point.abs() - DVec3::new(0.1, 0.05, 0.08);
            let expected = q.max(DVec3::ZERO).length() + q.max_element().min(0.0);
            let (distance, _) = field.distance_and_gradient(point);
            // Trilinear interpolation is exact on faces, and off by a fraction of a cell by edges.
            assert!((distance - expected).abs() < 0.3 * field.cell_size(), "{point}: {distance} against {expected}");
        }
    }

    #[test]
    fn a_hole_is_outvoted_and_bad_meshes_are_refused() {
        let (positions, mut triangles) = box_mesh(DVec3::splat(0.1));
        triangles.remove(0);
        let field = DistanceField::bake(&positions, &triangles, 0.01).unwrap();
        assert_eq!(field.open_edges(), 3);
        for point in probes(0.09, 500) {
            assert!(field.distance_and_gradient(point).0 < 0.0, "{point} is inside");
        }
        assert_eq!(DistanceField::bake(&positions, &[], 0.01), Err(DistanceFieldError::NoTriangles));
        assert!(matches!(
            DistanceField::bake(&positions, &[[0, 1, 8]], 0.01),
            Err(DistanceFieldError::IndexOutOfRange { triangle: 0, vertex: 8, vertices: 8 })
        ));
        let mut bad = positions.clone();
        bad[2].y = f64::NAN;
        assert!(matches!(
            DistanceField::bake(&bad, &triangles, 0.01),
            Err(DistanceFieldError::NonFiniteVertex { vertex: 2, .. })
        ));
        for cell in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            assert!(matches!(
                DistanceField::bake(&positions, &triangles, cell),
                Err(DistanceFieldError::InvalidCellSize(_))
            ));
        }
        assert!(matches!(
            DistanceField::bake(&positions, &triangles, 1e-5),
            Err(DistanceFieldError::TooManySamples { .. })
        ));
    }

    #[test]
    fn shells_that_overlap_are_inside_where_any_of_them_is() {
        // A 10 cm ball with a 3 cm ball sunk halfway into its side (an ear), and behind it a box wound
        // inside out: every point inside any of them is inside, by more than a cell's error. (A shell wound
        // inside out that overlaps one wound right cancels it there, as the parity of crossings would.)
        let (mut positions, mut triangles) = uv_sphere(0.1, 48);
        let (ear, ear_triangles) = uv_sphere(0.03, 24);
        let (block, block_triangles) = box_mesh(DVec3::new(0.02, 0.02, 0.012));
        for (shell, shell_triangles, centre, inside_out) in [
            (ear, ear_triangles, DVec3::new(0.1, 0.0, 0.0), false),
            (block, block_triangles, DVec3::new(0.0, 0.0, -0.125), true),
        ] {
            let first = positions.len() as u32;
            positions.extend(shell.iter().map(|&corner| corner + centre));
            triangles.extend(shell_triangles.iter().map(|&[a, b, c]| {
                if inside_out { [first + a, first + c, first + b] } else { [first + a, first + b, first + c] }
            }));
        }
        let field = DistanceField::bake(&positions, &triangles, 0.004).unwrap();
        let facets = 0.1 * (1.0 - (std::f64::consts::PI / 48.0).cos());
        let (mut overlaps, mut in_blocks, mut worst_overlap) = (0, 0, f64::INFINITY);
        for point in probes(0.14, 20_000) {
            let in_ball = 0.1 - point.length();
            let in_ear = 0.03 - point.distance(DVec3::new(0.1, 0.0, 0.0));
            let q = (point - DVec3::new(0.0, 0.0, -0.125)).abs() - DVec3::new(0.02, 0.02, 0.012);
            let in_block = -q.max_element();
            let depth = in_ball.max(in_ear).max(in_block);
            if depth > facets + field.cell_size() {
                let (distance, _) = field.distance_and_gradient(point);
                assert!(distance < 0.0, "{point}, {depth} m inside: {distance}");
                in_blocks += usize::from(in_block > 0.0);
                if in_ball > 0.0 && in_ear > 0.0 {
                    overlaps += 1;
                    worst_overlap = worst_overlap.min(-distance);
                }
            }
        }
        // The overlap was probed (with the parity of crossings, it baked as outside), and the box.
        assert!(overlaps > 20 && in_blocks > 5, "{overlaps} probes in the overlap, {in_blocks} in the box");
        assert!(worst_overlap > 0.0);
    }

    #[test]
    fn outside_the_grid_the_distance_is_a_lower_bound() {
        let (positions, triangles) = uv_sphere(0.1, 24);
        let field = DistanceField::bake(&positions, &triangles, 0.01).unwrap();
        for point in probes(1.0, 2000) {
            let (distance, _) = field.distance_and_gradient(point);
            // The polyhedron holds the ball of its faces' least distance from the centre.
            let inner = 0.1 * (std::f64::consts::PI / 24.0).cos().powi(2);
            assert!(distance <= point.length() - inner + 1e-12, "{point}: {distance}");
            if point.length() > 0.2 {
                assert!(distance > 0.0);
            }
        }
    }
}
