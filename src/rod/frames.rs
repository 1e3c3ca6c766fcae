//! Geometry of the discrete framed curve: parallel transport, signed angles, curvature binormals.

use bevy::math::DVec3;

use super::lanes::{LaneMask, Points, Real, Vector, lanes_in};

/// Parallel transport `P(from → to) v`: the minimal rotation taking unit tangent `from` to unit tangent `to`,
/// applied to `v`. With `b = from × to` and `c = from · to`: `P v = c v + b × v + (b · v) b / (1 + c)`.
///
/// Identity when the tangents coincide. When they are opposite the rotation is not unique; a half turn
/// about an axis perpendicular to `from` is used.
pub fn parallel_transport(v: DVec3, from: DVec3, to: DVec3) -> DVec3 {
    let axis = from.cross(to);
    let cosine = from.dot(to);
    if 1.0 + cosine < 1e-12 {
        let perpendicular = from.any_orthonormal_vector();
        return 2.0 * perpendicular.dot(v) * perpendicular - v;
    }
    cosine * v + axis.cross(v) + axis.dot(v) / (1.0 + cosine) * axis
}

/// Signed angle, in radians in `(−π, π]`, that rotates `u` onto `v` about the unit `axis` (both ⟂ `axis`).
pub fn signed_angle(u: DVec3, v: DVec3, axis: DVec3) -> f64 {
    u.cross(v).dot(axis).atan2(u.dot(v))
}

/// Curvature binormal on unit tangents: `(κb)_i = 2 t^{i−1} × t^i / (1 + t^{i−1} · t^i)`, of length `2 tan(φ/2)`.
pub fn curvature_binormal(previous_tangent: DVec3, next_tangent: DVec3) -> DVec3 {
    2.0 * previous_tangent.cross(next_tangent) / (1.0 + previous_tangent.dot(next_tangent))
}

/// Material directors `(m1, m2)` from the reference director `a1`, the tangent `t` and the twist angle `θ`:
/// `m1 = cos θ a1 + sin θ a2`, `m2 = −sin θ a1 + cos θ a2`, with `a2 = t × a1`.
pub fn material_directors(reference: DVec3, tangent: DVec3, twist: f64) -> (DVec3, DVec3) {
    let (m1, m2) = directors_turned_by(reference.into(), tangent.into(), twist);
    (m1.lane(0), m2.lane(0))
}

/// [`material_directors`] for one strand (`f64`, the same operations as glam's) or a lockstep batch's
/// lanes (`sin_cos` lane by lane).
#[inline(always)]
pub(crate) fn directors_turned_by<T: Real>(
    reference: Vector<T>,
    tangent: Vector<T>,
    twist: T,
) -> (Vector<T>, Vector<T>) {
    let reference_2 = tangent.cross(reference);
    let (sin, cos) = twist.sin_cos();
    (reference.scale(cos) + reference_2.scale(sin), reference_2.scale(cos) - reference.scale(sin))
}

/// `v` made perpendicular to the unit `tangent` and normalised; `None` when `v` is (nearly) parallel to it
/// or not finite.
pub fn perpendicular_unit(v: DVec3, tangent: DVec3) -> Option<DVec3> {
    let perpendicular = v - v.dot(tangent) * tangent;
    let length = perpendicular.length();
    (length.is_finite() && length > 1e-9 * v.length()).then(|| perpendicular / length)
}

/// The angle `a` wrapped into `(−π, π]`.
pub fn wrap_angle(a: f64) -> f64 {
    let pi = std::f64::consts::PI;
    a - (2.0 * pi) * ((a + pi) / (2.0 * pi)).floor()
}

/// The reference frames carried to the current positions, for one strand (`f64`) or a lockstep
/// batch's lanes, with the same operations as [`parallel_transport`], [`perpendicular_unit`],
/// [`signed_angle`] and [`wrap_angle`] in every lane: each edge's tangent and reference director carried
/// by parallel transport in time, then each interior vertex's reference twist, continued from its last
/// value (see `Rod::refresh_frames`).
#[inline(always)]
pub(crate) fn carry_reference_frames<T: Real>(
    positions: &(impl Points<T> + ?Sized),
    tangents: &mut (impl Points<T> + ?Sized),
    directors: &mut (impl Points<T> + ?Sized),
    reference_twist: &mut [T],
    edge_count: usize,
) {
    let one = T::splat(1.0);
    for edge in 0..edge_count {
        let e = positions.point(edge + 1) - positions.point(edge);
        let tangent = e.scale(one / e.length());
        let carried = transport(directors.point(edge), tangents.point(edge), tangent);
        // `perpendicular_unit(carried, tangent).unwrap_or(carried)`.
        let perpendicular = carried - tangent.scale(carried.dot(tangent));
        let length = perpendicular.length();
        let usable = length.lt(T::splat(f64::INFINITY)) & length.gt(T::splat(1e-9) * carried.length());
        directors.set_point(edge, Vector::select(usable, perpendicular.divide(length), carried));
        tangents.set_point(edge, tangent);
    }
    let (pi, two_pi) = (T::splat(std::f64::consts::PI), T::splat(2.0 * std::f64::consts::PI));
    for (vertex, twist) in reference_twist.iter_mut().enumerate().take(edge_count).skip(1) {
        let tangent = tangents.point(vertex);
        let carried = transport(directors.point(vertex - 1), tangents.point(vertex - 1), tangent);
        let director = directors.point(vertex);
        let angle = carried.cross(director).dot(tangent).atan2(carried.dot(director));
        let turn = angle - *twist;
        *twist += turn - two_pi * ((turn + pi) / two_pi).floor();
    }
}

/// [`parallel_transport`] in every lane (its rare case of opposite tangents lane by lane).
#[inline(always)]
fn transport<T: Real>(v: Vector<T>, from: Vector<T>, to: Vector<T>) -> Vector<T> {
    let axis = from.cross(to);
    let cosine = from.dot(to);
    let one = T::splat(1.0);
    let mut carried = v.scale(cosine) + axis.cross(v) + axis.scale(axis.dot(v) / (one + cosine));
    let opposite: LaneMask = (one + cosine).lt(T::splat(1e-12));
    if opposite != 0 {
        for lane in lanes_in(opposite) {
            carried.set_lane(lane, parallel_transport(v.lane(lane), from.lane(lane), to.lane(lane)));
        }
    }
    carried
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    #[test]
    fn transport_maps_tangent_to_tangent_and_preserves_angles() {
        let from = DVec3::new(1.0, 2.0, 3.0).normalize();
        let to = DVec3::new(-2.0, 0.5, 1.0).normalize();
        assert!((parallel_transport(from, from, to) - to).length() < 1e-14);
        let u = from.any_orthonormal_vector();
        let w = from.cross(u);
        let (pu, pw) = (parallel_transport(u, from, to), parallel_transport(w, from, to));
        assert!(pu.dot(to).abs() < 1e-14 && pw.dot(to).abs() < 1e-14);
        assert!((pu.length() - 1.0).abs() < 1e-14 && pu.dot(pw).abs() < 1e-14);
        assert!((pu.cross(pw) - to).length() < 1e-14, "orientation is kept");
        // The rotation is about from × to: vectors along that axis are unchanged.
        let axis = from.cross(to).normalize();
        assert!((parallel_transport(axis, from, to) - axis).length() < 1e-14);
    }

    #[test]
    fn transport_of_opposite_tangents_is_a_rotation() {
        let from = DVec3::X;
        let v = DVec3::new(0.3, 0.4, -0.5);
        let moved = parallel_transport(v, from, -from);
        assert!((moved.length() - v.length()).abs() < 1e-14);
        assert!((moved.dot(-from) - v.dot(from)).abs() < 1e-14);
    }

    #[test]
    fn regular_polygon_has_twice_tan_half_turning_angle() {
        for sides in [3usize, 5, 12, 100] {
            let turning = 2.0 * PI / sides as f64;
            let t0 = DVec3::X;
            let t1 = DVec3::new(turning.cos(), turning.sin(), 0.0);
            let kb = curvature_binormal(t0, t1);
            assert!((kb.length() - 2.0 * (PI / sides as f64).tan()).abs() < 1e-12);
            assert!((kb.normalize() - DVec3::Z).length() < 1e-12);
        }
    }

    #[test]
    fn signed_angle_and_wrap() {
        assert!((signed_angle(DVec3::X, DVec3::Y, DVec3::Z) - PI / 2.0).abs() < 1e-15);
        assert!((signed_angle(DVec3::Y, DVec3::X, DVec3::Z) + PI / 2.0).abs() < 1e-15);
        assert!((wrap_angle(3.0 * PI / 2.0) + PI / 2.0).abs() < 1e-14);
        assert!((wrap_angle(-0.25) + 0.25).abs() < 1e-15);
    }

    #[test]
    fn material_directors_rotate_by_twist() {
        let (m1, m2) = material_directors(DVec3::X, DVec3::Z, PI / 2.0);
        assert!((m1 - DVec3::Y).length() < 1e-15 && (m2 + DVec3::X).length() < 1e-15);
    }
}
