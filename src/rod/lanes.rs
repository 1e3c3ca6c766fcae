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
}

/// One `f64` per strand of a lockstep batch.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
#[repr(transparent)]
pub struct Lanes(pub [f64; LANES]);

impl Lanes {
    /// The lanes from a function of the lane's index.
    #[inline(always)]
    pub fn from_fn(value: impl FnMut(usize) -> f64) -> Self {
        Self(std::array::from_fn(value))
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
        self.0.iter().enumerate().fold(0, |mask, (lane, &value)| mask | (value.not_positive_finite() << lane))
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn operations_act_lane_by_lane() {
        let a = Lanes::from_fn(|lane| lane as f64 + 1.0);
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
