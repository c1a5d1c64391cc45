//! Safe file input and output, and resource limits shared by every command.
//!
//! * [`write_atomic`]: every writer (CSV, SVG, JSON, text) goes through it. It
//!   writes a temporary file in the target's folder and renames it over the
//!   target, so a reader never sees half a file. It writes only to a regular
//!   file or a new path: a device (`/dev/null`, `/dev/full`), a FIFO, a socket
//!   or a directory is refused with [`Error::UnsafeOutput`] naming the path. A
//!   symbolic link is followed to its final target and the target is replaced
//!   atomically; the link itself is never replaced.
//! * [`read_capped`] / [`read_to_string_capped`]: read an input file with a
//!   size cap ([`max_input_bytes`], default 256 MiB, environment variable
//!   `SPRINGMASS_MAX_INPUT`), so that `/dev/urandom` or a runaway pipe cannot
//!   be read forever.
//! * [`memory_budget`] / [`check_alloc`]: refuse a job whose estimated
//!   allocation exceeds the memory budget (default 4 GiB, environment variable
//!   `SPRINGMASS_MEMORY_BUDGET`, for example `16G` or `512M`) before any work
//!   starts.
//! * [`check_threads`], [`check_magnitude`]: thread counts and numeric ranges
//!   that would hang.
//!
//! ```
//! use springmass::io::{read_to_string_capped, write_atomic};
//! let dir = std::env::temp_dir().join(format!("springmass-io-doc-{}", std::process::id()));
//! let path = dir.join("hello.txt");
//! write_atomic(&path, b"hello\n")?;
//! assert_eq!(read_to_string_capped(&path)?, "hello\n");
//! // a directory is not a file to write
//! assert!(write_atomic(&dir, b"x").is_err());
//! # std::fs::remove_dir_all(&dir).ok();
//! # Ok::<(), springmass::Error>(())
//! ```

use crate::error::{Error, Result};
use std::fs::{self, OpenOptions};
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// Default memory budget: 4 GiB.
pub const DEFAULT_MEMORY_BUDGET: u64 = 4 << 30;
/// Environment variable that overrides the memory budget (`16G`, `512M`, bytes).
pub const MEMORY_BUDGET_ENV: &str = "SPRINGMASS_MEMORY_BUDGET";
/// Default cap on the size of an input file: 256 MiB.
pub const DEFAULT_MAX_INPUT: u64 = 256 << 20;
/// Environment variable that overrides the input cap (`1G`, `64M`, bytes).
pub const MAX_INPUT_ENV: &str = "SPRINGMASS_MAX_INPUT";
/// Largest accepted thread count.
pub const MAX_THREADS: usize = 1024;
/// Largest magnitude accepted for a range end point that the code steps through
/// (mass ranges, delays); its reciprocal is the smallest non-zero one.
pub const MAX_MAGNITUDE: f64 = 1e300;

/// What kind of file system object sits at a path (for error messages).
fn kind_of(meta: &fs::Metadata) -> &'static str {
    let ft = meta.file_type();
    if ft.is_dir() {
        return "a directory";
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if ft.is_fifo() {
            return "a FIFO (named pipe)";
        }
        if ft.is_socket() {
            return "a socket";
        }
        if ft.is_char_device() {
            return "a character device";
        }
        if ft.is_block_device() {
            return "a block device";
        }
    }
    if ft.is_file() {
        "a regular file"
    } else {
        "not a regular file"
    }
}

fn unsafe_output(path: &Path, reason: impl Into<String>) -> Error {
    Error::UnsafeOutput {
        path: path.display().to_string(),
        reason: reason.into(),
    }
}

/// Resolve the file that a write to `path` would replace: follow symbolic
/// links (also dangling ones, to the path they name) and check that the final
/// target is a regular file or does not exist yet.
///
/// Call it before a long computation to refuse a bad `--out` early;
/// [`write_atomic`] calls it again.
///
/// # Errors
/// [`Error::UnsafeOutput`] naming the path for a directory, a device, a FIFO,
/// a socket, a symlink loop (more than 40 links) or an empty path;
/// [`Error::Io`] if the path cannot be inspected.
pub fn resolve_output(path: &Path) -> Result<PathBuf> {
    if path.as_os_str().is_empty() {
        return Err(unsafe_output(path, "empty path"));
    }
    let mut p = path.to_path_buf();
    for _ in 0..40 {
        match fs::symlink_metadata(&p) {
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                if p.file_name().is_none() {
                    return Err(unsafe_output(path, "no file name (ends in `..` or `/`)"));
                }
                return Ok(p);
            }
            Err(e) => return Err(Error::io(&p, e)),
            Ok(meta) if meta.file_type().is_symlink() => {
                let target = fs::read_link(&p).map_err(|e| Error::io(&p, e))?;
                p = match p.parent() {
                    Some(dir) if target.is_relative() => dir.join(target),
                    _ => target,
                };
            }
            Ok(meta) if meta.file_type().is_file() => return Ok(p),
            Ok(meta) => {
                let what = if p == path {
                    format!(
                        "is {}; only a regular file or a new path can be written",
                        kind_of(&meta)
                    )
                } else {
                    format!(
                        "is a symbolic link to {} which is {}; only a regular file or a new path can be written",
                        p.display(),
                        kind_of(&meta)
                    )
                };
                return Err(unsafe_output(path, what));
            }
        }
    }
    Err(unsafe_output(path, "too many levels of symbolic links"))
}

/// Check every output path of a command before it starts working (see
/// [`resolve_output`]).
///
/// # Errors
/// The first [`resolve_output`] error.
pub fn check_outputs<'a>(paths: impl IntoIterator<Item = &'a Path>) -> Result<()> {
    for p in paths {
        resolve_output(p)?;
    }
    Ok(())
}

/// Check an output file *prefix* (a command adds `.csv`, `.svg`): it must
/// end in a file name (not `/`, `.` or `..`) and must not itself be a folder,
/// device or other special file (`--out /dev/null` would write
/// `/dev/null.csv`; `--out DIR/` would write `DIR.csv` beside the folder).
///
/// # Errors
/// [`Error::UnsafeOutput`] naming the prefix.
pub fn check_prefix(prefix: &Path) -> Result<()> {
    let text = prefix.as_os_str().to_string_lossy();
    let no_name = text.is_empty()
        || text.ends_with('/')
        || text.ends_with(std::path::MAIN_SEPARATOR)
        || !matches!(
            prefix.components().next_back(),
            Some(std::path::Component::Normal(_))
        );
    if no_name {
        return Err(unsafe_output(
            prefix,
            "is not a file name prefix: give one such as out/surface (the command adds .csv and .svg)",
        ));
    }
    if let Ok(meta) = fs::metadata(prefix) {
        if !meta.is_file() {
            return Err(unsafe_output(
                prefix,
                format!(
                    "is {}; --out is a file name prefix to which .csv and .svg are added, e.g. out/surface",
                    kind_of(&meta)
                ),
            ));
        }
    }
    Ok(())
}

/// Check an output folder: not empty, not the file system root, and either
/// new or an existing folder.
///
/// # Errors
/// [`Error::UnsafeOutput`] naming the folder.
pub fn check_output_dir(dir: &Path) -> Result<()> {
    if dir.as_os_str().is_empty() {
        return Err(unsafe_output(dir, "empty path"));
    }
    let resolved = fs::canonicalize(dir).unwrap_or_else(|_| dir.to_path_buf());
    if resolved.parent().is_none() {
        return Err(unsafe_output(
            dir,
            "is the root of the file system; give a folder of its own, e.g. out/run1",
        ));
    }
    if let Ok(meta) = fs::metadata(dir) {
        if !meta.is_dir() {
            return Err(unsafe_output(
                dir,
                format!("exists and is {}, not a folder", kind_of(&meta)),
            ));
        }
    }
    Ok(())
}

static TMP_COUNTER: AtomicU64 = AtomicU64::new(0);

/// Write `bytes` to `path` atomically: a new temporary file in the target's
/// folder (created exclusively, so a planted link is never followed), write,
/// `fsync`, rename over the target. Creates missing parent folders. The target
/// must be a regular file or a new path; a symbolic link is followed and its
/// final target replaced (the link stays). An existing target keeps its
/// permissions.
///
/// # Errors
/// [`Error::UnsafeOutput`] for a directory, device, FIFO, socket or symlink
/// loop at `path` (naming it); [`Error::Io`] naming the file for any failed
/// system call (the temporary file is removed then).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    let target = resolve_output(path)?;
    let dir = target
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .map(Path::to_path_buf);
    if let Some(dir) = &dir {
        fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    }
    let file_name = target
        .file_name()
        .map(|f| f.to_string_lossy().to_string())
        .unwrap_or_default();
    let existing = fs::metadata(&target).ok();
    let (tmp, mut f) = loop {
        let k = TMP_COUNTER.fetch_add(1, Ordering::Relaxed);
        let tmp = target.with_file_name(format!(".{file_name}.tmp{}.{k}", std::process::id()));
        match OpenOptions::new().write(true).create_new(true).open(&tmp) {
            Ok(f) => break (tmp, f),
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists && k < 1_000_000 => continue,
            Err(e) => return Err(Error::io(&tmp, e)),
        }
    };
    let result = (|| {
        f.write_all(bytes).map_err(|e| Error::io(&target, e))?;
        if let Some(meta) = &existing {
            f.set_permissions(meta.permissions())
                .map_err(|e| Error::io(&target, e))?;
        }
        f.sync_all().map_err(|e| Error::io(&target, e))?;
        drop(f);
        // re-check: the target must not have become a special file meanwhile
        resolve_output(&target)?;
        fs::rename(&tmp, &target).map_err(|e| Error::io(&target, e))
    })();
    if result.is_err() {
        let _ = fs::remove_file(&tmp);
    }
    result
}

/// Parse a byte size: a plain number of bytes or a number with a binary
/// suffix `K`, `M`, `G`, `T` (optionally followed by `iB` or `B`; `2G` = 2 GiB).
///
/// # Errors
/// [`Error::Parse`] for anything else, or a size that does not fit in `u64`.
pub fn parse_size(text: &str) -> Result<u64> {
    let t = text.trim();
    let upper = t.to_ascii_uppercase();
    let stripped = upper
        .strip_suffix("IB")
        .or_else(|| upper.strip_suffix('B'))
        .unwrap_or(&upper);
    let (num, mult) = match stripped.chars().last() {
        Some('K') => (&stripped[..stripped.len() - 1], 1u64 << 10),
        Some('M') => (&stripped[..stripped.len() - 1], 1 << 20),
        Some('G') => (&stripped[..stripped.len() - 1], 1 << 30),
        Some('T') => (&stripped[..stripped.len() - 1], 1 << 40),
        _ => (stripped, 1),
    };
    let v: f64 = num.trim().parse().map_err(|_| {
        Error::parse(
            "size",
            t,
            "expected bytes or a number with K, M, G or T (e.g. 4G)",
        )
    })?;
    let bytes = v * mult as f64;
    if !(bytes.is_finite() && bytes >= 1.0 && bytes < u64::MAX as f64) {
        return Err(Error::parse(
            "size",
            t,
            "a size of at least 1 byte, below 16 EiB",
        ));
    }
    Ok(bytes as u64)
}

fn env_size(var: &str, default: u64) -> Result<u64> {
    match std::env::var(var) {
        Ok(v) => parse_size(&v)
            .map_err(|e| Error::invalid(var, v, format!("a size such as 4G or 512M ({e})"))),
        Err(_) => Ok(default),
    }
}

/// The memory budget in bytes: `SPRINGMASS_MEMORY_BUDGET` if set, else 4 GiB.
///
/// # Errors
/// [`Error::InvalidParameter`] if the variable is set but not a size.
pub fn memory_budget() -> Result<u64> {
    env_size(MEMORY_BUDGET_ENV, DEFAULT_MEMORY_BUDGET)
}

/// The input size cap in bytes: `SPRINGMASS_MAX_INPUT` if set, else 256 MiB.
///
/// # Errors
/// [`Error::InvalidParameter`] if the variable is set but not a size.
pub fn max_input_bytes() -> Result<u64> {
    env_size(MAX_INPUT_ENV, DEFAULT_MAX_INPUT)
}

fn human(bytes: f64) -> String {
    const UNITS: [&str; 6] = ["B", "KiB", "MiB", "GiB", "TiB", "PiB"];
    let mut v = bytes;
    let mut u = 0;
    while v >= 1024.0 && u + 1 < UNITS.len() {
        v /= 1024.0;
        u += 1;
    }
    if u + 1 == UNITS.len() && v >= 1024.0 {
        return format!("{bytes:.3e} B");
    }
    format!("{v:.1} {}", UNITS[u])
}

/// Refuse a job whose estimated allocation `bytes` (a float so that products
/// cannot overflow) exceeds [`memory_budget`]. `what` names the job and the
/// parameters that drive its size, for example `simulate (n = 1e9, 4001 samples)`.
///
/// ```
/// use springmass::io::check_alloc;
/// assert!(check_alloc("small", 1e6).is_ok());
/// assert!(check_alloc("huge", 1e30).is_err());
/// ```
///
/// # Errors
/// [`Error::ResourceLimit`] with the estimate and the budget; the budget's
/// own error if the environment variable is malformed.
pub fn check_alloc(what: &str, bytes: f64) -> Result<()> {
    let budget = memory_budget()?;
    if bytes.is_nan() || bytes > budget as f64 {
        return Err(Error::ResourceLimit {
            what: what.to_string(),
            need: human(bytes),
            budget: format!(
                "{} (set {MEMORY_BUDGET_ENV} to change it)",
                human(budget as f64)
            ),
        });
    }
    Ok(())
}

/// Working memory of a defect search on an `n`-mass chain, per mass: the
/// greedy search keeps `O(n Q)` values for `Q` Laplace nodes (about 64 nodes
/// of 8 bytes).
pub const FIT_BYTES_PER_MASS: f64 = 512.0;
/// Working memory of a whole-profile inversion per squared unknown: dense
/// Jacobians and normal matrices of about 16 `n x n` f64 blocks (the
/// 128 TB that `n = 10^6` asked for).
pub const PROFILE_BYTES_PER_MASS_SQUARED: f64 = 128.0;

/// Refuse a fit of an `n`-mass chain whose working memory would exceed the
/// budget ([`check_alloc`]), before any work: `profile` for the
/// whole-profile inversion (quadratic in `n`), else the defect search
/// (linear in `n`). The one check the CLI and Python share.
///
/// ```
/// use springmass::io::check_fit_memory;
/// assert!(check_fit_memory(1000, false).is_ok());
/// assert!(check_fit_memory(1_000_000_000, false).is_err());
/// assert!(check_fit_memory(1_000_000, true).is_err());
/// ```
///
/// # Errors
/// [`Error::ResourceLimit`] naming `n` and the budget.
pub fn check_fit_memory(n: usize, profile: bool) -> Result<()> {
    let m = n as f64;
    if profile {
        check_alloc(
            &format!("profile fit (n = {n}: dense n x n matrices)"),
            PROFILE_BYTES_PER_MASS_SQUARED * m * m,
        )
    } else {
        check_alloc(&format!("fit (n = {n})"), FIT_BYTES_PER_MASS * m)
    }
}

/// Check a thread count: `1..=MAX_THREADS` (1024).
///
/// # Errors
/// [`Error::InvalidParameter`] naming `field`.
pub fn check_threads(field: &str, threads: usize) -> Result<usize> {
    if (1..=MAX_THREADS).contains(&threads) {
        Ok(threads)
    } else {
        Err(Error::invalid(field, threads, format!("1..={MAX_THREADS}")))
    }
}

/// Check that a value is zero or has a magnitude within
/// `[1/MAX_MAGNITUDE, MAX_MAGNITUDE]` (1e-300..=1e300): values beyond make
/// grids, logarithms and step counts degenerate (subnormal masses, infinite
/// ratios).
///
/// # Errors
/// [`Error::InvalidParameter`] naming `field`.
pub fn check_magnitude(field: &str, v: f64) -> Result<f64> {
    let a = v.abs();
    if v.is_finite() && (a == 0.0 || (1.0 / MAX_MAGNITUDE..=MAX_MAGNITUDE).contains(&a)) {
        Ok(v)
    } else {
        Err(Error::invalid(
            field,
            v,
            "0 or a magnitude within 1e-300..=1e300",
        ))
    }
}

/// Read a whole input file, refusing more than [`max_input_bytes`] bytes
/// (a device such as `/dev/urandom` stops at the cap instead of being read
/// forever) and refusing a directory.
///
/// # Errors
/// [`Error::Io`] naming the file (including "larger than the cap").
pub fn read_capped(path: &Path) -> Result<Vec<u8>> {
    let cap = max_input_bytes()?;
    if let Ok(meta) = fs::metadata(path) {
        if meta.is_dir() {
            return Err(Error::io(path, "is a directory, expected a file"));
        }
        if blocks_on_open(&meta) {
            // a FIFO's open() waits for a writer forever; a socket cannot be read
            return Err(Error::io(
                path,
                format!("is {}, expected a regular file", kind_of(&meta)),
            ));
        }
        if meta.is_file() && meta.len() > cap {
            return Err(too_big(path, cap));
        }
    }
    let f = fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let mut buf = Vec::new();
    f.take(cap + 1)
        .read_to_end(&mut buf)
        .map_err(|e| Error::io(path, e))?;
    if buf.len() as u64 > cap {
        return Err(too_big(path, cap));
    }
    Ok(buf)
}

/// A FIFO, socket or block device: input that blocks or is not a data file
/// (character devices such as `/dev/urandom` are read up to the input cap).
fn blocks_on_open(meta: &fs::Metadata) -> bool {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        let ft = meta.file_type();
        ft.is_fifo() || ft.is_socket() || ft.is_block_device()
    }
    #[cfg(not(unix))]
    {
        let _ = meta;
        false
    }
}

fn too_big(path: &Path, cap: u64) -> Error {
    Error::io(
        path,
        format!(
            "larger than the input cap of {} (set {MAX_INPUT_ENV} to change it)",
            human(cap as f64)
        ),
    )
}

/// [`read_capped`] as UTF-8 text.
///
/// Read a text file (as [`read_to_string_capped`]) and parse it with
/// `parse`, every [`Error::Parse`] prefixed with the file's path.
///
/// # Errors
/// As [`read_to_string_capped`] and `parse`.
pub fn parse_file<T>(path: &Path, parse: impl FnOnce(&str) -> Result<T>) -> Result<T> {
    let text = read_to_string_capped(path)?;
    parse(&text).map_err(|e| match e {
        Error::Parse {
            what,
            input,
            reason,
        } => Error::Parse {
            what: format!("{}: {what}", path.display()),
            input,
            reason,
        },
        other => other,
    })
}

/// # Errors
/// As [`read_capped`]; [`Error::Parse`] naming the file if it is not UTF-8.
pub fn read_to_string_capped(path: &Path) -> Result<String> {
    let bytes = read_capped(path)?;
    String::from_utf8(bytes).map_err(|e| {
        Error::parse(
            path.display().to_string(),
            "",
            format!(
                "not UTF-8 text (invalid byte at offset {})",
                e.utf8_error().valid_up_to()
            ),
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tmpdir(tag: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("springmass-io-{tag}-{}", std::process::id()));
        let _ = fs::remove_dir_all(&d);
        fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn writes_new_and_replaces_regular() {
        let d = tmpdir("reg");
        let p = d.join("sub/a.csv");
        write_atomic(&p, b"one").unwrap();
        write_atomic(&p, b"two").unwrap();
        assert_eq!(fs::read(&p).unwrap(), b"two");
        // no temporary file left behind
        let n = fs::read_dir(p.parent().unwrap()).unwrap().count();
        assert_eq!(n, 1);
        fs::remove_dir_all(&d).ok();
    }

    #[test]
    fn refuses_directories_and_devices() {
        let d = tmpdir("dir");
        let e = write_atomic(&d, b"x").unwrap_err();
        assert!(matches!(e, Error::UnsafeOutput { .. }), "{e}");
        assert!(e.to_string().contains("directory"), "{e}");
        #[cfg(unix)]
        {
            let e = write_atomic(Path::new("/dev/null"), b"x").unwrap_err();
            assert!(e.to_string().contains("/dev/null"), "{e}");
            assert!(e.to_string().contains("character device"), "{e}");
        }
        fs::remove_dir_all(&d).ok();
    }

    #[cfg(unix)]
    #[test]
    fn follows_symlinks_and_keeps_them() {
        let d = tmpdir("link");
        let target = d.join("target.csv");
        fs::write(&target, "old").unwrap();
        let link = d.join("link.csv");
        std::os::unix::fs::symlink("target.csv", &link).unwrap();
        write_atomic(&link, b"new").unwrap();
        assert!(fs::symlink_metadata(&link)
            .unwrap()
            .file_type()
            .is_symlink());
        assert_eq!(fs::read(&target).unwrap(), b"new");
        // dangling link: creates its target
        let dangling = d.join("dangling.csv");
        std::os::unix::fs::symlink("made.csv", &dangling).unwrap();
        write_atomic(&dangling, b"m").unwrap();
        assert_eq!(fs::read(d.join("made.csv")).unwrap(), b"m");
        // link to a device: refused, the link stays
        let dev = d.join("dev.csv");
        std::os::unix::fs::symlink("/dev/null", &dev).unwrap();
        let e = write_atomic(&dev, b"x").unwrap_err();
        assert!(e.to_string().contains("symbolic link"), "{e}");
        assert!(fs::symlink_metadata(&dev).unwrap().file_type().is_symlink());
        // a loop
        let a = d.join("a");
        let b = d.join("b");
        std::os::unix::fs::symlink("b", &a).unwrap();
        std::os::unix::fs::symlink("a", &b).unwrap();
        assert!(write_atomic(&a, b"x").is_err());
        fs::remove_dir_all(&d).ok();
    }

    #[test]
    fn prefixes_and_folders() {
        // issue 32 item 8
        let d = tmpdir("prefix");
        assert!(check_prefix(&d.join("surf")).is_ok());
        let dir_slash = format!("{}/", d.display());
        assert!(check_prefix(Path::new(&dir_slash)).is_err());
        assert!(check_prefix(&d).is_err());
        assert!(check_prefix(Path::new("..")).is_err());
        #[cfg(unix)]
        assert!(check_prefix(Path::new("/dev/null"))
            .unwrap_err()
            .to_string()
            .contains("character device"));
        assert!(check_output_dir(&d.join("new")).is_ok());
        assert!(check_output_dir(&d).is_ok());
        assert!(check_output_dir(Path::new("/")).is_err());
        #[cfg(unix)]
        assert!(check_output_dir(Path::new("/dev/null")).is_err());
        fs::remove_dir_all(&d).ok();
    }

    #[test]
    fn sizes_and_limits() {
        assert_eq!(parse_size("4G").unwrap(), 4 << 30);
        assert_eq!(parse_size("512MiB").unwrap(), 512 << 20);
        assert_eq!(parse_size("1000").unwrap(), 1000);
        assert!(parse_size("lots").is_err());
        assert!(parse_size("-1G").is_err());
        assert!(check_threads("threads", 0).is_err());
        assert!(check_threads("threads", 4_294_967_296).is_err());
        assert_eq!(check_threads("threads", 8).unwrap(), 8);
        assert!(check_magnitude("m", 1e-320).is_err());
        assert!(check_magnitude("m", 1e308).is_err());
        assert!(check_magnitude("m", 0.0).is_ok());
        assert!(check_magnitude("m", -2.5).is_ok());
        let e = check_alloc("test", 1e20).unwrap_err();
        assert!(matches!(e, Error::ResourceLimit { .. }), "{e}");
    }

    #[test]
    fn capped_read() {
        let d = tmpdir("read");
        let p = d.join("x.txt");
        fs::write(&p, "abc").unwrap();
        assert_eq!(read_to_string_capped(&p).unwrap(), "abc");
        assert!(read_capped(&d).is_err());
        assert!(read_capped(&d.join("missing")).is_err());
        #[cfg(unix)]
        {
            // issue 32 item 9: a FIFO as input blocked forever in open()
            let fifo = d.join("p.csv");
            let st = std::process::Command::new("mkfifo").arg(&fifo).status();
            assert!(st.unwrap().success(), "mkfifo");
            let e = read_capped(&fifo).unwrap_err().to_string();
            assert!(e.contains("FIFO"), "{e}");
        }
        fs::remove_dir_all(&d).ok();
    }
}
