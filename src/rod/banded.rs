//! A symmetric positive-definite banded matrix with an in-place Cholesky factorisation.
//!
//! A strand's implicit system couples each unknown only to its neighbours within a fixed half-bandwidth
//! (10 for the `x₀, θ⁰, x₁, θ¹, …` ordering), so a banded Cholesky solves it in `O(n · bandwidth²)` with
//! no allocation once the storage has its size.

/// Lower band of a symmetric matrix, stored row by row: row `i` holds columns `i − bandwidth ..= i`.
#[derive(Debug, Clone, Default)]
pub struct BandedMatrix {
    size: usize,
    bandwidth: usize,
    values: Vec<f64>,
    /// `1 / L(i, i)` after [`BandedMatrix::factorize`].
    inverse_diagonal: Vec<f64>,
    /// Scratch: the column of `L` being applied during [`BandedMatrix::factorize`].
    column: Vec<f64>,
}

/// The factorisation met a non-positive pivot: the matrix is not positive definite.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct NotPositiveDefinite {
    /// Row at which the pivot was not positive.
    pub row: usize,
}

impl BandedMatrix {
    /// Resizes to `size × size` with the given half-bandwidth and sets every entry to zero.
    /// Allocates only when the storage grows.
    pub fn reset(&mut self, size: usize, bandwidth: usize) {
        self.size = size;
        self.bandwidth = bandwidth;
        self.values.clear();
        self.values.resize(size * (bandwidth + 1), 0.0);
    }

    /// Number of rows.
    pub fn size(&self) -> usize {
        self.size
    }

    #[inline]
    fn index(&self, row: usize, column: usize) -> usize {
        debug_assert!(column <= row && row - column <= self.bandwidth);
        row * (self.bandwidth + 1) + self.bandwidth + column - row
    }

    /// Entry `(row, column)` of the lower band (`column ≤ row`).
    #[inline]
    pub fn get(&self, row: usize, column: usize) -> f64 {
        self.values[self.index(row, column)]
    }

    /// Adds `value` to the symmetric entry `(row, column)`; either order of indices is accepted.
    #[inline]
    pub fn add(&mut self, row: usize, column: usize, value: f64) {
        let (row, column) = if row >= column { (row, column) } else { (column, row) };
        let index = self.index(row, column);
        self.values[index] += value;
    }

    /// Replaces row and column `dof` by those of the identity, decoupling that unknown.
    pub fn set_identity_row(&mut self, dof: usize) {
        let first = dof.saturating_sub(self.bandwidth);
        for column in first..dof {
            let index = self.index(dof, column);
            self.values[index] = 0.0;
        }
        let last = (dof + self.bandwidth).min(self.size - 1);
        for row in dof + 1..=last {
            let index = self.index(row, dof);
            self.values[index] = 0.0;
        }
        let index = self.index(dof, dof);
        self.values[index] = 1.0;
    }

    /// Multiplies every entry by `factor`.
    pub fn scale(&mut self, factor: f64) {
        self.values.iter_mut().for_each(|value| *value *= factor);
    }

    /// `out = A x` for the symmetric matrix.
    pub fn multiply(&self, x: &[f64], out: &mut [f64]) {
        self.multiply_columns(0..self.size, x, out);
    }

    /// `out = A x` where only `x[columns]` may be non-zero: costs `O(columns · bandwidth)`, so a few
    /// prescribed unknowns do not pay for the whole matrix.
    pub fn multiply_columns(&self, columns: std::ops::Range<usize>, x: &[f64], out: &mut [f64]) {
        let width = self.bandwidth + 1;
        let (x, out) = (&x[..self.size], &mut out[..self.size]);
        out.fill(0.0);
        for column in columns.start..columns.end.min(self.size) {
            let value = x[column];
            if value == 0.0 {
                continue;
            }
            // Row `column` of the band holds A(column, first..=column); A is symmetric.
            let first = column.saturating_sub(self.bandwidth);
            let row_band = &self.values[column * width + self.bandwidth - (column - first)..(column + 1) * width];
            for (out, entry) in out[first..=column].iter_mut().zip(row_band) {
                *out += entry * value;
            }
            // Column `column` below the diagonal: A(row, column) for row in column + 1 ..= last.
            let last = (column + self.bandwidth).min(self.size - 1);
            for (row, out) in out.iter_mut().enumerate().take(last + 1).skip(column + 1) {
                *out += self.values[row * width + self.bandwidth + column - row] * value;
            }
        }
    }

    /// Factorises in place into `L Lᵀ` (Cholesky); the band then holds `L`, and the reciprocals of its
    /// diagonal are kept so that neither this nor [`BandedMatrix::solve_factorized`] divides in its loops.
    ///
    /// Right-looking: each finished column updates the rows below it, `A(i, k) −= L(i, j) L(k, j)`. These
    /// updates are independent of each other (no chain of dependent additions) and run along contiguous
    /// row segments, so the compiler vectorises them.
    pub fn factorize(&mut self) -> Result<(), NotPositiveDefinite> {
        let (width, bandwidth, size) = (self.bandwidth + 1, self.bandwidth, self.size);
        let Self { values, inverse_diagonal, column, .. } = self;
        inverse_diagonal.clear();
        inverse_diagonal.resize(size, 0.0);
        column.clear();
        column.resize(bandwidth, 0.0);
        for j in 0..size {
            let pivot = values[j * width + bandwidth];
            if !(pivot > 0.0 && pivot.is_finite()) {
                return Err(NotPositiveDefinite { row: j });
            }
            let diagonal = pivot.sqrt();
            values[j * width + bandwidth] = diagonal;
            inverse_diagonal[j] = 1.0 / diagonal;
            let below = (size - 1 - j).min(bandwidth);
            // L(j + 1 + t, j) for t < below, kept contiguous for the updates.
            for (t, entry) in column[..below].iter_mut().enumerate() {
                let row = j + 1 + t;
                let index = row * width + bandwidth + j - row;
                values[index] *= inverse_diagonal[j];
                *entry = values[index];
            }
            for t in 0..below {
                let row = j + 1 + t;
                // A(row, j + 1 ..= row), contiguous in the row's band.
                let start = row * width + bandwidth + j + 1 - row;
                let factor = column[t];
                for (value, other) in values[start..=start + t].iter_mut().zip(&column[..=t]) {
                    *value -= factor * other;
                }
            }
        }
        Ok(())
    }

    /// Solves `L Lᵀ x = b` in place (`rhs` becomes `x`), after [`BandedMatrix::factorize`].
    pub fn solve_factorized(&self, rhs: &mut [f64]) {
        let (width, bandwidth) = (self.bandwidth + 1, self.bandwidth);
        for row in 0..self.size {
            let first = row.saturating_sub(bandwidth);
            let band = &self.values[row * width + bandwidth - (row - first)..row * width + bandwidth];
            let known: f64 = band.iter().zip(&rhs[first..row]).map(|(l, x)| l * x).sum();
            rhs[row] = (rhs[row] - known) * self.inverse_diagonal[row];
        }
        for row in (0..self.size).rev() {
            let last = (row + bandwidth).min(self.size - 1);
            let known: f64 = (row + 1..=last).map(|k| self.values[k * width + bandwidth - k + row] * rhs[k]).sum();
            rhs[row] = (rhs[row] - known) * self.inverse_diagonal[row];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rod::test_support::Lcg;

    #[test]
    fn cholesky_solves_a_random_banded_system() {
        let (size, bandwidth) = (37, 10);
        let mut random = Lcg(7);
        let mut banded = BandedMatrix::default();
        banded.reset(size, bandwidth);
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
        banded.factorize().expect("diagonally dominant");
        banded.solve_factorized(&mut rhs);
        for (x, e) in rhs.iter().zip(&expected) {
            assert!((x - e).abs() < 1e-12);
        }
    }

    #[test]
    fn indefinite_matrix_is_reported() {
        let mut banded = BandedMatrix::default();
        banded.reset(3, 1);
        banded.add(0, 0, 1.0);
        banded.add(1, 0, 2.0);
        banded.add(1, 1, 1.0);
        banded.add(2, 2, 1.0);
        assert_eq!(banded.factorize(), Err(NotPositiveDefinite { row: 1 }));
    }

    #[test]
    fn identity_rows_decouple_an_unknown() {
        let mut banded = BandedMatrix::default();
        banded.reset(3, 2);
        for (r, c, v) in [(0, 0, 4.0), (1, 0, 1.0), (1, 1, 4.0), (2, 0, 1.0), (2, 1, 1.0), (2, 2, 4.0)] {
            banded.add(r, c, v);
        }
        banded.set_identity_row(1);
        assert_eq!((banded.get(1, 0), banded.get(2, 1), banded.get(1, 1)), (0.0, 0.0, 1.0));
        assert_eq!(banded.get(2, 0), 1.0);
    }
}
