//! `springmass fit --data FILE --excitation ambient --observe 1,15,30`:
//! output-only fits (`springmass::detect::fit::ambient`).

use super::fit_args::Args;
use anyhow::Context;
use springmass::detect::data::ambient::AmbientRecord;
use springmass::detect::fit::ambient::{fit_ambient, AmbientOptions, AmbientTarget};
use springmass::detect::fit::profile::ProfileMode;
use springmass::forward::Observable;

/// Parse the flags, read the record, fit, print.
pub fn run(a: &Args) -> anyhow::Result<()> {
    let excitation = a.excitation.as_deref().unwrap_or_default();
    if excitation.trim() != "ambient" {
        anyhow::bail!(springmass::Error::invalid(
            "excitation",
            excitation,
            "ambient (an impulse or a measured force need no --excitation)"
        ));
    }
    let path = match a.data.as_slice() {
        [one] => one.clone(),
        [] => anyhow::bail!(springmass::Error::invalid(
            "data",
            "(none)",
            "--data FILE with --excitation ambient"
        )),
        more => anyhow::bail!(springmass::Error::invalid(
            "data",
            format!("{} files", more.len()),
            "one --data file with --excitation ambient"
        )),
    };
    let n = super::fit_args::chain_size(a)?;
    let opts = options(a)?;
    let kind: Observable = a
        .observe_kind
        .as_deref()
        .unwrap_or("displacement")
        .parse()?;
    let observe = if a.observe.is_empty() {
        vec![1]
    } else {
        a.observe.clone()
    };
    if let Some(model) = a
        .damping
        .as_deref()
        .filter(|m| *m != "grounded" && !m.contains(':'))
    {
        // the chain's own message would send the user to --fit d, which
        // fits only the grounded d here
        Err(springmass::Error::invalid(
            "damping",
            model,
            format!("{model} with its parameters given for an output-only record (e.g. between:0.05, rayleigh:0.01:0.02, modal:0.02): its fit estimates only the grounded model's d (--fit d)"),
        ))?;
    }
    let nominal = super::fit_modes::nominal_chain(a, n)?;
    let columns: Vec<&str> = a
        .column
        .as_deref()
        .map_or_else(Vec::new, |c| c.split(',').map(str::trim).collect());
    let series = springmass::series::TimeSeries::read_csv(&path)?;
    let rec = AmbientRecord::from_series_columns(&series, &columns, observe, kind)?;
    let report = fit_ambient(&nominal, &rec, &opts)
        .with_context(|| format!("fitting the ambient record {}", path.display()))?;
    super::print_report(a.json, &report, |r| r.summary())
}

/// The fit's options from the flags: --defects or --profile, --kinds,
/// --fit d (also when --d is not given: the damping is then unknown),
/// --ambient-on.
fn options(a: &Args) -> anyhow::Result<AmbientOptions> {
    let mut opts = AmbientOptions::default();
    let kinds = a.kinds.as_deref().or(a.profile.as_deref());
    if let Some(k) = kinds {
        opts.kinds = match k.trim() {
            "spring" | "springs" => ProfileMode::Springs,
            "mass" | "masses" => ProfileMode::Masses,
            other => Err(springmass::Error::invalid(
                "kinds",
                other,
                "spring or mass (with --excitation ambient)",
            ))?,
        };
    }
    if a.profile.is_some() {
        opts.target = AmbientTarget::Profile;
    } else {
        let text = a.defects.as_deref().unwrap_or("auto");
        let (k_min, k_max) = super::fit_modes::parse_defects(text)?;
        opts.target = AmbientTarget::Defects { k_min, k_max };
    }
    let fit = a.fit.as_deref().unwrap_or("");
    if let Some(other) = fit
        .split(',')
        .map(str::trim)
        .find(|p| !p.is_empty() && *p != "d")
    {
        anyhow::bail!(springmass::Error::invalid(
            "fit",
            other,
            "d (with --excitation ambient; the masses fix the scale)"
        ));
    }
    opts.fit_d = fit.contains('d') || a.d.is_none();
    if !a.ambient_on.is_empty() {
        opts.ambient_on = Some(a.ambient_on.clone());
    }
    if let Some(text) = &a.ambient_band {
        opts.force_band = Some(parse_band(text)?);
    }
    Ok(opts)
}

/// `LO:HI` of --ambient-band (the fit checks the range).
fn parse_band(text: &str) -> springmass::Result<(f64, f64)> {
    let bad = || {
        springmass::Error::invalid(
            "ambient_band",
            text,
            "LO:HI, two numbers with 0 <= LO < HI (rad per unit time)",
        )
    };
    let (lo, hi) = text.split_once(':').ok_or_else(bad)?;
    let lo: f64 = lo.trim().parse().map_err(|_| bad())?;
    let hi: f64 = hi.trim().parse().map_err(|_| bad())?;
    Ok((lo, hi))
}
