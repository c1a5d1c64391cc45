//! `springmass monitor`: fit every record of a structure in service the way
//! its baseline was fitted (a whole-profile inversion), and test each
//! against the baseline for a change ([`springmass::detect::monitor`]).
//! It reads, fits, writes and plots; the statistics are the library's.

use anyhow::Context;
use clap::Args as ClapArgs;
use rayon::prelude::*;
use springmass::detect::fit::options::FitSpec;
use springmass::detect::fit::profile::{ProfileMode, ProfileOptions};
use springmass::detect::monitor::{change_test, ChangeTest, Snapshot};
use std::path::{Path, PathBuf};

/// Arguments of `springmass monitor`.
#[derive(ClapArgs, Debug)]
#[command(
    after_help = "springmass fit --data day0.csv --n 8 --profile springs --json > base.json\n\
springmass monitor --baseline base.json --n 8 records/ --out trend.csv --plot trend.svg\n\n\
Output-only records (the same flags as fit --excitation ambient):\n\
springmass fit --data day0.csv --n 12 --observe 1,6,12 --excitation ambient --profile springs --json > base.json\n\
springmass monitor --baseline base.json --n 12 --observe 1,6,12 --excitation ambient records/"
)]
pub struct Args {
    /// The records: CSV files, folders (their *.csv) or a pattern with * and
    /// ? in the file name (`'data/day-*.csv'`). Ordered by the `# time: T`
    /// comment line every record carries (numbers by value, else the text,
    /// as ISO 8601 sorts), else by file name (digit runs by value).
    #[arg(required = true, value_name = "RECORDS")]
    pub records: Vec<PathBuf>,
    /// The baseline fit: the JSON of `springmass fit --data FILE --profile
    /// MODE --json` on the reference record (its mode is the records' too).
    /// Repeat it for several reference records: their weighted mean is the
    /// baseline (smaller error bars, fewer false alarms shared by a run).
    #[arg(long, value_name = "FIT.json", required = true)]
    pub baseline: Vec<PathBuf>,
    /// False-alarm probability per record of the change flag.
    #[arg(long, default_value_t = 0.001)]
    pub alarm_rate: f64,
    /// Number of masses of the nominal chain.
    #[arg(long)]
    pub n: Option<usize>,
    /// Uniform damping [default: 0.1].
    #[arg(long, allow_negative_numbers = true)]
    pub d: Option<f64>,
    /// Uniform stiffness [default: 1].
    #[arg(long, allow_negative_numbers = true)]
    pub k: Option<f64>,
    /// Uniform mass [default: 1].
    #[arg(long, allow_negative_numbers = true)]
    pub mass: Option<f64>,
    /// Impulse on mass 1 [default: 1].
    #[arg(long, allow_negative_numbers = true)]
    pub gamma: Option<f64>,
    /// Chain parameters fitted too, as for fit: a subset of d,gamma,k,mass.
    #[arg(long)]
    pub fit: Option<String>,
    /// The nominal chain as a measured profile table (as `fit --baseline`).
    #[arg(long, value_name = "FILE")]
    pub chain_baseline: Option<PathBuf>,
    /// Left end: fixed or free [default: fixed].
    #[arg(long)]
    pub left: Option<String>,
    /// Right end: fixed or free [default: fixed].
    #[arg(long)]
    pub right: Option<String>,
    /// The observed mass [default: 1]; with --excitation ambient the
    /// observed masses, one per value column in order (1,6,12).
    #[arg(long, value_delimiter = ',')]
    pub observe: Vec<usize>,
    /// ambient: output-only records (an unknown broadband force, as `fit
    /// --excitation ambient`), each fitted as an output-only profile; the
    /// baseline is then the JSON of `fit --excitation ambient --profile MODE`.
    #[arg(long)]
    pub excitation: Option<String>,
    /// displacement, velocity or acceleration [default: displacement].
    #[arg(long)]
    pub observe_kind: Option<String>,
    /// The column of each record to fit [default: the first after t].
    #[arg(long)]
    pub column: Option<String>,
    /// Noise standard deviation of the samples: auto or SIGMA [default: auto].
    #[arg(long)]
    pub noise: Option<String>,
    /// Write the table (time, record, common factor, change statistic,
    /// p-value, status, changed elements, each factor and SE) as CSV.
    #[arg(long, value_name = "FILE.csv")]
    pub out: Option<PathBuf>,
    /// Write the same table as JSON lines, one record a line.
    #[arg(long, value_name = "FILE.jsonl")]
    pub jsonl: Option<PathBuf>,
    /// Plot each factor against the record with 2 SE bars, the common
    /// factor and the change statistic, flagged records marked (SVG).
    #[arg(long, value_name = "FILE.svg")]
    pub plot: Option<PathBuf>,
}

/// One record's line of the table.
#[derive(Debug, serde::Serialize)]
struct Row {
    /// Its time stamp (`# time:`), or empty.
    time: String,
    /// Its file.
    record: String,
    /// `ok`, `changed`, or `failed: ...` (the fit or the test failed).
    status: String,
    /// The profile fit's own status.
    fit_status: String,
    /// The factors of the record's fit.
    factors: Vec<f64>,
    /// Their standard errors.
    ses: Vec<f64>,
    /// The change test (none when it failed).
    test: Option<ChangeTest>,
    /// The changed elements' names.
    changed: Vec<String>,
}

pub fn run(a: Args) -> anyhow::Result<()> {
    let records = ordered_records(&a.records)?;
    let (base, mode, base_kind) = read_baselines(&a.baseline)?;
    springmass::error::check_f64(
        "alarm_rate",
        a.alarm_rate,
        a.alarm_rate > 0.0 && a.alarm_rate < 1.0,
        "in (0, 1): the false-alarm probability per record",
    )?;
    let mut spec = fit_spec(&a)?;
    // the records are of the baseline record's sensor (its fit says which)
    match (&spec.observe_kind, base_kind) {
        (None, kind) => spec.observe_kind = kind,
        (Some(given), Some(kind)) if given.trim() != kind => {
            anyhow::bail!(springmass::Error::invalid(
                "observe_kind",
                given,
                format!("{kind}, the baseline record's sensor (its fit's observe_kind)")
            ))
        }
        _ => {}
    }
    spec.build()?; // every option checked before the first fit

    // output-only records: the channels' masses
    let channels = ambient(&a)?.then(|| {
        if a.observe.is_empty() {
            vec![1]
        } else {
            a.observe.clone()
        }
    });
    springmass::io::check_outputs(
        a.out
            .iter()
            .chain(&a.jsonl)
            .chain(&a.plot)
            .map(|p| p.as_path()),
    )?;
    let rows: Vec<Row> = records
        .par_iter()
        .map(|(path, time)| {
            let how = (&spec, mode, channels.as_deref());
            record_row(path, time, how, &base, a.alarm_rate)
        })
        .collect();
    if let Some(out) = &a.out {
        write_csv(out, &base, &rows)?;
    }
    if let Some(out) = &a.jsonl {
        write_jsonl(out, &base, &rows)?;
    }
    if let Some(svg) = &a.plot {
        plot(svg, &base, &rows, a.alarm_rate)?;
    }
    print_summary(&rows, a.alarm_rate);
    // the tables are written; a run with no record tested is a failure
    if let Some(first) = rows.first() {
        if rows.iter().all(|r| r.status.starts_with("failed")) {
            anyhow::bail!("every record failed; the first: {}", first.status);
        }
    }
    Ok(())
}

/// The baseline: the weighted mean of the fits of `paths`, all of one
/// profile mode.
fn read_baselines(paths: &[PathBuf]) -> anyhow::Result<(Snapshot, ProfileMode, Option<String>)> {
    let mut snaps = Vec::new();
    let mut modes = Vec::new();
    let mut kinds = Vec::new();
    for p in paths {
        let text = springmass::io::read_to_string_capped(p)
            .with_context(|| format!("reading {}", p.display()))?;
        snaps.push(
            Snapshot::from_profile_json(&text).with_context(|| format!("in {}", p.display()))?,
        );
        modes.push(baseline_mode(&text).with_context(|| format!("in {}", p.display()))?);
        let v: serde_json::Value = serde_json::from_str(&text)?;
        kinds.push(v["observe_kind"].as_str().map(str::to_string));
    }
    if modes.iter().any(|m| *m != modes[0]) {
        anyhow::bail!(springmass::Error::invalid(
            "baseline",
            "fits of different profile modes",
            "every --baseline fitted with the same --profile"
        ));
    }
    if kinds.iter().any(|k| *k != kinds[0]) {
        anyhow::bail!(springmass::Error::invalid(
            "baseline",
            "fits of records of different sensors",
            "every --baseline fitted on records of one observe_kind"
        ));
    }
    Ok((Snapshot::average(&snaps)?, modes[0], kinds[0].clone()))
}

/// The fit options of every record, from the chain flags.
fn fit_spec(a: &Args) -> anyhow::Result<FitSpec> {
    let n = match (a.n, &a.chain_baseline) {
        (Some(n), _) => n,
        (None, Some(b)) => springmass::chain::Baseline::read_csv(b)?.n(),
        (None, None) => anyhow::bail!(springmass::Error::invalid(
            "n",
            "(none)",
            "--n N, the number of masses (or --chain-baseline FILE)"
        )),
    };
    Ok(FitSpec {
        d: a.d,
        k: a.k,
        mass: a.mass,
        gamma: a.gamma,
        fit: a.fit.clone(),
        left: a.left.clone(),
        right: a.right.clone(),
        observe: match a.observe.as_slice() {
            [] => None,
            [one] => Some(*one),
            more if !ambient(a)? => anyhow::bail!(springmass::Error::invalid(
                "observe",
                format!("{more:?}"),
                "one mass (several sensors with --excitation ambient)"
            )),
            _ => None,
        },
        observe_kind: a.observe_kind.clone(),
        noise: a.noise.clone(),
        baseline: a
            .chain_baseline
            .as_ref()
            .map(|p| springmass::chain::BaselineSpec::Path(p.display().to_string())),
        ..FitSpec::new(n)
    })
}

/// Whether the records are output-only (`--excitation ambient`).
fn ambient(a: &Args) -> anyhow::Result<bool> {
    match a.excitation.as_deref().map(str::trim) {
        None => Ok(false),
        Some("ambient") => Ok(true),
        Some(other) => anyhow::bail!(springmass::Error::invalid(
            "excitation",
            other,
            "ambient (an impulse needs no --excitation)"
        )),
    }
}

/// The profile mode the baseline was fitted with (its JSON's `mode`; an
/// output-only profile's: the kind of its factors).
fn baseline_mode(text: &str) -> anyhow::Result<ProfileMode> {
    let v: serde_json::Value = serde_json::from_str(text)?;
    if v["target"] == "profile" && v["mode"].is_null() {
        let kind = v["factors"][0]["kind"].as_str().unwrap_or("(none)");
        return Ok(ProfileMode::parse(&format!("{kind}s"))?);
    }
    let m = v["mode"].as_str().unwrap_or("(none)");
    Ok(ProfileMode::parse(m)?)
}

/// Fit one record and test it; a failure is the row's status.
fn record_row(
    path: &Path,
    time: &Option<String>,
    how: How<'_>,
    base: &Snapshot,
    alarm_rate: f64,
) -> Row {
    let mut row = Row {
        time: time.clone().unwrap_or_default(),
        record: path.display().to_string(),
        status: String::new(),
        fit_status: String::new(),
        factors: vec![f64::NAN; base.labels.len()],
        ses: vec![f64::NAN; base.labels.len()],
        test: None,
        changed: Vec::new(),
    };
    let snap = match fit_record(path, how) {
        Ok((snap, status)) => {
            row.fit_status = status;
            snap
        }
        Err(e) => {
            row.status = format!("failed: {e:#}");
            return row;
        }
    };
    if snap.labels != base.labels {
        // another chain than the baseline's (its --n, ends or profile)
        let span = |l: &[String]| match (l.first(), l.last()) {
            (Some(a), Some(b)) => format!("{} elements, {a} to {b}", l.len()),
            _ => "no elements".to_string(),
        };
        row.status = format!(
            "failed: the record's profile has {}, the baseline's {}: fit both with the same --n, ends and --profile",
            span(&snap.labels),
            span(&base.labels)
        );
        return row;
    }
    row.factors.clone_from(&snap.factors);
    row.ses = snap.ses();
    match change_test(base, &snap, alarm_rate) {
        Ok(t) => {
            row.status = if t.flagged { "changed" } else { "ok" }.into();
            row.changed = t.changed.iter().map(|&i| base.labels[i].clone()).collect();
            row.test = Some(t);
        }
        Err(e) => row.status = format!("failed: {e}"),
    }
    row
}

/// How every record is fitted: the chain and options, the profile mode,
/// and for output-only records the channels' masses.
type How<'a> = (&'a FitSpec, ProfileMode, Option<&'a [usize]>);

/// The profile fit of one record, as a snapshot, and the fit's status.
fn fit_record(path: &Path, (spec, mode, channels): How<'_>) -> anyhow::Result<(Snapshot, String)> {
    use springmass::detect::data::observations::{Observations, Series};
    use springmass::series::TimeSeries;
    let (model, opts) = spec.build()?;
    if let Some(observe) = channels {
        use springmass::detect::data::ambient::AmbientRecord;
        use springmass::detect::fit::ambient::{fit_ambient, AmbientOptions, AmbientTarget};
        let kind = spec
            .observe_kind
            .as_deref()
            .unwrap_or("displacement")
            .parse()?;
        let rec = AmbientRecord::read_csv(path, observe.to_vec(), kind)?;
        let opts = AmbientOptions {
            target: AmbientTarget::Profile,
            kinds: mode,
            fit_d: spec.d.is_none() || spec.fit.as_deref().is_some_and(|f| f.contains('d')),
            ..AmbientOptions::default()
        };
        let r = fit_ambient(model.chain(), &rec, &opts)?;
        return Ok((Snapshot::from_ambient(&r)?, r.status.clone()));
    }
    let sensor = spec.measurement(None)?;
    let table = TimeSeries::read_csv(path)?;
    let fitted = table.names().first().cloned().unwrap_or_default();
    let (table, _notes) = springmass::units::record_in_si(&table, &fitted, sensor.sensor().kind)?;
    let series = Series::from_table(&table, None, opts.noise.known())?;
    let obs = Observations::Series(series.with_measurement(sensor)?);
    let mut po = ProfileOptions::new(mode);
    po.noise = opts.noise;
    let r = springmass::detect::fit::fit_profile(&obs, &model, &po)?;
    Ok((Snapshot::from_profile(&r)?, r.status.name().to_string()))
}

/// The records named by `args` (files, folders, patterns), each with its
/// time stamp, in time order (see [`Args::records`]).
fn ordered_records(args: &[PathBuf]) -> anyhow::Result<Vec<(PathBuf, Option<String>)>> {
    let mut files = Vec::new();
    for a in args {
        files.extend(expand(a)?);
    }
    if files.is_empty() {
        anyhow::bail!(springmass::Error::invalid(
            "records",
            "(none)",
            "at least one CSV record"
        ));
    }
    let mut recs: Vec<(PathBuf, Option<String>)> = files
        .into_iter()
        .map(|p| {
            let t = time_stamp(&p)?;
            Ok((p, t))
        })
        .collect::<anyhow::Result<_>>()?;
    if recs.iter().all(|(_, t)| t.is_some()) {
        let nums: Option<Vec<f64>> = recs
            .iter()
            .map(|(_, t)| t.as_deref().and_then(|s| s.parse().ok()))
            .collect();
        match nums {
            Some(v) => {
                let mut idx: Vec<usize> = (0..recs.len()).collect();
                idx.sort_by(|&a, &b| v[a].total_cmp(&v[b]));
                recs = idx.into_iter().map(|i| recs[i].clone()).collect();
            }
            None => recs.sort_by(|a, b| a.1.cmp(&b.1)),
        }
    } else {
        recs.sort_by_key(|a| natural_key(&a.0));
    }
    Ok(recs)
}

/// A file, the *.csv of a folder (sorted), or the files a pattern matches.
fn expand(a: &Path) -> anyhow::Result<Vec<PathBuf>> {
    if a.is_dir() {
        let mut v: Vec<PathBuf> = std::fs::read_dir(a)?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.is_file() && p.extension().is_some_and(|x| x == "csv"))
            .collect();
        v.sort();
        return Ok(v);
    }
    let name = a.file_name().map(|s| s.to_string_lossy().to_string());
    match name {
        Some(pat) if !a.exists() && (pat.contains('*') || pat.contains('?')) => {
            let dir = a.parent().filter(|d| !d.as_os_str().is_empty());
            let dir = dir.unwrap_or(Path::new("."));
            let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
                .with_context(|| format!("the folder of {}", a.display()))?
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| {
                    p.is_file()
                        && p.file_name()
                            .is_some_and(|f| wildcard(pat.as_bytes(), f.as_encoded_bytes()))
                })
                .collect();
            if v.is_empty() {
                anyhow::bail!("no file matches {}", a.display());
            }
            v.sort();
            Ok(v)
        }
        // a FIFO or device would block the time-stamp read: files only
        _ if a.is_file() => Ok(vec![a.to_path_buf()]),
        _ => anyhow::bail!(springmass::Error::invalid(
            "records",
            a.display(),
            "existing CSV files, folders or a pattern with * or ?"
        )),
    }
}

/// `*` (any run) and `?` (one byte) matching of a whole name.
fn wildcard(pat: &[u8], s: &[u8]) -> bool {
    match (pat.first(), s.first()) {
        (None, None) => true,
        (Some(b'*'), _) => wildcard(&pat[1..], s) || (!s.is_empty() && wildcard(pat, &s[1..])),
        (Some(b'?'), Some(_)) => wildcard(&pat[1..], &s[1..]),
        (Some(p), Some(c)) if p == c => wildcard(&pat[1..], &s[1..]),
        _ => false,
    }
}

/// A file name split into text and numbers, so that `r2` sorts before `r10`.
fn natural_key(p: &Path) -> Vec<(String, u128)> {
    let name = p.to_string_lossy();
    let mut key = Vec::new();
    let mut text = String::new();
    let mut num: Option<u128> = None;
    for c in name.chars() {
        match (c.to_digit(10), num) {
            (Some(d), Some(n)) => num = Some(n.saturating_mul(10).saturating_add(d as u128)),
            (Some(d), None) => num = Some(d as u128),
            (None, Some(n)) => {
                key.push((std::mem::take(&mut text), n));
                num = None;
                text.push(c);
            }
            (None, None) => text.push(c),
        }
    }
    key.push((text, num.unwrap_or(0)));
    key
}

/// The `# time: T` comment among the leading comment lines of a record.
fn time_stamp(p: &Path) -> anyhow::Result<Option<String>> {
    use std::io::BufRead;
    let f = std::fs::File::open(p).with_context(|| format!("opening {}", p.display()))?;
    for line in std::io::BufReader::new(f).lines().take(64) {
        let line = line.with_context(|| format!("reading {}", p.display()))?;
        let line = line.trim_start_matches('\u{feff}').trim();
        let Some(c) = line.strip_prefix('#') else {
            break;
        };
        if let Some(t) = c.trim().strip_prefix("time:") {
            return Ok(Some(t.trim().to_string()));
        }
    }
    Ok(None)
}

/// A number for the table: empty when not finite.
fn num(x: f64) -> String {
    if x.is_finite() {
        format!("{x:.8e}")
    } else {
        String::new()
    }
}

/// Column-safe element names (`spring 3` -> `spring3`).
fn column_names(base: &Snapshot) -> Vec<String> {
    base.labels.iter().map(|l| l.replace(' ', "")).collect()
}

fn write_csv(out: &Path, base: &Snapshot, rows: &[Row]) -> anyhow::Result<()> {
    let mut w = csv::Writer::from_writer(Vec::new());
    let names = column_names(base);
    let mut head: Vec<String> = [
        "time",
        "record",
        "status",
        "changed",
        "common",
        "common_se",
        "chi2",
        "dof",
        "p_value",
        "fit_status",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    for n in &names {
        head.push(format!("f_{n}"));
        head.push(format!("se_{n}"));
    }
    w.write_record(&head)?;
    for r in rows {
        let t = r.test.as_ref();
        let mut line = vec![
            r.time.clone(),
            r.record.clone(),
            r.status.clone(),
            r.changed.join(";"),
            num(t.map_or(f64::NAN, |t| t.common)),
            num(t.map_or(f64::NAN, |t| t.common_se)),
            num(t.map_or(f64::NAN, |t| t.chi2)),
            t.map_or(String::new(), |t| t.dof.to_string()),
            num(t.map_or(f64::NAN, |t| t.p_value)),
            r.fit_status.clone(),
        ];
        for (f, s) in r.factors.iter().zip(&r.ses) {
            line.push(num(*f));
            line.push(num(*s));
        }
        w.write_record(&line)?;
    }
    let bytes = w.into_inner().map_err(|e| anyhow::anyhow!("{e}"))?;
    springmass::io::write_atomic(out, &bytes).with_context(|| format!("writing {}", out.display()))
}

fn write_jsonl(out: &Path, base: &Snapshot, rows: &[Row]) -> anyhow::Result<()> {
    let mut s = String::new();
    for r in rows {
        let mut v = serde_json::to_value(r)?;
        v["elements"] = serde_json::to_value(&base.labels)?;
        s.push_str(&serde_json::to_string(&v)?);
        s.push('\n');
    }
    springmass::io::write_atomic(out, s.as_bytes())
        .with_context(|| format!("writing {}", out.display()))
}

/// Small multiples against the record number: every factor with 2 SE
/// bars, the common factor, and -log10 p of the change statistic with the
/// alarm line; flagged records marked in every panel.
fn plot(svg: &Path, base: &Snapshot, rows: &[Row], alarm_rate: f64) -> anyhow::Result<()> {
    use springmass::plot::{Line, LinePlot};
    let x = |i: usize| (i + 1) as f64;
    let flagged: Vec<usize> = (0..rows.len())
        .filter(|&i| rows[i].status == "changed")
        .collect();
    let mut p = LinePlot::new(
        format!(
            "monitoring {} records: factors (2 SE), common factor, change test",
            rows.len()
        ),
        "record",
        "",
    )
    .own_y(true)
    .integer_x(true);
    let panel = |p: LinePlot, name: &str, pts: Vec<(f64, f64)>, bars: Vec<(f64, f64)>| {
        let marks = flagged.iter().map(|&i| pts[i]).collect();
        p.line(Line::new("fit", pts).markers().errors(bars).panel(name))
            .line(Line::new("flagged", marks).markers().panel(name))
    };
    for (e, label) in base.labels.iter().enumerate() {
        let pts = rows
            .iter()
            .enumerate()
            .map(|(i, r)| (x(i), r.factors[e]))
            .collect();
        let bars = rows
            .iter()
            .map(|r| (r.factors[e] - 2.0 * r.ses[e], r.factors[e] + 2.0 * r.ses[e]))
            .collect();
        p = panel(p, label, pts, bars);
    }
    let test = |f: &dyn Fn(&ChangeTest) -> f64| -> Vec<f64> {
        rows.iter()
            .map(|r| r.test.as_ref().map_or(f64::NAN, f))
            .collect()
    };
    let (c, cse) = (test(&|t| t.common), test(&|t| t.common_se));
    let pts = c.iter().enumerate().map(|(i, v)| (x(i), *v)).collect();
    let bars = c
        .iter()
        .zip(&cse)
        .map(|(v, s)| (v - 2.0 * s, v + 2.0 * s))
        .collect();
    p = panel(p, "common factor", pts, bars);
    let lp = test(&|t| -t.p_value.max(1e-300).log10());
    let pts: Vec<(f64, f64)> = lp
        .iter()
        .enumerate()
        .map(|(i, v)| (x(i), v.min(30.0)))
        .collect();
    p = panel(p, "-log10 p (change)", pts, Vec::new());
    let alarm = vec![
        (1.0, -alarm_rate.log10()),
        (x(rows.len() - 1), -alarm_rate.log10()),
    ];
    p = p.line(
        Line::new("alarm rate", alarm)
            .dashed()
            .panel("-log10 p (change)"),
    );
    p.write_svg(svg)
        .with_context(|| format!("writing {}", svg.display()))
}

fn print_summary(rows: &[Row], alarm_rate: f64) {
    let flagged: Vec<&Row> = rows.iter().filter(|r| r.status == "changed").collect();
    let failed = rows
        .iter()
        .filter(|r| r.status.starts_with("failed"))
        .count();
    println!(
        "{} records, {} flagged at a false-alarm rate of {alarm_rate} per record, {failed} failed",
        rows.len(),
        flagged.len()
    );
    if let Some(first) = flagged.first() {
        println!(
            "first flagged: {} {} (changed: {})",
            first.time,
            first.record,
            first.changed.join(", ")
        );
    }
    // a change is flagged from the record's test; which elements changed
    // comes from a profile that may not explain the record
    let unexplained = flagged
        .iter()
        .filter(|r| r.fit_status == "model-mismatch")
        .count();
    if unexplained > 0 {
        println!(
            "{unexplained} of the {} flagged records are not explained by the profile (fit_status model-mismatch): the change is real, but the elements named changed are not reliable (a change the profile cannot express: damping, a mass, a support)",
            flagged.len()
        );
    }
    // a record the profile cannot explain passes the change test only in
    // what the profile expresses
    let quiet: Vec<&Row> = rows
        .iter()
        .filter(|r| r.status != "changed" && r.fit_status == "model-mismatch")
        .collect();
    if let Some(first) = quiet.first() {
        println!(
            "{} of the {} records not flagged are not explained by the profile either (fit_status model-mismatch; first: {} {}): no change is seen in the elements the profile fits, but something it cannot express may have changed (damping, a mass, a support, the sensor)",
            quiet.len(),
            rows.len() - flagged.len(),
            first.time,
            first.record
        );
    }
    for r in rows
        .iter()
        .filter(|r| r.status.starts_with("failed"))
        .take(5)
    {
        println!("  {}: {}", r.record, r.status);
    }
}
