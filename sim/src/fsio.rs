//! The workspace's one atomic file write: every file a later command trusts (datasets,
//! checkpoints, policies, blobs, reports, plots) goes through it, so a kill or a full disk
//! leaves either the old file or the new one, never a truncated mix, and no temporary behind.

use std::io::Write;
use std::path::{Path, PathBuf};

/// The temporary sibling [`write_atomic`] writes first: hidden, named for the target and the
/// process, so two writers of different files in one folder never share one.
pub fn temp_sibling(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "file".into());
    path.with_file_name(format!(".{name}.{}.tmp", std::process::id()))
}

/// Removes the temporary siblings of `path` ([`temp_sibling`]) that writers killed part way
/// left behind: a kill -9 runs no clean-up, so the next write of the same file does it. Only
/// those whose process is gone (no `/proc/<pid>`; where the OS has no `/proc`, none) go: a
/// live writer's temporary is never touched. Errors are ignored, the write goes on.
fn remove_dead_siblings(path: &Path) {
    let (Some(dir), Some(name)) = (path.parent(), path.file_name()) else {
        return;
    };
    let proc = Path::new("/proc");
    if !proc.join("self").exists() {
        return;
    }
    let dir = if dir.as_os_str().is_empty() {
        Path::new(".")
    } else {
        dir
    };
    let prefix = format!(".{}.", name.to_string_lossy());
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let file = e.file_name();
        let file = file.to_string_lossy();
        let Some(pid) = file
            .strip_prefix(&prefix)
            .and_then(|rest| rest.strip_suffix(".tmp"))
            .and_then(|pid| pid.parse::<u32>().ok())
        else {
            continue;
        };
        if pid != std::process::id() && !proc.join(pid.to_string()).exists() {
            let _ = std::fs::remove_file(e.path());
        }
    }
}

/// Writes `bytes` to `path` through a temporary sibling, `fsync` and a rename. On any failure
/// the temporary is removed and `path` is untouched.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    write_atomic_with(path, |f| f.write_all(bytes))
}

/// As [`write_atomic`], with the contents produced by `fill` into the open temporary file.
pub fn write_atomic_with(
    path: &Path,
    fill: impl FnOnce(&mut std::fs::File) -> std::io::Result<()>,
) -> std::io::Result<()> {
    remove_dead_siblings(path);
    let tmp = temp_sibling(path);
    let result = (|| {
        let mut f = std::fs::File::create(&tmp)?;
        fill(&mut f)?;
        f.sync_all()?;
        drop(f);
        std::fs::rename(&tmp, path)
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

/// The bytes of a safetensors file with its JSON header in one order: every object's keys
/// sorted, padded with spaces to the header's length (the format's own padding).
///
/// safetensors writes `__metadata__` from a `HashMap`, whose order changes from process to
/// process, so the same data and seed would give different files (and different SHA-256s,
/// which runs record for their demos). Readers find tensors by name and offset, so the order
/// means nothing to them. Bytes that are not a safetensors file come back unchanged.
pub fn canonical_safetensors(mut bytes: Vec<u8>) -> Vec<u8> {
    fn sorted(v: serde_json::Value) -> serde_json::Value {
        match v {
            serde_json::Value::Object(m) => {
                let mut entries: Vec<_> = m.into_iter().collect();
                entries.sort_by(|a, b| a.0.cmp(&b.0));
                serde_json::Value::Object(
                    entries.into_iter().map(|(k, v)| (k, sorted(v))).collect(),
                )
            }
            other => other,
        }
    }
    let Some(n) = bytes
        .get(..8)
        .and_then(|b| <[u8; 8]>::try_from(b).ok())
        .map(|b| u64::from_le_bytes(b) as usize)
    else {
        return bytes;
    };
    let Some(header) = bytes.get(8..8usize.saturating_add(n)) else {
        return bytes;
    };
    let Ok(v) = serde_json::from_slice::<serde_json::Value>(header) else {
        return bytes;
    };
    let mut text = sorted(v).to_string().into_bytes();
    if text.len() > n {
        return bytes;
    }
    text.resize(n, b' ');
    bytes[8..8 + n].copy_from_slice(&text);
    bytes
}

/// SHA-256 of `bytes`, lower-case hex: how a run names its demos and an export report its blob.
pub fn sha256_hex(bytes: &[u8]) -> String {
    use sha2::Digest;
    sha2::Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[cfg(unix)]
    #[test]
    fn a_write_removes_the_temporaries_of_killed_writers_and_keeps_live_ones() {
        let dir = std::env::temp_dir().join(format!("sim-fsio-dead-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let target = dir.join("policy.blob");
        // A pid no process has (above Linux's pid_max of 4194304), and this live process's.
        let dead = dir.join(".policy.blob.4294967295.tmp");
        // This process's own temporary is the write's, renamed into place.
        let own = dir.join(format!(".policy.blob.{}.tmp", std::process::id()));
        let parent = dir.join(format!(
            ".policy.blob.{}.tmp",
            std::os::unix::process::parent_id()
        ));
        let other = dir.join(".other.blob.4294967295.tmp");
        for f in [&dead, &parent, &other] {
            std::fs::write(f, b"partial").unwrap();
        }
        write_atomic(&target, b"new").unwrap();
        assert_eq!(std::fs::read(&target).unwrap(), b"new");
        if Path::new("/proc/self").exists() {
            assert!(!dead.exists(), "a killed writer's temporary is removed");
        }
        assert!(parent.exists(), "a live writer's temporary stays");
        assert!(other.exists(), "another file's temporary stays");
        assert!(!own.exists());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn replaces_and_leaves_no_temporary_on_failure() {
        let dir = std::env::temp_dir().join(format!("sim-fsio-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("a.bin");
        write_atomic(&p, b"one").unwrap();
        write_atomic(&p, b"two").unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"two");
        // A failing fill: the old contents stay and no temporary is left.
        let e = write_atomic_with(&p, |_| Err(std::io::Error::other("disk full")));
        assert!(e.is_err());
        assert_eq!(std::fs::read(&p).unwrap(), b"two");
        let left: Vec<_> = std::fs::read_dir(&dir).unwrap().collect();
        assert_eq!(left.len(), 1, "{left:?}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}

#[cfg(test)]
mod canonical_tests {
    use std::collections::HashMap;

    use safetensors::{Dtype, SafeTensors, tensor::TensorView};

    #[test]
    fn canonical_safetensors_orders_the_header_and_keeps_the_contents() {
        let data: Vec<u8> = (0..16).collect();
        let files: Vec<Vec<u8>> = (0..8)
            .map(|i| {
                // Metadata maps built in different insertion orders (and, across processes,
                // with different hash seeds): the serialised header order varies.
                let mut keys: Vec<String> = (0..12).map(|k| format!("key{k}")).collect();
                keys.rotate_left(i);
                let meta: HashMap<String, String> = keys
                    .into_iter()
                    .map(|k| (k.clone(), format!("v-{k}")))
                    .collect();
                let a = TensorView::new(Dtype::F32, vec![2, 2], &data).unwrap();
                let b = TensorView::new(Dtype::U8, vec![16], &data).unwrap();
                super::canonical_safetensors(
                    safetensors::serialize([("b", b), ("a", a)], Some(meta)).unwrap(),
                )
            })
            .collect();
        assert!(files.windows(2).all(|w| w[0] == w[1]), "headers differ");
        let st = SafeTensors::deserialize(&files[0]).unwrap();
        assert_eq!(st.tensor("a").unwrap().data(), &data[..]);
        assert_eq!(st.tensor("b").unwrap().shape(), &[16]);
        let (_, meta) = SafeTensors::read_metadata(&files[0]).unwrap();
        assert_eq!(meta.metadata().as_ref().unwrap()["key3"], "v-key3");
        // Not a safetensors file: unchanged.
        assert_eq!(super::canonical_safetensors(vec![1, 2, 3]), vec![1, 2, 3]);
    }
}

/// Removes `path`, a file or a whole folder; `Ok(false)` when there was nothing to remove.
pub fn remove_any(path: &Path) -> std::io::Result<bool> {
    let gone = if path.is_dir() {
        std::fs::remove_dir_all(path)
    } else {
        std::fs::remove_file(path)
    };
    match gone {
        Ok(()) => Ok(true),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(false),
        Err(e) => Err(e),
    }
}
