//! The `smile` application over the [`trainer`] library: what a user runs, not what learns.
//!
//! * [`quickstart`]: the whole pipeline on point-goal in one call (`smile quickstart`), a
//!   list of steps each calling the library: expert, demos, SMILe + Meta-BC, evaluation,
//!   blob export, the simulated device.
//! * [`sweep`]: grids of runs from a plan (`smile sweep`), locally on every core or as a Slurm
//!   array; each cell trains and evaluates through the library.
//! * [`report`]: mean +- std over seeds of sweeps and evaluations (`smile report`): markdown,
//!   JSON and plots.
//! * [`bench`](mod@bench): timing of the learner's update steps (`smile bench`, and the
//!   criterion benchmarks in `benches/`).
//!
//! The command line itself is the binary (`src/bin/smile/`, one file per subcommand). Every
//! module here uses only `trainer`'s documented public API: the learning library knows
//! nothing of commands, plans or reports.
#![warn(missing_docs)]

pub mod bench;
pub mod device_table;
pub mod progress;
pub mod quickstart;
pub mod report;
pub mod sweep;
