//! Hardware in the loop over a real serial port: the device as its own process
//! ([`board::serve`], `firmware-sim device`), the plant on the host driving it tick by tick
//! ([`RemoteDevice`], `firmware-sim host`), and the line between them ([`Wire`]: an OS serial
//! device in raw mode, paced at the baud rate). The messages and their bytes are
//! `docs/PROTOCOL.md`.

pub mod board;
mod remote;
mod wire;

pub use board::{BoardConfig, BoardError, BoardEvent};
pub use remote::{DeviceStatus, LinkCounters, LinkEvent, RemoteDevice, SerialConfig, SerialLink};
pub use wire::{Faults, Wire, WireStats, line_time};

/// Creates a pseudo-terminal pair in raw mode and links `link` to its device side, so that a
/// host can open `link` as a serial port while this process serves the other side; returns
/// the wire on this side and the other side's path. The other side's handle is returned too:
/// kept open, a host that closes its end does not hang up this one.
pub fn pty(
    link: &std::path::Path,
    baud: u32,
) -> Result<(Wire, serialport::TTYPort, std::path::PathBuf), crate::link::LinkError> {
    let fail = |e: &dyn std::fmt::Display| wire::port_error(&link.to_string_lossy(), e);
    // Never replace what is not a stale link of ours: a regular file's contents would be lost,
    // and a live link is another device's (issue 72, item 2).
    if let Ok(meta) = std::fs::symlink_metadata(link) {
        if !meta.file_type().is_symlink() {
            return Err(fail(
                &"exists and is not a pseudo-terminal link: refusing to replace it (pick another --pty path)",
            ));
        }
        if std::fs::metadata(link).is_ok() {
            return Err(fail(
                &"links to a live pseudo-terminal: another device serves it (stop it, or pick another --pty path)",
            ));
        }
    }
    let (master, slave) = serialport::TTYPort::pair().map_err(|e| fail(&e))?;
    let path = std::path::PathBuf::from(
        serialport::SerialPort::name(&slave)
            .ok_or_else(|| fail(&"the pseudo-terminal has no name"))?,
    );
    // Linked under a temporary name and renamed over `link`: a host reopening `link` finds
    // either the old terminal or the new one, never no file.
    let mut tmp = link.as_os_str().to_owned();
    tmp.push(format!(".{}", std::process::id()));
    let tmp = std::path::PathBuf::from(tmp);
    let _ = std::fs::remove_file(&tmp);
    std::os::unix::fs::symlink(&path, &tmp).map_err(|e| fail(&e))?;
    std::fs::rename(&tmp, link).map_err(|e| fail(&e))?;
    let wire = Wire::from_port(Box::new(master), &path.to_string_lossy(), baud);
    Ok((wire, slave, path))
}
