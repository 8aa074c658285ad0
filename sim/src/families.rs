//! Which families a name finds: the five built in, then those registered from other crates
//! ([`Family::register`]). It sits above every family's module (it imports them all for the
//! built-in list), so no family module and nothing below them imports it back.
//!
//! Adding a family in this crate: its module with its environment, its `SPEC` and its
//! [`Family`] constant (as `point_goal.rs`), and its entry in [`Family::BUILTIN`]. From another
//! crate: the same module there and one [`Family::register`] call (GUIDE.md, "Your own task
//! family").

use std::str::FromStr;
use std::sync::RwLock;

use crate::error::SimError;
use crate::family::Family;
use crate::sensing::ObsComponent;

/// The families registered from outside this crate, in registration order.
static REGISTERED: RwLock<Vec<Family>> = RwLock::new(Vec::new());

impl Family {
    /// The paper's five families, in CLI order.
    pub const BUILTIN: [Family; 5] = [
        Family::POINT_GOAL,
        Family::CHEETAH_VEL,
        Family::WALKER_DYN,
        Family::ANT_GOAL,
        Family::ANT_LINCLASS,
    ];

    /// Every family a name finds: the built-in ones, then the registered ones.
    pub fn all() -> Vec<Family> {
        let registered = REGISTERED.read().unwrap_or_else(|e| e.into_inner());
        Family::BUILTIN
            .iter()
            .chain(registered.iter())
            .copied()
            .collect()
    }

    /// Makes `self` known by its name to every parser (configurations, datasets, policy files,
    /// flags), as Gymnasium's `register` does an environment id. Registering the same
    /// declaration again is a no-op; another declaration under a name already taken is refused
    /// ([`SimError::FamilyNameRefused`]), and so is a name that is not a CLI word.
    pub fn register(self) -> Result<Family, SimError> {
        let name = self.name();
        let word = !name.is_empty()
            && name
                .chars()
                .all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '-');
        if !word {
            return Err(SimError::FamilyNameRefused {
                name: name.to_string(),
                reason: "a family's name is lowercase letters, digits and dashes",
            });
        }
        let mut registered = REGISTERED.write().unwrap_or_else(|e| e.into_inner());
        let same = |f: &Family| std::ptr::eq(f.spec(), self.spec());
        if registered.iter().any(same) {
            return Ok(self);
        }
        if Family::BUILTIN.contains(&self) || registered.contains(&self) {
            return Err(SimError::FamilyNameRefused {
                name: name.to_string(),
                reason: "another family has it",
            });
        }
        registered.push(self);
        Ok(self)
    }

    /// Per observation index, what the entry is: a measured position or angle, the rate of
    /// another entry, or a directly measured quantity. Its length is [`Family::obs_dim`].
    pub fn obs_components(self) -> &'static [ObsComponent] {
        self.spec().obs_components
    }
}

/// A family is read by its CLI name, among the built-in and registered ones.
impl FromStr for Family {
    type Err = SimError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let all = Family::all();
        all.iter()
            .find(|family| family.name() == s)
            .copied()
            .ok_or_else(|| SimError::UnknownFamily {
                name: s.to_string(),
                known: all.iter().map(|f| f.name()).collect::<Vec<_>>().join(", "),
            })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::family::FamilySpec;

    static RENAMED: FamilySpec = FamilySpec {
        name: "point-goal-renamed",
        ..crate::point_goal::SPEC
    };
    static NOT_A_WORD: FamilySpec = FamilySpec {
        name: "Point Goal",
        ..crate::point_goal::SPEC
    };
    static TAKEN: FamilySpec = FamilySpec {
        name: "cheetah-vel",
        ..crate::point_goal::SPEC
    };

    #[test]
    fn a_registered_family_is_parsed_and_a_bad_or_taken_name_is_refused() {
        assert!("point-goal-renamed".parse::<Family>().is_err());
        let family = Family::of(&RENAMED).register().unwrap();
        assert_eq!("point-goal-renamed".parse::<Family>(), Ok(family));
        assert_eq!(
            Family::of(&RENAMED).register(),
            Ok(family),
            "registering again is a no-op"
        );
        assert!(Family::all().ends_with(&[family]));
        // An unknown name's message lists the registered families too.
        let unknown = "nope".parse::<Family>().unwrap_err().to_string();
        assert!(unknown.contains("point-goal-renamed"), "{unknown}");
        for (spec, why) in [
            (&NOT_A_WORD, "lowercase"),
            (&TAKEN, "another family has it"),
        ] {
            let err = Family::of(spec).register().unwrap_err().to_string();
            assert!(err.contains(spec.name) && err.contains(why), "{err}");
        }
        assert_eq!("cheetah-vel".parse::<Family>(), Ok(Family::CHEETAH_VEL));
    }
}
