//! The damping models of a chain ([`Damping`]).

use super::*;

/// How the chain dissipates energy: where its dampers sit.
///
/// | model | `C` in `M x'' + C x' + K x = f` | uniform parameters |
/// |---|---|---|
/// | `grounded` (the paper's, default) | `diag(d_i)`: a damper from every mass to the ground | `d` |
/// | `between` | `diag(d_i) + Lap(c_j)`: a damper `c_j` parallel to every spring (the wall springs included), as between the storeys of a building | `c` (and `d`, usually 0) |
/// | `rayleigh` | `a M + b K` (`M`, `K` with the defects) plus `diag(d_i)` | `a`, `b` (and `d`, usually 0) |
/// | `modal` | every undamped mode `j` of the chain (defects included) damped with its ratio `zeta_j`: `M Phi diag(2 zeta_j omega_j) Phi^T M`, plus `diag(d_i)` | `zeta` (one ratio for every mode) or `zeta_1, zeta_2, ..` (one per mode, the last for every higher mode), and `d`, usually 0 |
///
/// The modal model's `C` is a full matrix: its responses are exact modal
/// sums ([`crate::time::modal`], [`crate::forward::response`]), and
/// the Laplace-domain code that needs a tridiagonal `K(s)` (the fit's
/// Laplace screens) works with its Rayleigh stand-in
/// ([`Damping::tridiagonal`]), never as an answer. It has no damper defects
/// (its dampers are not physical elements).
///
/// A damper defect (`damper:at:value`) changes one damper of the model: the
/// grounded damper of mass `at` (`grounded`, `rayleigh`: an added damper to
/// the ground there) or the damper parallel to spring `at` (`between`,
/// `0..=n`). In `rayleigh` a mass defect changes its damping by `a dm` and a
/// spring (or ground spring) defect by `b dk` ([`Chain::site`]).
///
/// ```
/// use springmass::chain::Damping;
/// assert_eq!("rayleigh".parse::<Damping>()?.name(), "rayleigh");
/// assert_eq!(Damping::default(), Damping::Grounded);
/// # Ok::<(), springmass::Error>(())
/// ```
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(
    tag = "model",
    rename_all = "lowercase",
    deny_unknown_fields,
    try_from = "DampingRepr"
)]
pub enum Damping {
    /// Dampers from each mass to the ground (the chain's `d`).
    #[default]
    Grounded,
    /// Dampers `c` parallel to the springs.
    Between {
        /// Damping of every spring's damper, `>= 0`.
        c: f64,
    },
    /// `C = a M + b K`.
    Rayleigh {
        /// Mass-proportional coefficient, `>= 0` (1/time).
        a: f64,
        /// Stiffness-proportional coefficient, `>= 0` (time).
        b: f64,
    },
    /// Damping ratios of the undamped modes.
    Modal {
        /// The ratios of the modes in the order of their frequencies, each
        /// `0 <= zeta <= 4`: one value for every mode, or one per mode with
        /// the last for every higher mode (at least one, at most
        /// [`Damping::MAX_RATIOS`]). Written as a number when there is one.
        #[serde(serialize_with = "ratios_as_written")]
        zeta: Vec<f64>,
    },
}

/// One ratio as a number, several as a list.
fn ratios_as_written<S: serde::Serializer>(
    zeta: &[f64],
    s: S,
) -> std::result::Result<S::Ok, S::Error> {
    match zeta {
        [one] => s.serialize_f64(*one),
        many => many.serialize(s),
    }
}

/// A modal ratio in a scene's table: a number or a list.
#[derive(Deserialize)]
#[serde(untagged)]
enum Ratios {
    One(f64),
    PerMode(Vec<f64>),
}

/// A damping model as scene files write it: the table
/// `{ model = "rayleigh", a = 0.01, b = 0.02 }` or the text
/// `"rayleigh:0.01:0.02"` ([`Damping::parse_spec`], every parameter given).
#[derive(Deserialize)]
#[serde(untagged)]
enum DampingRepr {
    Text(String),
    Table(DampingTable),
}

#[derive(Deserialize)]
#[serde(tag = "model", rename_all = "lowercase", deny_unknown_fields)]
enum DampingTable {
    Grounded,
    Between { c: f64 },
    Rayleigh { a: f64, b: f64 },
    Modal { zeta: Ratios },
}

impl TryFrom<DampingRepr> for Damping {
    type Error = Error;
    fn try_from(r: DampingRepr) -> Result<Damping> {
        let d = match r {
            DampingRepr::Text(t) => Damping::parse_complete(&t)?,
            DampingRepr::Table(DampingTable::Grounded) => Damping::Grounded,
            DampingRepr::Table(DampingTable::Between { c }) => Damping::Between { c },
            DampingRepr::Table(DampingTable::Rayleigh { a, b }) => Damping::Rayleigh { a, b },
            DampingRepr::Table(DampingTable::Modal { zeta }) => Damping::Modal {
                zeta: match zeta {
                    Ratios::One(z) => vec![z],
                    Ratios::PerMode(z) => z,
                },
            },
        };
        d.check()?;
        Ok(d)
    }
}

impl Damping {
    /// Every model's name.
    pub const MODELS: [&'static str; 4] = ["grounded", "between", "rayleigh", "modal"];

    /// `grounded`, `between`, `rayleigh` or `modal`.
    pub fn name(&self) -> &'static str {
        match self {
            Damping::Grounded => "grounded",
            Damping::Between { .. } => "between",
            Damping::Rayleigh { .. } => "rayleigh",
            Damping::Modal { .. } => "modal",
        }
    }

    /// The paper's model.
    pub fn is_grounded(&self) -> bool {
        *self == Damping::Grounded
    }

    /// The `modal` model (a full `C`: see [`Damping::tridiagonal`]).
    pub fn is_modal(&self) -> bool {
        matches!(self, Damping::Modal { .. })
    }

    /// The model's own parameters `(name, value)` (none for `grounded`,
    /// whose parameter is the chain's `d`): `c`; `a`, `b`; `zeta` for one
    /// modal ratio, `zeta_1`, `zeta_2`, .. for one per mode.
    pub fn params(&self) -> Vec<(String, f64)> {
        match self {
            Damping::Grounded => vec![],
            Damping::Between { c } => vec![("c".into(), *c)],
            Damping::Rayleigh { a, b } => vec![("a".into(), *a), ("b".into(), *b)],
            Damping::Modal { zeta } => zeta
                .iter()
                .enumerate()
                .map(|(j, &z)| (Damping::ratio_name(j, zeta.len()), z))
                .collect(),
        }
    }

    /// The name of modal ratio `j` (0-based) of `count`: `zeta` alone,
    /// else `zeta_{j+1}`.
    pub fn ratio_name(j: usize, count: usize) -> String {
        if count == 1 {
            "zeta".into()
        } else {
            format!("zeta_{}", j + 1)
        }
    }

    /// One damping ratio `zeta` for every mode.
    pub fn modal(zeta: f64) -> Damping {
        Damping::Modal { zeta: vec![zeta] }
    }

    /// The ratio of the mode of rank `j` (0-based, in the order of the
    /// frequencies) under the modal model: its own, or the last one given
    /// for every higher mode; 0 for another model.
    pub fn modal_ratio(&self, j: usize) -> f64 {
        match self {
            Damping::Modal { zeta } => zeta.get(j).or(zeta.last()).copied().unwrap_or(0.0),
            _ => 0.0,
        }
    }

    /// The modal ratio of each of `omega2` (squared frequencies in any
    /// order): the ratio of its rank among them ([`Damping::modal_ratio`];
    /// ties keep their order).
    pub fn modal_ratios_of(&self, omega2: &[f64]) -> Vec<f64> {
        let mut order: Vec<usize> = (0..omega2.len()).collect();
        order.sort_by(|&a, &b| omega2[a].total_cmp(&omega2[b]));
        let mut out = vec![0.0; omega2.len()];
        for (rank, &i) in order.iter().enumerate() {
            out[i] = self.modal_ratio(rank);
        }
        out
    }

    /// The same model with its parameters `values` (in the order of
    /// [`Damping::params`]; missing values keep the current ones; a modal
    /// model takes as many ratios as given, if more than it had).
    pub fn with_params(self, values: &[f64]) -> Damping {
        let v = |i: usize, old: f64| values.get(i).copied().unwrap_or(old);
        match self {
            Damping::Grounded => Damping::Grounded,
            Damping::Between { c } => Damping::Between { c: v(0, c) },
            Damping::Rayleigh { a, b } => Damping::Rayleigh {
                a: v(0, a),
                b: v(1, b),
            },
            Damping::Modal { zeta } => Damping::Modal {
                zeta: (0..zeta.len().max(values.len()))
                    .map(|i| v(i, zeta.get(i).copied().unwrap_or(0.0)))
                    .collect(),
            },
        }
    }

    /// The model `name` with parameters `c`, `a`, `b` where it needs them.
    ///
    /// # Errors
    /// An unknown name (field `damping`); a parameter the model needs that
    /// is `None` (field `damping`, naming the parameter); a negative or
    /// non-finite value (field `damping.c`, `damping.a`, `damping.b`).
    pub fn build(name: &str, c: Option<f64>, a: Option<f64>, b: Option<f64>) -> Result<Damping> {
        let need = |v: Option<f64>, p: &str| {
            v.ok_or_else(|| {
                Error::invalid(
                    "damping",
                    name,
                    format!("the {name} model needs its parameter {p} (give it, or fit it with --fit d)"),
                )
            })
        };
        let model: Damping = name.parse()?;
        let out = match model {
            Damping::Grounded => Damping::Grounded,
            Damping::Between { .. } => Damping::Between { c: need(c, "c")? },
            Damping::Rayleigh { .. } => Damping::Rayleigh {
                a: need(a, "a")?,
                b: need(b, "b")?,
            },
            Damping::Modal { .. } => Damping::modal(need(c, "zeta (passed as c)")?),
        };
        out.check()?;
        Ok(out)
    }

    /// Parse `MODEL[:P1[:P2]]`: `grounded`, `between[:c]`,
    /// `rayleigh[:a:b]`, `modal[:zeta]` or `modal:zeta_1,zeta_2,..` (one
    /// ratio per mode, the last for every higher mode). Returns the model
    /// (missing parameters 0) and the names of the parameters not given.
    ///
    /// # Errors
    /// An unknown model or a parameter that is not a number (field
    /// `damping`); too many parameters (field `damping`); a negative or
    /// non-finite one (`damping.c`, `damping.a`, `damping.b`), a ratio out
    /// of `0..=4` (`damping.zeta`).
    ///
    /// ```
    /// use springmass::chain::Damping;
    /// let (d, missing) = Damping::parse_spec("rayleigh:0.01")?;
    /// assert_eq!(d, Damping::Rayleigh { a: 0.01, b: 0.0 });
    /// assert_eq!(missing, vec!["b"]);
    /// let (d, _) = Damping::parse_spec("modal:0.01,0.02,0.05")?;
    /// assert_eq!(d.modal_ratio(1), 0.02);
    /// assert_eq!(d.modal_ratio(7), 0.05);
    /// # Ok::<(), springmass::Error>(())
    /// ```
    pub fn parse_spec(text: &str) -> Result<(Damping, Vec<&'static str>)> {
        let mut parts = text.split(':').map(str::trim);
        let model: Damping = parts.next().unwrap_or("").parse()?;
        let number = |p: &str| {
            p.trim().parse::<f64>().map_err(|_| {
                Error::parse(
                    "damping",
                    text,
                    "MODEL[:P1[:P2]], e.g. between:0.05, rayleigh:0.01:0.02, modal:0.02 or modal:0.01,0.02,0.03, with numbers",
                )
            })
        };
        let rest: Vec<&str> = parts.collect();
        if model.is_modal() {
            return match rest.as_slice() {
                [] => Ok((model, vec!["zeta"])),
                [list] => {
                    let zeta = list.split(',').map(number).collect::<Result<Vec<f64>>>()?;
                    let out = Damping::Modal { zeta };
                    out.check()?;
                    Ok((out, vec![]))
                }
                _ => Err(Error::invalid(
                    "damping",
                    text,
                    "modal:ZETA (one ratio for every mode) or modal:ZETA_1,ZETA_2,.. (one per mode, the last for every higher mode)",
                )),
            };
        }
        let values: Vec<f64> = rest.into_iter().map(number).collect::<Result<_>>()?;
        let names: Vec<&'static str> = match model {
            Damping::Between { .. } => vec!["c"],
            Damping::Rayleigh { .. } => vec!["a", "b"],
            _ => vec![],
        };
        if values.len() > names.len() {
            return Err(Error::invalid(
                "damping",
                text,
                format!(
                    "at most {} parameter(s) for the {} model ({})",
                    names.len(),
                    model.name(),
                    if names.is_empty() {
                        "none: its damping is the chain's d".to_string()
                    } else {
                        names.join(", ")
                    }
                ),
            ));
        }
        let out = model.with_params(&values);
        out.check()?;
        Ok((out, names[values.len()..].to_vec()))
    }

    /// [`Damping::parse_spec`] with every parameter given.
    ///
    /// # Errors
    /// As [`Damping::parse_spec`]; a parameter missing (field `damping`).
    pub fn parse_complete(text: &str) -> Result<Damping> {
        let (d, missing) = Damping::parse_spec(text)?;
        if let Some(p) = missing.first() {
            return Err(Error::invalid(
                "damping",
                text,
                format!(
                    "the {} model needs its parameter {p} (e.g. between:0.05, rayleigh:0.01:0.02, modal:0.02), or fit it with --fit d",
                    d.name()
                ),
            ));
        }
        Ok(d)
    }

    /// Every parameter finite and `>= 0` (a modal ratio at most
    /// [`Damping::MAX_ZETA`], from 1 to [`Damping::MAX_RATIOS`] of them).
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming `damping.<parameter>` and the range.
    pub fn check(&self) -> Result<()> {
        if let Damping::Modal { zeta } = self {
            if zeta.is_empty() || zeta.len() > Self::MAX_RATIOS {
                return Err(Error::invalid(
                    "damping.zeta",
                    format!("{} ratios", zeta.len()),
                    format!(
                        "1 to {} damping ratios (the last one applies to every higher mode)",
                        Self::MAX_RATIOS
                    ),
                ));
            }
            for (j, &z) in zeta.iter().enumerate() {
                let field = if zeta.len() == 1 {
                    "damping.zeta".to_string()
                } else {
                    format!("damping.zeta[{j}]")
                };
                check_f64(
                    &field,
                    z,
                    (0.0..=Self::MAX_ZETA).contains(&z),
                    "0 <= zeta <= 4 (a damping ratio)",
                )?;
            }
            return Ok(());
        }
        for (p, v) in self.params() {
            check_f64(&format!("damping.{p}"), v, v >= 0.0, ">= 0 and finite")?;
        }
        Ok(())
    }

    /// The most modal damping ratios a model holds (one per mode; the last
    /// applies to every higher mode).
    pub const MAX_RATIOS: usize = 10_000;

    /// The largest modal damping ratio accepted.
    pub const MAX_ZETA: f64 = 4.0;

    /// The model as the tridiagonal `K(s) = M s^2 + C s + K` of a chain with
    /// undamped frequencies `omegas` (ascending) can hold it: itself, except
    /// `modal`, whose full `C` is replaced by the Rayleigh damping
    /// `a M + b K` whose ratio `a / (2 omega) + b omega / 2` is closest to
    /// each mode's `zeta_j` over `omegas` (least squares, `a, b >= 0`, each
    /// mode weighted by `1 / omega_j^3`, as its share of a displacement
    /// record after a blow: amplitude `1 / omega_j`, ringing time
    /// `1 / (zeta_j omega_j)`; with a ratio per mode, an unweighted fit
    /// followed the many high modes and the screens lost the true defects).
    /// Only the fit's Laplace screens use that stand-in; every response of
    /// a modal chain is its exact modal sum.
    ///
    /// ```
    /// use springmass::chain::Damping;
    /// let Damping::Rayleigh { a, b } = Damping::modal(0.02).tridiagonal(&[1.0]) else {
    ///     unreachable!()
    /// };
    /// assert!((a / 2.0 + b / 2.0 - 0.02).abs() < 1e-15);
    /// ```
    pub fn tridiagonal(&self, omegas: &[f64]) -> Damping {
        if !self.is_modal() {
            return self.clone();
        }
        // (omega, its target ratio), the rigid-body modes left out
        let w: Vec<(f64, f64)> = omegas
            .iter()
            .enumerate()
            .filter(|(_, w)| **w > 0.0)
            .map(|(j, &w)| (w, self.modal_ratio(j)))
            .collect();
        if w.is_empty() || w.iter().all(|p| p.1 == 0.0) {
            return Damping::Rayleigh { a: 0.0, b: 0.0 };
        }
        // ratio(w) = a u + b v, u = 1 / (2 w), v = w / 2, weight q = 1 / w^3
        let (mut uu, mut uv, mut vv, mut uz, mut vz) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for &(x, zeta) in &w {
            let (u, v) = (0.5 / x, 0.5 * x);
            let q = 1.0 / (x * x * x);
            uu += q * u * u;
            uv += q * u * v;
            vv += q * v * v;
            uz += q * u * zeta;
            vz += q * v * zeta;
        }
        let det = uu * vv - uv * uv;
        let (a, b) = if det > 1e-12 * uu * vv {
            ((uz * vv - vz * uv) / det, (vz * uu - uz * uv) / det)
        } else {
            (f64::NAN, f64::NAN)
        };
        if a >= 0.0 && b >= 0.0 {
            return Damping::Rayleigh { a, b };
        }
        // one term alone: the better of mass- and stiffness-proportional
        let (a1, b1) = ((uz / uu).max(0.0), (vz / vv).max(0.0));
        let err = |a: f64, b: f64| -> f64 {
            w.iter()
                .map(|&(x, zeta)| (a * 0.5 / x + b * 0.5 * x - zeta).powi(2) / (x * x * x))
                .sum()
        };
        if err(a1, 0.0) <= err(0.0, b1) {
            Damping::Rayleigh { a: a1, b: 0.0 }
        } else {
            Damping::Rayleigh { a: 0.0, b: b1 }
        }
    }
}

impl Chain {
    /// The uniform chain's undamped frequencies `omega_j = 2 sqrt(k / mass)
    /// sin(theta_j / 2)` (closed form for its ends, `closed_theta`).
    pub fn uniform_omegas(&self) -> Vec<f64> {
        let ends = (self.left, self.right);
        let scale = self.uniform_band();
        (1..=self.n)
            .map(|j| scale * (0.5 * closed_theta(ends, self.n, j)).sin())
            .collect()
    }

    /// The damping model as the tridiagonal `K(s)` holds it
    /// ([`Damping::tridiagonal`]: `modal` becomes its Rayleigh stand-in
    /// over [`Chain::uniform_omegas`]).
    pub fn tridiagonal_damping(&self) -> Damping {
        // the frequencies only for the modal model: `site` and `dampers`
        // call this on every chain, in the fit's inner loops, where the
        // uniform part (hence the stand-in) rarely changes: the last one
        // computed on this thread is kept
        if !self.damping.is_modal() {
            return self.damping.clone();
        }
        type Key = (usize, u64, u64, Boundary, Boundary, Damping);
        thread_local! {
            static LAST: std::cell::RefCell<Option<(Key, Damping)>> =
                const { std::cell::RefCell::new(None) };
        }
        let key: Key = (
            self.n,
            self.k.to_bits(),
            self.mass.to_bits(),
            self.left,
            self.right,
            self.damping.clone(),
        );
        LAST.with(|last| {
            if let Some((k, d)) = last.borrow().as_ref() {
                if *k == key {
                    return d.clone();
                }
            }
            let d = self.damping.tridiagonal(&self.uniform_omegas());
            *last.borrow_mut() = Some((key, d.clone()));
            d
        })
    }
}

/// `theta_j` of the uniform chain's mode `j` (1-based) for the given ends:
/// `j pi / (n + 1)` fixed-fixed, `(j - 1) pi / n` free-free, `(2j - 1) pi /
/// (2n + 1)` with one end free (the chain's frequencies are
/// `2 sqrt(k / m) sin(theta_j / 2)`, see [`crate::green`]).
pub(crate) fn closed_theta(ends: (Boundary, Boundary), n: usize, j: usize) -> f64 {
    use std::f64::consts::PI;
    let (n, j) = (n as f64, j as f64);
    match ends {
        (Boundary::Fixed, Boundary::Fixed) => j * PI / (n + 1.0),
        (Boundary::Free, Boundary::Free) => (j - 1.0) * PI / n,
        _ => (2.0 * j - 1.0) * PI / (2.0 * n + 1.0),
    }
}

impl std::fmt::Display for Damping {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())?;
        for (i, (p, v)) in self.params().iter().enumerate() {
            write!(f, "{}{p} = {v}", if i == 0 { " (" } else { ", " })?;
        }
        if !self.params().is_empty() {
            f.write_str(")")?;
        }
        Ok(())
    }
}

impl std::str::FromStr for Damping {
    type Err = Error;
    /// The model by name, its parameters zero (see [`Damping::build`]).
    fn from_str(s: &str) -> Result<Damping> {
        match s.trim().to_ascii_lowercase().as_str() {
            "grounded" | "ground" => Ok(Damping::Grounded),
            "between" | "interstorey" | "spring-parallel" => Ok(Damping::Between { c: 0.0 }),
            "rayleigh" => Ok(Damping::Rayleigh { a: 0.0, b: 0.0 }),
            "modal" => Ok(Damping::modal(0.0)),
            _ => Err(Error::invalid(
                "damping",
                s,
                "grounded, between, rayleigh or modal",
            )),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_ratio_per_mode_is_parsed_checked_and_written() {
        let (d, missing) = Damping::parse_spec("modal:0.01, 0.05,0.02").unwrap();
        assert!(missing.is_empty());
        assert_eq!(
            d,
            Damping::Modal {
                zeta: vec![0.01, 0.05, 0.02]
            }
        );
        // the last ratio for every higher mode; other models none
        assert_eq!(
            (0..5).map(|j| d.modal_ratio(j)).collect::<Vec<_>>(),
            [0.01, 0.05, 0.02, 0.02, 0.02]
        );
        assert_eq!(Damping::Between { c: 1.0 }.modal_ratio(0), 0.0);
        // ranks by frequency whatever the order of the frequencies
        assert_eq!(
            d.modal_ratios_of(&[9.0, 1.0, 16.0, 4.0]),
            [0.02, 0.01, 0.02, 0.05]
        );
        let names: Vec<String> = d.params().into_iter().map(|p| p.0).collect();
        assert_eq!(names, ["zeta_1", "zeta_2", "zeta_3"]);
        assert_eq!(Damping::modal(0.02).params(), [("zeta".to_string(), 0.02)]);
        assert_eq!(
            d.to_string(),
            "modal (zeta_1 = 0.01, zeta_2 = 0.05, zeta_3 = 0.02)"
        );
        // more values than ratios: the model takes them all
        assert_eq!(
            Damping::modal(0.02).with_params(&[0.1, 0.2]).params().len(),
            2
        );
        // a bad ratio names its place; a bad list the format
        match Damping::parse_complete("modal:0.01,7") {
            Err(Error::InvalidParameter { field, allowed, .. }) => {
                assert_eq!(field, "damping.zeta[1]");
                assert!(allowed.contains("0 <= zeta <= 4"), "{allowed}");
            }
            other => panic!("{other:?}"),
        }
        for bad in ["modal:0.01,,0.02", "modal:0.01:0.02", "modal:a,b"] {
            match Damping::parse_complete(bad) {
                Err(Error::InvalidParameter { field, .. }) => assert_eq!(field, "damping", "{bad}"),
                Err(Error::Parse { what, .. }) => assert_eq!(what, "damping", "{bad}"),
                other => panic!("{bad}: {other:?}"),
            }
        }
        assert!(Damping::Modal { zeta: vec![] }.check().is_err());
    }

    #[test]
    fn a_ratio_per_mode_reads_from_tables_and_round_trips() {
        #[derive(Deserialize)]
        struct Scene {
            damping: Damping,
        }
        let one: Scene = toml::from_str("damping = { model = \"modal\", zeta = 0.02 }").unwrap();
        assert_eq!(one.damping, Damping::modal(0.02));
        let many: Scene =
            toml::from_str("damping = { model = \"modal\", zeta = [0.01, 0.03] }").unwrap();
        let text: Scene = toml::from_str("damping = \"modal:0.01,0.03\"").unwrap();
        assert_eq!(many.damping, text.damping);
        assert!(
            toml::from_str::<Scene>("damping = { model = \"modal\", zeta = [0.01, -1] }").is_err()
        );
        // JSON: one ratio a number, several a list
        let json = serde_json::to_string(&many.damping).unwrap();
        assert_eq!(json, r#"{"model":"modal","zeta":[0.01,0.03]}"#);
        assert_eq!(
            serde_json::to_string(&one.damping).unwrap(),
            r#"{"model":"modal","zeta":0.02}"#
        );
        assert_eq!(
            serde_json::from_str::<Damping>(&json).unwrap(),
            many.damping
        );
    }

    #[test]
    fn the_stand_in_follows_each_modes_ratio() {
        // ratios that a Rayleigh damping holds exactly are kept exactly
        let omegas = [0.5, 1.0, 2.0, 3.0];
        let (a, b) = (0.02, 0.01);
        let zeta: Vec<f64> = omegas.iter().map(|w| a / (2.0 * w) + b * w / 2.0).collect();
        let Damping::Rayleigh { a: ga, b: gb } = Damping::Modal { zeta }.tridiagonal(&omegas)
        else {
            panic!("a Rayleigh stand-in")
        };
        assert!(
            (ga - a).abs() < 1e-14 && (gb - b).abs() < 1e-14,
            "{ga} {gb}"
        );
        // ratios falling with frequency: mass-proportional alone
        let Damping::Rayleigh { a, b } = Damping::Modal {
            zeta: vec![0.08, 0.04, 0.02, 0.0],
        }
        .tridiagonal(&omegas) else {
            panic!("a Rayleigh stand-in")
        };
        assert!(a > 0.0 && b == 0.0, "{a} {b}");
    }

    #[test]
    fn damping_models_validate_and_roundtrip() {
        let c = Chain::paper(5).unwrap();
        for (bad, field) in [
            (Damping::Between { c: -0.1 }, "damping.c"),
            (
                Damping::Rayleigh {
                    a: 0.1,
                    b: f64::NAN,
                },
                "damping.b",
            ),
            (Damping::Rayleigh { a: -1.0, b: 0.0 }, "damping.a"),
        ] {
            match c.clone().with_damping(bad.clone()) {
                Err(Error::InvalidParameter {
                    field: f, allowed, ..
                }) => {
                    assert_eq!(f, field);
                    assert!(allowed.contains(">= 0"));
                }
                other => panic!("{bad:?} gave {other:?}"),
            }
        }
        // a model that needs a parameter not given: typed, naming `damping`
        match Damping::build("rayleigh", None, Some(0.1), None) {
            Err(Error::InvalidParameter { field, allowed, .. }) => {
                assert_eq!(field, "damping");
                assert!(allowed.contains("parameter b"), "{allowed}");
            }
            other => panic!("{other:?}"),
        }
        assert!(matches!(
            Damping::build("viscous", None, None, None),
            Err(Error::InvalidParameter { field, .. }) if field == "damping"
        ));
        assert_eq!(
            Damping::build("between", Some(0.2), None, None).unwrap(),
            Damping::Between { c: 0.2 }
        );
        // between: a damper defect sits on a spring, 0..=n
        let b = c.clone().with_damping(Damping::Between { c: 0.1 }).unwrap();
        let b = b.with_defect(Defect::Damper { at: 0, d: 0.5 }).unwrap();
        assert_eq!(b.spring_dampers(), vec![0.5, 0.1, 0.1, 0.1, 0.1, 0.1]);
        assert_eq!(b.dampers(), vec![0.1; 5]);
        assert!(b
            .clone()
            .with_defect(Defect::Damper { at: 6, d: 0.5 })
            .is_err());
        // the same defect is refused at mass 0 in the grounded model
        assert!(c
            .clone()
            .with_defect(Defect::Damper { at: 0, d: 0.5 })
            .is_err());
        // rayleigh: a mass defect's site is s^2 + a s
        let r = c
            .with_d(0.0)
            .unwrap()
            .with_damping(Damping::Rayleigh { a: 0.2, b: 0.3 })
            .unwrap()
            .with_defect(Defect::Mass { at: 2, m: 3.0 })
            .unwrap();
        assert_eq!(r.site(&r.defects()[0]).poly, [0.0, 0.2, 1.0]);
        assert!((r.dampers()[1] - 0.6).abs() < 1e-15);
        assert_eq!(r.spring_dampers()[0], 0.3);
        // serde: the model in JSON and TOML; grounded chains print as before
        let json = serde_json::to_string(&r).unwrap();
        assert!(
            json.contains(r#""damping":{"model":"rayleigh","a":0.2,"b":0.3}"#),
            "{json}"
        );
        assert_eq!(serde_json::from_str::<Chain>(&json).unwrap(), r);
        assert!(!serde_json::to_string(&Chain::paper(3).unwrap())
            .unwrap()
            .contains("damping"));
        let spec: ChainSpec =
            toml::from_str("n = 4\nd = 0\ndamping = { model = \"between\", c = 0.05 }").unwrap();
        assert_eq!(
            spec.build().unwrap().damping(),
            &Damping::Between { c: 0.05 }
        );
        assert!(toml::from_str::<ChainSpec>("n = 4\ndamping = { model = \"between\" }").is_err());
        // SI: c in N s/m, a = C/M, b = C/K
        let si = r.to_si(&Units::new(10.0, 100.0, 1000.0).unwrap()).unwrap();
        assert_eq!(si.damping(), &Damping::Rayleigh { a: 20.0, b: 3.0 });
        // modal: a ratio in 0..=4, the same in SI; no damper defects; its
        // tridiagonal stand-in a Rayleigh damping close to zeta
        let (m, missing) = Damping::parse_spec("modal").unwrap();
        assert_eq!((m, missing), (Damping::modal(0.0), vec!["zeta"]));
        let m = Damping::parse_complete("modal:0.03").unwrap();
        for bad in ["modal:-0.1", "modal:5", "modal:nan"] {
            match Damping::parse_complete(bad) {
                Err(Error::InvalidParameter { field, allowed, .. }) => {
                    assert_eq!(field, "damping.zeta", "{bad}");
                    assert!(allowed.contains("0 <= zeta <= 4"), "{allowed}");
                }
                other => panic!("{bad}: {other:?}"),
            }
        }
        let mc = Chain::paper(5)
            .unwrap()
            .with_d(0.0)
            .unwrap()
            .with_damping(m.clone())
            .unwrap();
        assert_eq!(
            mc.to_si(&Units::new(10.0, 100.0, 1000.0).unwrap())
                .unwrap()
                .damping(),
            &m
        );
        match mc.clone().with_defect(Defect::Damper { at: 2, d: 0.3 }) {
            Err(Error::InvalidParameter { field, allowed, .. }) => {
                assert_eq!(field, "defects[0]");
                assert!(allowed.contains("no dampers"), "{allowed}");
            }
            other => panic!("{other:?}"),
        }
        let Damping::Rayleigh { a, b } = mc.tridiagonal_damping() else {
            panic!("a Rayleigh stand-in")
        };
        let worst = mc
            .uniform_omegas()
            .iter()
            .map(|w| (a / (2.0 * w) + b * w / 2.0 - 0.03).abs())
            .fold(0.0, f64::max);
        assert!(a > 0.0 && b > 0.0 && worst < 0.03, "{a} {b} {worst}");
        let json = serde_json::to_string(&mc).unwrap();
        assert!(
            json.contains(r#""damping":{"model":"modal","zeta":0.03}"#),
            "{json}"
        );
        assert_eq!(serde_json::from_str::<Chain>(&json).unwrap(), mc);
    }
}
