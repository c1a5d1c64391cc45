//! Output-only (ambient) fits against a generator of their own: the exact
//! discretisation of the continuous state-space model under white forces
//! (matrix exponential of the dense state matrix, the discrete noise
//! covariance by Van Loan's method), independent of the fitted model's
//! tridiagonal frequency-domain path; bad records refused.

use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};
use springmass::chain::{Chain, Defect};
use springmass::detect::data::ambient::AmbientRecord;
use springmass::detect::fit::ambient::{fit_ambient, AmbientOptions, AmbientTarget};
use springmass::forward::Observable;
use springmass::time::modal::natural_modes;

use nalgebra::DMatrix;

/// The state matrix `[[0, I], [-M^-1 K, -M^-1 D]]` and the force input
/// `[0; M^-1 E_on]`, assembled densely from the chain's coefficient lists.
fn state_space(chain: &Chain, on: &[usize]) -> (DMatrix<f64>, DMatrix<f64>) {
    let n = chain.n();
    let c = chain.coefficients();
    let mut k = DMatrix::zeros(n, n);
    let mut d = DMatrix::zeros(n, n);
    for i in 0..n {
        k[(i, i)] = c.g[i] + c.k[i] + c.k[i + 1];
        d[(i, i)] = c.d[i] + c.c[i] + c.c[i + 1];
        if i + 1 < n {
            k[(i, i + 1)] = -c.k[i + 1];
            k[(i + 1, i)] = -c.k[i + 1];
            d[(i, i + 1)] = -c.c[i + 1];
            d[(i + 1, i)] = -c.c[i + 1];
        }
    }
    let minv = DMatrix::from_diagonal(&nalgebra::DVector::from_iterator(
        n,
        c.m.iter().map(|m| 1.0 / m),
    ));
    let mut a = DMatrix::zeros(2 * n, 2 * n);
    a.view_mut((0, n), (n, n)).fill_with_identity();
    a.view_mut((n, 0), (n, n)).copy_from(&(-&minv * k));
    a.view_mut((n, n), (n, n)).copy_from(&(-&minv * d));
    let mut b = DMatrix::zeros(2 * n, on.len());
    for (j, &m) in on.iter().enumerate() {
        b[(n + m - 1, j)] = minv[(m - 1, m - 1)];
    }
    (a, b)
}

/// `Phi = e^{A h}` and a square root of `Q_d = int_0^h e^{A t} B B^T e^{A^T t} dt`
/// (unit force intensity) by Van Loan's block exponential.
fn discretise(a: &DMatrix<f64>, b: &DMatrix<f64>, h: f64) -> (DMatrix<f64>, DMatrix<f64>) {
    let s = a.nrows();
    let mut c = DMatrix::zeros(2 * s, 2 * s);
    c.view_mut((0, 0), (s, s)).copy_from(&(-a * h));
    c.view_mut((0, s), (s, s))
        .copy_from(&(b * b.transpose() * h));
    c.view_mut((s, s), (s, s)).copy_from(&(a.transpose() * h));
    let e = c.exp();
    let phi = e.view((s, s), (s, s)).transpose();
    let q = &phi * e.view((0, s), (s, s));
    let q = (&q + q.transpose()) * 0.5;
    let eig = q.symmetric_eigen();
    let root = DMatrix::from_diagonal(&eig.eigenvalues.map(|v| v.max(0.0).sqrt()));
    (phi, &eig.eigenvectors * root)
}

/// A record of `samples` at step `dt`: `sub` exact steps per sample; the
/// channels at `observe` (displacement, velocity, or acceleration as the
/// mean over the last sub-step, what a sensor with a short averaging time
/// records), plus white sensor noise of `noise` times each channel's std.
#[allow(clippy::too_many_arguments)]
fn generate(
    chain: &Chain,
    observe: &[usize],
    kind: Observable,
    dt: f64,
    sub: usize,
    samples: usize,
    noise: f64,
    seed: u64,
) -> AmbientRecord {
    let n = chain.n();
    let on: Vec<usize> = (1..=n).collect();
    let (a, b) = state_space(chain, &on);
    let h = dt / sub as f64;
    let (phi, root) = discretise(&a, &b, h);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let mut z = nalgebra::DVector::<f64>::zeros(2 * n);
    let mut step = |z: &nalgebra::DVector<f64>| {
        let xi = nalgebra::DVector::from_fn(2 * n, |_, _| StandardNormal.sample(&mut rng));
        &phi * z + &root * xi
    };
    for _ in 0..20 * sub * 50 {
        z = step(&z); // settle into the stationary state
    }
    let mut ch = vec![Vec::with_capacity(samples); observe.len()];
    for _ in 0..samples {
        let mut prev = z.clone();
        for _ in 0..sub {
            prev = z.clone();
            z = step(&z);
        }
        for (c, &o) in ch.iter_mut().zip(observe) {
            let i = o - 1;
            c.push(match kind {
                Observable::Displacement => z[i],
                Observable::Velocity => z[n + i],
                Observable::Acceleration => (z[n + i] - prev[n + i]) / h,
            });
        }
    }
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed ^ 0x5eed);
    for c in &mut ch {
        let mean = c.iter().sum::<f64>() / c.len() as f64;
        let sd = (c.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / c.len() as f64).sqrt();
        for v in c.iter_mut() {
            let e: f64 = StandardNormal.sample(&mut rng);
            *v += noise * sd * e;
        }
    }
    AmbientRecord::new(dt, observe.to_vec(), kind, ch).unwrap()
}

#[test]
fn one_weak_storey_of_an_8_mass_chain_is_found_from_three_displacement_channels() {
    let nominal = Chain::paper(8).unwrap();
    let truth = nominal
        .clone()
        .with_defect(Defect::Spring { at: 3, k: 0.8 })
        .unwrap();
    let rec = generate(
        &truth,
        &[1, 5, 8],
        Observable::Displacement,
        0.5,
        2,
        6000,
        0.1,
        7,
    );
    let opts = AmbientOptions {
        target: AmbientTarget::Defects { k_min: 0, k_max: 1 },
        ..AmbientOptions::default()
    };
    let r = fit_ambient(&nominal, &rec, &opts).unwrap();
    assert_eq!(r.status, "converged", "{}", r.summary());
    assert_eq!(r.k, 1, "{}", r.summary());
    let f = &r.factors[0];
    assert_eq!((f.kind, f.at), ("spring", 3), "{}", r.summary());
    let se = f.se.unwrap();
    assert!((f.factor - 0.8).abs() < 3.0 * se, "{}", r.summary());
    assert!(se < 0.05, "{}", r.summary());
    let (d, dse) = r.d;
    assert!((d - 0.1).abs() < 3.0 * dse.unwrap(), "{}", r.summary());
    // the first modes' frequency and damping within 3 SE of the truth
    let true_modes = natural_modes(&truth).unwrap();
    for m in r.modes.iter().take(3) {
        let t = &true_modes[m.mode - 1];
        assert!(
            (m.omega - t.omega).abs() < 3.0 * m.omega_se.unwrap(),
            "mode {}: {} vs {}\n{}",
            m.mode,
            m.omega,
            t.omega,
            r.summary()
        );
        assert!(
            (m.zeta - t.zeta.unwrap()).abs() < 3.0 * m.zeta_se.unwrap(),
            "{}",
            r.summary()
        );
    }
}
