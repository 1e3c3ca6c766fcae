//! Collider shapes and their geometry: inside tests, closest surface points, where a moving point first
//! enters a shape, and the deepest point of a segment. Everything here works in the collider's own
//! frame, on the shape *inflated* by a strand's collision thickness.

use bevy::math::{DQuat, DVec3};
use bevy::platform::sync::Arc;
use bevy::reflect::Reflect;

use super::distance_field::DistanceField;
use super::error::RodError;

/// The solid shape of a collider, in its own frame (m).
#[derive(Debug, Clone, PartialEq, Reflect)]
pub enum ColliderShape {
    /// A ball of `radius` m around the origin.
    Sphere {
        /// Radius, m.
        radius: f64,
    },
    /// The points within `radius` m of the segment from `(0, −half_length, 0)` to `(0, half_length, 0)`:
    /// a neck, an arm, a shoulder line.
    Capsule {
        /// Radius, m.
        radius: f64,
        /// Half the length of the axis segment (along local Y), m; the capsule is `2 (half_length +
        /// radius)` long in all.
        half_length: f64,
    },
    /// The ellipsoid `Σ (x_i / a_i)² ≤ 1` with semi-axes `a` (m) along local X, Y and Z: the usual skull.
    Ellipsoid {
        /// Semi-axes along local X, Y and Z, m.
        semi_axes: DVec3,
    },
    /// The half-space below the plane through the origin with normal local +Y: a floor, a table.
    Plane,
    /// The points within `rounding` m of the box `|x_i| ≤ h_i` with half extents `h` (m) along local X, Y
    /// and Z: a box with its edges and corners rounded (sharp at `rounding` 0): a shoulder, a chair back,
    /// a hat's brim.
    Cuboid {
        /// Half the box's size along local X, Y and Z, m.
        half_extents: DVec3,
        /// How far the solid reaches beyond the box, rounding its edges and corners, m.
        rounding: f64,
    },
    /// A closed triangle mesh (a face with its ears, shoulders, a body), as the zero level set of a signed
    /// distance field baked from it ([`DistanceField`]): the field's frame scaled by `scale` per axis
    /// (exact under an even scale; under an uneven one, distances are taken at the least scale) and grown
    /// by `inflation` m. Shared, so cloning it is cheap.
    Mesh {
        /// The baked distances, in the mesh's own units before `scale`.
        field: Arc<DistanceField>,
        /// The scale of the field's frame along local X, Y and Z (positive).
        scale: DVec3,
        /// How far the solid reaches beyond the mesh, m.
        inflation: f64,
    },
}

/// Where a point meets a shape: a point on the (inflated) surface and the outward unit normal there.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfacePoint {
    /// The point on the surface, m, in the collider's frame.
    pub point: DVec3,
    /// The outward unit normal there.
    pub normal: DVec3,
}

impl ColliderShape {
    /// A ball of `radius` m.
    pub fn sphere(radius: f64) -> Self {
        Self::Sphere { radius }
    }

    /// A capsule of `radius` m around a segment `2 half_length` m long along local Y.
    pub fn capsule(radius: f64, half_length: f64) -> Self {
        Self::Capsule { radius, half_length }
    }

    /// An ellipsoid with semi-axes `semi_axes` (m) along local X, Y, Z.
    pub fn ellipsoid(semi_axes: DVec3) -> Self {
        Self::Ellipsoid { semi_axes }
    }

    /// A box with half extents `half_extents` (m) along local X, Y, Z, its edges sharp.
    pub fn cuboid(half_extents: DVec3) -> Self {
        Self::Cuboid { half_extents, rounding: 0.0 }
    }

    /// The mesh whose signed distance field is `field`, unscaled.
    pub fn mesh(field: Arc<DistanceField>) -> Self {
        Self::Mesh { field, scale: DVec3::ONE, inflation: 0.0 }
    }

    /// Checks that every dimension is positive and finite (a capsule's half length and a cuboid's rounding
    /// may be zero).
    pub fn validate(&self) -> Result<(), RodError> {
        let check = |parameter, value: f64, minimum_ok: bool| {
            if value.is_finite() && (value > 0.0 || (minimum_ok && value == 0.0)) {
                Ok(())
            } else {
                Err(RodError::InvalidCollider { parameter, value })
            }
        };
        match *self {
            Self::Sphere { radius } => check("radius", radius, false),
            Self::Capsule { radius, half_length } => {
                check("radius", radius, false)?;
                check("half_length", half_length, true)
            }
            Self::Ellipsoid { semi_axes } => {
                check("semi_axes.x", semi_axes.x, false)?;
                check("semi_axes.y", semi_axes.y, false)?;
                check("semi_axes.z", semi_axes.z, false)
            }
            Self::Plane => Ok(()),
            Self::Cuboid { half_extents, rounding } => {
                check("half_extents.x", half_extents.x, false)?;
                check("half_extents.y", half_extents.y, false)?;
                check("half_extents.z", half_extents.z, false)?;
                check("rounding", rounding, true)
            }
            Self::Mesh { scale, inflation, .. } => {
                check("scale.x", scale.x, false)?;
                check("scale.y", scale.y, false)?;
                check("scale.z", scale.z, false)?;
                check("inflation", inflation, true)
            }
        }
    }

    /// The shape seen through a scale of its frame by `scale` (per local axis): a sphere scaled unevenly
    /// becomes an ellipsoid, a capsule takes the larger of its X and Z scales as its radius scale.
    pub fn scaled(&self, scale: DVec3) -> Self {
        let scale = scale.abs();
        match *self {
            Self::Sphere { radius } if scale.x == scale.y && scale.y == scale.z => Self::sphere(radius * scale.x),
            Self::Sphere { radius } => Self::ellipsoid(radius * scale),
            Self::Capsule { radius, half_length } => {
                Self::capsule(radius * scale.x.max(scale.z), half_length * scale.y)
            }
            Self::Ellipsoid { semi_axes } => Self::ellipsoid(semi_axes * scale),
            Self::Plane => Self::Plane,
            // The rounding as the least scale takes it: exact for an even scale or sharp edges.
            Self::Cuboid { half_extents, rounding } => {
                Self::Cuboid { half_extents: half_extents * scale, rounding: rounding * scale.min_element() }
            }
            Self::Mesh { ref field, scale: own, inflation } => {
                Self::Mesh { field: field.clone(), scale: own * scale, inflation: inflation * scale.min_element() }
            }
        }
    }

    /// Radius of a ball around the origin that holds the shape, m (infinite for a plane).
    pub fn bounding_radius(&self) -> f64 {
        match *self {
            Self::Sphere { radius } => radius,
            Self::Capsule { radius, half_length } => radius + half_length,
            Self::Ellipsoid { semi_axes } => semi_axes.max_element(),
            Self::Plane => f64::INFINITY,
            Self::Cuboid { half_extents, rounding } => half_extents.length() + rounding,
            Self::Mesh { ref field, scale, inflation } => {
                let (low, high) = field.bounds();
                (low.abs().max(high.abs()) * scale).length() + inflation
            }
        }
    }

    /// The smallest radius of curvature of the surface, m (infinite for a plane): how sharply an edge
    /// lying on the surface between two touching nodes can dip into it.
    pub fn smallest_curvature_radius(&self) -> f64 {
        match *self {
            Self::Sphere { radius } | Self::Capsule { radius, .. } => radius,
            Self::Ellipsoid { semi_axes } => semi_axes.min_element().powi(2) / semi_axes.max_element(),
            Self::Plane => f64::INFINITY,
            Self::Cuboid { rounding, .. } => rounding,
            // The interpolated surface bends within a cell.
            Self::Mesh { ref field, scale, inflation } => field.cell_size() * scale.min_element() + inflation,
        }
    }

    /// The shape grown outwards by `thickness` m. Exact for spheres, capsules and cuboids (whose rounding
    /// grows); an ellipsoid grows its
    /// semi-axes, which differs from the true offset surface by `O(thickness² / semi-axis)`. A plane is
    /// returned as it is: it grows by moving its frame `thickness` along its normal.
    pub fn inflated(&self, thickness: f64) -> Self {
        match *self {
            Self::Sphere { radius } => Self::sphere(radius + thickness),
            Self::Capsule { radius, half_length } => Self::capsule(radius + thickness, half_length),
            Self::Ellipsoid { semi_axes } => Self::ellipsoid(semi_axes + DVec3::splat(thickness)),
            Self::Plane => Self::Plane,
            Self::Cuboid { half_extents, rounding } => Self::Cuboid { half_extents, rounding: rounding + thickness },
            Self::Mesh { ref field, scale, inflation } => {
                Self::Mesh { field: field.clone(), scale, inflation: inflation + thickness }
            }
        }
    }

    /// A lower bound on the signed distance from `point` to the surface, m (negative inside); exact but
    /// for ellipsoids, and for meshes the interpolated distance. Cheap: used to skip points that cannot
    /// touch the shape this step.
    pub fn distance_bound(&self, point: DVec3) -> f64 {
        match *self {
            Self::Sphere { radius } => point.length() - radius,
            Self::Capsule { radius, half_length } => (point - capsule_axis_point(point, half_length)).length() - radius,
            // `point` lies on the ellipsoid scaled by `s`; the gap between the two surfaces is at least
            // `(s − 1) a_min` outside (`sE = E ⊕ (s − 1)E ⊇ E ⊕ B((s − 1) a_min)`) and `(s − 1) a_max`
            // inside (the surface point `point / s` is that close).
            Self::Ellipsoid { semi_axes } => {
                let scale = (point / semi_axes).length();
                let axis = if scale >= 1.0 { semi_axes.min_element() } else { semi_axes.max_element() };
                (scale - 1.0) * axis
            }
            Self::Plane => point.y,
            Self::Cuboid { half_extents, rounding } => box_distance(half_extents, point) - rounding,
            Self::Mesh { ref field, scale, inflation } => mesh_distance(field, scale, inflation, point).0,
        }
    }

    /// Whether `point` lies strictly inside the shape.
    pub fn contains(&self, point: DVec3) -> bool {
        match *self {
            Self::Ellipsoid { semi_axes } => (point / semi_axes).length_squared() < 1.0,
            _ => self.distance_bound(point) < 0.0,
        }
    }

    /// The point of the surface closest to `point`, with the outward normal there. Used for points
    /// inside the shape; a point at a sphere's centre (or on a capsule's axis) is pushed out along +Y.
    pub fn closest_surface_point(&self, point: DVec3) -> SurfacePoint {
        match *self {
            Self::Sphere { radius } => ball_surface(DVec3::ZERO, radius, point),
            Self::Capsule { radius, half_length } => {
                ball_surface(capsule_axis_point(point, half_length), radius, point)
            }
            Self::Ellipsoid { semi_axes } => closest_ellipsoid_point(semi_axes, point),
            Self::Plane => SurfacePoint { point: DVec3::new(point.x, 0.0, point.z), normal: DVec3::Y },
            Self::Cuboid { half_extents, rounding } => closest_cuboid_point(half_extents, rounding, point),
            Self::Mesh { ref field, scale, inflation } => closest_mesh_point(field, scale, inflation, point),
        }
    }

    /// Where the straight path from `start` (outside) to `end` first enters the shape, if it does.
    pub fn entry(&self, start: DVec3, end: DVec3) -> Option<SurfacePoint> {
        match *self {
            Self::Sphere { radius } => ball_entry(DVec3::ZERO, radius, start, end).map(|(_, hit)| hit),
            Self::Capsule { radius, half_length } => capsule_entry(radius, half_length, start, end),
            Self::Ellipsoid { semi_axes } => {
                let (_, unit) = ball_entry(DVec3::ZERO, 1.0, start / semi_axes, end / semi_axes)?;
                let point = unit.point * semi_axes;
                Some(SurfacePoint { point, normal: (unit.point / semi_axes).normalize() })
            }
            Self::Plane => {
                if start.y < 0.0 || end.y >= 0.0 {
                    return None;
                }
                let fraction = start.y / (start.y - end.y);
                Some(SurfacePoint { point: start.lerp(end, fraction), normal: DVec3::Y })
            }
            Self::Cuboid { .. } => {
                // The signed distance along the path is convex (the solid is): if its least value is
                // inside, the entry is the one root before it.
                if self.distance_bound(start) < 0.0 {
                    return None;
                }
                let (deepest, depth) = self.deepest_along(start, end);
                (depth < 0.0).then(|| self.entry_between(start, end, 0.0, deepest))
            }
            // Not convex: the first stretch between samples half a cell apart that reaches inside.
            Self::Mesh { .. } => {
                if self.contains(start) {
                    return None;
                }
                let (low, deepest, _) = self.mesh_dips(start, end).find(|&(_, _, depth)| depth < 0.0)?;
                Some(self.entry_between(start, end, low, deepest))
            }
        }
    }

    /// The stretches of `start`–`end`, between samples at most half a cell of a mesh's field apart (at
    /// most 256), that can reach inside the mesh, in order: their start, and the fraction and signed
    /// distance of their deepest point. A stretch whose ends lie `d₀` and `d₁` from the surface stays
    /// outside if `d₀ + d₁` exceeds its length (the distance changes no faster than the point moves).
    fn mesh_dips(&self, start: DVec3, end: DVec3) -> impl Iterator<Item = (f64, f64, f64)> {
        let spacing = match self {
            Self::Mesh { field, scale, .. } => 0.5 * field.cell_size() * scale.min_element(),
            _ => f64::INFINITY,
        };
        let length = start.distance(end);
        let intervals = (length / spacing).ceil().clamp(1.0, 256.0) as usize;
        let stretch = length / intervals as f64;
        let distance = move |k: usize| self.distance_bound(start.lerp(end, k as f64 / intervals as f64));
        (0..intervals).filter_map(move |k| {
            // A margin for the interpolation, whose slope may exceed one slightly.
            if distance(k) + distance(k + 1) > 1.1 * stretch {
                return None;
            }
            let (low, high) = (k as f64 / intervals as f64, (k + 1) as f64 / intervals as f64);
            let (deepest, depth) = self.deepest_between(start, end, low, high, MESH_STRETCH_SEARCH);
            Some((low, deepest, depth))
        })
    }

    /// Where the path from `start` to `end` crosses the surface between the fractions `outside` and
    /// `inside` along it, by bisection; the normal from the point just inside.
    fn entry_between(&self, start: DVec3, end: DVec3, mut outside: f64, mut inside: f64) -> SurfacePoint {
        for _ in 0..60 {
            let middle = 0.5 * (outside + inside);
            if self.contains(start.lerp(end, middle)) {
                inside = middle;
            } else {
                outside = middle;
            }
        }
        let surface = self.closest_surface_point(start.lerp(end, inside));
        SurfacePoint { point: start.lerp(end, outside), normal: surface.normal }
    }

    /// The fraction along `start`–`end` of its point deepest in (or nearest to) a cuboid, and the signed
    /// distance there.
    fn deepest_along(&self, start: DVec3, end: DVec3) -> (f64, f64) {
        self.deepest_between(start, end, 0.0, 1.0, 48)
    }

    /// The fraction between `low` and `high` along `start`–`end` of the point deepest in the shape, and
    /// the signed distance there: a golden-section search of `iterations` steps (each shrinks the
    /// bracket by 0.618), exact where the distance is convex along the segment (a convex solid).
    fn deepest_between(&self, start: DVec3, end: DVec3, mut low: f64, mut high: f64, iterations: u32) -> (f64, f64) {
        const GOLDEN: f64 = 0.618_033_988_749_895;
        let distance = |fraction: f64| self.distance_bound(start.lerp(end, fraction));
        let (first, last) = (low, high);
        let (mut a, mut b) = (high - GOLDEN * (high - low), low + GOLDEN * (high - low));
        let (mut at_a, mut at_b) = (distance(a), distance(b));
        for _ in 0..iterations {
            if at_a <= at_b {
                high = b;
                (b, at_b) = (a, at_a);
                a = high - GOLDEN * (high - low);
                at_a = distance(a);
            } else {
                low = a;
                (a, at_a) = (b, at_b);
                b = low + GOLDEN * (high - low);
                at_b = distance(b);
            }
        }
        // The ends too: the least of a convex function on a segment may sit at either end.
        [(0.5 * (low + high), distance(0.5 * (low + high))), (first, distance(first)), (last, distance(last))]
            .into_iter()
            .min_by(|x, y| x.1.total_cmp(&y.1))
            .unwrap_or((first, f64::INFINITY))
    }

    /// The point of the segment `start`–`end` deepest inside the shape when it dips in (both ends may be
    /// outside): its fraction along the segment, and the surface point it is pushed to. `None` when the
    /// segment stays outside, or for a plane (a segment only dips below a plane at an end).
    pub fn segment_contact(&self, start: DVec3, end: DVec3) -> Option<(f64, SurfacePoint)> {
        let (fraction, deepest) = match *self {
            Self::Sphere { .. } => closest_to_origin(start, end),
            Self::Capsule { half_length, .. } => closest_to_axis(start, end, half_length),
            Self::Ellipsoid { semi_axes } => {
                let (fraction, _) = closest_to_origin(start / semi_axes, end / semi_axes);
                (fraction, start.lerp(end, fraction))
            }
            Self::Plane => return None,
            Self::Cuboid { .. } => {
                let (fraction, _) = self.deepest_along(start, end);
                (fraction, start.lerp(end, fraction))
            }
            // The deepest of the stretches that can reach inside.
            Self::Mesh { .. } => {
                let (_, fraction, _) =
                    self.mesh_dips(start, end).min_by(|x, y| x.2.total_cmp(&y.2)).unwrap_or((0.0, 0.0, f64::INFINITY));
                (fraction, start.lerp(end, fraction))
            }
        };
        self.contains(deepest).then(|| (fraction, self.closest_surface_point(deepest)))
    }
}

/// The signed distance from `point` to the box `|x_i| ≤ h_i` (negative inside): `|max(q, 0)| +
/// min(max_i q_i, 0)` with `q = |p| − h` (Quílez, "distance functions").
fn box_distance(half_extents: DVec3, point: DVec3) -> f64 {
    let q = point.abs() - half_extents;
    q.max(DVec3::ZERO).length() + q.max_element().min(0.0)
}

/// The closest point to `point` on the surface of the box with half extents `h` grown by `rounding`, with
/// the outward normal: from the nearest point of the box when `point` is outside the box; through the
/// nearest face (the largest `|p_i| − h_i`) when inside.
fn closest_cuboid_point(half_extents: DVec3, rounding: f64, point: DVec3) -> SurfacePoint {
    let nearest = point.clamp(-half_extents, half_extents);
    if let Some(normal) = (point - nearest).try_normalize() {
        return SurfacePoint { point: nearest + rounding * normal, normal };
    }
    let q = point.abs() - half_extents;
    let axis = if q.x >= q.y && q.x >= q.z {
        0
    } else if q.y >= q.z {
        1
    } else {
        2
    };
    let mut normal = DVec3::ZERO;
    normal[axis] = if point[axis] < 0.0 { -1.0 } else { 1.0 };
    let mut surface = point;
    surface[axis] = normal[axis] * (half_extents[axis] + rounding);
    SurfacePoint { point: surface, normal }
}

/// The point of the capsule's axis segment closest to `point`.
fn capsule_axis_point(point: DVec3, half_length: f64) -> DVec3 {
    DVec3::new(0.0, point.y.clamp(-half_length, half_length), 0.0)
}

/// The closest point to `point` on the sphere of `radius` around `centre`.
fn ball_surface(centre: DVec3, radius: f64, point: DVec3) -> SurfacePoint {
    let normal = (point - centre).try_normalize().unwrap_or(DVec3::Y);
    SurfacePoint { point: centre + radius * normal, normal }
}

/// First crossing of the path `start → end` into the ball of `radius` around `centre`: `|p(s) − c|² = r²`,
/// `p(s) = start + s (end − start)`, smallest root `s ∈ [0, 1]` with `start` outside.
fn ball_entry(centre: DVec3, radius: f64, start: DVec3, end: DVec3) -> Option<(f64, SurfacePoint)> {
    let offset = start - centre;
    let path = end - start;
    let c = offset.length_squared() - radius * radius;
    let a = path.length_squared();
    let b = offset.dot(path);
    if c < 0.0 || a == 0.0 || b >= 0.0 {
        return None;
    }
    let discriminant = b * b - a * c;
    if discriminant < 0.0 {
        return None;
    }
    let fraction = (-b - discriminant.sqrt()) / a;
    (fraction <= 1.0).then(|| {
        let point = start + fraction * path;
        (fraction, SurfacePoint { point, normal: (point - centre) / radius })
    })
}

/// First crossing of `start → end` into a capsule: the earliest entry into its cylinder side (within the
/// axis segment) or into either end ball (the first entry into a union is the earliest into any part).
fn capsule_entry(radius: f64, half_length: f64, start: DVec3, end: DVec3) -> Option<SurfacePoint> {
    let axis_end = DVec3::new(0.0, half_length, 0.0);
    let balls = [axis_end, -axis_end].map(|centre| ball_entry(centre, radius, start, end));
    let path = end - start;
    let (a, b, c) = (
        path.x * path.x + path.z * path.z,
        start.x * path.x + start.z * path.z,
        start.x * start.x + start.z * start.z - radius * radius,
    );
    let side = (c >= 0.0 && a > 0.0 && b < 0.0 && b * b >= a * c)
        .then(|| (-b - (b * b - a * c).sqrt()) / a)
        .filter(|fraction| *fraction <= 1.0)
        .map(|fraction| (fraction, start + fraction * path))
        .filter(|(_, point)| point.y.abs() <= half_length)
        .map(|(fraction, point)| {
            (fraction, SurfacePoint { point, normal: DVec3::new(point.x, 0.0, point.z) / radius })
        });
    balls.into_iter().chain([side]).flatten().min_by(|x, y| x.0.total_cmp(&y.0)).map(|(_, hit)| hit)
}

/// The fraction along `start`–`end` of its point closest to the origin, and that point.
fn closest_to_origin(start: DVec3, end: DVec3) -> (f64, DVec3) {
    let path = end - start;
    let length_squared = path.length_squared();
    let fraction = if length_squared > 0.0 { (-start.dot(path) / length_squared).clamp(0.0, 1.0) } else { 0.0 };
    (fraction, start + fraction * path)
}

/// The point of `start`–`end` closest to the capsule axis segment `(0, ±half_length, 0)`: the closest
/// points of two segments (Ericson, *Real-Time Collision Detection*, 5.1.9).
fn closest_to_axis(start: DVec3, end: DVec3, half_length: f64) -> (f64, DVec3) {
    let path = end - start;
    let axis = DVec3::new(0.0, 2.0 * half_length, 0.0);
    let offset = start + 0.5 * axis;
    let (a, e, f, c) = (path.length_squared(), axis.length_squared(), axis.dot(offset), path.dot(offset));
    let fraction = if a == 0.0 {
        0.0
    } else if e == 0.0 {
        (-c / a).clamp(0.0, 1.0)
    } else {
        let b = path.dot(axis);
        let denominator = a * e - b * b;
        let s = if denominator > 0.0 { ((b * f - c * e) / denominator).clamp(0.0, 1.0) } else { 0.0 };
        let t = (b * s + f) / e;
        if t < 0.0 {
            (-c / a).clamp(0.0, 1.0)
        } else if t > 1.0 {
            ((b - c) / a).clamp(0.0, 1.0)
        } else {
            s
        }
    };
    (fraction, start + fraction * path)
}

/// The closest point to `point` on the ellipsoid with semi-axes `a`: `x_i = a_i² p_i / (a_i² + λ)` where
/// `F(λ) = Σ (a_i p_i / (a_i² + λ))² − 1 = 0` (Eberly, "Distance from a point to an ellipsoid"), solved by
/// Newton's method safeguarded with bisection on `λ ∈ (−a_min², λ_max]`.
fn closest_ellipsoid_point(semi_axes: DVec3, point: DVec3) -> SurfacePoint {
    let squared = semi_axes * semi_axes;
    let smallest = squared.min_element();
    let value = |lambda: f64| {
        let scaled = semi_axes * point / (squared + DVec3::splat(lambda));
        let derivative = -2.0 * (scaled * scaled / (squared + DVec3::splat(lambda))).element_sum();
        (scaled.length_squared() - 1.0, derivative)
    };
    let (mut low, mut high) = (-smallest, (semi_axes * point).length().max(0.0));
    let mut lambda = 0.0_f64.clamp(low, high);
    for _ in 0..64 {
        let (f, derivative) = value(lambda);
        if f > 0.0 {
            low = lambda
        } else {
            high = lambda
        }
        if f.abs() < 1e-13 || high - low < 1e-18 * smallest {
            break;
        }
        let newton = lambda - f / derivative;
        lambda = if newton > low && newton < high && newton.is_finite() { newton } else { 0.5 * (low + high) };
    }
    let surface = squared * point / (squared + DVec3::splat(lambda));
    let normal = (surface / squared).try_normalize();
    match normal {
        Some(normal) if surface.is_finite() && ((surface / semi_axes).length_squared() - 1.0).abs() < 1e-6 => {
            SurfacePoint { point: surface, normal }
        }
        // A point on a symmetry plane through the centre (`F` has no pole at `−a_min²`): push it out radially.
        _ => {
            let direction = point.try_normalize().unwrap_or(DVec3::Y);
            let surface = direction / (direction / semi_axes).length();
            SurfacePoint { point: surface, normal: (surface / squared).normalize() }
        }
    }
}

/// Golden-section steps searching a half-cell stretch of a path for its point deepest in a mesh: the
/// bracket shrinks to 0.618²⁰ ≈ 7·10⁻⁵ of the stretch (0.1 µm in a 3 mm cell), and the depth found is off
/// by the square of that, since the distance is flat at its least.
const MESH_STRETCH_SEARCH: u32 = 20;

/// The signed distance from `point` to a mesh's surface and its gradient: the field at `point / scale`,
/// taken at the least scale, less the inflation.
fn mesh_distance(field: &DistanceField, scale: DVec3, inflation: f64, point: DVec3) -> (f64, DVec3) {
    let least = scale.min_element();
    let (distance, gradient) = field.distance_and_gradient(point / scale);
    (distance * least - inflation, gradient / scale * least)
}

/// The point of a mesh's surface (the field's zero level set) nearest to `point`, by Newton steps along
/// the gradient, `p ← p − d ∇d / |∇d|²`, with the outward normal there.
fn closest_mesh_point(field: &DistanceField, scale: DVec3, inflation: f64, point: DVec3) -> SurfacePoint {
    let mut surface = point;
    for _ in 0..32 {
        let (distance, gradient) = mesh_distance(field, scale, inflation, surface);
        let squared = gradient.length_squared();
        if distance.abs() < 1e-13 || squared < 1e-12 {
            break;
        }
        surface -= gradient * (distance / squared);
    }
    let (_, gradient) = mesh_distance(field, scale, inflation, surface);
    SurfacePoint { point: surface, normal: gradient.try_normalize().unwrap_or(DVec3::Y) }
}

/// A rigid placement of a collider: `x ↦ rotation · x + translation`.
#[derive(Debug, Clone, Copy, PartialEq, Reflect)]
pub struct RigidPose {
    /// Orientation (unit quaternion).
    pub rotation: DQuat,
    /// Position of the collider's origin, m.
    pub translation: DVec3,
}

impl Default for RigidPose {
    fn default() -> Self {
        Self { rotation: DQuat::IDENTITY, translation: DVec3::ZERO }
    }
}

impl RigidPose {
    /// A pose at `translation` turned by `rotation`.
    pub fn new(rotation: DQuat, translation: DVec3) -> Self {
        Self { rotation, translation }
    }

    /// World position of the collider-local point `local`.
    pub fn to_world(&self, local: DVec3) -> DVec3 {
        self.translation + self.rotation * local
    }

    /// Collider-local position of the world point `world`.
    pub fn to_local(&self, world: DVec3) -> DVec3 {
        self.rotation.inverse() * (world - self.translation)
    }
}

/// A collider during one step: its shape, friction and where it is at the start and at the end of the
/// step (so contact follows a collider that moves or turns fast, without tunnelling).
#[derive(Debug, Clone, PartialEq, Reflect)]
pub struct MovingCollider {
    /// The solid shape, in the collider's frame.
    pub shape: ColliderShape,
    /// Coulomb friction coefficient `μ`, dimensionless: hair in contact sticks while the tangential force
    /// is below `μ` times the normal force, and slides against a force `μ` times the normal force.
    pub friction: f64,
    /// Pose at the start of the step.
    pub start: RigidPose,
    /// Pose at the end of the step.
    pub end: RigidPose,
}

impl MovingCollider {
    /// A collider that stays at `pose` during the step.
    pub fn fixed(shape: ColliderShape, friction: f64, pose: RigidPose) -> Self {
        Self { shape, friction, start: pose, end: pose }
    }

    /// Checks the shape's dimensions, the friction coefficient (zero or positive) and the poses.
    pub fn validate(&self) -> Result<(), RodError> {
        self.shape.validate()?;
        if !(self.friction.is_finite() && self.friction >= 0.0) {
            return Err(RodError::InvalidCollider { parameter: "friction", value: self.friction });
        }
        for pose in [self.start, self.end] {
            if !(pose.translation.is_finite() && pose.rotation.is_finite() && pose.rotation.is_normalized()) {
                return Err(RodError::InvalidCollider { parameter: "pose", value: f64::NAN });
            }
        }
        Ok(())
    }

    /// A world-space ball `(centre, radius)` holding the collider at both poses, grown by `margin` m
    /// (an infinite radius for a plane).
    pub fn swept_bounds(&self, margin: f64) -> (DVec3, f64) {
        let centre = 0.5 * (self.start.translation + self.end.translation);
        let travel = 0.5 * self.start.translation.distance(self.end.translation);
        (centre, self.shape.bounding_radius() + travel + margin)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const SHAPES: [ColliderShape; 6] = [
        ColliderShape::Sphere { radius: 0.1 },
        ColliderShape::Capsule { radius: 0.05, half_length: 0.08 },
        ColliderShape::Ellipsoid { semi_axes: DVec3::new(0.08, 0.1, 0.12) },
        ColliderShape::Plane,
        ColliderShape::Cuboid { half_extents: DVec3::new(0.06, 0.1, 0.04), rounding: 0.0 },
        ColliderShape::Cuboid { half_extents: DVec3::new(0.03, 0.05, 0.08), rounding: 0.02 },
    ];

    /// Points spread through a 0.3 m cube around the origin.
    fn probe_points() -> impl Iterator<Item = DVec3> {
        (0..2000).map(|i| {
            let t = i as f64;
            DVec3::new((t * 0.618_034).fract(), (t * 0.754_878).fract(), (t * 0.569_840).fract()) * 0.3
                - DVec3::splat(0.15)
        })
    }

    #[test]
    fn closest_points_lie_on_the_surface_and_are_closest() {
        for shape in SHAPES {
            for point in probe_points().filter(|p| shape.contains(*p)) {
                let surface = shape.closest_surface_point(point);
                // On the surface: just outside along the normal, just inside against it.
                assert!(!shape.contains(surface.point + 1e-9 * surface.normal), "{shape:?} {point}");
                assert!(shape.contains(surface.point - 1e-9 * surface.normal), "{shape:?} {point}");
                // Closest: the offset from the point is along the normal (a stationary distance).
                let offset = surface.point - point;
                assert!(offset.cross(surface.normal).length() < 1e-9, "{shape:?} {point}: {offset}");
                // No other surface point (the surface points of nearby probes) is closer.
                let distance = offset.length();
                for other in probe_points().filter(|p| shape.contains(*p)).take(200) {
                    let candidate = shape.closest_surface_point(other).point;
                    assert!(candidate.distance(point) >= distance - 1e-12, "{shape:?} {point}");
                }
            }
        }
    }

    /// Checks `shape`'s entry on the path `start` (outside) to `end` against 4 000 samples of it: the
    /// first inside sample is just past the entry, and the path enters against the normal. Whether it
    /// entered.
    fn entry_matches_sampling(shape: &ColliderShape, start: DVec3, end: DVec3) -> bool {
        let first_inside = (1..=4000).map(|k| k as f64 / 4000.0).find(|s| shape.contains(start.lerp(end, *s)));
        match (shape.entry(start, end), first_inside) {
            (Some(hit), Some(fraction)) => {
                let sampled = start.lerp(end, fraction);
                assert!(hit.point.distance(sampled) <= start.distance(end) / 4000.0 + 1e-12, "{shape:?}");
                assert!(hit.normal.dot(end - start) < 0.0, "{shape:?}: the path enters against the normal");
                true
            }
            (None, None) => false,
            (hit, sampled) => panic!("{shape:?} {start} → {end}: entry {hit:?}, sampled {sampled:?}"),
        }
    }

    #[test]
    fn entry_points_are_where_a_path_first_crosses_the_surface() {
        for shape in SHAPES {
            let mut entries = 0;
            for (start, end) in probe_points().zip(probe_points().skip(7)) {
                if shape.contains(start) {
                    continue;
                }
                entries += usize::from(entry_matches_sampling(&shape, start, end));
            }
            assert!(entries > 50, "{shape:?}: only {entries} paths entered");
        }
    }

    #[test]
    fn a_segment_dipping_into_a_shape_is_found_at_its_deepest_point() {
        // A chord passing 2 cm inside a 10 cm ball, both ends outside.
        let shape = ColliderShape::sphere(0.1);
        let (fraction, surface) =
            shape.segment_contact(DVec3::new(-0.2, 0.08, 0.0), DVec3::new(0.2, 0.08, 0.0)).unwrap();
        assert!((fraction - 0.5).abs() < 1e-12);
        assert!(surface.point.distance(DVec3::new(0.0, 0.1, 0.0)) < 1e-12);
        // A capsule lying along Y and a segment crossing over its top cap 1 cm deep.
        let capsule = ColliderShape::capsule(0.05, 0.1);
        let (fraction, surface) =
            capsule.segment_contact(DVec3::new(-0.2, 0.14, 0.0), DVec3::new(0.2, 0.14, 0.0)).unwrap();
        assert!((fraction - 0.5).abs() < 1e-6, "{fraction}");
        assert!(surface.point.distance(DVec3::new(0.0, 0.15, 0.0)) < 1e-6);
        assert!(shape.segment_contact(DVec3::new(-0.2, 0.11, 0.0), DVec3::new(0.2, 0.11, 0.0)).is_none());
        assert!(ColliderShape::Plane.segment_contact(DVec3::NEG_Y, DVec3::X).is_none());
        // A segment across a rounded box's edge (box to x, y = 0.1, rounding 2 cm), 1 cm into the rounding:
        // deepest over the edge, pushed out along the diagonal.
        let rounded = ColliderShape::Cuboid { half_extents: DVec3::splat(0.1), rounding: 0.02 };
        let corner_gap = 0.01 / std::f64::consts::SQRT_2;
        let (start, end) = (
            DVec3::new(0.1 + corner_gap - 0.2, 0.1 + corner_gap + 0.2, 0.0),
            DVec3::new(0.1 + corner_gap + 0.2, 0.1 + corner_gap - 0.2, 0.0),
        );
        let (fraction, surface) = rounded.segment_contact(start, end).unwrap();
        assert!((fraction - 0.5).abs() < 1e-6, "{fraction}");
        let expected = DVec3::new(0.1, 0.1, 0.0) + 0.02 * DVec3::new(1.0, 1.0, 0.0).normalize();
        assert!(surface.point.distance(expected) < 1e-6, "{}", surface.point);
        let shifted = DVec3::new(0.02, 0.02, 0.0);
        assert!(rounded.segment_contact(start + shifted, end + shifted).is_none());
    }

    #[test]
    fn distance_bounds_never_exceed_the_distance_to_the_surface() {
        for shape in SHAPES {
            for point in probe_points() {
                let distance = if shape.contains(point) {
                    -point.distance(shape.closest_surface_point(point).point)
                } else {
                    // Outside: the distance is the smallest over surface points, sampled by the
                    // closest points of points inside along the way to the origin.
                    (1..=400)
                        .map(|k| point * (k as f64 / 400.0))
                        .filter(|p| shape.contains(*p))
                        .map(|p| point.distance(shape.closest_surface_point(p).point))
                        .fold(f64::INFINITY, f64::min)
                };
                let bound = shape.distance_bound(point);
                assert!(bound <= distance + 1e-12, "{shape:?} {point}: bound {bound} > distance {distance}");
            }
        }
    }

    #[test]
    fn scaling_and_inflating_change_the_dimensions() {
        assert_eq!(ColliderShape::sphere(0.1).scaled(DVec3::splat(2.0)), ColliderShape::sphere(0.2));
        assert_eq!(
            ColliderShape::sphere(0.1).scaled(DVec3::new(1.0, 2.0, 1.0)),
            ColliderShape::ellipsoid(DVec3::new(0.1, 0.2, 0.1))
        );
        assert_eq!(ColliderShape::capsule(0.1, 0.2).inflated(0.01), ColliderShape::capsule(0.11, 0.2));
        assert!(ColliderShape::sphere(-1.0).validate().is_err());
        assert!(ColliderShape::capsule(0.1, 0.0).validate().is_ok());
        assert!(ColliderShape::ellipsoid(DVec3::new(0.1, f64::NAN, 0.1)).validate().is_err());
        let cuboid = ColliderShape::cuboid(DVec3::new(0.1, 0.2, 0.3));
        assert_eq!(
            cuboid.inflated(0.01),
            ColliderShape::Cuboid { half_extents: DVec3::new(0.1, 0.2, 0.3), rounding: 0.01 }
        );
        assert_eq!(
            cuboid.inflated(0.01).scaled(DVec3::new(2.0, 1.0, 4.0)),
            ColliderShape::Cuboid { half_extents: DVec3::new(0.2, 0.2, 1.2), rounding: 0.01 }
        );
        assert!((cuboid.inflated(0.01).bounding_radius() - (0.14_f64.sqrt() + 0.01)).abs() < 1e-15);
        assert!(cuboid.validate().is_ok());
        assert!(ColliderShape::Cuboid { half_extents: DVec3::new(0.1, 0.0, 0.1), rounding: 0.0 }.validate().is_err());
        assert!(ColliderShape::Cuboid { half_extents: DVec3::splat(0.1), rounding: -0.01 }.validate().is_err());
    }

    /// Meshes as colliders: a baked ball, a baked head with ears (not convex), scaled and grown.
    fn mesh_shapes() -> Vec<ColliderShape> {
        use crate::rod::distance_field::tests::{head_with_ears, uv_sphere};
        let bake = |(positions, triangles): (Vec<DVec3>, Vec<[u32; 3]>), cell| {
            ColliderShape::mesh(Arc::new(DistanceField::bake(&positions, &triangles, cell).unwrap()))
        };
        let ball = bake(uv_sphere(0.1, 32), 0.005);
        let head = bake(head_with_ears(40), 0.004);
        vec![ball.clone(), ball.scaled(DVec3::splat(1.2)).inflated(0.005), head.clone(), head.inflated(0.002)]
    }

    #[test]
    fn a_mesh_is_met_on_its_fields_surface() {
        for shape in mesh_shapes() {
            let (mut closest, mut entries, mut dips) = (0, 0, 0);
            for point in probe_points() {
                assert_eq!(shape.contains(point), shape.distance_bound(point) < 0.0);
                if !shape.contains(point) {
                    continue;
                }
                closest += 1;
                let surface = shape.closest_surface_point(point);
                assert!(shape.distance_bound(surface.point).abs() < 1e-12, "{point}: {surface:?}");
                assert!(!shape.contains(surface.point + 1e-9 * surface.normal), "{point}");
                assert!(shape.contains(surface.point - 1e-9 * surface.normal), "{point}");
                // Near the closest: the field is a distance, within a few per cent where it is smooth.
                let depth = -shape.distance_bound(point);
                assert!(surface.point.distance(point) <= 1.1 * depth + 1e-4, "{point}: {depth}");
            }
            for (start, end) in probe_points().zip(probe_points().skip(7)) {
                if shape.contains(start) {
                    assert!(shape.entry(start, end).is_none());
                    continue;
                }
                entries += usize::from(entry_matches_sampling(&shape, start, end));
                // A segment's deepest point: no sample of it lies deeper.
                if let Some((fraction, surface)) = shape.segment_contact(start, end) {
                    dips += 1;
                    let deepest = shape.distance_bound(start.lerp(end, fraction));
                    let sampled = (0..=400)
                        .map(|k| shape.distance_bound(start.lerp(end, k as f64 / 400.0)))
                        .fold(f64::INFINITY, f64::min);
                    assert!(deepest <= sampled + 1e-9, "{start} → {end}: {deepest} > {sampled}");
                    assert!(shape.distance_bound(surface.point).abs() < 1e-12);
                }
            }
            assert!(closest > 50 && entries > 50 && dips > 50, "{closest} {entries} {dips}");
        }
    }
}
