//! What the quickstart runs on each family, one block per family: where its expert comes from,
//! which shipped demo files it starts from, and which configuration files (the ones behind the
//! family's rows in docs/RESULTS.md) it trains SMILe and Meta-BC with. Everything else in the
//! quickstart reads the family's [`Recipe`]; a new built-in family adds its block to [`RECIPES`].

use sim::Family;

/// Where a family's expert comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum ExpertSource {
    /// A scripted controller the quickstart writes itself: nothing shipped, nothing trained.
    Scripted,
    /// The shipped SAC expert (`assets/experts/<family>/`); without it (or at the tiny budget)
    /// the quickstart trains SAC itself, which the long budget must pay for.
    Sac,
    /// The shipped scripted expert over another family's SAC expert. Never trained here: SAC
    /// on the family's own sparse reward would burn hours for nothing. `make` says how to
    /// build it by hand.
    ScriptedOver {
        /// The commands that make the expert, for the error without the shipped files.
        make: &'static str,
    },
}

/// A configuration file of `docs/configs`, compiled in: `(file name, text)`. An empty text
/// stands for the learner's defaults.
pub(crate) type Preset = (&'static str, &'static str);

/// The quickstart's choices for one family.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Recipe {
    /// Where the expert comes from.
    pub expert: ExpertSource,
    /// The shipped demo files `(train, test)` in `assets/experts/<family>/`.
    pub shipped_demos: (&'static str, &'static str),
    /// SMILe's and Meta-BC's configuration files, at the family's own episode length.
    pub presets: [Preset; 2],
    /// Without the shipped expert: a shorter episode and the presets made for it (cheetah-vel:
    /// 200 steps, as the reference's section 7 prototype, to keep its own expert affordable).
    pub own_expert: Option<(usize, [Preset; 2])>,
    /// How many times the preset's SMILe update pairs the long budget trains.
    pub long_updates: u64,
}

/// A file of `docs/configs` with its text (the quickstart trains with these files, not with a
/// restatement of them).
macro_rules! preset {
    ($file:literal) => {
        (
            $file,
            include_str!(concat!("../../../docs/configs/", $file)),
        )
    };
}

/// The paper's low-data demos: 4 per task, every 20th step kept.
const DEMOS_4X_SUB20: (&str, &str) = (
    "demos-train-4x-sub20.safetensors",
    "demos-test-4x-sub20.safetensors",
);

/// The quickstart's recipe for `family`; `None` for a family registered from another crate,
/// which has no shipped files (train it through the library, GUIDE.md "Your own task family").
pub(crate) fn recipe(family: Family) -> Option<Recipe> {
    RECIPES.iter().find(|(f, _)| *f == family).map(|(_, r)| *r)
}

/// One block per built-in family.
const RECIPES: [(Family, Recipe); 5] = [
    (
        Family::POINT_GOAL,
        Recipe {
            expert: ExpertSource::Scripted,
            shipped_demos: DEMOS_4X_SUB20,
            presets: [preset!("pg-smile-2threads.toml"), ("defaults", "")],
            own_expert: None,
            long_updates: 2,
        },
    ),
    (
        Family::CHEETAH_VEL,
        Recipe {
            expert: ExpertSource::Sac,
            shipped_demos: DEMOS_4X_SUB20,
            presets: [preset!("cv1000-smile.toml"), preset!("cv1000-bc-roll.toml")],
            own_expert: Some((200, [preset!("cv-smile.toml"), preset!("cv-bc-roll.toml")])),
            long_updates: 1,
        },
    ),
    (
        Family::WALKER_DYN,
        Recipe {
            expert: ExpertSource::Sac,
            shipped_demos: DEMOS_4X_SUB20,
            presets: [preset!("wd-smile.toml"), preset!("wd-bc-roll.toml")],
            own_expert: None,
            long_updates: 1,
        },
    ),
    (
        Family::ANT_GOAL,
        Recipe {
            expert: ExpertSource::Sac,
            shipped_demos: DEMOS_4X_SUB20,
            presets: [preset!("ag-smile-rs1.toml"), preset!("ag-bc-roll.toml")],
            own_expert: None,
            long_updates: 1,
        },
    ),
    (
        Family::ANT_LINCLASS,
        Recipe {
            expert: ExpertSource::ScriptedOver {
                make: "make it with `smile expert --kind scripted-linclass --goal-expert \
                       assets/experts/ant-goal` and use `smile demos` / `smile train`",
            },
            // The paper's ant-linclass demos: 16 per task, every 5th step kept.
            shipped_demos: (
                "demos-train-16x-sub5.safetensors",
                "demos-test-16x-sub5.safetensors",
            ),
            presets: [preset!("alc-smile.toml"), preset!("alc-bc-roll.toml")],
            own_expert: None,
            long_updates: 1,
        },
    ),
];
