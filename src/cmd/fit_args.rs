//! The arguments of `springmass fit` and what the data-first, modal and
//! ambient fits read from them alike (the chain's size, the baseline).

use clap::Args as ClapArgs;
use std::path::PathBuf;

/// Arguments of `springmass fit`.
#[derive(ClapArgs, Debug)]
#[command(group = clap::ArgGroup::new("input").args(["data", "modes"]).multiple(false))]
#[command(
    after_help = "Data-first: springmass fit --data x1.csv --n 37 [--d 0.05 | --fit d,gamma] \
[--defects auto|K] [--kinds mass|spring|damper|ground|any] [--noise auto|SIGMA] [--misfit time|bromwich|real-axis] \
[--method NAME] [--left fixed|free] [--right fixed|free] \
[--observe-kind displacement|velocity|acceleration] [--force-column f | --force force.csv] \
[--plot fit.svg] [--out-csv fit.csv] [--json]\n\
Scene file: springmass fit --scene configs/scenes/table1-system3.toml (its [chain] defects are the truth that synthesises the data)."
)]
pub struct Args {
    /// A measured series: CSV with a time column `t` and one or more value
    /// columns. Repeat for several records of the same chain (several hammer
    /// hits, each with its own times, impulse or --force-column): one joint
    /// fit, a noise level per record, and a record the answer does not
    /// explain is named.
    #[arg(long, conflicts_with = "scene", action = clap::ArgAction::Append)]
    pub data: Vec<PathBuf>,
    /// Measured modes instead of a series: CSV, one row per mode, columns
    /// frequency (Hz), optional frequency_se, damping (ratio), damping_se,
    /// phi_J (shape at mass J) and phi_J_se; the storey springs (or masses,
    /// --profile) are updated as factors of the nominal chain (--n, --mass,
    /// --k, --left, --right, --baseline), or with --defects the changed ones
    /// are found (--kinds spring|mass|damper|any, or a comma list; by
    /// default spring, and damper too when the ratios are fitted). With a
    /// damped nominal chain (--damping, --d) the damping ratios are fitted.
    #[arg(long, conflicts_with_all = ["scene", "column", "gamma", "fit", "known",
        "noise", "misfit", "criterion", "max_evals", "trigger", "force_window", "noise_model",
        "nuisance", "observe", "observe_kind", "force_column", "force", "plot", "out_csv",
        "profile_change", "penalty", "method", "trace", "level"])]
    pub modes: Option<PathBuf>,
    /// Modes of --modes (1-based, increasing frequency) kept out of the fit
    /// and only predicted, e.g. 3,4.
    #[arg(long, requires = "modes", value_name = "J,...")]
    pub hold_out: Option<String>,
    /// Random starts of the modal update beside the nominal one [default: 20].
    #[arg(long, requires = "modes")]
    pub starts: Option<usize>,
    /// How --modes are compared with the chain: property (the modal-property
    /// difference: frequencies and MAC-paired shapes) or dynamic (the modal
    /// dynamic residual: the equations of motion at the measured
    /// frequencies, the unmeasured shape components profiled out)
    /// [default: property].
    #[arg(long, requires = "modes", value_name = "property|dynamic")]
    pub modal_residual: Option<String>,
    /// The column of --data to fit [default: the first after t]; with
    /// several --observe masses one column per mass, in order: a,b,c
    /// [default: the value columns in order, the force column left out].
    #[arg(long, requires = "data")]
    pub column: Option<String>,
    /// Number of masses of the chain (--data, --modes).
    #[arg(long, requires = "input")]
    pub n: Option<usize>,
    /// Uniform damping (known, or the starting value with --fit d) [default: 0.1].
    #[arg(long, requires = "input", allow_negative_numbers = true)]
    pub d: Option<f64>,
    /// Uniform stiffness, in the data's units (N/m for SI data) [default: 1].
    #[arg(long, requires = "input", allow_negative_numbers = true)]
    pub k: Option<f64>,
    /// Uniform mass, in the data's units (kg for SI data) [default: 1].
    #[arg(long, requires = "input", allow_negative_numbers = true)]
    pub mass: Option<f64>,
    /// Impulse on mass 1 [default: 1].
    #[arg(long, requires = "data", allow_negative_numbers = true)]
    pub gamma: Option<f64>,
    /// Chain parameters fitted too: a comma-separated subset of d,gamma,k,mass.
    #[arg(long, requires = "data")]
    pub fit: Option<String>,
    /// A known defect `kind:at:value` (repeatable).
    #[arg(long = "known", value_name = "KIND:AT:VALUE", requires = "data")]
    pub known: Vec<String>,
    /// Number of defects: auto (0..=4 by the criterion; with --modes 0..=2
    /// over every set, then one more at a time, nested in the best answers
    /// at one fewer, while it wins; output-only records 0..=2), auto:KMAX,
    /// or K [default: auto].
    #[arg(long, requires = "data")]
    pub defects: Option<String>,
    /// Kinds of defect sought: mass, spring, damper, ground (a spring to the
    /// ground) or any (mass, spring or damper) [default: any; mass with
    /// another --method than enumerate, and in chains too long to
    /// enumerate every kind (the search is then greedy, as it is for 3
    /// defects or more told in a chain of 40 masses or more)].
    #[arg(long, requires = "data")]
    pub kinds: Option<String>,
    /// Noise standard deviation of the samples: auto (estimated) or SIGMA [default: auto].
    /// With --scene: the synthetic data's noise level.
    #[arg(long, allow_hyphen_values = true)]
    pub noise: Option<String>,
    /// time, bromwich or real-axis [default: time].
    #[arg(long, requires = "data")]
    pub misfit: Option<String>,
    /// Criterion of --defects auto: bic, aic, chi2 or chi2:ALPHA [default: bic].
    #[arg(long, requires = "data")]
    pub criterion: Option<String>,
    /// Evaluation budget of the stochastic searches [default: 20000].
    #[arg(long)]
    pub max_evals: Option<usize>,
    /// When the blow came, on the record's time axis: auto (detected from a
    /// quiet pre-trigger segment, a late clock, or a displacement record
    /// that starts away from rest, cut short after the blow; then fitted
    /// with its standard error) or a time [default: auto; a record that
    /// starts with the blow is fitted as it is].
    #[arg(long, requires = "data", allow_hyphen_values = true)]
    pub trigger: Option<String>,
    /// The window of a measured force (--force-column, --force): auto (the
    /// detected pulse; the sensor's noise elsewhere set to zero, as a modal
    /// test does), none, or T0:T1 on the record's axis [default: auto].
    #[arg(long, allow_hyphen_values = true)]
    pub force_window: Option<String>,
    /// Noise model of the record (time misfit): auto (white unless the white
    /// fit's residual fails the Ljung-Box test and AR(p), p <= 8, wins by BIC),
    /// white, ar (order by BIC) or ar:P [default: auto].
    #[arg(long, requires = "data")]
    pub noise_model: Option<String>,
    /// Sensor offset and linear drift, profiled out of the time misfit: auto
    /// (fitted when the white fit's residual is not white and BIC wants them),
    /// none, offset or offset+drift [default: auto].
    #[arg(long, requires = "data")]
    pub nuisance: Option<String>,
    /// A measured profile the defects sit on: a CSV with one row per mass,
    /// columns mass, spring (to the mass before; empty for a free left
    /// end) and optionally damper, and a last row with only the right
    /// wall's spring when that end is fixed. Gives n and the ends (--n,
    /// --left, --right must agree); defects are reported relative to it
    /// (with --modes: the nominal chain the factors multiply).
    #[arg(long, requires = "input", value_name = "FILE")]
    pub baseline: Option<PathBuf>,
    /// Left end (mass 1's side): fixed (a wall spring) or free [default: fixed].
    #[arg(long, requires = "input")]
    pub left: Option<String>,
    /// Right end (mass n's side): fixed or free [default: fixed].
    #[arg(long, requires = "input")]
    pub right: Option<String>,
    /// The observed mass (1-based) [default: 1]; several masses, one value
    /// column each (--column), are fitted jointly, each sensor's noise
    /// level estimated: 1,30,60 (with --excitation ambient: the channels).
    #[arg(long, requires = "data", value_delimiter = ',')]
    pub observe: Vec<usize>,
    /// What the column measured: displacement, velocity or acceleration [default: displacement]; with several --observe masses one kind for all or one per mass: displacement,acceleration,acceleration.
    #[arg(long, requires = "data")]
    pub observe_kind: Option<String>,
    /// The excitation of --data: impulse (or a measured force, --force) by
    /// default; `ambient`: an unknown broadband force (output-only), the
    /// channels' Welch cross-spectral matrix fitted (--observe a list).
    #[arg(long, requires = "data", value_name = "ambient")]
    pub excitation: Option<String>,
    /// With --excitation ambient: the masses the white forces act on
    /// [default: every mass].
    #[arg(long, requires = "excitation", value_delimiter = ',')]
    pub ambient_on: Vec<usize>,
    /// With --excitation ambient: band-limited forces, a flat spectrum of the
    /// fitted level over LO:HI (angular frequencies, rad per unit of the
    /// record's time, as the report's band) and none outside [default: white].
    #[arg(
        long,
        requires = "excitation",
        value_name = "LO:HI",
        allow_hyphen_values = true
    )]
    pub ambient_band: Option<String>,
    /// A measured force on mass 1 instead of the impulse: this column of --data
    /// (with --force FILE: of that file) [hammer test].
    #[arg(long, requires = "data")]
    pub force_column: Option<String>,
    /// A measured force on mass 1 instead of the impulse: a CSV with the same
    /// times as --data (its first value column, or --force-column).
    #[arg(long, requires = "data")]
    pub force: Option<PathBuf>,
    /// Draw data, model and residual to this SVG (--data; with a profile,
    /// the profile, also for --scene).
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Draw the probability of a defect at each site along the chain to
    /// this SVG (--data).
    #[arg(long, requires = "data", value_name = "SVG")]
    pub plot_posterior: Option<PathBuf>,
    /// Level of the intervals of every fitted value, 0 < LEVEL < 1
    /// [default: 0.9].
    #[arg(long, requires = "data")]
    pub level: Option<f64>,
    /// Prior over the number of defects for the hypotheses' probabilities:
    /// uniform (every count searched equally probable, positions uniform
    /// given it) or site:P (every site defective with probability P)
    /// [default: uniform].
    #[arg(long, requires = "data", value_name = "uniform|site:P")]
    pub prior_k: Option<String>,
    /// Prior range of a defect's value, LO:HI times the value it replaces
    /// [default: the search range of its kind].
    #[arg(long, requires = "data", value_name = "LO:HI")]
    pub prior_range: Option<String>,
    /// Leave out the intervals and the hypotheses' probabilities (faster).
    #[arg(long, requires = "data")]
    pub no_uncertainty: bool,
    /// With --defects auto, search every position (and kind) set at every
    /// number of defects. By default the search at 3 defects and more is
    /// nested in the best answers at one defect fewer, and --kinds any
    /// tries at each position the kinds the data point to (much faster;
    /// the report then says `exhaustive: false`), and a chain whose sets
    /// pass 200 000 (from n = 48 with up to four defects) is searched
    /// greedily; with --exhaustive it is enumerated, or refused at once
    /// with the count of its sets (ask for fewer: --defects auto:3). With
    /// --scene: rank every
    /// position set (`search.exhaustive`; by default, from 3 defects on
    /// chains of 40 masses or more, a greedy answer whose residual is at
    /// the data's error floor is kept without enumerating: `certified`).
    #[arg(long)]
    pub exhaustive: bool,
    /// Speed against accuracy of the search: low (fewer time-domain
    /// refits; with --defects auto, searches from 3 defects nested in 4
    /// answers at one fewer, not 8, and k raised while one more defect
    /// helps), normal, or high (every shortlisted set refitted; with
    /// --defects auto, every set at every number of defects up to the
    /// largest where there are at most 200 000; with --fit d and no
    /// --damping, every damping model searched, not only until one
    /// explains the record) [default: normal].
    #[arg(long, requires = "data", value_name = "LEVEL", value_parser = ["low", "normal", "high"])]
    pub effort: Option<String>,
    /// Write t, observed, model, residual to this CSV (--data; with a
    /// profile, the profile's values, also for --scene).
    #[arg(long)]
    pub out_csv: Option<PathBuf>,
    /// Whole-profile inversion instead of a defect search: every mass,
    /// every spring, or both free (masses|springs|both), with standard
    /// errors and the depth the data can see (--data, or --scene, whose
    /// [profile] table it overrides).
    #[arg(long, conflicts_with_all = ["defects", "kinds", "method", "criterion", "known"])]
    pub profile: Option<String>,
    /// The relative change the profile's visibility is stated for: a value
    /// is visible when the data show such a change at 2 standard errors [default: 0.1].
    #[arg(long, requires = "profile", allow_negative_numbers = true)]
    pub profile_change: Option<f64>,
    /// A fixed penalty weight for --profile instead of the continuation to
    /// the noise level (> 0).
    #[arg(long, requires = "profile", allow_negative_numbers = true)]
    pub penalty: Option<f64>,
    /// The fit scene (TOML with [chain], [data], [unknowns], [misfit], [search]).
    #[arg(long)]
    pub scene: Option<PathBuf>,
    /// The search over positions (the names of `springmass::detect::search::SEARCHES`).
    #[arg(long, long_help = springmass::detect::search::registry::cli_help())]
    pub method: Option<String>,
    /// Seed of stochastic methods.
    #[arg(long)]
    pub seed: Option<u64>,
    /// Record and print the optimizer's trace (--scene).
    #[arg(long)]
    pub trace: bool,
    /// Print the report as JSON.
    #[arg(long)]
    pub json: bool,
    /// Worker threads, 1 to 1024 [default: RAYON_NUM_THREADS, else the number of cores]. Small fits run on one; results do not depend on it.
    #[arg(long)]
    pub threads: Option<usize>,
    /// Damping model: grounded (a damper from every mass to the ground, the
    /// paper's), between[:C] (dampers parallel to the springs, as between
    /// storeys), rayleigh[:A:B] (C = A M + B K), modal[:ZETA] (one damping
    /// ratio for every mode) or modal:Z1,Z2,.. (a ratio per mode, the last
    /// for every higher mode; with --fit d these are the starting values of
    /// the fitted ratios). Parameters not given are fitted with --fit d.
    /// Default: grounded; with --fit d the models are searched cheapest
    /// first until one explains the record, the others fitted at its
    /// defects, and BIC chooses (--effort high searches every model). --d
    /// is then the extra grounded damping (default 0).
    #[arg(long, requires = "input", value_name = "MODEL[:P1[:P2]]")]
    pub damping: Option<String>,
}

/// The number of masses: `--n`, or the row count of `--baseline`.
pub(super) fn chain_size(a: &Args) -> anyhow::Result<usize> {
    Ok(match (a.n, &a.baseline) {
        (Some(n), _) => n,
        (None, Some(b)) => springmass::chain::Baseline::read_csv(b)?.n(),
        (None, None) => Err(springmass::Error::invalid(
            "n",
            "(none)",
            "--n N, the number of masses of the chain (or --baseline FILE)",
        ))?,
    })
}

/// `--baseline FILE` as the fit options take it.
pub(super) fn baseline_spec(a: &Args) -> Option<springmass::chain::BaselineSpec> {
    a.baseline
        .as_ref()
        .map(|p| springmass::chain::BaselineSpec::Path(p.display().to_string()))
}
