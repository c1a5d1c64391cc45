//! A fit scene fitted on its own data, whatever they are: a record or
//! Laplace values (the scene path, [`crate::detect::fit::paper::fit`]) or
//! measured modes (the modal defect search,
//! [`crate::detect::fit::modal_scene::fit_modal_scene`]), with the options
//! of its `[search]`. The CLI's `fit --scene`, the `fit` study kind and
//! Python's `fit_scene` call this.
//!
//! ```
//! use springmass::detect::scene::FitScene;
//! use springmass::detect::fit::fit_scene;
//! let scene = FitScene::from_toml("[chain]\nn = 5\ndefects = [{ kind = \"mass\", at = 2, m = 3.0 }]\n")?;
//! assert_eq!(fit_scene(&scene)?.defects[0].at(), 2);
//! # Ok::<(), springmass::Error>(())
//! ```

use crate::detect::fit::modal_scene::fit_modal_scene;
use crate::detect::fit::paper::{fit, SceneReport};
use crate::detect::scene::{DataSourceKind, FitScene};
use crate::error::Result;

/// Fit the scene's unknowns to the scene's own data ([`FitScene::data`],
/// or its measured modes for `source = "modes"`).
///
/// # Errors
/// As [`FitScene::data`], [`fit`] and [`fit_modal_scene`].
pub fn fit_scene(scene: &FitScene) -> Result<SceneReport> {
    if scene.data.source == DataSourceKind::Modes {
        return fit_modal_scene(scene);
    }
    fit(scene, &scene.data()?, &scene.options())
}
