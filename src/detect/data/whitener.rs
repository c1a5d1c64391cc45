//! The whitening product `W X` of whitened Laplace values
//! ([`super::laplace::LaplaceObs::whitened`]): a matrix `W` held with the
//! first column in which each of its rows is not zero, so that the product
//! skips the zeros before it.
//!
//! A whitening matrix matters only through `||W r||^2`, `W^T W` and
//! `(W J)^T (W r)`: any `U W` with `U` orthogonal whitens as well. The
//! observations hold `W` rotated to `R` of its QR decomposition `W = Q R`
//! ([`Whitener::rotated`]), upper trapezoidal when `W` has no more rows than
//! columns: row `i` starts at column `i`, and the products cost about half
//! of the dense ones when `W` is square (the transformed record's
//! whitening keeps nearly every component). The chi-square, the normal
//! equations and every fit on them are the same up to rounding.

use nalgebra::DMatrix;

/// A whitening matrix `W` (`K x m`) and, per row, the first column where it
/// is not zero (`m` for a row of zeros).
#[derive(Clone, Debug, PartialEq)]
pub struct Whitener {
    matrix: DMatrix<f64>,
    lead: Vec<usize>,
}

impl Whitener {
    /// `w` as it is.
    pub fn new(w: DMatrix<f64>) -> Whitener {
        let lead = (0..w.nrows())
            .map(|i| {
                (0..w.ncols())
                    .find(|&j| w[(i, j)] != 0.0)
                    .unwrap_or(w.ncols())
            })
            .collect();
        Whitener { matrix: w, lead }
    }

    /// `w` rotated to `R` of `w = Q R` (Householder QR) when it has no
    /// more rows than columns (as it is otherwise: `R` would have fewer
    /// rows, and the chi-square fewer degrees of freedom): the same
    /// whitening (`R^T R = W^T W`) with zeros before the diagonal.
    pub fn rotated(w: DMatrix<f64>) -> Whitener {
        if w.nrows() > w.ncols() || w.nrows() == 0 {
            return Whitener::new(w);
        }
        Whitener::new(w.qr().r())
    }

    /// `W`.
    pub fn matrix(&self) -> &DMatrix<f64> {
        &self.matrix
    }

    /// Rows of `W`: the whitened residuals.
    pub fn rows(&self) -> usize {
        self.matrix.nrows()
    }

    /// `W X` for the `cols` columns of `x` (column-major, `W.ncols()` rows),
    /// column-major: every column of `W` read once for all columns of `X`.
    /// Per row the same sums in the same order as nalgebra's product
    /// (`W[i][0] x_0`, then `+ W[i][j] x_j` for `j = 1, 2, ...`) but for
    /// the zeros before the rows' first column, which are not added: the
    /// same values.
    pub fn apply(&self, x: &[f64], cols: usize) -> Vec<f64> {
        let mut out = vec![0.0; self.matrix.nrows() * cols];
        self.apply_into(x, cols, &mut out);
        out
    }

    /// [`Whitener::apply`] into `out` (`W.nrows() * cols` entries, every
    /// one written).
    pub fn apply_into(&self, x: &[f64], cols: usize, out: &mut [f64]) {
        let (k, m) = self.matrix.shape();
        debug_assert_eq!(x.len(), m * cols);
        debug_assert_eq!(out.len(), k * cols);
        if k == 0 || m == 0 {
            out.fill(0.0);
            return;
        }
        let ws = self.matrix.as_slice();
        // the first column any of rows `a..b` reads
        let from = |a: usize, b: usize| self.lead[a..b].iter().copied().min().unwrap_or(m);
        // blocks of rows of W held in registers across its columns (every
        // entry of W read once per pair of columns of X, no store until the
        // block is done); per output the same sums in the same order as below
        let mut i0 = 0;
        if cols == 1 {
            while i0 + 16 <= k {
                block::<16, 1>(ws, (k, m), x, out, (i0, 0), from(i0, i0 + 16));
                i0 += 16;
            }
        }
        while i0 + 8 <= k {
            let j0 = from(i0, i0 + 8);
            let mut c = 0;
            while c + 2 <= cols {
                block::<8, 2>(ws, (k, m), x, out, (i0, c), j0);
                c += 2;
            }
            if c < cols {
                block::<8, 1>(ws, (k, m), x, out, (i0, c), j0);
            }
            i0 += 8;
        }
        // the last rows, column by column
        if i0 < k {
            let j0 = from(i0, k);
            if j0 >= m {
                for o in out.chunks_exact_mut(k) {
                    o[i0..].fill(0.0);
                }
            }
            for (j, wc) in ws.chunks_exact(k).enumerate().skip(j0) {
                for (c, o) in out.chunks_exact_mut(k).enumerate() {
                    let v = x[c * m + j];
                    let (o, wc) = (&mut o[i0..], &wc[i0..]);
                    if j == j0 {
                        for (o, a) in o.iter_mut().zip(wc) {
                            *o = a * v;
                        }
                    } else {
                        for (o, a) in o.iter_mut().zip(wc) {
                            *o += a * v;
                        }
                    }
                }
            }
        }
    }
}

/// Rows `i0..i0 + R` of `W X` for the columns `c0..c0 + C` of `X` (`W`
/// column-major `k x m` in `ws`, zero before column `j0` in these rows;
/// `X` column-major `m x cols` in `x`; the result column-major `k x cols`
/// in `out`): `W[i][j0] x_j0`, then `+ W[i][j] x_j` for `j = j0 + 1, ...`,
/// in registers.
#[inline(always)]
fn block<const R: usize, const C: usize>(
    ws: &[f64],
    (k, m): (usize, usize),
    x: &[f64],
    out: &mut [f64],
    (i0, c0): (usize, usize),
    j0: usize,
) {
    if j0 >= m {
        for c in c0..c0 + C {
            out[c * k + i0..c * k + i0 + R].fill(0.0);
        }
        return;
    }
    let xs: [&[f64]; C] = std::array::from_fn(|c| &x[(c0 + c) * m..(c0 + c + 1) * m]);
    let w0: &[f64; R] = ws[j0 * k + i0..j0 * k + i0 + R].try_into().expect("block");
    let mut acc: [[f64; R]; C] = std::array::from_fn(|c| w0.map(|v| v * xs[c][j0]));
    for j in j0 + 1..m {
        let wj: &[f64; R] = ws[j * k + i0..j * k + i0 + R].try_into().expect("block");
        for (a, xc) in acc.iter_mut().zip(&xs) {
            let v = xc[j];
            for (a, w) in a.iter_mut().zip(wj) {
                *a += w * v;
            }
        }
    }
    for (c, a) in acc.iter().enumerate() {
        let o = (c0 + c) * k + i0;
        out[o..o + R].copy_from_slice(a);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Row `i` of `w` times column `c` of `x`, `W[i][0] x_0` then `+ W[i][j]
    /// x_j`: nalgebra's order.
    fn reference(w: &DMatrix<f64>, x: &DMatrix<f64>) -> Vec<f64> {
        let (rows, m) = w.shape();
        let mut want = vec![0.0; rows * x.ncols()];
        for c in 0..x.ncols() {
            for i in 0..rows {
                let mut acc = w[(i, 0)] * x[(0, c)];
                for j in 1..m {
                    acc += w[(i, j)] * x[(j, c)];
                }
                want[c * rows + i] = acc;
            }
        }
        want
    }

    /// Dense matrices: nalgebra's product to the bit, over register blocks
    /// and the rows left over.
    #[test]
    fn dense_products_are_nalgebras() {
        let m = 23;
        let x = DMatrix::from_fn(m, 3, |i, j| (i * 3 + j) as f64 - 7.5);
        let wm = DMatrix::from_fn(4, m, |i, j| ((i + 2 * j) % 5) as f64 * 0.3 - 0.4);
        let w = Whitener::new(wm.clone());
        assert_eq!(w.apply(x.as_slice(), 3), (&wm * &x).as_slice().to_vec());
        for (rows, cols) in [(8, 1), (17, 2), (19, 3), (24, 5), (19, 1), (40, 1)] {
            let x = DMatrix::from_fn(m, cols, |i, j| ((i * 7 + j) % 11) as f64 * 0.37 - 1.1);
            let wm = DMatrix::from_fn(rows, m, |i, j| ((i * 5 + 3 * j) % 13) as f64 * 0.21 - 1.3);
            let got = Whitener::new(wm.clone()).apply(x.as_slice(), cols);
            assert_eq!(got, reference(&wm, &x), "{rows} x {cols}");
        }
    }

    /// The rotated form: upper trapezoidal, the same `W^T W` (so the same
    /// chi-square and normal equations), and its skipping product equal to
    /// the full product of the same matrix to the bit; a tall matrix and a
    /// zero row are kept as they are.
    #[test]
    fn rotated_whitening_is_the_same_whitening_with_zeros_skipped() {
        for (rows, m, cols) in [(1, 1, 1), (5, 9, 2), (17, 17, 1), (19, 40, 3), (40, 40, 2)] {
            let wm = DMatrix::from_fn(rows, m, |i, j| {
                1.0 / (1.0 + (i as f64 - j as f64).abs()) + 0.01 * ((i * 7 + j) % 5) as f64
            });
            let w = Whitener::rotated(wm.clone());
            let r = w.matrix();
            assert_eq!(r.shape(), (rows, m));
            for i in 0..rows {
                assert!((0..i).all(|j| r[(i, j)] == 0.0), "row {i} of {rows} x {m}");
            }
            let (a, b) = (r.transpose() * r, wm.transpose() * &wm);
            assert!((a - &b).amax() <= 1e-13 * b.amax(), "{rows} x {m}");
            let x = DMatrix::from_fn(m, cols, |i, j| ((i * 7 + j) % 11) as f64 * 0.37 - 1.1);
            let got = w.apply(x.as_slice(), cols);
            assert_eq!(got, reference(r, &x), "{rows} x {m}");
            let (y, z) = (DMatrix::from_vec(rows, cols, got), &wm * &x);
            for c in 0..cols {
                let (ny, nz) = (y.column(c).norm(), z.column(c).norm());
                assert!((ny - nz).abs() <= 1e-13 * nz, "{rows} x {m}: |W x|");
            }
        }
        let tall = DMatrix::from_fn(6, 4, |i, j| (i + j) as f64);
        assert_eq!(Whitener::rotated(tall.clone()).matrix(), &tall);
        let mut zero_row = DMatrix::from_fn(9, 12, |i, j| (i * j) as f64 + 1.0);
        zero_row.row_mut(8).fill(0.0);
        let w = Whitener::new(zero_row.clone());
        let x: Vec<f64> = (0..12).map(|j| j as f64 - 3.0).collect();
        assert_eq!(w.apply(&x, 1)[8], 0.0);
        assert_eq!(
            w.apply(&x, 1),
            reference(&zero_row, &DMatrix::from_vec(12, 1, x.clone()))
        );
    }
}
