//! The README (with the guide it links, `docs/GUIDE.md`) and `smile --help` agree: every flag a
//! `smile` command there uses is one its subcommand's `--help` lists, the help's expert examples
//! include the guide's expert command, and `--help` shows the defaults of `--env` and `-o`.

mod common;
use common::{ok, smile};

/// The README and the guide, one after the other.
fn readme() -> String {
    ["README.md", "docs/GUIDE.md"]
        .iter()
        .map(|file| {
            let path = format!("{}/../{file}", env!("CARGO_MANIFEST_DIR"));
            std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"))
        })
        .collect::<Vec<_>>()
        .join("\n")
}

fn help(args: &[&str]) -> String {
    let out = smile(args);
    ok(&out);
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// The README's `smile <sub> ...` commands (code lines and inline commands), as token lists.
fn readme_commands(text: &str) -> Vec<Vec<String>> {
    let mut commands = Vec::new();
    for line in text.lines() {
        for (i, _) in line.match_indices("smile ") {
            let rest = &line[i + "smile ".len()..];
            let end = rest.find(['`', '#', ';']).unwrap_or(rest.len());
            let tokens: Vec<String> = rest[..end].split_whitespace().map(String::from).collect();
            let sub = [
                "expert",
                "demos",
                "train",
                "eval",
                "export",
                "quickstart",
                "bench",
            ];
            if tokens.first().is_some_and(|t| sub.contains(&t.as_str())) {
                commands.push(tokens);
            }
        }
    }
    commands
}

#[test]
fn readme_commands_use_flags_the_help_lists() {
    let text = readme();
    let commands = readme_commands(&text);
    assert!(commands.len() >= 12, "{commands:?}");
    for tokens in &commands {
        let sub = tokens[0].as_str();
        let h = help(&[sub, "--help"]);
        for flag in tokens.iter().filter(|t| t.starts_with("--")) {
            assert!(
                h.contains(&format!("{flag} ")) || h.contains(&format!("{flag}\n")),
                "README: smile {} uses {flag}, which `smile {sub} --help` does not list",
                tokens.join(" ")
            );
        }
    }
    // The README's point-goal expert command is one of the help's examples.
    let expert = help(&["expert", "--help"]);
    let line = "smile expert --env point-goal --total-steps 30000 -o runs/pg-expert";
    assert!(text.contains(line) && expert.contains(line), "{expert}");
    assert!(
        expert.contains("smile expert --env cheetah-vel --horizon 1000"),
        "{expert}"
    );
}

#[test]
fn help_shows_the_defaults_of_env_and_out() {
    let expert = help(&["expert", "--help"]);
    assert!(expert.contains("[default: point-goal"), "{expert}");
    assert!(expert.contains("[default: runs/expert-<env>"), "{expert}");
    // `smile train` takes the family of its demo file unless --env says otherwise.
    let train = help(&["train", "--help"]);
    assert!(train.contains("[default: the demo file's]"), "{train}");
    // `smile eval` too (the policies must then be of it).
    let eval = help(&["eval", "--help"]);
    assert!(eval.contains("the --contexts file's"), "{eval}");
    assert!(eval.contains("[default: eval]"), "{eval}");
    let h = help(&["quickstart", "--help"]);
    assert!(h.contains("[default: point-goal]"), "{h}");
    assert!(h.contains("[default: runs/quickstart]"), "{h}");
}
