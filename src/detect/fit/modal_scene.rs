//! The scene path on modal data (`[data] source = "modes"`): the modal
//! defect search ([`locate_from_modes`]) on the scene's measured modes,
//! against the scene's uniform chain (its boundaries kept), answered in the
//! scene's report, so that scenes and studies score modal data as they
//! score records.
//!
//! ```
//! use springmass::detect::scene::FitScene;
//! use springmass::detect::fit::fit_scene;
//! let scene = FitScene::from_toml(r#"
//!     [chain]
//!     n = 6
//!     right = "free"
//!     defects = [{ kind = "spring", at = 3, k = 0.7 }]
//!     [data]
//!     source = "modes"
//!     modes = 3
//!     floors = [2, 4, 6]
//!     [unknowns]
//!     kind = "spring"
//! "#)?;
//! let r = fit_scene(&scene)?;
//! assert_eq!(r.defects[0].at(), 3);
//! assert!((r.defects[0].value() - 0.7).abs() < 1e-6);
//! # Ok::<(), springmass::Error>(())
//! ```

use crate::chain::Defect;
use crate::detect::fit::modal_locate::{locate_from_modes, ModalLocateOptions};
use crate::detect::fit::modal_update::ModalFormulation;
use crate::detect::fit::paper::SceneReport;
use crate::detect::fit::profile::ProfileMode;
use crate::detect::fit::report::{Alternative, Status};
use crate::detect::scene::FitScene;
use crate::detect::search::FitMethod;
use crate::detect::unknowns::DefectKind;
use crate::error::{Error, Result};
use std::time::Instant;

/// Which elements the scene's `unknowns.kind` lets the modes search.
///
/// # Errors
/// [`Error::InvalidParameter`] naming `unknowns.kind`: dampers or grounds
/// (undamped modes do not see them).
pub fn modal_kinds(scene: &FitScene) -> Result<ProfileMode> {
    let kinds = scene.unknowns.kind.kinds();
    let mass = kinds.contains(&DefectKind::Mass);
    let spring = kinds.contains(&DefectKind::Spring);
    match (mass, spring) {
        (true, true) => Ok(ProfileMode::Both),
        (true, false) => Ok(ProfileMode::Masses),
        (false, true) => Ok(ProfileMode::Springs),
        (false, false) => Err(Error::invalid(
            "unknowns.kind",
            scene.unknowns.kind.name(),
            "mass, spring or any with modal data (undamped modes see masses and springs)",
        )),
    }
}

/// The scene's `data.modal_residual` (default: the property difference).
///
/// # Errors
/// [`Error::InvalidParameter`] naming `data.modal_residual`.
pub fn formulation(scene: &FitScene) -> Result<ModalFormulation> {
    match &scene.data.modal_residual {
        None => Ok(ModalFormulation::default()),
        Some(text) => ModalFormulation::parse(text).map_err(|_| {
            Error::invalid(
                "data.modal_residual",
                text,
                "property (the modal-property difference) or dynamic (the modal dynamic residual)",
            )
        }),
    }
}

/// The modal search is exhaustive: a `modes` scene takes `enumerate`.
///
/// # Errors
/// [`Error::InvalidParameter`] naming `search.method`.
pub fn check_method(scene: &FitScene) -> Result<()> {
    if scene.search.method != FitMethod::Enumerate {
        return Err(Error::invalid(
            "search.method",
            scene.search.method.name(),
            "enumerate with modal data (the modal defect search fits every position set)",
        ));
    }
    Ok(())
}

/// Fit a `modes` scene: the modal defect search for exactly the scene's
/// `unknowns.k` changed elements of the kinds of `unknowns.kind`.
///
/// # Errors
/// As [`FitScene::measured_modes`], [`modal_kinds`] and
/// [`locate_from_modes`]; `unknowns` as [`FitScene::unknowns`].
pub fn fit_modal_scene(scene: &FitScene) -> Result<SceneReport> {
    let t0 = Instant::now();
    check_method(scene)?;
    let modes = scene.measured_modes()?;
    let kinds = modal_kinds(scene)?;
    let k = scene.unknowns()?.k();
    let nominal = scene.truth()?.uniform();
    let opts = ModalLocateOptions {
        kinds: Some(kinds),
        k_min: k,
        k_max: k,
        formulation: formulation(scene)?,
        ..ModalLocateOptions::default()
    };
    let setup = t0.elapsed().as_secs_f64();
    let t1 = Instant::now();
    let r = locate_from_modes(&nominal, modes, &opts)?;
    let defects: Vec<Defect> = r
        .chain
        .defects()
        .iter()
        .filter(|d| {
            r.defects
                .iter()
                .any(|e| e.at == d.at() && e.kind == kind_name(d))
        })
        .copied()
        .collect();
    let se = |d: &Defect| {
        r.defects
            .iter()
            .find(|e| e.at == d.at() && e.kind == kind_name(d))
            .and_then(|e| e.se.map(|s| s * e.nominal))
            .unwrap_or(f64::NAN)
    };
    let std_errors: Vec<f64> = defects.iter().map(se).collect();
    let runners_up = r
        .runner_up
        .as_ref()
        .map(|(_, gap)| Alternative::new(r.runner_up_defects.clone(), r.chi2 + gap, r.chi2))
        .into_iter()
        .collect();
    let fits_data = r.status != Status::ModelMismatch;
    Ok(SceneReport {
        method: "modal defect search (exhaustive)".into(),
        defects,
        residual: r.chi2,
        error_bars: std_errors.clone(),
        runners_up,
        evaluations: r.sets,
        sets: Some(r.sets),
        exhaustive: Some(true),
        wall_time_s: t1.elapsed().as_secs_f64(),
        setup_time_s: setup,
        trace: Vec::new(),
        misfit: format!(
            "modal {} ({} weights)",
            opts.formulation.name(),
            if r.errors_given { "given" } else { "assumed" }
        ),
        nodes: r.dof,
        floor: (r.dof.max(1) as f64).ln(),
        status: r.status,
        message: r.message,
        resolved: r.resolved,
        fits_data,
        certified: false,
        std_errors,
        chain_params: Vec::new(),
        identifiability: None,
    })
}

/// `spring` or `mass`, as the modal report names a defect's kind.
fn kind_name(d: &Defect) -> &'static str {
    if matches!(d, Defect::Mass { .. }) {
        "mass"
    } else {
        "spring"
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scene(tail: &str) -> FitScene {
        FitScene::from_toml(&format!(
            "[chain]\nn = 8\nright = \"free\"\ndefects = [{{ kind = \"spring\", at = 3, k = 0.7 }}, {{ kind = \"spring\", at = 6, k = 1.3 }}]\n[data]\nsource = \"modes\"\nmodes = 4\nfloors = [2, 4, 6, 8]\n{tail}"
        ))
        .unwrap()
    }

    #[test]
    fn noisy_modes_place_two_springs_within_their_errors() {
        let s = scene("frequency_noise = 0.002\nshape_noise = 0.01\nseed = 5\n[unknowns]\nkind = \"spring\"\n");
        let r = fit_modal_scene(&s).unwrap();
        assert_eq!(r.status, Status::Converged, "{}", r.message);
        let at: Vec<usize> = r.defects.iter().map(Defect::at).collect();
        assert_eq!(at, [3, 6]);
        for (d, (want, se)) in r.defects.iter().zip([0.7, 1.3].iter().zip(&r.std_errors)) {
            assert!((d.value() - want).abs() < 4.0 * se, "{d:?} +- {se}");
        }
        assert_eq!(r.runners_up.len(), 1);
        assert!(r.runners_up[0].gap > 0.0);
        assert_eq!(r.runners_up[0].defects.len(), 2);
    }

    #[test]
    fn dampers_are_refused_with_modes() {
        let s = scene("[unknowns]\nkind = \"damper\"\nk = 1\n");
        match fit_modal_scene(&s) {
            Err(Error::InvalidParameter { field, .. }) => assert_eq!(field, "unknowns.kind"),
            other => panic!("{other:?}"),
        }
    }
}
