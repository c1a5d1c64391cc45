//! Command-line fuzz test: the built `springmass` binary over seeded, mutated
//! command lines of every subcommand (and mutated scene and study files).
//!
//! One case in eight is a mutated data file (CSV) read by `laplace` or fitted
//! by `fit`; one in eight of the rest a mutated scene or study file.
//!
//! Checks, for every case:
//! * no panic (exit status 101 or `panicked` on stderr);
//! * no hang (a per-case timeout, `SPRINGMASS_FUZZ_TIMEOUT` seconds, default 60);
//! * no special file replaced: every worker owns a FIFO, a socket, a folder, a
//!   symbolic link to the FIFO and one to a regular file, passed as outputs;
//!   after each case they must still be what they were;
//! * never exit 0 on input that is invalid by construction (a non-number for a
//!   number, an unknown option, a FIFO, socket or folder as an output file, a
//!   folder, a missing, empty or binary file, or `/dev/urandom` as an input;
//!   in a data file a cell that is not a number, a field too many or too few,
//!   a repeated column name, no header or no samples).
//!
//! Scale with `SPRINGMASS_FUZZ_CASES` (default 10000), `SPRINGMASS_FUZZ_JOBS`
//! (parallel cases, default 4), `SPRINGMASS_FUZZ_SEED` (default 17); leave
//! subcommands out with `SPRINGMASS_FUZZ_SKIP=study,config` (comma separated
//! first words, also skips the mutated `config check` files). Generated
//! cases use tiny chains and short records so that the whole run stays within
//! a few minutes on 2 cores. Heavy subcommands (`study`, `fit`, `noise-study`)
//! only get mutations that make them invalid, so that they fail in validation.
//!
//! A failure prints each failing command line, marked with the file that owns
//! the subcommand, so that it can be reproduced by hand.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

const BIN: &str = env!("CARGO_BIN_EXE_springmass");

fn env_usize(name: &str, default: usize) -> usize {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

/// What an option's value is, which decides the mutations that apply.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Kind {
    /// A number (f64 or integer).
    Num,
    /// A list of numbers or complex numbers, a defect spec, an enum name.
    Text,
    /// An input file.
    In,
    /// An output file (or prefix).
    Out,
    /// An output folder.
    OutDir,
    /// A flag without value.
    Flag,
    /// A positional word (subcommand name).
    Word,
}

#[derive(Clone, Debug)]
struct Tok {
    flag: String,
    value: Option<String>,
    kind: Kind,
}

fn t(flag: &str, value: &str, kind: Kind) -> Tok {
    Tok {
        flag: flag.to_string(),
        value: Some(value.to_string()),
        kind,
    }
}
fn f(flag: &str) -> Tok {
    Tok {
        flag: flag.to_string(),
        value: None,
        kind: Kind::Flag,
    }
}
fn w(word: &str) -> Tok {
    Tok {
        flag: word.to_string(),
        value: None,
        kind: Kind::Word,
    }
}

struct Template {
    /// The file that implements the subcommand (for the report).
    owner: &'static str,
    /// Only invalid-by-construction mutations (valid runs would be long).
    heavy: bool,
    toks: Vec<Tok>,
}

/// Paths a worker owns.
struct Files {
    dir: PathBuf,
    fifo: PathBuf,
    socket: PathBuf,
    folder: PathBuf,
    link_fifo: PathBuf,
    link_file: PathBuf,
    link_target: PathBuf,
    series: PathBuf,
    series_text: String,
    scene: PathBuf,
    study: PathBuf,
    empty: PathBuf,
    binary: PathBuf,
    _listener: std::os::unix::net::UnixListener,
}

fn mkfifo(path: &Path) {
    let st = Command::new("mkfifo").arg(path).status().expect("mkfifo");
    assert!(st.success(), "mkfifo {}", path.display());
}

const SCENE: &str = "[chain]
n = 5
d = 0.1
defects = [ { kind = \"mass\", at = 2, m = 3.0 } ]

[data]
source = \"exact\"
noise = 0.0
seed = 0

[unknowns]
k = 1
mass_bounds = [0.5, 10.0]

[misfit]
kind = \"real-axis\"
rule = \"gl-log\"
panels = 2
per_panel = 4
first = 0.05
s_max = 30.0

[search]
method = \"enumerate\"
seed = 0
max_evals = 200
keep = 2
";

fn setup(root: &Path, worker: usize, study_text: &str) -> Files {
    let dir = root.join(format!("w{worker}"));
    std::fs::create_dir_all(&dir).unwrap();
    let fifo = dir.join("fifo.csv");
    mkfifo(&fifo);
    let socket = dir.join("socket.csv");
    let listener = std::os::unix::net::UnixListener::bind(&socket).unwrap();
    let folder = dir.join("folder.csv");
    std::fs::create_dir_all(&folder).unwrap();
    let link_fifo = dir.join("link-fifo.csv");
    std::os::unix::fs::symlink("fifo.csv", &link_fifo).unwrap();
    let link_target = dir.join("target.csv");
    std::fs::write(&link_target, "t,x1\n0,1\n").unwrap();
    let link_file = dir.join("link-file.csv");
    std::os::unix::fs::symlink("target.csv", &link_file).unwrap();
    let series = dir.join("series.csv");
    let mut csv = String::from("t,x1\n");
    for i in 0..60 {
        let tt = i as f64 * 0.1;
        csv.push_str(&format!("{tt},{}\n", (-0.3 * tt).exp() * (1.3 * tt).sin()));
    }
    std::fs::write(&series, &csv).unwrap();
    let scene = dir.join("scene.toml");
    std::fs::write(&scene, SCENE).unwrap();
    let study = dir.join("study.toml");
    std::fs::write(&study, study_text).unwrap();
    let empty = dir.join("empty.csv");
    std::fs::write(&empty, "").unwrap();
    let binary = dir.join("binary.csv");
    std::fs::write(
        &binary,
        (0..4096u64)
            .map(|i| (i.wrapping_mul(2654435761) >> 13) as u8)
            .collect::<Vec<_>>(),
    )
    .unwrap();
    Files {
        dir,
        fifo,
        socket,
        folder,
        link_fifo,
        link_file,
        link_target,
        series,
        series_text: csv,
        scene,
        study,
        empty,
        binary,
        _listener: listener,
    }
}

/// The special files must still be what they were.
fn check_specials(fl: &Files) -> Result<(), String> {
    use std::os::unix::fs::FileTypeExt;
    let ft = |p: &Path| std::fs::symlink_metadata(p).map(|m| m.file_type());
    let ok = ft(&fl.fifo).map(|t| t.is_fifo()).unwrap_or(false)
        && ft(&fl.socket).map(|t| t.is_socket()).unwrap_or(false)
        && ft(&fl.folder).map(|t| t.is_dir()).unwrap_or(false)
        && ft(&fl.link_fifo).map(|t| t.is_symlink()).unwrap_or(false)
        && ft(&fl.link_file).map(|t| t.is_symlink()).unwrap_or(false)
        && std::fs::read_link(&fl.link_fifo).ok() == Some(PathBuf::from("fifo.csv"))
        && std::fs::read_link(&fl.link_file).ok() == Some(PathBuf::from("target.csv"))
        && ft(&fl.link_target).map(|t| t.is_file()).unwrap_or(false);
    if ok {
        Ok(())
    } else {
        Err("a special file (FIFO, socket, folder or symbolic link) was replaced".into())
    }
}

fn templates(fl: &Files) -> Vec<Template> {
    let p = |x: &Path| x.display().to_string();
    let out = |name: &str| fl.dir.join(name).display().to_string();
    vec![
        Template {
            owner: "src/cmd/response.rs",
            heavy: false,
            toks: vec![
                w("response"),
                t("--n", "5", Kind::Num),
                t("--s", "0.5,1+5i", Kind::Text),
                t("--defect", "mass:3:2", Kind::Text),
                t("--gamma", "1", Kind::Num),
                t("--d", "0.1", Kind::Num),
                t("--k", "1", Kind::Num),
                t("--mass", "1", Kind::Num),
                t("--observe", "1", Kind::Num),
                f("--json"),
            ],
        },
        Template {
            owner: "src/cmd/simulate.rs",
            heavy: false,
            toks: vec![
                w("simulate"),
                t("--n", "3", Kind::Num),
                t("--t-end", "1", Kind::Num),
                t("--dt", "0.25", Kind::Num),
                t("--observe", "1,3", Kind::Text),
                t("--noise", "0.01", Kind::Text),
                t("--seed", "1", Kind::Num),
                t("--method", "auto", Kind::Text),
                t("--out", &out("sim.csv"), Kind::Out),
                t("--plot", &out("sim.svg"), Kind::Out),
            ],
        },
        Template {
            owner: "src/cmd/laplace.rs",
            heavy: false,
            toks: vec![
                w("laplace"),
                t("--series", &p(&fl.series), Kind::In),
                t("--s", "0.5,1+2i", Kind::Text),
                t("--degree", "5", Kind::Num),
                t("--tail", "envelope", Kind::Text),
                t("--column", "x1", Kind::Text),
                t("--noise-sigma", "0.01", Kind::Num),
                f("--json"),
            ],
        },
        Template {
            owner: "src/cmd/locate.rs",
            heavy: false,
            toks: vec![
                w("locate"),
                t("--n", "8", Kind::Num),
                t("--defect", "mass:4:3", Kind::Text),
                t("--m", "3", Kind::Num),
                t("--s", "0.5", Kind::Text),
                t("--curve", "0.1:1:5", Kind::Text),
                t("--plot", &out("curve.svg"), Kind::Out),
                f("--json"),
            ],
        },
        Template {
            owner: "src/cmd/suppress.rs",
            heavy: false,
            toks: vec![
                w("suppress"),
                t("--n", "3", Kind::Num),
                t("--t-end", "2", Kind::Num),
                t("--dt", "0.1", Kind::Num),
                t("--robust-delays", "0,0.1", Kind::Text),
                t("--robust-gains", "0,0.01", Kind::Text),
                t("--delay", "0", Kind::Num),
                t("--out-dir", &out("suppress"), Kind::OutDir),
            ],
        },
        Template {
            owner: "src/cmd/surface.rs",
            heavy: false,
            toks: vec![
                w("surface"),
                t("--scene", &p(&fl.scene), Kind::In),
                t("--kind", "jm", Kind::Text),
                t("--m-steps", "4", Kind::Num),
                Tok {
                    flag: "--m-range".into(),
                    value: Some("0.5".into()),
                    kind: Kind::Num,
                },
                Tok {
                    flag: String::new(),
                    value: Some("10".into()),
                    kind: Kind::Num,
                },
                t("--out", &out("surf"), Kind::Out),
            ],
        },
        Template {
            owner: "src/main.rs",
            heavy: false,
            toks: vec![w("completions"), w("bash")],
        },
        Template {
            owner: "src/main.rs",
            heavy: false,
            toks: vec![w("man")],
        },
        Template {
            owner: "src/cmd/config.rs (not io-cli's)",
            heavy: false,
            toks: vec![w("config"), w("check"), t("", &p(&fl.study), Kind::In)],
        },
        Template {
            owner: "src/cmd/fit.rs (not io-cli's)",
            heavy: true,
            toks: vec![
                w("fit"),
                t("--scene", &p(&fl.scene), Kind::In),
                t("--method", "enumerate", Kind::Text),
                t("--seed", "1", Kind::Num),
                t("--noise", "0", Kind::Num),
                f("--json"),
            ],
        },
        Template {
            owner: "src/cmd/study.rs (not io-cli's)",
            heavy: true,
            toks: vec![
                w("study"),
                t("", &p(&fl.study), Kind::In),
                t("--out", &out("study"), Kind::OutDir),
                t("--threads", "1", Kind::Num),
                t("--shard", "1/2", Kind::Text),
                f("--quiet"),
            ],
        },
        Template {
            owner: "src/cmd/noise.rs (not io-cli's)",
            heavy: true,
            toks: vec![
                w("noise-study"),
                w("misfits"),
                t("--seeds", "1", Kind::Num),
                t("--levels", "0.01", Kind::Text),
                t("--systems", "S1", Kind::Text),
                t("--misfits", "real-axis", Kind::Text),
                t("--threads", "1", Kind::Num),
                t("--out", &out("noise"), Kind::OutDir),
                f("--quiet"),
            ],
        },
    ]
}

const HOSTILE_NUM: &[&str] = &[
    "0",
    "-1",
    "-1e-3",
    "-0.001",
    "1e308",
    "-1e308",
    "1.7976931348623157e308",
    "1e-320",
    "5e-324",
    "4294967296",
    "18446744073709551616",
    "9223372036854775807",
    "1e300",
    "999999999",
    "1000000000",
    "0.0",
    "-0",
    "1e15",
    "3",
    "0.5",
];
/// Values that are not a number for any numeric option.
const NOT_NUMBERS: &[&str] = &["nan", "NaN", "inf", "-inf", "abc", "1+", "1e", "0x10", "--"];
const HOSTILE_TEXT: &[&str] = &[
    "",
    ",",
    "1e308+1e308i",
    "1+5i",
    "-1e-3",
    "mass:0:1",
    "mass:999999999999:1",
    "spring:1:-1",
    "damper:2:1e308",
    "1e-320:10:5",
    "0.1:1e308:100000",
    "0.1:1:4294967296",
    "nan",
    "0,1e308",
    "1e308",
    "2/1",
    "0/0",
    "rk",
    "modal",
    "snr:-400",
    "rel:1e308",
];

/// Build one case: (arguments, invalid by construction, owner).
fn gen_case(
    rng: &mut ChaCha8Rng,
    tpls: &[Template],
    fl: &Files,
) -> (Vec<String>, bool, &'static str) {
    let skip = std::env::var("SPRINGMASS_FUZZ_SKIP").unwrap_or_default();
    let tpls: Vec<&Template> = tpls
        .iter()
        .filter(|t| {
            !skip
                .split(',')
                .any(|w| !w.is_empty() && t.toks[0].flag == w)
        })
        .collect();
    let tpl = tpls[rng.random_range(0..tpls.len())];
    let mut toks = tpl.toks.clone();
    let mut invalid = false;
    let p = |x: &Path| x.display().to_string();
    let bad_outputs = [&fl.fifo, &fl.socket, &fl.folder, &fl.link_fifo];
    let bad_inputs = [
        p(&fl.folder),
        p(&fl.empty),
        p(&fl.binary),
        p(&fl.dir.join("missing.csv")),
        "/dev/urandom".to_string(),
    ];
    // SPRINGMASS_FUZZ_NO_DEVICES=1 leaves /dev/urandom out (to look past
    // commands that still read it without a cap)
    let n_inputs = if std::env::var_os("SPRINGMASS_FUZZ_NO_DEVICES").is_some() {
        bad_inputs.len() - 1
    } else {
        bad_inputs.len()
    };
    // exploratory mutations first (validity unknown), light commands only
    if !tpl.heavy {
        for _ in 0..rng.random_range(0..3) {
            let i = rng.random_range(0..toks.len());
            let kind = toks[i].kind;
            match rng.random_range(0..6) {
                0 if toks[i].value.is_some() && kind == Kind::Num => {
                    toks[i].value =
                        Some(HOSTILE_NUM[rng.random_range(0..HOSTILE_NUM.len())].into());
                }
                1 if toks[i].value.is_some() && kind != Kind::In => {
                    toks[i].value =
                        Some(HOSTILE_TEXT[rng.random_range(0..HOSTILE_TEXT.len())].into());
                }
                2 if kind == Kind::Out => {
                    toks[i].value = Some(p(&fl.link_file));
                }
                3 if i > 0 && kind != Kind::Word => {
                    toks.remove(i);
                }
                4 if i > 0 && kind != Kind::Word => {
                    let dup = toks[i].clone();
                    toks.push(dup);
                }
                5 if toks[i].value.is_some() => {
                    let v = toks[i].value.clone().unwrap();
                    let cut = rng.random_range(0..=v.len());
                    if v.is_char_boundary(cut) {
                        toks[i].value = Some(v[..cut].to_string());
                    }
                }
                _ => {}
            }
        }
    }
    // then, for heavy commands always and otherwise in half of the cases, one
    // mutation that makes the command line invalid by construction
    if tpl.heavy || rng.random_range(0..2) == 0 {
        invalid = true;
        let applicable: Vec<(usize, u8)> = toks
            .iter()
            .enumerate()
            .flat_map(|(i, tok)| {
                let mut ops = Vec::new();
                if tok.value.is_some() && tok.kind == Kind::Num && !tok.flag.is_empty() {
                    ops.push((i, 0));
                }
                if matches!(tok.kind, Kind::Out | Kind::OutDir) {
                    ops.push((i, 1));
                }
                if tok.kind == Kind::In {
                    ops.push((i, 2));
                }
                ops
            })
            .collect();
        let pick = rng.random_range(0..=applicable.len());
        match applicable.get(pick) {
            Some(&(i, 0)) => {
                toks[i].value = Some(NOT_NUMBERS[rng.random_range(0..NOT_NUMBERS.len())].into());
            }
            Some(&(i, 1)) => {
                let choices: &[usize] = if toks[i].kind == Kind::Out {
                    &[0, 1, 2, 3]
                } else {
                    &[0, 1, 3]
                };
                toks[i].value = Some(p(bad_outputs[choices[rng.random_range(0..choices.len())]]));
            }
            Some(&(i, _)) => {
                toks[i].value = Some(bad_inputs[rng.random_range(0..n_inputs)].clone());
            }
            None => {
                let pos = rng.random_range(1..=toks.len());
                toks.insert(
                    pos,
                    f(["--bogus", "--nn", "--out-put", "-z"][rng.random_range(0..4)]),
                );
            }
        }
    }
    let mut args = Vec::new();
    for tok in toks {
        if !tok.flag.is_empty() {
            args.push(tok.flag);
        }
        if let Some(v) = tok.value {
            args.push(v);
        }
    }
    (args, invalid, tpl.owner)
}

/// A mutated copy of a TOML text (validity unknown).
fn mutate_toml(rng: &mut ChaCha8Rng, text: &str) -> String {
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    for _ in 0..1 + rng.random_range(0..3) {
        if lines.is_empty() {
            break;
        }
        let i = rng.random_range(0..lines.len());
        match rng.random_range(0..6) {
            0 => {
                lines.remove(i);
            }
            1 => {
                let l = lines[i].clone();
                lines.insert(i, l);
            }
            2 | 3 => {
                // replace the first number on the line
                let l = &lines[i];
                if let Some(start) = l.find(|c: char| c.is_ascii_digit()) {
                    let end = l[start..]
                        .find(|c: char| !(c.is_ascii_digit() || c == '.' || c == 'e' || c == '-'))
                        .map_or(l.len(), |e| start + e);
                    let rep = [
                        "-3",
                        "0",
                        "1e308",
                        "9223372036854775807",
                        "\"abc\"",
                        "nan",
                        "1e-320",
                        "4294967296",
                    ][rng.random_range(0..8)];
                    lines[i] = format!("{}{}{}", &l[..start], rep, &l[end..]);
                }
            }
            4 => {
                let cut = rng.random_range(0..=lines[i].len());
                if lines[i].is_char_boundary(cut) {
                    lines[i].truncate(cut);
                }
            }
            _ => {
                lines.insert(
                    i,
                    ["nn = 3", "[bogus]", "x = ", "panels = 9223372036854775807"]
                        [rng.random_range(0..4)]
                    .to_string(),
                );
            }
        }
    }
    lines.join("\n") + "\n"
}

/// A mutated copy of the record's CSV text and whether it is invalid by
/// construction (a cell that is not a number, a row with a field too many or
/// too few, a repeated column name, no header, nothing but a header).
fn mutate_csv(rng: &mut ChaCha8Rng, text: &str) -> (Vec<u8>, bool) {
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    let row = rng.random_range(1..lines.len());
    let join = |lines: &[String]| (lines.join("\n") + "\n").into_bytes();
    match rng.random_range(0..10) {
        0 => {
            let t = lines[row].split(',').next().unwrap_or("0").to_string();
            let bad = [
                "abc", "1.2.3", "--1", "0x1g", "#N/A", "1e", "+", "nan", "inf",
            ];
            lines[row] = format!("{t},{}", bad[rng.random_range(0..bad.len())]);
            (join(&lines), true)
        }
        1 => {
            // (a trailing empty field is allowed: spreadsheets write one)
            lines[row].push_str([",5", ",x", ",1,2"][rng.random_range(0..3)]);
            (join(&lines), true)
        }
        2 => {
            lines[0] = ["t,t", "x1,x1"][rng.random_range(0..2)].to_string();
            (join(&lines), true)
        }
        3 => (join(&lines[1..]), true),
        4 => {
            lines[row] = lines[row].split(',').next().unwrap_or("").to_string();
            (join(&lines), true)
        }
        5 => {
            // a few bytes flipped anywhere: valid or not
            let mut b = join(&lines);
            for _ in 0..rng.random_range(1..5) {
                let i = rng.random_range(0..b.len());
                b[i] = rng.random_range(0..=255u8);
            }
            (b, false)
        }
        6 => {
            let t = lines[row].split(',').next().unwrap_or("0").to_string();
            let v = ["1e308", "-1e308", "5e-324", "0", "1e-310", "-0"];
            lines[row] = format!("{t},{}", v[rng.random_range(0..v.len())]);
            (join(&lines), false)
        }
        7 => {
            let i = rng.random_range(1..lines.len());
            if rng.random_range(0..2) == 0 {
                let l = lines[i].clone();
                lines.insert(i, l);
            } else {
                lines.remove(i);
            }
            (join(&lines), false)
        }
        8 => {
            let text = String::from_utf8(join(&lines)).unwrap();
            let forms = [
                text.replace('\n', "\r\n"),
                format!("\u{feff}{text}"),
                text.replace(',', ";"),
                text.replacen("t,x1", "t [s],x1 [m]", 1),
                text.replace(',', "\t"),
            ];
            (
                forms[rng.random_range(0..forms.len())].clone().into_bytes(),
                false,
            )
        }
        _ => {
            let forms = ["t,x1\n", ",\n", "\n\n", "t,x1\n0\n"];
            (
                forms[rng.random_range(0..forms.len())].as_bytes().to_vec(),
                true,
            )
        }
    }
}

/// The command that reads a mutated data file: `laplace` (cheap) or a small
/// `fit` (one defect on three masses).
fn data_file_args(rng: &mut ChaCha8Rng, path: &Path) -> Vec<String> {
    let p = path.display().to_string();
    let words: Vec<&str> = if rng.random_range(0..2) == 0 {
        vec!["laplace", "--series", &p, "--s", "0.5,1+2i", "--json"]
    } else {
        vec!["fit", "--data", &p, "--n", "3", "--defects", "1", "--json"]
    };
    words.into_iter().map(str::to_string).collect()
}

struct Outcome {
    code: Option<i32>,
    stderr: String,
    timed_out: bool,
}

fn run_case(args: &[String], timeout: Duration, dir: &Path) -> Outcome {
    let mut child = Command::new(BIN)
        .args(args)
        .current_dir(dir)
        .env("SPRINGMASS_MAX_INPUT", "1M")
        .env("RAYON_NUM_THREADS", "1")
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn springmass");
    let mut stderr = child.stderr.take().unwrap();
    let reader = std::thread::spawn(move || {
        use std::io::Read;
        let mut buf = Vec::new();
        let _ = (&mut stderr).take(1 << 20).read_to_end(&mut buf);
        String::from_utf8_lossy(&buf).into_owned()
    });
    let start = Instant::now();
    let mut timed_out = false;
    let status = loop {
        match child.try_wait().expect("wait") {
            Some(st) => break st,
            None if start.elapsed() > timeout => {
                let _ = child.kill();
                timed_out = true;
                break child.wait().expect("wait after kill");
            }
            None => std::thread::sleep(Duration::from_millis(5)),
        }
    };
    let stderr = reader.join().unwrap_or_default();
    Outcome {
        code: status.code(),
        stderr,
        timed_out,
    }
}

fn quote(args: &[String]) -> String {
    args.iter()
        .map(|a| {
            if a.is_empty()
                || a.contains(|c: char| c.is_whitespace() || "\"'$\\|&;<>()*?[]#~".contains(c))
            {
                format!("'{}'", a.replace('\'', "'\\''"))
            } else {
                a.clone()
            }
        })
        .collect::<Vec<_>>()
        .join(" ")
}

#[test]
fn fuzz_command_lines() {
    let cases = env_usize("SPRINGMASS_FUZZ_CASES", 10_000);
    let jobs = env_usize("SPRINGMASS_FUZZ_JOBS", 4).max(1);
    let seed = env_usize("SPRINGMASS_FUZZ_SEED", 17) as u64;
    let timeout = Duration::from_secs(env_usize("SPRINGMASS_FUZZ_TIMEOUT", 60) as u64);
    let root = std::env::temp_dir().join(format!("springmass-fuzz-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&root);
    std::fs::create_dir_all(&root).unwrap();

    // the embedded default study, as a base for mutated study files
    let show = Command::new(BIN)
        .args(["config", "show-default"])
        .output()
        .expect("springmass config show-default");
    assert!(show.status.success(), "config show-default failed");
    let study_text = String::from_utf8(show.stdout).unwrap();
    assert!(
        study_text.contains("[study]"),
        "unexpected default study: {study_text}"
    );

    let next = Arc::new(AtomicUsize::new(0));
    let failures = Arc::new(Mutex::new(Vec::<String>::new()));
    let stats = Arc::new(Mutex::new([0usize; 3])); // [cases, exit 0, invalid cases]
    let mut handles = Vec::new();
    for wk in 0..jobs {
        let (next, failures, stats, root, study_text) = (
            next.clone(),
            failures.clone(),
            stats.clone(),
            root.clone(),
            study_text.clone(),
        );
        handles.push(std::thread::spawn(move || {
            let fl = setup(&root, wk, &study_text);
            let tpls = templates(&fl);
            loop {
                let idx = next.fetch_add(1, Ordering::SeqCst);
                if idx >= cases {
                    break;
                }
                let mut rng = ChaCha8Rng::seed_from_u64(
                    seed.wrapping_mul(1_000_003).wrapping_add(idx as u64),
                );
                // one case in eight: a mutated scene or study file
                let skip = std::env::var("SPRINGMASS_FUZZ_SKIP").unwrap_or_default();
                let skip_config = skip.split(',').any(|w| w == "config");
                let mut mutated: Option<String> = None;
                let (args, invalid, owner) = if rng.random_range(0..8) == 0 {
                    // a mutated data file, read by `laplace` or fitted by `fit`
                    let path = fl.dir.join(format!("m{idx}.csv"));
                    let (bytes, invalid) = mutate_csv(&mut rng, &fl.series_text);
                    std::fs::write(&path, &bytes).unwrap();
                    mutated = Some(String::from_utf8_lossy(&bytes).into_owned());
                    (
                        data_file_args(&mut rng, &path),
                        invalid,
                        "src/series.rs (data file)",
                    )
                } else if rng.random_range(0..7) == 0 {
                    let (base, path, args, owner): (&str, PathBuf, Vec<String>, &str) =
                        match rng.random_range(skip_config as u32..3) {
                            0 => {
                                let p = fl.dir.join(format!("m{idx}.toml"));
                                (
                                    &study_text,
                                    p.clone(),
                                    vec!["config".into(), "check".into(), p.display().to_string()],
                                    "src/cmd/config.rs (not io-cli's)",
                                )
                            }
                            1 => {
                                let p = fl.dir.join(format!("m{idx}.toml"));
                                let out = fl.dir.join("surf-m").display().to_string();
                                (
                                    SCENE,
                                    p.clone(),
                                    vec![
                                        "surface".into(),
                                        "--scene".into(),
                                        p.display().to_string(),
                                        "--kind".into(),
                                        "jm".into(),
                                        "--m-steps".into(),
                                        "3".into(),
                                        "--out".into(),
                                        out,
                                    ],
                                    "src/cmd/surface.rs + src/detect/scene.rs",
                                )
                            }
                            _ => {
                                let p = fl.dir.join(format!("m{idx}.toml"));
                                (
                                    SCENE,
                                    p.clone(),
                                    vec![
                                        "response".into(),
                                        "--scene".into(),
                                        p.display().to_string(),
                                        "--s".into(),
                                        "1".into(),
                                    ],
                                    "src/cmd/mod.rs",
                                )
                            }
                        };
                    let text = mutate_toml(&mut rng, base);
                    std::fs::write(&path, &text).unwrap();
                    mutated = Some(text);
                    (args, false, owner)
                } else {
                    gen_case(&mut rng, &tpls, &fl)
                };
                let o = run_case(&args, timeout, &fl.dir);
                let mut problems = Vec::new();
                if o.timed_out {
                    problems.push(format!("hang (killed after {} s)", timeout.as_secs()));
                }
                if o.code == Some(101) || o.stderr.contains("panicked") {
                    problems.push(format!(
                        "panic: {}",
                        o.stderr.lines().take(3).collect::<Vec<_>>().join(" | ")
                    ));
                }
                if invalid && o.code == Some(0) {
                    problems.push("exit 0 on invalid input".into());
                }
                if let Err(e) = check_specials(&fl) {
                    problems.push(e);
                }
                {
                    let mut s = stats.lock().unwrap();
                    s[0] += 1;
                    s[1] += (o.code == Some(0)) as usize;
                    s[2] += invalid as usize;
                }
                if !problems.is_empty() {
                    let file = mutated
                        .map(|t| {
                            format!(
                                "\n    with the file:\n{}",
                                t.lines()
                                    .map(|l| format!("      {l}"))
                                    .collect::<Vec<_>>()
                                    .join("\n")
                            )
                        })
                        .unwrap_or_default();
                    failures.lock().unwrap().push(format!(
                        "[{owner}] case {idx}: {}\n    springmass {}{file}",
                        problems.join("; "),
                        quote(&args)
                    ));
                    // restore the special files for the next cases
                    let _ = std::fs::remove_dir_all(&fl.dir);
                    return Some(wk);
                }
                let _ = std::fs::remove_file(fl.dir.join(format!("m{idx}.toml")));
                let _ = std::fs::remove_file(fl.dir.join(format!("m{idx}.csv")));
            }
            None
        }));
    }
    let mut broken_workers = Vec::new();
    for h in handles {
        if let Some(wk) = h.join().expect("fuzz worker panicked") {
            broken_workers.push(wk);
        }
    }
    let s = *stats.lock().unwrap();
    let failures = failures.lock().unwrap();
    eprintln!(
        "fuzz: {} cases (seed {seed}), {} exited 0, {} invalid by construction, {} failures",
        s[0],
        s[1],
        s[2],
        failures.len()
    );
    let _ = std::fs::remove_dir_all(&root);
    assert!(
        failures.is_empty(),
        "{} failing command lines (a worker stops at its first failure; re-run with SPRINGMASS_FUZZ_SEED={seed}):\n{}",
        failures.len(),
        failures.join("\n")
    );
    // the generator must exercise both sides
    assert!(s[0] == cases, "ran {} of {cases} cases", s[0]);
    assert!(s[1] > 0 && s[2] > 0, "degenerate generator: {s:?}");
}
