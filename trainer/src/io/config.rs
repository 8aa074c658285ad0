//! Reading a configuration file over the algorithm's defaults.
//!
//! serde's `#[serde(default)]` fills a missing field from the *field type's* `Default`, so a
//! partial nested table such as `[sac] reward_scale = 2.0` in a SMILe config would take every
//! other SAC field from `SacConfig::default()` (2 x 256, reward scale 1) instead of from
//! `SmileConfig::default()` (2 x 128, reward scale 8). Sessions 6 and 7 ran their reward-scale
//! probes with exactly that accident (docs/RESULTS.md). Here the file's tables are merged key by
//! key into the serialised defaults of the whole configuration first, so a key the file does
//! not name keeps the value the algorithm's own default gives it, at any depth.

use serde::Serialize;
use serde::de::DeserializeOwned;

/// Deserialises `text` (TOML) into `T`, every key the text does not set taken from
/// `T::default()`, nested tables included. Unknown keys and wrong types are still refused by
/// `T`'s own `Deserialize` (e.g. `deny_unknown_fields`).
pub fn from_toml_over_defaults<T: Serialize + DeserializeOwned + Default>(
    text: &str,
) -> Result<T, toml::de::Error> {
    // The file alone first: its unknown keys and wrong types are reported with their line.
    toml::from_str::<T>(text)?;
    let given: toml::Table = toml::from_str(text)?;
    // The defaults always serialise (numbers, strings, vectors, tables).
    let mut merged = toml::Table::try_from(T::default()).unwrap_or_default();
    merge_tables(&mut merged, given);
    merged.try_into()
}

/// Sets a dotted `key` in `table` (creating sections as needed); a table value merges key by
/// key into a table already there (`set = { sac = { hidden = [..] } }` keeps the base file's
/// other `[sac]` keys).
pub fn set_key(
    table: &mut toml::Table,
    key: &str,
    value: toml::Value,
) -> std::result::Result<(), String> {
    let mut parts: Vec<&str> = key.split('.').collect();
    let last = parts.pop().ok_or("empty key")?;
    let mut t = table;
    for p in parts {
        t = t
            .entry(p)
            .or_insert_with(|| toml::Value::Table(toml::Table::new()))
            .as_table_mut()
            .ok_or_else(|| format!("`{p}` in `{key}` is not a section"))?;
    }
    match (t.get_mut(last), value) {
        (Some(toml::Value::Table(base)), toml::Value::Table(over)) => merge_tables(base, over),
        (_, value) => {
            t.insert(last.to_string(), value);
        }
    }
    Ok(())
}

/// `over` into `base`: tables merge recursively, every other value replaces.
pub(crate) fn merge_tables(base: &mut toml::Table, over: toml::Table) {
    for (k, v) in over {
        match (base.get_mut(&k), v) {
            (Some(toml::Value::Table(b)), toml::Value::Table(o)) => merge_tables(b, o),
            (_, v) => {
                base.insert(k, v);
            }
        }
    }
}

/// The most of any count a run or an evaluation is given (episodes, draws, rollouts, demos,
/// batch rows, buffer capacities): 2^24. Beyond it no run on one machine finishes or fits, and
/// a value of 2^32 or more is a typo, not a plan.
pub const MAX_COUNT: u64 = 1 << 24;
/// The most training steps a budget may name (update pairs, gradient steps, environment
/// steps): 10^10, about 11 days at 10,000 a second.
pub const MAX_STEPS: u64 = 10_000_000_000;
/// The longest episode an override may ask for, in plant steps (the paper's longest is 1000).
pub const MAX_HORIZON: usize = 1_000_000;

/// The one check of a count, naming its key: at least 1 and at most [`MAX_COUNT`]. Flags,
/// configuration files and sweep plans all end in a configuration's `validate`, which calls
/// this, so a `0` or a `2^40` that a flag would refuse cannot pass through a file either (an
/// untrained policy marked finished, a metric over zero steps, a run that never ends).
pub(crate) fn require_positive(counts: &[(&str, u64)]) -> crate::error::Result<()> {
    require_within(counts, MAX_COUNT)
}

/// [`require_positive`] for training budgets, at most [`MAX_STEPS`].
fn require_budget(counts: &[(&str, u64)]) -> crate::error::Result<()> {
    require_within(counts, MAX_STEPS)
}

fn require_within(counts: &[(&str, u64)], max: u64) -> crate::error::Result<()> {
    match counts.iter().find(|(_, v)| *v == 0 || *v > max) {
        Some((key, v)) => Err(crate::error::Error::Config(format!(
            "{key} must be a count from 1 to {max}, not {v}"
        ))),
        None => Ok(()),
    }
}

/// The checks every learner's configuration makes alike, each naming its key: the training
/// `budget` (1 to [`MAX_STEPS`]), its `counts` (each 1 to [`MAX_COUNT`]), the episode-length
/// override and the learner's thread count. A learner's own rules follow in its `validate`.
pub(crate) fn require_run(
    budget: (&str, u64),
    counts: &[(&str, usize)],
    horizon: Option<usize>,
    learner_threads: usize,
) -> crate::error::Result<()> {
    require_budget(&[budget])?;
    let counts: Vec<(&str, u64)> = counts.iter().map(|&(k, v)| (k, v as u64)).collect();
    require_positive(&counts)?;
    require_horizon(horizon)?;
    crate::threads::check_learner_threads(learner_threads)
}

/// An episode-length override must be 1 to [`MAX_HORIZON`] steps (`None`: the family's own).
fn require_horizon(horizon: Option<usize>) -> crate::error::Result<()> {
    match horizon {
        Some(h) if h == 0 || h > MAX_HORIZON => Err(crate::error::Error::Config(format!(
            "horizon must be 1 to {MAX_HORIZON} steps (leave it out for the family's own \
             horizon), not {h}"
        ))),
        _ => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::algo::smile::SmileConfig;

    /// A count, a budget or a horizon no run could finish is refused from a file as from a
    /// flag, naming the key and the bound (issue 72, item 4: 2^32-2^64 ran forever or aborted).
    #[test]
    fn absurd_counts_budgets_and_horizons_are_refused_naming_the_key() {
        let meta_bc = |t: &str| {
            from_toml_over_defaults::<crate::algo::meta_bc::MetaBcConfig>(t)
                .unwrap()
                .validate()
        };
        let smile = |t: &str| {
            from_toml_over_defaults::<SmileConfig>(t)
                .unwrap()
                .validate()
        };
        for (text, says) in [
            (
                "total_updates = 9223372036854775807",
                "total_updates must be a count from 1 to 10000000000",
            ),
            (
                "replay_per_task = 1099511627776",
                "replay_per_task must be a count from 1 to 16777216",
            ),
            ("eval_episodes = 4294967296", "eval_episodes"),
            ("horizon = 4294967296", "horizon must be 1 to 1000000 steps"),
        ] {
            let e = smile(text).unwrap_err().to_string();
            assert!(e.contains(says), "{text}: {e}");
        }
        let e = meta_bc("per_task = 4294967296").unwrap_err().to_string();
        assert!(e.contains("per_task must be a count"), "{e}");
        let e = meta_bc("total_steps = 0").unwrap_err().to_string();
        assert!(e.contains("total_steps"), "{e}");
        smile("total_updates = 10000000000\nhorizon = 1000000").unwrap();
    }

    #[test]
    fn a_partial_nested_table_keeps_the_algorithms_defaults() {
        let c: SmileConfig =
            from_toml_over_defaults("seed = 3\n[sac]\nreward_scale = 2.0\n").unwrap();
        let d = SmileConfig::default();
        assert_eq!((c.seed, c.sac.reward_scale), (3, 2.0));
        // SmileConfig's SAC (2 x 128), not SacConfig's (2 x 256); every other field untouched.
        assert_eq!(c.sac.hidden, vec![128, 128]);
        let mut want = d.clone();
        (want.seed, want.sac.reward_scale) = (3, 2.0);
        assert_eq!(c, want);
        // What plain serde does with the same text: the accident this module prevents.
        let plain: SmileConfig = toml::from_str("[sac]\nreward_scale = 2.0\n").unwrap();
        assert_eq!(plain.sac.hidden, vec![256, 256]);
        // An empty file is the defaults; a full file is itself.
        assert_eq!(from_toml_over_defaults::<SmileConfig>("").unwrap(), d);
        let full = toml::to_string(&want).unwrap();
        assert_eq!(from_toml_over_defaults::<SmileConfig>(&full).unwrap(), want);
    }

    #[test]
    fn unknown_keys_and_wrong_types_are_still_refused_with_their_line() {
        let e = from_toml_over_defaults::<SmileConfig>("seed = 1\n[sac]\nreward_scal = 2.0\n")
            .unwrap_err();
        assert!(
            e.to_string().contains("reward_scal") && e.span().is_some(),
            "{e}"
        );
        let e = from_toml_over_defaults::<SmileConfig>("[sac]\nhidden = \"wide\"\n").unwrap_err();
        assert!(e.to_string().contains("line 2"), "{e}");
    }
}
