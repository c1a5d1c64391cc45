//! The parallel runner: every case of a study (or of one shard) on a rayon
//! pool, one JSON line per finished case, resumable.
//!
//! Output folder:
//!
//! | file | what |
//! |---|---|
//! | `study.toml` | the study file as run (a resume must use the same) |
//! | `manifest.json` | study name, content hash, number of cases, shard |
//! | `results.jsonl` | one [`Record`] per finished case (sorted by id at the end) |
//! | `summary.csv`, `report.md`, `*.svg` | written when every case is done ([`super::report`]) |
//! | `cases/<id>-<name>.svg` | pictures of single cases (kinds that draw them), written before their record |
//!
//! **Nothing lost.** Each record is written with one `write` call on a file
//! opened for appending, and the file is `fsync`ed at least once a second and
//! at the end: a killed run leaves complete lines plus at most one partial
//! last line. A new run with the same command reads the complete lines,
//! drops a partial or damaged line (rewriting the file atomically), and runs
//! only the cases that have no record. Failed cases (an error in the case,
//! or a panic) are records too: they are deterministic and are not retried.
//!
//! **Same results, any thread count.** A case's numbers depend only on its
//! scene and its seed (derived from its parameters, [`super::sweep`]); the
//! lines of `results.jsonl` arrive in completion order while running, and
//! are rewritten in id order when the run completes, so all final files are
//! identical for any `--threads` (timings apart, see `study.timings`).

use super::kinds::CaseOutput;
#[cfg(not(feature = "cli"))]
use super::progress::{progress_bar, ProgressBar};
pub use super::records::{
    check_out_folder, load_records, write_records, Counts, Manifest, Record, CASES, MANIFEST,
    RESULTS, STUDY_COPY,
};
use super::shard::Shard;
use super::sweep::Case;
use super::Study;
use crate::error::{Error, Result};
use crate::series::write_atomic;
#[cfg(feature = "cli")]
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use rayon::prelude::*;
use std::collections::BTreeMap;
use std::fs::{File, OpenOptions};
#[cfg_attr(not(feature = "cli"), allow(unused_imports))]
use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::time::{Duration, Instant};

/// Most worker threads of a run (`--threads`).
pub const MAX_THREADS: usize = 1024;

/// Check a thread count: `1 <= n <=` [`MAX_THREADS`].
///
/// # Errors
/// [`Error::InvalidParameter`] naming `threads` and the allowed range.
pub fn check_threads(n: usize) -> Result<()> {
    if n == 0 || n > MAX_THREADS {
        return Err(Error::invalid(
            "threads",
            n,
            format!("1 <= threads <= {MAX_THREADS}"),
        ));
    }
    Ok(())
}

/// Options of a run.
#[derive(Clone, Debug)]
pub struct RunOptions {
    /// Output folder (created).
    pub out: PathBuf,
    /// Worker threads (default: rayon's choice, the number of cores).
    pub threads: Option<usize>,
    /// Run only this slice of the cases.
    pub shard: Option<Shard>,
    /// Show a progress bar on stderr (only drawn when stderr is a terminal).
    pub progress: bool,
    /// Run at most this many cases, then stop (as if interrupted; for tests
    /// and for budgeted runs). Default: all.
    pub max_cases: Option<usize>,
}

impl RunOptions {
    /// Defaults: all cores, no shard, a progress bar, every case.
    pub fn new(out: impl Into<PathBuf>) -> RunOptions {
        RunOptions {
            out: out.into(),
            threads: None,
            shard: None,
            progress: true,
            max_cases: None,
        }
    }
}

/// What a run did.
#[derive(Clone, Debug, PartialEq)]
pub struct RunSummary {
    /// Cases of the whole study.
    pub total: usize,
    /// Cases of this run's slice (all of them without a shard).
    pub selected: usize,
    /// Cases found finished in the folder (resumed).
    pub resumed: usize,
    /// Cases run now.
    pub ran: usize,
    /// Failed cases (status `error`) among all finished ones of the slice.
    pub failed: usize,
    /// Skipped cases (status `skipped`: invalid scenes with
    /// `study.invalid_cases = "skip"`) among all finished ones of the slice;
    /// not counted in `failed`.
    pub skipped: usize,
    /// Every case of the slice is finished.
    pub complete: bool,
    /// The report, when written (complete, unsharded runs).
    pub report: Option<PathBuf>,
}

/// Run one case and write its pictures into `out/cases/` (atomically, before
/// the record that lists them is appended). Never panics: a panic in a kind,
/// or a picture that cannot be written, becomes a failed record.
pub fn execute(study: &Study, case: &Case, out: &Path) -> Record {
    let mut rec = execute_case(study, case);
    let plots = std::mem::take(&mut rec.1);
    let mut rec = rec.0;
    for p in plots {
        let file = format!("{CASES}/{}-{}.svg", case.id, p.name);
        match write_atomic(&out.join(&file), p.svg.as_bytes()) {
            Ok(()) => rec.files.push(file),
            Err(e) => {
                rec.status = "error".into();
                rec.error = Some(e.to_string());
            }
        }
    }
    rec
}

/// Run one case without writing anything: its record and its pictures.
pub fn execute_case(study: &Study, case: &Case) -> (Record, Vec<super::kinds::CasePlot>) {
    let kind = case.kind;
    let skip = study.file.study.invalid_cases == super::config::InvalidCases::Skip;
    let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        if skip {
            kind.validate(&case.scene).map_err(|e| (true, e))?;
        }
        kind.run(&case.scene, case.seed).map_err(|e| (false, e))
    }));
    let (status, error, out) = match result {
        Ok(Err((true, e))) => ("skipped", Some(e.to_string()), CaseOutput::default()),
        Ok(Err((false, e))) => ("error", Some(e.to_string()), CaseOutput::default()),
        Ok(Ok(out)) => ("ok", None, out),
        Err(p) => {
            let msg = p
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| p.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "unknown panic".into());
            (
                "error",
                Some(format!("panic: {msg}")),
                CaseOutput::default(),
            )
        }
    };
    let rec = Record {
        id: case.id.clone(),
        key: case.key.clone(),
        seed: case.seed,
        repeat: case.repeat,
        params: case.params.clone(),
        status: status.into(),
        error,
        metrics: out.metrics,
        timings: if study.file.study.timings {
            out.timings
        } else {
            serde_json::Map::new()
        },
        files: Vec::new(),
        trace: out.trace,
    };
    (rec, out.plots)
}

/// Run a study (or one shard of it) into `opts.out`, resuming what is there.
///
/// # Errors
/// [`Error::InvalidParameter`] for a thread count outside `1..=`
/// [`MAX_THREADS`], an output path that is not a folder or a non-empty
/// folder without a manifest (results this tool did not write: refused, never
/// overwritten), a folder of another study or shard, or a record in it that
/// does not match this study's cases; [`Error::Io`] on the output folder.
///
/// ```no_run
/// use springmass::study::{Study, run::{run, RunOptions}};
/// let study = Study::from_file("configs/studies/scaling.toml")?;
/// let summary = run(&study, &RunOptions::new("out/scaling"))?;
/// println!("report: {:?}", summary.report);
/// # Ok::<(), springmass::Error>(())
/// ```
pub fn run(study: &Study, opts: &RunOptions) -> Result<RunSummary> {
    let out = &opts.out;
    if let Some(n) = opts.threads {
        check_threads(n)?;
    }
    check_out_folder(out)?;
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    let _lock = FolderLock::take(out)?;
    let manifest = Manifest {
        study: study.file.study.name.clone(),
        hash: study.hash.clone(),
        cases: study.cases.len(),
        shard: opts.shard.map(|s| s.to_string()),
    };
    prepare_folder(out, study, &manifest)?;
    let selected: Vec<&Case> = study
        .cases
        .iter()
        .filter(|c| opts.shard.is_none_or(|s| s.contains(c.index)))
        .collect();
    let done = read_records(out, study)?;
    for id in done.keys() {
        if !selected.iter().any(|c| &c.id == id) {
            return Err(Error::invalid(
                out.join(RESULTS).display().to_string(),
                id,
                "a case of this study and shard (the folder holds results of another run; use a fresh --out)",
            ));
        }
    }
    let mut todo: Vec<&Case> = selected
        .iter()
        .copied()
        .filter(|c| !done.contains_key(&c.id))
        .collect();
    if let Some(m) = opts.max_cases {
        todo.truncate(m);
    }
    let resumed = done.len();
    let pb = progress_bar(opts.progress, todo.len() as u64, resumed);
    let ran = execute_all(study, &todo, out, opts.threads, &pb);
    pb.finish_and_clear();
    ran?;
    let records = read_records(out, study)?;
    let complete = selected.iter().all(|c| records.contains_key(&c.id));
    let counts = Counts::of(records.values());
    let mut report = None;
    if complete {
        let sorted: Vec<Record> = records.into_values().collect();
        write_records(out, &sorted)?;
        if opts.shard.is_none() {
            super::report::write(study, &sorted, out)?;
            report = Some(out.join(super::report::REPORT));
        }
    }
    Ok(RunSummary {
        total: study.cases.len(),
        selected: selected.len(),
        resumed,
        ran: todo.len(),
        failed: counts.failed,
        skipped: counts.skipped,
        complete,
        report,
    })
}

/// Run the cases `todo` (on a pool of `threads`, or the current one) and
/// append their records to the results file, one line each as it finishes.
///
/// # Errors
/// The first record that cannot be written, or a pool that cannot be built.
fn execute_all(
    study: &Study,
    todo: &[&Case],
    out: &Path,
    threads: Option<usize>,
    pb: &ProgressBar,
) -> Result<()> {
    let writer = Mutex::new(Appender::open(&out.join(RESULTS))?);
    let failure: Mutex<Option<Error>> = Mutex::new(None);
    let work = || {
        todo.par_iter().for_each(|case| {
            let rec = crate::detect::search::parallel::as_task(|| execute(study, case, out));
            let line = match serde_json::to_string(&rec) {
                Ok(l) => l,
                Err(e) => {
                    failure
                        .lock()
                        .unwrap_or_else(|p| p.into_inner())
                        .get_or_insert(Error::invalid("record", &rec.id, e.to_string()));
                    return;
                }
            };
            let mut w = writer.lock().unwrap_or_else(|p| p.into_inner());
            if let Err(e) = w.append(&line) {
                failure
                    .lock()
                    .unwrap_or_else(|p| p.into_inner())
                    .get_or_insert(e);
            }
            drop(w);
            pb.inc(1);
        })
    };
    match threads {
        Some(n) => rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build()
            .map_err(|e| Error::invalid("threads", n, e.to_string()))?
            .install(work),
        None => work(),
    }
    writer
        .into_inner()
        .unwrap_or_else(|p| p.into_inner())
        .sync()?;
    if let Some(e) = failure.into_inner().unwrap_or_else(|p| p.into_inner()) {
        return Err(e);
    }
    Ok(())
}

/// The lock file of a study folder (defined with the folder's other file
/// names).
pub use super::records::LOCK;

/// Whether process `pid` is alive (Linux: `/proc/PID`; elsewhere every
/// process is taken as alive, so nothing of another run is touched).
fn pid_alive(pid: u32) -> bool {
    if pid == std::process::id() {
        return true;
    }
    if cfg!(target_os = "linux") {
        Path::new("/proc").join(pid.to_string()).exists()
    } else {
        true
    }
}

/// `out/.lock` holding this process's id while a run uses the folder;
/// removed when dropped. A lock of a process that is gone is taken over.
struct FolderLock {
    path: PathBuf,
}

impl FolderLock {
    /// # Errors
    /// [`Error::Io`] naming the folder and the process that holds it.
    fn take(out: &Path) -> Result<FolderLock> {
        let path = out.join(LOCK);
        let me = std::process::id();
        for _ in 0..2 {
            match OpenOptions::new().write(true).create_new(true).open(&path) {
                Ok(mut f) => {
                    f.write_all(format!("{me}\n").as_bytes())
                        .map_err(|e| Error::io(&path, e))?;
                    return Ok(FolderLock { path });
                }
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {
                    let text = std::fs::read_to_string(&path).unwrap_or_default();
                    match text.trim().parse::<u32>() {
                        Ok(pid) if pid_alive(pid) => {
                            return Err(Error::io(
                                out,
                                format!(
                                    "another study run (process {pid}) is using this folder (lock file {}); wait for it to finish or use another --out",
                                    path.display()
                                ),
                            ))
                        }
                        // a run that died: its lock is stale
                        _ => {
                            let _ = std::fs::remove_file(&path);
                        }
                    }
                }
                Err(e) => return Err(Error::io(&path, e)),
            }
        }
        Err(Error::io(&path, "could not take the folder's lock file"))
    }
}

impl Drop for FolderLock {
    fn drop(&mut self) {
        let mine = std::fs::read_to_string(&self.path)
            .is_ok_and(|t| t.trim() == std::process::id().to_string());
        if mine {
            let _ = std::fs::remove_file(&self.path);
        }
    }
}

/// Remove temporary files of atomic writes that an interrupted run left
/// behind (`.<name>.tmp<pid>.<k>` next to our outputs), of processes that
/// are gone only.
fn remove_stale_temporaries(out: &Path) {
    let Ok(entries) = std::fs::read_dir(out) else {
        return;
    };
    for e in entries.flatten() {
        let name = e.file_name().to_string_lossy().to_string();
        let Some(rest) = name.strip_prefix('.') else {
            continue;
        };
        let Some((base, pid)) = rest.rsplit_once(".tmp") else {
            continue;
        };
        let ours = [RESULTS, STUDY_COPY, MANIFEST, "summary.csv", "report.md"].contains(&base)
            || base.ends_with(".svg");
        // `.tmp<pid>` (older writers) or `.tmp<pid>.<k>` (the atomic writer)
        let pid = pid.split_once('.').map_or(pid, |(p, _)| p);
        let dead = pid.parse::<u32>().is_ok_and(|p| !pid_alive(p));
        if ours && dead {
            let _ = std::fs::remove_file(e.path());
        }
    }
}

/// Create or check `study.toml` and `manifest.json` in `out`.
fn prepare_folder(out: &Path, study: &Study, manifest: &Manifest) -> Result<()> {
    remove_stale_temporaries(out);
    remove_stale_temporaries(&out.join(CASES));
    let mpath = out.join(MANIFEST);
    if mpath.exists() {
        let text = std::fs::read_to_string(&mpath).map_err(|e| Error::io(&mpath, e))?;
        let old: Manifest = serde_json::from_str(&text)
            .map_err(|e| Error::parse(mpath.display().to_string(), "", e.to_string()))?;
        if old != *manifest {
            return Err(Error::invalid(
                out.display().to_string(),
                format!(
                    "a folder of study {:?} (hash {}, shard {})",
                    old.study,
                    old.hash,
                    old.shard.as_deref().unwrap_or("none")
                ),
                format!(
                    "a folder of this study {:?} (hash {}, shard {}): the study file changed or another study ran here; use a fresh --out",
                    manifest.study,
                    manifest.hash,
                    manifest.shard.as_deref().unwrap_or("none")
                ),
            ));
        }
        if !out.join(STUDY_COPY).is_file() {
            // a run killed between the manifest and the copy of the study
            write_atomic(&out.join(STUDY_COPY), study.text.as_bytes())?;
        }
    } else {
        // the manifest first: from then on the folder is ours (a run killed
        // before the copy of the study resumes and writes it)
        let text = serde_json::to_string_pretty(manifest).unwrap_or_default() + "\n";
        write_atomic(&mpath, text.as_bytes())?;
        write_atomic(&out.join(STUDY_COPY), study.text.as_bytes())?;
    }
    Ok(())
}

/// The finished records of a folder, by id. Drops a partial or damaged line
/// (rewriting the file atomically) and later duplicates of an id.
///
/// # Errors
/// [`Error::Io`]; [`Error::InvalidParameter`] when a record's key does not
/// match the study's case of that id.
pub fn read_records(out: &Path, study: &Study) -> Result<BTreeMap<String, Record>> {
    let (records, dirty) = load_records(&out.join(RESULTS))?;
    let mut by_id: BTreeMap<String, Record> = BTreeMap::new();
    let mut dup = false;
    for r in records {
        let Some(case) = study.case(&r.id) else {
            return Err(Error::invalid(
                out.join(RESULTS).display().to_string(),
                &r.id,
                "a case id of this study (the folder holds results of another study)",
            ));
        };
        if case.key != r.key {
            return Err(Error::invalid(
                out.join(RESULTS).display().to_string(),
                &r.id,
                "a record whose parameters match this study's case (the study changed; use a fresh --out)",
            ));
        }
        if by_id.contains_key(&r.id) {
            dup = true;
            continue;
        }
        by_id.insert(r.id.clone(), r);
    }
    if dirty || dup {
        let v: Vec<Record> = by_id.values().cloned().collect();
        write_records(out, &v)?;
    }
    Ok(by_id)
}

/// Appends one line per `write` call, `fsync`ing at most once a second.
struct Appender {
    path: PathBuf,
    file: File,
    last_sync: Instant,
}

impl Appender {
    fn open(path: &Path) -> Result<Appender> {
        let file = OpenOptions::new()
            .create(true)
            .append(true)
            .open(path)
            .map_err(|e| Error::io(path, e))?;
        Ok(Appender {
            path: path.to_path_buf(),
            file,
            last_sync: Instant::now(),
        })
    }

    fn append(&mut self, line: &str) -> Result<()> {
        let mut buf = Vec::with_capacity(line.len() + 1);
        buf.extend_from_slice(line.as_bytes());
        buf.push(b'\n');
        self.file
            .write_all(&buf)
            .map_err(|e| Error::io(&self.path, e))?;
        if self.last_sync.elapsed() >= Duration::from_secs(1) {
            self.sync()?;
        }
        Ok(())
    }

    fn sync(&mut self) -> Result<()> {
        self.last_sync = Instant::now();
        self.file.sync_data().map_err(|e| Error::io(&self.path, e))
    }
}

#[cfg(feature = "cli")]
fn progress_bar(show: bool, len: u64, resumed: usize) -> ProgressBar {
    if !show || !std::io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let pb = ProgressBar::with_draw_target(Some(len), ProgressDrawTarget::stderr());
    if let Ok(style) = ProgressStyle::with_template(
        "{bar:32.cyan/blue} {pos}/{len} cases  {per_sec}  elapsed {elapsed}  left {eta}  {msg}",
    ) {
        pb.set_style(style);
    }
    if resumed > 0 {
        pb.set_message(format!("({resumed} resumed)"));
    }
    pb
}

#[cfg(test)]
mod tests {
    use super::*;

    const TEXT: &str = r#"
[study]
name = "runtest"
kind = "forward"
timings = false
[scene]
chain = { n = 8 }
s = { count = 4 }
timing = { min_seconds = 0.0 }
[[sweep]]
path = "random_defects.count"
values = [0, 1, 2]
[[sweep]]
path = "chain.n"
values = [8, 30]
"#;

    fn tmp(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("springmass-run-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        d
    }

    fn files(dir: &Path) -> BTreeMap<String, Vec<u8>> {
        std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().path())
            .map(|p| {
                (
                    p.file_name().unwrap().to_string_lossy().to_string(),
                    std::fs::read(&p).unwrap(),
                )
            })
            .collect()
    }

    #[test]
    fn records_roundtrip_byte_for_byte() {
        // floats must survive parse + print exactly (serde_json float_roundtrip),
        // or a resumed run would rewrite the records of earlier runs differently
        let study = Study::from_text(TEXT, "t").unwrap();
        for case in &study.cases {
            let (rec, _) = execute_case(&study, case);
            let line = serde_json::to_string(&rec).unwrap();
            let back: Record = serde_json::from_str(&line).unwrap();
            assert_eq!(serde_json::to_string(&back).unwrap(), line);
        }
        for x in [
            5.796622836856578e-16,
            0.1 + 0.2,
            1e-300,
            f64::MAX,
            2.0f64.sqrt(),
        ] {
            let t = serde_json::to_string(&x).unwrap();
            assert_eq!(
                serde_json::from_str::<f64>(&t).unwrap().to_bits(),
                x.to_bits()
            );
        }
    }

    /// The id of a process that has exited.
    fn dead_pid() -> u32 {
        let mut c = std::process::Command::new("true").spawn().unwrap();
        let pid = c.id();
        c.wait().unwrap();
        assert!(!pid_alive(pid), "pid {pid} reused");
        pid
    }

    #[cfg(unix)]
    #[test]
    fn a_second_run_on_one_folder_is_refused_naming_the_holder() {
        // issue 32 item 12
        let study = Study::from_text(TEXT, "t").unwrap();
        let d = tmp("lock");
        // a study folder with one case done
        let mut o = RunOptions::new(&d);
        o.progress = false;
        o.max_cases = Some(1);
        run(&study, &o).unwrap();
        o.max_cases = None;
        // a live holder: this test's parent process stands in for another run
        let holder = std::os::unix::process::parent_id();
        std::fs::write(d.join(LOCK), format!("{holder}\n")).unwrap();
        let e = run(&study, &o).unwrap_err().to_string();
        assert!(e.contains(&format!("process {holder}")), "{e}");
        assert!(e.contains(LOCK), "{e}");
        // a temporary of a live process is left alone, a stale one removed
        let live = d.join(format!(".{RESULTS}.tmp{holder}.0"));
        std::fs::write(&live, "x").unwrap();
        let stale = d.join(format!(".{RESULTS}.tmp{}.1", dead_pid()));
        std::fs::write(&stale, "x").unwrap();
        // the holder's lock gone stale: taken over, and released at the end
        std::fs::write(d.join(LOCK), format!("{}\n", dead_pid())).unwrap();
        let s = run(&study, &o).unwrap();
        assert!(s.complete);
        assert!(!d.join(LOCK).exists());
        assert!(live.exists() && !stale.exists());
    }

    #[test]
    fn resume_after_partial_run_and_torn_line_gives_same_files() {
        let study = Study::from_text(TEXT, "t").unwrap();
        let a = tmp("a");
        let mut o = RunOptions::new(&a);
        o.progress = false;
        let s = run(&study, &o).unwrap();
        assert!(s.complete && s.ran == 6 && s.failed == 0);
        let b = tmp("b");
        let mut o = RunOptions::new(&b);
        o.progress = false;
        o.max_cases = Some(2);
        o.threads = Some(2);
        let s = run(&study, &o).unwrap();
        assert!(!s.complete && s.report.is_none());
        // a torn last line, as a kill in the middle of a write would leave
        let mut f = OpenOptions::new()
            .append(true)
            .open(b.join(RESULTS))
            .unwrap();
        f.write_all(b"{\"id\":\"c0005\",\"key\":\"ab").unwrap();
        drop(f);
        // and temporary files of interrupted atomic writes, of a process
        // that is gone (the older name form and the atomic writer's)
        let dead = dead_pid();
        std::fs::write(b.join(format!(".summary.csv.tmp{dead}")), "x").unwrap();
        std::fs::write(b.join(format!(".{RESULTS}.tmp{dead}.3")), "x").unwrap();
        o.max_cases = None;
        o.threads = Some(1);
        let s = run(&study, &o).unwrap();
        assert_eq!((s.resumed, s.ran), (2, 4));
        assert!(s.complete);
        assert_eq!(files(&a), files(&b));
        // a changed study refuses the folder
        let other = Study::from_text(&TEXT.replace("[8, 30]", "[8, 31]"), "t").unwrap();
        let mut o = RunOptions::new(&a);
        o.progress = false;
        assert!(run(&other, &o).is_err());
        let _ = std::fs::remove_dir_all(&a);
        let _ = std::fs::remove_dir_all(&b);
    }
}
