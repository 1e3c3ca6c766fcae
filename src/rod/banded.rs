//! A symmetric positive-definite banded matrix with an in-place `L D Lᵀ` (Cholesky) factorisation.
//!
//! A strand's implicit system couples each unknown only to its neighbours within a fixed half-bandwidth
//! (10 for the `x₀, θ⁰, x₁, θ¹, …` ordering), so a banded `L D Lᵀ` factorisation solves it in
//! `O(n · bandwidth²)` with no allocation once the storage has its size.
//!
//! The half-bandwidth is a compile-time constant and the storage has `HALF_BANDWIDTH` extra identity
//! rows after the last, so every loop over a band has a fixed length with no clamping at the ends: the
//! compiler unrolls and vectorises them (a strand's matrix is small, ~130 rows, where loop overhead
//! would otherwise cost more than the arithmetic).
//!
//! The entries are `f64` for one strand, or [`Lanes`] for a batch of strands stepped in lockstep
//! ([`super::lockstep`]): one entry holds the same entry of every strand's matrix, and the
//! factorisation and solves run on all of them at once with the same operations in the same order.

use multiversion::multiversion;

use super::energy::BANDWIDTH;
use super::lanes::{LaneMask, Lanes, Real};

/// Lower band of a symmetric matrix, stored row by row: row `i` holds columns `i − HALF_BANDWIDTH ..= i`
/// (entries left of column 0 are zero).
#[derive(Debug, Clone, Default)]
pub struct BandedMatrix<const HALF_BANDWIDTH: usize, T = f64> {
    size: usize,
    /// `(size + HALF_BANDWIDTH) × (HALF_BANDWIDTH + 1)` entries: the rows, then the identity padding.
    values: Vec<T>,
    /// `1 / D(i)` after [`BandedMatrix::factorize`].
    inverse_diagonal: Vec<T>,
    /// Scratch for products and solves: a vector with `HALF_BANDWIDTH` zeros on each side.
    padded: Vec<T>,
    /// Scratch: the result of a product, padded like `padded`.
    product: Vec<T>,
}

/// The factorisation met a non-positive pivot: the matrix is not positive definite.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct NotPositiveDefinite {
    /// Row at which the pivot was not positive.
    pub row: usize,
}

#[allow(private_bounds)]
impl<const HALF_BANDWIDTH: usize, T: Real> BandedMatrix<HALF_BANDWIDTH, T> {
    /// Entries stored per row.
    const WIDTH: usize = HALF_BANDWIDTH + 1;

    /// Resizes to `size × size` and sets every entry to zero. Allocates only when the storage grows.
    pub fn reset(&mut self, size: usize) {
        let (width, band) = (Self::WIDTH, HALF_BANDWIDTH);
        self.size = size;
        self.values.clear();
        self.values.resize((size + band) * width, T::default());
        for row in size..size + band {
            self.values[row * width + band] = T::splat(1.0);
        }
        // The scratch vectors get their size here, so that products and solves never allocate.
        self.padded.resize(size + 2 * band, T::default());
        self.product.resize(size + 2 * band, T::default());
        self.inverse_diagonal.resize(size, T::default());
    }

    /// Number of rows.
    pub fn size(&self) -> usize {
        self.size
    }

    #[inline]
    fn index(&self, row: usize, column: usize) -> usize {
        debug_assert!(column <= row && row - column <= HALF_BANDWIDTH && row < self.size);
        row * Self::WIDTH + HALF_BANDWIDTH + column - row
    }

    /// The stored bands of `rows`, one after another, `HALF_BANDWIDTH + 1` entries each: entry
    /// `HALF_BANDWIDTH − (row − column)` of a row's band is `(row, column)`, for the columns
    /// `row − HALF_BANDWIDTH ..= row` (those left of column 0 must stay zero).
    #[inline]
    pub fn band_rows_mut(&mut self, rows: std::ops::Range<usize>) -> &mut [T] {
        assert!(rows.end <= self.size, "rows {rows:?} of a {} × {} matrix", self.size, self.size);
        &mut self.values[rows.start * Self::WIDTH..rows.end * Self::WIDTH]
    }

    /// `out = A x` for the symmetric matrix.
    #[inline(always)]
    pub fn multiply(&mut self, x: &[T], out: &mut [T]) {
        self.multiply_columns(0..self.size, x, out);
    }

    /// `out = A x` where only `x[columns]` may be non-zero: costs `O(columns · bandwidth)`, so a few
    /// prescribed unknowns do not pay for the whole matrix.
    #[inline(always)]
    pub fn multiply_columns(&mut self, columns: std::ops::Range<usize>, x: &[T], out: &mut [T]) {
        let Self { values, padded, product, size, .. } = self;
        band_product::<HALF_BANDWIDTH, T>(|index| values[index], *size, columns, x, padded, product, out);
    }

    /// Adds `value` to the symmetric entry `(row, column)` of every lane; either order of indices is
    /// accepted.
    #[inline(always)]
    pub(crate) fn add_entry(&mut self, row: usize, column: usize, value: T) {
        let (row, column) = if row >= column { (row, column) } else { (column, row) };
        let index = self.index(row, column);
        self.values[index] += value;
    }

    /// [`BandedMatrix::add`] in lane `lane` of the entries (0 for `f64`).
    #[inline]
    pub(crate) fn add_in_lane(&mut self, lane: usize, row: usize, column: usize, value: f64) {
        let (row, column) = if row >= column { (row, column) } else { (column, row) };
        let index = self.index(row, column);
        *self.values[index].lane_mut(lane) += value;
    }

    /// [`BandedMatrix::scale_diagonal`] in lane `lane` of the entries (0 for `f64`).
    pub(crate) fn scale_diagonal_in_lane(&mut self, lane: usize, factor: f64) {
        for row in 0..self.size {
            let index = self.index(row, row);
            *self.values[index].lane_mut(lane) *= factor;
        }
    }

    /// [`BandedMatrix::set_identity_row`] in lane `lane` of the entries (0 for `f64`).
    pub(crate) fn set_identity_row_in_lane(&mut self, lane: usize, dof: usize) {
        // Row `dof`'s band is one run ending at the diagonal; column `dof` below it steps by `band`
        // (entry `(dof + s, dof)` sits `s · band` after the diagonal).
        let band = HALF_BANDWIDTH;
        let diagonal = self.index(dof, dof);
        for entry in &mut self.values[diagonal - dof.min(band)..diagonal] {
            *entry.lane_mut(lane) = 0.0;
        }
        *self.values[diagonal].lane_mut(lane) = 1.0;
        for below in 1..=(dof + band).min(self.size - 1) - dof {
            *self.values[diagonal + below * band].lane_mut(lane) = 0.0;
        }
    }

    /// [`BandedMatrix::set_identity_row`] in every lane of the entries.
    pub(crate) fn set_identity_row_in_every_lane(&mut self, dof: usize) {
        let band = HALF_BANDWIDTH;
        let diagonal = self.index(dof, dof);
        self.values[diagonal - dof.min(band)..diagonal].fill(T::default());
        self.values[diagonal] = T::splat(1.0);
        for below in 1..=(dof + band).min(self.size - 1) - dof {
            self.values[diagonal + below * band] = T::default();
        }
    }

    /// Factorises in place into `L D Lᵀ` (Cholesky without square roots, `L` with a unit diagonal); the
    /// band then holds `L` below the diagonal and `D` on it, and the reciprocals of `D` are kept so that
    /// [`BandedMatrix::solve_factorized`] does not divide. Returns the lanes (bit `k` for lane `k`)
    /// that met a pivot that is not positive, with the first such row of each in `failed_rows`; it stops
    /// early only when every lane has failed. A lane's failure never changes another lane's result.
    ///
    /// Right-looking: each finished column updates the rows below it, `A(i, k) −= L(i, j) D(j) L(k, j)`.
    /// These updates are independent of each other (no chain of dependent additions) and run along
    /// contiguous row segments of fixed length; the only chain from one column to the next is one
    /// division, one multiplication and one update.
    #[inline(always)]
    pub(crate) fn factorize_lanes(&mut self, failed_rows: &mut [usize]) -> LaneMask {
        let (width, band) = (Self::WIDTH, HALF_BANDWIDTH);
        let all: LaneMask = (1 << T::LANES) - 1;
        let mut failed: LaneMask = 0;
        let Self { values, inverse_diagonal, .. } = self;
        // One entry per row (sized in `reset`).
        for (j, inverse) in inverse_diagonal.iter_mut().enumerate() {
            // Rows `j ..= j + band`, padding included: one bounds check for the whole column.
            let rows = &mut values[j * width..(j + 1 + band) * width];
            let pivot = rows[band];
            let new_failures = pivot.not_positive_finite() & !failed;
            if new_failures != 0 {
                for (lane, row) in failed_rows.iter_mut().enumerate() {
                    if new_failures & (1 << lane) != 0 {
                        *row = j;
                    }
                }
                failed |= new_failures;
                if failed == all {
                    return failed;
                }
            }
            *inverse = T::splat(1.0) / pivot;
            // `D(j) L(j + 1 + t, j)` is the entry at position `band − 1 − t` of row `j + 1 + t` (zero in the
            // padding); it becomes `L(j + 1 + t, j)`.
            let mut scaled = [T::default(); HALF_BANDWIDTH];
            let mut column = [T::default(); HALF_BANDWIDTH];
            for (t, (scaled, entry)) in scaled.iter_mut().zip(&mut column).enumerate() {
                let index = (1 + t) * width + band - 1 - t;
                *scaled = rows[index];
                *entry = *scaled * *inverse;
                rows[index] = *entry;
            }
            for (t, &factor) in column.iter().enumerate() {
                // A(j + 1 + t, j + 1 ..= j + 1 + t): positions `band − t ..= band` of row `j + 1 + t`.
                // A loop of fixed length with a test that is known once it is unrolled, so that the
                // compiler unrolls it whole for wide entries too.
                let start = (1 + t) * width + band - t;
                for (k, &other) in scaled.iter().enumerate() {
                    if k <= t {
                        rows[start + k] -= factor * other;
                    }
                }
            }
        }
        failed
    }

    /// Solves `L D Lᵀ x = b` in place (`rhs` becomes `x`), after [`BandedMatrix::factorize`].
    #[inline(always)]
    pub fn solve_factorized(&mut self, rhs: &mut [T]) {
        let (width, band, size) = (Self::WIDTH, HALF_BANDWIDTH, self.size);
        let Self { values, inverse_diagonal, padded, .. } = self;
        padded.fill(T::default());
        padded[band..band + size].copy_from_slice(&rhs[..size]);
        // `L y = b`, column by column: each solved entry is removed from the rows below it.
        for j in 0..size {
            let solved = padded[band + j];
            let below = &mut padded[band + j + 1..band + j + 1 + band];
            for (t, value) in below.iter_mut().enumerate() {
                *value -= values[(j + 1 + t) * width + band - 1 - t] * solved;
            }
        }
        // `Lᵀ x = D⁻¹ y`, from the last row up: each solved entry is removed from the rows above it,
        // along its own row of `L`.
        for (value, &inverse) in padded[band..band + size].iter_mut().zip(inverse_diagonal.iter()) {
            *value *= inverse;
        }
        for j in (0..size).rev() {
            let solved = padded[band + j];
            let row = &values[j * width..j * width + band];
            for (value, &entry) in padded[j..j + band].iter_mut().zip(row) {
                *value -= entry * solved;
            }
        }
        rhs[..size].copy_from_slice(&padded[band..band + size]);
    }
}

/// [`BandedMatrix::factorize_lanes`] compiled for the best instruction set the CPU has, chosen when the
/// program runs. The operations and their order are the same on every one (Rust never fuses a
/// multiplication and an addition of its own accord), so the result is the same bit for bit; wider
/// registers only do more of them at once.
#[multiversion(targets("x86_64+avx2+fma", "x86_64+avx"))]
pub(crate) fn factorize_best<T: Real>(matrix: &mut BandedMatrix<BANDWIDTH, T>, failed_rows: &mut [usize]) -> LaneMask {
    matrix.factorize_lanes(failed_rows)
}

/// [`BandedMatrix::solve_factorized`] compiled for the best instruction set the CPU has, like
/// [`factorize_best`].
#[multiversion(targets("x86_64+avx2+fma", "x86_64+avx"))]
pub(crate) fn solve_best<T: Real>(matrix: &mut BandedMatrix<BANDWIDTH, T>, rhs: &mut [T]) {
    matrix.solve_factorized(rhs);
}

impl<const HALF_BANDWIDTH: usize> BandedMatrix<HALF_BANDWIDTH> {
    /// Entry `(row, column)` of the lower band (`column ≤ row`).
    #[inline]
    pub fn get(&self, row: usize, column: usize) -> f64 {
        self.values[self.index(row, column)]
    }

    /// Adds `value` to the symmetric entry `(row, column)`; either order of indices is accepted.
    #[inline]
    pub fn add(&mut self, row: usize, column: usize, value: f64) {
        self.add_in_lane(0, row, column, value);
    }

    /// Multiplies every diagonal entry by `factor` (a Levenberg–Marquardt shift `λ diag(A)` with
    /// `factor = 1 + λ`).
    pub fn scale_diagonal(&mut self, factor: f64) {
        self.scale_diagonal_in_lane(0, factor);
    }

    /// Replaces row and column `dof` by those of the identity, decoupling that unknown.
    pub fn set_identity_row(&mut self, dof: usize) {
        self.set_identity_row_in_every_lane(dof);
    }

    /// Factorises in place into `L D Lᵀ` (Cholesky without square roots, `L` with a unit diagonal; the
    /// band then holds `L` below the diagonal and `D` on it), or says at which row the matrix showed it
    /// is not positive definite.
    pub fn factorize(&mut self) -> Result<(), NotPositiveDefinite> {
        let mut row = [0];
        match self.factorize_lanes(&mut row) {
            0 => Ok(()),
            _ => Err(NotPositiveDefinite { row: row[0] }),
        }
    }
}

/// `out = A x` for the symmetric band whose stored entry `index` (row by row, as in [`BandedMatrix`])
/// is `entry(index)`, where only `x[columns]` may be non-zero; `padded` and `product` are scratch of
/// `size + 2 HALF_BANDWIDTH` entries. One strand's matrix and its lane of a batch's matrix share it, so
/// both give the same bits.
#[inline(always)]
fn band_product<const HALF_BANDWIDTH: usize, T: Real>(
    entry: impl Fn(usize) -> T,
    size: usize,
    columns: std::ops::Range<usize>,
    x: &[T],
    padded: &mut [T],
    product: &mut [T],
    out: &mut [T],
) {
    let (width, band) = (HALF_BANDWIDTH + 1, HALF_BANDWIDTH);
    let columns = columns.start..columns.end.min(size);
    // Vectors shifted by `band`: index `band + i` is entry `i`, with zeros around. Only the window the
    // columns reach is cleared and read: padded indices `columns.start ..< columns.end + 2 band`.
    let window = columns.start..(columns.end + 2 * band).min(size + 2 * band);
    padded[window.clone()].fill(T::default());
    padded[band + columns.start..band + columns.end].copy_from_slice(&x[columns.clone()]);
    product[window].fill(T::default());
    // Row `r`'s band covers the columns `r − band ..= r`, that is padded indices `r ..= r + band`.
    // The rows that meet the columns: `columns.start ..< columns.end + band`.
    for row in columns.start..(columns.end + band).min(size) {
        let near = &padded[row..row + width];
        let x_row = near[band];
        let mut sum = T::default();
        for (k, (&x, out)) in near.iter().zip(&mut product[row..row + width]).enumerate() {
            let entry = entry(row * width + k);
            sum += entry * x;
            // The transposed entry `(column, row)`, above the diagonal.
            *out += entry * x_row;
        }
        // The diagonal was counted twice.
        product[row + band] += sum - entry(row * width + band) * x_row;
    }
    // The rows the product can reach: `columns.start − band ..< columns.end + band`; zero elsewhere.
    let reached = columns.start.saturating_sub(band)..(columns.end + band).min(size);
    out[..size].fill(T::default());
    out[reached.clone()].copy_from_slice(&product[reached.start + band..reached.end + band]);
}

/// A strand's Newton matrix as the terms after the elastic ones write it ([`super::solver`]): the
/// strand's own [`BandedMatrix`], or its lane of a lockstep batch's ([`MatrixLane`]).
pub(crate) trait StrandMatrix {
    /// Adds `value` to the symmetric entry `(row, column)`; either order of indices is accepted.
    fn add(&mut self, row: usize, column: usize, value: f64);
    /// Multiplies every diagonal entry by `factor`.
    fn scale_diagonal(&mut self, factor: f64);
    /// Replaces row and column `dof` by those of the identity.
    fn set_identity_row(&mut self, dof: usize);
    /// `out = A x` where only `x[columns]` may be non-zero.
    fn multiply_columns(&mut self, columns: std::ops::Range<usize>, x: &[f64], out: &mut [f64]);
    /// `out = A x` with the matrix as the elastic terms left it, before any other term was added.
    fn multiply_elastic(&mut self, x: &[f64], out: &mut [f64]);
}

impl<const HALF_BANDWIDTH: usize> StrandMatrix for BandedMatrix<HALF_BANDWIDTH> {
    #[inline]
    fn add(&mut self, row: usize, column: usize, value: f64) {
        BandedMatrix::add(self, row, column, value);
    }

    fn scale_diagonal(&mut self, factor: f64) {
        BandedMatrix::scale_diagonal(self, factor);
    }

    fn set_identity_row(&mut self, dof: usize) {
        BandedMatrix::set_identity_row(self, dof);
    }

    fn multiply_columns(&mut self, columns: std::ops::Range<usize>, x: &[f64], out: &mut [f64]) {
        BandedMatrix::multiply_columns(self, columns, x, out);
    }

    /// Called right after the elastic terms: the product with the whole matrix.
    fn multiply_elastic(&mut self, x: &[f64], out: &mut [f64]) {
        BandedMatrix::multiply_columns(self, 0..self.size, x, out);
    }
}

/// One lane of a lockstep batch's matrix, written as its strand's own matrix would be (the same
/// operations on the same values, so the same bits), with scratch for products.
pub(crate) struct MatrixLane<'a, const HALF_BANDWIDTH: usize> {
    pub matrix: &'a mut BandedMatrix<HALF_BANDWIDTH, Lanes>,
    pub lane: usize,
    /// Two vectors for [`StrandMatrix::multiply_columns`] (sized there).
    pub scratch: &'a mut [Vec<f64>; 2],
    /// The product of the elastic terms' matrix with each lane's `x` of
    /// [`StrandMatrix::multiply_elastic`], computed in lanes before the lane's other terms.
    pub elastic_product: &'a [Lanes],
}

impl<const HALF_BANDWIDTH: usize> StrandMatrix for MatrixLane<'_, HALF_BANDWIDTH> {
    #[inline]
    fn add(&mut self, row: usize, column: usize, value: f64) {
        self.matrix.add_in_lane(self.lane, row, column, value);
    }

    fn scale_diagonal(&mut self, factor: f64) {
        self.matrix.scale_diagonal_in_lane(self.lane, factor);
    }

    fn set_identity_row(&mut self, dof: usize) {
        self.matrix.set_identity_row_in_lane(self.lane, dof);
    }

    fn multiply_columns(&mut self, columns: std::ops::Range<usize>, x: &[f64], out: &mut [f64]) {
        let (size, lane) = (self.matrix.size, self.lane);
        let [padded, product] = &mut *self.scratch;
        padded.resize(size + 2 * HALF_BANDWIDTH, 0.0);
        product.resize(size + 2 * HALF_BANDWIDTH, 0.0);
        let values = &self.matrix.values;
        band_product::<HALF_BANDWIDTH, f64>(|index| values[index].0[lane], size, columns, x, padded, product, out);
    }

    fn multiply_elastic(&mut self, _x: &[f64], out: &mut [f64]) {
        for (out, product) in out.iter_mut().zip(self.elastic_product) {
            *out = product.0[self.lane];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rod::test_support::Lcg;

    #[test]
    fn the_factorisation_for_the_best_instruction_set_gives_the_same_bits() {
        let mut random = Lcg(11);
        let size = 131;
        let (mut best, mut baseline) = (BandedMatrix::<BANDWIDTH>::default(), BandedMatrix::<BANDWIDTH>::default());
        best.reset(size);
        for row in 0..size {
            for column in row.saturating_sub(10)..row {
                best.add(row, column, random.next());
            }
            best.add(row, row, 30.0 + random.next());
        }
        baseline.clone_from(&best);
        let rhs: Vec<f64> = (0..size).map(|_| random.next()).collect();
        let (mut x_best, mut x_baseline) = (rhs.clone(), rhs);
        // Dispatched to AVX2 where the CPU has it, against the generic code compiled for the baseline.
        assert_eq!(factorize_best(&mut best, &mut [0]), 0);
        solve_best(&mut best, &mut x_best);
        baseline.factorize().unwrap();
        baseline.solve_factorized(&mut x_baseline);
        for (row, (a, b)) in x_best.iter().zip(&x_baseline).enumerate() {
            assert_eq!(a.to_bits(), b.to_bits(), "row {row}: {a} against {b}");
        }
        for row in 0..size {
            for column in row.saturating_sub(10)..=row {
                assert_eq!(best.get(row, column).to_bits(), baseline.get(row, column).to_bits());
            }
        }
    }

    #[test]
    fn cholesky_solves_a_random_banded_system() {
        const BANDWIDTH: usize = 10;
        let (size, bandwidth) = (37, BANDWIDTH);
        let mut random = Lcg(7);
        let mut banded = BandedMatrix::<BANDWIDTH>::default();
        banded.reset(size);
        for row in 0..size {
            for column in row.saturating_sub(bandwidth)..row {
                banded.add(row, column, random.next());
            }
            banded.add(row, row, 2.0 * bandwidth as f64);
        }
        let entry = |r: usize, c: usize| {
            if r.abs_diff(c) <= bandwidth { banded.get(r.max(c), r.min(c)) } else { 0.0 }
        };
        let dense: Vec<Vec<f64>> = (0..size).map(|r| (0..size).map(|c| entry(r, c)).collect()).collect();
        let expected: Vec<f64> = (0..size).map(|_| random.next()).collect();
        let mut rhs: Vec<f64> = dense.iter().map(|row| row.iter().zip(&expected).map(|(a, x)| a * x).sum()).collect();
        let mut product = vec![0.0; size];
        banded.multiply(&expected, &mut product);
        for (a, b) in product.iter().zip(&rhs) {
            assert!((a - b).abs() < 1e-12, "band product matches the dense product");
        }
        // A vector that is non-zero only on some columns, multiplied over those columns alone.
        let columns = 14..19;
        let sparse: Vec<f64> = (0..size).map(|i| if columns.contains(&i) { expected[i] } else { 0.0 }).collect();
        banded.multiply_columns(columns, &sparse, &mut product);
        for (row, value) in product.iter().enumerate() {
            let dense_value: f64 = (0..size).map(|c| dense[row][c] * sparse[c]).sum();
            assert!((value - dense_value).abs() < 1e-12, "row {row}: {value} against {dense_value}");
        }
        banded.factorize().expect("diagonally dominant");
        banded.solve_factorized(&mut rhs);
        for (x, e) in rhs.iter().zip(&expected) {
            assert!((x - e).abs() < 1e-12);
        }
    }

    #[test]
    fn indefinite_matrix_is_reported() {
        let mut banded = BandedMatrix::<1>::default();
        banded.reset(3);
        banded.add(0, 0, 1.0);
        banded.add(1, 0, 2.0);
        banded.add(1, 1, 1.0);
        banded.add(2, 2, 1.0);
        assert_eq!(banded.factorize(), Err(NotPositiveDefinite { row: 1 }));
    }

    #[test]
    fn identity_rows_decouple_an_unknown() {
        let mut banded = BandedMatrix::<2>::default();
        banded.reset(3);
        for (r, c, v) in [(0, 0, 4.0), (1, 0, 1.0), (1, 1, 4.0), (2, 0, 1.0), (2, 1, 1.0), (2, 2, 4.0)] {
            banded.add(r, c, v);
        }
        banded.set_identity_row(1);
        assert_eq!((banded.get(1, 0), banded.get(2, 1), banded.get(1, 1)), (0.0, 0.0, 1.0));
        assert_eq!(banded.get(2, 0), 1.0);
    }
}
