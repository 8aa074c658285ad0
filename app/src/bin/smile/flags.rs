//! The library's errors as `smile` says them: the library names an input in words
//! (`trainer::Error::Input`), and here it gets the flag that gives it.

/// `e` with the flag (or the command) that fixes it, when an error down its chain names an
/// input.
pub fn render(e: anyhow::Error) -> anyhow::Error {
    match e.chain().find_map(hint) {
        Some(hint) => anyhow::anyhow!("{} {hint}", sim::error_line(&*e)),
        None => e,
    }
}

/// What `smile` adds to one error of the chain.
fn hint(cause: &(dyn std::error::Error + 'static)) -> Option<String> {
    if let Some(sim::DatasetError::PhysicsMismatch { found, .. }) = cause.downcast_ref() {
        return Some(format!("(--physics {found} runs on its plant)"));
    }
    if let Some(sim::SimError::PhysicsUnavailable { .. }) = cause.downcast_ref() {
        return Some("(--physics)".into());
    }
    Some(match cause.downcast_ref::<trainer::Error>()? {
        trainer::Error::Input { input, .. } => format!("({})", flag(*input)?),
        trainer::Error::WrongPhysics { found, .. } => format!("(--physics {found})"),
        trainer::Error::Unfinished { run, .. } => format!(
            "(smile train --resume -o {} --demos DEMOS; --allow-unfinished uses it as it is)",
            run.display()
        ),
        _ => return None,
    })
}

/// The flag that gives `input`.
fn flag(input: trainer::Input) -> Option<&'static str> {
    use trainer::Input;
    Some(match input {
        Input::Demos => "--demos",
        Input::Contexts => "--contexts",
        Input::Split => "--split",
        Input::ContextsTasks => "--contexts-tasks",
        Input::Family => "--env",
        Input::Algo => "--algo",
        Input::Expert => "--expert",
        Input::Base => "--base",
        Input::InitFrom => "--init-from",
        Input::WalkerProtocol => "--walker-protocol",
        Input::Output => "-o",
        Input::Resume => "--resume",
        Input::ContextSizes => "--context-sizes",
        _ => return None,
    })
}
