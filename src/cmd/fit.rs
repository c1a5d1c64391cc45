//! `springmass fit`: fit defects to a measured series (`--data`, the
//! data-first pipeline `springmass::detect::fit::fit`) or to the data a TOML
//! scene describes (`--scene`, see `springmass::detect::scene`).

pub use super::fit_args::Args;
use super::fit_args::{baseline_spec, chain_size};
use anyhow::Context;
use springmass::detect::data::observations::{Observations, Series};
use springmass::detect::fit::fit_scene;
use springmass::detect::fit::identify::Identifiability;
use springmass::detect::fit::options::FitSpec;
use springmass::detect::fit::paper::SceneReport;
use springmass::detect::fit::FitMethod;
use springmass::detect::scene::FitScene;
use springmass::series::TimeSeries;

pub fn run(a: Args) -> anyhow::Result<()> {
    if a.modes.is_some() {
        return super::fit_modes::run(&a);
    }
    if a.excitation.is_some() {
        return super::fit_ambient::run(&a);
    }
    if !a.data.is_empty() {
        return run_data(a);
    }
    let Some(scene_path) = a.scene.clone() else {
        anyhow::bail!(springmass::Error::invalid(
            "data",
            "(none)",
            "--data FILE (a measured series) or --scene FILE (a fit scene)"
        ));
    };
    let mut scene = FitScene::load(&scene_path)?;
    apply_flags(&a, &mut scene)?;
    if let Some(mode) = scene.profile.requested() {
        let mode = springmass::detect::fit::profile::ProfileMode::parse(mode)?;
        scene.profile.check()?;
        if scene.data.source == springmass::detect::scene::DataSourceKind::Modes {
            return super::fit_modes::run_scene(&a, &scene, mode);
        }
        let truth = scene.truth()?;
        let model = springmass::detect::fit::Model::from_chain(&truth.uniform());
        let (obs, sigma) = scene.observations().context("in [data]")?;
        let noise = sigma.map_or(
            springmass::detect::fit::NoiseSpec::Auto,
            springmass::detect::fit::NoiseSpec::Sigma,
        );
        let (change, penalty) = (scene.profile.change, scene.profile.penalty);
        let r = run_profile(&a, &scene_path, &obs, &model, mode, noise, change, penalty)?;
        if !a.json {
            println!("{}", truth_line(&r, &truth));
        }
        return Ok(());
    }
    if a.plot.is_some() || a.out_csv.is_some() {
        anyhow::bail!(springmass::Error::invalid(
            if a.plot.is_some() { "plot" } else { "out_csv" },
            "(with --scene)",
            "--data FILE, or a profile (--profile or the scene's [profile] table)"
        ));
    }
    let report = fit_scene(&scene)?;
    if a.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print_text(&scene, &report);
    }
    Ok(())
}

/// The command line's flags that override a scene's fields: `--method`,
/// `--seed`, `--noise`, `--max-evals`, `--trace`, `--profile`,
/// `--profile-change`, `--penalty`.
fn apply_flags(a: &Args, scene: &mut FitScene) -> anyhow::Result<()> {
    if let Some(m) = &a.method {
        scene.search.method = FitMethod::parse(m)?;
    }
    if let Some(s) = a.seed {
        scene.search.seed = s;
    }
    if a.exhaustive {
        scene.search.exhaustive = true;
    }
    if let Some(x) = &a.noise {
        let v: f64 = x.parse().map_err(|_| {
            springmass::Error::invalid(
                "noise",
                x,
                "a number >= 0 (the synthetic data's noise level)",
            )
        })?;
        springmass::error::check_f64("noise", v, v >= 0.0, ">= 0 and finite")?;
        scene.data.noise = v;
    }
    if let Some(m) = a.max_evals {
        scene.search.max_evals = m;
    }
    if a.trace {
        scene.search.trace = true;
    }
    if let Some(m) = &a.profile {
        scene.profile.mode = Some(m.clone());
    }
    if let Some(c) = a.profile_change {
        scene.profile.change = Some(c);
    }
    if let Some(w) = a.penalty {
        scene.profile.penalty = Some(w);
    }
    Ok(())
}

/// The force column `name` of `table` (`None`: its first value column).
fn force_column(table: &TimeSeries, name: Option<&str>) -> springmass::Result<Vec<f64>> {
    let col = match name {
        Some(c) => table.column(c).ok_or_else(|| {
            springmass::Error::invalid(
                "force_column",
                c,
                format!("one of the file's columns: {}", table.names().join(", ")),
            )
        })?,
        None => table.column_at(0).ok_or_else(|| {
            springmass::Error::invalid("force", "(no value column)", "a force column")
        })?,
    };
    Ok(col.to_vec())
}

/// `springmass fit --data`: the data-first pipeline.
fn run_data(a: Args) -> anyhow::Result<()> {
    use springmass::detect::fit as dfit;
    let path = a.data[0].clone();
    let n = chain_size(&a)?;
    // every option is parsed before the data are read or any work starts
    let spec = data_spec(&a, n);
    let (model, opts) = spec.build()?;
    let profile = profile_mode(&a)?;
    let (obs, axes) = match a.data.len() {
        1 => read_observations(&a, &path, &spec, &opts)?,
        _ => read_records(&a, &spec, &opts, profile.is_some())?,
    };
    if let Some(mode) = profile {
        let (c, w) = (a.profile_change, a.penalty);
        run_profile(&a, &path, &obs, &model, mode, opts.noise, c, w)?;
        return Ok(());
    }
    opts.validate(&obs, &model)?;
    springmass::io::check_outputs(a.plot_posterior.iter().map(|p| p.as_path()))?;
    let report = with_spinner(a.json, "fitting", || dfit::fit(&obs, &model, &opts))?;
    if let Some(p) = &report.predicted {
        if let Some(out) = &a.out_csv {
            TimeSeries::new(
                p.t.clone(),
                vec![
                    ("observed".into(), p.observed.clone()),
                    ("model".into(), p.model.clone()),
                    ("residual".into(), p.residual.clone()),
                ],
            )?
            .write_csv(out)?;
        }
        if let Some(svg) = &a.plot {
            fit_plot(&path, &report, p, &axes).write_svg(svg)?;
        }
    }
    if a.json {
        println!("{}", json_report(&report)?);
    } else {
        print!("{}", report.summary());
    }
    if let Some(svg) = &a.plot_posterior {
        match &report.posterior {
            Some(post) => posterior_plot(&path, post, model.n()).write_svg(svg)?,
            None => anyhow::bail!(
                "no probabilities over hypotheses to plot (--no-uncertainty, or they could not be computed)"
            ),
        }
    }
    Ok(())
}

/// The probability of a defect at each site along the chain, one spike
/// per site and kind.
fn posterior_plot(
    path: &std::path::Path,
    post: &springmass::detect::fit::posterior::Posterior,
    n: usize,
) -> springmass::plot::LinePlot {
    use springmass::plot::{Line, LinePlot};
    let file = path
        .file_name()
        .unwrap_or(path.as_os_str())
        .to_string_lossy();
    let mut plot = LinePlot::new(
        format!(
            "probability of a defect at each site, {file} (answer {:.3}; not refitted: up to {:.1e})",
            post.answer_probability, post.pruned_bound
        ),
        format!("position along the chain (masses 1..{n}, springs 0..{n})"),
        "probability",
    )
    .y_range(0.0, 1.05)
    .integer_x(true);
    let mut kinds: Vec<&str> = post.position_probability.iter().map(|p| p.kind).collect();
    kinds.dedup();
    for kind in kinds {
        let mut spikes = vec![(0.0, 0.0)];
        let mut tops = Vec::new();
        for p in post.position_probability.iter().filter(|p| p.kind == kind) {
            let x = p.at as f64;
            spikes.extend([(x, 0.0), (x, p.probability), (x, 0.0)]);
            tops.push((x, p.probability));
        }
        spikes.push((n as f64, 0.0));
        plot = plot
            .line(Line::new(kind.to_string(), spikes))
            .line(Line::new(format!("{kind} (site)"), tops).markers());
    }
    plot.size(900, 420)
}

/// The options of a data-first fit as the library takes them.
fn data_spec(a: &Args, n: usize) -> FitSpec {
    FitSpec {
        d: a.d,
        k: a.k,
        mass: a.mass,
        gamma: a.gamma,
        left: a.left.clone(),
        right: a.right.clone(),
        observe: a.observe.first().copied(),
        observe_kind: a.observe_kind.clone().filter(|k| !k.contains(',')),
        sensors: match (a.observe.len(), kind_list(a).len()) {
            (0 | 1, 0 | 1) => Vec::new(),
            (0, _) => vec![1],
            _ => a.observe.clone(),
        },
        sensor_kinds: kind_list(a),
        fit: a.fit.clone(),
        known: a.known.clone(),
        defects: a.defects.clone(),
        kinds: a.kinds.clone(),
        noise: a.noise.clone(),
        misfit: a.misfit.clone(),
        method: a.method.clone(),
        criterion: a.criterion.clone(),
        seed: a.seed,
        max_evals: a.max_evals,
        trigger: a.trigger.clone(),
        force_window: a.force_window.clone(),
        noise_model: a.noise_model.clone(),
        nuisance: a.nuisance.clone(),
        damping: a.damping.clone(),
        baseline: baseline_spec(a),
        level: a.level,
        prior_k: a.prior_k.clone(),
        prior_range: a.prior_range.clone(),
        uncertainty: a.no_uncertainty.then_some(false),
        exhaustive: a.exhaustive.then_some(true),
        effort: a.effort.clone(),
        ..FitSpec::new(n)
    }
}

/// `--observe-kind` as a list of several kinds (empty: one kind or none).
fn kind_list(a: &Args) -> Vec<String> {
    match a.observe_kind.as_deref() {
        Some(k) if k.contains(',') => k.split(',').map(|s| s.trim().to_string()).collect(),
        _ => Vec::new(),
    }
}

/// `--profile` parsed, with its options checked (before the data are read).
fn profile_mode(a: &Args) -> anyhow::Result<Option<springmass::detect::fit::profile::ProfileMode>> {
    let profile = a
        .profile
        .as_deref()
        .map(springmass::detect::fit::profile::ProfileMode::parse)
        .transpose()?;
    if let Some(c) = a.profile_change {
        springmass::error::check_f64("profile_change", c, c > 0.0, "> 0 and finite")?;
    }
    if let Some(w) = a.penalty {
        springmass::error::check_f64("penalty", w, w > 0.0, "> 0 and finite")?;
    }
    Ok(profile)
}

/// Axis labels of the data: the time and the fitted column, each with the
/// unit its header gave (`t [s]`, `x1 [m]`).
struct AxisNames {
    t: String,
    x: String,
}

/// The record of `path` as observations (the fitted column, the sensor,
/// the measured force if any), and the names of its axes.
fn read_observations(
    a: &Args,
    path: &std::path::Path,
    spec: &FitSpec,
    opts: &springmass::detect::fit::FitOptions,
) -> anyhow::Result<(Observations, AxisNames)> {
    if !spec.sensors.is_empty() {
        return read_sensors(a, path, spec, opts);
    }
    // the sensor is checked before the data are read; the force is data
    let sensor_only = spec.measurement(None)?;
    let table = TimeSeries::read_csv(path)?;
    // the fitted column: --column, or the first one that is not the force
    let column = match (&a.column, &a.force_column, &a.force) {
        (Some(c), _, _) => Some(c.clone()),
        (None, Some(fc), None) => table.names().iter().find(|c| *c != fc).cloned(),
        _ => None,
    };
    // units in the header converted to SI (or refused when they contradict
    // the observable)
    let fitted = column
        .clone()
        .or_else(|| table.names().first().cloned())
        .unwrap_or_default();
    let (table, notes) =
        springmass::units::record_in_si(&table, &fitted, sensor_only.sensor().kind)?;
    for note in &notes {
        eprintln!("note: {note}");
    }
    let series = Series::from_table(&table, column.as_deref(), opts.noise.known())?;
    let measurement = if a.force.is_some() || a.force_column.is_some() {
        spec.measurement_at(table.t(), Some(read_force(a, &table)?))?
    } else {
        sensor_only
    };
    let with_unit = |name: &str, unit: Option<&str>| match unit {
        Some(u) => format!("{name} [{u}]"),
        None => name.to_string(),
    };
    let x_name = column
        .clone()
        .or_else(|| table.names().first().cloned())
        .unwrap_or_else(|| "x".into());
    let axes = AxisNames {
        t: with_unit("t", table.time_unit()),
        x: with_unit(&x_name, table.unit(&x_name)),
    };
    Ok((
        Observations::Series(series.with_measurement(measurement)?),
        axes,
    ))
}

/// Several records of the same chain (`--data` repeated), each read as
/// one record is, joined for one joint fit.
fn read_records(
    a: &Args,
    spec: &FitSpec,
    opts: &springmass::detect::fit::FitOptions,
    profile: bool,
) -> anyhow::Result<(Observations, AxisNames)> {
    let refuse = |what: &str, value: String| -> anyhow::Result<()> {
        anyhow::bail!(springmass::Error::invalid(
            what,
            value,
            format!(
                "one --data file with {what} ({} given: several records are fitted jointly as one defect fit of records of one sensor each, with their own force columns)",
                a.data.len()
            ),
        ))
    };
    if !spec.sensors.is_empty() {
        refuse("observe", format!("{:?}", spec.sensors))?;
    }
    if a.force.is_some() {
        refuse("force", "a force file".into())?;
    }
    if profile {
        refuse("profile", a.profile.clone().unwrap_or_default())?;
    }
    let mut records = Vec::new();
    let mut axes = None;
    for path in &a.data {
        let (obs, ax) = read_observations(a, path, spec, opts)
            .with_context(|| format!("record {}", path.display()))?;
        let Observations::Series(s) = obs else {
            anyhow::bail!("{}: not a sampled series", path.display());
        };
        records.push(s);
        axes.get_or_insert(ax);
    }
    let first = records.remove(0);
    Ok((
        Observations::Series(first.with_records(records)?),
        axes.expect("at least two records"),
    ))
}

/// The record of several sensors of `path` (`--observe` a list): one value
/// column per sensor (`--column a,b,c`, or the value columns in order, the
/// force column left out), each in SI units, with the measured force if
/// any.
fn read_sensors(
    a: &Args,
    path: &std::path::Path,
    spec: &FitSpec,
    opts: &springmass::detect::fit::FitOptions,
) -> anyhow::Result<(Observations, AxisNames)> {
    // the sensors are checked before the data are read; the force is data
    let sensors = spec.measurements(None)?;
    let mut table = TimeSeries::read_csv(path)?;
    let columns: Option<Vec<String>> = a
        .column
        .as_ref()
        .map(|c| c.split(',').map(|s| s.trim().to_string()).collect());
    let skip = a.force_column.as_deref().filter(|_| a.force.is_none());
    let names: Vec<String> = match &columns {
        Some(c) => c.clone(),
        None => table
            .names()
            .iter()
            .filter(|c| Some(c.as_str()) != skip)
            .take(sensors.len())
            .cloned()
            .collect(),
    };
    for (name, m) in names.iter().zip(&sensors) {
        if table.column(name).is_none() {
            continue; // named by the reader below
        }
        let (t, notes) = springmass::units::record_in_si(&table, name, m.sensor().kind)?;
        for note in &notes {
            eprintln!("note: {note}");
        }
        table = t;
    }
    let measurements = if a.force.is_some() || a.force_column.is_some() {
        spec.measurements_at(table.t(), Some(read_force(a, &table)?))?
    } else {
        sensors
    };
    let series = Series::from_table_sensors(
        &table,
        columns.as_deref(),
        skip,
        measurements,
        opts.noise.known(),
    )?;
    let axes = AxisNames {
        t: match table.time_unit() {
            Some(u) => format!("t [{u}]"),
            None => "t".to_string(),
        },
        x: names.first().cloned().unwrap_or_else(|| "x".into()),
    };
    Ok((Observations::Series(series), axes))
}

/// The measured force: `--force FILE` (same times as the data) or a column
/// of the data (`--force-column`).
fn read_force(a: &Args, table: &TimeSeries) -> anyhow::Result<Vec<f64>> {
    use springmass::series::TimeSeries;
    let Some(fpath) = &a.force else {
        return Ok(force_column(table, a.force_column.as_deref())?);
    };
    let ft =
        TimeSeries::read_csv(fpath).with_context(|| format!("force from {}", fpath.display()))?;
    let same = ft.t().len() == table.t().len()
        && ft
            .t()
            .iter()
            .zip(table.t())
            .all(|(a, b)| (a - b).abs() <= 1e-9 * b.abs().max(1e-9));
    if !same {
        return Err(springmass::Error::invalid(
            "force",
            fpath.display(),
            "a CSV with the same times as --data",
        )
        .into());
    }
    Ok(force_column(&ft, a.force_column.as_deref())?)
}

/// `job`, with a spinner and the elapsed time on stderr while it runs when
/// stderr is a terminal (nothing when piped, or with `quiet`: --json).
fn with_spinner<T>(quiet: bool, what: &str, job: impl FnOnce() -> T) -> T {
    use std::io::IsTerminal;
    if quiet || !std::io::stderr().is_terminal() {
        return job();
    }
    let pb = indicatif::ProgressBar::new_spinner();
    if let Ok(style) = indicatif::ProgressStyle::with_template("{spinner} {msg} ({elapsed})") {
        pb.set_style(style);
    }
    pb.set_message(what.to_string());
    pb.enable_steady_tick(std::time::Duration::from_millis(120));
    let out = job();
    pb.finish_and_clear();
    out
}

/// The fit plot: the record and the model on top, the residual below on
/// its own axis with the noise band (+-1 sigma and +-2 sigma); the title
/// carries the fit's status and whether the model fits the data.
fn fit_plot(
    path: &std::path::Path,
    r: &springmass::detect::fit::FitReport,
    p: &springmass::detect::fit::report::Predicted,
    axes: &AxisNames,
) -> springmass::plot::LinePlot {
    use springmass::plot::{Line, LinePlot};
    let pts = |y: &[f64]| {
        p.t.iter()
            .copied()
            .zip(y.iter().copied())
            .collect::<Vec<_>>()
    };
    let band = |w: f64| -> Vec<(f64, f64, f64)> {
        p.t.iter()
            .map(|&t| (t, -w * r.noise_sigma, w * r.noise_sigma))
            .collect()
    };
    let verdict = if r.fits_data {
        format!("fits the data (p = {:.2})", r.fit_p_value)
    } else {
        format!("does NOT fit the data (p = {:.1e})", r.fit_p_value)
    };
    let file = path
        .file_name()
        .unwrap_or(path.as_os_str())
        .to_string_lossy();
    let title = format!("fit of {file}: k = {}, {}, {verdict}", r.k, r.status.name());
    let (top, bottom) = ("data and model", "residual (data - model)");
    LinePlot::new(title, axes.t.clone(), axes.x.clone())
        .line(Line::new("observed", pts(&p.observed)).panel(top))
        .line(Line::new("model", pts(&p.model)).dashed().panel(top))
        .line(
            Line::new("noise +-2 sigma", Vec::new())
                .band(band(2.0))
                .panel(bottom),
        )
        .line(Line::new("residual", pts(&p.residual)).panel(bottom))
        .own_y(true)
        .columns(1)
        .panel_y_labels(vec![axes.x.clone(), format!("residual {}", axes.x)])
        .size(1000, 720)
}

/// How the truth of a scene compares with its fitted profile: the visible
/// values within 2 standard errors of it, and the largest error.
fn truth_line(
    r: &springmass::detect::fit::profile::ProfileReport,
    truth: &springmass::Chain,
) -> String {
    let (masses, springs) = (truth.masses(), truth.springs());
    let (mut within, mut visible, mut worst) = (0, 0, 0.0f64);
    for e in r.elements.iter().filter(|e| e.visible) {
        let t = if e.kind == "mass" {
            masses[e.at - 1]
        } else {
            springs[e.at]
        };
        visible += 1;
        within += usize::from((e.value - t).abs() <= 2.0 * e.se);
        worst = worst.max((e.value / t - 1.0).abs());
    }
    format!(
        "truth ([chain]): {within} of {visible} visible values within 2 SE; largest relative error {worst:.2e}"
    )
}

/// `springmass fit --data ... --profile MODE` (or a scene's profile): the
/// whole-profile inversion.
#[allow(clippy::too_many_arguments)]
fn run_profile(
    a: &Args,
    path: &std::path::Path,
    obs: &springmass::detect::data::observations::Observations,
    model: &springmass::detect::fit::Model,
    mode: springmass::detect::fit::profile::ProfileMode,
    noise: springmass::detect::fit::NoiseSpec,
    change: Option<f64>,
    penalty: Option<f64>,
) -> anyhow::Result<springmass::detect::fit::profile::ProfileReport> {
    use springmass::detect::fit::fit_profile;
    use springmass::detect::fit::profile::ProfileOptions;
    // refuse a FIFO, device or folder as --out-csv/--plot before the fit
    springmass::io::check_outputs(a.out_csv.iter().chain(&a.plot).map(|p| p.as_path()))?;
    let mut po = ProfileOptions::new(mode);
    po.noise = noise;
    if let Some(c) = change {
        po.change = c;
    }
    po.lambda = penalty;
    let r = fit_profile(obs, model, &po)?;
    if let Some(out) = &a.out_csv {
        write_profile_csv(out, &r)?;
    }
    if let Some(svg) = &a.plot {
        plot_profile(svg, &r, mode, path)?;
    }
    super::print_report(a.json, &r, |r| r.summary())?;
    Ok(r)
}

/// The profile's elements as CSV (kind, at, value, se, uniform, visible,
/// depth) to `out`.
fn write_profile_csv(
    out: &std::path::Path,
    r: &springmass::detect::fit::profile::ProfileReport,
) -> anyhow::Result<()> {
    // issue 32 item 8: built in memory, written by the atomic writer
    let mut w = csv::Writer::from_writer(Vec::new());
    w.write_record(["kind", "at", "value", "se", "uniform", "visible", "depth"])?;
    for e in &r.elements {
        w.write_record([
            e.kind.to_string(),
            e.at.to_string(),
            format!("{:.10e}", e.value),
            format!("{:.4e}", e.se),
            format!("{}", e.uniform),
            e.visible.to_string(),
            format!("{}", e.depth),
        ])?;
    }
    let bytes = w.into_inner().map_err(|e| anyhow::anyhow!("{e}"))?;
    springmass::io::write_atomic(out, &bytes)
        .with_context(|| format!("cannot write {}", out.display()))?;
    Ok(())
}

/// The profile against position: visible values with their 2 SE band, and
/// the values the data cannot see.
fn plot_profile(
    svg: &std::path::Path,
    r: &springmass::detect::fit::profile::ProfileReport,
    mode: springmass::detect::fit::profile::ProfileMode,
    path: &std::path::Path,
) -> anyhow::Result<()> {
    let mut plot = springmass::plot::LinePlot::new(
        format!(
            "profile of {} from {} ({} of {} visible)",
            mode.name(),
            path.display(),
            r.visible_count(),
            r.elements.len()
        ),
        "position",
        "value",
    );
    for kind in ["mass", "spring"] {
        let of: Vec<_> = r.elements.iter().filter(|e| e.kind == kind).collect();
        if of.is_empty() {
            continue;
        }
        let pts = |f: &dyn Fn(&&springmass::detect::fit::profile::ElementEstimate) -> f64| {
            of.iter()
                .filter(|e| e.visible)
                .map(|e| (e.at as f64, f(e)))
                .collect::<Vec<_>>()
        };
        plot = plot
            .line(
                springmass::plot::Line::new(format!("{kind} (visible)"), pts(&|e| e.value))
                    .markers(),
            )
            .line(
                springmass::plot::Line::new(
                    format!("{kind} +2 SE"),
                    pts(&|e| e.value + 2.0 * e.se),
                )
                .dashed(),
            )
            .line(
                springmass::plot::Line::new(
                    format!("{kind} -2 SE"),
                    pts(&|e| e.value - 2.0 * e.se),
                )
                .dashed(),
            );
        let hidden: Vec<(f64, f64)> = of
            .iter()
            .filter(|e| !e.visible)
            .map(|e| (e.at as f64, e.value))
            .collect();
        if !hidden.is_empty() {
            plot = plot.line(
                springmass::plot::Line::new(format!("{kind} (not visible)"), hidden).markers(),
            );
        }
    }
    plot.write_svg(svg)?;
    Ok(())
}

/// The JSON form of a data-first report: the answer first, the predicted
/// series left out (see --out-csv).
fn json_report(r: &springmass::detect::fit::FitReport) -> anyhow::Result<String> {
    let mut v = serde_json::to_value(r)?;
    if let Some(o) = v.as_object_mut() {
        o.remove("predicted");
    }
    Ok(serde_json::to_string_pretty(&v)?)
}

/// `(at, value)` for masses; `(kind at, value)` for other kinds or when
/// `kinds` (the general fit).
fn fmt_defects(d: &[springmass::Defect], kinds: bool) -> String {
    d.iter()
        .map(|d| match d {
            springmass::Defect::Mass { .. } if !kinds => format!("({}, {:.6})", d.at(), d.value()),
            _ => format!("({} {}, {:.6})", d.kind(), d.at(), d.value()),
        })
        .collect::<Vec<_>>()
        .join(", ")
}

/// The answer with its error bars: the general fit's standard errors, or on
/// the mass path the fit's errors scaled to the data's floor; the fitted
/// chain parameters.
fn print_answer(r: &SceneReport, general: bool) {
    println!("found      {}", fmt_defects(&r.defects, general));
    let bars = if general {
        &r.std_errors
    } else {
        &r.error_bars
    };
    for (d, se) in r.defects.iter().zip(bars) {
        println!(
            "  {:<6} at {:>3}  {:.6} +- {:.2e}",
            d.kind(),
            d.at(),
            d.value(),
            se
        );
    }
    if !general && !bars.is_empty() {
        println!("           (error bars from the data's error floor; approximate)");
    }
    for p in &r.chain_params {
        println!(
            "  chain {:<6} {:.6} +- {:.2e}",
            p.name, p.value, p.std_error
        );
    }
}

/// How far each defect of the answer stands from its rivals.
fn print_identifiability(id: &Identifiability) {
    println!(
        "identifiability (noise level {:.3e}; gap threshold {})",
        id.sigma, id.threshold
    );
    if let (Some(g), Some(s)) = (id.runner_up_gap, id.sigma_indistinguishable) {
        println!(
            "  runner-up chi2 gap {g:.4e}: indistinguishable from the answer at noise {s:.3e} ({:.1}x the data's)",
            if id.sigma > 0.0 { s / id.sigma } else { f64::INFINITY }
        );
    }
    for d in &id.defects {
        println!(
            "  at {:>3}: {:.1} SE from the uniform value; {}{}",
            d.at,
            d.significance,
            match (d.nearest_rival, d.position_gap) {
                (Some(p), Some(g)) => format!("nearest rival position {p} (chi2 gap {g:.3e})"),
                _ => "no listed alternative moves it".to_string(),
            },
            if d.identifiable {
                String::from("  identifiable")
            } else {
                format!("  NOT identifiable: {}", d.reason)
            }
        );
    }
}

/// The scene's report: the answer and its error bars first, then the
/// truth it is scored against, how it was found and how far to trust it.
fn print_text(scene: &FitScene, r: &SceneReport) {
    let general = !r.std_errors.is_empty();
    println!("status     {} - {}", r.status.name(), r.message);
    print_answer(r, general);
    let truth: Vec<springmass::Defect> = scene.chain.defects.clone();
    if !truth.is_empty() {
        println!("truth      {}", fmt_defects(&truth, general));
    }
    println!("# method   {}", r.method);
    println!("# misfit   {} ({} nodes)", r.misfit, r.nodes);
    println!(
        "{}   {:.6e}",
        if general { "chi2    " } else { "residual" },
        r.residual
    );
    println!(
        "{} {:.3e}  ({})",
        if general { "gap thr. " } else { "data floor" },
        r.floor,
        if r.resolved {
            "resolved: the first runner-up is above the floor"
        } else {
            "NOT resolved: the first runner-up is within the data's error"
        }
    );
    if !r.fits_data {
        println!(
            "WARNING    the residual is far above the data floor: the hypothesis does not explain the data (a defect missing from [unknowns], or the search missed the truth)"
        );
    }
    if !r.runners_up.is_empty() {
        println!("runners-up");
        for alt in &r.runners_up {
            println!(
                "  {:<48} r = {:.6e}  gap = {:.3e}",
                fmt_defects(&alt.defects, general),
                alt.chi2,
                alt.gap
            );
        }
    }
    if let Some(id) = &r.identifiability {
        print_identifiability(id);
    }
    let sets = r
        .sets
        .map(|s| format!(", {s} position sets"))
        .unwrap_or_default();
    let beam = match r.exhaustive {
        _ if r.certified => {
            " (not every set ranked: the answer is certified, see the message; --exhaustive ranks them all)"
        }
        Some(false) => " (not every set ranked: see the method)",
        _ => "",
    };
    println!("evaluations {}{sets}{beam}", r.evaluations);
    println!(
        "wall time  {:.3} ms (setup {:.3} ms)",
        r.wall_time_s * 1e3,
        r.setup_time_s * 1e3
    );
    if !r.trace.is_empty() {
        println!("trace (evaluations, best residual)");
        for (e, c) in &r.trace {
            println!("  {e:>8} {c:.6e}");
        }
    }
}
