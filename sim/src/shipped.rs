//! Shipped files prove their integrity: a folder of shipped files (`assets/experts/*`,
//! `assets/policies/*`) holds a [`SUMS_FILE`] in `sha256sum`'s own format, and every load of a
//! file it lists checks the bytes against it ([`check_shipped_bytes`]), so a flipped byte or a
//! partial copy is refused, naming the file, instead of evaluated as a policy. Folders without
//! the file (run directories, a user's exports) are not checked. `sha256sum -c SHA256SUMS` in the
//! folder checks the same list with the system's tool; `docs/scripts/shipped-sums.sh` writes it.

use std::path::{Path, PathBuf};

/// The checksum list of a folder of shipped files: lines `<sha256 hex>  <file name>`.
pub const SUMS_FILE: &str = "SHA256SUMS";

/// A shipped file that is not what was shipped, or a checksum list that cannot be read.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum IntegrityError {
    /// The file's bytes are not the ones its folder's checksum list names.
    #[error(
        "{path}: SHA-256 {found}, but {sums} lists {expected}: the file is not the one shipped \
         (a changed byte or a partial copy); restore it (git checkout -- {path}), or write the \
         list again if it was changed on purpose (docs/scripts/shipped-sums.sh)"
    )]
    Mismatch {
        /// The file.
        path: PathBuf,
        /// The checksum list.
        sums: PathBuf,
        /// The SHA-256 the list names.
        expected: String,
        /// The SHA-256 of the bytes read.
        found: String,
    },
    /// The checksum list exists but cannot be read or parsed.
    #[error("{sums}: {reason}")]
    Sums {
        /// The checksum list.
        sums: PathBuf,
        /// What is wrong with it.
        reason: String,
    },
}

/// The SHA-256 that `path`'s folder's [`SUMS_FILE`] lists for it: `None` when the folder has no
/// list or the list does not name the file.
pub fn shipped_sha256(path: &Path) -> Result<Option<String>, IntegrityError> {
    let (Some(dir), Some(name)) = (path.parent(), path.file_name()) else {
        return Ok(None);
    };
    let sums = dir.join(SUMS_FILE);
    let text = match std::fs::read_to_string(&sums) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => {
            return Err(IntegrityError::Sums {
                sums,
                reason: e.to_string(),
            });
        }
    };
    let bad = |n: usize, why: &str| IntegrityError::Sums {
        sums: sums.clone(),
        reason: format!("line {n}: {why}"),
    };
    for (i, line) in text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty())
    {
        // `sha256sum` writes "<hex>  <name>" (text mode) or "<hex> *<name>" (binary mode).
        let (hex, rest) = line
            .split_once(' ')
            .ok_or_else(|| bad(i + 1, "not `<sha256>  <file>`"))?;
        let listed = rest.strip_prefix([' ', '*']).unwrap_or(rest);
        if hex.len() != 64 || !hex.bytes().all(|b| b.is_ascii_hexdigit()) {
            return Err(bad(i + 1, "not a SHA-256 in hex"));
        }
        if listed == name.to_string_lossy() {
            return Ok(Some(hex.to_ascii_lowercase()));
        }
    }
    Ok(None)
}

/// Checks `bytes`, read from `path`, against the SHA-256 its folder's [`SUMS_FILE`] lists;
/// `Ok(true)` when checked, `Ok(false)` when no list names the file.
pub fn check_shipped_bytes(path: &Path, bytes: &[u8]) -> Result<bool, IntegrityError> {
    let Some(expected) = shipped_sha256(path)? else {
        return Ok(false);
    };
    let found = crate::fsio::sha256_hex(bytes);
    if found != expected {
        return Err(IntegrityError::Mismatch {
            path: path.to_path_buf(),
            sums: path.with_file_name(SUMS_FILE),
            expected,
            found,
        });
    }
    Ok(true)
}

/// [`check_shipped_bytes`] on the file at `path` (read only when a list names it).
pub fn check_shipped(path: &Path) -> Result<bool, IntegrityError> {
    if shipped_sha256(path)?.is_none() {
        return Ok(false);
    }
    let bytes = std::fs::read(path).map_err(|e| IntegrityError::Sums {
        sums: path.with_file_name(SUMS_FILE),
        reason: format!("reading the listed file {}: {e}", path.display()),
    })?;
    check_shipped_bytes(path, &bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_listed_file_is_checked_and_a_changed_byte_is_named() {
        let dir = std::env::temp_dir().join(format!("sim-shipped-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let (a, b) = (dir.join("a.bin"), dir.join("b.bin"));
        std::fs::write(&a, b"shipped").unwrap();
        std::fs::write(&b, b"not listed").unwrap();
        // No list: nothing to check.
        assert!(!check_shipped(&a).unwrap());
        let sums = format!("{}  a.bin\n", crate::fsio::sha256_hex(b"shipped"));
        std::fs::write(dir.join(SUMS_FILE), sums).unwrap();
        assert!(check_shipped(&a).unwrap());
        assert!(!check_shipped(&b).unwrap(), "a file the list does not name");
        std::fs::write(&a, b"shipped!").unwrap();
        let e = check_shipped(&a).unwrap_err().to_string();
        assert!(e.contains("a.bin") && e.contains(SUMS_FILE), "{e}");
        // The binary-mode marker of `sha256sum -b` reads the same.
        let sums = format!("{} *a.bin\n", crate::fsio::sha256_hex(b"shipped!"));
        std::fs::write(dir.join(SUMS_FILE), sums).unwrap();
        assert!(check_shipped(&a).unwrap());
        std::fs::write(dir.join(SUMS_FILE), "xyz  a.bin\n").unwrap();
        let e = check_shipped(&a).unwrap_err().to_string();
        assert!(e.contains("line 1") && e.contains(SUMS_FILE), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
