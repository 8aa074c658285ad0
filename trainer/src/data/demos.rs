//! Reading a demo file given as an input of a run, an evaluation or an export: its errors name
//! the input and the path.

use std::path::Path;

use sim::{DemoDataset, Family};

use crate::error::{Error, Input, Result};

/// Reads the demo file given as `input` (any family); errors are [`Error::Input`]s naming it
/// and the path.
pub fn read_demos(path: &Path, input: Input) -> Result<DemoDataset> {
    let at = |e: &dyn std::fmt::Display| {
        Error::input(input, format!("{} {}: {e}", input.noun(), path.display()))
    };
    DemoDataset::read(path).map_err(|e| match e {
        // Its message names the path already.
        sim::DatasetError::Io { source, .. } => at(&source),
        e => at(&e),
    })
}

/// Reads the demo file given as `input`, checking it holds demos of `family`: a mismatch names
/// the file and the family that fits it (an [`Input::Family`] error: choosing the family is
/// the first remedy).
pub fn read_demos_of(path: &Path, input: Input, family: Family) -> Result<DemoDataset> {
    let demos = read_demos(path, input)?;
    if demos.family != family {
        return Err(Error::input(
            Input::Family,
            format!(
                "{} {} hold {} demos, but the family is {family}; choose the family {} or a \
                 file of {family} demos",
                input.noun(),
                path.display(),
                demos.family,
                demos.family
            ),
        ));
    }
    demos
        .ensure_family(family)
        .map_err(|e| Error::input(input, format!("{} {}: {e}", input.noun(), path.display())))?;
    Ok(demos)
}
