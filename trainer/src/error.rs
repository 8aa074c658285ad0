//! The trainer's one error type.

use std::path::PathBuf;

/// Errors of the trainer library.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// A tensor operation failed inside candle.
    #[error("tensor op: {0}")]
    Candle(#[from] candle_core::Error),
    /// A configuration value is invalid (a config file, a flag, a hyper-parameter).
    #[error("invalid config: {0}")]
    Config(String),
    /// The arguments cannot do what was asked together (a missing input, a budget that does
    /// not fit the family); the message says what to pass instead.
    #[error("{0}")]
    Usage(String),
    /// An input the caller gave cannot serve what was asked. `problem` says why and what
    /// would, in words ("the demos ... hold cheetah-vel demos, but the family is point-goal");
    /// `input` says which input, and an application adds how its user gives it (`smile`: the
    /// flag). The library names no flag.
    #[error("{problem}")]
    Input {
        /// The input at fault.
        input: Input,
        /// What is wrong with it, and what would do.
        problem: String,
    },
    /// The input data do not fit what was asked: demos, contexts, experts or reference returns
    /// that are missing, empty, of another split or family, or inconsistent with each other.
    #[error("{0}")]
    Data(String),
    /// An input is of another task family than the one asked for (demos for the config's
    /// family, an expert among others, a policy for its demos).
    #[error("{what}: family {found}, expected {expected}")]
    WrongFamily {
        /// The input, named for a person (a path, "the demos").
        what: String,
        /// Its family.
        found: sim::Family,
        /// The family it must be.
        expected: sim::Family,
    },
    /// An input was made on another physics backend than the run's (demos recorded on
    /// MuJoCo for a Rapier run, a checkpoint trained on Rapier evaluated on MuJoCo): its
    /// observations mean other things there.
    #[error(
        "{what} was made on the {found} plant, this run simulates {expected}: give one made \
         on {expected}, or run on the {found} plant"
    )]
    WrongPhysics {
        /// The input, named for a person (a path, "the demos").
        what: String,
        /// Its plant.
        found: sim::Physics,
        /// The plant it must be.
        expected: sim::Physics,
    },
    /// A setting was given to an algorithm that has no such setting (SMILe's `gp_weight` to
    /// Meta-BC, say).
    #[error("`{name}` is not a setting of {algo}")]
    NoSuchSetting {
        /// The setting's name ([`Setting::name`](crate::Setting::name)).
        name: &'static str,
        /// Its position in the settings given.
        at: usize,
        /// The algorithm's name.
        algo: &'static str,
    },
    /// A resume would change a setting the run started with: only its budget may change.
    #[error(
        "resuming {} continues the configuration it started with, but `{key}` would change \
         ({was} -> {now}); only the budget may change on a resume: restore {}, or start a new \
         run to change it",
        run.display(),
        run.join("config.toml").display()
    )]
    ResumeChanges {
        /// The run directory.
        run: PathBuf,
        /// The configuration's top-level key that differs.
        key: String,
        /// The positions, in the caller's settings, of those that alone change `key` (none:
        /// the run's `config.toml` was changed).
        given: Box<[usize]>,
        /// Its value in the run.
        was: String,
        /// The value asked for (`missing` if absent).
        now: String,
    },
    /// Training failed part way; the run directory keeps its last good checkpoint, if any.
    #[error(
        "training stopped at {unit} {step}: {source}{}",
        checkpoint.as_ref().map_or(String::new(), |c| format!(
            "; last good checkpoint kept at {}",
            c.display()
        ))
    )]
    Stopped {
        /// The units of work it reached (an expert's env steps, SMILe's update pairs).
        step: u64,
        /// One unit, in words ("env step", "update", "step").
        unit: &'static str,
        /// The checkpoint it can resume from.
        checkpoint: Option<PathBuf>,
        /// Why it stopped.
        source: Box<Error>,
    },
    /// Tensor shapes or dimensions disagree (e.g. a checkpoint for another network size).
    #[error("shape mismatch: {0}")]
    Shape(String),
    /// A loss or statistic became NaN or infinite.
    #[error("non-finite {what} ({value}) at update {update}")]
    NonFinite {
        /// Which quantity diverged, e.g. `losses/qf_loss`.
        what: &'static str,
        /// Its value.
        value: f32,
        /// The update counter at which it happened (1-based).
        update: u64,
    },
    /// A replay buffer cannot serve the request (e.g. sampling from an empty buffer).
    #[error("replay buffer: {0}")]
    Replay(String),
    /// A checkpoint or run directory could not be written or read (missing, truncated,
    /// corrupt, not a checkpoint, or a run directory that already holds a run).
    #[error("checkpoint {}: {reason}", path.display())]
    Checkpoint {
        /// The file or directory concerned.
        path: PathBuf,
        /// What is wrong with it.
        reason: String,
    },
    /// A checkpoint was read, but the state it holds is malformed or does not fit this run
    /// (a missing or mistyped metadata field, weights of another configuration or data).
    #[error("checkpoint {} holds a state this run cannot use: {reason}", path.display())]
    CheckpointState {
        /// The checkpoint file.
        path: PathBuf,
        /// What does not fit.
        reason: String,
    },
    /// A policy comes from a training run that did not finish (killed, or still running).
    #[error(
        "{} is from an unfinished run (stopped at update {updates} of {total}: killed, or still \
         training); finish it by resuming its run {}",
        path.display(),
        run.display()
    )]
    Unfinished {
        /// The policy file.
        path: PathBuf,
        /// Updates done when it was written.
        updates: u64,
        /// The run's budget.
        total: u64,
        /// The run directory that finishes it when resumed.
        run: PathBuf,
    },
    /// Another process is writing the directory.
    #[error(
        "{} is in use by another process (pid {pid}, lock file {}); wait for it to finish or \
         choose another output directory",
        path.display(),
        lock.display()
    )]
    Locked {
        /// The directory.
        path: PathBuf,
        /// Its lock file.
        lock: PathBuf,
        /// The holder's process id, as it wrote it in the lock file (`?` if unreadable).
        pid: String,
    },
    /// An environment error from `sim`.
    #[error("sim: {0}")]
    Sim(#[from] sim::SimError),
    /// A demo dataset could not be read, written or used (from `sim`, its format's owner).
    #[error("dataset: {0}")]
    Dataset(#[from] sim::DatasetError),

    /// A shipped file (listed in its folder's `SHA256SUMS`) that is not the one shipped.
    #[error(transparent)]
    Integrity(#[from] sim::IntegrityError),
    /// An export report (`<blob>.json`) that cannot be read or written.
    #[error("{0}")]
    Report(#[from] sim::ReportError),
    /// infer-core could not write the policy as a blob, refused a blob (corrupt, truncated,
    /// of another version or shape), or could not run it on an input (wrong length,
    /// non-finite).
    #[error("blob: {0}")]
    Blob(#[from] infer_core::Error),
    /// The simulated device (firmware-sim) refused the blob or failed to run it.
    #[error("device: {0}")]
    Device(String),
    /// A report or configuration could not be serialised (JSON, TOML).
    #[error("serialising {what}: {reason}")]
    Serialise {
        /// What was being written.
        what: &'static str,
        /// The serialiser's message.
        reason: String,
    },
    /// A child process (a sweep cell's `smile train` or `smile eval`, `sbatch`) failed.
    #[error("`{command}` failed ({status}); see {}", log.display())]
    Child {
        /// The command line, abbreviated.
        command: String,
        /// Its exit status.
        status: String,
        /// Where its output went.
        log: PathBuf,
    },
    /// The learner's thread pool could not be started (the OS refused a thread).
    #[error("cannot start {threads} learner threads: {reason}")]
    Threads {
        /// Threads asked for.
        threads: usize,
        /// The OS's or rayon's message.
        reason: String,
    },
    /// A file could not be read or written.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file concerned.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
}

/// The inputs an [`Error::Input`] names: what a caller gives the library's runs, evaluations
/// and exports. Each is one option of an application (`smile` renders each as its flag).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum Input {
    /// The demos a run learns from (or a blob is calibrated on).
    Demos,
    /// The held-out demos an evaluation or an export conditions on.
    Contexts,
    /// The split an evaluation runs on.
    Split,
    /// Evaluating on the contexts' own tasks rather than a split's.
    ContextsTasks,
    /// The family.
    Family,
    /// The algorithm.
    Algo,
    /// The expert (a run, a policy file, or a folder of per-task ones).
    Expert,
    /// The base policy of the normalised metric.
    Base,
    /// The checkpoint an expert starts from.
    InitFrom,
    /// Running episodes through falls (the walker authors' evaluation).
    WalkerProtocol,
    /// Where the output goes.
    Output,
    /// Continuing a run rather than starting one.
    Resume,
    /// How many demos each evaluated context holds.
    ContextSizes,
}

impl Input {
    /// The input named for a person, as the library's messages name it ("the demos").
    pub fn noun(self) -> &'static str {
        match self {
            Input::Demos => "the demos",
            Input::Contexts => "the contexts",
            Input::Split => "the split",
            Input::ContextsTasks => "the contexts' own tasks",
            Input::Family => "the family",
            Input::Algo => "the algorithm",
            Input::Expert => "the expert",
            Input::Base => "the base",
            Input::InitFrom => "the starting checkpoint",
            Input::WalkerProtocol => "the walker authors' protocol",
            Input::Output => "the output",
            Input::Resume => "resuming",
            Input::ContextSizes => "the context sizes",
        }
    }
}

impl Error {
    /// An I/O failure on `path`, as `map_err` takes it: `.map_err(Error::io(&path))`.
    pub(crate) fn io(path: &std::path::Path) -> impl Fn(std::io::Error) -> Error + Copy + '_ {
        move |source| Error::Io {
            path: path.to_path_buf(),
            source,
        }
    }

    /// An [`Error::Input`].
    pub fn input(input: Input, problem: impl Into<String>) -> Self {
        Error::Input {
            input,
            problem: problem.into(),
        }
    }

    /// An expert given to `algo`, a learner of the demos alone: refused, not ignored (by the
    /// run driver before it loads one, naming its path, and by the learner's own start).
    pub(crate) fn takes_no_expert(algo: &str, expert: Option<&std::path::Path>) -> Self {
        let given = expert.map_or("an expert".into(), |p| {
            format!("the expert {}", p.display())
        });
        let problem = format!(
            "{algo} learns from the demos alone: {given} would relabel Meta-DAgger's rollouts \
             (drop it, or train meta-dagger)"
        );
        Error::input(Input::Expert, problem)
    }

    /// The one plant check: an input made on the `found` plant serves a run on `expected` only
    /// when they are the same (its observations mean other things on another plant); `what`
    /// names the input for a person.
    pub(crate) fn same_plant(
        what: impl FnOnce() -> String,
        found: sim::Physics,
        expected: sim::Physics,
    ) -> Result<()> {
        if found == expected {
            return Ok(());
        }
        Err(Error::WrongPhysics {
            what: what(),
            found,
            expected,
        })
    }
}

/// Result alias of the trainer library.
pub type Result<T, E = Error> = std::result::Result<T, E>;
