//! Hair grown on a scalp mesh instead of the [`Scalp`]'s ellipsoid: roots spread over its triangles by
//! area (and by a density painted in its vertex colours), each growing from the surface's normal, combed
//! along the surface.

use std::cmp::Ordering;
use std::collections::BinaryHeap;
use std::sync::Arc;

use bevy::math::Affine3A;
use bevy::mesh::VertexAttributeValues;
use bevy::platform::collections::HashMap;
use bevy::prelude::*;

use super::procedural::{GroomError, Scalp, ScalpRoot};
use crate::collision::mesh::mesh_triangles;
use crate::rod::{barycentric, closest_point_on_triangle};

/// On a head: the surface its [`HairGroom`](super::HairGroom) grows on, in the head's local space, in place
/// of its [`Scalp`]'s ellipsoid. [`HairScalpMesh`](crate::scalp::HairScalpMesh) adds it and fills it from
/// the scalp mesh as it is posed when the groom grows; a groom waits while it is
/// [`GroomSurface::Waiting`]. A groom file placed with
/// [`GroomPlacement::fit_to_scalp`](super::GroomPlacement::fit_to_scalp) is fitted to it.
#[derive(Component, Debug, Clone, Default)]
pub enum GroomSurface {
    /// The surface is not known yet (its mesh is loading, or cannot be used): grooms wait.
    #[default]
    Waiting,
    /// The surface to grow on.
    Ready(Arc<ScalpSurface>),
}

impl GroomSurface {
    /// The surface, once known.
    pub fn surface(&self) -> Option<&ScalpSurface> {
        match self {
            Self::Waiting => None,
            Self::Ready(surface) => Some(surface),
        }
    }
}

/// Triangles that grow hair, m, in a head's local space, with a hair density at each corner (0 to 1).
///
/// Roots are spread over it by area times density, evenly (no clumps, no bald patches: Yuksel's *sample
/// elimination*, 2015, over five times as many random points), and inside the [`Scalp`]'s hairline as
/// judged by the surface's normal. The normal is the corners' area-weighted normals blended across the
/// triangle, so that a coarse mesh still combs smoothly; triangles face outwards when their corners run
/// anticlockwise seen from outside (Bevy's front faces).
#[derive(Debug, Clone)]
pub struct ScalpSurface {
    positions: Vec<Vec3>,
    triangles: Vec<[u32; 3]>,
    normals: Vec<Vec3>,
    density: Vec<f32>,
    /// Triangles by the cells (of [`ScalpSurface::cell`] m) their bounds, grown by a cell, overlap.
    cells: HashMap<IVec3, Vec<u32>>,
    cell: f32,
}

impl ScalpSurface {
    /// The surface of `triangles` over `positions` (m, head-local), every corner growing hair at full
    /// density. Triangles without area, or naming a vertex that is missing or not finite, are dropped;
    /// fails if none is left.
    pub fn new(positions: Vec<Vec3>, triangles: Vec<[u32; 3]>) -> Result<Self, GroomError> {
        let usable = |triangle: &[u32; 3]| {
            let corners = triangle.map(|corner| positions.get(corner as usize).copied());
            let [Some(a), Some(b), Some(c)] = corners else { return false };
            a.is_finite() && b.is_finite() && c.is_finite() && (b - a).cross(c - a).length_squared() > 0.0
        };
        let triangles: Vec<[u32; 3]> = triangles.into_iter().filter(usable).collect();
        if triangles.is_empty() {
            return Err(GroomError::NoScalpTriangles);
        }
        let mut normals = vec![Vec3::ZERO; positions.len()];
        let (mut low, mut high, mut edges) = (Vec3::INFINITY, Vec3::NEG_INFINITY, 0.0);
        for triangle in &triangles {
            let [a, b, c] = triangle.map(|corner| positions[corner as usize]);
            let area_normal = (b - a).cross(c - a);
            for corner in triangle {
                normals[*corner as usize] += area_normal;
            }
            (low, high) = (low.min(a).min(b).min(c), high.max(a).max(b).max(c));
            edges += a.distance(b) + b.distance(c) + c.distance(a);
        }
        let normals = normals.into_iter().map(|normal| normal.normalize_or_zero()).collect();
        // Cells of about two edges, and never more than 64 along the surface's longest side.
        let cell = (2.0 * edges / (3.0 * triangles.len() as f32)).max((high - low).max_element() / 64.0);
        let mut surface = Self {
            density: vec![1.0; positions.len()],
            positions,
            triangles,
            normals,
            cells: HashMap::default(),
            cell,
        };
        for (index, triangle) in surface.triangles.iter().enumerate() {
            let [a, b, c] = triangle.map(|corner| surface.positions[corner as usize]);
            let (from, to) = (surface.cell_of(a.min(b).min(c) - cell), surface.cell_of(a.max(b).max(c) + cell));
            for x in from.x..=to.x {
                for y in from.y..=to.y {
                    for z in from.z..=to.z {
                        surface.cells.entry(IVec3::new(x, y, z)).or_default().push(index as u32);
                    }
                }
            }
        }
        Ok(surface)
    }

    /// Its vertices (m), triangles and the hair density at each vertex.
    pub(crate) fn parts(&self) -> (&[Vec3], &[[u32; 3]], &[f32]) {
        (&self.positions, &self.triangles, &self.density)
    }

    /// This surface with a hair density (0 to 1) at each vertex: roots are spread by area times the
    /// density blended across each triangle. Fails if the counts differ, a density is outside 0 to 1, or
    /// no triangle has any.
    pub fn with_density(mut self, density: Vec<f32>) -> Result<Self, GroomError> {
        if density.len() != self.positions.len() {
            return Err(GroomError::ScalpDensity { vertices: self.positions.len(), densities: density.len() });
        }
        if let Some(vertex) = density.iter().position(|value| !(0.0..=1.0).contains(value)) {
            return Err(GroomError::ScalpDensityValue { vertex, value: density[vertex] });
        }
        self.density = density;
        if self.triangles.iter().all(|triangle| triangle.iter().all(|&corner| self.density[corner as usize] == 0.0)) {
            return Err(GroomError::NoScalpTriangles);
        }
        Ok(self)
    }

    /// The surface of a triangle-list `mesh`, its positions taken through `transform` into the head's
    /// local space, with the density painted in its vertex colours ([`ScalpSurface::vertex_density`]).
    pub fn from_mesh(mesh: &Mesh, transform: Affine3A) -> Result<Self, GroomError> {
        let (positions, triangles) = mesh_triangles(mesh, transform).map_err(GroomError::ScalpMesh)?;
        Self::new(positions.iter().map(|position| position.as_vec3()).collect(), triangles)?.painted_by(mesh)
    }

    /// This surface (made of `mesh`'s vertices, in their order) with the density painted in `mesh`'s
    /// vertex colours, if it has them ([`ScalpSurface::vertex_density`]).
    pub fn painted_by(self, mesh: &Mesh) -> Result<Self, GroomError> {
        match Self::vertex_density(mesh) {
            Some(density) => self.with_density(density),
            None => Ok(self),
        }
    }

    /// The hair density painted in `mesh`'s vertex colours ([`Mesh::ATTRIBUTE_COLOR`], linear), if it has
    /// them: each vertex's luminance `0.2126 r + 0.7152 g + 0.0722 b` times its alpha, so white grows full
    /// hair, black none.
    pub fn vertex_density(mesh: &Mesh) -> Option<Vec<f32>> {
        let luminance = |[r, g, b, a]: [f32; 4]| ((0.2126 * r + 0.7152 * g + 0.0722 * b) * a).clamp(0.0, 1.0);
        match mesh.try_attribute(Mesh::ATTRIBUTE_COLOR).ok()? {
            VertexAttributeValues::Float32x4(colors) => Some(colors.iter().map(|&color| luminance(color)).collect()),
            VertexAttributeValues::Float32x3(colors) => {
                Some(colors.iter().map(|&[r, g, b]| luminance([r, g, b, 1.0])).collect())
            }
            _ => None,
        }
    }

    /// The area of the triangles, m², and that of the hair they grow (area times density).
    pub fn area(&self) -> (f32, f32) {
        self.triangles.iter().fold((0.0, 0.0), |(area, hair), triangle| {
            let (triangle_area, density) = self.triangle_area_and_density(triangle);
            (area + triangle_area, hair + triangle_area * density)
        })
    }

    /// The corners of the surface's bounds, m.
    pub fn bounds(&self) -> (Vec3, Vec3) {
        self.triangles.iter().flatten().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(low, high), &corner| {
            let position = self.positions[corner as usize];
            (low.min(position), high.max(position))
        })
    }

    fn triangle_area_and_density(&self, triangle: &[u32; 3]) -> (f32, f32) {
        let [a, b, c] = triangle.map(|corner| self.positions[corner as usize]);
        let density = triangle.iter().map(|&corner| self.density[corner as usize]).sum::<f32>() / 3.0;
        (0.5 * (b - a).cross(c - a).length(), density)
    }

    fn cell_of(&self, point: Vec3) -> IVec3 {
        (point / self.cell).floor().as_ivec3()
    }

    /// Moves the strand `nodes` (head-local, m), whole, so that its root lies on the surface's nearest
    /// point.
    pub fn move_onto(&self, nodes: &mut [Vec3]) {
        let Some(&root) = nodes.first() else { return };
        let offset = self.nearest(root).0 - root;
        nodes.iter_mut().for_each(|node| *node += offset);
    }

    /// The point of the surface nearest `point`, with the surface's blended normal there.
    pub fn nearest(&self, point: Vec3) -> (Vec3, Vec3) {
        self.nearest_near(point).unwrap_or_else(|| {
            let all = 0..self.triangles.len() as u32;
            let (triangle, nearest) = self.nearest_among(point, all).expect("a surface has a triangle");
            (nearest, self.normal_at(triangle, nearest))
        })
    }

    /// The point of the surface nearest `point` with the normal there, if the surface passes within a
    /// grid cell of it (a few of its edges); `None` farther away. Cheap: one cell's triangles (within a
    /// cell of the surface, the nearest triangles are all in the point's cell).
    pub(super) fn nearest_near(&self, point: Vec3) -> Option<(Vec3, Vec3)> {
        let near = self.cells.get(&self.cell_of(point))?;
        let (triangle, nearest) = self.nearest_among(point, near.iter().copied())?;
        (nearest.distance(point) <= self.cell).then(|| (nearest, self.normal_at(triangle, nearest)))
    }

    fn nearest_among(&self, point: Vec3, triangles: impl Iterator<Item = u32>) -> Option<(u32, Vec3)> {
        let point_f64 = point.as_dvec3();
        triangles
            .map(|index| {
                let [a, b, c] = self.triangles[index as usize].map(|corner| self.positions[corner as usize].as_dvec3());
                (index, closest_point_on_triangle(point_f64, a, b, c).as_vec3())
            })
            .min_by(|a, b| a.1.distance_squared(point).total_cmp(&b.1.distance_squared(point)))
    }

    /// The blended normal of `triangle` at `point` (on it).
    fn normal_at(&self, triangle: u32, point: Vec3) -> Vec3 {
        let corners = self.triangles[triangle as usize];
        let [a, b, c] = corners.map(|corner| self.positions[corner as usize]);
        let weights = barycentric(point.as_dvec3(), a.as_dvec3(), b.as_dvec3(), c.as_dvec3()).as_vec3();
        let blended = corners.iter().zip(weights.to_array()).map(|(&corner, w)| w * self.normals[corner as usize]);
        let face = (b - a).cross(c - a).normalize();
        blended.sum::<Vec3>().try_normalize().unwrap_or(face)
    }

    fn density_at(&self, triangle: u32, point: Vec3) -> f32 {
        let corners = self.triangles[triangle as usize];
        let [a, b, c] = corners.map(|corner| self.positions[corner as usize]);
        let weights = barycentric(point.as_dvec3(), a.as_dvec3(), b.as_dvec3(), c.as_dvec3()).as_vec3().to_array();
        corners.iter().zip(weights).map(|(&corner, w)| w * self.density[corner as usize]).sum()
    }

    /// The roots of `guides × every` hairs spread evenly over the surface by area times density, inside
    /// `hairline`'s hairline, drawn with `random`: the roots of `guides` of them, themselves spread evenly,
    /// and the others'.
    pub(super) fn guide_and_follower_roots(
        &self,
        guides: usize,
        every: usize,
        hairline: &Scalp,
        random: &mut fastrand::Rng,
    ) -> Result<(Vec<ScalpRoot>, Vec<ScalpRoot>), GroomError> {
        let count = guides.saturating_mul(every);
        if count == 0 {
            return Ok((Vec::new(), Vec::new()));
        }
        // Triangles drawn by area times their largest corner density, points kept with the density there
        // over that (so kept points are spread by area times density).
        let mut cumulative = Vec::with_capacity(self.triangles.len());
        let mut total = 0.0;
        for triangle in &self.triangles {
            let (area, _) = self.triangle_area_and_density(triangle);
            let most = triangle.iter().map(|&corner| self.density[corner as usize]).fold(0.0, f32::max);
            total += area * most;
            cumulative.push(total);
        }
        let wanted = count.saturating_mul(CANDIDATES_PER_ROOT);
        let mut candidates: Vec<(ScalpRoot, f32)> = Vec::with_capacity(wanted);
        let mut tries = 0_usize;
        while candidates.len() < wanted {
            tries += 1;
            if tries > 100 * wanted.max(100) {
                return Err(GroomError::EmptyScalp {
                    nape_height: hairline.nape_height,
                    brow_height: hairline.brow_height,
                });
            }
            let drawn = random.f32() * total;
            let index = cumulative.partition_point(|&sum| sum <= drawn).min(self.triangles.len() - 1);
            let triangle = self.triangles[index];
            let most = triangle.iter().map(|&corner| self.density[corner as usize]).fold(0.0, f32::max);
            let [a, b, c] = triangle.map(|corner| self.positions[corner as usize]);
            let (u, v) = (random.f32().sqrt(), random.f32());
            let point = a + u * (1.0 - v) * (b - a) + u * v * (c - a);
            let density = self.density_at(index as u32, point);
            if random.f32() * most >= density {
                continue;
            }
            let normal = self.normal_at(index as u32, point);
            if !hairline.grows_hair_at(normal) {
                continue;
            }
            candidates.push((ScalpRoot { position: point, normal }, density));
        }
        let hair_area = self.area().1;
        let kept = eliminate(&candidates, count, hair_area);
        let roots: Vec<(ScalpRoot, f32)> =
            candidates.into_iter().zip(kept).filter_map(|(root, kept)| kept.then_some(root)).collect();
        let is_guide = eliminate(&roots, guides, hair_area);
        let (guides, followers): (Vec<_>, Vec<_>) = roots.into_iter().zip(is_guide).partition(|(_, guide)| *guide);
        let roots = |list: Vec<((ScalpRoot, f32), bool)>| list.into_iter().map(|((root, _), _)| root).collect();
        Ok((roots(guides), roots(followers)))
    }
}

/// Random points drawn for each root kept by [`eliminate`] (Yuksel 2015 uses 5).
const CANDIDATES_PER_ROOT: usize = 5;

/// Which `count` of `candidates` (roots with their hair density) to keep, evenly spread over `area` (m² of
/// hair at full density): Yuksel's weighted sample elimination (2015), removing one by one the point most
/// crowded by its neighbours within twice the spacing of `count` points packed hexagonally, distances
/// measured in units of the local spacing (scaled by the square root of the density).
fn eliminate(candidates: &[(ScalpRoot, f32)], count: usize, area: f32) -> Vec<bool> {
    if candidates.len() <= count {
        return vec![true; candidates.len()];
    }
    // Yuksel's r_max, and the weight (1 − d / 2 r_max)⁸ of a neighbour at scaled distance d.
    let reach = 2.0 * (area / (2.0 * 3.0_f32.sqrt() * count as f32)).sqrt();
    // Where the density is low the spacing is wide: scaled distances count down to a tenth of full density.
    let scale = |density: f32| density.max(0.1).sqrt();
    let search = reach / scale(0.0);
    let cell_of = |point: Vec3| (point / search).floor().as_ivec3();
    let mut grid: HashMap<IVec3, Vec<u32>> = HashMap::default();
    for (index, (root, _)) in candidates.iter().enumerate() {
        grid.entry(cell_of(root.position)).or_default().push(index as u32);
    }
    let neighbours = |index: usize| {
        let (root, density) = candidates[index];
        let cell = cell_of(root.position);
        let grid = &grid;
        (-1..=1)
            .flat_map(move |x| (-1..=1).flat_map(move |y| (-1..=1).map(move |z| cell + IVec3::new(x, y, z))))
            .flat_map(move |near| {
                grid.get(&near).into_iter().flatten().filter_map(move |&other| {
                    let (other_root, other_density) = candidates[other as usize];
                    let distance = root.position.distance(other_root.position) * scale(0.5 * (density + other_density));
                    (other as usize != index && distance < reach)
                        .then(|| (other as usize, (1.0 - distance / reach).powi(8)))
                })
            })
    };
    let mut weights: Vec<f32> = (0..candidates.len()).map(|index| neighbours(index).map(|(_, w)| w).sum()).collect();
    let mut removed = vec![false; candidates.len()];
    let mut heap: BinaryHeap<Crowded> =
        weights.iter().enumerate().map(|(index, &weight)| Crowded { weight, index }).collect();
    let mut left = candidates.len();
    while left > count {
        let Some(Crowded { weight, index }) = heap.pop() else { break };
        if removed[index] || weight != weights[index] {
            continue; // Stale: it was removed, or its weight has fallen since.
        }
        removed[index] = true;
        left -= 1;
        for (other, w) in neighbours(index) {
            if !removed[other] {
                weights[other] -= w;
                heap.push(Crowded { weight: weights[other], index: other });
            }
        }
    }
    removed.into_iter().map(|removed| !removed).collect()
}

/// A candidate and how crowded it is, ordered by that (most crowded first out of the heap).
struct Crowded {
    weight: f32,
    index: usize,
}

impl PartialEq for Crowded {
    fn eq(&self, other: &Self) -> bool {
        self.cmp(other) == Ordering::Equal
    }
}

impl Eq for Crowded {}

impl PartialOrd for Crowded {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for Crowded {
    fn cmp(&self, other: &Self) -> Ordering {
        self.weight.total_cmp(&other.weight).then(other.index.cmp(&self.index))
    }
}
