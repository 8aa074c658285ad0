//! The one way this crate writes a file a person or another tool reads.

/// Writes `bytes` to `path` atomically with the workspace's one atomic write
/// ([`sim::write_atomic`]: temporary sibling, fsync, rename), the error naming the file (a full
/// disk says which output it could not write).
pub fn write_atomic(path: &std::path::Path, bytes: &[u8]) -> std::io::Result<()> {
    sim::write_atomic(path, bytes)
        .map_err(|e| std::io::Error::new(e.kind(), format!("writing {}: {e}", path.display())))
}
