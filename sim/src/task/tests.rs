//! The splits, names and the tolerant task lookup.

use super::*;
use crate::dynamics::WalkerDynamics;
use std::f32::consts::PI;

#[test]
fn splits_match_the_reference() {
    let train = Family::POINT_GOAL.train_tasks();
    assert_eq!(train.len(), 32);
    assert!((train[3].value() - 3.0 * std::f64::consts::PI / 16.0).abs() < 1e-6);
    let test = Family::POINT_GOAL.test_tasks();
    assert_eq!(test.len(), 16);
    assert!((test[1].value() - (2.0 * PI / 16.0 + PI / 32.0) as f64).abs() < 1e-6);
    let train = Family::CHEETAH_VEL.train_tasks();
    assert_eq!(train.len(), 31);
    assert!((train[30].value() - 3.0).abs() < 1e-5);
    let test = Family::CHEETAH_VEL.test_tasks();
    assert_eq!(test.len(), 30);
    assert!((test[0].value() - 0.05).abs() < 1e-6);
    assert!((test[29].value() - 2.95).abs() < 1e-5);
    assert_eq!(Family::ANT_GOAL.train_tasks().len(), 32);
    assert_eq!(Family::ANT_GOAL.test_tasks().len(), 16);
    assert_eq!(
        Family::ANT_GOAL.tasks(Split::Test)[1].value(),
        Family::POINT_GOAL.test_tasks()[1].value()
    );
    assert_eq!(Family::WALKER_DYN.train_tasks().len(), 50);
    assert_eq!(Family::WALKER_DYN.test_tasks().len(), 25);
}

#[test]
fn train_and_test_tasks_are_disjoint() {
    for family in Family::BUILTIN {
        let train = family.train_tasks();
        for task in family.test_tasks() {
            assert!(!train.contains(&task), "{task} is in both splits");
        }
    }
}

#[test]
fn family_names_round_trip_and_unknown_names_fail() {
    for family in Family::BUILTIN {
        assert_eq!(family.to_string().parse::<Family>(), Ok(family));
    }
    let err = "ant".parse::<Family>().unwrap_err();
    assert!(
        matches!(&err, SimError::UnknownFamily { name, .. } if name == "ant"),
        "{err:?}"
    );
    // The message lists every family the parser accepts.
    let msg = err.to_string();
    for family in Family::all() {
        assert!(msg.contains(family.name()), "{msg}");
    }
    assert_eq!("test".parse::<Split>(), Ok(Split::Test));
    assert_eq!(
        "val".parse::<Split>(),
        Err(SimError::UnknownSplit("val".into()))
    );
}

#[test]
fn task_from_value_round_trips() {
    for family in Family::BUILTIN {
        for task in family.test_tasks() {
            assert_eq!(family.task_from_value(task.value()), Ok(task));
        }
    }
    assert!(Family::WALKER_DYN.task_from_value(1.5).is_err());
    assert!(Family::CHEETAH_VEL.task_from_value(f64::NAN).is_err());
}

#[test]
fn a_value_read_off_a_label_names_its_task_and_a_far_value_lists_the_tasks() {
    let tests = Family::POINT_GOAL.test_tasks();
    // test goal 1 is 0.490874 rad; its label prints 0.4909.
    assert_eq!(tests[1].label(), "goal_angle=0.4909");
    assert_eq!(Family::POINT_GOAL.find_task(0.4909, &tests), Ok(1));
    assert!(tests[1].is_named_by(0.4909));
    assert!(!tests[1].is_named_by(0.4909 + 2.0 * TASK_VALUE_TOLERANCE));
    assert_eq!(Family::POINT_GOAL.task_named(0.4909), Ok(tests[1]));
    // A value far from every task is a new task with exactly that value.
    assert_eq!(
        Family::POINT_GOAL.task_named(0.3),
        Ok(Task::point_goal(0.3))
    );
    let err = Family::POINT_GOAL.find_task(0.5, &tests).unwrap_err();
    let message = err.to_string();
    assert!(matches!(err, SimError::NoTaskNear { .. }), "{err:?}");
    assert!(message.contains("within 0.001 of 0.5"), "{message}");
    assert!(message.contains("0.0982, 0.4909, 0.8836"), "{message}");
    // f32 0.35 is 0.3499999940395355 as f64, which an exact comparison missed.
    let cheetah = Family::CHEETAH_VEL.test_tasks();
    assert_eq!(Family::CHEETAH_VEL.find_task(0.35, &cheetah), Ok(3));
    assert_eq!(Family::CHEETAH_VEL.find_task(0.25, &cheetah), Ok(2));
    assert_eq!(
        Family::CHEETAH_VEL.task_named(0.35),
        Ok(Task::cheetah_vel(0.05 + 3.0 * 0.1))
    );
    // Seeds are integers: exact, and the nominal walker is known.
    let walker = Family::WALKER_DYN.test_tasks();
    assert_eq!(Family::WALKER_DYN.find_task(10_003.0, &walker), Ok(3));
    let err = Family::WALKER_DYN.find_task(3.0, &walker).unwrap_err();
    assert!(err.to_string().contains("equal to 3;"), "{err}");
    assert_eq!(
        Family::WALKER_DYN.task_named(WALKER_NOMINAL_SEED as f64),
        Ok(Task::walker_nominal())
    );
    // Tasks of another family are never matched; an empty list says "none".
    let err = Family::POINT_GOAL.find_task(0.05, &cheetah).unwrap_err();
    assert!(err.to_string().ends_with("available: none"), "{err}");
}

#[test]
fn no_value_names_two_tasks_of_a_family() {
    for family in Family::BUILTIN {
        let mut all = family.train_tasks();
        all.extend(family.test_tasks());
        for (i, a) in all.iter().enumerate() {
            for b in &all[i + 1..] {
                let gap = (a.value() - b.value()).abs();
                assert!(gap > 2.0 * family.value_tolerance(), "{a} and {b}");
            }
            assert!(a.same_task(a));
        }
    }
}

#[test]
fn the_nominal_walker_seed_is_the_unmodified_robot_in_neither_split() {
    let nominal = Task::walker_nominal();
    assert_eq!(
        Family::WALKER_DYN.task_from_value(WALKER_NOMINAL_SEED as f64),
        Ok(nominal)
    );
    assert_eq!(
        Family::WALKER_DYN.task_from_value(nominal.value()),
        Ok(nominal)
    );
    assert_eq!(nominal.walker_dynamics(), Some(WalkerDynamics::nominal()));
    assert_ne!(
        WalkerDynamics::from_seed(WALKER_NOMINAL_SEED),
        WalkerDynamics::nominal(),
        "the raw draw of the reserved seed is not nominal: only Task maps it"
    );
    let parameter = nominal.parameter();
    assert_eq!(parameter.len(), WalkerDynamics::VECTOR_DIM);
    assert!(parameter.iter().all(|p| *p == 0.0), "{parameter:?}");
    for split in [Split::Train, Split::Test] {
        let tasks = Family::WALKER_DYN.tasks(split);
        assert!(
            !tasks.contains(&nominal),
            "nominal walker in the {split} split"
        );
        // Every split task really is randomised (non-zero parameter).
        assert!(
            tasks
                .iter()
                .all(|t| t.parameter().iter().any(|p| *p != 0.0))
        );
    }
    assert!(nominal.label().contains("nominal"));
    assert_eq!(Task::cheetah_vel(1.0).walker_dynamics(), None);
}

#[test]
fn every_family_refuses_a_task_whose_value_is_not_finite() {
    // `Task::new` takes any number; a reset must refuse a NaN goal, velocity or seed before it
    // poisons the rewards (point-goal used to take one).
    for family in Family::BUILTIN {
        let mut env = crate::make_env(family, crate::EnvConfig::default()).unwrap();
        for value in [f64::NAN, f64::INFINITY] {
            let err = env.reset(&Task::new(family, value), 0).unwrap_err();
            assert!(
                matches!(&err, SimError::InvalidTask { family: f, reason } if *f == family.name() && reason.contains("not finite")),
                "{family}: {err:?}"
            );
        }
        let task = family.train_tasks()[0];
        assert!(
            env.reset(&task, 0).is_ok(),
            "{family}: a finite task still resets"
        );
    }
}
