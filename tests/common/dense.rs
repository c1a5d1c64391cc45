//! The tests' own generator of records, independent of the fitted models'
//! code paths: the dense state-space matrix exponential of a chain after
//! the impulse on mass 1.

use nalgebra::{DMatrix, DVector};
use springmass::Chain;

/// The displacement of every mass in `at` after the impulse, at `0, dt,
/// ..., t_end`, by the dense state-space matrix exponential.
pub fn records(truth: &Chain, at: &[usize], t_end: f64, dt: f64) -> (Vec<f64>, Vec<Vec<f64>>) {
    let c = truth.coefficients();
    let n = c.m.len();
    let mut a = DMatrix::<f64>::zeros(2 * n, 2 * n);
    for i in 0..n {
        a[(i, n + i)] = 1.0;
        a[(n + i, i)] = -(c.g[i] + c.k[i] + c.k[i + 1]) / c.m[i];
        if i > 0 {
            a[(n + i, i - 1)] = c.k[i] / c.m[i];
        }
        if i + 1 < n {
            a[(n + i, i + 1)] = c.k[i + 1] / c.m[i];
        }
        a[(n + i, n + i)] = -c.d[i] / c.m[i];
    }
    let step = (a * dt).exp();
    let mut z = DVector::<f64>::zeros(2 * n);
    z[n] = truth.gamma() / c.m[0];
    let samples = (t_end / dt).round() as usize + 1;
    let mut t = Vec::with_capacity(samples);
    let mut x = vec![Vec::with_capacity(samples); at.len()];
    for i in 0..samples {
        t.push(i as f64 * dt);
        for (xs, &j) in x.iter_mut().zip(at) {
            xs.push(z[j - 1]);
        }
        z = &step * z;
    }
    (t, x)
}
