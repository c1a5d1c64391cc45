//! Time-domain misfit: the chi-square between a sampled series `y_i ~ x_1(t_i)`
//! and the model's exact `x_1(t)` (finite modal sum, [`crate::time::modal`]).
//!
//! `chi^2 = sum_i (x_1(t_i; chain) - y_i)^2 / sigma^2`
//!
//! with `sigma` the data's white-noise level, which belongs to the data object
//! ([`TimeData`]); at the truth `chi^2` is a chi-square variable with as many
//! degrees of freedom as samples. With noise-free data `sigma` is replaced by
//! an effective floor `8 eps max|y|` (see [`TimeData::sigma_eff`]).
//!
//! Unlike the real-axis residual, this misfit keeps the conditioning of the
//! measurement: moving a deep defect by one position changes `x_1(t)` by per
//! cents, not by `1e-13` (docs/paper-notes.md, "Why deep defects are hard on the real s axis").
//!
//! ```
//! use springmass::{Chain, Defect, noise::NoiseLevel};
//! use springmass::detect::{data::series::TimeData, misfit::time::TimeMisfit};
//! let truth = Chain::paper(20)?.with_defects([
//!     Defect::Mass { at: 8, m: 5.0 }, Defect::Mass { at: 15, m: 2.0 }])?;
//! let data = TimeData::simulate(&truth, 200.0, 0.5, NoiseLevel::RelativeMax(1e-3), 7)?;
//! let misfit = TimeMisfit::new(data);
//! let right = misfit.chi2(&truth)?;
//! let wrong = misfit.chi2(&Chain::paper(20)?.with_defects([
//!     Defect::Mass { at: 8, m: 5.0 }, Defect::Mass { at: 16, m: 2.0 }])?)?;
//! assert!(right < 2.0 * 401.0 && wrong > right + 1000.0);  // 401 samples
//! # Ok::<(), springmass::Error>(())
//! ```

use crate::chain::Chain;
use crate::detect::data::noise_model::NoiseModel;
use crate::detect::data::nuisance::{Nuisance, Projector};
use crate::detect::data::series::TimeData;
use crate::detect::misfit::time_screen::{simulate, sub_steps, Saved, Screen, TimeGrid};
use crate::detect::model::{Enough, Near};
use crate::detect::unknowns::DefectKind;
use crate::error::{Error, Result};
use crate::sensitivity::Param;
use crate::time::modal::{DoublePoleSum, ModalChange, Modes};

/// Chains from this many masses have their record simulated by
/// [`simulate`] (sparse stepping) unless their modes are already at hand.
const STEP_MIN_N: usize = 100;

/// Most Taylor sub-steps per record sample for which the probes of
/// [`MeasurementModel::near`](crate::detect::model::MeasurementModel::near)
/// are simulated (beyond, a stiff or heavily damped chain, each probe is
/// summed over its modes, whose cost does not grow with the stiffness).
const NEAR_MAX_STEPS: usize = 4;
use nalgebra::DMatrix;

thread_local! {
    /// The last modal decomposition made on this thread and its chain: a
    /// fit asks for the residuals and then the Jacobian at the same point.
    static LAST_MODES: std::cell::RefCell<Option<(Chain, std::rc::Rc<Modes>)>> =
        const { std::cell::RefCell::new(None) };
}

/// The derivative of `x_at` over a change of the chain by weighted sites:
/// [`Modes::sites_derivative`], or under the `modal` damping model
/// [`Modes::modal_derivative`] (`None` where neither has a closed form).
///
/// # Errors
/// As either.
fn sites_column(
    modes: &Modes,
    at: usize,
    gamma: f64,
    terms: &[(crate::chain::Site, f64)],
) -> Result<Option<DoublePoleSum>> {
    match modes.sites_derivative(at, 1, gamma, terms)? {
        Some(d) => Ok(Some(d)),
        None => modes.modal_derivative(at, 1, gamma, ModalChange::Sites(terms)),
    }
}

/// Whether `chain`'s record is simulated rather than summed over its
/// modes: a chain of [`STEP_MIN_N`] masses or more whose modes this thread
/// has not decomposed (an impulse to respond to).
fn simulated(chain: &Chain) -> bool {
    chain.n() >= STEP_MIN_N
        && steppable(chain)
        && !LAST_MODES.with(|c| c.borrow().as_ref().is_some_and(|(k, _)| k == chain))
}

/// Defect `i` of `chain` (a Jacobian's [`Param::Defect`]).
///
/// # Errors
/// An index out of range (field `params`).
fn defect_at(chain: &Chain, i: usize) -> Result<&crate::chain::Defect> {
    chain.defects().get(i).ok_or_else(|| {
        Error::invalid(
            "params",
            format!("defect {i}"),
            format!("an index below {}", chain.defects().len()),
        )
    })
}

/// Whether `chain`'s record can be simulated by [`simulate`]: an impulse
/// to respond to, grounded damping.
fn steppable(chain: &Chain) -> bool {
    chain.gamma() != 0.0 && chain.damping().is_grounded()
}

/// The grid on which [`MeasurementModel::near`]'s probes of `chain` are
/// simulated for the record times `t`: `None` where `chain` cannot be
/// stepped or would take more than [`NEAR_MAX_STEPS`] Taylor sub-steps per
/// sample.
///
/// [`MeasurementModel::near`]: crate::detect::model::MeasurementModel::near
fn near_grid(t: &[f64], chain: &Chain) -> Option<TimeGrid> {
    let grid = TimeGrid::new(t, chain).filter(|_| steppable(chain))?;
    (grid.sub.saturating_mul(sub_steps(chain, &grid)) <= NEAR_MAX_STEPS).then_some(grid)
}

/// `f` of `chain`'s modal decomposition, made once per chain and thread.
fn with_modes<T>(chain: &Chain, f: impl FnOnce(&Modes) -> Result<T>) -> Result<T> {
    let cached = LAST_MODES.with(|c| {
        c.borrow()
            .as_ref()
            .filter(|(k, _)| k == chain)
            .map(|(_, m)| m.clone())
    });
    let modes = match cached {
        Some(m) => m,
        None => {
            let m = std::rc::Rc::new(Modes::new(chain)?);
            LAST_MODES.with(|c| *c.borrow_mut() = Some((chain.clone(), m.clone())));
            m
        }
    };
    f(&modes)
}

/// The time-domain chi-square of a candidate chain against [`TimeData`].
#[derive(Clone, Debug)]
pub struct TimeMisfit {
    data: TimeData,
    inv_sigma: f64,
    analytic: bool,
    /// The noise model (white: the paper's); `sigma` is then its innovation sd.
    noise: NoiseModel,
    /// The sensor's nuisances, profiled out.
    nuisance: Nuisance,
    projector: Option<Projector>,
    /// The further sensors' misfits ([`TimeData::others`]): their
    /// residuals follow this sensor's, each whitened by its own level.
    others: Vec<TimeMisfit>,
    /// One of several sensors: the modal sum and its exact Jacobian serve
    /// the displacement of any mass after the impulse (one sensor keeps
    /// the single-sensor path: differences off mass 1).
    joint: bool,
}

impl TimeMisfit {
    /// Misfit against `data`.
    pub fn new(data: TimeData) -> TimeMisfit {
        let joint = !data.others().is_empty();
        let others = data
            .others()
            .iter()
            .map(|o| TimeMisfit {
                joint,
                ..TimeMisfit::new(o.clone())
            })
            .collect();
        let inv_sigma = 1.0 / data.sigma_eff();
        TimeMisfit {
            data,
            inv_sigma,
            analytic: true,
            noise: NoiseModel::White,
            nuisance: Nuisance::None,
            projector: None,
            others,
            joint,
        }
    }

    /// The number of sensors (1 + the further sensors').
    pub fn sensors(&self) -> usize {
        1 + self.others.len()
    }

    /// The further sensors' misfits (empty: one sensor).
    pub fn others(&self) -> &[TimeMisfit] {
        &self.others
    }

    /// The same misfit under a noise model and with sensor nuisances
    /// profiled out: residuals `P W (x - y) / sigma` and Jacobian
    /// `P W J / sigma` ([`crate::detect::data::noise_model`],
    /// [`crate::detect::data::nuisance`]), `sigma` the data's level read as
    /// the innovation standard deviation; `N - p - nuisances` degrees of
    /// freedom.
    ///
    /// # Errors
    /// As [`Projector::new`].
    pub fn with_record_model(
        mut self,
        noise: NoiseModel,
        nuisance: Nuisance,
    ) -> Result<TimeMisfit> {
        self.projector = Projector::new(nuisance, self.data.t(), &noise)?;
        self.others = std::mem::take(&mut self.others)
            .into_iter()
            .map(|o| o.with_record_model(noise.clone(), nuisance))
            .collect::<Result<_>>()?;
        self.noise = noise;
        self.nuisance = nuisance;
        Ok(self)
    }

    /// The noise model.
    pub fn noise_model(&self) -> &NoiseModel {
        &self.noise
    }

    /// The nuisances profiled out.
    pub fn nuisance(&self) -> Nuisance {
        self.nuisance
    }

    /// Whether the residuals are the paper's `(x - y) / sigma` as they are.
    fn plain(&self) -> bool {
        self.noise.is_white() && self.projector.is_none()
    }

    /// `P W r` of a residual in the record's units (no division by sigma):
    /// `r` itself for white noise without nuisances.
    pub fn whiten(&self, r: &[f64]) -> Vec<f64> {
        let w = self.noise.filter(r);
        match &self.projector {
            Some(p) => p.project(&w),
            None => w,
        }
    }

    /// `P W m` of every column of `m` (rows = samples).
    fn whiten_columns(&self, m: DMatrix<f64>) -> DMatrix<f64> {
        if self.plain() {
            return m;
        }
        let w = self.noise.filter_columns(&m);
        match &self.projector {
            Some(p) => p.project_columns(&w),
            None => w,
        }
    }

    /// The nuisances that fit best at `chain` (`offset`, `drift`; empty
    /// without nuisances), in the record's units.
    ///
    /// # Errors
    /// As [`TimeMisfit::model`].
    pub fn nuisance_values(&self, chain: &Chain) -> Result<Vec<f64>> {
        let Some(p) = &self.projector else {
            return Ok(Vec::new());
        };
        let r: Vec<f64> = self
            .model(chain)?
            .iter()
            .zip(self.data.y())
            .map(|(a, b)| a - b)
            .collect();
        Ok(p.coefficients(&self.noise.filter(&r)))
    }

    /// The nuisance columns `[1, t]` (as many as nuisances; rows = samples),
    /// whitened by the noise model but not projected, divided by sigma: the
    /// nuisances' block of the full Jacobian `[J, B]`.
    pub fn nuisance_jacobian(&self) -> DMatrix<f64> {
        self.noise
            .filter_columns(&self.nuisance.columns(self.data.t()))
            * self.inv_sigma
    }

    /// The defect and chain-parameter block of the full Jacobian `[J, B]`:
    /// `W J / sigma`, not projected (`None` as [`TimeMisfit::jacobian`]).
    ///
    /// # Errors
    /// As [`TimeMisfit::jacobian`].
    pub fn unprojected_jacobian(
        &self,
        chain: &Chain,
        params: &[Param],
    ) -> Result<Option<DMatrix<f64>>> {
        let plain = TimeMisfit {
            projector: None,
            nuisance: Nuisance::None,
            others: Vec::new(),
            ..self.clone()
        };
        plain.jacobian(chain, params)
    }

    /// With `false`, [`TimeMisfit::jacobian`] always answers `None` (the
    /// caller then differences the residuals: the earlier path, kept as a
    /// baseline for benchmarks and tests).
    pub fn with_analytic_jacobian(mut self, analytic: bool) -> TimeMisfit {
        self.analytic = analytic;
        self.others = std::mem::take(&mut self.others)
            .into_iter()
            .map(|o| o.with_analytic_jacobian(analytic))
            .collect();
        self
    }

    /// The Jacobian of [`TimeMisfit::residuals`] with respect to `params` of
    /// `chain` (rows = samples), exact: defect values by
    /// [`Modes::value_derivative`] (the modal sum's derivative, double poles
    /// included), the uniform chain parameters and the damping models'
    /// (`d`, `k`, `mass`, `c`, `a`, `b`) by [`Modes::sites_derivative`] over
    /// their sites ([`crate::sensitivity::stiffness_terms`]), under the
    /// `modal` damping model its ratios, masses and springs by
    /// [`Modes::modal_derivative`], `gamma` as `x_1 / gamma`; one modal
    /// decomposition for all columns. `Ok(None)` where that does not apply
    /// (another measurement than the paper's, grounded dampers beside the
    /// modal model's ratios, a decomposition without simple poles, the
    /// analytic Jacobian switched off, a chain of 100 masses or more whose
    /// modes this thread has not decomposed): difference the residuals
    /// then.
    ///
    /// # Errors
    /// A defect index out of range (field `params`); as [`Modes::new`].
    /// With several sensors the rows of every sensor follow each other
    /// (`None` unless every sensor's block is exact).
    pub fn jacobian(&self, chain: &Chain, params: &[Param]) -> Result<Option<DMatrix<f64>>> {
        let Some(mut out) = self.channel_jacobian(chain, params)? else {
            return Ok(None);
        };
        for o in &self.others {
            let Some(b) = o.channel_jacobian(chain, params)? else {
                return Ok(None);
            };
            let top = out.nrows();
            out = out.resize_vertically(top + b.nrows(), 0.0);
            out.rows_mut(top, b.nrows()).copy_from(&b);
        }
        Ok(Some(out))
    }

    /// The observed mass when this sensor's model is the modal sum of the
    /// displacement after the impulse with its exact Jacobian: mass 1
    /// (the paper's measurement), or any mass as one of several sensors.
    fn modal_mass(&self) -> Option<usize> {
        let m = self.data.measurement();
        if m.is_paper() {
            return Some(1);
        }
        let displacement = m.sensor().kind == crate::forward::Observable::Displacement;
        (self.joint && m.force().is_none() && displacement).then_some(m.sensor().at)
    }

    /// [`TimeMisfit::jacobian`] of this sensor alone.
    fn channel_jacobian(&self, chain: &Chain, params: &[Param]) -> Result<Option<DMatrix<f64>>> {
        let Some(at) = self.modal_mass() else {
            return Ok(None);
        };
        if !self.analytic {
            return Ok(None);
        }
        // a long chain whose modes are not at hand: its record is simulated
        // ([`TimeMisfit::model`]), and so are the differenced residuals (a
        // modal decomposition is O(n^3): minutes at n = 1000)
        if simulated(chain) {
            return self.stepped_jacobian(chain, params, at);
        }
        with_modes(chain, |modes| self.jacobian_with(modes, chain, params, at))
    }

    /// The Jacobian of a chain whose record is simulated ([`simulated`]):
    /// the defect values' columns by reciprocity from one simulation of
    /// every mass ([`Screen::each`]: the response at mass 1 of a change at
    /// the defect's site, a convolution), where every parameter is a defect
    /// value and the data are the paper's measurement on a uniform grid;
    /// `None` otherwise (the residuals are then differenced, two
    /// simulations a parameter).
    ///
    /// # Errors
    /// A defect index out of range (field `params`); as [`Screen::each`].
    fn stepped_jacobian(
        &self,
        chain: &Chain,
        params: &[Param],
        at: usize,
    ) -> Result<Option<DMatrix<f64>>> {
        if at != 1 || !self.data.measurement().is_paper() {
            return Ok(None);
        }
        let mut cands = Vec::with_capacity(params.len());
        for p in params {
            let Param::Defect(i) = *p else {
                return Ok(None);
            };
            cands.push(DefectKind::key_of(defect_at(chain, i)?));
        }
        let Some(screen) = Screen::new(self.data.t(), self.data.y(), chain) else {
            return Ok(None);
        };
        let (_, cols) = screen.each(chain, &cands, false, |_, g| g.to_vec())?;
        let mut out = DMatrix::zeros(self.data.t().len(), params.len());
        for (c, col) in cols.iter().enumerate() {
            for (o, v) in out.column_mut(c).iter_mut().zip(col) {
                *o = v * self.inv_sigma;
            }
        }
        Ok(Some(self.whiten_columns(out)))
    }

    fn jacobian_with(
        &self,
        modes: &Modes,
        chain: &Chain,
        params: &[Param],
        at: usize,
    ) -> Result<Option<DMatrix<f64>>> {
        let t = self.data.t();
        let n = chain.n();
        let gamma = chain.gamma();
        // the derivatives over the modes first, then evaluated together
        // (they share their poles: one pass over the samples)
        enum Column {
            Sum(DoublePoleSum),
            Values(Vec<f64>),
        }
        let mut columns = Vec::with_capacity(params.len());
        for p in params {
            let col = match *p {
                Param::Defect(i) => {
                    let site = chain.site(defect_at(chain, i)?);
                    let u: Vec<(usize, f64)> = site.probe.entries(n).collect();
                    match modes.value_derivative_poly(at, 1, gamma, &u, site.poly)? {
                        Some(d) => Some(d),
                        // the proportional paths
                        None => sites_column(modes, at, gamma, &[(site, 1.0)])?,
                    }
                    .map(Column::Sum)
                }
                Param::Gamma => (gamma != 0.0)
                    .then(|| modes.response(at, 1, 1.0))
                    .transpose()?
                    .map(|r| Column::Values(r.eval_many(t))),
                Param::Zeta { index, of } => modes
                    .modal_derivative(at, 1, gamma, ModalChange::Ratio { index, of })?
                    .map(Column::Sum),
                // a uniform chain parameter: the sum of its sites
                _ => match crate::sensitivity::stiffness_terms(chain, p)? {
                    Some(terms) => sites_column(modes, at, gamma, &terms)?,
                    None => None,
                }
                .map(Column::Sum),
            };
            let Some(col) = col else {
                return Ok(None);
            };
            columns.push(col);
        }
        let sums: Vec<&DoublePoleSum> = columns
            .iter()
            .filter_map(|c| match c {
                Column::Sum(s) => Some(s),
                Column::Values(_) => None,
            })
            .collect();
        let mut evaluated = DoublePoleSum::eval_many_columns(&sums, t).into_iter();
        let mut out = DMatrix::zeros(t.len(), params.len());
        for (c, col) in columns.into_iter().enumerate() {
            let values = match col {
                Column::Sum(_) => evaluated.next().expect("one per sum"),
                Column::Values(v) => v,
            };
            for (o, v) in out.column_mut(c).iter_mut().zip(&values) {
                *o = v * self.inv_sigma;
            }
        }
        Ok(Some(self.whiten_columns(out)))
    }

    /// The data.
    pub fn data(&self) -> &TimeData {
        &self.data
    }

    /// Model of the record for `chain`: `x_1(t_i)` by the exact modal sum
    /// for the paper's measurement (for chains of 100 masses or more whose
    /// modes this thread has not just computed, and records on a uniform
    /// grid, by the sparse stepping of [`crate::detect::misfit::time_screen`],
    /// exact to rounding as well), otherwise as the data's
    /// [`Measurement`](crate::detect::data::measurement::Measurement) says
    /// (another observable or mass, a measured force).
    ///
    /// # Errors
    /// As [`ModalResponse::impulse`](crate::time::modal::ModalResponse::impulse) and
    /// [`Measurement::time_model`](crate::detect::data::measurement::Measurement::time_model).
    pub fn model(&self, chain: &Chain) -> Result<Vec<f64>> {
        let m = self.data.measurement();
        if let Some(at) = self.modal_mass().filter(|&at| at != 1) {
            // another sensor of several: the modal sum of the decomposition
            // every sensor shares
            return with_modes(chain, |modes| {
                Ok(modes
                    .response(at, 1, chain.gamma())?
                    .eval_many(self.data.t()))
            });
        }
        if m.is_paper() {
            // a long chain whose modes are not at hand: the sparse stepping
            // (O(n T), exact to rounding as the modal sum) rather than a
            // modal decomposition (O(n^3): 0.3 s at n = 300)
            if simulated(chain) {
                if let Some(grid) = TimeGrid::new(self.data.t(), chain) {
                    return Ok(simulate(chain, &grid, &[])?.x1);
                }
            }
            return with_modes(chain, |modes| {
                Ok(modes
                    .response(1, 1, chain.gamma())?
                    .eval_many(self.data.t()))
            });
        }
        m.time_model(chain, self.data.t())
    }

    /// Whitened residuals `(x_1(t_i) - y_i) / sigma` (with a noise model
    /// or nuisances: `P W (x - y) / sigma`, see
    /// [`TimeMisfit::with_record_model`]); with several sensors, each
    /// sensor's in turn, each at its own noise level.
    ///
    /// # Errors
    /// As [`TimeMisfit::model`].
    pub fn residuals(&self, chain: &Chain) -> Result<Vec<f64>> {
        let mut r = self.channel_residuals(chain)?;
        for o in &self.others {
            r.extend(o.channel_residuals(chain)?);
        }
        Ok(r)
    }

    /// [`TimeMisfit::residuals`] of this sensor alone.
    pub fn channel_residuals(&self, chain: &Chain) -> Result<Vec<f64>> {
        self.residuals_of(&self.model(chain)?)
    }

    /// This sensor's residuals of the model record `x`.
    fn residuals_of(&self, x: &[f64]) -> Result<Vec<f64>> {
        let r: Vec<f64> = x
            .iter()
            .zip(self.data.y())
            .map(|(a, b)| (a - b) * self.inv_sigma)
            .collect();
        if self.plain() {
            return Ok(r);
        }
        Ok(self.whiten(&r))
    }

    /// `chi^2 = sum (x_1(t_i) - y_i)^2 / sigma^2`.
    ///
    /// # Errors
    /// As [`TimeMisfit::model`].
    pub fn chi2(&self, chain: &Chain) -> Result<f64> {
        Ok(self.residuals(chain)?.iter().map(|r| r * r).sum())
    }
}

impl crate::detect::model::MeasurementModel for TimeMisfit {
    fn name(&self) -> &'static str {
        "time"
    }
    fn dof(&self) -> usize {
        let own = self
            .data
            .t()
            .len()
            .saturating_sub(self.noise.order() + self.nuisance.count());
        own + self
            .others
            .iter()
            .map(crate::detect::model::MeasurementModel::dof)
            .sum::<usize>()
    }
    fn residuals(&self, chain: &Chain) -> Result<Vec<f64>> {
        TimeMisfit::residuals(self, chain)
    }
    fn jacobian(&self, chain: &Chain, params: &[Param]) -> Result<Option<DMatrix<f64>>> {
        TimeMisfit::jacobian(self, chain, params)
    }
    fn near<'a>(&'a self, base: &Chain) -> Result<Near<'a>> {
        // one sensor on mass 1 of a chain that steps in a few sub-steps per
        // sample: the saved states of base's simulation ([`Saved`]). At
        // every length: a probe resumed where the impulse's front reaches
        // its change, and stopped once its first samples show it, costs less
        // than its modal sum (the hidden-defect check on System 3, n = 20:
        // 459 million instructions summed over modes, 149 million stepped)
        let stepped = self.others.is_empty()
            && self.modal_mass().is_none_or(|at| at == 1)
            && self.data.measurement().is_paper();
        let grid = near_grid(self.data.t(), base).filter(|_| stepped);
        let Some(grid) = grid else {
            return Ok(Box::new(move |c: &Chain, _: Enough<'_>| self.residuals(c)));
        };
        let saved = Saved::new(base, &grid)?;
        // without nuisances (projected out over the whole record) the
        // residuals of a record's first samples are the first residuals
        let causal = self.projector.is_none();
        Ok(Box::new(move |c: &Chain, enough: Enough<'_>| {
            let grid = near_grid(self.data.t(), c);
            let Some(g) = grid else {
                return self.residuals(c);
            };
            let x1 = saved.resume(c, &g, |x1| {
                causal && self.residuals_of(x1).is_ok_and(|r| enough(&r))
            })?;
            self.residuals_of(&x1)
        }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::chain::Defect;
    use crate::noise::NoiseLevel;

    #[test]
    fn chi2_is_a_chi_square_at_the_truth() {
        let truth = crate::scenes::paper_with(10, "mass:3:3.0 mass:7:2.0").unwrap();
        let mut sum = 0.0;
        let reps = 20;
        for seed in 0..reps {
            let data = TimeData::simulate(&truth, 100.0, 0.5, NoiseLevel::RelativeMax(1e-3), seed)
                .unwrap();
            sum += TimeMisfit::new(data).chi2(&truth).unwrap();
        }
        let mean = sum / reps as f64;
        // 201 degrees of freedom, sd of the mean sqrt(2*201/20) = 4.5
        assert!((mean - 201.0).abs() < 20.0, "mean chi2 {mean}");
    }

    /// Central differences (relative step 1e-5) of `misfit`'s residuals
    /// with respect to `params` at `truth`.
    fn differenced(misfit: &TimeMisfit, truth: &Chain, params: &[Param]) -> DMatrix<f64> {
        differenced_by(misfit, truth, params, 1e-5)
    }

    /// [`differenced`] with the step `h`.
    fn differenced_by(
        misfit: &TimeMisfit,
        truth: &Chain,
        params: &[Param],
        h: f64,
    ) -> DMatrix<f64> {
        use crate::detect::search::lsq::{central_jacobian, LeastSquares};
        struct P<'a>(&'a TimeMisfit, &'a Chain, &'a [Param]);
        impl LeastSquares for P<'_> {
            fn residuals(&self, theta: &[f64]) -> Result<Vec<f64>> {
                let mut c = self.1.clone();
                for (p, v) in self.2.iter().zip(theta) {
                    c = p.set(&c, *v)?;
                }
                self.0.residuals(&c)
            }
        }
        let theta: Vec<f64> = params.iter().map(|p| p.get(truth).unwrap()).collect();
        central_jacobian(&P(misfit, truth, params), &theta, h).unwrap()
    }

    #[test]
    fn analytic_jacobian_matches_central_differences() {
        // defects of every kind, a wall spring among them, and gamma
        let truth = crate::scenes::mixed(7).unwrap();
        let data =
            TimeData::simulate(&truth, 120.0, 0.1, NoiseLevel::RelativeMax(1e-3), 4).unwrap();
        let misfit = TimeMisfit::new(data);
        let mut params = Param::defects(&truth);
        params.push(Param::Gamma);
        let fd = differenced(&misfit, &truth, &params);
        let exact = misfit.jacobian(&truth, &params).unwrap().unwrap();
        for (c, p) in params.iter().enumerate() {
            let (a, b) = (exact.column(c), fd.column(c));
            let err = (a - b).norm() / b.norm();
            assert!(err < 1e-8, "{p:?}: relative error {err:.2e}");
        }
        // switched off, or a parameter it does not cover: None
        let off = misfit.clone().with_analytic_jacobian(false);
        assert!(off.jacobian(&truth, &params).unwrap().is_none());
        assert!(misfit.jacobian(&truth, &[Param::Defect(9)]).is_err());
    }

    /// A chain of 100 masses or more is simulated rather than decomposed:
    /// its defect values' columns come by reciprocity from one simulation,
    /// against central differences of the simulated record (a mass, an
    /// interior and a wall spring, a damper: 1e-8, 4e-10, 2e-3 for the
    /// wall spring on mass 1, 1e-6); a chain parameter beside them is left
    /// to differences (`None`).
    #[test]
    fn a_simulated_chains_defect_columns_match_central_differences() {
        let truth = Chain::paper(110)
            .and_then(|c| c.with_d(0.01))
            .and_then(|c| {
                c.with_defects([
                    Defect::Mass { at: 3, m: 1.7 },
                    Defect::Spring { at: 6, k: 0.6 },
                    Defect::Spring { at: 0, k: 1.4 },
                    Defect::Damper { at: 2, d: 0.05 },
                ])
            })
            .unwrap();
        let data =
            TimeData::simulate(&truth, 120.0, 0.2, NoiseLevel::RelativeMax(1e-3), 4).unwrap();
        let misfit = TimeMisfit::new(data);
        assert!(simulated(&truth));
        let params = Param::defects(&truth);
        let fd = differenced(&misfit, &truth, &params);
        let exact = misfit.jacobian(&truth, &params).unwrap().unwrap();
        for (c, p) in params.iter().enumerate() {
            let (a, b) = (exact.column(c), fd.column(c));
            let err = (a - b).norm() / b.norm();
            // the screen's trapezoid end correction next to mass 1 (its
            // module docs: 8e-4 for the values touching mass 1)
            let tol = if c == 2 { 3e-3 } else { 1e-5 };
            assert!(err < tol, "{p:?}: relative error {err:.2e}");
        }
        let mut with_d = params.clone();
        with_d.push(Param::D);
        assert!(misfit.jacobian(&truth, &with_d).unwrap().is_none());
    }

    /// The uniform chain parameters and the damping models' (their sites'
    /// sums) beside the defect values, against central differences of the
    /// modal sum: both modal paths (quadratic; proportional by the closed
    /// form and by the symmetric eigenproblem), overdamped modes, a free
    /// end, masses from 1e-3 to 1e3; the `modal` model's ratios, masses
    /// and springs (its modes' derivatives). Grounded dampers beside the
    /// ratios are left to differences.
    #[test]
    fn chain_parameter_jacobian_matches_central_differences_in_every_damping_model() {
        use crate::chain::{Boundary, Damping};
        let between = |c: f64| Damping::Between { c };
        let rayleigh = Damping::Rayleigh { a: 0.05, b: 0.02 };
        let modal = |zeta: Vec<f64>| Damping::Modal { zeta };
        let cases: Vec<(&str, Chain, Vec<Param>)> = vec![
            (
                "grounded, defects",
                crate::scenes::paper_with(7, "mass:3:2.0 spring:5:0.6").unwrap(),
                vec![Param::D, Param::K, Param::Mass],
            ),
            (
                "uniform (closed form)",
                Chain::paper(6).unwrap(),
                vec![Param::D, Param::K, Param::Mass],
            ),
            (
                "overdamped, uniform",
                Chain::paper(5).unwrap().with_d(2.5).unwrap(),
                vec![Param::D, Param::K, Param::Mass],
            ),
            (
                "between, a mass defect (proportional)",
                crate::scenes::paper_with(7, "mass:4:2.0")
                    .unwrap()
                    .with_d(0.0)
                    .unwrap()
                    .with_damping(between(0.08))
                    .unwrap(),
                vec![Param::C, Param::K, Param::Mass],
            ),
            (
                "between and grounded, a free end",
                crate::scenes::paper_with(6, "spring:2:1.7 damper:3:0.2")
                    .unwrap()
                    .with_boundaries(Boundary::Fixed, Boundary::Free)
                    .unwrap()
                    .with_damping(between(0.05))
                    .unwrap(),
                vec![Param::C, Param::D, Param::K, Param::Mass],
            ),
            (
                "rayleigh",
                crate::scenes::paper_with(7, "mass:2:1e-3 mass:5:1e3")
                    .unwrap()
                    .with_d(0.0)
                    .unwrap()
                    .with_damping(rayleigh)
                    .unwrap(),
                vec![Param::A, Param::B, Param::K, Param::Mass],
            ),
            (
                "modal, one ratio, uniform (closed form)",
                Chain::paper(6)
                    .unwrap()
                    .with_d(0.0)
                    .unwrap()
                    .with_damping(modal(vec![0.03]))
                    .unwrap(),
                vec![Param::Zeta { index: 0, of: 1 }, Param::K, Param::Mass],
            ),
            (
                "modal, three ratios, defects, an overdamped mode",
                crate::scenes::paper_with(7, "mass:2:1e-3 spring:5:0.6 mass:6:40")
                    .unwrap()
                    .with_d(0.0)
                    .unwrap()
                    .with_damping(modal(vec![1.4, 0.05, 0.02]))
                    .unwrap(),
                (0..3)
                    .map(|index| Param::Zeta { index, of: 3 })
                    .chain([Param::K, Param::Mass])
                    .collect(),
            ),
        ];
        for (name, truth, extra) in cases {
            let data =
                TimeData::simulate(&truth, 60.0, 0.1, NoiseLevel::RelativeMax(1e-3), 1).unwrap();
            let misfit = TimeMisfit::new(data);
            let mut params = Param::defects(&truth);
            params.extend(extra);
            // three steps: rounding limits the small ones where the modal
            // sum is least precise (the 1e-3 mass), truncation the large one
            let fds = [1e-5, 1e-4, 1e-3].map(|h| differenced_by(&misfit, &truth, &params, h));
            let exact = misfit.jacobian(&truth, &params).unwrap();
            let exact = exact.unwrap_or_else(|| panic!("{name}: no analytic Jacobian"));
            for (c, p) in params.iter().enumerate() {
                let err = fds
                    .iter()
                    .map(|fd| (exact.column(c) - fd.column(c)).norm() / fd.column(c).norm())
                    .fold(f64::INFINITY, f64::min);
                assert!(err < 1e-7, "{name}, {p:?}: relative error {err:.2e}");
            }
        }
        // grounded dampers beside the ratios: differences
        let modal = Chain::paper(5)
            .unwrap()
            .with_damping(Damping::Modal { zeta: vec![0.02] })
            .unwrap();
        let data = TimeData::simulate(&modal, 60.0, 0.1, NoiseLevel::RelativeMax(1e-3), 1).unwrap();
        let misfit = TimeMisfit::new(data);
        let zeta = Param::Zeta { index: 0, of: 1 };
        assert!(misfit.jacobian(&modal, &[zeta]).unwrap().is_none());
        assert!(misfit.jacobian(&modal, &[Param::K]).unwrap().is_none());
    }

    /// A long chain's nearby residuals stop at first rows once these are
    /// enough, and those rows are the whole vector's; with nuisances
    /// (projected over the whole record) they never stop.
    #[test]
    fn near_residuals_stop_where_enough_with_the_whole_vectors_first_rows() {
        use crate::detect::data::{noise_model::NoiseModel, nuisance::Nuisance};
        use crate::detect::model::MeasurementModel;
        let base = crate::scenes::paper_with(120, "mass:3:2.0").unwrap();
        let data =
            TimeData::simulate(&base, 240.0, 0.25, NoiseLevel::RelativeMax(1e-3), 3).unwrap();
        let deep = base
            .clone()
            .with_defect(crate::chain::Defect::parse("mass:60:2").unwrap())
            .unwrap();
        for (noise, nuisance, stops) in [
            (NoiseModel::White, Nuisance::None, true),
            (NoiseModel::ar(vec![0.5]).unwrap(), Nuisance::None, true),
            (NoiseModel::White, Nuisance::Offset, false),
        ] {
            let misfit = TimeMisfit::new(data.clone())
                .with_record_model(noise.clone(), nuisance)
                .unwrap();
            let near = misfit.near(&base).unwrap();
            let whole = misfit.residuals(&deep).unwrap();
            let all = near(&deep, &mut |_| false).unwrap();
            let mut asked = 0;
            let first = near(&deep, &mut |r| {
                asked += 1;
                r.len() >= 400
            })
            .unwrap();
            let peak = whole.iter().fold(0.0f64, |a, b| a.max(b.abs()));
            assert_eq!(all.len(), whole.len());
            assert!(all
                .iter()
                .zip(&whole)
                .all(|(a, b)| (a - b).abs() <= 1e-12 * peak));
            if stops {
                assert!(first.len() >= 400 && first.len() < 500, "{}", first.len());
                assert!(asked > 1);
                assert!(first
                    .iter()
                    .zip(&whole)
                    .all(|(a, b)| (a - b).abs() <= 1e-12 * peak));
            } else {
                assert_eq!((first.len(), asked), (whole.len(), 0), "{noise:?}");
            }
        }
    }

    /// A probe lighter than the saved chain has a finer internal grid of
    /// its own: it is stepped from rest on it, not resumed from states
    /// saved on the other grid (which gave a record off by 2e-5 of its
    /// peak here).
    #[test]
    fn near_residuals_of_a_probe_on_a_finer_grid_are_its_own() {
        use crate::detect::model::MeasurementModel;
        for (n, at, t_end) in [(8, 5, 90.0), (200, 150, 400.0), (400, 350, 200.0)] {
            let base = crate::scenes::paper_with(n, "mass:2:1.5").unwrap();
            let data =
                TimeData::simulate(&base, t_end, 0.45, NoiseLevel::RelativeMax(1e-3), 1).unwrap();
            let misfit = TimeMisfit::new(data);
            let probe = base
                .clone()
                .with_defect(crate::chain::Defect::parse(&format!("mass:{at}:0.5")).unwrap())
                .unwrap();
            let t = misfit.data().t();
            let (g0, g1) = (near_grid(t, &base).unwrap(), near_grid(t, &probe).unwrap());
            assert!(g1.sub > g0.sub, "n = {n}: {} {}", g0.sub, g1.sub);
            let whole = misfit.residuals(&probe).unwrap();
            let all = misfit.near(&base).unwrap()(&probe, &mut |_| false).unwrap();
            assert_same_record(&all, &whole, n);
        }
    }

    /// `all` is `whole` to `1e-10` of its peak (the chain of `n` masses).
    fn assert_same_record(all: &[f64], whole: &[f64], n: usize) {
        let peak = whole.iter().fold(0.0f64, |a, b| a.max(b.abs()));
        assert_eq!(all.len(), whole.len());
        let worst = all
            .iter()
            .zip(whole)
            .fold(0.0f64, |w, (a, b)| w.max((a - b).abs()));
        assert!(worst <= 1e-10 * peak, "n = {n}: {worst:e} of {peak:e}");
    }

    #[test]
    fn near_residuals_of_short_chains_are_stepped_unless_stiff() {
        use crate::detect::model::MeasurementModel;
        // short chains (summed over their modes by `residuals`): the probes
        // are stepped, to rounding the modal residuals, and stop early
        for (n, at) in [(2, 2), (5, 3), (20, 12)] {
            let base = crate::scenes::paper_with(n, "mass:1:1.5").unwrap();
            let data =
                TimeData::simulate(&base, 120.0, 0.1, NoiseLevel::RelativeMax(1e-3), 1).unwrap();
            let misfit = TimeMisfit::new(data);
            assert!(near_grid(misfit.data().t(), &base).is_some(), "n = {n}");
            let probe = base
                .clone()
                .with_defect(crate::chain::Defect::parse(&format!("spring:{at}:0.5")).unwrap())
                .unwrap();
            let whole = misfit.residuals(&probe).unwrap();
            let near = misfit.near(&base).unwrap();
            let all = near(&probe, &mut |_| false).unwrap();
            assert_same_record(&all, &whole, n);
            let first = near(&probe, &mut |r| r.len() >= 300).unwrap();
            assert!(first.len() >= 300 && first.len() < whole.len(), "n = {n}");
        }
        // a chain whose light masses need many sub-steps per sample: no
        // grid, the probes are the modal residuals themselves
        let stiff = crate::scenes::paper_with(5, "mass:3:0.001").unwrap();
        let t: Vec<f64> = (0..200).map(|i| i as f64 * 0.5).collect();
        assert!(near_grid(&t, &stiff).is_none());
    }

    #[test]
    fn whitened_and_profiled_jacobian_matches_central_differences() {
        use crate::detect::data::{noise_model::NoiseModel, nuisance::Nuisance};
        use crate::detect::model::MeasurementModel;
        let truth = crate::scenes::paper_with(8, "mass:3:3.0 spring:6:0.5").unwrap();
        let data =
            TimeData::simulate(&truth, 100.0, 0.25, NoiseLevel::RelativeMax(1e-3), 2).unwrap();
        let misfit = TimeMisfit::new(data)
            .with_record_model(
                NoiseModel::ar(vec![1.1, -0.3]).unwrap(),
                Nuisance::OffsetDrift,
            )
            .unwrap();
        assert_eq!(MeasurementModel::dof(&misfit), 401 - 2 - 2);
        let mut params = Param::defects(&truth);
        params.push(Param::Gamma);
        let fd = differenced(&misfit, &truth, &params);
        let exact = misfit.jacobian(&truth, &params).unwrap().unwrap();
        // the projection keeps the rows (rank N - p - 2)
        assert_eq!(exact.nrows(), 399);
        for (c, p) in params.iter().enumerate() {
            let err = (exact.column(c) - fd.column(c)).norm() / fd.column(c).norm();
            assert!(err < 1e-7, "{p:?}: relative error {err:.2e}");
        }
        // an offset and a drift added to the record are found, and leave
        // the residual unchanged
        let plain = misfit.residuals(&truth).unwrap();
        let y: Vec<f64> = misfit
            .data()
            .t()
            .iter()
            .zip(misfit.data().y())
            .map(|(t, y)| y + 0.02 + 1e-4 * t)
            .collect();
        let shifted = TimeData::new(misfit.data().t().to_vec(), y, misfit.data().sigma()).unwrap();
        let m2 = TimeMisfit::new(shifted)
            .with_record_model(
                NoiseModel::ar(vec![1.1, -0.3]).unwrap(),
                Nuisance::OffsetDrift,
            )
            .unwrap();
        let r2 = m2.residuals(&truth).unwrap();
        assert!(plain.iter().zip(&r2).all(|(a, b)| (a - b).abs() < 1e-8));
        let c = m2.nuisance_values(&truth).unwrap();
        let c0 = misfit.nuisance_values(&truth).unwrap();
        assert!((c[0] - c0[0] - 0.02).abs() < 1e-12 && (c[1] - c0[1] - 1e-4).abs() < 1e-14);
    }

    #[test]
    fn bad_input() {
        assert!(TimeData::new(vec![], vec![], 0.1).is_err());
        assert!(TimeData::new(vec![0.0], vec![1.0, 2.0], 0.1).is_err());
        assert!(TimeData::new(vec![0.0], vec![f64::NAN], 0.1).is_err());
        assert!(TimeData::new(vec![0.0], vec![1.0], -0.1).is_err());
        let d = TimeData::new(vec![0.0, 1.0], vec![0.0, 0.0], 0.0).unwrap();
        assert!(d.sigma_eff() > 0.0);
    }
}
