//! Test-only reference: a chain's `M`, `C`, `K` assembled densely from the
//! damping models' definitions (not from [`Chain::site`] or
//! [`Chain::coefficients`]), the dense solve of `K(s) X = gamma e_1` and
//! the impulse response by the matrix exponential of the state-space form.
//! Every kernel's tests for the damping models compare against these.

use super::{Chain, Damping, Defect};
use nalgebra::{DMatrix, DVector};
use num_complex::Complex64;

/// The dense matrices of the equations of motion `M x'' + C x' + K x = f`.
pub struct Dense {
    pub m: DMatrix<f64>,
    pub c: DMatrix<f64>,
    pub k: DMatrix<f64>,
}

/// Add `v (e_j - e_{j+1})(e_j - e_{j+1})^T` (1-based masses, walls out).
fn add_link(a: &mut DMatrix<f64>, n: usize, j: usize, v: f64) {
    if j >= 1 {
        a[(j - 1, j - 1)] += v;
    }
    if j < n {
        a[(j, j)] += v;
    }
    if j >= 1 && j < n {
        a[(j - 1, j)] -= v;
        a[(j, j - 1)] -= v;
    }
}

/// `M`, `C`, `K` of `chain` by the definitions of [`Damping`].
pub fn assemble(chain: &Chain) -> Dense {
    let n = chain.n();
    let mut masses = vec![chain.mass(); n];
    let mut springs = vec![chain.k(); n + 1];
    let mut grounds = vec![0.0; n];
    let mut grounded = vec![chain.d(); n];
    let between_c = match chain.damping() {
        Damping::Between { c } => *c,
        _ => 0.0,
    };
    let mut links = vec![between_c; n + 1];
    if let Some(b) = chain.baseline() {
        masses = b.masses().to_vec();
        springs = b.springs().to_vec();
        if let Some(d) = b.dampers() {
            match chain.damping() {
                Damping::Between { .. } => links = d.to_vec(),
                _ => grounded = d[..n].to_vec(),
            }
        }
    }
    for d in chain.defects() {
        match *d {
            Defect::Mass { at, m } => masses[at - 1] = m,
            Defect::Spring { at, k } => springs[at] = k,
            Defect::Ground { at, g } => grounds[at - 1] = g,
            Defect::Damper { at, d } => match chain.damping() {
                Damping::Between { .. } => links[at] = d,
                _ => grounded[at - 1] = d,
            },
        }
    }
    if chain.left().is_free() {
        springs[0] = 0.0;
        links[0] = 0.0;
    }
    if chain.right().is_free() {
        springs[n] = 0.0;
        links[n] = 0.0;
    }
    let m = DMatrix::from_diagonal(&DVector::from_vec(masses));
    let mut k = DMatrix::from_diagonal(&DVector::from_vec(grounds));
    for (j, &v) in springs.iter().enumerate() {
        add_link(&mut k, n, j, v);
    }
    let mut c = DMatrix::from_diagonal(&DVector::from_vec(grounded));
    match chain.damping() {
        Damping::Grounded => {}
        Damping::Between { .. } => {
            for (j, &v) in links.iter().enumerate() {
                add_link(&mut c, n, j, v);
            }
        }
        Damping::Rayleigh { a, b } => c += &m * *a + &k * *b,
        Damping::Modal { zeta } => {
            // M^-1/2 K M^-1/2 = Q diag(omega^2) Q^T, Phi = M^-1/2 Q:
            // C = M Phi diag(2 zeta_j omega_j) Phi^T M, zeta_j by the rank of
            // omega_j (the last ratio for every higher mode)
            let mh = DMatrix::from_diagonal(&m.diagonal().map(|v| 1.0 / v.sqrt()));
            let eig = (&mh * &k * &mh).symmetric_eigen();
            let phi = &mh * &eig.eigenvectors;
            let mut order: Vec<usize> = (0..n).collect();
            order.sort_by(|&i, &j| eig.eigenvalues[i].total_cmp(&eig.eigenvalues[j]));
            let mut w = eig.eigenvalues.clone();
            for (rank, &i) in order.iter().enumerate() {
                let z = zeta[rank.min(zeta.len() - 1)];
                w[i] = 2.0 * z * eig.eigenvalues[i].max(0.0).sqrt();
            }
            c += &m * &phi * DMatrix::from_diagonal(&w) * phi.transpose() * &m;
        }
    }
    Dense { m, c, k }
}

/// `X_observe(s)` by a dense LU solve of `(M s^2 + C s + K) X = gamma e_1`.
pub fn solve(chain: &Chain, s: Complex64, observe: usize) -> Complex64 {
    let d = assemble(chain);
    let n = chain.n();
    let a = DMatrix::from_fn(n, n, |i, j| {
        s * s * d.m[(i, j)] + s * d.c[(i, j)] + Complex64::new(d.k[(i, j)], 0.0)
    });
    let mut b = DVector::<Complex64>::zeros(n);
    b[0] = chain.gamma().into();
    a.lu().solve(&b).expect("a regular system")[observe - 1]
}

/// The displacement of mass `observe` after the impulse `gamma` on mass 1,
/// at `t = i dt` for `i < samples`, by `y_{i+1} = exp(A dt) y_i` with
/// `A = [[0, I], [-M^-1 K, -M^-1 C]]`.
pub fn impulse(chain: &Chain, observe: usize, dt: f64, samples: usize) -> Vec<f64> {
    let d = assemble(chain);
    let n = chain.n();
    let minv = d.m.clone().try_inverse().expect("positive masses");
    let mut a = DMatrix::zeros(2 * n, 2 * n);
    a.view_mut((0, n), (n, n)).fill_with_identity();
    a.view_mut((n, 0), (n, n)).copy_from(&(-(&minv * &d.k)));
    a.view_mut((n, n), (n, n)).copy_from(&(-(&minv * &d.c)));
    let e = (a * dt).exp();
    let mut y = DVector::zeros(2 * n);
    y[n] = chain.gamma() / d.m[(0, 0)];
    let mut out = Vec::with_capacity(samples);
    for _ in 0..samples {
        out.push(y[observe - 1]);
        y = &e * y;
    }
    out
}

/// Chains of every damping model with a defect of each kind, for the
/// kernels' tests: `(grounded, between, rayleigh)` variants of `n = 8`.
pub fn model_chains() -> Vec<Chain> {
    use super::Boundary;
    let base = crate::scenes::paper_with(8, "mass:3:2 spring:5:1.5 damper:4:0.3 ground:6:0.4")
        .expect("a valid chain");
    let mut out = Vec::new();
    for ends in [
        (Boundary::Fixed, Boundary::Fixed),
        (Boundary::Free, Boundary::Fixed),
    ] {
        let c = base.clone().with_boundaries(ends.0, ends.1).expect("ends");
        out.push(c.clone());
        out.push(
            c.clone()
                .with_d(0.0)
                .and_then(|c| c.with_damping(Damping::Between { c: 0.07 }))
                .expect("between"),
        );
        out.push(
            c.with_d(0.01)
                .and_then(|c| c.with_damping(Damping::Rayleigh { a: 0.03, b: 0.05 }))
                .expect("rayleigh"),
        );
    }
    out
}

/// Modally damped chains (`zeta = 0.03`, `d = 0`) with a mass, a spring and
/// a ground defect, `n = 8`, fixed-fixed and free-fixed; one with a
/// grounded `d` proportional to the masses beside the modes' damping; one
/// with a ratio per mode.
pub fn modal_chains() -> Vec<Chain> {
    use super::Boundary;
    let base = crate::scenes::paper_with(8, "mass:3:2 spring:5:1.5 ground:6:0.4")
        .and_then(|c| c.with_d(0.0))
        .and_then(|c| c.with_damping(Damping::modal(0.03)))
        .expect("a valid chain");
    let mut out: Vec<Chain> = [
        (Boundary::Fixed, Boundary::Fixed),
        (Boundary::Free, Boundary::Fixed),
    ]
    .iter()
    .map(|e| base.clone().with_boundaries(e.0, e.1).expect("ends"))
    .collect();
    out.push(
        crate::scenes::paper_with(8, "spring:5:1.5")
            .and_then(|c| c.with_d(0.02))
            .and_then(|c| c.with_damping(Damping::modal(0.05)))
            .expect("a valid chain"),
    );
    // one ratio per mode, not in the order of the modes, the last for
    // modes 4 to 8
    out.push(
        base.clone()
            .with_damping(Damping::Modal {
                zeta: vec![0.01, 0.06, 0.002, 0.03],
            })
            .expect("a valid chain"),
    );
    out
}

/// Nonuniform chains on a [`super::Baseline`] (masses and springs varying
/// by up to 30%, seeded), `n` masses, with the ends given (a free end has
/// no wall spring) and a damper column when `dampers`.
pub fn baseline_chain(n: usize, ends: (super::Boundary, super::Boundary), dampers: bool) -> Chain {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(n as u64 * 7 + 3);
    let mut vary = |x: f64| x * (1.0 + 0.3 * (2.0 * rng.random::<f64>() - 1.0));
    let mass: Vec<f64> = (0..n).map(|_| vary(1.0)).collect();
    let mut spring: Vec<f64> = (0..=n).map(|_| vary(1.0)).collect();
    if ends.0.is_free() {
        spring[0] = 0.0;
    }
    if ends.1.is_free() {
        spring[n] = 0.0;
    }
    let damper = dampers.then(|| (0..=n).map(|_| vary(0.1)).collect());
    let b = super::Baseline::new(mass, spring, damper, "test").expect("a valid baseline");
    Chain::paper(n)
        .and_then(|c| c.with_baseline(b))
        .expect("a valid chain")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rayleigh_is_a_m_plus_b_k_and_between_is_a_laplacian() {
        let cs = model_chains();
        let r = assemble(&cs[2]);
        let g = assemble(&cs[0]);
        // K is the same in every model; C = a M + b K + grounded dampers
        assert_eq!(r.k, g.k);
        let want = &r.m * 0.03 + &r.k * 0.05;
        assert!((r.c[(0, 1)] - want[(0, 1)]).abs() < 1e-15);
        let b = assemble(&cs[1]);
        // each row of a Laplacian sums to the wall dampers only
        let rows: Vec<f64> = (0..8).map(|i| b.c.row(i).sum()).collect();
        assert!((rows[0] - 0.07).abs() < 1e-15 && rows[3].abs() < 1e-15);
    }
}
