//! A chain on a [`Baseline`]: the builder and the base values the defects
//! are measured from.

use super::*;

impl Chain {
    /// The chain on the measured profile `baseline`: its `n` and ends are
    /// the table's, the masses, springs (and dampers, if the table has
    /// them) start from it and the defects apply on top
    /// ([`Defect::base_value`]). The chain's `mass` and `k` become the
    /// profile's means (the scales the fits start from); its `d` stays
    /// the grounded damper of every mass unless the table has a `damper`
    /// column.
    ///
    /// # Errors
    /// A defect that the profile's ends remove (a wall spring at a free
    /// end), field `defects[i].at`.
    ///
    /// ```
    /// use springmass::{Chain, Defect, chain::Baseline};
    /// let b = Baseline::new(vec![2.0, 1.0], vec![3.0, 2.0, 0.0], None, "")?;
    /// let c = Chain::paper(2)?.with_baseline(b)?
    ///     .with_defect(Defect::Mass { at: 2, m: 1.5 })?;
    /// assert_eq!(c.masses(), vec![2.0, 1.5]);
    /// assert_eq!(c.springs(), vec![3.0, 2.0, 0.0]);
    /// assert_eq!(Defect::Spring { at: 1, k: 9.0 }.base_value(&c), 2.0);
    /// # Ok::<(), springmass::Error>(())
    /// ```
    pub fn with_baseline(mut self, baseline: Baseline) -> Result<Chain> {
        self.n = baseline.n();
        self.mass = baseline.mean_mass();
        self.k = baseline.mean_spring();
        let (left, right) = (baseline.left(), baseline.right());
        self.baseline = Some(Arc::new(baseline));
        let defects = std::mem::take(&mut self.defects);
        self.left = left;
        self.right = right;
        self.with_defects(defects)
    }

    /// `self` on the profile of `other` (shared, not copied), when `other`
    /// has one: for a chain rebuilt from `other`'s parameters (same `n`
    /// and ends), e.g. [`crate::sensitivity::Param::set`].
    pub fn with_baseline_from(mut self, other: &Chain) -> Chain {
        self.baseline = other.baseline.clone();
        self
    }

    /// The measured profile, if the chain has one.
    pub fn baseline(&self) -> Option<&Baseline> {
        self.baseline.as_deref()
    }

    /// The same chain without its profile (uniform, with the profile's
    /// mean mass and spring).
    pub fn without_baseline(&self) -> Chain {
        Chain {
            baseline: None,
            ..self.clone()
        }
    }

    /// Refuse a chain on a [`Baseline`] where a kernel is derived for the
    /// uniform chain's closed form only.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming `baseline` and `what`.
    pub fn require_uniform(&self, what: &str) -> Result<()> {
        match &self.baseline {
            None => Ok(()),
            Some(b) => Err(Error::invalid(
                "baseline",
                b.source(),
                format!("a uniform chain (no baseline) for {what}"),
            )),
        }
    }

    /// The mass of mass `i` (1-based) without defects: the profile's, or
    /// the uniform mass (also for an index out of range).
    pub fn base_mass(&self, i: usize) -> f64 {
        match &self.baseline {
            Some(b) if (1..=self.n).contains(&i) => b.masses()[i - 1],
            _ => self.mass,
        }
    }

    /// Spring `i` (`0..=n`) without defects: the profile's (`0` at a free
    /// end), or the uniform `k`.
    pub fn base_spring(&self, i: usize) -> f64 {
        match &self.baseline {
            Some(b) if i <= self.n => b.springs()[i],
            _ => self.k,
        }
    }

    /// The damper a damper defect at `at` replaces: beside spring `at`
    /// under `between` (the profile's or `c`), else mass `at`'s grounded
    /// damper (the profile's or `d`).
    pub fn base_damper(&self, at: usize) -> f64 {
        let table = self.baseline_dampers();
        match self.damping {
            Damping::Between { c } => table.and_then(|t| t.get(at).copied()).unwrap_or(c),
            _ => match table {
                Some(t) if (1..=self.n).contains(&at) => t[at - 1],
                _ => self.d,
            },
        }
    }

    /// The profile's `n + 1` dampers, when it has a `damper` column.
    pub(super) fn baseline_dampers(&self) -> Option<&[f64]> {
        self.baseline.as_deref().and_then(Baseline::dampers)
    }
}

#[cfg(test)]
mod tests {
    use super::super::dense_ref::{self, baseline_chain};
    use super::*;
    use crate::forward::{tridiag, Forward};
    use crate::time::simulate::{matches_the_dense_reference, Method};
    use num_complex::Complex64;

    /// Baseline chains of every damping model and both end cases, with a
    /// defect of each kind.
    fn chains() -> Vec<Chain> {
        let mut out = Vec::new();
        for (ends, dampers) in [
            ((Boundary::Fixed, Boundary::Fixed), false),
            ((Boundary::Free, Boundary::Fixed), true),
            ((Boundary::Fixed, Boundary::Free), true),
        ] {
            let base = baseline_chain(9, ends, dampers)
                .with_defects(crate::scenes::defects("mass:3:2 spring:5:1.5 damper:4:0.3").unwrap())
                .unwrap();
            out.push(base.clone());
            out.push(
                base.clone()
                    .with_damping(Damping::Between { c: 0.07 })
                    .unwrap(),
            );
            out.push(
                base.with_d(0.01)
                    .unwrap()
                    .with_damping(Damping::Rayleigh { a: 0.03, b: 0.05 })
                    .unwrap(),
            );
        }
        out
    }

    #[test]
    fn profile_and_base_values() {
        let c = baseline_chain(5, (Boundary::Free, Boundary::Fixed), true);
        let b = c.baseline().unwrap().clone();
        assert_eq!(
            (c.n(), c.left(), c.right()),
            (5, Boundary::Free, Boundary::Fixed)
        );
        assert_eq!(c.masses(), b.masses());
        assert_eq!(c.springs(), b.springs());
        assert_eq!(c.dampers(), b.dampers().unwrap()[..5].to_vec());
        let d = c
            .clone()
            .with_defect(Defect::Mass { at: 2, m: 7.0 })
            .unwrap();
        assert_eq!(d.mass_at(2), 7.0);
        assert_eq!(d.mass_at(3), b.masses()[2]);
        assert_eq!(Defect::Mass { at: 3, m: 1.0 }.base_value(&d), b.masses()[2]);
        assert_eq!(
            Defect::Spring { at: 5, k: 1.0 }.base_value(&d),
            b.springs()[5]
        );
        assert_eq!(
            Defect::Damper { at: 1, d: 1.0 }.base_value(&d),
            b.dampers().unwrap()[0]
        );
        // the left wall spring does not exist in the table: refused
        let e = c
            .clone()
            .with_defect(Defect::Spring { at: 0, k: 1.0 })
            .unwrap_err();
        assert!(
            matches!(e, Error::InvalidParameter { ref field, .. } if field == "defects[0].at"),
            "{e}"
        );
        // uniform chains: the base value is the uniform one
        let u = Chain::paper(4).unwrap();
        assert_eq!(Defect::Mass { at: 2, m: 3.0 }.base_value(&u), 1.0);
        assert_eq!(Defect::Damper { at: 2, d: 3.0 }.base_value(&u), 0.1);
        // serde: the table inline, and back
        let json = serde_json::to_string(&d).unwrap();
        assert!(json.contains("\"baseline\":{"), "{json}");
        assert_eq!(serde_json::from_str::<Chain>(&json).unwrap(), d);
        assert_eq!(ChainSpec::from(&d).build().unwrap(), d);
        assert_eq!(d.without_baseline().baseline(), None);
    }

    #[test]
    fn coefficients_and_solvers_match_the_dense_reference() {
        for chain in chains() {
            let dense = dense_ref::assemble(&chain);
            let c = chain.coefficients();
            let n = chain.n();
            for i in 0..n {
                assert_eq!(c.m[i], dense.m[(i, i)]);
                assert!((c.k_diag()[i] - dense.k[(i, i)]).abs() < 1e-14);
                assert!(
                    (c.d_diag()[i] - dense.c[(i, i)]).abs() < 1e-14,
                    "{}",
                    chain.damping()
                );
            }
            let f = Forward::new(&chain);
            for s in [
                Complex64::new(0.3, 0.0),
                Complex64::new(0.05, 1.1),
                Complex64::new(2.0, -7.0),
            ] {
                for o in [1, 4, n] {
                    let want = dense_ref::solve(&chain, s, o);
                    let tol = 1e-11 * want.norm().max(1e-300);
                    let t = tridiag::solve(&chain, s, o).unwrap();
                    assert!(
                        (t - want).norm() <= tol,
                        "tridiag {} s={s}",
                        chain.damping()
                    );
                    let w = f.eval_woodbury(s, o).unwrap();
                    assert!(
                        (w - want).norm() <= 1e-10 * want.norm(),
                        "woodbury {} s={s}: {w} vs {want}",
                        chain.damping()
                    );
                }
            }
        }
    }

    #[test]
    fn simulations_match_the_matrix_exponential() {
        for chain in chains() {
            for method in [Method::Expm, Method::Rk, Method::Modal] {
                if method == Method::Modal && !chain.damping().is_grounded() {
                    continue;
                }
                matches_the_dense_reference(&chain, method, 1e-9);
            }
        }
    }
}
