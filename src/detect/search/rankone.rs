//! Rank-one scoring of candidate defects and O(n) reciprocity columns: the
//! kernel behind the greedy search (`detect::fit::greedy`) and
//! of the whole-profile inversion to come (issue 14).
//!
//! # Columns by excess stiffness (O(n) per node, any profile)
//!
//! For a chain with masses `m_i`, dampers `d_i` and springs `kappa_j`
//! (`kappa_0`, `kappa_n` the wall springs, 0 at a free end), with
//! `l_i = m_i s^2 + d_i s`, the excess stiffnesses seen from the right and
//! from the left obey (as in [`crate::sensitivity::green_column`])
//!
//! `t^R_i = kappa_i E^R_{i+1} / (E^R_{i+1} + kappa_i)`, `E^R_i = l_i + t^R_i`,
//! `t^L_i = kappa_{i-1} E^L_{i-1} / (E^L_{i-1} + kappa_{i-1})`, `E^L_i = l_i + t^L_i`,
//!
//! and then, with no subtraction anywhere,
//!
//! * `G_ii = 1 / (l_i + t^R_i + t^L_i)` (every diagonal entry),
//! * `G_{i+1,1} = G_{i1} kappa_i / (E^R_{i+1} + kappa_i)` (the column `G e_1`),
//! * spring `j` (`u = e_j - e_{j+1}`): `u^T G e_1 = G_{1j} E^R_{j+1} / (E^R_{j+1} + kappa_j)`
//!   and `u^T G u = c / (1 + kappa_j c)`, `c = 1/E^L_j + 1/E^R_{j+1}` (the
//!   two halves the spring joins, in series).
//!
//! [`Sweep`] holds these for one chain at every node of the data: O(n Q)
//! memory, never an `n x n` matrix.
//!
//! # Rank-one update (Sherman-Morrison)
//!
//! A defect that changes one value by `delta` adds `c u u^T` to the dynamic
//! stiffness, `c = delta s^2` (mass), `delta s` (damper) or `delta` (spring),
//! so with `a = u^T G e_1` and `b = u^T G u` of the *current* chain
//!
//! `X_1' = X_1 - gamma c a^2 / (1 + c b)`,  `dX_1'/d delta = -gamma kappa a^2 / (1 + c b)^2`
//!
//! (`X_1' = gamma b / (1 + c b)` when `u = +-e_1`, without cancellation).
//! [`score`] fits `delta` for every candidate this way: a log-spaced grid
//! over the value's bounds (12 points by default) for every candidate, then
//! a bounded one-dimensional Gauss-Newton from the best grid point for the
//! `polish` best (64 by default), at O(Q) per evaluation (O(Q K) with a
//! whitening matrix of `K` rows).
//!
//! ```
//! use springmass::{Chain, Complex64, Defect};
//! use springmass::detect::data::laplace::LaplaceObs;
//! use springmass::detect::search::rankone::{score, ScoreOptions, Sweep, Target};
//! use springmass::detect::unknowns::DefectKind;
//! let truth = Chain::paper(30)?.with_d(0.1)?.with_defect(Defect::Mass { at: 17, m: 2.5 })?;
//! let s: Vec<Complex64> = (0..40).map(|q| Complex64::new(0.05, 0.1 * q as f64)).collect();
//! let obs = LaplaceObs::exact(&truth, s.clone(), vec![1.0; 40])?;
//! let target = Target::new(&obs);
//! let sweep = Sweep::new(&truth.uniform(), &s, &[DefectKind::Mass])?;
//! let scored = score(&sweep, &target, &[], &ScoreOptions::default(), true);
//! assert_eq!((scored[0].kind, scored[0].at), (DefectKind::Mass, 17));
//! assert!((scored[0].value - 2.5).abs() < 1e-8);
//! # Ok::<(), springmass::Error>(())
//! ```

use crate::chain::{Chain, Defect, Probe};
use crate::detect::data::laplace::LaplaceObs;
use crate::detect::data::whitener::Whitener;
use crate::detect::unknowns::{DefectKind, KindBounds};
use crate::error::{Error, Result};
use nalgebra::DMatrix;
use num_complex::Complex64 as C;

/// Every mass, damper and spring of a chain, as plain arrays (no defect
/// list: a profile with every value free is one of these).
#[derive(Clone, Debug, PartialEq)]
pub struct Profile {
    /// `m_1..m_n` (index `i - 1`).
    pub masses: Vec<f64>,
    /// `d_1..d_n`.
    pub dampers: Vec<f64>,
    /// `kappa_0..kappa_n` (`kappa_j` joins masses `j` and `j + 1`; 0 at a free end).
    pub springs: Vec<f64>,
    /// `g_1..g_n`, the stiffness to the ground besides the springs (zero in
    /// the uniform chain).
    pub grounds: Vec<f64>,
    /// Impulse on mass 1.
    pub gamma: f64,
}

impl Profile {
    /// The arrays of `chain` (its defects applied).
    pub fn of_chain(chain: &Chain) -> Profile {
        Profile {
            masses: chain.masses(),
            dampers: chain.dampers(),
            springs: chain.springs(),
            grounds: chain.grounds(),
            gamma: chain.gamma(),
        }
    }

    /// Number of masses.
    pub fn n(&self) -> usize {
        self.masses.len()
    }
}

/// The excess stiffnesses and the column `G e_1` of one profile at one `s`.
#[derive(Clone, Debug)]
pub struct Column {
    /// `G_{j1}`, `j = 1..=n` (index `j - 1`).
    pub g1: Vec<C>,
    /// `E^R_j`.
    pub er: Vec<C>,
    /// `E^L_j`.
    pub el: Vec<C>,
    /// `l_j = m_j s^2 + d_j s + g_j`.
    pub local: Vec<C>,
}

impl Column {
    /// Sweep `p` at `s` (module docs). `None` at a pole (a pivot that vanishes
    /// or a non-finite entry).
    pub fn new(p: &Profile, s: C) -> Option<Column> {
        let n = p.n();
        let kap = &p.springs;
        let s2 = s * s;
        let local: Vec<C> = (0..n)
            .map(|i| s2 * p.masses[i] + s * p.dampers[i] + p.grounds[i])
            .collect();
        let mut er = vec![C::new(0.0, 0.0); n];
        for i in (0..n).rev() {
            let t = if i + 1 == n {
                C::new(kap[n], 0.0)
            } else {
                er[i + 1] * kap[i + 1] / (er[i + 1] + kap[i + 1])
            };
            er[i] = local[i] + t;
        }
        let mut el = vec![C::new(0.0, 0.0); n];
        for i in 0..n {
            let t = if i == 0 {
                C::new(kap[0], 0.0)
            } else {
                el[i - 1] * kap[i] / (el[i - 1] + kap[i])
            };
            el[i] = local[i] + t;
        }
        let mut g1 = vec![C::new(0.0, 0.0); n];
        // G_11 = 1 / (l_1 + t^R_1 + t^L_1) = 1 / (E^R_1 + E^L_1 - l_1)
        g1[0] = C::new(1.0, 0.0) / (er[0] + (el[0] - local[0]));
        for i in 1..n {
            g1[i] = g1[i - 1] * kap[i] / (er[i] + kap[i]);
        }
        let ok = g1.iter().chain(&er).chain(&el).all(|z| z.is_finite());
        ok.then_some(Column { g1, er, el, local })
    }

    /// `G_jj` (1-based `j`).
    pub fn diag(&self, j: usize) -> C {
        let i = j - 1;
        C::new(1.0, 0.0) / (self.er[i] + self.el[i] - self.local[i])
    }

    /// `(a, b) = (u^T G e_1, u^T G u)` of the probe of `kind` at `at`
    /// (a point site: `u = e_at`; a spring-like site `at` joins `at` and `at + 1`).
    pub fn probe(&self, p: &Profile, kind: DefectKind, at: usize) -> (C, C) {
        let n = p.n();
        match kind.site(at).probe {
            Probe::Point(_) => (self.g1[at - 1], self.diag(at)),
            Probe::Diff(_) => {
                if at == 0 {
                    let b = self.diag(1);
                    (-b, b)
                } else if at == n {
                    (self.g1[n - 1], self.diag(n))
                } else {
                    let kj = p.springs[at];
                    let (l, r) = (at - 1, at);
                    let a = self.g1[l] * self.er[r] / (self.er[r] + kj);
                    let c = C::new(1.0, 0.0) / self.el[l] + C::new(1.0, 0.0) / self.er[r];
                    (a, c / (c * kj + 1.0))
                }
            }
        }
    }
}

/// The coefficient `kappa(s) = s^power` of a kind: `c = delta kappa(s)`.
pub fn kind_factor(kind: DefectKind, s: C) -> C {
    match kind.site(1).power {
        0 => C::new(1.0, 0.0),
        1 => s,
        _ => s * s,
    }
}

/// Is the probe `+-e_1` (then `X_1' = gamma b / (1 + c b)`)?
fn probe_is_e1(kind: DefectKind, at: usize) -> bool {
    matches!(kind.site(at).probe, Probe::Point(1) | Probe::Diff(0))
}

/// The data side of a Laplace least-squares problem: nodes, values, and
/// either per-node weights or a whitening matrix, as in [`LaplaceObs`]; maps
/// model values at the nodes to whitened residuals.
#[derive(Clone, Debug)]
pub struct Target {
    s: Vec<C>,
    d: Vec<C>,
    sw: Vec<f64>,
    w: Option<Whitener>,
    rows: Vec<(usize, bool)>,
}

impl Target {
    /// The target of `obs`.
    pub fn new(obs: &LaplaceObs) -> Target {
        let s = obs.nodes().to_vec();
        // the row order of LaplaceObs::residuals: stacked when whitened,
        // node by node (Re, then Im of a complex node) otherwise
        let rows = if obs.whitening().is_some() {
            crate::time::series::stacked_rows(&s)
        } else {
            s.iter()
                .enumerate()
                .flat_map(|(q, z)| {
                    std::iter::once((q, false)).chain((z.im != 0.0).then_some((q, true)))
                })
                .collect()
        };
        Target {
            d: obs.values().to_vec(),
            sw: obs.weights().iter().map(|w| w.sqrt()).collect(),
            w: obs.whitener().cloned(),
            rows,
            s,
        }
    }

    /// The nodes.
    pub fn nodes(&self) -> &[C] {
        &self.s
    }

    /// Number of whitened residuals.
    pub fn m(&self) -> usize {
        match &self.w {
            Some(w) => w.rows(),
            None => self.rows.len(),
        }
    }

    /// Number of stacked (unwhitened) real rows.
    pub fn stacked(&self) -> usize {
        self.rows.len()
    }

    /// The whitened image of per-node complex values `z` (no data
    /// subtracted): `sqrt(w_q) [Re z; Im z]` or `W [Re z; Im z]`, into `out`
    /// (length [`Target::m`]); `tmp` is scratch of length [`Target::stacked`].
    pub fn apply(&self, z: &[C], tmp: &mut [f64], out: &mut [f64]) {
        match &self.w {
            None => {
                for (o, &(q, im)) in out.iter_mut().zip(&self.rows) {
                    *o = self.sw[q] * if im { z[q].im } else { z[q].re };
                }
            }
            Some(w) => {
                for (t, &(q, im)) in tmp.iter_mut().zip(&self.rows) {
                    *t = if im { z[q].im } else { z[q].re };
                }
                // out = W tmp: the register-blocked product, the same sums in
                // the same order as column by column
                w.apply_into(tmp, 1, out);
            }
        }
    }

    /// Whitened residuals of model values `x` at the nodes.
    pub fn residuals(&self, x: &[C]) -> Vec<f64> {
        let diff: Vec<C> = x.iter().zip(&self.d).map(|(a, b)| a - b).collect();
        let mut tmp = vec![0.0; self.stacked()];
        let mut out = vec![0.0; self.m()];
        self.apply(&diff, &mut tmp, &mut out);
        out
    }
}

/// `X_1` and, per kind and position, the `(a, b)` of every probe at one node.
type NodeProbes = (C, Vec<Vec<(C, C)>>);

/// The columns of one chain at every node, and the `(a, b)` of every
/// candidate probe, laid out candidate by candidate.
#[derive(Clone, Debug)]
pub struct Sweep {
    profile: Profile,
    /// `X_1` at every node.
    x: Vec<C>,
    kinds: Vec<DefectKind>,
    /// Per kind: `(a, b)` at `[pos_index * Q + q]`.
    ab: Vec<Vec<(C, C)>>,
    /// Per kind: the positions probed.
    positions: Vec<Vec<usize>>,
    /// Per kind: the uniform value of the chain (current value at a position without a defect of that kind).
    uniform: Vec<f64>,
}

impl Sweep {
    /// Sweep `chain` at the nodes `s`, with the probes of `kinds`.
    ///
    /// # Errors
    /// [`Error::Singular`] at a node where the chain has a pole.
    pub fn new(chain: &Chain, s: &[C], kinds: &[DefectKind]) -> Result<Sweep> {
        chain.require_grounded("the greedy search's rank-one scores")?;
        chain.require_uniform("the greedy search's rank-one scores (use --method enumerate)")?;
        let profile = Profile::of_chain(chain);
        let (lo, hi) = chain.spring_range();
        let positions: Vec<Vec<usize>> = kinds
            .iter()
            .map(|k| match k.site(1).probe {
                Probe::Diff(_) => (lo..=hi).collect(),
                Probe::Point(_) => (1..=chain.n()).collect(),
            })
            .collect();
        let uniform = kinds.iter().map(|k| k.uniform(chain)).collect();
        Self::build(profile, s, kinds, positions, uniform)
    }

    fn build(
        profile: Profile,
        s: &[C],
        kinds: &[DefectKind],
        positions: Vec<Vec<usize>>,
        uniform: Vec<f64>,
    ) -> Result<Sweep> {
        let q = s.len();
        // per node: X_1 and the (a, b) of every probe (node-major)
        let per_node: Vec<Option<NodeProbes>> =
            crate::detect::search::parallel::map(s, true, 2, |&z| {
                let col = Column::new(&profile, z)?;
                let x = col.g1[0] * profile.gamma;
                let ab = kinds
                    .iter()
                    .zip(&positions)
                    .map(|(&k, pos)| pos.iter().map(|&at| col.probe(&profile, k, at)).collect())
                    .collect();
                Some((x, ab))
            });
        let mut x = Vec::with_capacity(q);
        let mut nodes = Vec::with_capacity(q);
        for (qi, v) in per_node.into_iter().enumerate() {
            match v {
                Some((xv, ab)) => {
                    x.push(xv);
                    nodes.push(ab);
                }
                None => {
                    return Err(Error::Singular {
                        s: format!("{}", s[qi]),
                    })
                }
            }
        }
        // transpose to candidate-major
        let ab: Vec<Vec<(C, C)>> = (0..kinds.len())
            .map(|ki| {
                let np = positions[ki].len();
                let mut v = vec![(C::new(0.0, 0.0), C::new(0.0, 0.0)); np * q];
                for (pi, chunk) in v.chunks_mut(q).enumerate() {
                    for (qi, slot) in chunk.iter_mut().enumerate() {
                        *slot = nodes[qi][ki][pi];
                    }
                }
                v
            })
            .collect();
        Ok(Sweep {
            profile,
            x,
            kinds: kinds.to_vec(),
            ab,
            positions,
            uniform,
        })
    }

    /// `X_1` of the swept chain at every node.
    pub fn x(&self) -> &[C] {
        &self.x
    }

    /// The swept profile.
    pub fn profile(&self) -> &Profile {
        &self.profile
    }
}

/// Options of [`score`].
#[derive(Clone, Debug, PartialEq)]
pub struct ScoreOptions {
    /// Value bounds per kind (default [`KindBounds::default`]).
    pub bounds: KindBounds,
    /// Grid points over each value range before the Gauss-Newton polish (default 12).
    pub grid: usize,
    /// Gauss-Newton iterations of the polish (default 20).
    pub max_iter: usize,
    /// Candidates polished: the best by their grid chi-square (default 64;
    /// the others keep their best grid value).
    pub polish: usize,
}

impl Default for ScoreOptions {
    fn default() -> Self {
        ScoreOptions {
            bounds: KindBounds::default(),
            grid: 12,
            max_iter: 20,
            polish: 64,
        }
    }
}

/// One scored candidate: add a defect of `kind` at `at` with `value` to the
/// swept chain (other values fixed), giving `chi2`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Scored {
    /// Kind of the candidate defect.
    pub kind: DefectKind,
    /// Its position.
    pub at: usize,
    /// Best value found for it.
    pub value: f64,
    /// The chi-square with it added.
    pub chi2: f64,
    /// Rank-one evaluations spent on it.
    pub evaluations: usize,
}

/// Grid values of a range: log-spaced when `lo > 0`, otherwise 0 and
/// log-spaced from `1e-4 hi`.
fn grid_values(lo: f64, hi: f64, g: usize) -> Vec<f64> {
    let g = g.max(2);
    if lo > 0.0 {
        (0..g)
            .map(|i| lo * (hi / lo).powf((i as f64 + 0.5) / g as f64))
            .collect()
    } else {
        let a = 1e-4 * hi;
        std::iter::once(lo.max(0.0))
            .chain((0..g - 1).map(|i| a * (hi / a).powf(i as f64 / (g - 2).max(1) as f64)))
            .collect()
    }
}

/// The distinct probes of `defects` (the columns of the capacitance
/// systems), the column of each defect and the number of free values.
///
/// # Errors
/// As [`SetProblem::new`].
fn probe_columns(chain: &Chain, defects: &[SetDefect]) -> Result<(Vec<Probe>, Vec<usize>, usize)> {
    let n = chain.n();
    let (slo, shi) = chain.spring_range();
    let mut probes: Vec<Probe> = Vec::new();
    let mut col = Vec::with_capacity(defects.len());
    let mut p = 0;
    for (i, d) in defects.iter().enumerate() {
        let (kind, at) = d.kind_at();
        let probe = kind.site(at).probe;
        let ok = match probe {
            Probe::Diff(_) => (slo..=shi).contains(&at),
            Probe::Point(_) => (1..=n).contains(&at),
        };
        if !ok {
            return Err(Error::invalid(
                format!("defects[{i}].at"),
                at,
                "a position of the defect's kind in this chain",
            ));
        }
        if let SetDefect::Free(_, _, j) = *d {
            p = p.max(j + 1);
        }
        let c = match probes.iter().position(|&q| q == probe) {
            Some(c) => c,
            None => {
                probes.push(probe);
                probes.len() - 1
            }
        };
        col.push(c);
    }
    let mut seen = vec![false; p];
    for d in defects {
        if let SetDefect::Free(_, _, j) = *d {
            seen[j] = true;
        }
    }
    if seen.iter().any(|s| !s) {
        return Err(Error::invalid(
            "defects",
            "free indices with gaps",
            "free value indices 0..p, each used",
        ));
    }
    Ok((probes, col, p))
}

/// Per node of `target`, in node order: the capacitance matrix of the
/// probes (`ncol^2`), its right-hand side (`ncol`) and `g11`.
fn node_tables(chain: &Chain, target: &Target, probes: &[Probe]) -> (Vec<C>, Vec<C>, Vec<C>) {
    let ncol = probes.len();
    let src = Probe::Point(1);
    let per: Vec<(Vec<C>, Vec<C>, C)> =
        crate::detect::search::parallel::map(target.nodes(), true, 2, |&z| {
            let g = crate::green::Green::of_chain(chain, z);
            let fs = g.factors(src);
            let fu: Vec<_> = probes.iter().map(|&pr| g.factors(pr)).collect();
            let mut a = vec![C::new(0.0, 0.0); ncol * ncol];
            for l in 0..ncol {
                for m in l..ncol {
                    let v = g.pair(&fu[l], &fu[m]);
                    a[l * ncol + m] = v;
                    a[m * ncol + l] = v;
                }
            }
            let rhs = fu.iter().map(|f| g.pair(f, &fs)).collect();
            (a, rhs, g.pair(&fs, &fs))
        });
    let mut a = Vec::with_capacity(per.len() * ncol * ncol);
    let mut rhs = Vec::with_capacity(per.len() * ncol);
    let mut g11 = Vec::with_capacity(per.len());
    for (pa, pr, g) in per {
        a.extend(pa);
        rhs.extend(pr);
        g11.push(g);
    }
    (a, rhs, g11)
}

/// Score every candidate of `sweep` not in `exclude` against `target`
/// (module docs): the best value of each and the chi-square it gives, best
/// first (ties by position, then kind). Parallel over candidates when
/// `parallel`; the result does not depend on it.
pub fn score(
    sweep: &Sweep,
    target: &Target,
    exclude: &[(DefectKind, usize)],
    opts: &ScoreOptions,
    parallel: bool,
) -> Vec<Scored> {
    let q = target.nodes().len();
    let r0 = target.residuals(&sweep.x);
    let gamma = sweep.profile.gamma;
    let mut jobs: Vec<(usize, usize)> = Vec::new();
    for (ki, pos) in sweep.positions.iter().enumerate() {
        for (pi, &at) in pos.iter().enumerate() {
            if !exclude.contains(&(sweep.kinds[ki], at)) {
                jobs.push((ki, pi));
            }
        }
    }
    let factors: Vec<Vec<C>> = sweep
        .kinds
        .iter()
        .map(|&k| target.nodes().iter().map(|&z| kind_factor(k, z)).collect())
        .collect();
    let cand = |ki: usize, pi: usize| -> Candidate1<'_> {
        let kind = sweep.kinds[ki];
        let at = sweep.positions[ki][pi];
        Candidate1 {
            ab: &sweep.ab[ki][pi * q..(pi + 1) * q],
            kappa: &factors[ki],
            x: &sweep.x,
            gamma,
            e1: probe_is_e1(kind, at),
            uniform: sweep.uniform[ki],
        }
    };
    // grid pass over every candidate
    let grid = |scratch: &mut Scratch, &(ki, pi): &(usize, usize)| -> Scored {
        let kind = sweep.kinds[ki];
        let (lo, hi) = opts.bounds.of(kind);
        let (value, chi2, evaluations) = cand(ki, pi).grid(target, &r0, lo, hi, opts, scratch);
        Scored {
            kind,
            at: sweep.positions[ki][pi],
            value,
            chi2,
            evaluations,
        }
    };
    let mut out = with_scratch(&jobs, parallel, target, grid);
    // polish of the best by grid chi-square
    let mut idx: Vec<usize> = (0..out.len()).collect();
    idx.sort_by(|&a, &b| best_first(&out[a], &out[b]));
    idx.truncate(opts.polish);
    let polish = |scratch: &mut Scratch, &i: &usize| -> Scored {
        let (ki, pi) = jobs[i];
        let mut sc = out[i];
        let (lo, hi) = opts.bounds.of(sc.kind);
        let (v, c, e) = cand(ki, pi).polish(target, &r0, sc.value, sc.chi2, lo, hi, opts, scratch);
        sc.value = v;
        sc.chi2 = c;
        sc.evaluations += e;
        sc
    };
    let polished = with_scratch(&idx, parallel, target, polish);
    for (&i, p) in idx.iter().zip(polished) {
        out[i] = p;
    }
    out.sort_by(best_first);
    out
}

/// `f` on every item with a [`Scratch`] of its thread (one per worker when
/// `parallel`); the results in the order of `items`.
fn with_scratch<I: Sync, F>(items: &[I], parallel: bool, target: &Target, f: F) -> Vec<Scored>
where
    F: Fn(&mut Scratch, &I) -> Scored + Sync + Send,
{
    crate::detect::search::parallel::map_init(items, parallel, 2, || Scratch::new(target), f)
}

/// Scores best first: by chi-square, then position, then kind.
fn best_first(a: &Scored, b: &Scored) -> std::cmp::Ordering {
    a.chi2
        .total_cmp(&b.chi2)
        .then(a.at.cmp(&b.at))
        .then(a.kind.cmp(&b.kind))
}

struct Scratch {
    dz: Vec<C>,
    jz: Vec<C>,
    tmp: Vec<f64>,
    res: Vec<f64>,
    jac: Vec<f64>,
}

impl Scratch {
    fn new(t: &Target) -> Scratch {
        let q = t.nodes().len();
        Scratch {
            dz: vec![C::new(0.0, 0.0); q],
            jz: vec![C::new(0.0, 0.0); q],
            tmp: vec![0.0; t.stacked()],
            res: vec![0.0; t.m()],
            jac: vec![0.0; t.m()],
        }
    }
}

struct Candidate1<'a> {
    ab: &'a [(C, C)],
    kappa: &'a [C],
    x: &'a [C],
    gamma: f64,
    e1: bool,
    uniform: f64,
}

impl Candidate1<'_> {
    /// chi2 at value `v`; with `jac`, the whitened derivative too.
    fn eval(&self, t: &Target, r0: &[f64], v: f64, sc: &mut Scratch, jac: bool) -> f64 {
        let delta = v - self.uniform;
        for q in 0..self.ab.len() {
            let (a, b) = self.ab[q];
            let c = self.kappa[q] * delta;
            let den = c * b + 1.0;
            sc.dz[q] = if self.e1 {
                b * self.gamma / den - self.x[q]
            } else {
                -(c * a * a * self.gamma) / den
            };
            if jac {
                let top = if self.e1 { b * b } else { a * a };
                sc.jz[q] = -(self.kappa[q] * top * self.gamma) / (den * den);
            }
        }
        t.apply(&sc.dz, &mut sc.tmp, &mut sc.res);
        let mut chi2 = 0.0;
        for (r, base) in sc.res.iter_mut().zip(r0) {
            *r += base;
            chi2 += *r * *r;
        }
        if jac {
            t.apply(&sc.jz, &mut sc.tmp, &mut sc.jac);
        }
        if chi2.is_finite() {
            chi2
        } else {
            f64::MAX
        }
    }

    /// Best grid value in `[lo, hi]`: `(value, chi2, evaluations)`.
    fn grid(
        &self,
        t: &Target,
        r0: &[f64],
        lo: f64,
        hi: f64,
        opts: &ScoreOptions,
        sc: &mut Scratch,
    ) -> (f64, f64, usize) {
        let mut evals = 0;
        let mut best = (self.uniform.clamp(lo, hi), f64::MAX);
        for v in grid_values(lo, hi, opts.grid) {
            let c = self.eval(t, r0, v, sc, false);
            evals += 1;
            if c < best.1 {
                best = (v, c);
            }
        }
        (best.0, best.1, evals)
    }

    /// Bounded Gauss-Newton with Levenberg damping from `(v, f)`:
    /// `(value, chi2, evaluations)`.
    #[allow(clippy::too_many_arguments)]
    fn polish(
        &self,
        t: &Target,
        r0: &[f64],
        mut v: f64,
        mut f: f64,
        lo: f64,
        hi: f64,
        opts: &ScoreOptions,
        sc: &mut Scratch,
    ) -> (f64, f64, usize) {
        let mut evals = 0;
        if f >= f64::MAX {
            return (v, f, evals);
        }
        let mut mu = 1e-3;
        let mut it = 0;
        while it < opts.max_iter {
            it += 1;
            let fc = self.eval(t, r0, v, sc, true);
            evals += 1;
            let (mut g, mut h) = (0.0, 0.0);
            for (r, j) in sc.res.iter().zip(&sc.jac) {
                g += r * j;
                h += j * j;
            }
            f = fc;
            if h.is_nan() || h <= 0.0 || !g.is_finite() {
                break;
            }
            let mut accepted = false;
            while mu < 1e12 {
                let trial = (v - g / (h * (1.0 + mu))).clamp(lo, hi);
                if trial == v {
                    break;
                }
                let ft = self.eval(t, r0, trial, sc, false);
                evals += 1;
                if ft < f {
                    let rel_step = ((trial - v) / v.abs().max(1e-12)).abs();
                    let rel_dec = (f - ft) / f.max(1e-300);
                    v = trial;
                    f = ft;
                    mu = (mu / 4.0).max(1e-12);
                    accepted = true;
                    if rel_step < 1e-10 || rel_dec < 1e-14 {
                        return (v, f, evals);
                    }
                    break;
                }
                mu *= 8.0;
            }
            if !accepted {
                break;
            }
        }
        (v, f, evals)
    }
}

/// The model `X_1` of `chain` at the nodes by the sweep (O(n) per node).
///
/// # Errors
/// [`Error::Singular`] at a pole.
pub fn x1(chain: &Chain, s: &[C]) -> Result<Vec<C>> {
    let p = Profile::of_chain(chain);
    s.iter()
        .map(|&z| {
            Column::new(&p, z)
                .map(|c| c.g1[0] * p.gamma)
                .ok_or_else(|| Error::Singular { s: format!("{z}") })
        })
        .collect()
}

/// One defect of a [`SetProblem`]: kind, position, and either a fixed value
/// or the index of its free value.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SetDefect {
    /// A defect whose value is known.
    Fixed(DefectKind, usize, f64),
    /// A defect whose value is `theta[i]`.
    Free(DefectKind, usize, usize),
}

impl SetDefect {
    fn kind_at(&self) -> (DefectKind, usize) {
        match *self {
            SetDefect::Fixed(k, a, _) | SetDefect::Free(k, a, _) => (k, a),
        }
    }
}

/// The values of defects at fixed positions as a least-squares problem
/// against a [`Target`], by Woodbury on the uniform chain's closed-form
/// Green's function ([`crate::green::Green`]): per node a `c x c` solve (`c`
/// the distinct probe columns), `X_1 = gamma (G_11 - sum_l G_1l c_l y_l)`
/// with `(I + A C) y = U^T G e_1`, and the Jacobian
/// `dX_1/dv = -gamma kappa(s) y_l^2` at no extra solve. The entries are
/// gathered once per position set: an evaluation costs O(Q c^3), whatever `n`.
#[derive(Clone, Debug)]
pub struct SetProblem<'a> {
    target: &'a Target,
    gamma: f64,
    defects: Vec<SetDefect>,
    /// column of each defect
    col: Vec<usize>,
    /// uniform value of each defect's kind
    uniform: Vec<f64>,
    /// `kappa(s)` of each defect's kind at each node (`[q * defects + i]`):
    /// depends only on the nodes, so made once
    factor: Vec<C>,
    ncol: usize,
    /// per column: `Some(sign)` when the probe is `+-e_1`
    e1: Vec<Option<f64>>,
    /// per node: `A` (`ncol^2`), `rhs` (`ncol`), `g11`
    a: Vec<C>,
    rhs: Vec<C>,
    g11: Vec<C>,
    p: usize,
}

impl<'a> SetProblem<'a> {
    /// The problem of `defects` on the uniform part of `chain` (its `n`, `k`,
    /// `mass`, `d`, `gamma`, ends), data `target`.
    ///
    /// # Errors
    /// A position outside the kind's range (field `defects[i].at`); free
    /// indices that are not `0..p` (field `defects`).
    pub fn new(chain: &Chain, defects: &[SetDefect], target: &'a Target) -> Result<SetProblem<'a>> {
        chain.require_grounded("the greedy search's rank-one set problems")?;
        chain.require_uniform(
            "the greedy search's rank-one set problems (use --method enumerate)",
        )?;
        let (probes, col, p) = probe_columns(chain, defects)?;
        let ncol = probes.len();
        let e1 = probes
            .iter()
            .map(|pr| match *pr {
                Probe::Point(1) => Some(1.0),
                Probe::Diff(0) => Some(-1.0),
                _ => None,
            })
            .collect();
        let (a, rhs, g11) = node_tables(chain, target, &probes);
        let factor = target
            .nodes()
            .iter()
            .flat_map(|&z| defects.iter().map(move |d| kind_factor(d.kind_at().0, z)))
            .collect();
        Ok(SetProblem {
            target,
            gamma: chain.gamma(),
            factor,
            uniform: defects
                .iter()
                .map(|d| d.kind_at().0.uniform(chain))
                .collect(),
            defects: defects.to_vec(),
            col,
            ncol,
            e1,
            a,
            rhs,
            g11,
            p,
        })
    }

    /// Number of free values.
    pub fn p(&self) -> usize {
        self.p
    }

    /// `X_1` at every node, and with `jac` the derivative of each node's
    /// `X_1` in each free value (`[q * p + j]`). `None` where a capacitance
    /// system is singular.
    pub fn eval(&self, theta: &[f64], mut jac: Option<&mut Vec<C>>) -> Option<Vec<C>> {
        let nc = self.ncol;
        let s = self.target.nodes();
        let mut x = Vec::with_capacity(s.len());
        let mut m = vec![C::new(0.0, 0.0); nc * nc];
        let mut y = vec![C::new(0.0, 0.0); nc];
        let mut c = vec![C::new(0.0, 0.0); nc];
        if let Some(j) = jac.as_mut() {
            j.clear();
            j.resize(s.len() * self.p, C::new(0.0, 0.0));
        }
        let nd = self.defects.len();
        for q in 0..s.len() {
            let factor = &self.factor[q * nd..(q + 1) * nd];
            c.iter_mut().for_each(|v| *v = C::new(0.0, 0.0));
            for (i, d) in self.defects.iter().enumerate() {
                let v = match *d {
                    SetDefect::Fixed(_, _, v) => v,
                    SetDefect::Free(_, _, j) => theta[j],
                };
                c[self.col[i]] += factor[i] * (v - self.uniform[i]);
            }
            let a = &self.a[q * nc * nc..(q + 1) * nc * nc];
            let rhs = &self.rhs[q * nc..(q + 1) * nc];
            for l in 0..nc {
                for k in 0..nc {
                    m[l * nc + k] = a[l * nc + k] * c[k] + if l == k { 1.0 } else { 0.0 };
                }
                y[l] = rhs[l];
            }
            if !crate::linalg::solve_in_place(&mut m, &mut y, nc) {
                return None;
            }
            let xv = match self.e1.iter().position(Option::is_some) {
                Some(l) => y[l] * (self.gamma * self.e1[l].unwrap_or(1.0)),
                None => {
                    let mut corr = C::new(0.0, 0.0);
                    for l in 0..nc {
                        corr += rhs[l] * c[l] * y[l];
                    }
                    (self.g11[q] - corr) * self.gamma
                }
            };
            x.push(xv);
            if let Some(j) = jac.as_mut() {
                for (i, d) in self.defects.iter().enumerate() {
                    if let SetDefect::Free(_, _, jj) = *d {
                        let yl = y[self.col[i]];
                        j[q * self.p + jj] = -(factor[i] * yl * yl) * self.gamma;
                    }
                }
            }
        }
        x.iter().all(|v| v.is_finite()).then_some(x)
    }
}

impl crate::detect::search::lsq::LeastSquares for SetProblem<'_> {
    fn residuals(&self, theta: &[f64]) -> Result<Vec<f64>> {
        let x = self.eval(theta, None).ok_or_else(|| Error::Numerical {
            method: "set problem".into(),
            reason: "a singular capacitance system".into(),
        })?;
        Ok(self.target.residuals(&x))
    }

    fn jacobian(&self, theta: &[f64]) -> Result<DMatrix<f64>> {
        let mut jz = Vec::new();
        self.eval(theta, Some(&mut jz))
            .ok_or_else(|| Error::Numerical {
                method: "set problem".into(),
                reason: "a singular capacitance system".into(),
            })?;
        let q = self.target.nodes().len();
        let m = self.target.m();
        let mut out = DMatrix::zeros(m, self.p);
        let mut colz = vec![C::new(0.0, 0.0); q];
        let mut tmp = vec![0.0; self.target.stacked()];
        let mut o = vec![0.0; m];
        for j in 0..self.p {
            for (qi, v) in colz.iter_mut().enumerate() {
                *v = jz[qi * self.p + j];
            }
            self.target.apply(&colz, &mut tmp, &mut o);
            out.column_mut(j).copy_from_slice(&o);
        }
        Ok(out)
    }
}

/// The defect a scored candidate describes.
pub fn defect_of(sc: &Scored) -> Defect {
    sc.kind.defect(sc.at, sc.value)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::forward::response;

    fn nodes() -> Vec<C> {
        (0..24)
            .map(|q| C::new(0.08, 0.15 * q as f64))
            .chain([C::new(0.3, 0.0), C::new(1.7, 0.0)])
            .collect()
    }

    fn chain() -> Chain {
        crate::scenes::three_kinds(9, [3, 5, 7]).unwrap()
    }

    #[test]
    fn column_matches_the_forward_model() {
        for c in [
            chain(),
            chain()
                .with_boundaries(crate::chain::Boundary::Fixed, crate::chain::Boundary::Free)
                .unwrap(),
        ] {
            let x = x1(&c, &nodes()).unwrap();
            for (z, v) in nodes().iter().zip(&x) {
                let r = response(&c, *z, 1).unwrap();
                assert!((v - r).norm() <= 1e-12 * r.norm(), "{z}: {v} vs {r}");
            }
        }
    }

    #[test]
    fn rank_one_update_matches_the_forward_model_for_every_kind() {
        let base = chain();
        let s = nodes();
        let kinds = [DefectKind::Mass, DefectKind::Spring, DefectKind::Damper];
        let sweep = Sweep::new(&base, &s, &kinds).unwrap();
        let p = sweep.profile().clone();
        for (kind, at, v) in [
            (DefectKind::Mass, 1, 3.0),
            (DefectKind::Mass, 6, 0.4),
            (DefectKind::Mass, 9, 5.0),
            (DefectKind::Spring, 0, 2.0),
            (DefectKind::Spring, 2, 0.3),
            (DefectKind::Spring, 9, 4.0),
            (DefectKind::Damper, 1, 0.9),
            (DefectKind::Damper, 4, 0.0),
        ] {
            let changed = base.clone().with_defect(kind.defect(at, v)).unwrap();
            let uniform = kind.uniform(&base);
            for &z in &s {
                let col = Column::new(&p, z).unwrap();
                let (a, b) = col.probe(&p, kind, at);
                let c = kind_factor(kind, z) * (v - uniform);
                let x = col.g1[0] * p.gamma;
                let upd = if probe_is_e1(kind, at) {
                    b * p.gamma / (c * b + 1.0)
                } else {
                    x - c * a * a * p.gamma / (c * b + 1.0)
                };
                let r = response(&changed, z, 1).unwrap();
                assert!(
                    (upd - r).norm() <= 1e-11 * r.norm(),
                    "{kind:?}@{at}={v} at {z}: {upd} vs {r}"
                );
            }
        }
    }

    #[test]
    fn score_finds_each_kind_and_is_thread_independent() {
        let base = Chain::paper(12).unwrap();
        let s = nodes();
        let kinds = [DefectKind::Mass, DefectKind::Spring, DefectKind::Damper];
        for truth in [
            Defect::Mass { at: 7, m: 3.5 },
            Defect::Spring { at: 4, k: 0.4 },
            Defect::Damper { at: 2, d: 1.5 },
        ] {
            let t = base.clone().with_defect(truth).unwrap();
            let obs = LaplaceObs::exact(&t, s.clone(), vec![1.0; s.len()]).unwrap();
            let target = Target::new(&obs);
            let sweep = Sweep::new(&base, &s, &kinds).unwrap();
            let a = score(&sweep, &target, &[], &ScoreOptions::default(), true);
            let b = score(&sweep, &target, &[], &ScoreOptions::default(), false);
            assert_eq!(a, b);
            assert_eq!((a[0].kind, a[0].at), (DefectKind::of(&truth), truth.at()));
            assert!(
                (a[0].value - truth.value()).abs() < 1e-7 * truth.value(),
                "{truth:?}: {:?}",
                a[0]
            );
            assert!(a[0].chi2 < 1e-20 && a[1].chi2 > 1e3 * a[0].chi2.max(1e-30));
            // exclusion
            let ex = score(
                &sweep,
                &target,
                &[(DefectKind::of(&truth), truth.at())],
                &ScoreOptions::default(),
                true,
            );
            assert_eq!(ex.len(), a.len() - 1);
        }
    }

    #[test]
    fn set_problem_matches_obs_residuals_and_jacobian() {
        use crate::detect::search::lsq::LeastSquares;
        use crate::sensitivity::Param;
        let base = Chain::paper(11)
            .unwrap()
            .with_boundaries(crate::chain::Boundary::Fixed, crate::chain::Boundary::Free)
            .unwrap();
        let s = nodes();
        let obs = LaplaceObs::exact(&chain(), s.clone(), vec![2.0; s.len()]).unwrap();
        let target = Target::new(&obs);
        let defs = [
            SetDefect::Free(DefectKind::Mass, 1, 0),
            SetDefect::Fixed(DefectKind::Damper, 1, 0.5),
            SetDefect::Free(DefectKind::Spring, 4, 1),
            SetDefect::Free(DefectKind::Damper, 9, 2),
            SetDefect::Free(DefectKind::Mass, 9, 3),
        ];
        let theta = [2.5, 0.7, 0.3, 0.6];
        let sp = SetProblem::new(&base, &defs, &target).unwrap();
        let chain = base
            .clone()
            .with_defects(
                crate::scenes::defects(
                    "mass:1:2.5 damper:1:0.5 spring:4:0.7 damper:9:0.3 mass:9:0.6",
                )
                .unwrap(),
            )
            .unwrap();
        let direct = obs.residuals(&chain).unwrap();
        let mine = sp.residuals(&theta).unwrap();
        for (a, b) in direct.iter().zip(&mine) {
            assert!((a - b).abs() <= 1e-10 * a.abs().max(1e-3), "{a} vs {b}");
        }
        let params = [
            Param::Defect(0),
            Param::Defect(2),
            Param::Defect(3),
            Param::Defect(4),
        ];
        let jd = obs.jacobian(&chain, &params).unwrap();
        let jm = sp.jacobian(&theta).unwrap();
        for (a, b) in jd.iter().zip(jm.iter()) {
            assert!((a - b).abs() <= 1e-9 * a.abs().max(1e-3), "{a} vs {b}");
        }
        // a spring outside the chain's range is refused
        assert!(SetProblem::new(
            &base,
            &[SetDefect::Free(DefectKind::Spring, 11, 0)],
            &target
        )
        .is_err());
    }

    #[test]
    fn whitened_target_matches_obs_residuals() {
        let t = chain();
        let s = nodes();
        let m = crate::time::series::stacked_rows(&s).len();
        let w = DMatrix::from_fn(m - 3, m, |r, c| ((r * 7 + c * 3) % 11) as f64 - 5.0);
        let data: Vec<C> = s.iter().map(|z| response(&t, *z, 1).unwrap()).collect();
        let obs = LaplaceObs::whitened(s.clone(), data, w).unwrap();
        let other = Chain::paper(9).unwrap();
        let direct = obs.residuals(&other).unwrap();
        let mine = Target::new(&obs).residuals(&x1(&other, &s).unwrap());
        for (a, b) in direct.iter().zip(&mine) {
            assert!((a - b).abs() <= 1e-10 * a.abs().max(1.0), "{a} vs {b}");
        }
    }
}
