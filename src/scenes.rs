//! The paper's reference scenes, in one place for tests, benchmarks, examples
//! and configs alike.
//!
//! | name | n | defects `(j, m)` | where in the paper |
//! |---|---|---|---|
//! | `P1` | 20 | (15, 1.01) | section 4.1.1, Figures 10-11 |
//! | `P2` | 5 | (3, 4) | section 4.1.2, Figures 12-13 |
//! | `P3` | 20 | (3, 5) | section 4.1.3, Figures 14-15 |
//! | `P4` | 20 | (10, 3), (15, 7) | section 4.2.2, Figure 17 |
//! | `S1`..`S4` | 5, 10, 20, 20 | Table 1 | section 4.2.3 |
//! | `C3a` | 10 | (2, 2), (5, 4), (8, 0.5) | three defects (noise study) |
//! | `C3b` | 20 | (4, 3), (10, 0.5), (16, 2) | three defects, one deep and light (noise study) |
//! | `k0`..`k3` | 10 | none; (4, 2); as `S2`; as `C3a` | 0 to 3 defects (choice of k) |
//!
//! All with `k = 1`, `d = 0.1`, `gamma = 1`, unit masses elsewhere (the
//! conventions of `shared/reference/`).
//!
//! Test and bench fixtures (not from the paper), built by functions:
//!
//! | function | chain | use |
//! |---|---|---|
//! | [`mixed`]`(n)` | paper, `gamma = 1.3`; mass `(2, 3)`, spring `((n+1)/2, 0.6)`, damper `((n+1)/2+1, 0.3)`, wall spring `(n, 1.4)`, mass `(n-1, 0.5)` | a defect of every kind, a wall spring among them, and gamma (Jacobians, sensitivities) |
//! | [`three_kinds`]`(n, [jm, jk, jd])` | paper; mass `(jm, 2)`, spring `(jk, 0.6)`, damper `(jd, 0.4)` | one defect of each kind (forward models, searches over every kind) |
//! | [`paper_with`]`(n, "mass:3:2 spring:6:0.5")` | paper; the listed defects ([`defects`]) | any hand-made scene of a test, as one line of data |
//! | [`frame6`], [`shear_frame`] | shear frames seen from the roof | spring profiles |
//! | [`profile_chain`] | every mass differs ([`mass_profile`]) | mass profiles |
//!
//! ```
//! use springmass::scenes;
//! let s3 = scenes::table1(3)?;
//! assert_eq!(s3.n(), 20);
//! assert_eq!(scenes::by_name("P2")?.defects().len(), 1);
//! # Ok::<(), springmass::Error>(())
//! ```

use crate::chain::{Chain, Defect};
use crate::error::{Error, Result};

/// Names of the paper's reference scenes.
pub const NAMES: [&str; 8] = ["P1", "P2", "P3", "P4", "S1", "S2", "S3", "S4"];

/// The noise study's systems: Table 1 and two chains with three defects.
pub const NOISE_SYSTEMS: [&str; 6] = ["S1", "S2", "S3", "S4", "C3a", "C3b"];

/// Chains with 0 to 3 defects on `n = 10`, for the choice of the number of
/// defects (`k0` has none).
pub const SELECTION: [&str; 4] = ["k0", "k1", "k2", "k3"];

/// `(n, [(j, m), ...])` of a scene.
fn spec(name: &str) -> Option<(usize, &'static [(usize, f64)])> {
    Some(match name {
        "P1" => (20, &[(15, 1.01)]),
        "P2" => (5, &[(3, 4.0)]),
        "P3" => (20, &[(3, 5.0)]),
        "P4" => (20, &[(10, 3.0), (15, 7.0)]),
        "S1" => (5, &[(2, 3.0), (4, 0.5)]),
        "S2" => (10, &[(3, 3.0), (7, 2.0)]),
        "S3" => (20, &[(8, 5.0), (15, 2.0)]),
        "S4" => (20, &[(8, 5.0), (15, 15.0)]),
        "C3A" | "K3" => (10, &[(2, 2.0), (5, 4.0), (8, 0.5)]),
        "C3B" => (20, &[(4, 3.0), (10, 0.5), (16, 2.0)]),
        "K0" => (10, &[]),
        "K1" => (10, &[(4, 2.0)]),
        "K2" => (10, &[(3, 3.0), (7, 2.0)]),
        _ => return None,
    })
}

/// A reference scene by name (`P1`..`P4`, `S1`..`S4`, `C3a`, `C3b`,
/// `k0`..`k3`; case-insensitive).
///
/// # Errors
/// [`Error::InvalidParameter`] for an unknown name, listing the known ones.
pub fn by_name(name: &str) -> Result<Chain> {
    let up = name.trim().to_ascii_uppercase();
    let (n, defects) = spec(&up).ok_or_else(|| Error::invalid("scene", name, all_names()))?;
    Chain::paper(n)?.with_defects(defects.iter().map(|&(at, m)| Defect::Mass { at, m }))
}

/// The true defects `(j, m)` of a reference scene (all are mass defects), in
/// increasing `j`.
///
/// ```
/// use springmass::scenes;
/// assert_eq!(scenes::truth("S3")?, vec![(8, 5.0), (15, 2.0)]);
/// # Ok::<(), springmass::Error>(())
/// ```
///
/// # Errors
/// [`Error::InvalidParameter`] for an unknown name, listing the known ones.
pub fn truth(name: &str) -> Result<Vec<(usize, f64)>> {
    let up = name.trim().to_ascii_uppercase();
    spec(&up)
        .map(|(_, d)| d.to_vec())
        .ok_or_else(|| Error::invalid("scene", name, all_names()))
}

/// A paper chain of `n >= 5` masses with a defect of every kind, a wall
/// spring among them, and `gamma = 1.3`: mass `(2, 3.0)`, spring
/// `((n+1)/2, 0.6)`, damper `((n+1)/2 + 1, 0.3)`, the right wall spring
/// `(n, 1.4)` and mass `(n-1, 0.5)`, in that order (the order of
/// [`Chain::defects`]).
///
/// ```
/// use springmass::{scenes, chain::Defect};
/// let c = scenes::mixed(7)?;
/// assert_eq!(c.gamma(), 1.3);
/// assert_eq!(c.defects()[3], Defect::Spring { at: 7, k: 1.4 });
/// # Ok::<(), springmass::Error>(())
/// ```
///
/// # Errors
/// `n < 5` (the five defects need room) or `n` out of range.
pub fn mixed(n: usize) -> Result<Chain> {
    if n < 5 {
        return Err(Error::invalid("n", n, "n >= 5"));
    }
    let mid = n.div_ceil(2);
    Chain::paper(n)?.with_gamma(1.3)?.with_defects([
        Defect::Mass { at: 2, m: 3.0 },
        Defect::Spring { at: mid, k: 0.6 },
        Defect::Damper {
            at: mid + 1,
            d: 0.3,
        },
        Defect::Spring { at: n, k: 1.4 },
        Defect::Mass { at: n - 1, m: 0.5 },
    ])
}

/// A paper chain of `n` masses with one defect of each kind at `at =
/// [mass, spring, damper]`: mass `m = 2.0`, spring `k = 0.6`, damper
/// `d = 0.4`, in that order.
///
/// ```
/// use springmass::{scenes, chain::Defect};
/// let c = scenes::three_kinds(9, [3, 5, 7])?;
/// assert_eq!(c.defects()[2], Defect::Damper { at: 7, d: 0.4 });
/// # Ok::<(), springmass::Error>(())
/// ```
///
/// # Errors
/// `n` out of range or a position outside the chain.
pub fn three_kinds(n: usize, at: [usize; 3]) -> Result<Chain> {
    Chain::paper(n)?.with_defects([
        Defect::Mass { at: at[0], m: 2.0 },
        Defect::Spring { at: at[1], k: 0.6 },
        Defect::Damper { at: at[2], d: 0.4 },
    ])
}

/// Defects in the CLI form `kind:at:value` ([`Defect::parse`]), separated
/// by white space, in order: the compact way for tests to write a list.
///
/// ```
/// use springmass::{scenes, chain::Defect};
/// let d = scenes::defects("mass:3:2.5 damper:7:0.4")?;
/// assert_eq!(d, vec![Defect::Mass { at: 3, m: 2.5 }, Defect::Damper { at: 7, d: 0.4 }]);
/// # Ok::<(), springmass::Error>(())
/// ```
///
/// # Errors
/// [`Error::Parse`] for an entry not of that form.
pub fn defects(list: &str) -> Result<Vec<Defect>> {
    list.split_whitespace().map(Defect::parse).collect()
}

/// The paper's chain of `n` masses with the [`defects`] of `list`.
///
/// # Errors
/// `n` out of range, a bad entry or a defect outside the chain.
pub fn paper_with(n: usize, list: &str) -> Result<Chain> {
    Chain::paper(n)?.with_defects(defects(list)?)
}

/// A shear frame of `storeys` floors seen from its roof: mass 1 is the roof
/// at the free (left) end, spring `i` (`1..=storeys`) is the storey between
/// floor `i` and floor `i + 1`, spring `storeys` ties the lowest floor to the
/// ground (the fixed right end); unit floor masses and storey stiffnesses,
/// damping `d` to ground on every floor (light damping: `d = 0.05` gives a
/// first-mode damping ratio of about `0.09` for 5 storeys). `weakened`,
/// if given, is `(storey, factor)`: that storey's stiffness times `factor`.
///
/// ```
/// use springmass::{scenes, chain::Boundary};
/// let c = scenes::shear_frame(5, 0.05, Some((3, 0.7)))?;
/// assert_eq!(c.left(), Boundary::Free);
/// assert_eq!(c.springs(), vec![0.0, 1.0, 1.0, 0.7, 1.0, 1.0]);
/// # Ok::<(), springmass::Error>(())
/// ```
///
/// # Errors
/// `storeys == 0`, `d < 0`, a storey outside `1..=storeys` or a factor that
/// is not `> 0`.
pub fn shear_frame(storeys: usize, d: f64, weakened: Option<(usize, f64)>) -> Result<Chain> {
    let c = Chain::new(storeys)?
        .with_d(d)?
        .with_boundaries(crate::chain::Boundary::Free, crate::chain::Boundary::Fixed)?;
    match weakened {
        None => Ok(c),
        Some((at, factor)) => c.with_defect(Defect::Spring { at, k: factor }),
    }
}

/// The storey stiffness changes of [`frame6`], storey 1 (the roof's) first.
pub const FRAME6_CHANGE: [f64; 6] = [-0.25, 0.05, -0.1, -0.2, 0.0, -0.15];

/// A six-storey shear frame seen from its roof (left end free, d = 0.02)
/// with every storey stiffness changed by [`FRAME6_CHANGE`]: the
/// whole-profile spring scene of the tests and benches.
///
/// # Errors
/// Never in practice (valid values).
pub fn frame6() -> Result<Chain> {
    shear_frame(6, 0.02, None)?.with_defects((1..=6).map(|j| Defect::Spring {
        at: j,
        k: 1.0 + FRAME6_CHANGE[j - 1],
    }))
}

/// A deterministic "every mass differs" profile of `n` masses in [0.75,
/// 1.3]: `1 + 0.2 sin(0.7 i) + 0.1 cos(1.9 i + 0.3)`.
pub fn mass_profile(n: usize) -> Vec<f64> {
    (1..=n)
        .map(|i| {
            let x = i as f64;
            1.0 + 0.2 * (0.7 * x).sin() + 0.1 * (1.9 * x + 0.3).cos()
        })
        .collect()
}

/// The paper's chain of `n` masses with damping `d` and every mass set by
/// [`mass_profile`]: the whole-profile mass scene of the tests and benches.
///
/// # Errors
/// `n` out of range, `d < 0`.
pub fn profile_chain(n: usize, d: f64) -> Result<Chain> {
    Chain::paper(n)?.with_d(d)?.with_defects(
        mass_profile(n)
            .into_iter()
            .enumerate()
            .map(|(i, m)| Defect::Mass { at: i + 1, m }),
    )
}

fn all_names() -> String {
    NAMES
        .iter()
        .chain(&NOISE_SYSTEMS[4..])
        .chain(&SELECTION)
        .copied()
        .collect::<Vec<_>>()
        .join(", ")
}

/// System `i` (1..=4) of the paper's Table 1.
pub fn table1(i: usize) -> Result<Chain> {
    if !(1..=4).contains(&i) {
        return Err(Error::invalid("system", i, "1 <= system <= 4"));
    }
    by_name(&format!("S{i}"))
}

/// The paper's genetic-algorithm estimates of Table 1, `[(j1, m1), (j2, m2)]`
/// for systems 1..=4 (to print next to ours).
pub const TABLE1_PAPER_GA: [[(usize, f64); 2]; 4] = [
    [(2, 2.9760), (4, 0.6579)],
    [(3, 2.9009), (4, 1.3364)],
    [(8, 5.0113), (17, 3.2586)],
    [(8, 5.0646), (16, 14.2290)],
];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn all_scenes_build() {
        for name in NAMES {
            let c = by_name(name).unwrap();
            assert_eq!(c.d(), 0.1);
            assert!(!c.defects().is_empty());
        }
        assert!(by_name("S9").is_err());
        assert!(truth("S9").is_err());
        for name in NAMES {
            let want: Vec<(usize, f64)> = by_name(name)
                .unwrap()
                .defects()
                .iter()
                .map(|d| match *d {
                    Defect::Mass { at, m } => (at, m),
                    _ => unreachable!("reference scenes have mass defects only"),
                })
                .collect();
            assert_eq!(truth(name).unwrap(), want, "{name}");
        }
        assert!(table1(0).is_err() && table1(5).is_err());
        for name in NOISE_SYSTEMS.iter().chain(&SELECTION) {
            by_name(name).unwrap();
        }
        assert_eq!(by_name("C3b").unwrap().n(), 20);
        assert!(by_name("k0").unwrap().defects().is_empty());
        assert_eq!(by_name("k3").unwrap(), by_name("C3a").unwrap());
        assert_eq!(
            table1(4).unwrap().defects()[1],
            Defect::Mass { at: 15, m: 15.0 }
        );
    }

    #[test]
    fn fixtures_build() {
        assert!(mixed(4).is_err());
        for n in [5, 6, 7, 12, 40] {
            let c = mixed(n).unwrap();
            assert_eq!((c.n(), c.defects().len(), c.gamma()), (n, 5, 1.3));
        }
        assert!(three_kinds(4, [1, 2, 5]).is_err());
        assert_eq!(three_kinds(6, [1, 3, 5]).unwrap().defects().len(), 3);
        assert_eq!(
            paper_with(9, "mass:3:2 spring:5:0.6 damper:7:0.4").unwrap(),
            three_kinds(9, [3, 5, 7]).unwrap()
        );
        assert!(defects("mass:3").is_err() && paper_with(4, "mass:5:2").is_err());
        assert!(defects("").unwrap().is_empty());
    }
}
