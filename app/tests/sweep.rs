//! `smile sweep` and `smile report` as a user runs them: bad plans refused before anything runs
//! (naming the plan line), a local sweep that survives kill -9 of the runner and all its cells
//! with results byte-identical to an uninterrupted sweep, and (with `--ignored`, run by .ci/run
//! after tests/slurm/start.sh) a real Slurm array.

mod common;
use common::{ok, smile};

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

use sim::{Family, Split};

fn tmp(name: &str) -> PathBuf {
    common::fresh_dir("smile-sweep", name)
}

/// Point-goal PD demos (train: 8 tasks x 2, test: all 16 x 1) and a plan over them in `dir`.
fn setup(dir: &Path, plan: &str) -> PathBuf {
    let fam = Family::POINT_GOAL;
    common::pd_demos(Split::Train, fam.train_tasks()[..8].to_vec(), 2, 20)
        .write(dir.join("train.safetensors"))
        .unwrap();
    common::pd_demos(Split::Test, fam.test_tasks(), 1, 20)
        .write(dir.join("test.safetensors"))
        .unwrap();
    let path = dir.join("plan.toml");
    std::fs::write(&path, plan).unwrap();
    path
}

const PLAN: &str = r#"env = "point-goal"
out = "OUT"
demos = ["train.safetensors"]
seeds = [0, 1]

[algo.smile]
set = { total_updates = 600, eval_every = 200, checkpoint_every = 100, disc_hidden = [16, 16], sac = { hidden = [16, 16] } }

[eval]
contexts = "test.safetensors"
rollouts = 2
"#;

fn plan_with_out(out: &Path) -> String {
    PLAN.replace("OUT", out.to_str().unwrap())
}

#[test]
fn bad_plans_are_refused_before_anything_runs() {
    let dir = tmp("bad");
    let out = dir.join("out");
    let good = plan_with_out(&out);
    setup(&dir, &good);
    let cases = [
        (
            good.replace("seeds = [0, 1]", "seeds = []"),
            "(line 4): the axis `seeds` is empty",
        ),
        (
            good.replace("seeds = [0, 1]", "seeds = [0, 0]"),
            "are the same training",
        ),
        (
            good.replace("total_updates = 600", "total_updatez = 600"),
            "(line 7): [algo.smile]: unknown field `total_updatez`",
        ),
        (
            good.replace("\"test.safetensors\"", "\"missing.safetensors\""),
            "(line 10): contexts file",
        ),
        (
            // A header comment that quotes the file does not take the line number.
            format!("# made with: smile demos -o missing.safetensors\n{good}")
                .replace("\"test.safetensors\"", "\"missing.safetensors\""),
            "(line 11): contexts file",
        ),
        (
            good.replace("rollouts = 2", "rollouts = 2\nbogus = 1"),
            "unknown field `bogus`",
        ),
        (
            good.replace("[algo.smile]", "[algo.smile]\nalgo = \"smiley\""),
            "unknown algo \"smiley\"",
        ),
        (
            good.replace(
                "[algo.smile]",
                "[algo.smile]\nexpert = \"train.safetensors\"",
            ),
            "smile takes no `expert`",
        ),
        (
            good.replace("[algo.smile]", "[algo.smile]\nalgo = \"smile-state-only\"")
                .replace(
                    "total_updates = 600,",
                    "total_updates = 600, bc_weight = 1.0,",
                ),
            "the state-only variant has none",
        ),
        (
            good.replace("rollouts = 2", "rollouts = 2\nbase = \"b\""),
            "`base` and `experts` go together",
        ),
        (
            good.replace(
                "rollouts = 2",
                "rollouts = 2\nbase = \"b\"\nexperts = [\"e\"]",
            ),
            "point-goal has none",
        ),
    ];
    for (plan, want) in cases {
        let p = dir.join("bad.toml");
        std::fs::write(&p, &plan).unwrap();
        let o = smile(&["sweep", p.to_str().unwrap(), "--jobs", "1"]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "accepted:\n{plan}");
        assert!(err.contains(want), "want {want:?} in: {err}");
        assert!(
            !out.exists(),
            "{} was created for a refused plan",
            out.display()
        );
    }
    // Missing data passes only the unchecked load; a missing config never does.
    let p = dir.join("bad.toml");
    let no_data = good.replace("\"test.safetensors\"", "\"missing.safetensors\"");
    std::fs::write(&p, no_data).unwrap();
    assert!(smile_app::sweep::Sweep::load(&p).is_err());
    assert!(smile_app::sweep::Sweep::load_unchecked(&p).is_ok());
    let no_config = good.replace("[algo.smile]", "[algo.smile]\nconfig = \"nope.toml\"");
    std::fs::write(&p, no_config).unwrap();
    let e = smile_app::sweep::Sweep::load_unchecked(&p).unwrap_err();
    assert!(e.to_string().contains("config file"), "{e}");
    std::fs::remove_dir_all(&dir).ok();
}

/// `root` and all its descendants (from /proc), parents first.
fn process_tree(root: u32) -> Vec<u32> {
    let mut parent_of = Vec::new();
    for entry in std::fs::read_dir("/proc").unwrap().flatten() {
        let Ok(pid) = entry.file_name().to_string_lossy().parse::<u32>() else {
            continue;
        };
        let Ok(stat) = std::fs::read_to_string(entry.path().join("stat")) else {
            continue;
        };
        // pid (comm) state ppid ...: comm may hold spaces, so split after the last ')'.
        let rest = &stat[stat.rfind(')').map_or(0, |i| i + 1)..];
        if let Some(ppid) = rest
            .split_whitespace()
            .nth(1)
            .and_then(|s| s.parse::<u32>().ok())
        {
            parent_of.push((pid, ppid));
        }
    }
    let mut tree = vec![root];
    let mut i = 0;
    while i < tree.len() {
        let p = tree[i];
        tree.extend(parent_of.iter().filter(|(_, pp)| *pp == p).map(|(c, _)| *c));
        i += 1;
    }
    tree
}

/// Each cell's status in the sweep directory's manifest, in cell order.
fn manifest_status(sweep: &Path) -> Vec<String> {
    let manifest: serde_json::Value =
        serde_json::from_slice(&bytes(&sweep.join("manifest.json"))).unwrap();
    manifest["cells"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c["status"].as_str().unwrap().to_string())
        .collect()
}

fn bytes(p: &Path) -> Vec<u8> {
    std::fs::read(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

#[test]
fn a_killed_local_sweep_resumes_to_the_same_results() {
    let dir = tmp("kill");
    let (a, b) = (dir.join("a"), dir.join("b"));
    let plan_a = setup(&dir, &plan_with_out(&a));
    let plan_b = dir.join("plan-b.toml");
    std::fs::write(&plan_b, plan_with_out(&b)).unwrap();

    // Reference: uninterrupted.
    ok(&smile(&[
        "sweep",
        plan_a.to_str().unwrap(),
        "--jobs",
        "2",
        "--quiet",
    ]));

    // Interrupted: kill -9 the runner and its cells (one process group) once a cell has a
    // checkpoint, then run the sweep again.
    let mut child = Command::new(env!("CARGO_BIN_EXE_smile"))
        .args(["sweep", plan_b.to_str().unwrap(), "--jobs", "2", "--quiet"])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let ckpt = b.join("smile-s0/train/checkpoint.safetensors");
    let t0 = Instant::now();
    while !ckpt.exists() {
        assert!(
            t0.elapsed() < Duration::from_secs(60),
            "no checkpoint appeared"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    // kill -9 of the runner and every process below it, each by its own (positive) pid.
    let tree = process_tree(child.id());
    assert!(
        tree.len() >= 2,
        "expected the runner and its cells, got {tree:?}"
    );
    for pid in &tree {
        let _ = Command::new("kill")
            .args(["-KILL", &pid.to_string()])
            .status();
    }
    let _ = child.wait();
    // SIGKILL lands asynchronously: a cell process still running (on a busy machine) holds its
    // cell's lock, and the new runner would rightly leave that cell to it. Wait until every
    // killed process is gone or a zombie (its files, the lock among them, closed).
    for pid in &tree {
        let t0 = Instant::now();
        while std::fs::read_to_string(format!("/proc/{pid}/stat")).is_ok_and(|st| {
            st[st.rfind(')').map_or(0, |i| i + 1)..]
                .split_whitespace()
                .next()
                != Some("Z")
        }) {
            assert!(
                t0.elapsed() < Duration::from_secs(30),
                "pid {pid} survived kill -9"
            );
            std::thread::sleep(Duration::from_millis(10));
        }
    }
    assert!(
        !b.join("smile-s0/eval/eval.json").exists(),
        "killed too late: the cell had finished"
    );
    let err = ok(&smile(&["sweep", plan_b.to_str().unwrap(), "--jobs", "2"]));
    assert!(err.contains("2 of 2 cells done"), "{err}");

    for cell in ["smile-s0", "smile-s1"] {
        for f in [
            "train/meta_policy.safetensors",
            "train/checkpoint.safetensors",
            "eval/eval.json",
        ] {
            assert!(
                bytes(&a.join(cell).join(f)) == bytes(&b.join(cell).join(f)),
                "{cell}/{f} differs after kill -9 and resume"
            );
        }
    }
    assert_eq!(manifest_status(&b), ["done", "done"]);

    // `smile report` on the sweep directory: one row over both seeds.
    let rep = dir.join("report");
    ok(&smile(&[
        "report",
        b.to_str().unwrap(),
        "-o",
        rep.to_str().unwrap(),
    ]));
    let json: serde_json::Value = serde_json::from_slice(&bytes(&rep.join("report.json"))).unwrap();
    let row = &json["rows"][0];
    assert_eq!(row["seeds"].as_array().unwrap().len(), 2);
    let per_seed: Vec<f64> = row["per_seed"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    let mean = (per_seed[0] + per_seed[1]) / 2.0;
    assert!((row["mean"].as_f64().unwrap() - mean).abs() < 1e-5);
    assert!(
        std::fs::read_to_string(rep.join("tasks.svg"))
            .unwrap()
            .contains("<svg")
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// Issue 27, item 2: an edited plan trains again what changed (the old cell kept aside),
/// manifest and cell.toml agree; two demo files of one name get two cells; an evaluation
/// that is not there, or unreadable, is named by `smile report`, not silently dropped.
#[test]
fn an_edited_plan_reruns_what_changed_and_nothing_collides() {
    let dir = tmp("edited");
    let out = dir.join("out");
    setup(&dir, "");
    std::fs::create_dir_all(dir.join("other")).unwrap();
    common::pd_demos(
        Split::Train,
        Family::POINT_GOAL.train_tasks()[..8].to_vec(),
        3,
        20,
    )
    .write(dir.join("other/train.safetensors"))
    .unwrap();
    let plan = |steps: u32, demos: &str| {
        format!(
            r#"env = "point-goal"
out = "{}"
demos = [{demos}]
seeds = [0]

[algo.meta-bc]
set = {{ total_steps = {steps}, eval_every = 50, policy_hidden = [8, 8] }}

[eval]
contexts = "test.safetensors"
rollouts = 1
"#,
            out.display()
        )
    };
    let p = dir.join("plan.toml");
    std::fs::write(&p, plan(100, r#""train.safetensors""#)).unwrap();
    let sweep_quietly = || {
        ok(&smile(&[
            "sweep",
            p.to_str().unwrap(),
            "--jobs",
            "1",
            "--quiet",
        ]))
    };
    sweep_quietly();
    let cell = out.join("meta-bc-s0");
    let first = bytes(&cell.join("train/meta_policy.safetensors"));
    std::fs::write(&p, plan(200, r#""train.safetensors""#)).unwrap();
    let err = ok(&smile(&["sweep", p.to_str().unwrap(), "--jobs", "1"]));
    assert!(err.contains("1 of 1 cells done"), "{err}");
    let toml = std::fs::read_to_string(cell.join("cell.toml")).unwrap();
    assert!(toml.contains("total_steps = 200"), "{toml}");
    let manifest = std::fs::read_to_string(out.join("manifest.json")).unwrap();
    assert!(manifest.contains("total_steps = 200"), "{manifest}");
    assert_ne!(bytes(&cell.join("train/meta_policy.safetensors")), first);
    let aside: Vec<String> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with("meta-bc-s0.stale-"))
        .collect();
    assert_eq!(
        aside.len(),
        1,
        "the old training is kept aside once: {aside:?}"
    );
    // Two demo files named train.safetensors: two cells, two directories.
    std::fs::write(
        &p,
        plan(100, r#""train.safetensors", "other/train.safetensors""#),
    )
    .unwrap();
    let sweep = smile_app::sweep::Sweep::load(&p).unwrap();
    let dirs: Vec<_> = sweep.cells.iter().map(|c| sweep.cell_dir(c)).collect();
    assert_eq!(dirs.len(), 2);
    assert_ne!(dirs[0], dirs[1], "{dirs:?}");
    sweep_quietly();
    // One evaluation unreadable: the report names it.
    std::fs::write(dirs[1].join("eval/eval.json"), "{\"trunc").unwrap();
    let rep = dir.join("report");
    let o = smile(&["report", out.to_str().unwrap(), "-o", rep.to_str().unwrap()]);
    let err = ok(&o);
    assert!(err.contains("1 sweep cell(s) left out"), "{err}");
    let md = std::fs::read_to_string(rep.join("report.md")).unwrap();
    assert!(md.contains("left out"), "{md}");
    // ... and the sweep counts it not done: it is evaluated again.
    let err = ok(&smile(&["sweep", p.to_str().unwrap(), "--jobs", "1"]));
    assert!(err.contains("2 of 2 cells done"), "{err}");
    serde_json::from_slice::<serde_json::Value>(&bytes(&dirs[1].join("eval/eval.json"))).unwrap();
    // A manifest listing a cell twice (hand-edited: issue 72, item 8, counted as two seeds) is
    // refused naming the file and the cell.
    let path = out.join("manifest.json");
    let mut m: serde_json::Value = serde_json::from_slice(&bytes(&path)).unwrap();
    let cells = m["cells"].as_array_mut().unwrap();
    cells.push(cells[0].clone());
    std::fs::write(&path, serde_json::to_vec(&m).unwrap()).unwrap();
    let o = smile(&["report", out.to_str().unwrap(), "-o", rep.to_str().unwrap()]);
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && e.contains("manifest.json") && e.contains("twice"),
        "{e}"
    );
    // A cell another process holds (an orphan of an earlier sweep) is left to it, and the
    // sweep says so by its exit status instead of 0 with a report that lacks the cell
    // (issue 72, item 8).
    std::fs::remove_file(dirs[1].join("eval/eval.json")).unwrap();
    let lock = std::fs::File::create(dirs[1].join("lock")).unwrap();
    lock.try_lock().unwrap();
    let o = smile(&["sweep", p.to_str().unwrap(), "--jobs", "1", "--quiet"]);
    let e = String::from_utf8_lossy(&o.stderr);
    let name = dirs[1].file_name().unwrap().to_str().unwrap();
    assert_eq!(o.status.code(), Some(smile_app::sweep::BUSY_EXIT), "{e}");
    assert!(e.contains("another process") && e.contains(name), "{e}");
    drop(lock);
    let err = ok(&smile(&["sweep", p.to_str().unwrap(), "--jobs", "1"]));
    assert!(err.contains("2 of 2 cells done"), "{err}");
    std::fs::remove_dir_all(&dir).ok();
}

/// A real Slurm: `.ci/run` starts one with tests/slurm/start.sh and runs this test with
/// `--ignored`. Without a responding cluster it fails, saying so.
#[test]
#[ignore = "needs a running Slurm (tests/slurm/start.sh, run by .ci/run)"]
fn slurm_array_runs_the_cells_and_the_report() {
    let sinfo = Command::new("sinfo").args(["-h", "-o", "%T"]).output();
    let up = sinfo
        .as_ref()
        .is_ok_and(|o| o.status.success() && String::from_utf8_lossy(&o.stdout).contains("idle"));
    assert!(
        up,
        "no idle Slurm node answers `sinfo` ({sinfo:?}): start one with tests/slurm/start.sh"
    );
    let dir = tmp("slurm");
    let out = dir.join("out");
    let plan = setup(
        &dir,
        &plan_with_out(&out).replace("total_updates = 600", "total_updates = 200"),
    );
    let o = ok(&smile(&["sweep", plan.to_str().unwrap(), "--slurm"]));
    assert!(o.contains("2 cells"), "{o}");
    let script = std::fs::read_to_string(out.join("slurm/cells.sbatch")).unwrap();
    assert!(script.contains("#SBATCH --array=0-1") && script.contains("--cpus-per-task=1"));
    let o = smile(&["sweep", plan.to_str().unwrap(), "--slurm", "--submit"]);
    let stdout = String::from_utf8_lossy(&o.stdout).into_owned();
    ok(&o);
    assert!(stdout.contains("submitted array job"), "{stdout}");
    let report = out.join("report/report.json");
    let t0 = Instant::now();
    while !report.exists() {
        assert!(
            t0.elapsed() < Duration::from_secs(300),
            "the Slurm jobs did not finish in 300 s; squeue: {}",
            String::from_utf8_lossy(&Command::new("squeue").output().unwrap().stdout)
        );
        std::thread::sleep(Duration::from_millis(500));
    }
    // Written by the report job after both array tasks succeeded (afterok).
    std::thread::sleep(Duration::from_millis(500));
    for cell in ["smile-s0", "smile-s1"] {
        assert!(
            out.join(cell).join("eval/eval.json").exists(),
            "{cell} not evaluated"
        );
        let log = std::fs::read_to_string(
            out.join("slurm")
                .join(format!("cell-{}.out", &cell[cell.len() - 1..])),
        )
        .unwrap();
        assert!(log.contains("done"), "{cell}: {log}");
    }
    let json: serde_json::Value = serde_json::from_slice(&bytes(&report)).unwrap();
    assert_eq!(json["rows"][0]["seeds"].as_array().unwrap().len(), 2);
    std::fs::remove_dir_all(&dir).ok();
}

/// The plans behind docs/RESULTS.md expand (their files exist, their configs validate).
/// Only data under `runs/`, or a demo file too large for git, may be missing, and only when a
/// `smile demos` command in the plan's header records it.
#[test]
fn the_docs_plans_load() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../docs/plans");
    let mut n = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "toml") {
            let sweep = smile_app::sweep::Sweep::load_unchecked(&path)
                .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            assert!(!sweep.cells.is_empty(), "{}", path.display());
            if let Err(e) = smile_app::sweep::Sweep::load(&path) {
                let (msg, text) = (e.to_string(), std::fs::read_to_string(&path).unwrap());
                let missing = msg
                    .split_whitespace()
                    .find(|w| w.contains("/runs/") || w.ends_with(".safetensors"))
                    .unwrap_or_else(|| panic!("{}: {msg}", path.display()));
                let name = Path::new(missing).file_name().unwrap().to_string_lossy();
                assert!(
                    text.lines()
                        .any(|l| l.contains("smile demos") && l.contains(&*name)),
                    "{}: {name} is neither there nor recorded by a command in the plan",
                    path.display()
                );
            }
            n += 1;
        }
    }
    assert!(n >= 3, "only {n} plans in {}", dir.display());
}

/// A cell with two learner threads counts as two cores: the local default runs one per two
/// cores, and the Slurm script asks two CPUs per task.
#[test]
fn two_learner_thread_cells_count_two_cores() {
    let dir = tmp("cpus");
    let out = dir.join("out");
    let plan = plan_with_out(&out).replace(
        "total_updates = 600,",
        "learner_threads = 2, total_updates = 600,",
    ) + "\n[algo.meta-bc]\nset = { total_steps = 100 }\n";
    let path = setup(&dir, &plan);
    let sweep = smile_app::sweep::Sweep::load(&path).unwrap();
    let cpus: Vec<(String, usize)> = sweep
        .cells
        .iter()
        .map(|c| (c.algo.clone(), c.cpus()))
        .collect();
    assert!(
        cpus.iter()
            .all(|(a, n)| *n == if a == "smile" { 2 } else { 1 }),
        "{cpus:?}"
    );
    assert_eq!(sweep.cpus_per_cell(), 2);
    assert_eq!(
        (
            sweep.default_jobs(1),
            sweep.default_jobs(2),
            sweep.default_jobs(16)
        ),
        (1, 1, 8)
    );
    ok(&smile(&["sweep", path.to_str().unwrap(), "--slurm"]));
    let script = std::fs::read_to_string(out.join("slurm/cells.sbatch")).unwrap();
    assert!(script.contains("--cpus-per-task=2"), "{script}");
    // Without two-thread cells, one per core, as before.
    let single = smile_app::sweep::Sweep::load(&setup(&dir, &plan_with_out(&out))).unwrap();
    assert_eq!((single.cpus_per_cell(), single.default_jobs(2)), (1, 2));
    std::fs::remove_dir_all(&dir).ok();
}

/// `set = { sac = { .. } }` merges into the base config's `[sac]` table instead of replacing it.
#[test]
fn a_set_table_merges_into_the_base_configs_table() {
    let dir = tmp("set-merge");
    let out = dir.join("out");
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("base.toml"), "[sac]\nreward_scale = 3.0\n").unwrap();
    let plan =
        plan_with_out(&out).replace("[algo.smile]\n", "[algo.smile]\nconfig = \"base.toml\"\n");
    let sweep = smile_app::sweep::Sweep::load(&setup(&dir, &plan)).unwrap();
    let cfg: toml::Table = sweep.cells[0].config.parse().unwrap();
    let sac = cfg["sac"].as_table().unwrap();
    assert_eq!(sac["reward_scale"].as_float(), Some(3.0), "{cfg}");
    assert_eq!(sac["hidden"].as_array().map(Vec::len), Some(2), "{cfg}");
    std::fs::remove_dir_all(&dir).ok();
}

/// Cells run one by one (`smile sweep run-cell`, as a hand-made queue or a cluster does) leave
/// a manifest that `smile report` reads, naming what is not done yet; a directory that is
/// neither a sweep nor an evaluation is refused with what to do, not "No such file".
#[test]
fn cells_run_one_by_one_leave_a_manifest_the_report_reads() {
    let dir = tmp("run-cell");
    let out = dir.join("out");
    let plan = setup(
        &dir,
        &plan_with_out(&out).replace("total_updates = 600", "total_updates = 200"),
    );
    std::fs::create_dir_all(&out).unwrap();
    let e = smile(&["report", out.to_str().unwrap(), "-o", "unused"]);
    assert!(!e.status.success());
    let err = String::from_utf8_lossy(&e.stderr);
    assert!(
        err.contains("neither a sweep directory") && err.contains("run-cell"),
        "{err}"
    );
    ok(&smile(&[
        "sweep",
        "run-cell",
        plan.to_str().unwrap(),
        "--index",
        "1",
    ]));
    assert_eq!(manifest_status(&out), ["pending", "done"]);
    let rep = dir.join("report");
    let err = ok(&smile(&[
        "report",
        out.to_str().unwrap(),
        "-o",
        rep.to_str().unwrap(),
    ]));
    assert!(
        err.contains("smile-s0"),
        "the cell left out is named: {err}"
    );
    let json: serde_json::Value = serde_json::from_slice(&bytes(&rep.join("report.json"))).unwrap();
    assert_eq!(json["rows"][0]["seeds"].as_array().unwrap().len(), 1);
    std::fs::remove_dir_all(&dir).ok();
}

/// A SMILe cell whose plan only raised its budget continues from its checkpoint (the updates
/// it made are not made again) and keeps its earlier evaluation beside the new one; lowering
/// the budget again is another setting, trained again.
#[test]
fn a_raised_budget_extends_a_smile_cell() {
    let dir = tmp("extend");
    let out = dir.join("out");
    let plan = |updates: u32| {
        plan_with_out(&out)
            .replace("seeds = [0, 1]", "seeds = [0]")
            .replace("total_updates = 600", &format!("total_updates = {updates}"))
    };
    let p = setup(&dir, &plan(200));
    let p = p.to_str().unwrap();
    ok(&smile(&["sweep", p, "--jobs", "1", "--quiet"]));
    let cell = out.join("smile-s0");
    let evals_at = |step: u64| {
        std::fs::read_to_string(cell.join("train/metrics.jsonl"))
            .unwrap()
            .lines()
            .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap())
            .filter(|v| v["step"] == step && v.get("eval/val_metric").is_some())
            .count()
    };
    assert_eq!(evals_at(200), 1);
    let first_eval = bytes(&cell.join("eval/eval.json"));

    std::fs::write(p, plan(400)).unwrap();
    let o = smile(&["sweep", p, "--dry-run"]);
    ok(&o);
    let dry = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(dry.contains("extend"), "{dry}");
    ok(&smile(&["sweep", p, "--jobs", "1", "--quiet"]));
    // One training, continued: the evaluation at 200 updates was logged once, then 400.
    assert_eq!(evals_at(200), 1);
    assert_eq!(evals_at(400), 1);
    let toml = std::fs::read_to_string(cell.join("cell.toml")).unwrap();
    assert!(toml.contains("total_updates = 400"), "{toml}");
    let names: Vec<String> = std::fs::read_dir(&out)
        .unwrap()
        .chain(std::fs::read_dir(&cell).unwrap())
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert!(!names.iter().any(|n| n.contains(".stale-")), "{names:?}");
    let before: Vec<&String> = names
        .iter()
        .filter(|n| n.starts_with("eval.before-"))
        .collect();
    assert_eq!(before.len(), 1, "{names:?}");
    assert_eq!(bytes(&cell.join(before[0]).join("eval.json")), first_eval);
    serde_json::from_slice::<serde_json::Value>(&bytes(&cell.join("eval/eval.json"))).unwrap();
    let done = ok(&smile(&["sweep", p, "--jobs", "1"]));
    assert!(done.contains("1 of 1 cells done"), "{done}");

    // A lower budget is not an extension: the cell trains again, the longer one kept aside.
    std::fs::write(p, plan(200)).unwrap();
    let dry = String::from_utf8_lossy(&smile(&["sweep", p, "--dry-run"]).stdout).into_owned();
    assert!(dry.contains("stale"), "{dry}");
    std::fs::remove_dir_all(&dir).ok();
}
