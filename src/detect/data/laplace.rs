//! Laplace-domain observations `d_q ~ X_1(s_q)` at real or complex nodes,
//! weighted per node or whitened by their covariance, with the residuals and
//! Jacobian a least-squares fit needs. The model at each node is the
//! observable of the data's [`Sensor`] (default: `X_1`), times the transform
//! of the measured force when there is one
//! ([`crate::detect::data::measurement`]).

use crate::chain::Chain;
use crate::detect::data::measurement::{laplace_gradient, laplace_model, scale_gradient, Sensor};
use crate::detect::data::whitener::Whitener;
use crate::error::{check_f64, Error, Result};
use crate::forward::transfer::{SweepTable, SweepWork};
use crate::forward::Forward;
use crate::sensitivity::{
    defect_gradient_from, defect_gradient_with, observe_defect_gradient_with, Gradient, Gradients,
    Param,
};
use nalgebra::DMatrix;
use num_complex::Complex64;
use std::sync::{Arc, RwLock};

/// Laplace-domain observations: `chi^2 = sum_q w_q |X_1(s_q) - d_q|^2`
/// (diagonal weights, [`LaplaceObs::new`]) or `chi^2 = ||W r||^2` with `r`
/// the stacked real residuals `[Re r_1..r_Q; Im r_q for complex s_q]`
/// ([`crate::time::series::stack_re_im`]) and a whitening matrix `W`
/// ([`LaplaceObs::whitened`]).
#[derive(Clone, Debug, PartialEq)]
pub struct LaplaceObs {
    s: Vec<Complex64>,
    values: Vec<Complex64>,
    weights: Vec<f64>,
    whitening: Option<Whitener>,
    sensor: Sensor,
    /// Transform of the measured force at the nodes (`None`: the impulse).
    force_hat: Option<Vec<Complex64>>,
    /// Per-node powers of one uniform chain: the first evaluated, or the
    /// one a fit holds its chain parameters at ([`LaplaceObs::retable`]).
    tables: TableCache,
    /// The same data at a subset of the nodes, whitened by their own
    /// (marginal) covariance: a cheaper true chi-square for screening.
    screen: Option<Box<LaplaceObs>>,
    /// Names these nodes, data and measurement for the per-thread memo of
    /// the last sweep ([`LastSweep`]); a new one whenever they change.
    id: ObsId,
    /// Further sensors' values (each its own nodes, weighting and sensor):
    /// their residuals follow these (empty: one sensor).
    others: Vec<LaplaceObs>,
}

/// A process-wide unique number naming the content of a [`LaplaceObs`]
/// (copied by `clone`, which copies the content); compares equal to every
/// other id (it is not data).
#[derive(Clone, Debug)]
struct ObsId(u64);

impl ObsId {
    fn fresh() -> ObsId {
        static NEXT: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
        ObsId(NEXT.fetch_add(1, std::sync::atomic::Ordering::Relaxed))
    }
}

impl PartialEq for ObsId {
    fn eq(&self, _: &ObsId) -> bool {
        true
    }
}

/// The tabulated sweeps of one chain at every node of one observation: per
/// node `X_1` and its derivatives with respect to every defect value
/// ([`LaplaceObs::tabulated_gradients`], `None` where the table does not
/// apply). A least-squares fit asks for the residuals at a point and then
/// for the Jacobian at the same point (and the driver once more for the
/// Jacobian at its last point): one sweep per node serves both.
struct LastSweep {
    id: u64,
    chain: Chain,
    grads: Vec<Option<Gradient<Complex64>>>,
}

thread_local! {
    /// The last [`LastSweep`] made on this thread.
    static LAST_SWEEP: std::cell::RefCell<Option<LastSweep>> =
        const { std::cell::RefCell::new(None) };
}

/// Largest chain whose per-node sweep tables are kept (`2 (2n + 2)` complex
/// values per node: 640 KB per node at this size).
pub const MAX_TABLE_N: usize = 10_000;

/// [`SweepTable`]s at the nodes for one uniform chain (`None` above
/// [`MAX_TABLE_N`] masses), with the chain's `(k, mass, d)` and `n` they
/// were built for.
#[derive(Debug)]
struct Tables {
    key: ((u64, u64, u64), usize),
    nodes: Option<Vec<SweepTable<Complex64>>>,
}

impl Tables {
    fn key(chain: &Chain) -> ((u64, u64, u64), usize) {
        let (k, mass, d) = (chain.k(), chain.mass(), chain.d());
        ((k.to_bits(), mass.to_bits(), d.to_bits()), chain.n())
    }
}

/// The [`Tables`] of one uniform chain, built on first use and rebuilt
/// by [`LaplaceObs::retable`]; a chain they were not built for falls back
/// to the direct sweep ([`crate::forward::transfer::Transfer::fits`]).
/// Clones share the tables; compares equal to every other cache (it is
/// derived data).
#[derive(Debug, Default)]
struct TableCache(RwLock<Option<Arc<Tables>>>);

impl Clone for TableCache {
    fn clone(&self) -> TableCache {
        TableCache(RwLock::new(self.get()))
    }
}

impl TableCache {
    fn get(&self) -> Option<Arc<Tables>> {
        self.0.read().ok().and_then(|t| t.clone())
    }

    /// The tables for `chain`'s uniform part, built when there are none
    /// or (with `rebuild`) when they were built for another.
    fn for_chain(&self, s: &[Complex64], chain: &Chain, rebuild: bool) -> Option<Arc<Tables>> {
        // every evaluation asks (`rebuild` false): the key only to rebuild
        if let Some(t) = self
            .get()
            .filter(|t| !rebuild || t.key == Tables::key(chain))
        {
            return Some(t);
        }
        let key = Tables::key(chain);
        let built = Arc::new(Tables {
            key,
            nodes: (chain.n() <= MAX_TABLE_N)
                .then(|| s.iter().map(|&z| SweepTable::new(chain, z)).collect()),
        });
        let mut slot = self.0.write().ok()?;
        match slot.as_ref() {
            // another thread built the same first
            Some(t) if t.key == key || !rebuild => Some(t.clone()),
            _ => {
                *slot = Some(built.clone());
                Some(built)
            }
        }
    }
}

impl PartialEq for TableCache {
    fn eq(&self, _: &TableCache) -> bool {
        true
    }
}

impl LaplaceObs {
    /// Nodes, data and weights.
    ///
    /// # Errors
    /// Lengths differ or are zero; a node with `Re s < 0` or non-finite; a
    /// weight negative or non-finite.
    pub fn new(s: Vec<Complex64>, values: Vec<Complex64>, weights: Vec<f64>) -> Result<LaplaceObs> {
        super::check_lengths(
            "s",
            s.len(),
            values.len(),
            (weights.len(), "weights"),
            "equal lengths, at least one node",
        )?;
        for (i, z) in s.iter().enumerate() {
            crate::forward::check_s(z)
                .map_err(|_| Error::invalid(format!("s[{i}]"), z, "finite, Re s >= 0"))?;
        }
        for (i, w) in weights.iter().enumerate() {
            check_f64(&format!("weights[{i}]"), *w, *w >= 0.0, ">= 0 and finite")?;
        }
        for (i, v) in values.iter().enumerate() {
            if !(v.re.is_finite() && v.im.is_finite()) {
                return Err(Error::invalid(format!("values[{i}]"), v, "finite"));
            }
        }
        Ok(LaplaceObs {
            s,
            values,
            weights,
            whitening: None,
            sensor: Sensor::PAPER,
            force_hat: None,
            tables: TableCache::default(),
            screen: None,
            id: ObsId::fresh(),
            others: Vec::new(),
        })
    }

    /// The same data as another sensor's, driven by a measured force whose
    /// transform at the nodes is `force_hat` (`None`: the impulse).
    ///
    /// # Errors
    /// `force_hat` of another length than the nodes or non-finite (field
    /// `force`).
    pub fn with_measurement(
        mut self,
        sensor: Sensor,
        force_hat: Option<Vec<Complex64>>,
    ) -> Result<LaplaceObs> {
        if let Some(f) = &force_hat {
            if f.len() != self.s.len() || f.iter().any(|v| !(v.re.is_finite() && v.im.is_finite()))
            {
                return Err(Error::invalid(
                    "force",
                    format!("{} transform values for {} nodes", f.len(), self.s.len()),
                    "one finite value per node",
                ));
            }
        }
        self.sensor = sensor;
        self.force_hat = force_hat;
        self.id = ObsId::fresh();
        Ok(self)
    }

    /// Attach a screening observation: the same data at a subset of the
    /// nodes, whitened by their marginal covariance (built by
    /// [`crate::detect::fit::general::laplace_obs`]); a search ranks every
    /// candidate on it and fits only the best on `self`.
    pub fn with_screen(mut self, screen: LaplaceObs) -> LaplaceObs {
        self.screen = Some(Box::new(screen));
        self
    }

    /// The same values joined by further sensors' (one joint chi-square,
    /// the residuals of each sensor in turn; the screens join as well).
    /// The rational set kernels do not apply to a joint observation
    /// ([`crate::detect::misfit::laplace_sets::SetTables::new`] answers
    /// `None`): every evaluation sweeps the chain at every node.
    pub fn with_others(mut self, others: Vec<LaplaceObs>) -> LaplaceObs {
        let screens: Option<Vec<LaplaceObs>> = others.iter().map(|o| o.screen().cloned()).collect();
        if let (Some(sc), Some(screens)) = (self.screen.as_mut(), screens) {
            sc.others = screens;
        } else {
            self.screen = None;
        }
        self.others = others;
        self
    }

    /// The further sensors' values (empty: one sensor).
    pub fn others(&self) -> &[LaplaceObs] {
        &self.others
    }

    /// The screening observation, if any (see [`LaplaceObs::with_screen`]).
    pub fn screen(&self) -> Option<&LaplaceObs> {
        self.screen.as_deref()
    }

    /// The sensor whose observable the data are.
    pub fn sensor(&self) -> Sensor {
        self.sensor
    }

    /// The sweep tables of the nodes (built on first use for `chain`'s
    /// uniform part; `None` above [`MAX_TABLE_N`] masses).
    fn tables(&self, chain: &Chain) -> Option<Arc<Tables>> {
        self.tables
            .for_chain(&self.s, chain, false)
            .filter(|t| t.nodes.is_some())
    }

    /// Build the sweep tables for `chain`'s uniform part (this
    /// observation's, its screen's and the other sensors'), unless they
    /// are: a fit that holds the chain parameters at new values calls it
    /// before its evaluations, which then take the tabulated sweep (the
    /// tables of other values do not apply to them).
    pub(crate) fn retable(&self, chain: &Chain) {
        self.tables.for_chain(&self.s, chain, true);
        if let Some(sc) = &self.screen {
            sc.retable(chain);
        }
        for o in &self.others {
            o.retable(chain);
        }
    }

    /// Whether the model is `s^p F(s) X_at(s)` (or `X_at`), which the
    /// tabulated sweep gives; the acceleration after the impulse needs the
    /// direct evaluation (its jump).
    pub(crate) fn tabulable(&self) -> bool {
        self.force_hat.is_some() || self.sensor.kind != crate::forward::Observable::Acceleration
    }

    /// The factor turning `X_at` into the model at node `q`: `s^p F(s)`, or
    /// `s^p` for the impulse (velocity: `x(0) = 0`, no jump).
    pub(crate) fn factor(&self, q: usize) -> Complex64 {
        let sp = self.s[q].powu(self.sensor.kind.power());
        match &self.force_hat {
            Some(f) => sp * f[q],
            None => sp,
        }
    }

    /// `X` at `sites` by the tabulated sweep, if it applies.
    fn x_sites(&self, fwd: &Forward, q: usize, sites: &[usize]) -> Option<Vec<Complex64>> {
        let tables = self.tables(fwd.chain())?;
        fwd.sites_with(&self.s[q], &tables.nodes.as_ref()?[q], sites)
    }

    /// The model of the data at node `q` for `fwd`'s chain.
    fn model_at(&self, fwd: &Forward, q: usize) -> Result<Complex64> {
        if self.tabulable() {
            if let Some(x) = self.x_sites(fwd, q, &[self.sensor.at]) {
                return Ok(self.factor(q) * x[0]);
            }
        }
        if self.force_hat.is_none() && self.sensor == Sensor::PAPER {
            return fwd.eval(self.s[q], 1);
        }
        laplace_model(
            self.sensor,
            fwd,
            self.s[q],
            self.force_hat.as_ref().map(|f| f[q]),
        )
    }

    /// Nodes, data and a whitening matrix `W` (`K` rows, one column per row of
    /// the stacked real residual vector: `Q` plus the number of complex
    /// nodes), typically [`crate::detect::data::whiten::Whitening::matrix`] of the
    /// data covariance; `chi^2 = ||W r||^2` has `K` degrees of freedom at the
    /// true chain.
    ///
    /// # Errors
    /// As [`LaplaceObs::new`]; `W` with the wrong number of columns, no rows,
    /// or a non-finite entry (field `whitening`).
    pub fn whitened(
        s: Vec<Complex64>,
        values: Vec<Complex64>,
        whitening: DMatrix<f64>,
    ) -> Result<LaplaceObs> {
        let q = s.len();
        let mut obs = LaplaceObs::new(s, values, vec![1.0; q])?;
        let m = crate::time::series::stacked_rows(&obs.s).len();
        if whitening.ncols() != m || whitening.nrows() == 0 {
            return Err(Error::invalid(
                "whitening",
                format!("{}x{}", whitening.nrows(), whitening.ncols()),
                format!("at least one row and {m} columns (stacked residuals)"),
            ));
        }
        if whitening.iter().any(|v| !v.is_finite()) {
            return Err(Error::invalid("whitening", "non-finite entry", "finite"));
        }
        obs.whitening = Some(Whitener::rotated(whitening));
        obs.id = ObsId::fresh();
        Ok(obs)
    }

    /// Degrees of freedom of the chi-square at a fixed chain: the rows of `W`
    /// when whitened, otherwise the number of real residuals (one per real
    /// node, two per complex node; with diagonal weights this is only a
    /// count, the misfit is not a chi-square).
    pub fn dof(&self) -> usize {
        let own = match &self.whitening {
            Some(w) => w.rows(),
            None => crate::time::series::stacked_rows(&self.s).len(),
        };
        own + self.others.iter().map(LaplaceObs::dof).sum::<usize>()
    }

    /// The whitening matrix, if any: `R` of the `W = Q R` given to
    /// [`LaplaceObs::whitened`] (the same whitening, see
    /// [`Whitener::rotated`]).
    pub fn whitening(&self) -> Option<&DMatrix<f64>> {
        self.whitening.as_ref().map(Whitener::matrix)
    }

    /// The whitening as the products use it.
    pub(crate) fn whitener(&self) -> Option<&Whitener> {
        self.whitening.as_ref()
    }

    /// The data values.
    pub fn values(&self) -> &[Complex64] {
        &self.values
    }

    /// The per-node weights (all 1 when whitened).
    pub fn weights(&self) -> &[f64] {
        &self.weights
    }

    /// `chi^2` of `chain` (the sum of squared [`LaplaceObs::residuals`]).
    ///
    /// # Errors
    /// As [`LaplaceObs::residuals`].
    pub fn chi2(&self, chain: &Chain) -> Result<f64> {
        Ok(self.residuals(chain)?.iter().map(|v| v * v).sum())
    }

    /// Exact data of `truth` at the nodes (for tests and studies).
    ///
    /// # Errors
    /// As [`Forward::eval`] and [`LaplaceObs::new`].
    pub fn exact(truth: &Chain, s: Vec<Complex64>, weights: Vec<f64>) -> Result<LaplaceObs> {
        let fwd = Forward::new(truth);
        let values = s
            .iter()
            .map(|z| fwd.eval(*z, 1))
            .collect::<Result<Vec<_>>>()?;
        LaplaceObs::new(s, values, weights)
    }

    /// The nodes.
    pub fn nodes(&self) -> &[Complex64] {
        &self.s
    }

    /// Whitened residuals of `chain` (real and imaginary parts, imaginary parts
    /// only for complex nodes; with further sensors, each sensor's in turn).
    ///
    /// # Errors
    /// As [`Forward::eval`].
    pub fn residuals(&self, chain: &Chain) -> Result<Vec<f64>> {
        let mut r = self.channel_residuals(chain)?;
        for o in &self.others {
            r.extend(o.channel_residuals(chain)?);
        }
        Ok(r)
    }

    /// [`LaplaceObs::residuals`] of this sensor alone.
    fn channel_residuals(&self, chain: &Chain) -> Result<Vec<f64>> {
        let fwd = Forward::new(chain);
        let model = self.models(&fwd)?;
        if let Some(w) = &self.whitening {
            let diff: Vec<Complex64> = model.iter().zip(&self.values).map(|(x, d)| x - d).collect();
            let r = crate::time::series::stack_re_im(&self.s, &diff);
            return Ok(w.apply(&r, 1));
        }
        let mut r = Vec::with_capacity(2 * self.s.len());
        for (q, &x) in model.iter().enumerate() {
            let sw = self.weights[q].sqrt();
            let e = (x - self.values[q]) * sw;
            r.push(e.re);
            if self.s[q].im != 0.0 {
                r.push(e.im);
            }
        }
        Ok(r)
    }

    /// The model at every node for `fwd`'s chain ([`LaplaceObs::model_at`];
    /// from the memo of the last sweep where it applies).
    fn models(&self, fwd: &Forward) -> Result<Vec<Complex64>> {
        if self.sweep_memo_applies() {
            return self.with_sweep(fwd, |grads| {
                grads
                    .iter()
                    .enumerate()
                    .map(|(q, g)| match g {
                        Some(g) => Ok(self.factor(q) * g.value),
                        None => self.model_at(fwd, q),
                    })
                    .collect()
            });
        }
        (0..self.s.len()).map(|q| self.model_at(fwd, q)).collect()
    }

    /// Whether the tabulated gradient sweep gives the model (observable of
    /// mass 1 that the table gives): then one sweep per node serves the
    /// residuals and the Jacobian ([`LastSweep`]).
    fn sweep_memo_applies(&self) -> bool {
        self.sensor.at == 1 && self.tabulable()
    }

    /// `f` of the tabulated gradients of `fwd`'s chain at every node
    /// (`None` where the table does not apply), swept once per chain and
    /// thread ([`LastSweep`]).
    fn with_sweep<T>(
        &self,
        fwd: &Forward,
        f: impl FnOnce(&[Option<Gradient<Complex64>>]) -> T,
    ) -> T {
        LAST_SWEEP.with(|cell| {
            let mut slot = cell.borrow_mut();
            let hit = slot
                .as_ref()
                .is_some_and(|m| m.id == self.id.0 && m.chain == *fwd.chain());
            if !hit {
                let grads = self.tabulated_gradients(fwd);
                *slot = Some(LastSweep {
                    id: self.id.0,
                    chain: fwd.chain().clone(),
                    grads,
                });
            }
            f(&slot.as_ref().expect("set above").grads)
        })
    }

    /// `X_1` and its derivatives with respect to every defect value of
    /// `fwd`'s chain at every node, from `X` at mass 1 and the defect sites
    /// in one tabulated sweep per node (as [`defect_gradient_with`]); `None`
    /// where the table does not apply. The sites once per chain, the sweep's
    /// buffers once for all nodes.
    fn tabulated_gradients(&self, fwd: &Forward) -> Vec<Option<Gradient<Complex64>>> {
        let chain = fwd.chain();
        let tables = self.tables(chain);
        let Some(nodes) = tables.as_ref().and_then(|t| t.nodes.as_deref()) else {
            return vec![None; self.s.len()];
        };
        let n = chain.n();
        let mut sites = vec![1];
        for d in chain.defects() {
            sites.extend(chain.site(d).probe.entries(n).map(|(i, _)| i));
        }
        sites.sort_unstable();
        sites.dedup();
        let mut work = SweepWork::default();
        self.s
            .iter()
            .zip(nodes)
            .map(|(s, table)| {
                if !fwd.sites_into(s, table, &sites, &mut work) {
                    return None;
                }
                let x = work.out();
                // x_0 = x_{n+1} = 0
                let at = |i: usize| -> Result<Complex64> {
                    Ok(sites
                        .binary_search(&i)
                        .map_or(Complex64::new(0.0, 0.0), |j| x[j]))
                };
                defect_gradient_from(chain, s, at).ok()
            })
            .collect()
    }

    pub(crate) fn jacobian(&self, chain: &Chain, params: &[Param]) -> Result<DMatrix<f64>> {
        let mut out = self.channel_jacobian(chain, params)?;
        for o in &self.others {
            let b = o.channel_jacobian(chain, params)?;
            let top = out.nrows();
            out = out.resize_vertically(top + b.nrows(), 0.0);
            out.rows_mut(top, b.nrows()).copy_from(&b);
        }
        Ok(out)
    }

    /// [`LaplaceObs::jacobian`] of this sensor alone.
    fn channel_jacobian(&self, chain: &Chain, params: &[Param]) -> Result<DMatrix<f64>> {
        // defect parameters only: O(k) per site by the transfer sweep
        let defect_idx: Option<Vec<usize>> = params
            .iter()
            .map(|p| match p {
                Param::Defect(i) => Some(*i),
                _ => None,
            })
            .collect();
        let fwd = Forward::new(chain);
        if let (Some(idx), Some(w)) = (&defect_idx, &self.whitening) {
            if let Some(j) = self.memo_whitened_jacobian(&fwd, idx, w) {
                return Ok(j);
            }
        }
        let tabs = match &defect_idx {
            Some(idx) if self.sweep_memo_applies() => self.memo_gradients(&fwd, idx),
            _ => vec![None; self.s.len()],
        };
        let mut grads: Vec<Vec<Complex64>> = Vec::with_capacity(self.s.len());
        // the chain's coefficients, taken once for every node that needs them
        let mut general: Option<Gradients> = None;
        for (q, tab) in tabs.into_iter().enumerate() {
            let g = match tab {
                Some(g) => g,
                None => {
                    self.node_gradient(&fwd, chain, q, defect_idx.as_deref(), params, &mut general)?
                }
            };
            grads.push(g.grad);
        }
        if let Some(w) = &self.whitening {
            // stacked rows: Re of every node, then Im of the complex nodes
            let layout = crate::time::series::stacked_rows(&self.s);
            let j = DMatrix::from_fn(layout.len(), params.len(), |r, c| {
                let (q, im) = layout[r];
                if im {
                    grads[q][c].im
                } else {
                    grads[q][c].re
                }
            });
            return Ok(DMatrix::from_vec(
                w.rows(),
                params.len(),
                w.apply(j.as_slice(), params.len()),
            ));
        }
        let mut rows: Vec<Vec<f64>> = Vec::with_capacity(2 * self.s.len());
        for (q, g) in grads.iter().enumerate() {
            let sw = self.weights[q].sqrt();
            rows.push(g.iter().map(|v| v.re * sw).collect());
            if self.s[q].im != 0.0 {
                rows.push(g.iter().map(|v| v.im * sw).collect());
            }
        }
        Ok(DMatrix::from_fn(rows.len(), params.len(), |i, j| {
            rows[i][j]
        }))
    }

    /// Whitened defect values of the tabulated observable: the stacked
    /// Jacobian straight from the memo of the sweep (the same values as the
    /// node-by-node path of [`LaplaceObs::jacobian`]); `None` where the memo
    /// does not apply.
    fn memo_whitened_jacobian(
        &self,
        fwd: &Forward,
        idx: &[usize],
        w: &Whitener,
    ) -> Option<DMatrix<f64>> {
        if !self.sweep_memo_applies() {
            return None;
        }
        let layout = crate::time::series::stacked_rows(&self.s);
        let (m, p) = (layout.len(), idx.len());
        let j = self.with_sweep(fwd, |all| {
            let mut j = vec![0.0; m * p];
            for (r, &(q, im)) in layout.iter().enumerate() {
                let g = all[q].as_ref()?;
                let c = self.factor(q);
                for (col, &i) in idx.iter().enumerate() {
                    let v = g.grad[i] * c;
                    j[col * m + r] = if im { v.im } else { v.re };
                }
            }
            Some(j)
        })?;
        Some(DMatrix::from_vec(w.rows(), p, w.apply(&j, p)))
    }

    /// Defect values of the tabulated observable: the sweeps of the
    /// residuals at this chain (memo), scaled by each node's factor.
    fn memo_gradients(&self, fwd: &Forward, idx: &[usize]) -> Vec<Option<Gradient<Complex64>>> {
        self.with_sweep(fwd, |all| {
            all.iter()
                .enumerate()
                .map(|(q, g)| {
                    g.as_ref().map(|all| {
                        let c = self.factor(q);
                        Gradient {
                            value: all.value * c,
                            grad: idx.iter().map(|&i| all.grad[i] * c).collect(),
                        }
                    })
                })
                .collect()
        })
    }

    /// The gradient of the model at node `q` with respect to `params`
    /// (`defect_idx`: their defect indices when all are defect values;
    /// `general`: the chain's [`Gradients`], made at the first node that
    /// needs them and kept for the others).
    fn node_gradient<'c>(
        &self,
        fwd: &Forward,
        chain: &'c Chain,
        q: usize,
        defect_idx: Option<&[usize]>,
        params: &[Param],
        general: &mut Option<Gradients<'c>>,
    ) -> Result<Gradient<Complex64>> {
        let s = self.s[q];
        let force = self.force_hat.as_ref().map(|f| f[q]);
        let paper = self.force_hat.is_none() && self.sensor == Sensor::PAPER;
        Ok(match defect_idx {
            // defect values of an observable of mass 1: O(k) per site
            Some(idx) if self.sensor.at == 1 => {
                let all = match (paper, force) {
                    (true, _) => defect_gradient_with(fwd, s)?,
                    (false, None) => observe_defect_gradient_with(fwd, s, self.sensor.kind)?,
                    (false, Some(f)) => scale_gradient(
                        defect_gradient_with(fwd, s)?,
                        s.powu(self.sensor.kind.power()) * f,
                    ),
                };
                Gradient {
                    value: all.value,
                    grad: idx.iter().map(|&i| all.grad[i]).collect(),
                }
            }
            _ if paper => general
                .get_or_insert_with(|| Gradients::new(chain))
                .at(s, 1, params)?,
            _ => laplace_gradient(self.sensor, chain, s, force, params)?,
        })
    }
}

impl crate::detect::model::MeasurementModel for LaplaceObs {
    fn name(&self) -> &'static str {
        "laplace"
    }
    fn dof(&self) -> usize {
        LaplaceObs::dof(self)
    }
    fn residuals(&self, chain: &Chain) -> Result<Vec<f64>> {
        LaplaceObs::residuals(self, chain)
    }
    fn jacobian(&self, chain: &Chain, params: &[Param]) -> Result<Option<DMatrix<f64>>> {
        LaplaceObs::jacobian(self, chain, params).map(Some)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sensitivity::gradient;

    /// Tables built for one damping do not serve another; retabled, they
    /// do, with the direct sweep's residuals and Jacobian to rounding, and
    /// retabling at the values they are for builds nothing new.
    #[test]
    fn retabled_nodes_serve_a_chain_of_other_damping() {
        let truth = crate::scenes::paper_with(12, "mass:3:2.5 spring:9:0.6").unwrap();
        let s: Vec<Complex64> = (1..8)
            .map(|q| Complex64::new(0.05, 0.3 * q as f64))
            .collect();
        let exact = || LaplaceObs::exact(&truth, s.clone(), vec![1.0; s.len()]).unwrap();
        let params = [Param::Defect(0), Param::Defect(1)];
        let obs = exact();
        // the tables are built for the first chain evaluated
        let _ = obs.residuals(&truth).unwrap();
        let other = truth.clone().with_d(0.5 * truth.d()).unwrap();
        let tabulated = |o: &LaplaceObs, c: &Chain| {
            let g = o.tabulated_gradients(&Forward::new(c));
            g.iter().filter(|g| g.is_some()).count()
        };
        assert_eq!(tabulated(&obs, &truth), s.len());
        assert_eq!(
            tabulated(&obs, &other),
            0,
            "tables of another d do not apply"
        );
        let direct = (
            obs.residuals(&other).unwrap(),
            obs.jacobian(&other, &params).unwrap(),
        );
        obs.retable(&other);
        assert_eq!(tabulated(&obs, &other), s.len(), "retabled at the other d");
        assert_eq!(tabulated(&obs, &truth), 0);
        // a fresh observation (no memo of the direct sweep) retabled: the
        // same residuals and Jacobian to rounding
        let fresh = exact();
        fresh.retable(&other);
        let r = fresh.residuals(&other).unwrap();
        let j = fresh.jacobian(&other, &params).unwrap();
        let scale = direct.0.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        assert!(scale > 0.0);
        for (a, b) in r.iter().zip(&direct.0) {
            assert!((a - b).abs() <= 1e-12 * scale, "{a} vs {b}");
        }
        let scale = direct.1.amax();
        for (a, b) in j.iter().zip(direct.1.iter()) {
            assert!((a - b).abs() <= 1e-12 * scale, "{a} vs {b}");
        }
        // retabling at the chain the tables are for builds nothing new
        let before = fresh.tables.get().unwrap();
        let more = other
            .clone()
            .with_defect(crate::chain::Defect::Mass { at: 5, m: 1.3 });
        fresh.retable(&more.unwrap());
        assert!(Arc::ptr_eq(&before, &fresh.tables.get().unwrap()));
    }

    /// The residuals and Jacobian through the memo of the last sweep agree
    /// with the per-call path (the model node by node, nalgebra's `W r` and
    /// `W J`, the general gradient), whichever of the two is asked first.
    #[test]
    fn memo_of_the_sweep_matches_the_per_call_path() {
        let truth = crate::scenes::paper_with(12, "mass:3:2.5 mass:9:0.6").unwrap();
        let s: Vec<Complex64> = (0..9)
            .map(|q| Complex64::new(0.05, 0.4 * q as f64))
            .chain([Complex64::new(0.3, 0.0)])
            .collect();
        let fwd = Forward::new(&truth);
        let values: Vec<Complex64> = s
            .iter()
            .enumerate()
            .map(|(q, z)| fwd.eval(*z, 1).unwrap() * (1.0 + 1e-3 * q as f64))
            .collect();
        let m = crate::time::series::stacked_rows(&s).len();
        let w = DMatrix::from_fn(m - 2, m, |i, j| {
            1.0 / (1.0 + (i as f64 - j as f64).abs()) + 0.01 * i as f64
        });
        let obs = LaplaceObs::whitened(s.clone(), values.clone(), w.clone()).unwrap();
        // the observation holds W rotated (the same whitening): the per-call
        // products below take the matrix it holds
        let w = obs.whitening().unwrap().clone();
        let params = [Param::Defect(0), Param::Defect(1)];
        let chains = [
            truth.clone(),
            Param::Defect(1).set(&truth, 0.9).unwrap(),
            Param::Defect(0).set(&truth, 1.7).unwrap(),
        ];
        for (i, c) in chains.iter().enumerate() {
            // per call: the model node by node, nalgebra's products
            let f = Forward::new(c);
            let diff: Vec<Complex64> = (0..s.len())
                .map(|q| obs.model_at(&f, q).unwrap() - values[q])
                .collect();
            let r0 = &w * nalgebra::DVector::from_vec(crate::time::series::stack_re_im(&s, &diff));
            let layout = crate::time::series::stacked_rows(&s);
            let g: Vec<Gradient<Complex64>> = s
                .iter()
                .map(|z| gradient(c, *z, 1, &params).unwrap())
                .collect();
            let j0 = &w
                * DMatrix::from_fn(m, params.len(), |r, col| {
                    let (q, im) = layout[r];
                    if im {
                        g[q].grad[col].im
                    } else {
                        g[q].grad[col].re
                    }
                });
            // residuals first on even chains, the Jacobian first on odd ones
            let (r1, j1) = if i % 2 == 0 {
                let r = obs.residuals(c).unwrap();
                (r, obs.jacobian(c, &params).unwrap())
            } else {
                let j = obs.jacobian(c, &params).unwrap();
                (obs.residuals(c).unwrap(), j)
            };
            assert_eq!(r1.len(), r0.len());
            for (a, b) in r1.iter().zip(r0.iter()) {
                assert_eq!(a, b, "chain {i}");
            }
            let scale = j0.amax();
            for (a, b) in j1.iter().zip(j0.iter()) {
                assert!((a - b).abs() <= 1e-12 * scale, "chain {i}: {a} vs {b}");
            }
            // again, now from the memo: the same values
            assert_eq!(obs.residuals(c).unwrap(), r1);
            assert_eq!(obs.jacobian(c, &params).unwrap(), j1);
        }
        // another observation (same nodes, other data) never reads this one's memo
        let other =
            LaplaceObs::whitened(s.clone(), vec![Complex64::new(0.0, 0.0); s.len()], w).unwrap();
        let _ = obs.residuals(&truth).unwrap();
        let ro = other.residuals(&truth).unwrap();
        let ra = obs.residuals(&truth).unwrap();
        assert_ne!(ro, ra);
    }
}
