//! Numbers for stepping several strands in lockstep: [`Lanes`] holds one `f64` per strand of a batch,
//! and every operation acts on all of them at once, lane by lane. Written as plain loops over a
//! fixed-size array, they become single SIMD instructions wherever the code is compiled for a SIMD
//! instruction set (see [`super::lockstep`]), and stay correct everywhere else.
//!
//! [`Real`] is what the banded factorisation asks of its numbers, so that one `L D Lᵀ` serves one
//! strand (`f64`) and a batch ([`Lanes`]), with the same operations in the same order: a lane's result
//! is bit for bit what the strand alone would get.

use std::ops::{Add, AddAssign, Div, Mul, MulAssign, Neg, Sub, SubAssign};

/// Strands stepped in lockstep: one `f64` lane each, four to an AVX2 register.
pub const LANES: usize = 4;

/// A bit per lane, bit `k` for lane `k`.
pub(crate) type LaneMask = u32;

/// The lanes whose bit is set in `mask`, in order.
pub(crate) fn lanes_in(mask: LaneMask) -> impl Iterator<Item = usize> {
    (0..LANES).filter(move |lane| mask & (1 << lane) != 0)
}

/// The numbers the banded factorisation works on: `f64`, or [`Lanes`] of them.
pub(crate) trait Real:
    Copy
    + Default
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + AddAssign
    + SubAssign
    + MulAssign
{
    /// How many independent values one holds.
    const LANES: usize;
    /// The same value in every lane.
    fn splat(value: f64) -> Self;
    /// The lanes (bit `k` for lane `k`) whose value is not a finite positive number.
    fn not_positive_finite(self) -> LaneMask;
    /// The larger of the two, lane by lane, as [`f64::max`] takes it.
    fn max(self, other: Self) -> Self;
    /// The square root, lane by lane.
    fn sqrt(self) -> Self;
    /// The absolute value, lane by lane.
    fn abs(self) -> Self;
    /// The lanes where `self < other`.
    fn lt(self, other: Self) -> LaneMask;
    /// The lanes where `self <= other`.
    fn le(self, other: Self) -> LaneMask;
    /// The lanes where `self > other`.
    fn gt(self, other: Self) -> LaneMask;
    /// The lanes where `self == other`.
    fn eq(self, other: Self) -> LaneMask;
    /// `if_set` in the lanes of `mask`, `otherwise` in the others.
    fn select(mask: LaneMask, if_set: Self, otherwise: Self) -> Self;
    /// `atan2(self, x)`, lane by lane (std's).
    fn atan2(self, x: Self) -> Self;
    /// `(sin, cos)` of `self`, lane by lane (std's).
    fn sin_cos(self) -> (Self, Self);
    /// The largest integer not above, lane by lane.
    fn floor(self) -> Self;
    /// The value of lane `lane`.
    fn lane(self, lane: usize) -> f64;
    /// Lane `lane`, to write.
    fn lane_mut(&mut self, lane: usize) -> &mut f64;
}

impl Real for f64 {
    const LANES: usize = 1;

    #[inline(always)]
    fn splat(value: f64) -> Self {
        value
    }

    #[inline(always)]
    fn not_positive_finite(self) -> LaneMask {
        LaneMask::from(!(self > 0.0 && self.is_finite()))
    }

    #[inline(always)]
    fn max(self, other: Self) -> Self {
        f64::max(self, other)
    }

    #[inline(always)]
    fn sqrt(self) -> Self {
        f64::sqrt(self)
    }

    #[inline(always)]
    fn abs(self) -> Self {
        f64::abs(self)
    }

    #[inline(always)]
    fn lt(self, other: Self) -> LaneMask {
        LaneMask::from(self < other)
    }

    #[inline(always)]
    fn le(self, other: Self) -> LaneMask {
        LaneMask::from(self <= other)
    }

    #[inline(always)]
    fn gt(self, other: Self) -> LaneMask {
        LaneMask::from(self > other)
    }

    #[inline(always)]
    fn eq(self, other: Self) -> LaneMask {
        LaneMask::from(self == other)
    }

    #[inline(always)]
    fn select(mask: LaneMask, if_set: Self, otherwise: Self) -> Self {
        if mask & 1 != 0 { if_set } else { otherwise }
    }

    #[inline(always)]
    fn atan2(self, x: Self) -> Self {
        f64::atan2(self, x)
    }

    #[inline(always)]
    fn sin_cos(self) -> (Self, Self) {
        f64::sin_cos(self)
    }

    #[inline(always)]
    fn floor(self) -> Self {
        f64::floor(self)
    }

    #[inline(always)]
    fn lane(self, _lane: usize) -> f64 {
        self
    }

    #[inline(always)]
    fn lane_mut(&mut self, _lane: usize) -> &mut f64 {
        self
    }
}

/// One `f64` per strand of a lockstep batch.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
#[repr(transparent)]
pub struct Lanes(pub [f64; LANES]);

impl Lanes {
    /// The lanes where `test(self, other)` holds.
    #[inline(always)]
    fn compare(self, other: Self, test: impl Fn(f64, f64) -> bool) -> LaneMask {
        (0..LANES).fold(0, |mask, lane| mask | (LaneMask::from(test(self.0[lane], other.0[lane])) << lane))
    }

    /// Lane by lane `f(self, other)`.
    #[inline(always)]
    fn zip(self, other: Self, f: impl Fn(f64, f64) -> f64) -> Self {
        Self(std::array::from_fn(|lane| f(self.0[lane], other.0[lane])))
    }
}

impl Real for Lanes {
    const LANES: usize = LANES;

    #[inline(always)]
    fn splat(value: f64) -> Self {
        Self([value; LANES])
    }

    #[inline(always)]
    fn not_positive_finite(self) -> LaneMask {
        // `0 < x < ∞` is `x > 0 && x.is_finite()` (NaN fails both), in two comparisons of all lanes.
        !(self.gt(Self::splat(0.0)) & self.lt(Self::splat(f64::INFINITY))) & ((1 << LANES) - 1)
    }

    #[inline(always)]
    fn max(self, other: Self) -> Self {
        self.zip(other, f64::max)
    }

    #[inline(always)]
    fn sqrt(self) -> Self {
        Self(self.0.map(f64::sqrt))
    }

    #[inline(always)]
    fn abs(self) -> Self {
        Self(self.0.map(f64::abs))
    }

    #[inline(always)]
    fn lt(self, other: Self) -> LaneMask {
        self.compare(other, |a, b| a < b)
    }

    #[inline(always)]
    fn le(self, other: Self) -> LaneMask {
        self.compare(other, |a, b| a <= b)
    }

    #[inline(always)]
    fn gt(self, other: Self) -> LaneMask {
        self.compare(other, |a, b| a > b)
    }

    #[inline(always)]
    fn eq(self, other: Self) -> LaneMask {
        self.compare(other, |a, b| a == b)
    }

    #[inline(always)]
    fn select(mask: LaneMask, if_set: Self, otherwise: Self) -> Self {
        Self(std::array::from_fn(|lane| if mask & (1 << lane) != 0 { if_set.0[lane] } else { otherwise.0[lane] }))
    }

    #[inline(always)]
    fn atan2(self, x: Self) -> Self {
        self.zip(x, f64::atan2)
    }

    #[inline(always)]
    fn sin_cos(self) -> (Self, Self) {
        let both = self.0.map(f64::sin_cos);
        (Self(both.map(|(sin, _)| sin)), Self(both.map(|(_, cos)| cos)))
    }

    #[inline(always)]
    fn floor(self) -> Self {
        Self(self.0.map(f64::floor))
    }

    #[inline(always)]
    fn lane(self, lane: usize) -> f64 {
        self.0[lane]
    }

    #[inline(always)]
    fn lane_mut(&mut self, lane: usize) -> &mut f64 {
        &mut self.0[lane]
    }
}

macro_rules! lane_operator {
    ($trait:ident, $method:ident, $assign_trait:ident, $assign_method:ident, $op:tt) => {
        impl $trait for Lanes {
            type Output = Self;
            #[inline(always)]
            fn $method(self, other: Self) -> Self {
                self.zip(other, |a, b| a $op b)
            }
        }
        impl $assign_trait for Lanes {
            #[inline(always)]
            fn $assign_method(&mut self, other: Self) {
                *self = *self $op other;
            }
        }
    };
}

lane_operator!(Add, add, AddAssign, add_assign, +);
lane_operator!(Sub, sub, SubAssign, sub_assign, -);
lane_operator!(Mul, mul, MulAssign, mul_assign, *);

impl Div for Lanes {
    type Output = Self;
    #[inline(always)]
    fn div(self, other: Self) -> Self {
        self.zip(other, |a, b| a / b)
    }
}

impl Neg for Lanes {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        Self(self.0.map(|value| -value))
    }
}

/// The 3 × 3 matrix with entries `entry(row, column)`, written out so that the compiler inlines
/// `entry` (`std::array::from_fn` leaves its closure out of line, one call per entry).
#[inline(always)]
pub(crate) fn matrix3<T>(entry: impl Fn(usize, usize) -> T) -> [[T; 3]; 3] {
    [
        [entry(0, 0), entry(0, 1), entry(0, 2)],
        [entry(1, 0), entry(1, 1), entry(1, 2)],
        [entry(2, 0), entry(2, 1), entry(2, 2)],
    ]
}

/// A 3-vector of [`Real`]s: a `DVec3` of one strand (`Vector<f64>`), or the same vector of every strand
/// of a batch (`Vector<Lanes>`). Its operations are glam's `DVec3` operations term by term, in the same
/// order, so a strand's result is bit for bit what glam would give.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct Vector<T> {
    pub x: T,
    pub y: T,
    pub z: T,
}

impl<T: Real> Vector<T> {
    /// `a · b`, summed as glam sums it: `(x x' + y y') + z z'`.
    #[inline(always)]
    pub fn dot(self, other: Self) -> T {
        self.x * other.x + self.y * other.y + self.z * other.z
    }

    /// `a × b`, with glam's terms.
    #[inline(always)]
    pub fn cross(self, other: Self) -> Self {
        Self {
            x: self.y * other.z - other.y * self.z,
            y: self.z * other.x - other.z * self.x,
            z: self.x * other.y - other.x * self.y,
        }
    }

    /// `s a`.
    #[inline(always)]
    pub fn scale(self, factor: T) -> Self {
        Self { x: factor * self.x, y: factor * self.y, z: factor * self.z }
    }

    /// `a / s`, component by component.
    #[inline(always)]
    pub fn divide(self, divisor: T) -> Self {
        Self { x: self.x / divisor, y: self.y / divisor, z: self.z / divisor }
    }

    /// `|a|`, as glam takes it: `√(a · a)`.
    #[inline(always)]
    pub fn length(self) -> T {
        self.dot(self).sqrt()
    }

    /// The components in order.
    #[inline(always)]
    pub fn to_array(self) -> [T; 3] {
        [self.x, self.y, self.z]
    }

    /// Lane `lane` as a `DVec3`.
    #[inline(always)]
    pub fn lane(self, lane: usize) -> bevy::math::DVec3 {
        bevy::math::DVec3::new(self.x.lane(lane), self.y.lane(lane), self.z.lane(lane))
    }

    /// Sets lane `lane` to `value`.
    #[inline(always)]
    pub fn set_lane(&mut self, lane: usize, value: bevy::math::DVec3) {
        (*self.x.lane_mut(lane), *self.y.lane_mut(lane), *self.z.lane_mut(lane)) = (value.x, value.y, value.z);
    }

    /// `if_set` in the lanes of `mask`, `otherwise` in the others.
    #[inline(always)]
    pub fn select(mask: LaneMask, if_set: Self, otherwise: Self) -> Self {
        Self {
            x: T::select(mask, if_set.x, otherwise.x),
            y: T::select(mask, if_set.y, otherwise.y),
            z: T::select(mask, if_set.z, otherwise.z),
        }
    }
}

/// A list of points, one strand's (`[DVec3]`, read as `Vector<f64>`) or a batch's (`[Vector<Lanes>]`).
pub(crate) trait Points<T> {
    /// Point `index`.
    fn point(&self, index: usize) -> Vector<T>;
    /// Sets point `index`.
    fn set_point(&mut self, index: usize, value: Vector<T>);
}

impl Points<f64> for [bevy::math::DVec3] {
    #[inline(always)]
    fn point(&self, index: usize) -> Vector<f64> {
        self[index].into()
    }

    #[inline(always)]
    fn set_point(&mut self, index: usize, value: Vector<f64>) {
        self[index] = bevy::math::DVec3::new(value.x, value.y, value.z);
    }
}

impl<T: Copy> Points<T> for [Vector<T>] {
    #[inline(always)]
    fn point(&self, index: usize) -> Vector<T> {
        self[index]
    }

    #[inline(always)]
    fn set_point(&mut self, index: usize, value: Vector<T>) {
        self[index] = value;
    }
}

impl From<bevy::math::DVec3> for Vector<f64> {
    #[inline(always)]
    fn from(v: bevy::math::DVec3) -> Self {
        Self { x: v.x, y: v.y, z: v.z }
    }
}

impl<T: Real> Add for Vector<T> {
    type Output = Self;
    #[inline(always)]
    fn add(self, other: Self) -> Self {
        Self { x: self.x + other.x, y: self.y + other.y, z: self.z + other.z }
    }
}

impl<T: Real> Sub for Vector<T> {
    type Output = Self;
    #[inline(always)]
    fn sub(self, other: Self) -> Self {
        Self { x: self.x - other.x, y: self.y - other.y, z: self.z - other.z }
    }
}

impl<T: Real> Neg for Vector<T> {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        Self { x: -self.x, y: -self.y, z: -self.z }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn operations_act_lane_by_lane() {
        let a = Lanes([1.0, 2.0, 3.0, 4.0]);
        let b = Lanes::splat(2.0);
        assert_eq!((a + b).0[3], 6.0);
        assert_eq!((a - b).0[0], -1.0);
        assert_eq!((a * b).0[2], 6.0);
        assert_eq!((a / b).0[1], 1.0);
        assert_eq!((-a).0[3], -4.0);
        let pivots = Lanes([1.0, 0.0, f64::NAN, -2.0]);
        assert_eq!(pivots.not_positive_finite(), 0b1110);
        assert_eq!(f64::INFINITY.not_positive_finite(), 1);
        assert_eq!(3.0.not_positive_finite(), 0);
    }
}
