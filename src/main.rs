//! `springmass` command-line interface: a thin layer over the library.
//! Every subcommand lives in its own file under `src/cmd/`.
//!
//! Exit statuses are decided here, in one place ([`exit_code`]), from the
//! typed error at the root of a failure ([`springmass::Error::exit_code`]).

mod cmd;

use clap::{CommandFactory, Parser, Subcommand};
use springmass::error::exit;
use std::io::Write;

/// The exit statuses and environment variables, shown by `--help`.
const AFTER_HELP: &str = "\
Exit status:
  0    success
  1    any other failure (a numerical method that failed, an internal error)
  2    usage error or invalid input (unknown option, value out of range,
       unreadable data or scene file, a job above the memory budget)
  3    input/output error (a file that cannot be read or written; an output
       path that is a directory, device, FIFO or socket; a full stdout)
  4    the data cannot resolve the requested result (signal below the
       rounding or noise floor, e.g. `locate` on an unresolvable defect)
  141  stdout or stderr is a closed pipe (killed by SIGPIPE, no message)

Environment:
  SPRINGMASS_MEMORY_BUDGET  memory one job may allocate (default 4G); larger
                            jobs are refused before they start
  SPRINGMASS_MAX_INPUT      largest input file read (default 256M)";

/// Vibration suppression and defect detection in 1D spring-mass chains.
#[derive(Parser)]
#[command(name = "springmass", version, about, long_about = None, after_help = AFTER_HELP)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Laplace-domain response X_i(s) of a chain (closed form + Woodbury).
    Response(cmd::response::Args),
    /// Run a study file (sweep of cases) in parallel into tables and plots; `study merge` combines shards.
    Study(cmd::study::Args),
    /// Check a study file, print the schema of every field with its default.
    Config(cmd::config::Args),
    /// Locate one mass defect from X_1(s) (section 4.1 locators, corrected).
    Locate(cmd::locate::Args),
    /// Time-domain simulation x_i(t): impulse on mass 1, optional forces, CSV/SVG out.
    Simulate(cmd::simulate::Args),
    /// Vibration suppression controls (Theorem 3.1, Corollary 3.2), verified by simulation.
    Suppress(cmd::suppress::Args),
    /// Laplace transform X(s) of a sampled series (CSV), with error estimates.
    Laplace(cmd::laplace::Args),
    /// Fit defects to a measured series (--data; noise and number of defects estimated) or a scene (--scene).
    Fit(Box<cmd::fit::Args>),
    /// Fit every record of a structure in service against a baseline fit; flag a change at a stated false-alarm rate.
    Monitor(Box<cmd::monitor::Args>),
    /// Residual surfaces r(j, m) and r(j1, j2) (the paper's Figures 16 and 17), CSV + SVG.
    Surface(cmd::surface::Args),
    /// The shipped noise studies (data-first defaults, per misfit, defect kinds) on the study engine.
    NoiseStudy(cmd::noise::Args),
    /// Every mass of a chain from the modes of mass 1 (frequencies and residues; inverse eigenvalue problem).
    Spectral(cmd::spectral::Args),
    /// Print a shell completion script: `springmass completions bash > ~/.local/share/bash-completion/completions/springmass`.
    Completions {
        /// The shell.
        #[arg(value_enum)]
        shell: clap_complete::Shell,
    },
    /// Print a man page (roff): `springmass man > springmass.1; man ./springmass.1`;
    /// `springmass man fit > springmass-fit.1` for a subcommand.
    Man {
        /// The subcommand (default: the top-level page, which lists them).
        command: Option<String>,
    },
}

fn run() -> anyhow::Result<()> {
    let cli = Cli::parse();
    match cli.command {
        Command::Response(a) => cmd::response::run(a),
        Command::Study(a) => cmd::study::run(a),
        Command::Config(a) => cmd::config::run(a),
        Command::Locate(a) => cmd::locate::run(a),
        Command::Simulate(a) => cmd::simulate::run(a),
        Command::Suppress(a) => cmd::suppress::run(a),
        Command::Laplace(a) => cmd::laplace::run(a),
        Command::Fit(a) => match a.threads {
            Some(n) => {
                springmass::study::run::check_threads(n)?;
                rayon::ThreadPoolBuilder::new()
                    .num_threads(n)
                    .build()?
                    .install(|| cmd::fit::run(*a))
            }
            None => cmd::fit::run(*a),
        },
        Command::Monitor(a) => cmd::monitor::run(*a),
        Command::Surface(a) => cmd::surface::run(a),
        Command::NoiseStudy(a) => cmd::noise::run(a),
        Command::Spectral(a) => cmd::spectral::run(a),
        Command::Completions { shell } => {
            let mut buf = Vec::new();
            clap_complete::generate(shell, &mut Cli::command(), "springmass", &mut buf);
            write_stdout(&buf)
        }
        Command::Man { command } => write_stdout(&man_page(command.as_deref())?),
    }
}

/// The man page of the whole tool, or of one subcommand
/// (`springmass-fit(1)`).
fn man_page(sub: Option<&str>) -> anyhow::Result<Vec<u8>> {
    let top = Cli::command();
    let cmd = match sub {
        None => top,
        Some(name) => {
            let names: Vec<String> = top
                .get_subcommands()
                .map(|c| c.get_name().to_string())
                .collect();
            let found = top.find_subcommand(name).cloned().ok_or_else(|| {
                springmass::Error::invalid("command", name, format!("one of {}", names.join(", ")))
            })?;
            // clap keeps names as &'static str: one small string, once per process
            let page: &'static str = Box::leak(format!("springmass-{name}").into_boxed_str());
            found.name(page)
        }
    };
    let mut buf = Vec::new();
    clap_mangen::Man::new(cmd).render(&mut buf)?;
    Ok(buf)
}

/// Write bytes to stdout, reporting a failure as an I/O error (exit 3).
fn write_stdout(bytes: &[u8]) -> anyhow::Result<()> {
    let mut out = std::io::stdout().lock();
    out.write_all(bytes)
        .and_then(|_| out.flush())
        .map_err(|e| springmass::Error::io("stdout", e))?;
    Ok(())
}

/// The exit status of a failure: the first typed error in the chain decides
/// ([`springmass::Error::exit_code`]; an OS error is I/O); an error that is
/// only a message comes from an argument check in `cmd/` and counts as
/// invalid input.
fn exit_code(e: &anyhow::Error) -> i32 {
    for cause in e.chain() {
        if let Some(se) = cause.downcast_ref::<springmass::Error>() {
            return se.exit_code();
        }
        if cause.is::<std::io::Error>() {
            return exit::IO;
        }
        if cause.is::<toml::de::Error>()
            || cause.is::<serde_json::Error>()
            || cause.is::<csv::Error>()
            || cause.is::<std::num::ParseFloatError>()
            || cause.is::<std::num::ParseIntError>()
        {
            return exit::USAGE;
        }
    }
    if e.chain().count() == 1 {
        exit::USAGE
    } else {
        exit::OTHER
    }
}

/// Conventional behaviour on pipes and full outputs:
/// * a closed stdout or stderr pipe ends the process quietly by SIGPIPE
///   (status 141 in a shell), as `cat` or `grep` do;
/// * a failed write to stdout or stderr (`> /dev/full`) that `println!`
///   would turn into a panic ends the process with status 3 and one line.
fn install_io_handlers() {
    #[cfg(unix)]
    // SAFETY: restoring the default disposition of SIGPIPE at the start of
    // main, before any thread exists; no handler function is involved.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    let default = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        let msg = info
            .payload()
            .downcast_ref::<String>()
            .map(String::as_str)
            .or_else(|| info.payload().downcast_ref::<&str>().copied())
            .unwrap_or("");
        if let Some(reason) = msg.strip_prefix("failed printing to stdout") {
            let _ = writeln!(std::io::stderr(), "error: writing to stdout{reason}");
            std::process::exit(exit::IO);
        }
        if msg.starts_with("failed printing to stderr") {
            std::process::exit(exit::IO);
        }
        default(info)
    }));
}

fn main() {
    install_io_handlers();
    let result = run().and_then(|()| {
        std::io::stdout()
            .flush()
            .map_err(|e| springmass::Error::io("stdout", e).into())
    });
    if let Err(e) = result {
        // one line: the error and its causes joined by ": "
        eprintln!("error: {e:#}");
        std::process::exit(exit_code(&e));
    }
}
