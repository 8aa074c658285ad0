//! Sweeps: a plan (TOML) of methods x demo files x config axes x seeds, expanded into one run
//! directory per cell and run locally (`--jobs`, one process per cell) or as a Slurm array.
//! Results are aggregated by `smile report` (the `eval::report` module).

mod local;
mod plan;
mod run;
mod slurm;

pub use local::{Event, Summary, run_local};
pub use plan::{Cell, EvalPlan, Method, Plan, Sweep};
pub use run::{
    BUSY_EXIT, CellOutcome, MANIFEST_FILE, Manifest, ManifestCell, Status, run_cell, status,
    write_manifest,
};
pub use slurm::{SlurmScripts, submit, write_scripts};
