//! The paper's compounding-error argument on one plant: an expert and a meta-policy evaluated
//! under Gaussian action noise of growing sigma, over the family's full episodes.
//!
//! ```sh
//! cargo run --release -p trainer --example compounding -- \
//!   --expert assets/experts/cheetah-vel --policy runs/cv-bc \
//!   --contexts assets/experts/cheetah-vel/demos-test-4x-sub20.safetensors \
//!   --sigmas 0,0.1,0.3 --rollouts 2 -o runs/compounding.json
//! ```
//!
//! For each sigma: the expert's metric on the meta-test tasks (`--rollouts` episodes each, the
//! expert's own evaluation seeds) and the meta-policy's (one-demo contexts, one draw,
//! `--rollouts` episodes per task), as JSON and as a markdown table on stdout.

use std::path::PathBuf;
use std::process::ExitCode;

use serde_json::json;
use sim::{DemoDataset, EnvConfig, Split};
use trainer::MetaPolicy;
use trainer::eval::{self, Protocol};
use trainer::expert::{Expert, evaluate_under_noise};

struct Args {
    expert: PathBuf,
    policy: PathBuf,
    contexts: PathBuf,
    sigmas: Vec<f32>,
    rollouts: usize,
    out: Option<PathBuf>,
}

fn parse() -> Result<Args, String> {
    let mut it = std::env::args().skip(1);
    let (mut expert, mut policy, mut contexts, mut out) = (None, None, None, None);
    let (mut sigmas, mut rollouts) = (vec![0.0, 0.1, 0.3], 2);
    while let Some(flag) = it.next() {
        let value = it.next().ok_or(format!("{flag} needs a value"))?;
        match flag.as_str() {
            "--expert" => expert = Some(PathBuf::from(value)),
            "--policy" => policy = Some(PathBuf::from(value)),
            "--contexts" => contexts = Some(PathBuf::from(value)),
            "-o" | "--out" => out = Some(PathBuf::from(value)),
            "--rollouts" => {
                rollouts = value
                    .parse()
                    .ok()
                    .filter(|&r| r > 0)
                    .ok_or(format!("--rollouts {value}: expected a positive count"))?
            }
            "--sigmas" => {
                sigmas = value
                    .split(',')
                    .map(|s| {
                        s.parse::<f32>()
                            .ok()
                            .filter(|x| x.is_finite() && *x >= 0.0)
                            .ok_or(format!("--sigmas: `{s}` is not a standard deviation"))
                    })
                    .collect::<Result<_, _>>()?
            }
            other => return Err(format!("unknown flag {other}")),
        }
    }
    Ok(Args {
        expert: expert.ok_or("--expert is required")?,
        policy: policy.ok_or("--policy is required")?,
        contexts: contexts.ok_or("--contexts is required")?,
        sigmas,
        rollouts,
        out,
    })
}

fn run(a: &Args) -> trainer::Result<serde_json::Value> {
    trainer::threads::set_compute_threads(1);
    let expert = Expert::load(&a.expert)?;
    let mut policy = MetaPolicy::load(&a.policy)?;
    let contexts = DemoDataset::read(&a.contexts)?;
    let family = expert.family();
    let tasks = family.tasks(Split::Test);
    let mut rows = Vec::new();
    println!("| sigma | expert | meta-policy |\n|---|---|---|");
    for &sigma in &a.sigmas {
        // Each on its own plant: the expert's and the policy's (the same one, or an error).
        let plant = EnvConfig {
            physics: expert.physics(),
            ..EnvConfig::default()
        };
        let e = evaluate_under_noise(&expert, &tasks, a.rollouts, plant, sigma)?;
        let protocol = Protocol {
            context_sizes: vec![1],
            draws: 1,
            rollouts: a.rollouts,
            horizon: None,
            action_noise: sigma,
            run_through_falls: false,
            physics: policy.physics,
        };
        let m = eval::evaluate(
            &mut policy,
            "meta-policy",
            family,
            Split::Test,
            &contexts,
            &protocol,
            &mut |_, _| {},
        )?;
        println!("| {sigma} | {:.3} | {:.3} |", e.mean, m.mean);
        rows.push(
            json!({"sigma": sigma, "expert": e.mean, "expert_per_task": e.per_task,
                         "policy": m.mean, "policy_episode_std": m.episode_std}),
        );
    }
    Ok(json!({
        "family": family.to_string(),
        "expert": a.expert.display().to_string(),
        "policy": a.policy.display().to_string(),
        "rollouts": a.rollouts,
        "rows": rows,
    }))
}

fn main() -> ExitCode {
    let args = match parse() {
        Ok(a) => a,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::from(2);
        }
    };
    match run(&args) {
        Ok(report) => {
            if let Some(out) = &args.out {
                let text = serde_json::to_string_pretty(&report).expect("JSON serialises");
                if let Err(e) = std::fs::write(out, text) {
                    eprintln!("error: writing {}: {e}", out.display());
                    return ExitCode::FAILURE;
                }
            }
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}
