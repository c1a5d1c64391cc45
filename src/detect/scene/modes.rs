//! The modal data of a scene (`[data] source = "modes"`): a modes CSV, or
//! the lowest undamped modes of the scene's true chain seen at some
//! floors, with seeded noise on the frequencies and the shapes.
//!
//! ```
//! use springmass::detect::scene::FitScene;
//! let scene = FitScene::from_toml(r#"
//!     [chain]
//!     n = 6
//!     right = "free"
//!     defects = [{ kind = "spring", at = 3, k = 0.7 }]
//!     [data]
//!     source = "modes"
//!     modes = 3
//!     floors = [2, 4, 6]
//!     frequency_noise = 0.001
//!     shape_noise = 0.01
//!     [unknowns]
//!     kind = "spring"
//! "#)?;
//! let modes = scene.measured_modes()?;
//! assert_eq!(modes.len(), 3);
//! assert_eq!(modes.modes()[0].shape.len(), 3);
//! assert!(modes.modes()[0].frequency_se.is_some()); // the noise is stated
//! # Ok::<(), springmass::Error>(())
//! ```

use super::{DataSourceKind, FitScene};
use crate::detect::data::modes::{MeasuredMode, MeasuredModes, ShapeEntry};
use crate::error::{check_f64, Error, Result};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

impl FitScene {
    /// The measured modes of a `modes` scene: read from `data.path`, or the
    /// lowest `data.modes` (default 3) undamped modes of `[chain]`, their
    /// shapes at `data.floors` (default every mass), each frequency times
    /// `1 + frequency_noise * N(0, 1)` and each shape component plus
    /// `shape_noise` times the mode's largest measured component times
    /// `N(0, 1)` (seed `data.seed`); the noise levels given are the table's
    /// standard errors (none when 0: the fit then assumes its weights).
    /// Frequencies in Hz of the chain's time unit (`omega / 2 pi`).
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming `data.source` (not `modes`),
    /// `data.modes` (0, or more than the chain's masses),
    /// `data.floors` (empty, or a mass outside the chain),
    /// `data.frequency_noise` / `data.shape_noise` (negative or not
    /// finite), `data.noise` (not 0: modal noise has its own fields),
    /// `data.path` with `modes`, `floors` or a noise level (the file holds
    /// the data), a rigid-body mode among the lowest; the modes CSV's
    /// own errors.
    pub fn measured_modes(&self) -> Result<MeasuredModes> {
        let d = &self.data;
        if d.source != DataSourceKind::Modes {
            return Err(Error::invalid(
                "data.source",
                format!("{:?}", d.source).to_lowercase(),
                "\"modes\" for modal data",
            ));
        }
        if d.noise != 0.0 {
            return Err(Error::invalid(
                "data.noise",
                d.noise,
                "0 with modes (frequency_noise and shape_noise give the modal noise)",
            ));
        }
        let paths = d.paths();
        if let Some(path) = paths.first() {
            let simulated = [
                ("data.modes", d.modes.is_some()),
                ("data.floors", d.floors.is_some()),
                ("data.frequency_noise", d.frequency_noise.is_some()),
                ("data.shape_noise", d.shape_noise.is_some()),
                ("data.path", paths.len() > 1),
            ];
            if let Some((field, _)) = simulated.iter().find(|(_, given)| *given) {
                return Err(Error::invalid(
                    *field,
                    "(given with a modes file)",
                    "nothing beside data.path: the file holds the measured modes",
                ));
            }
            let modes = MeasuredModes::read_csv(path)?;
            modes.check_chain(self.chain.n)?;
            return Ok(modes);
        }
        self.simulated_modes()
    }

    /// The simulated modes of [`FitScene::measured_modes`].
    fn simulated_modes(&self) -> Result<MeasuredModes> {
        let d = &self.data;
        let truth = self.truth()?;
        let n = truth.n();
        let count = d.modes.unwrap_or(3.min(n));
        if count == 0 || count > n {
            return Err(Error::invalid(
                "data.modes",
                count,
                format!("1..={n}, at most the chain's masses"),
            ));
        }
        let floors = d.floors.clone().unwrap_or_else(|| (1..=n).collect());
        if floors.is_empty() {
            return Err(Error::invalid(
                "data.floors",
                "[]",
                "at least one measured mass",
            ));
        }
        if let Some(&f) = floors.iter().find(|&&f| f == 0 || f > n) {
            return Err(Error::invalid(
                "data.floors",
                f,
                format!("masses of the chain, 1..={n}"),
            ));
        }
        let fnoise = d.frequency_noise.unwrap_or(0.0);
        let snoise = d.shape_noise.unwrap_or(0.0);
        check_f64(
            "data.frequency_noise",
            fnoise,
            fnoise >= 0.0,
            ">= 0 and finite",
        )?;
        check_f64("data.shape_noise", snoise, snoise >= 0.0, ">= 0 and finite")?;
        let m = crate::time::modal::undamped_modes(&truth)?;
        let mut rng = ChaCha8Rng::seed_from_u64(d.seed);
        let mut gauss = || -> f64 { StandardNormal.sample(&mut rng) };
        let mut modes = Vec::with_capacity(count);
        for j in 0..count {
            let omega = m.omega[j];
            if omega <= 0.0 {
                return Err(Error::invalid(
                    "data.modes",
                    count,
                    "elastic modes only (the chain has a rigid-body mode: fix an end)",
                ));
            }
            let f = omega / std::f64::consts::TAU;
            let peak = floors
                .iter()
                .map(|&i| m.shapes[(i - 1, j)].abs())
                .fold(0.0, f64::max);
            let frequency = f * (1.0 + fnoise * gauss());
            let shape = floors
                .iter()
                .map(|&i| ShapeEntry {
                    mass: i,
                    value: m.shapes[(i - 1, j)] + snoise * peak * gauss(),
                    se: (snoise > 0.0).then_some(snoise * peak),
                })
                .collect();
            modes.push(MeasuredMode {
                frequency,
                frequency_se: (fnoise > 0.0).then_some(fnoise * f),
                damping: None,
                damping_se: None,
                shape,
            });
        }
        MeasuredModes::new(modes)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{chain::Boundary, Chain, Defect};

    fn scene(data: &str) -> FitScene {
        FitScene::from_toml(&format!(
            "[chain]\nn = 5\nright = \"free\"\ndefects = [{{ kind = \"spring\", at = 2, k = 0.8 }}]\n[data]\nsource = \"modes\"\n{data}"
        ))
        .unwrap()
    }

    #[test]
    fn noise_free_modes_are_the_dense_eigenpairs() {
        // the generalized eigenproblem K phi = w^2 M phi, assembled here
        let truth = Chain::new(5)
            .unwrap()
            .with_boundaries(Boundary::Fixed, Boundary::Free)
            .unwrap()
            .with_defect(Defect::Spring { at: 2, k: 0.8 })
            .unwrap();
        let springs = truth.springs();
        let mut k = nalgebra::DMatrix::<f64>::zeros(5, 5);
        for (j, &kj) in springs.iter().enumerate() {
            // spring j joins masses j and j + 1 (0 and n + 1: the walls)
            for (a, b) in [(j, j), (j + 1, j + 1)] {
                if (1..=5).contains(&a) && a == b {
                    k[(a - 1, a - 1)] += kj;
                }
            }
            if (1..5).contains(&j) {
                k[(j - 1, j)] -= kj;
                k[(j, j - 1)] -= kj;
            }
        }
        let mut w2: Vec<f64> = k.symmetric_eigen().eigenvalues.iter().copied().collect();
        w2.sort_by(f64::total_cmp);
        let modes = scene("modes = 5\n").measured_modes().unwrap();
        for (j, m) in modes.modes().iter().enumerate() {
            let want = w2[j].sqrt() / std::f64::consts::TAU;
            assert!((m.frequency - want).abs() < 1e-12 * want, "{j}");
            assert!(m.frequency_se.is_none() && m.shape[0].se.is_none());
        }
    }

    #[test]
    fn shipped_scenes_of_several_sensors_and_of_modes_parse() {
        let modal =
            FitScene::from_toml(include_str!("../../../configs/scenes/modal-frame.toml")).unwrap();
        assert_eq!(modal.measured_modes().unwrap().len(), 3);
        let three = FitScene::from_toml(include_str!("../../../configs/scenes/three-sensors.toml"))
            .unwrap();
        assert_eq!(three.data.sensors().unwrap().len(), 3);
        assert!(three.data.is_joint() && !three.data.is_paper());
    }

    #[test]
    fn noise_is_seeded_and_stated() {
        let a = scene("modes = 2\nfrequency_noise = 0.01\nshape_noise = 0.05\nseed = 3\n");
        let (x, y) = (a.measured_modes().unwrap(), a.measured_modes().unwrap());
        assert_eq!(x, y);
        let b = scene("modes = 2\nfrequency_noise = 0.01\nshape_noise = 0.05\nseed = 4\n");
        assert_ne!(x, b.measured_modes().unwrap());
        assert!(x.modes()[0].frequency_se.unwrap() > 0.0);
    }

    #[test]
    fn bad_modal_data_name_their_field() {
        let field = |data: &str| match scene(data).measured_modes() {
            Err(Error::InvalidParameter { field, .. }) => field,
            other => panic!("{data}: {other:?}"),
        };
        assert_eq!(field("modes = 0\n"), "data.modes");
        assert_eq!(field("modes = 6\n"), "data.modes");
        assert_eq!(field("floors = []\n"), "data.floors");
        assert_eq!(field("floors = [1, 6]\n"), "data.floors");
        assert_eq!(field("frequency_noise = -0.1\n"), "data.frequency_noise");
        assert_eq!(field("shape_noise = nan\n"), "data.shape_noise");
        assert_eq!(field("noise = 0.1\n"), "data.noise");
        assert_eq!(field("path = \"m.csv\"\nmodes = 2\n"), "data.modes");
        let free_free = FitScene::from_toml(
            "[chain]\nn = 3\nleft = \"free\"\nright = \"free\"\n[data]\nsource = \"modes\"\n",
        )
        .unwrap();
        assert!(free_free.measured_modes().is_err());
    }
}
