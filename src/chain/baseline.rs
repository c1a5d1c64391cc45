//! A measured (or design) profile of a nonuniform chain ([`Baseline`]): one
//! mass, spring and optionally damper per storey, read from a CSV table
//! ([`Baseline::read_csv`]) or given inline in a scene.
//!
//! The table has one row per mass, top to bottom mass 1 to mass `n`:
//!
//! | column | meaning |
//! |---|---|
//! | `mass` | the mass, `> 0` |
//! | `spring` | the spring joining this mass to the one before it; for mass 1 the left wall's spring, **empty when the left end is free** |
//! | `damper` (optional) | the grounded damper of the mass (grounded and Rayleigh damping), or the damper parallel to the row's spring (`--damping between`); empty is no damper |
//!
//! When the right end is fixed, one last row has only `spring`: the right
//! wall's. So `n` is the number of rows with a mass and the ends follow from
//! the empty cells. Units in the header are converted to SI: `mass [kg]`,
//! `[g]`, `[t]`; `spring [N/m]`, `[kN/m]`, `[MN/m]`, `[N/mm]`, `[kN/mm]`;
//! `damper [N s/m]`, `[Ns/m]`, `[kN s/m]`; any other unit is refused. A
//! column named `storey`, `story`, `floor`, `level`, `row` or `index` is
//! ignored (a label). The CSV conventions are those of the records
//! ([`crate::series::TimeSeries::from_csv_str`]): a byte-order mark, CRLF,
//! `,`/`;`/tab (with `;`, a decimal comma), `#` comments.
//!
//! ```
//! use springmass::chain::{Baseline, Boundary};
//! let b = Baseline::from_csv_str("mass,spring\n2,\n1,3\n1.5,2\n", "frame.csv")?;
//! assert_eq!(b.n(), 3);
//! assert_eq!((b.left(), b.right()), (Boundary::Free, Boundary::Free));
//! assert_eq!(b.springs(), [0.0, 3.0, 2.0, 0.0]);
//! # Ok::<(), springmass::Error>(())
//! ```

use super::Boundary;
use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// A nonuniform chain's masses, springs and dampers (validated; see the
/// module docs). Inline in a scene:
/// `baseline = { mass = [2, 1, 1.5], spring = [0, 3, 2, 5] }` (`spring` has
/// `n + 1` entries, `0` for a free end's absent wall spring; `damper`
/// optional, `n + 1` entries aligned with `spring`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "RawBaseline", into = "RawBaseline")]
pub struct Baseline {
    source: String,
    mass: Vec<f64>,
    spring: Vec<f64>,
    damper: Option<Vec<f64>>,
}

/// The serialised form of a [`Baseline`] (validated on the way in).
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawBaseline {
    #[serde(default, skip_serializing_if = "String::is_empty")]
    source: String,
    mass: Vec<f64>,
    spring: Vec<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    damper: Option<Vec<f64>>,
}

impl TryFrom<RawBaseline> for Baseline {
    type Error = Error;
    fn try_from(r: RawBaseline) -> Result<Baseline> {
        Baseline::new(r.mass, r.spring, r.damper, &r.source)
    }
}

impl From<Baseline> for RawBaseline {
    fn from(b: Baseline) -> RawBaseline {
        RawBaseline {
            source: b.source,
            mass: b.mass,
            spring: b.spring,
            damper: b.damper,
        }
    }
}

impl Baseline {
    /// A validated profile: `mass` (`n` values `> 0`), `spring` (`n + 1`,
    /// `spring[i]` joining mass `i` and `i + 1`; `0` at a free end, `> 0`
    /// elsewhere), `damper` (`n + 1` values `>= 0`, aligned with `spring`:
    /// entry `i - 1` is mass `i`'s grounded damper, entry `i` the damper
    /// beside spring `i` under `between`). `source` names it in messages
    /// and reports (a file name, or empty for inline).
    ///
    /// # Errors
    /// A wrong element count or a value out of range, naming
    /// `baseline.mass[i]`, `baseline.spring[i]` or `baseline.damper[i]`.
    pub fn new(
        mass: Vec<f64>,
        spring: Vec<f64>,
        damper: Option<Vec<f64>>,
        source: &str,
    ) -> Result<Baseline> {
        let n = mass.len();
        if n == 0 || n > super::MAX_N {
            return Err(Error::invalid(
                "baseline.mass",
                format!("{n} masses"),
                format!("1 to {} masses", super::MAX_N),
            ));
        }
        check_len("baseline.spring", spring.len(), n + 1)?;
        if let Some(d) = &damper {
            check_len("baseline.damper", d.len(), n + 1)?;
        }
        let b = Baseline {
            source: source.to_string(),
            mass,
            spring,
            damper,
        };
        b.check_values()?;
        Ok(b)
    }

    fn check_values(&self) -> Result<()> {
        let n = self.n();
        for (i, &m) in self.mass.iter().enumerate() {
            check_value(
                &format!("baseline.mass[{i}]"),
                m,
                m > 0.0,
                "mass > 0 and finite",
            )?;
        }
        for (i, &k) in self.spring.iter().enumerate() {
            let wall = i == 0 || i == n;
            let (ok, range) = if wall {
                (k >= 0.0, "spring >= 0 and finite (0: a free end)")
            } else {
                (k > 0.0, "spring > 0 and finite between two masses")
            };
            check_value(&format!("baseline.spring[{i}]"), k, ok, range)?;
        }
        for (i, &d) in self.damper.iter().flatten().enumerate() {
            check_value(
                &format!("baseline.damper[{i}]"),
                d,
                d >= 0.0,
                "damper >= 0 and finite",
            )?;
        }
        Ok(())
    }

    /// Number of masses.
    pub fn n(&self) -> usize {
        self.mass.len()
    }
    /// Where the profile came from (a file name; `inline` when not named).
    pub fn source(&self) -> &str {
        if self.source.is_empty() {
            "inline"
        } else {
            &self.source
        }
    }
    /// The masses, 0-based (`masses()[i - 1]` is mass `i`).
    pub fn masses(&self) -> &[f64] {
        &self.mass
    }
    /// The `n + 1` springs (`0` at a free end).
    pub fn springs(&self) -> &[f64] {
        &self.spring
    }
    /// The `n + 1` dampers aligned with the springs, if the table has them.
    pub fn dampers(&self) -> Option<&[f64]> {
        self.damper.as_deref()
    }
    /// Left end: free when the left wall spring is absent.
    pub fn left(&self) -> Boundary {
        end_of(self.spring[0])
    }
    /// Right end: free when the right wall spring is absent.
    pub fn right(&self) -> Boundary {
        end_of(self.spring[self.n()])
    }
    /// The mean mass (the chain's representative `mass`).
    pub fn mean_mass(&self) -> f64 {
        self.mass.iter().sum::<f64>() / self.n() as f64
    }
    /// The mean of the springs that exist (the chain's representative `k`).
    pub fn mean_spring(&self) -> f64 {
        let present: Vec<f64> = self.spring.iter().copied().filter(|&k| k > 0.0).collect();
        if present.is_empty() {
            1.0
        } else {
            present.iter().sum::<f64>() / present.len() as f64
        }
    }

    /// The same profile with masses, springs and dampers multiplied by
    /// `(mass, stiffness, damping)` scales ([`super::Units`]).
    pub fn scaled(&self, ms: f64, ks: f64, ds: f64) -> Result<Baseline> {
        let sc = |v: &[f64], f: f64| v.iter().map(|x| x * f).collect::<Vec<f64>>();
        Baseline::new(
            sc(&self.mass, ms),
            sc(&self.spring, ks),
            self.damper.as_deref().map(|d| sc(d, ds)),
            &self.source,
        )
    }

    /// Check the profile against what the user also said of the chain:
    /// `n` and the ends (each `None` when not given).
    ///
    /// # Errors
    /// A contradiction, naming `n`, `left` or `right` and the table.
    pub fn check_agrees(
        &self,
        n: Option<usize>,
        left: Option<Boundary>,
        right: Option<Boundary>,
    ) -> Result<()> {
        if let Some(n) = n.filter(|&n| n != self.n()) {
            return Err(Error::invalid(
                "n",
                n,
                format!(
                    "n = {} (the rows with a mass in baseline {})",
                    self.n(),
                    self.source()
                ),
            ));
        }
        for (field, given, table, how) in [
            ("left", left, self.left(), "the first row's spring"),
            (
                "right",
                right,
                self.right(),
                "a last row with only a spring",
            ),
        ] {
            if let Some(g) = given.filter(|&g| g != table) {
                return Err(Error::invalid(
                    field,
                    g,
                    format!(
                        "{table}, as baseline {} says ({how}: present = fixed, absent = free)",
                        self.source()
                    ),
                ));
            }
        }
        Ok(())
    }

    /// Read a baseline table from a file (see the module docs).
    ///
    /// # Errors
    /// [`Error::Io`] for a file that cannot be read; the errors of
    /// [`Baseline::from_csv_str`].
    pub fn read_csv(path: impl AsRef<Path>) -> Result<Baseline> {
        let path = path.as_ref();
        let text = crate::io::read_to_string_capped(path)?;
        Baseline::from_csv_str(&text, &path.display().to_string())
    }

    /// Parse a baseline table (see the module docs); `source` names it in
    /// messages.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming `baseline <source> row R column
    /// `C`` and the allowed range: a missing `mass` or `spring` column, an
    /// unknown column or unit, a mass that is not `> 0`, a negative spring,
    /// an empty spring between two masses, a row without a mass that is
    /// not the last one.
    pub fn from_csv_str(text: &str, source: &str) -> Result<Baseline> {
        let table = super::baseline_csv::Table::parse(text, source)?;
        table.into_baseline(source)
    }
}

/// A baseline as a scene, a study or the Python package gives it: the path
/// of a table (relative to the current directory; the CLI resolves a
/// scene's paths against the scene file's directory) or the table inline,
/// `{ mass = [...], spring = [...] }`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum BaselineSpec {
    /// A CSV table's path ([`Baseline::read_csv`]).
    Path(String),
    /// The table itself.
    Table(Baseline),
}

impl BaselineSpec {
    /// The profile (read from its file, or the inline table).
    ///
    /// # Errors
    /// As [`Baseline::read_csv`].
    pub fn load(&self) -> Result<Baseline> {
        match self {
            BaselineSpec::Path(p) => Baseline::read_csv(p),
            BaselineSpec::Table(b) => Ok(b.clone()),
        }
    }

    /// A relative path taken against `dir` (a scene file's directory).
    pub fn relative_to(self, dir: &Path) -> BaselineSpec {
        match self {
            BaselineSpec::Path(p) if Path::new(&p).is_relative() => {
                BaselineSpec::Path(dir.join(p).display().to_string())
            }
            other => other,
        }
    }
}

fn end_of(wall_spring: f64) -> Boundary {
    if wall_spring > 0.0 {
        Boundary::Fixed
    } else {
        Boundary::Free
    }
}

fn check_len(field: &str, got: usize, want: usize) -> Result<()> {
    if got == want {
        Ok(())
    } else {
        Err(Error::invalid(
            field,
            format!("{got} values"),
            format!("{want} values (n + 1, one per spring, 0 for a free end's wall spring)"),
        ))
    }
}

fn check_value(field: &str, v: f64, ok: bool, range: &str) -> Result<()> {
    crate::error::check_f64(field, v, ok, range).map(|_| ())
}

/// Serde for `Option<Arc<Baseline>>` (the chain's field) without serde's
/// `rc` feature: written as the table, read into a new `Arc`.
pub(super) mod serde_arc {
    use super::Baseline;
    use serde::{Deserialize, Deserializer, Serialize, Serializer};
    use std::sync::Arc;

    pub fn serialize<S: Serializer>(v: &Option<Arc<Baseline>>, s: S) -> Result<S::Ok, S::Error> {
        v.as_deref().serialize(s)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Option<Arc<Baseline>>, D::Error> {
        Ok(Option::<Baseline>::deserialize(d)?.map(Arc::new))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inline_form_validates() {
        let b = Baseline::new(vec![1.0, 2.0], vec![1.0, 2.0, 3.0], None, "").unwrap();
        assert_eq!((b.left(), b.right()), (Boundary::Fixed, Boundary::Fixed));
        assert_eq!(b.source(), "inline");
        let bad = Baseline::new(vec![1.0, -2.0], vec![1.0, 2.0, 3.0], None, "");
        assert!(
            matches!(bad, Err(Error::InvalidParameter { field, .. }) if field == "baseline.mass[1]")
        );
        let bad = Baseline::new(vec![1.0, 2.0], vec![1.0, 0.0, 3.0], None, "");
        assert!(
            matches!(bad, Err(Error::InvalidParameter { field, .. }) if field == "baseline.spring[1]")
        );
        let bad = Baseline::new(vec![1.0, 2.0], vec![1.0, 2.0], None, "");
        assert!(
            matches!(bad, Err(Error::InvalidParameter { field, .. }) if field == "baseline.spring")
        );
        let json = r#"{"mass":[1.0,2.0],"spring":[0.0,2.0,3.0]}"#;
        let b: Baseline = serde_json::from_str(json).unwrap();
        assert_eq!(b.left(), Boundary::Free);
        assert_eq!(serde_json::to_string(&b).unwrap(), json);
        assert!(serde_json::from_str::<Baseline>(r#"{"mass":[0.0],"spring":[1.0,1.0]}"#).is_err());
    }

    #[test]
    fn scenes_give_it_inline_or_by_path() {
        use crate::chain::ChainSpec;
        let spec: ChainSpec =
            toml::from_str("n = 2\nbaseline = { mass = [1.0, 2.0], spring = [0.0, 2.0, 3.0] }")
                .unwrap();
        let c = spec.build().unwrap();
        assert_eq!((c.left(), c.masses()), (Boundary::Free, vec![1.0, 2.0]));
        let spec: ChainSpec = toml::from_str("n = 3\nbaseline = \"frame.csv\"").unwrap();
        let dir = std::env::temp_dir().join(format!("springmass-bl-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("frame.csv"), "mass,spring\n1,\n2,3\n").unwrap();
        let moved = spec.baseline.clone().unwrap().relative_to(&dir);
        let b = moved.load().unwrap();
        assert_eq!(b.n(), 2);
        // n = 3 contradicts the table's two masses
        let spec = ChainSpec {
            baseline: Some(moved),
            ..spec
        };
        let e = spec.build().unwrap_err();
        assert!(
            matches!(&e, Error::InvalidParameter { field, .. } if field == "n"),
            "{e}"
        );
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn agrees_with_the_flags() {
        let b = Baseline::new(vec![1.0, 2.0], vec![0.0, 2.0, 3.0], None, "b.csv").unwrap();
        assert!(b.check_agrees(Some(2), Some(Boundary::Free), None).is_ok());
        let e = b.check_agrees(Some(3), None, None).unwrap_err();
        assert!(
            matches!(&e, Error::InvalidParameter { field, .. } if field == "n"),
            "{e}"
        );
        let e = b
            .check_agrees(None, Some(Boundary::Fixed), None)
            .unwrap_err();
        assert!(
            matches!(&e, Error::InvalidParameter { field, .. } if field == "left"),
            "{e}"
        );
        assert!(e.to_string().contains("b.csv"));
    }
}
