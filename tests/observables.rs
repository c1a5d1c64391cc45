//! Observables (displacement, velocity, acceleration) and excitations
//! (impulse, measured force) against independent references: a matrix
//! exponential stepping of the state-space system written here (nalgebra
//! `DMatrix::exp`, nothing shared with `time::simulate`), dense solves,
//! 256-bit arithmetic, and the transform of the simulated series.

use nalgebra::{DMatrix, DVector};
use num_complex::Complex64;
use springmass::chain::Boundary::{self, Fixed, Free};
use springmass::forward::{observe, response, transfer_function, Observable};
use springmass::time::modal::ModalResponse;
use springmass::time::series::{SeriesTransform, TransformOptions};
use springmass::time::simulate::{simulate, simulate_forced, Forcing, Method, SimOptions};
use springmass::{Chain, Defect};
use std::f64::consts::PI;

const ENDS: [(Boundary, Boundary); 4] =
    [(Fixed, Fixed), (Free, Fixed), (Fixed, Free), (Free, Free)];
const KINDS: [Observable; 2] = [Observable::Velocity, Observable::Acceleration];

fn chain(left: Boundary, right: Boundary) -> Chain {
    Chain::paper(6)
        .unwrap()
        .with_gamma(1.4)
        .unwrap()
        .with_boundaries(left, right)
        .unwrap()
        .with_defects([
            Defect::Mass { at: 3, m: 2.5 },
            Defect::Spring { at: 4, k: 0.6 },
            Defect::Damper { at: 6, d: 0.4 },
        ])
        .unwrap()
}

/// `A = [[0, I], [-M^-1 K, -M^-1 D]]` from the chain's profiles.
fn state_matrix(c: &Chain) -> DMatrix<f64> {
    let n = c.n();
    let (m, k, d) = (c.masses(), c.springs(), c.dampers());
    let mut a = DMatrix::zeros(2 * n, 2 * n);
    for i in 0..n {
        a[(i, n + i)] = 1.0;
        a[(n + i, i)] = -(k[i] + k[i + 1]) / m[i];
        a[(n + i, n + i)] = -d[i] / m[i];
        if i > 0 {
            a[(n + i, i - 1)] = k[i] / m[i];
        }
        if i + 1 < n {
            a[(n + i, i + 1)] = k[i + 1] / m[i];
        }
    }
    a
}

/// The observable of mass `i` from the state `y` (and the force on mass `i`).
fn read(
    a: &DMatrix<f64>,
    y: &DVector<f64>,
    n: usize,
    i: usize,
    kind: Observable,
    f: f64,
    mi: f64,
) -> f64 {
    match kind {
        Observable::Displacement => y[i - 1],
        Observable::Velocity => y[n + i - 1],
        Observable::Acceleration => (a.row(n + i - 1) * y)[(0, 0)] + f / mi,
    }
}

/// Velocity and acceleration series from `simulate` (RK, expm, modal)
/// against an independent expm stepping, every boundary case, to 1e-10.
#[test]
fn velocity_and_acceleration_series_match_expm_stepping() {
    let (dt, t_end) = (0.1, 40.0);
    let observed = [1usize, 3, 6];
    for (left, right) in ENDS {
        let c = chain(left, right);
        let n = c.n();
        let a = state_matrix(&c);
        let e = (&a * dt).exp();
        let steps = (t_end / dt).round() as usize;
        let mut y = DVector::zeros(2 * n);
        y[n] = c.gamma() / c.masses()[0];
        let mut states = vec![y.clone()];
        for _ in 0..steps {
            y = &e * &y;
            states.push(y.clone());
        }
        for kind in KINDS {
            for method in [Method::Rk, Method::Expm, Method::Modal] {
                let opts = SimOptions::new(t_end, dt)
                    .with_observe(observed.to_vec())
                    .with_method(method)
                    .with_observe_kind(kind);
                let tr = simulate(&c, &opts).unwrap();
                assert_eq!(tr.kind, kind);
                assert_eq!(tr.t.len(), steps + 1);
                let mut worst: f64 = 0.0;
                for &i in &observed {
                    let got = tr.x(i).unwrap();
                    let want: Vec<f64> = states
                        .iter()
                        .map(|y| read(&a, y, n, i, kind, 0.0, 1.0))
                        .collect();
                    let scale = want.iter().fold(1.0_f64, |m, v| m.max(v.abs()));
                    for (k, (g, w)) in got.iter().zip(&want).enumerate() {
                        let err = (g - w).abs();
                        worst = worst.max(err / scale);
                        assert!(
                            err <= 1e-10 * scale,
                            "{left:?}-{right:?} {kind} {method} mass {i} t={}: {g} vs {w}",
                            tr.t[k]
                        );
                    }
                }
                eprintln!("{left:?}-{right:?} {kind} {method}: worst error / scale {worst:.2e}");
            }
        }
        // the acceleration at t = 0 is the 0+ limit: -d_1 v_1(0+) / m_1
        let tr = simulate(
            &c,
            &SimOptions::new(1.0, 0.5).with_observe_kind(Observable::Acceleration),
        )
        .unwrap();
        let v0 = c.gamma() / c.masses()[0];
        assert!((tr.x(1).unwrap()[0] + c.dampers()[0] * v0 / c.masses()[0]).abs() < 1e-15);
    }
}

/// A hammer test: the impulse replaced by a measured half-sine force of
/// width 0.05 on mass 1 (gamma = 0). Reference: the state-space system
/// augmented by the oscillator that generates the sine, stepped by expm,
/// switched off at the end of the pulse.
#[test]
fn hammer_force_series_match_expm_stepping() {
    let (w, f0) = (0.05, 10.0);
    let omega = PI / w;
    let (dt, t_end) = (0.01, 20.0);
    for (left, right) in ENDS {
        let c = chain(left, right).with_gamma(0.0).unwrap();
        let n = c.n();
        let m1 = c.masses()[0];
        let a = state_matrix(&c);
        // augmented: z = (y, sin(omega t), cos(omega t))
        let mut aug = DMatrix::zeros(2 * n + 2, 2 * n + 2);
        aug.view_mut((0, 0), (2 * n, 2 * n)).copy_from(&a);
        aug[(n, 2 * n)] = f0 / m1;
        aug[(2 * n, 2 * n + 1)] = omega;
        aug[(2 * n + 1, 2 * n)] = -omega;
        let e_on = (&aug * dt).exp();
        let e_off = (&a * dt).exp();
        let steps = (t_end / dt).round() as usize;
        let on_steps = (w / dt).round() as usize;
        let mut z = DVector::zeros(2 * n + 2);
        z[2 * n + 1] = 1.0;
        let mut states = vec![z.rows(0, 2 * n).into_owned()];
        let mut forces = vec![0.0];
        for k in 1..=steps {
            if k <= on_steps {
                z = &e_on * &z;
                states.push(z.rows(0, 2 * n).into_owned());
                forces.push(if k < on_steps { f0 * z[2 * n] } else { 0.0 });
            } else {
                let y = &e_off * states.last().unwrap();
                states.push(y);
                forces.push(0.0);
            }
        }
        let forcing = Forcing::new().on(1, move |t| {
            if (0.0..=w).contains(&t) {
                f0 * (omega * t).sin()
            } else {
                0.0
            }
        });
        for kind in [
            Observable::Displacement,
            Observable::Velocity,
            Observable::Acceleration,
        ] {
            for method in [Method::Expm, Method::Rk] {
                let opts = SimOptions::new(t_end, dt)
                    .with_observe(vec![1, n])
                    .with_method(method)
                    .with_substeps(10)
                    .with_observe_kind(kind);
                let tr = simulate_forced(&c, &opts, &forcing).unwrap();
                for i in [1, n] {
                    let want: Vec<f64> = states
                        .iter()
                        .zip(&forces)
                        .map(|(y, &f)| read(&a, y, n, i, kind, if i == 1 { f } else { 0.0 }, m1))
                        .collect();
                    let scale = want.iter().fold(1.0_f64, |m, v| m.max(v.abs()));
                    for (k, (g, wv)) in tr.x(i).unwrap().iter().zip(&want).enumerate() {
                        assert!(
                            (g - wv).abs() <= 1e-10 * scale,
                            "{left:?}-{right:?} {kind} {method} mass {i} t={}: {g} vs {wv}",
                            tr.t[k]
                        );
                    }
                }
            }
        }
    }
}

/// The modal sum differentiated once and twice has the transforms
/// `s X` and `s^2 X - x'(0+)` of the forward model, every boundary case.
#[test]
fn modal_derivatives_match_forward_observables() {
    for (left, right) in ENDS {
        let c = chain(left, right);
        for at in [1, 2, 6] {
            for kind in KINDS {
                let r = ModalResponse::impulse_observable(&c, at, kind).unwrap();
                for s in [
                    Complex64::new(0.3, 0.0),
                    Complex64::new(2.0, 0.0),
                    Complex64::new(0.1, 1.2),
                    Complex64::new(1.0, -4.0),
                ] {
                    let want = observe(&c, s, at, kind).unwrap();
                    let x = response(&c, s, at).unwrap();
                    let jump = if at == 1 && kind == Observable::Acceleration {
                        c.gamma() / c.masses()[0]
                    } else {
                        0.0
                    };
                    let naive = x * s.powu(kind.power()) - jump;
                    assert!((want - naive).norm() <= 1e-12 * want.norm().max(naive.norm()));
                    assert!(
                        (r.laplace(s) - want).norm() <= 1e-11 * want.norm().max(1e-3),
                        "{left:?}-{right:?} {kind} at={at} s={s}: {} vs {want}",
                        r.laplace(s)
                    );
                }
            }
        }
    }
}

/// The acceleration of the struck mass at large s: `-Z_1 X_1 / m_1`
/// against 256-bit arithmetic (where `s^2 X_1 - gamma/m_1` loses digits).
#[test]
fn acceleration_of_struck_mass_has_no_cancellation() {
    use springmass::forward::tridiag::solve_all;
    use springmass::precision::{with_precision, BigReal};
    use springmass::scalar::Scalar;
    for (left, right) in ENDS {
        let c = chain(left, right);
        for s in [10.0, 300.0, 1e4] {
            let got = observe(&c, s, 1, Observable::Acceleration).unwrap();
            let want = with_precision(256, || {
                let sb = BigReal::from_f64(s);
                let x = solve_all(&c, sb.clone()).unwrap().swap_remove(0);
                (sb.clone() * sb * x - BigReal::from_f64(c.gamma() / c.masses()[0])).re_f64()
            });
            let naive = Observable::Acceleration.from_displacement(
                response(&c, s, 1).unwrap(),
                &s,
                1,
                c.gamma(),
                c.masses()[0],
            );
            let e = (got - want).abs() / want.abs();
            eprintln!(
                "{left:?}-{right:?} s={s}: rel err {e:.1e}, naive s^2 X - gamma/m1 {:.1e}",
                (naive - want).abs() / want.abs()
            );
            assert!(e <= 1e-13, "{left:?}-{right:?} s={s}: {got} vs {want}");
        }
    }
}

/// Transfer functions (force on mass 1 to any observable) against a dense
/// solve: `H = [K^-1]_{o1}`, `s H`, `s^2 H`, with gamma = 0 in the chain.
#[test]
fn transfer_functions_match_dense() {
    for (left, right) in ENDS {
        let c = chain(left, right).with_gamma(0.0).unwrap();
        let n = c.n();
        for s in [Complex64::new(0.4, 0.0), Complex64::new(0.2, 1.7)] {
            let (m, k, d) = (c.masses(), c.springs(), c.dampers());
            let mut kk = DMatrix::<Complex64>::zeros(n, n);
            for i in 0..n {
                kk[(i, i)] = s * s * m[i] + s * d[i] + k[i] + k[i + 1];
                if i + 1 < n {
                    kk[(i, i + 1)] = (-k[i + 1]).into();
                    kk[(i + 1, i)] = (-k[i + 1]).into();
                }
            }
            let inv = kk.lu().try_inverse().unwrap();
            for o in 1..=n {
                for kind in [
                    Observable::Displacement,
                    Observable::Velocity,
                    Observable::Acceleration,
                ] {
                    let h = transfer_function(&c, s, o, kind).unwrap();
                    let want = inv[(o - 1, 0)] * s.powu(kind.power());
                    assert!(
                        (h - want).norm() <= 1e-12 * want.norm(),
                        "{kind} o={o} s={s}"
                    );
                }
            }
        }
    }
}

/// The transform of simulated velocity / acceleration series equals the
/// model's observable; for a hammer test the transform of the response is
/// `H(s) F(s)` with `F` the transform of the force series.
#[test]
fn series_transforms_of_observables() {
    let opts = TransformOptions::default();
    for (left, right) in ENDS {
        // damping 0.5 so that t_end = 150 leaves no tail
        let c = chain(left, right).with_d(0.5).unwrap();
        for kind in [Observable::Velocity, Observable::Acceleration] {
            let so = SimOptions::new(150.0, 0.02)
                .with_observe(vec![1, 6])
                .with_observe_kind(kind);
            let tr = simulate(&c, &so).unwrap();
            for at in [1, 6] {
                let st = SeriesTransform::new(&tr.t, tr.x(at).unwrap(), &opts).unwrap();
                for s in [Complex64::new(0.5, 0.0), Complex64::new(1.0, 2.0)] {
                    let v = st.eval(s).unwrap();
                    let want = observe(&c, s, at, kind).unwrap();
                    assert!(
                        (v.value - want).norm() <= 1e-9 + 2.0 * v.err,
                        "{left:?}-{right:?} {kind} at={at} s={s}: {} vs {want} (err {:e})",
                        v.value,
                        v.err
                    );
                }
            }
        }
        // hammer: half-sine of width 0.05 sampled every 1e-3
        let hc = c.clone().with_gamma(0.0).unwrap();
        let (w, f0) = (0.05, 10.0);
        let dt = 1e-3;
        let force = move |t: f64| {
            if (0.0..=w).contains(&t) {
                f0 * (PI * t / w).sin()
            } else {
                0.0
            }
        };
        let so = SimOptions::new(150.0, dt)
            .with_observe(vec![1])
            .with_observe_kind(Observable::Acceleration);
        let tr = simulate_forced(&hc, &so, &Forcing::new().on(1, force)).unwrap();
        let ft: Vec<f64> =
            tr.t.iter()
                .take_while(|&&t| t <= w + 1e-12)
                .copied()
                .collect();
        let fv: Vec<f64> = ft.iter().map(|&t| force(t)).collect();
        let fz = SeriesTransform::new(
            &ft,
            &fv,
            &TransformOptions {
                tail: springmass::time::series::Tail::Zero,
                ..TransformOptions::default()
            },
        )
        .unwrap();
        let xt = SeriesTransform::new(&tr.t, tr.x(1).unwrap(), &opts).unwrap();
        for s in [Complex64::new(0.5, 0.0), Complex64::new(1.0, 2.0)] {
            let f = fz.eval(s).unwrap();
            let y = xt.eval(s).unwrap();
            let h = transfer_function(&hc, s, 1, Observable::Acceleration).unwrap();
            let want = h * f.value;
            assert!(
                (y.value - want).norm() <= 1e-9 + 2.0 * (y.err + h.norm() * f.err),
                "{left:?}-{right:?} hammer s={s}: {} vs {want}",
                y.value
            );
        }
    }
}
