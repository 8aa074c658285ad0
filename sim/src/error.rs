//! Typed errors of the environments. A family is named here by its name, not its handle: the
//! error sits below the family interface (`family.rs`), whose environments return it.

/// A command-line tool's exit: success, or the error as one `error:` line on stderr (the full
/// chain and a backtrace only when `RUST_BACKTRACE` asks for them) and exit status 1.
pub fn exit_code<E>(result: Result<(), E>) -> std::process::ExitCode
where
    E: AsRef<dyn std::error::Error> + std::fmt::Debug,
{
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {}", error_line(e.as_ref()));
            if std::env::var_os("RUST_BACKTRACE").is_some_and(|v| v != "0") {
                eprintln!("\n{e:?}");
            }
            std::process::ExitCode::FAILURE
        }
    }
}

/// One line for an error, as the command-line tools (`smile`, `firmware-sim`) print it:
/// `<top message>: <root cause>`, the root left out when the top already says it (the OS
/// error is not repeated down a "Caused by" chain).
pub fn error_line(e: &(dyn std::error::Error + 'static)) -> String {
    let top = e.to_string();
    let mut root = e;
    while let Some(next) = root.source() {
        root = next;
    }
    let root = root.to_string();
    if top.contains(&root) {
        top
    } else {
        format!("{top}: {root}")
    }
}

/// Everything that can go wrong while building, resetting or stepping an environment.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SimError {
    /// The action slice does not have the environment's action dimension.
    #[error("action has {got} components, the {family} environment expects {expected}")]
    ActionLength {
        /// Family of the environment that rejected the action.
        family: &'static str,
        /// The environment's action dimension.
        expected: usize,
        /// Length of the action that was passed.
        got: usize,
    },
    /// An action component is NaN or infinite; it never reaches the physics.
    #[error("action component {index} is not finite ({value})")]
    NonFiniteAction {
        /// Index of the offending component.
        index: usize,
        /// Its value.
        value: f32,
    },
    /// A task of one family was given to an environment of another family.
    #[error("a {task_family} task was given to a {env_family} environment")]
    TaskFamilyMismatch {
        /// Family of the environment.
        env_family: &'static str,
        /// Family of the task.
        task_family: &'static str,
    },
    /// `step` was called after the episode ended (terminated or reached its horizon).
    #[error("the episode ended at step {step}; call reset before stepping again")]
    EpisodeOver {
        /// Number of steps the episode lasted.
        step: usize,
    },
    /// A caller-provided output buffer has the wrong length.
    #[error("output buffer has length {got}, expected {expected}")]
    BufferLength {
        /// Required length.
        expected: usize,
        /// Provided length.
        got: usize,
    },
    /// A task family name that is not one of the known ones (built in or registered).
    #[error("unknown task family {name:?}; expected one of {known}")]
    UnknownFamily {
        /// The name asked for.
        name: String,
        /// The names known: the built-in families, then the registered ones.
        known: String,
    },
    /// A family that cannot be registered under its name ([`crate::Family::register`]): the
    /// name is another family's, or not a CLI word.
    #[error("cannot register the task family {name:?}: {reason}")]
    FamilyNameRefused {
        /// The family's name.
        name: String,
        /// Why: the name is taken, or not a CLI word.
        reason: &'static str,
    },
    /// An episode-length override of zero steps (every command's `horizon` reaches the plant
    /// through [`make_env`](crate::make_env), which refuses it).
    #[error("horizon must be at least 1 step (leave it out for the family's own), not 0")]
    ZeroHorizon,
    /// A split name that is neither `train` nor `test`.
    #[error("unknown split {0:?}; expected train or test")]
    UnknownSplit(String),
    /// A task parameter that is out of range or not finite.
    #[error("invalid task parameter for {family}: {reason}")]
    InvalidTask {
        /// Family the parameter was meant for.
        family: &'static str,
        /// What is wrong with it.
        reason: String,
    },
    /// No task of a list is within the family's tolerance of a value
    /// ([`Family::find_task`](crate::Family::find_task)).
    #[error("{}", no_task_near(family, value_name, *value, *tolerance, available))]
    NoTaskNear {
        /// Family of the tasks searched.
        family: &'static str,
        /// What a task value of that family is (`goal angle (rad)`, ...).
        value_name: &'static str,
        /// The value asked for.
        value: f64,
        /// The family's tolerance ([`Family::value_tolerance`](crate::Family::value_tolerance)).
        tolerance: f64,
        /// The values of the tasks searched, as their labels print them.
        available: String,
    },
    /// The simulated state became non-finite (the physics diverged).
    #[error("the {family} physics diverged at step {step} (non-finite state)")]
    PhysicsDiverged {
        /// Family of the environment.
        family: &'static str,
        /// Step at which the state became non-finite.
        step: usize,
    },
    /// A physics backend name that is neither `rapier` nor `mujoco`.
    #[error("unknown physics {0:?}; expected rapier or mujoco")]
    UnknownPhysics(String),
    /// The backend asked for is not in this build, or its library could not be used.
    #[error("the {physics} physics is not available: {how}")]
    PhysicsUnavailable {
        /// The backend asked for.
        physics: crate::kinds::Physics,
        /// Why, and how to get it.
        how: String,
    },
}

fn no_task_near(
    family: &str,
    value_name: &str,
    value: f64,
    tolerance: f64,
    available: &str,
) -> String {
    let how = if tolerance > 0.0 {
        format!("within {tolerance} of")
    } else {
        "equal to".into()
    };
    format!("no {family} task has a {value_name} {how} {value}; available: {available}")
}
