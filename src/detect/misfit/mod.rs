//! L2 residuals between the model `X_1(s; defects)` and observed data, on a
//! fixed quadrature rule with tabled Green's functions.
//!
//! Two kinds, one interface ([`Misfit`]):
//!
//! * **real axis** (the paper's (4.18)): `r = int_0^{s_max} |X_1(s) - X_1*(s)|^2 ds`,
//!   `s_max = 300` by default;
//! * **Bromwich line** `s = sigma + i omega`:
//!   `r = int_0^{W} |X_1(sigma + i omega) - X_1*(sigma + i omega)|^2 d omega`
//!   (by Parseval this weights the time-domain misfit by `exp(-2 sigma t)`,
//!   which keeps the time-domain conditioning; docs/paper-notes.md).
//!
//! Both are `r = sum_q w_q |X_1(s_q) - d_q|^2` with data `d_q` sampled at the
//! same nodes as the model, so a rule's quadrature error never moves the zero
//! of `r` at the truth (data and model are consistent).
//!
//! For mass defects at positions `J` with changes `dm_l = m_l - mass`, per node
//! `c_l = dm_l s^2`, `z` solves `(I + G_JJ C) z = G_J1` and
//! `X_1 = gamma (G_11 - sum_l G_1 j_l c_l z_l)` (Woodbury), and
//! `dX_1/dm_l = -gamma s^2 z_l^2`. A [`SetTable`] gathers the Green's entries a
//! position set needs from the [`GreenTable`] once, so that a residual
//! evaluation is only the `k x k` solves and a weighted sum. One or two
//! defects on the real axis are *folded*: by Cramer's rule `X_1` at a node is
//! a ratio of bilinear forms in the mass changes,
//! `(N0 + N1 dm1 + N2 dm2 + N12 dm1 dm2) / (1 + D1 dm1 + D2 dm2 + D12 dm1 dm2)`,
//! whose seven coefficients (with `s^2` and `gamma` folded in) are computed
//! once per set, so that a residual is one division and a few multiply-adds
//! per node, over independent accumulators. Other sets (three or more
//! defects, the Bromwich line) take the general path
//! ([`Misfit::set_general`] forces it, the reference in tests).
//!
//! ```
//! use springmass::{Chain, Defect};
//! use springmass::detect::{data::exact::Data, misfit::{Misfit, MisfitSpec}};
//! let truth = Chain::paper(20)?.with_defects([
//!     Defect::Mass { at: 8, m: 5.0 }, Defect::Mass { at: 15, m: 2.0 }])?;
//! let misfit = Misfit::new(&truth.uniform(), &Data::exact(&truth), &MisfitSpec::default())?;
//! assert!(misfit.residual(&[(8, 5.0), (15, 2.0)]) < 1e-28);
//! assert!(misfit.residual(&[(8, 5.0), (16, 2.0)]) > 1e-15);
//! # Ok::<(), springmass::Error>(())
//! ```

pub mod ambient;
pub mod laplace_sets;
pub mod modal;
pub mod modal_dynamic;
pub mod quadrature;
mod set;
mod spec;
pub mod time;
pub mod time_screen;

use set::{Body, Folded, Gathered, Rows};
pub use set::{Num, SetTable};
use spec::time_has_no_rule;
pub use spec::{MisfitKind, MisfitSpec, RuleKind, MAX_PANELS, MAX_PER_PANEL};

use crate::chain::Chain;
use crate::detect::data::exact::Data;
use crate::detect::misfit::quadrature::{Adaptive, AdaptiveOutput, GreenTable, Rule};
use crate::error::{Error, Result};
use crate::forward::{woodbury, Update};
use crate::green::{Green, Probe};
use num_complex::Complex64;
#[derive(Clone, Debug)]
enum Tab {
    Real {
        g: GreenTable<f64>,
        d: Vec<f64>,
        /// `G_1j` and `G_jj` at every node for the folded sets (when small
        /// enough, [`MAX_ROWS`]).
        rows: Option<Rows>,
    },
    Complex {
        g: GreenTable<Complex64>,
        d: Vec<Complex64>,
    },
}

/// A residual on a fixed rule: nodes, weights, tabled Green's function and
/// data, built once per study.
#[derive(Clone, Debug)]
pub struct Misfit {
    spec: MisfitSpec,
    rule: Rule,
    chain: Chain,
    data: Data,
    w: Vec<f64>,
    sigma: Vec<f64>,
    tab: Tab,
}

impl Misfit {
    /// Build the residual of the uniform chain `model` (its `n, k, d, gamma,
    /// mass`; its defects are ignored) against `data`.
    ///
    /// # Errors
    /// Bad `spec` (fields `misfit.*`); a chain too long to table.
    pub fn new(model: &Chain, data: &Data, spec: &MisfitSpec) -> Result<Misfit> {
        model.require_fixed_ends(
            "the mass-only Woodbury kernel of the paper's residual (the data-first fit handles free ends)",
        )?;
        model.require_grounded(
            "the mass-only Woodbury kernel of the paper's residual (the data-first fit takes every model)",
        )?;
        model.require_uniform(
            "the mass-only Woodbury kernel of the paper's residual (the data-first fit takes a baseline)",
        )?;
        let rule = spec.rule()?;
        let chain = model.uniform();
        let (tab, sigma) = match spec.kind {
            MisfitKind::RealAxis => {
                let g = GreenTable::new(&chain, &rule.nodes)?;
                let sm = data.sample(&rule.nodes)?;
                let rows = Rows::new(&g, &rule.weights);
                (
                    Tab::Real {
                        g,
                        d: sm.values,
                        rows,
                    },
                    sm.sigma,
                )
            }
            MisfitKind::Bromwich => {
                let s: Vec<Complex64> = rule
                    .nodes
                    .iter()
                    .map(|&om| Complex64::new(spec.sigma, om))
                    .collect();
                let g = GreenTable::new(&chain, &s)?;
                let sm = data.sample(&s)?;
                (Tab::Complex { g, d: sm.values }, sm.sigma)
            }
            MisfitKind::Time => return Err(time_has_no_rule()),
        };
        Ok(Misfit {
            spec: spec.clone(),
            w: rule.weights.clone(),
            rule,
            chain,
            data: data.clone(),
            sigma,
            tab,
        })
    }

    /// The chi-square of mass defects against Laplace values given at fixed
    /// nodes (`data` from [`Data::at_nodes`]): `sum_q |X_1(s_q) - d_q|^2 /
    /// sigma_q^2`, on the same tables and kernels as the paper's residual.
    /// The data-first fit takes it for mass defects when the unknowns allow
    /// ([`crate::detect::fit`]).
    ///
    /// # Errors
    /// `data` not given at nodes (field `data`); nodes mixing real and
    /// complex values are tabled as complex; as [`Misfit::new`].
    pub fn at_nodes(model: &Chain, data: &Data) -> Result<Misfit> {
        model.require_fixed_ends("the mass-only Woodbury kernel")?;
        model.require_grounded("the mass-only Woodbury kernel")?;
        model.require_uniform("the mass-only Woodbury kernel")?;
        let (s, values, sigma) = match data.source() {
            crate::detect::data::exact::Source::Values { s, values, sigma } => (s, values, sigma),
            _ => {
                return Err(Error::invalid(
                    "data",
                    "not values at nodes",
                    "Laplace values at given nodes (Data::at_nodes)",
                ))
            }
        };
        let chain = model.uniform();
        let real = s.iter().chain(values.iter()).all(|z| z.im == 0.0);
        let w: Vec<f64> = sigma.iter().map(|e| 1.0 / (e * e)).collect();
        let coord: Vec<f64> = s.iter().map(|z| if real { z.re } else { z.im }).collect();
        let (lo, hi) = coord
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
                (a.min(v), b.max(v))
            });
        let rule = Rule {
            name: format!("{} given nodes", s.len()),
            nodes: coord,
            weights: w.clone(),
            a: lo,
            b: hi,
        };
        let tab = if real {
            let nodes: Vec<f64> = s.iter().map(|z| z.re).collect();
            let g = GreenTable::new(&chain, &nodes)?;
            let rows = Rows::new(&g, &w);
            Tab::Real {
                g,
                d: values.iter().map(|z| z.re).collect(),
                rows,
            }
        } else {
            Tab::Complex {
                g: GreenTable::new(&chain, s)?,
                d: values.clone(),
            }
        };
        Ok(Misfit {
            spec: MisfitSpec {
                kind: if real {
                    MisfitKind::RealAxis
                } else {
                    MisfitKind::Bromwich
                },
                ..MisfitSpec::default()
            },
            rule,
            chain,
            data: data.clone(),
            w,
            sigma: sigma.clone(),
            tab,
        })
    }

    /// The spec.
    pub fn spec(&self) -> &MisfitSpec {
        &self.spec
    }

    /// The rule (nodes in the integration variable).
    pub fn rule(&self) -> &Rule {
        &self.rule
    }

    /// Number of nodes.
    pub fn nodes(&self) -> usize {
        self.rule.len()
    }

    /// The uniform model chain.
    pub fn chain(&self) -> &Chain {
        &self.chain
    }

    /// The data.
    pub fn data(&self) -> &Data {
        &self.data
    }

    /// `sum_q w_q sigma_q^2`: the expected residual at the truth caused by
    /// the data's error (rounding and noise). Residual gaps below it are not
    /// resolved by these data.
    pub fn floor(&self) -> f64 {
        self.w.iter().zip(&self.sigma).map(|(w, s)| w * s * s).sum()
    }

    /// Gather the Green's entries of the position set `positions` (1-based,
    /// distinct, in `1..=n`; checked by debug asserts only). One or two
    /// defects on the real axis are folded (per node a ratio of bilinear forms
    /// in the mass changes, precomputed here); other sets keep the entries
    /// for the per-node `k x k` solves.
    pub fn set(&self, positions: &[usize]) -> SetTable {
        match &self.tab {
            Tab::Real { g, d, rows } if matches!(positions.len(), 1 | 2) => SetTable {
                body: Body::Folded(Folded::new(
                    g,
                    rows.as_ref(),
                    d,
                    &self.w,
                    positions,
                    self.chain.gamma(),
                )),
                obs: positions.iter().position(|&p| p == 1),
                gamma: self.chain.gamma(),
            },
            _ => self.set_general(positions),
        }
    }

    /// [`Misfit::set`] without the folded form: the general path (per node a
    /// pivoted `k x k` solve) for every set, the reference of the folded
    /// kernels in tests and benches.
    pub fn set_general(&self, positions: &[usize]) -> SetTable {
        let obs = positions.iter().position(|&p| p == 1);
        let gamma = self.chain.gamma();
        match &self.tab {
            Tab::Real { g, d, .. } => {
                let s2: Vec<f64> = g.s().iter().map(|s| s * s).collect();
                SetTable {
                    body: Body::Real(Gathered::new(g, &s2, d, &self.w, positions)),
                    obs,
                    gamma,
                }
            }
            Tab::Complex { g, d } => {
                let s2: Vec<Complex64> = g.s().iter().map(|s| s * s).collect();
                SetTable {
                    body: Body::Complex(Gathered::new(g, &s2, d, &self.w, positions)),
                    obs,
                    gamma,
                }
            }
        }
    }

    /// `r` for mass defects `(position, mass)` (positions distinct in `1..=n`).
    pub fn residual(&self, defects: &[(usize, f64)]) -> f64 {
        let pos: Vec<usize> = defects.iter().map(|d| d.0).collect();
        let dm: Vec<f64> = defects.iter().map(|d| d.1 - self.chain.mass()).collect();
        self.set(&pos).residual(&dm)
    }

    /// The same residual integrated by the adaptive reference against the
    /// noiseless data (the model evaluated afresh at every `s`).
    ///
    /// The integrand `|X - X*|^2` is known only to about `8 eps |X| |X - X*|`
    /// (each `X` to a few ulps), so its integral only to about
    /// `8 eps sqrt(r int |X*|^2)` (Cauchy-Schwarz); the absolute tolerance is
    /// raised to that floor when `adaptive.abs_tol` is below it (for the
    /// paper's System 3 runner-up, `r = 1.4e-13`, the floor is `6e-22`, a
    /// relative `4e-9`: no f64 quadrature of this integrand does better).
    ///
    /// # Errors
    /// Positions out of range; the adaptive rule not reaching its tolerance.
    pub fn reference(
        &self,
        defects: &[(usize, f64)],
        adaptive: &Adaptive,
    ) -> Result<AdaptiveOutput> {
        let c = &self.chain;
        for (i, &(at, m)) in defects.iter().enumerate() {
            if at == 0 || at > c.n() {
                return Err(Error::invalid(
                    format!("defects[{i}].at"),
                    at,
                    format!("1 <= at <= {}", c.n()),
                ));
            }
            if !(m.is_finite() && m > 0.0) {
                return Err(Error::invalid(
                    format!("defects[{i}].m"),
                    m,
                    "> 0 and finite",
                ));
            }
        }
        let x2: f64 = match &self.tab {
            Tab::Real { d, .. } => d.iter().zip(&self.w).map(|(d, w)| w * d * d).sum(),
            Tab::Complex { d, .. } => d.iter().zip(&self.w).map(|(d, w)| w * d.norm_sqr()).sum(),
        };
        let floor = 8.0 * f64::EPSILON * (self.residual(defects).max(0.0) * x2).sqrt();
        let adaptive = &Adaptive {
            abs_tol: adaptive.abs_tol.max(floor),
            ..adaptive.clone()
        };
        let updates: Vec<Update> = defects
            .iter()
            .map(|&(at, m)| Update {
                probe: Probe::Point(at),
                dm: m - c.mass(),
                dd: 0.0,
                dk: 0.0,
            })
            .collect();
        match self.spec.kind {
            MisfitKind::RealAxis => {
                let f = |s: f64| {
                    let g = Green::new(c.n(), c.k(), c.mass(), c.d(), s);
                    let x = woodbury(&g, &s, &updates, c.gamma(), 1);
                    let d = self.data.value(s).unwrap_or(f64::NAN);
                    (x - d) * (x - d)
                };
                adaptive.integrate(f, 0.0, self.spec.s_max)
            }
            MisfitKind::Bromwich => {
                let f = |om: f64| {
                    let s = Complex64::new(self.spec.sigma, om);
                    let g = Green::new(c.n(), c.k(), c.mass(), c.d(), s);
                    let x = woodbury(&g, &s, &updates, c.gamma(), 1);
                    let d = self.data.value(s).unwrap_or(Complex64::new(f64::NAN, 0.0));
                    (x - d).norm_sqr()
                };
                adaptive.integrate(f, 0.0, self.spec.omega_max)
            }
            MisfitKind::Time => Err(time_has_no_rule()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::chain::Defect;
    use crate::forward::response;

    fn chain_with(n: usize, defs: &[(usize, f64)]) -> Chain {
        Chain::paper(n)
            .unwrap()
            .with_defects(defs.iter().map(|&(at, m)| Defect::Mass { at, m }))
            .unwrap()
    }

    /// `sum_q w_q |X_1(s_q) - X_1*(s_q)|^2` of `model` against `truth` by the
    /// forward model, on the rule of `mis`, the node `s_q = at(x_q)`.
    fn direct<T: Num + crate::scalar::Scalar>(
        mis: &Misfit,
        model: &Chain,
        truth: &Chain,
        at: impl Fn(f64) -> T,
    ) -> f64 {
        let rule = mis.rule();
        rule.nodes
            .iter()
            .zip(&rule.weights)
            .map(|(&x, &w)| {
                let s = at(x);
                w * (response(model, s, 1).unwrap() - response(truth, s, 1).unwrap()).norm2()
            })
            .sum()
    }

    #[test]
    fn kernels_agree_with_forward_model() {
        // residual against data = 0 gives sum w X^2: compare with the forward model
        let truth = chain_with(12, &[(4, 2.0)]);
        let spec = MisfitSpec::real_axis(6, 5);
        let mis = Misfit::new(&truth.uniform(), &Data::exact(&truth), &spec).unwrap();
        for defs in [
            vec![(1usize, 3.0)],
            vec![(5, 0.3)],
            vec![(2, 4.0), (9, 0.7)],
            vec![(1, 4.0), (9, 0.7)],
            vec![(9, 0.7), (1, 4.0)],
            vec![(3, 2.0), (7, 5.0), (12, 0.2)],
        ] {
            let model = chain_with(12, &defs);
            let direct = direct(&mis, &model, &truth, |s| s);
            let pos: Vec<usize> = defs.iter().map(|d| d.0).collect();
            let dm: Vec<f64> = defs.iter().map(|d| d.1 - 1.0).collect();
            let set = mis.set(&pos);
            assert_eq!(set.is_folded(), pos.len() <= 2);
            let fast = set.residual(&dm);
            let gen = mis.set_general(&pos).residual(&dm);
            let (gn, _, _) = pieces(&set, &dm);
            for v in [fast, gen, gn, mis.residual(&defs)] {
                assert!(
                    (v - direct).abs() <= 1e-12 * direct,
                    "{defs:?}: {v} vs {direct}"
                );
            }
        }
    }

    /// `(r, grad, hess)` of a set at `dm` by [`SetTable::gauss_newton`].
    fn pieces(set: &SetTable, dm: &[f64]) -> (f64, Vec<f64>, Vec<f64>) {
        let k = dm.len();
        let (mut g, mut h) = (vec![0.0; k], vec![0.0; k * k]);
        let r = set.gauss_newton(dm, &mut g, &mut h);
        (r, g, h)
    }

    #[test]
    fn folded_equals_general_path() {
        use rand::{Rng, SeedableRng};
        use rand_chacha::ChaCha8Rng;
        let mut rng = ChaCha8Rng::seed_from_u64(13);
        // the paper's System 3 on the default rule, and a chain with another
        // gamma, damping and spring constant on a coarser rule
        let s3 = chain_with(20, &[(8, 5.0), (15, 2.0)]);
        let other = Chain::new(9)
            .and_then(|c| c.with_k(2.5))
            .and_then(|c| c.with_d(0.7))
            .and_then(|c| c.with_gamma(-1.7))
            .unwrap()
            .with_defects(crate::scenes::defects("mass:1:3.0 mass:6:0.4").unwrap())
            .unwrap();
        let mut compared = 0;
        for (truth, spec) in [
            (s3, MisfitSpec::default()),
            (other, MisfitSpec::real_axis(6, 6)),
        ] {
            let n = truth.n();
            let mis = Misfit::new(&truth.uniform(), &Data::exact(&truth), &spec).unwrap();
            for trial in 0..400 {
                let k = 1 + trial % 2;
                let a = rng.random_range(1..=n);
                let pos = if k == 1 {
                    vec![a]
                } else {
                    let mut b = rng.random_range(1..=n);
                    while b == a {
                        b = rng.random_range(1..=n);
                    }
                    vec![a, b]
                };
                // masses log-uniform in [1e-2, 1e3] (below, the conditioning
                // ~ 1 / m of both paths takes more digits than 1e-12 leaves)
                let dm: Vec<f64> = (0..k)
                    .map(|_| 10f64.powf(rng.random_range(-2.0..3.0)) - 1.0)
                    .collect();
                let set = mis.set(&pos);
                let gen = mis.set_general(&pos);
                assert!(set.is_folded() && !gen.is_folded());
                let (rf, gf, hf) = pieces(&set, &dm);
                let (rg, gg, hg) = pieces(&gen, &dm);
                let tag = format!("{pos:?} {dm:?}");
                assert!((rf - rg).abs() <= 1e-12 * rg, "{tag}: r {rf} vs {rg}");
                // the same sum over other accumulators (and X by a reciprocal)
                assert!(
                    (set.residual(&dm) - rf).abs() <= 1e-12 * rf,
                    "{tag}: {} vs {rf} vs {rg}",
                    set.residual(&dm)
                );
                for l in 0..k {
                    // |grad_l| <= sqrt(r hess_ll) (Cauchy-Schwarz) bounds the
                    // cancellation of the gradient's sum
                    let scale = (rg * hg[l * k + l]).sqrt();
                    assert!(
                        (gf[l] - gg[l]).abs() <= 1e-12 * scale,
                        "{tag}: grad {l} {} {} {scale}",
                        gf[l],
                        gg[l]
                    );
                    for m in 0..k {
                        let scale = (hg[l * k + l] * hg[m * k + m]).sqrt();
                        let (x, y) = (hf[l * k + m], hg[l * k + m]);
                        assert!((x - y).abs() <= 1e-12 * scale, "{tag}: hess {l}{m}");
                    }
                }
                compared += 1;
            }
            // near and at the truth (the observed mass 1 among the positions
            // of the second chain)
            let defs: Vec<(usize, f64)> = truth
                .defects()
                .iter()
                .map(|d| match d {
                    Defect::Mass { at, m } => (*at, *m),
                    _ => unreachable!(),
                })
                .collect();
            let pos = [defs[0].0, defs[1].0];
            // there `r` is known only to about `eps sqrt(r x2)` (each `X` to a
            // few ulps, as the data): both paths within that of each other
            let x2: f64 = match &mis.tab {
                Tab::Real { d, .. } => d.iter().zip(&mis.w).map(|(d, w)| w * d * d).sum(),
                Tab::Complex { .. } => unreachable!(),
            };
            let ulps = 16.0 * f64::EPSILON;
            for rel in [0.0, 1e-9, 1e-6, 1e-3] {
                let dm = [defs[0].1 * (1.0 + rel) - 1.0, defs[1].1 * (1.0 - rel) - 1.0];
                let (rf, gf, hf) = pieces(&mis.set(&pos), &dm);
                let (rg, gg, hg) = pieces(&mis.set_general(&pos), &dm);
                let tol = 1e-12 * rg + ulps * (rg * x2).sqrt();
                assert!((rf - rg).abs() <= tol, "{rel}: {rf} vs {rg}");
                if rel == 0.0 {
                    assert!(rf <= 1e-28 && rg <= 1e-28, "{rf} {rg}");
                }
                for l in 0..2 {
                    let h = hg[3 * l];
                    let tol = 1e-12 * (rg * h).sqrt() + ulps * (h * x2).sqrt();
                    assert!((gf[l] - gg[l]).abs() <= tol, "{rel}: grad {l}");
                }
                for i in 0..4 {
                    assert!((hf[i] - hg[i]).abs() <= 1e-12 * (hg[0] * hg[3]).sqrt());
                }
            }
        }
        assert_eq!(compared, 800);
    }

    #[test]
    fn folded_never_nan_near_singular_capacitance() {
        let truth = chain_with(10, &[(3, 3.0), (7, 2.0)]);
        let mis = Misfit::new(
            &truth.uniform(),
            &Data::exact(&truth),
            &MisfitSpec::default(),
        )
        .unwrap();
        for pos in [vec![3], vec![1], vec![3, 7], vec![1, 7], vec![7, 1]] {
            let set = mis.set(&pos);
            // each node's denominator vanishes at dm = -1 / D1 (the other mass
            // unchanged): an infinite residual, reported as f64::MAX
            let mut singular = vec![-1.0, -1.0 - 1e-12, -2.0, -1e300, f64::INFINITY, f64::NAN];
            singular.extend(set.folded_poles().expect("not folded"));
            for dm1 in singular {
                let mut dm = vec![dm1; pos.len()];
                if pos.len() == 2 {
                    dm[1] = 0.0;
                }
                let r = set.residual(&dm);
                let (rg, _, _) = pieces(&set, &dm);
                assert!(!r.is_nan() && r >= 0.0, "{pos:?} {dm1}: {r}");
                assert!(!rg.is_nan() && rg >= 0.0, "{pos:?} {dm1}: {rg}");
                if dm1.is_nan() || dm1.is_infinite() {
                    assert_eq!(r, f64::MAX);
                }
            }
        }
    }

    #[test]
    fn linearized_start_is_exact_for_the_sets_own_model() {
        // noiseless data of the set's own model: the linearised equations
        // hold exactly, their solution is the truth (to rounding)
        for (defs, pos) in [
            (vec![(3, 2.5), (7, 0.4)], vec![3, 7]),
            (vec![(1, 4.0), (12, 1.5)], vec![1, 12]),
            (vec![(6, 0.3)], vec![6]),
        ] {
            let truth = chain_with(12, &defs);
            let mis = Misfit::new(
                &truth.uniform(),
                &Data::exact(&truth),
                &MisfitSpec::default(),
            )
            .unwrap();
            let x = mis.set(&pos).linearized().unwrap();
            for (l, &(_, m)) in defs.iter().enumerate() {
                assert!((x[l] - (m - 1.0)).abs() < 1e-6 * m, "{defs:?}: {x:?}");
            }
            if defs.len() == 1 {
                assert_eq!(x[1], 0.0);
            }
            // a wrong set: a finite start; the general path has none
            assert!(mis.set(&[2, 9]).linearized().is_some());
            assert!(mis.set(&[2, 5, 9]).linearized().is_none());
            assert!(mis.set_general(&pos).linearized().is_none());
        }
    }

    #[test]
    fn jacobian_matches_finite_differences() {
        for kind in [MisfitKind::RealAxis, MisfitKind::Bromwich] {
            let truth = chain_with(10, &[(3, 3.0), (7, 2.0)]);
            let spec = MisfitSpec {
                kind,
                panels: Some(8),
                ..MisfitSpec::default()
            };
            let mis = Misfit::new(&truth.uniform(), &Data::exact(&truth), &spec).unwrap();
            let set = mis.set(&[3, 6]);
            let dm = [1.7, 0.4];
            let (mut g, mut h) = ([0.0; 2], [0.0; 4]);
            set.gauss_newton(&dm, &mut g, &mut h);
            for l in 0..2 {
                let hstep = 1e-6;
                let mut p = dm;
                p[l] += hstep;
                let mut m = dm;
                m[l] -= hstep;
                let fd = (set.residual(&p) - set.residual(&m)) / (2.0 * hstep);
                // d r / d m = 2 grad
                assert!(
                    (fd - 2.0 * g[l]).abs() <= 1e-6 * fd.abs(),
                    "{kind:?} {l}: {fd} vs {}",
                    2.0 * g[l]
                );
            }
            assert!(h[1] == h[2] && h[0] > 0.0 && h[0] * h[3] >= h[1] * h[1]);
        }
    }

    #[test]
    fn bromwich_matches_complex_forward() {
        let truth = chain_with(8, &[(2, 3.0), (6, 0.5)]);
        let spec = MisfitSpec {
            kind: MisfitKind::Bromwich,
            panels: Some(10),
            ..MisfitSpec::default()
        };
        let mis = Misfit::new(&truth.uniform(), &Data::exact(&truth), &spec).unwrap();
        let model = chain_with(8, &[(3, 3.0), (6, 0.5)]);
        let direct = direct(&mis, &model, &truth, |om| Complex64::new(0.1, om));
        let r = mis.residual(&[(3, 3.0), (6, 0.5)]);
        assert!((r - direct).abs() <= 1e-12 * direct);
        assert!(mis.residual(&[(2, 3.0), (6, 0.5)]) < 1e-25);
    }

    #[test]
    fn never_nan() {
        let truth = chain_with(6, &[(2, 3.0)]);
        let mis = Misfit::new(
            &truth.uniform(),
            &Data::exact(&truth),
            &MisfitSpec::default(),
        )
        .unwrap();
        for dm in [-1.0, -0.999_999, 1e300, f64::INFINITY, f64::NAN] {
            let r = mis.set(&[2]).residual(&[dm]);
            assert!(!r.is_nan(), "{dm}");
            let r = mis.set(&[2, 4]).residual(&[dm, dm]);
            assert!(!r.is_nan(), "{dm}");
        }
    }
}
