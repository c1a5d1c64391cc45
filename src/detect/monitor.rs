//! Monitoring over time: has a structure changed since its baseline fit?
//!
//! Every record is fitted the same way (a whole-profile inversion,
//! [`crate::detect::fit::fit_profile`], or for output-only records
//! [`crate::detect::fit::ambient::fit_ambient`]'s profile); each fit is a [`Snapshot`]: a
//! factor per element (fitted value over the nominal one) with the
//! covariance of the factors. [`change_test`] compares a record's snapshot
//! with the baseline's:
//!
//! * `d = f_record - f_baseline`, covariance `C = C_baseline + C_record`
//!   (the two fits are independent);
//! * a **common factor**: a uniform change of every element (temperature
//!   changes every stiffness a little) moves the factors along the baseline
//!   itself, `d = c f_baseline`. Its generalised least-squares estimate
//!   `c = u'C^-1 d / u'C^-1 u` (`u = f_baseline`) is reported as the common
//!   factor `1 + c` with its standard error, and is not a defect;
//! * the **change statistic**: what is left, `chi2 = d'C^-1 d - (u'C^-1
//!   d)^2 / u'C^-1 u`, is chi-square with `m - 1` degrees of freedom when
//!   nothing but the common factor changed (`m` elements compared). The
//!   record is flagged when its p-value is below the false-alarm rate per
//!   record (`alarm_rate`, the CLI's default 0.001): on records without a
//!   change a fraction `alarm_rate` is flagged, by construction;
//! * which elements changed, when flagged: the element whose setting aside
//!   leaves the smallest chi-square of the rest is set aside, and again,
//!   until the rest passes; the common factor is then the rest's (a defect
//!   does not drag it). The standardised deviations after the common factor
//!   (`z_i = r_i / sd(r_i)`, `r = d - c u`) are reported too; the largest
//!   is not always the changed element, since a defect drags the common
//!   factor and with it every other deviation.
//!
//! The test is only as right as the covariances: the profile fit's come from
//! the Gauss-Newton approximation at its estimated noise level, and
//! elements the data do not see (NaN standard error) are left out.
//!
//! The false-alarm rate is per record over the draws of both fits. Every
//! record shares the one baseline's error, so within one run the p-values
//! are not independent: a baseline that happened to fall a standard error
//! off raises every record's statistic a little. Several reference records
//! averaged ([`Snapshot::average`]) shrink the baseline's share.
//!
//! ```
//! use springmass::detect::monitor::{change_test, Snapshot};
//! use nalgebra::DMatrix;
//! let cov = DMatrix::from_diagonal_element(3, 3, 1e-6);
//! let labels: Vec<String> = (0..3).map(|i| format!("spring {i}")).collect();
//! let base = Snapshot::new(labels.clone(), vec![1.0; 3], cov.clone()).unwrap();
//! // every spring 0.5% stiffer: a common change, not a defect
//! let warm = Snapshot::new(labels.clone(), vec![1.005; 3], cov.clone()).unwrap();
//! let t = change_test(&base, &warm, 0.001).unwrap();
//! assert!(!t.flagged && (t.common - 1.005).abs() < 1e-12);
//! // spring 1 weakened by 5% besides
//! let hurt = Snapshot::new(labels, vec![1.005, 0.955, 1.005], cov).unwrap();
//! let t = change_test(&base, &hurt, 0.001).unwrap();
//! assert!(t.flagged && t.changed[0] == 1);
//! ```

use crate::detect::fit::profile::ProfileReport;
use crate::detect::fit::select::chi2_sf;
use crate::error::{Error, Result};
use nalgebra::{DMatrix, DVector};
use serde::Serialize;

/// One fit of the monitored structure: a factor per element (value over
/// nominal) and their covariance.
#[derive(Clone, Debug)]
pub struct Snapshot {
    /// Element names (`spring 3`, `mass 2`), the same in every snapshot.
    pub labels: Vec<String>,
    /// Factors (NaN for an element the fit could not see).
    pub factors: Vec<f64>,
    /// Covariance of the factors (NaN rows for the elements not seen).
    pub cov: DMatrix<f64>,
}

impl Snapshot {
    /// A snapshot from its parts.
    ///
    /// # Errors
    /// Lengths that disagree (field `snapshot`).
    pub fn new(labels: Vec<String>, factors: Vec<f64>, cov: DMatrix<f64>) -> Result<Snapshot> {
        let m = labels.len();
        if factors.len() != m || cov.nrows() != m || cov.ncols() != m {
            return Err(Error::invalid(
                "snapshot",
                format!(
                    "{} labels, {} factors, {}x{} covariance",
                    m,
                    factors.len(),
                    cov.nrows(),
                    cov.ncols()
                ),
                "one factor and one covariance row per element",
            ));
        }
        Ok(Snapshot {
            labels,
            factors,
            cov,
        })
    }

    /// The snapshot of a whole-profile fit: factors `value / uniform`.
    ///
    /// # Errors
    /// A report without its covariance rows (field `snapshot`).
    pub fn from_profile(r: &ProfileReport) -> Result<Snapshot> {
        let rows: Vec<Row> = r
            .elements
            .iter()
            .map(|e| Row {
                label: format!("{} {}", e.kind, e.at),
                value: e.value,
                uniform: e.uniform,
            })
            .collect();
        from_rows(&rows, &r.covariance)
    }

    /// The snapshot of an output-only profile fit: its factors and their
    /// covariance.
    ///
    /// # Errors
    /// A report without its covariance (field `snapshot`).
    pub fn from_ambient(r: &crate::detect::fit::ambient::AmbientReport) -> Result<Snapshot> {
        let rows: Vec<Row> = r
            .factors
            .iter()
            .map(|f| Row {
                label: format!("{} {}", f.kind, f.at),
                value: f.factor,
                uniform: 1.0,
            })
            .collect();
        from_rows(&rows, &r.covariance)
    }

    /// The snapshot of the JSON a `springmass fit --profile MODE --json`
    /// wrote (its `elements` with `kind`, `at`, `value`, `uniform`, and its
    /// `covariance`; a missing value is `null`), or an output-only profile's
    /// (`--excitation ambient --profile MODE`: its `factors` and their
    /// `covariance`).
    ///
    /// # Errors
    /// Not that JSON (field `baseline`).
    pub fn from_profile_json(text: &str) -> Result<Snapshot> {
        let bad = |why: &str| {
            Error::invalid(
                "baseline",
                why,
                "the JSON of `springmass fit --profile MODE --json` (elements and covariance)",
            )
        };
        let v: serde_json::Value = serde_json::from_str(text).map_err(|e| bad(&e.to_string()))?;
        let num = |x: &serde_json::Value| x.as_f64().unwrap_or(f64::NAN);
        if v["target"] == "profile" && v["elements"].is_null() {
            return from_ambient_json(&v);
        }
        let elems = v["elements"].as_array().ok_or_else(|| bad("no elements"))?;
        let mut rows = Vec::with_capacity(elems.len());
        for e in elems {
            let kind = e["kind"]
                .as_str()
                .ok_or_else(|| bad("an element without kind"))?;
            let at = e["at"]
                .as_u64()
                .ok_or_else(|| bad("an element without at"))?;
            rows.push(Row {
                label: format!("{kind} {at}"),
                value: num(&e["value"]),
                uniform: num(&e["uniform"]),
            });
        }
        let cov = covariance(&v).map_err(|why| {
            bad(if why == "no covariance" {
                "no covariance (written by an older springmass?)"
            } else {
                why
            })
        })?;
        from_rows(&rows, &cov)
    }

    /// The inverse-covariance weighted mean of several fits of the same
    /// structure (several reference records: a baseline with smaller error
    /// bars). Elements some fit does not see are NaN.
    ///
    /// # Errors
    /// No snapshot, or snapshots of different elements (field `baseline`);
    /// a covariance that is not positive definite ([`Error::Unresolvable`]).
    pub fn average(snaps: &[Snapshot]) -> Result<Snapshot> {
        let first = snaps
            .first()
            .ok_or_else(|| Error::invalid("baseline", "(none)", "at least one fit"))?;
        if let Some(s) = snaps.iter().find(|s| s.labels != first.labels) {
            return Err(Error::invalid(
                "baseline",
                s.labels.join(","),
                format!("the same elements in every fit: {}", first.labels.join(",")),
            ));
        }
        let m = first.labels.len();
        let seen: Vec<usize> = (0..m)
            .filter(|&i| {
                snaps
                    .iter()
                    .all(|s| s.factors[i].is_finite() && s.cov[(i, i)] > 0.0)
            })
            .collect();
        let k = seen.len();
        let (mut info, mut rhs) = (DMatrix::zeros(k, k), DVector::zeros(k));
        for s in snaps {
            let c = DMatrix::from_fn(k, k, |a, b| s.cov[(seen[a], seen[b])]);
            let f = DVector::from_fn(k, |a, _| s.factors[seen[a]]);
            let w = c.try_inverse().ok_or_else(not_pd)?;
            rhs += &w * f;
            info += w;
        }
        let cov = info.try_inverse().ok_or_else(not_pd)?;
        let mean = &cov * rhs;
        let mut factors = vec![f64::NAN; m];
        let mut full = DMatrix::from_element(m, m, f64::NAN);
        for (a, &i) in seen.iter().enumerate() {
            factors[i] = mean[a];
            for (b, &j) in seen.iter().enumerate() {
                full[(i, j)] = cov[(a, b)];
            }
        }
        Snapshot::new(first.labels.clone(), factors, full)
    }

    /// Standard errors of the factors.
    pub fn ses(&self) -> Vec<f64> {
        self.cov.diagonal().iter().map(|v| v.sqrt()).collect()
    }
}

/// The error of a covariance that cannot be inverted.
fn not_pd() -> Error {
    Error::Unresolvable {
        reason: "a covariance of the factors is not positive definite".into(),
    }
}

/// One element as a profile reports it.
struct Row {
    label: String,
    value: f64,
    uniform: f64,
}

/// The snapshot of an output-only profile's JSON (`springmass fit
/// --excitation ambient --profile MODE --json`: its `factors` with `kind`,
/// `at`, `factor`, and the factors' `covariance`).
fn from_ambient_json(v: &serde_json::Value) -> Result<Snapshot> {
    let bad = |why: &str| {
        Error::invalid(
            "baseline",
            why,
            "the JSON of `springmass fit --excitation ambient --profile MODE --json` (factors and covariance)",
        )
    };
    let num = |x: &serde_json::Value| x.as_f64().unwrap_or(f64::NAN);
    let factors = v["factors"].as_array().ok_or_else(|| bad("no factors"))?;
    let mut rows = Vec::with_capacity(factors.len());
    for f in factors {
        let kind = f["kind"]
            .as_str()
            .ok_or_else(|| bad("a factor without kind"))?;
        let at = f["at"].as_u64().ok_or_else(|| bad("a factor without at"))?;
        rows.push(Row {
            label: format!("{kind} {at}"),
            value: num(&f["factor"]),
            uniform: 1.0,
        });
    }
    // an output-only report writes an empty list when it has none
    let cov = covariance(v)
        .and_then(|c| {
            if c.is_empty() {
                Err("no covariance")
            } else {
                Ok(c)
            }
        })
        .map_err(bad)?;
    from_rows(&rows, &cov)
}

/// The `covariance` rows of a fit's JSON (`null` entries NaN), or why not.
fn covariance(v: &serde_json::Value) -> std::result::Result<Vec<Vec<f64>>, &'static str> {
    let num = |x: &serde_json::Value| x.as_f64().unwrap_or(f64::NAN);
    v["covariance"]
        .as_array()
        .ok_or("no covariance")?
        .iter()
        .map(|row| row.as_array().map(|r| r.iter().map(num).collect()))
        .collect::<Option<Vec<Vec<f64>>>>()
        .ok_or("a covariance row that is not a list")
}

/// Factors and their covariance from values over uniform values.
fn from_rows(rows: &[Row], cov: &[Vec<f64>]) -> Result<Snapshot> {
    let m = rows.len();
    if cov.len() != m || cov.iter().any(|r| r.len() != m) {
        return Err(Error::invalid(
            "snapshot",
            format!("{m} elements, {} covariance rows", cov.len()),
            "an m x m covariance for m elements",
        ));
    }
    let factors: Vec<f64> = rows.iter().map(|r| r.value / r.uniform).collect();
    let cov = DMatrix::from_fn(m, m, |i, j| cov[i][j] / (rows[i].uniform * rows[j].uniform));
    Snapshot::new(rows.iter().map(|r| r.label.clone()).collect(), factors, cov)
}

/// The change test of one record against the baseline (see the module docs).
#[derive(Clone, Debug, Serialize)]
pub struct ChangeTest {
    /// The common factor `1 + c`: every element's change that is one
    /// uniform factor (a temperature drift); when flagged, estimated from
    /// the elements that did not change.
    pub common: f64,
    /// Its standard error.
    pub common_se: f64,
    /// The change statistic (chi-square after the common factor).
    pub chi2: f64,
    /// Its degrees of freedom (elements compared - 1).
    pub dof: usize,
    /// Its p-value.
    pub p_value: f64,
    /// `p_value < alarm_rate`.
    pub flagged: bool,
    /// Standardised deviation of each element after the common factor (NaN
    /// for an element left out).
    pub z: Vec<f64>,
    /// When flagged: the elements that changed, in the order they were set
    /// aside (each the one that leaves the smallest chi-square, until the
    /// rest passes the test at `alarm_rate`). Empty when not flagged.
    pub changed: Vec<usize>,
}

/// Compare `rec` with `base` at the false-alarm rate `alarm_rate` per record.
///
/// # Errors
/// An alarm rate outside (0, 1) (field `alarm_rate`); snapshots of
/// different elements (field `snapshot`); fewer than two elements seen by
/// both fits, or a combined covariance that is not positive definite
/// ([`Error::Unresolvable`]).
pub fn change_test(base: &Snapshot, rec: &Snapshot, alarm_rate: f64) -> Result<ChangeTest> {
    crate::error::check_f64(
        "alarm_rate",
        alarm_rate,
        alarm_rate > 0.0 && alarm_rate < 1.0,
        "in (0, 1): the false-alarm probability per record",
    )?;
    if base.labels != rec.labels {
        return Err(Error::invalid(
            "snapshot",
            rec.labels.join(","),
            format!("the baseline's elements: {}", base.labels.join(",")),
        ));
    }
    let mut used = compared(base, rec);
    let m = used.len();
    if m < 2 {
        return Err(Error::Unresolvable {
            reason: format!(
                "only {m} element(s) seen by both the baseline and the record: a change cannot be told from the common factor"
            ),
        });
    }
    let full = projected(base, rec, &used)?;
    let flagged = full.p_value < alarm_rate;
    let mut z = vec![f64::NAN; base.labels.len()];
    for (k, &i) in used.iter().enumerate() {
        z[i] = full.z[k];
    }
    // which elements changed: the one whose setting aside leaves the
    // smallest chi-square, again until the rest passes; the common factor
    // from the rest
    let mut changed = Vec::new();
    let mut rest = full.clone();
    while flagged && used.len() > 2 {
        let (k, best) = best_left_out(base, rec, &used)?;
        changed.push(used.remove(k));
        rest = best;
        if rest.p_value >= alarm_rate {
            break;
        }
    }
    if flagged && changed.is_empty() {
        // two elements: the larger deviation
        let worst = (0..used.len()).max_by(|&a, &b| full.z[a].abs().total_cmp(&full.z[b].abs()));
        changed.extend(worst.map(|k| used[k]));
    }
    Ok(ChangeTest {
        common: 1.0 + rest.c,
        common_se: rest.c_se,
        chi2: full.chi2,
        dof: m - 1,
        p_value: full.p_value,
        flagged,
        z,
        changed,
    })
}

/// The element of `used` (its index there) whose setting aside explains
/// the most: the smallest chi-square of the rest, and that projection.
fn best_left_out(base: &Snapshot, rec: &Snapshot, used: &[usize]) -> Result<(usize, Projected)> {
    let mut best: Option<(usize, Projected)> = None;
    for k in 0..used.len() {
        let rest: Vec<usize> = used.iter().copied().filter(|&i| i != used[k]).collect();
        let p = projected(base, rec, &rest)?;
        if best.as_ref().is_none_or(|(_, b)| p.chi2 < b.chi2) {
            best = Some((k, p));
        }
    }
    best.ok_or_else(|| Error::Unresolvable {
        reason: "no element to set aside".into(),
    })
}

/// The projection of one comparison over the elements `used`.
#[derive(Clone, Debug)]
struct Projected {
    /// The common change `c` and its standard error.
    c: f64,
    c_se: f64,
    chi2: f64,
    p_value: f64,
    /// Standardised residuals, in the order of `used`.
    z: Vec<f64>,
}

/// The common change of `rec` from `base` over `used`, the chi-square of
/// what is left and its standardised residuals (see the module docs).
fn projected(base: &Snapshot, rec: &Snapshot, used: &[usize]) -> Result<Projected> {
    let m = used.len();
    let pick = |s: &Snapshot| DMatrix::from_fn(m, m, |a, b| s.cov[(used[a], used[b])]);
    let c = pick(base) + pick(rec);
    let d = DVector::from_fn(m, |a, _| rec.factors[used[a]] - base.factors[used[a]]);
    let u = DVector::from_fn(m, |a, _| base.factors[used[a]]);
    let chol = c.clone().cholesky().ok_or_else(|| Error::Unresolvable {
        reason: "the combined covariance of the baseline and the record is not positive definite"
            .into(),
    })?;
    let (ci_d, ci_u) = (chol.solve(&d), chol.solve(&u));
    let a = u.dot(&ci_u);
    let cc = ci_u.dot(&d) / a;
    let chi2 = (d.dot(&ci_d) - cc * cc * a).max(0.0);
    // the residual after the common change and its covariance C - u u'/a
    let r = &d - &u * cc;
    let z = (0..m)
        .map(|k| {
            let var = c[(k, k)] - u[k] * u[k] / a;
            if var > 0.0 {
                r[k] / var.sqrt()
            } else {
                0.0
            }
        })
        .collect();
    Ok(Projected {
        c: cc,
        c_se: (1.0 / a).sqrt(),
        chi2,
        p_value: chi2_sf(chi2, (m - 1) as f64),
        z,
    })
}

/// The elements with a finite factor and variance in both snapshots.
fn compared(base: &Snapshot, rec: &Snapshot) -> Vec<usize> {
    let ok = |s: &Snapshot, i: usize| {
        s.factors[i].is_finite() && s.cov[(i, i)].is_finite() && s.cov[(i, i)] > 0.0
    };
    (0..base.labels.len())
        .filter(|&i| ok(base, i) && ok(rec, i))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_distr::{Distribution, StandardNormal};

    /// A correlated covariance of a chain's springs: neighbours negatively
    /// correlated, as a profile fit's are.
    fn chain_cov(m: usize, sd: f64) -> DMatrix<f64> {
        DMatrix::from_fn(m, m, |i, j| match i.abs_diff(j) {
            0 => sd * sd,
            1 => -0.4 * sd * sd,
            _ => 0.0,
        })
    }

    fn labels(m: usize) -> Vec<String> {
        (0..m).map(|i| format!("spring {i}")).collect()
    }

    /// A draw of factors `mean + N(0, cov)`.
    fn draw(mean: &[f64], cov: &DMatrix<f64>, rng: &mut rand_chacha::ChaCha8Rng) -> Vec<f64> {
        let l = cov.clone().cholesky().unwrap().l();
        let e = DVector::from_fn(mean.len(), |_, _| StandardNormal.sample(rng));
        let x = l * e;
        mean.iter().zip(x.iter()).map(|(a, b)| a + b).collect()
    }

    #[test]
    fn false_alarm_rate_on_null_data_with_a_drift() {
        // 20 000 null records (a common drift, no defect) at a 1% rate:
        // the count is binomial(20000, 0.01), mean 200, sd 14
        let (m, sd, rate) = (6, 2e-3, 0.01);
        let cov = chain_cov(m, sd);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(29);
        let f0 = vec![1.0, 0.95, 1.02, 1.0, 0.9, 1.1];
        let base = Snapshot::new(labels(m), f0.clone(), cov.clone()).unwrap();
        let mut flags = 0;
        let mut common_err: f64 = 0.0;
        for r in 0..20_000 {
            let drift = 1.0 + 0.005 * r as f64 / 20_000.0;
            let mean: Vec<f64> = f0.iter().map(|f| f * drift).collect();
            let truth_base = draw(&f0, &cov, &mut rng);
            let b = Snapshot::new(labels(m), truth_base, cov.clone()).unwrap();
            let rec = Snapshot::new(labels(m), draw(&mean, &cov, &mut rng), cov.clone()).unwrap();
            let t = change_test(&b, &rec, rate).unwrap();
            flags += usize::from(t.flagged);
            common_err = common_err.max(((t.common - drift) / t.common_se).abs());
        }
        assert!((150..=250).contains(&flags), "{flags} false alarms");
        // the common factor within its error bars (5 SE over 20 000 draws)
        assert!(common_err < 5.0, "{common_err}");
        // the same test on the fixed baseline object is well formed
        assert_eq!(base.ses().len(), m);
    }

    #[test]
    fn a_defect_is_flagged_and_located_through_the_drift() {
        let (m, sd) = (6, 2e-3);
        let cov = chain_cov(m, sd);
        let base = Snapshot::new(labels(m), vec![1.0; m], cov.clone()).unwrap();
        let mut f = vec![1.004; m];
        f[3] *= 0.97;
        let rec = Snapshot::new(labels(m), f, cov).unwrap();
        let t = change_test(&base, &rec, 0.001).unwrap();
        assert!(t.flagged && t.p_value < 1e-6, "{t:?}");
        assert_eq!(t.changed, vec![3]);
        // the common factor from the other springs: not dragged by the defect
        assert!((t.common - 1.004).abs() < 3.0 * t.common_se, "{t:?}");
    }

    #[test]
    fn hidden_elements_are_left_out_and_bad_input_is_named() {
        let m = 4;
        let mut cov = chain_cov(m, 1e-3);
        for k in 0..m {
            cov[(0, k)] = f64::NAN;
            cov[(k, 0)] = f64::NAN;
        }
        let mut f = vec![1.0; m];
        f[0] = f64::NAN;
        let base = Snapshot::new(labels(m), f.clone(), cov.clone()).unwrap();
        let t = change_test(&base, &base, 0.001).unwrap();
        assert_eq!(t.dof, 2);
        assert!(t.z[0].is_nan() && !t.flagged);
        let e = change_test(&base, &base, 0.0).unwrap_err();
        assert!(e.to_string().contains("alarm_rate"), "{e}");
        let other = Snapshot::new(vec!["a".into(); m], f, cov.clone()).unwrap();
        assert!(change_test(&base, &other, 0.01).is_err());
        let one = Snapshot::new(labels(1), vec![1.0], DMatrix::from_element(1, 1, 1e-6)).unwrap();
        assert!(matches!(
            change_test(&one, &one, 0.01),
            Err(Error::Unresolvable { .. })
        ));
        assert!(Snapshot::new(labels(2), vec![1.0], cov).is_err());
    }

    #[test]
    fn several_reference_fits_average_to_a_tighter_baseline() {
        let m = 3;
        let cov = chain_cov(m, 1e-3);
        let a = Snapshot::new(labels(m), vec![1.0, 0.99, 1.02], cov.clone()).unwrap();
        let b = Snapshot::new(labels(m), vec![1.002, 0.97, 1.0], cov.clone()).unwrap();
        let avg = Snapshot::average(&[a.clone(), b]).unwrap();
        for (i, want) in [1.001, 0.98, 1.01].iter().enumerate() {
            assert!((avg.factors[i] - want).abs() < 1e-12, "{:?}", avg.factors);
            for j in 0..m {
                assert!((avg.cov[(i, j)] - cov[(i, j)] / 2.0).abs() < 1e-15);
            }
        }
        assert!(Snapshot::average(&[]).is_err());
        let other = Snapshot::new(vec!["x".into(); m], vec![1.0; m], cov).unwrap();
        assert!(Snapshot::average(&[a, other]).is_err());
    }

    #[test]
    fn reads_the_profile_json() {
        let text = r#"{"elements":[
            {"kind":"spring","at":0,"value":2.0,"se":0.02,"uniform":2.0},
            {"kind":"spring","at":1,"value":1.8,"se":null,"uniform":2.0}],
            "covariance":[[4e-4,null],[null,null]]}"#;
        let s = Snapshot::from_profile_json(text).unwrap();
        assert_eq!(s.labels, vec!["spring 0", "spring 1"]);
        assert_eq!(s.factors, vec![1.0, 0.9]);
        assert!((s.cov[(0, 0)] - 1e-4).abs() < 1e-18 && s.cov[(1, 1)].is_nan());
        let e = Snapshot::from_profile_json(r#"{"elements":[]}"#).unwrap_err();
        assert!(e.to_string().contains("covariance"), "{e}");
        assert!(Snapshot::from_profile_json("not json").is_err());
    }
}
