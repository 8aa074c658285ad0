//! Paths in JSON files without loss: a UTF-8 path is written as a string (what people and
//! other tools read), any other path as serde's `OsString` form (`{"Unix": [bytes]}`), so a
//! sweep under a folder whose name is not UTF-8 records the files it really used. Either form
//! reads back. Use as `#[serde(with = "crate::io::os_path")]` (or `os_path::option`).

use std::ffi::OsString;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Deserializer, Serialize, Serializer};

#[derive(Serialize, Deserialize)]
#[serde(untagged)]
enum Repr {
    Text(String),
    Os(OsString),
}

/// Serialises `p` as a string when it is UTF-8, else as its OS bytes.
pub fn serialize<S: Serializer>(p: &Path, s: S) -> Result<S::Ok, S::Error> {
    match p.to_str() {
        Some(t) => s.serialize_str(t),
        None => p.as_os_str().serialize(s),
    }
}

/// Reads either form written by [`serialize`].
pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<PathBuf, D::Error> {
    Ok(match Repr::deserialize(d)? {
        Repr::Text(t) => PathBuf::from(t),
        Repr::Os(o) => PathBuf::from(o),
    })
}

/// The same for `Option<PathBuf>` (`None` as `null`).
pub mod option {
    use super::*;

    /// Serialises `Some(p)` as [`super::serialize`] does, `None` as null.
    pub fn serialize<S: Serializer>(p: &Option<PathBuf>, s: S) -> Result<S::Ok, S::Error> {
        match p {
            Some(p) => super::serialize(p, s),
            None => s.serialize_none(),
        }
    }

    /// Reads either form, or null.
    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Option<PathBuf>, D::Error> {
        Ok(Option::<Repr>::deserialize(d)?.map(|r| match r {
            Repr::Text(t) => PathBuf::from(t),
            Repr::Os(o) => PathBuf::from(o),
        }))
    }
}

#[cfg(all(test, unix))]
mod tests {
    use std::os::unix::ffi::OsStrExt;

    use super::*;

    #[derive(Serialize, Deserialize, PartialEq, Debug)]
    struct T {
        #[serde(with = "super")]
        p: PathBuf,
        #[serde(with = "super::option", default)]
        q: Option<PathBuf>,
    }

    #[test]
    fn utf8_paths_are_strings_and_others_round_trip() {
        let t = T {
            p: PathBuf::from("runs/a b"),
            q: None,
        };
        let j = serde_json::to_string(&t).unwrap();
        assert_eq!(j, r#"{"p":"runs/a b","q":null}"#);
        assert_eq!(serde_json::from_str::<T>(&j).unwrap(), t);
        let raw = PathBuf::from(std::ffi::OsStr::from_bytes(b"caf\xe9/x"));
        let t = T {
            p: raw.clone(),
            q: Some(raw),
        };
        let j = serde_json::to_string(&t).unwrap();
        assert_eq!(serde_json::from_str::<T>(&j).unwrap(), t, "{j}");
    }
}
