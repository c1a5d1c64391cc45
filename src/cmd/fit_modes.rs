//! `springmass fit --modes FILE`: structural model updating from measured
//! modes (`springmass::detect::fit::modal_update`).

use super::fit_args::Args;
use anyhow::Context;
use springmass::detect::data::modes::MeasuredModes;
use springmass::detect::fit::modal_update::{update_from_modes, ModalUpdateOptions};
use springmass::detect::fit::profile::ProfileMode;

/// Read the modes, build the nominal chain, update it, print the report.
pub fn run(a: &Args) -> anyhow::Result<()> {
    let path = a.modes.clone().expect("checked by the caller");
    let n = super::fit_args::chain_size(a)?;
    if a.defects.is_some() {
        return run_locate(a, n);
    }
    let mut opts = ModalUpdateOptions::default();
    if let Some(p) = &a.profile {
        opts.mode = ProfileMode::parse(p)?;
    }
    if let Some(s) = a.seed {
        opts.seed = s;
    }
    if let Some(s) = a.starts {
        opts.starts = s;
    }
    if let Some(h) = &a.hold_out {
        opts.hold_out = parse_list(h)?;
    }
    if let Some(f) = &a.modal_residual {
        opts.formulation = springmass::detect::fit::modal_update::ModalFormulation::parse(f)?;
    }
    opts.check()?;
    let nominal = nominal_chain(a, n)?;
    let modes = MeasuredModes::read_csv(&path)?;
    let report = update_from_modes(&nominal, modes, &opts)
        .with_context(|| format!("updating the chain from {}", path.display()))?;
    super::print_report(a.json, &report, |r| r.summary())
}

/// A `modes` scene with a `[profile]` (or `--profile`): every element of
/// the mode's kind updated from the scene's measured modes, against the
/// scene's uniform chain.
pub fn run_scene(
    a: &Args,
    scene: &springmass::detect::scene::FitScene,
    mode: ProfileMode,
) -> anyhow::Result<()> {
    let opts = ModalUpdateOptions {
        mode,
        seed: a.seed.unwrap_or(0),
        ..ModalUpdateOptions::default()
    };
    opts.check()?;
    let modes = scene.measured_modes().context("in [data]")?;
    let report = update_from_modes(&scene.truth()?.uniform(), modes, &opts)?;
    super::print_report(a.json, &report, |r| r.summary())
}

/// `--defects`: which elements changed.
fn run_locate(a: &Args, n: usize) -> anyhow::Result<()> {
    use springmass::detect::fit::modal_locate::{locate_from_modes, ModalLocateOptions};
    let path = a.modes.clone().expect("checked by the caller");
    if let Some(h) = &a.hold_out {
        // the search fits every mode; it was silently ignored
        Err(springmass::Error::invalid(
            "hold_out",
            h,
            "no modes held out with --defects (the defect search fits every mode; --hold-out belongs to the profile, without --defects)",
        ))?;
    }
    let mut opts = ModalLocateOptions::default();
    let text = a.defects.as_deref().unwrap_or("auto");
    (opts.k_min, opts.k_max) = parse_defects(text)?;
    opts.extend = text.trim() == "auto";
    if let Some(f) = &a.modal_residual {
        opts.formulation = springmass::detect::fit::modal_update::ModalFormulation::parse(f)?;
    }
    let nominal = nominal_chain(a, n)?;
    let modes = MeasuredModes::read_csv(&path)?;
    let kinds = a.kinds.as_deref().unwrap_or("default");
    (opts.kinds, opts.dampers) =
        springmass::detect::fit::modal_locate::parse_kinds(kinds, &nominal, &modes)?;
    let ratios = modes.modes().iter().any(|m| m.damping.is_some());
    if kinds.contains("any") && !ratios && springmass::time::survey_modes::is_damped(&nominal) {
        eprintln!(
            "note: the table has no damping ratios (column damping): the dampers are not searched"
        );
    }
    let report = locate_from_modes(&nominal, modes, &opts)
        .with_context(|| format!("searching the modes of {}", path.display()))?;
    super::print_report(a.json, &report, |r| r.summary())
}

/// `auto` (0..=2), `auto:K` (0..=K) or `K` (exactly K).
pub(crate) fn parse_defects(text: &str) -> springmass::Result<(usize, usize)> {
    springmass::detect::fit::modal_locate::parse_defect_count(text)
}

/// The nominal chain of the flags: uniform (--mass, --k, --d) or a baseline.
pub(crate) fn nominal_chain(a: &Args, n: usize) -> anyhow::Result<springmass::Chain> {
    let spec = springmass::detect::fit::options::FitSpec {
        d: Some(a.d.unwrap_or(0.0)),
        k: a.k,
        mass: a.mass,
        left: a.left.clone(),
        right: a.right.clone(),
        damping: a.damping.clone(),
        baseline: super::fit_args::baseline_spec(a),
        ..springmass::detect::fit::options::FitSpec::new(n)
    };
    Ok(spec.model()?.chain().clone())
}

/// `3,4` -> `[3, 4]`.
fn parse_list(text: &str) -> springmass::Result<Vec<usize>> {
    text.split(',')
        .map(|p| {
            p.trim().parse::<usize>().map_err(|_| {
                springmass::Error::invalid(
                    "hold_out",
                    text,
                    "mode numbers separated by commas, e.g. 3,4",
                )
            })
        })
        .collect()
}
