//! Metrics log: one JSON object per line (`metrics.jsonl` in the run directory) with stable
//! CleanRL's names: `losses/qf_loss`, `losses/actor_loss`, `losses/alpha_loss`, `charts/alpha`,
//! `charts/entropy`, `charts/episodic_return`, `charts/metric`, `charts/sps`. Every line has
//! `step` (environment steps) and `wall_s` (seconds since the log was opened).
//!
//! The same scalars also go to a TensorBoard event file (`tb/events.out.tfevents.*`, watch with
//! `tensorboard --logdir runs`), written by [`TbWriter`]: TFRecord framing with masked CRC-32C
//! around hand-encoded `Event { wall_time, step, summary { value { tag, simple_value } } }`
//! protobufs (no maintained Rust crate does this without pulling in a protobuf toolchain).
//!
//! A resumed run continues the log from its checkpoint: [`MetricsLog::open_at`] drops the lines
//! written after the checkpoint by the interrupted process (rewriting the file atomically), and
//! the earlier event files lose their events past the checkpoint's step the same way (so any
//! reader of the files, not only TensorBoard, sees each step once), and the new event file
//! starts with a `SessionLog { status: START }` at that step, TensorBoard's own purge signal.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

use crate::error::{Error, Result};

/// File name of the metrics log inside a run directory.
pub const METRICS_FILE: &str = "metrics.jsonl";

/// An append-only JSON-lines metrics writer.
pub struct MetricsLog {
    path: PathBuf,
    file: std::io::BufWriter<std::fs::File>,
    t0: Instant,
    tb: TbWriter,
}

impl MetricsLog {
    /// Open (append to) `dir/metrics.jsonl` for a run now at `step` (0 for a fresh run): lines
    /// with a larger step, left by an interrupted process after its last checkpoint, are
    /// dropped first (as are torn, unparseable lines), so that no step appears twice.
    pub fn open_at(dir: &Path, step: u64) -> Result<Self> {
        let path = dir.join(METRICS_FILE);
        let io = Error::io(&path);
        std::fs::create_dir_all(dir).map_err(io)?;
        if let Ok(old) = std::fs::read_to_string(&path) {
            let kept: String = old
                .lines()
                .filter(|l| {
                    serde_json::from_str::<serde_json::Value>(l)
                        .ok()
                        .and_then(|v| v.get("step").and_then(serde_json::Value::as_u64))
                        .is_some_and(|s| s <= step)
                })
                .flat_map(|l| [l, "\n"])
                .collect();
            if kept.len() != old.len() {
                crate::io::checkpoint::write_atomic(&path, kept.as_bytes())?;
            }
        }
        let f = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(&path)
            .map_err(io)?;
        if step > 0 {
            truncate_events(&dir.join("tb"), step)?;
        }
        let mut tb = TbWriter::create(&dir.join("tb"))?;
        if step > 0 {
            tb.session_start(step)?;
        }
        Ok(Self {
            path,
            file: std::io::BufWriter::new(f),
            t0: Instant::now(),
            tb,
        })
    }

    /// Write one line `{"step": step, "wall_s": .., name: value, ...}` (non-finite values are
    /// written as null).
    pub fn log(&mut self, step: u64, values: &[(&str, f64)]) -> Result<()> {
        let mut obj = serde_json::Map::new();
        obj.insert("step".into(), step.into());
        obj.insert("wall_s".into(), self.t0.elapsed().as_secs_f64().into());
        for (k, v) in values {
            obj.insert(
                (*k).into(),
                serde_json::Number::from_f64(*v).map_or(serde_json::Value::Null, Into::into),
            );
        }
        let line = serde_json::Value::Object(obj).to_string();
        writeln!(self.file, "{line}")
            .and_then(|_| self.file.flush())
            .map_err(Error::io(&self.path))?;
        self.tb.scalars(step, values)
    }
}

/// CRC-32C (Castagnoli), as TFRecord uses.
fn crc32c(data: &[u8]) -> u32 {
    static TABLE: std::sync::OnceLock<[u32; 256]> = std::sync::OnceLock::new();
    let table = TABLE.get_or_init(|| {
        let mut t = [0u32; 256];
        for (i, e) in t.iter_mut().enumerate() {
            let mut c = i as u32;
            for _ in 0..8 {
                c = if c & 1 != 0 {
                    0x82f6_3b78 ^ (c >> 1)
                } else {
                    c >> 1
                };
            }
            *e = c;
        }
        t
    });
    !data.iter().fold(!0u32, |c, &b| {
        table[((c ^ b as u32) & 0xff) as usize] ^ (c >> 8)
    })
}

fn masked_crc(data: &[u8]) -> u32 {
    crc32c(data).rotate_right(15).wrapping_add(0xa282_ead8)
}

fn varint(mut v: u64, out: &mut Vec<u8>) {
    while v >= 0x80 {
        out.push((v as u8) | 0x80);
        v >>= 7;
    }
    out.push(v as u8);
}

/// Protobuf length-delimited field `field` holding `bytes`.
fn len_field(field: u32, bytes: &[u8], out: &mut Vec<u8>) {
    varint(((field << 3) | 2) as u64, out);
    varint(bytes.len() as u64, out);
    out.extend_from_slice(bytes);
}

/// Drops the events with a step past `step` from every event file in `tb` (rewritten
/// atomically where one changes), and a torn last record; a file that is not a valid TFRecord
/// file of events is left as it is.
fn truncate_events(tb: &Path, step: u64) -> Result<()> {
    let Ok(entries) = std::fs::read_dir(tb) else {
        return Ok(());
    };
    for entry in entries.flatten() {
        let path = entry.path();
        let is_events = path
            .file_name()
            .and_then(|n| n.to_str())
            .is_some_and(|n| n.starts_with("events.out.tfevents."));
        if !is_events {
            continue;
        }
        let Ok(bytes) = std::fs::read(&path) else {
            continue;
        };
        let kept = kept_records(&bytes, step);
        if kept.len() != bytes.len() {
            crate::io::checkpoint::write_atomic(&path, &kept)?;
        }
    }
    Ok(())
}

/// The records of a TFRecord file of events whose step is at most `step`, in order; stops at
/// the first record that does not check out (a torn write).
fn kept_records(bytes: &[u8], step: u64) -> Vec<u8> {
    let (mut at, mut kept) = (0usize, Vec::with_capacity(bytes.len()));
    while at + 12 <= bytes.len() {
        let len_bytes = &bytes[at..at + 8];
        let len = u64::from_le_bytes(len_bytes.try_into().expect("8 bytes")) as usize;
        let end = at.saturating_add(16).saturating_add(len);
        if end > bytes.len() || read_u32(bytes, at + 8) != masked_crc(len_bytes) {
            break;
        }
        let data = &bytes[at + 12..at + 12 + len];
        if read_u32(bytes, at + 12 + len) != masked_crc(data) {
            break;
        }
        if event_step(data).is_none_or(|s| s <= step) {
            kept.extend_from_slice(&bytes[at..end]);
        }
        at = end;
    }
    kept
}

fn read_u32(bytes: &[u8], at: usize) -> u32 {
    u32::from_le_bytes(bytes[at..at + 4].try_into().expect("4 bytes"))
}

/// The `step` (field 2) of an `Event` as [`TbWriter`] writes it: the wall time (field 1,
/// fixed64) first, then the step as a varint.
fn event_step(ev: &[u8]) -> Option<u64> {
    if ev.len() < 10 || ev[0] != 0x09 || ev[9] != 0x10 {
        return None;
    }
    let (mut v, mut shift) = (0u64, 0);
    for &b in &ev[10..] {
        v |= u64::from(b & 0x7f) << shift;
        if b & 0x80 == 0 {
            return Some(v);
        }
        shift += 7;
        if shift >= 64 {
            return None;
        }
    }
    None
}

/// A TensorBoard event-file writer for scalars.
pub struct TbWriter {
    path: PathBuf,
    file: std::io::BufWriter<std::fs::File>,
}

impl TbWriter {
    /// Create `dir/events.out.tfevents.<unix seconds>.<pid>.smile` and write the version event.
    pub fn create(dir: &Path) -> Result<Self> {
        let secs = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_secs());
        // A second writer of one process within the same second (an in-process resume) gets
        // its own file: `create_new`, never truncating the earlier one.
        let name = |n: u32| {
            let pid = std::process::id();
            match n {
                0 => format!("events.out.tfevents.{secs}.{pid}.smile"),
                n => format!("events.out.tfevents.{secs}.{pid}.{n}.smile"),
            }
        };
        std::fs::create_dir_all(dir).map_err(Error::io(dir))?;
        let mut n = 0;
        let (path, f) = loop {
            let path = dir.join(name(n));
            match std::fs::File::create_new(&path) {
                Ok(f) => break (path, f),
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists && n < 1000 => n += 1,
                Err(e) => return Err(Error::Io { path, source: e }),
            }
        };
        let mut w = Self {
            path,
            file: std::io::BufWriter::new(f),
        };
        let mut ev = Self::event_head(0);
        len_field(3, b"brain.Event:2", &mut ev);
        w.record(&ev)?;
        Ok(w)
    }

    fn event_head(step: u64) -> Vec<u8> {
        let wall = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0.0, |d| d.as_secs_f64());
        let mut ev = vec![0x09]; // field 1 (wall_time), fixed64
        ev.extend_from_slice(&wall.to_le_bytes());
        ev.push(0x10); // field 2 (step), varint
        varint(step, &mut ev);
        ev
    }

    fn record(&mut self, data: &[u8]) -> Result<()> {
        let len = (data.len() as u64).to_le_bytes();
        let mut rec = Vec::with_capacity(data.len() + 16);
        rec.extend_from_slice(&len);
        rec.extend_from_slice(&masked_crc(&len).to_le_bytes());
        rec.extend_from_slice(data);
        rec.extend_from_slice(&masked_crc(data).to_le_bytes());
        self.file
            .write_all(&rec)
            .and_then(|_| self.file.flush())
            .map_err(Error::io(&self.path))
    }

    /// A `SessionLog { status: START }` event at `step`: TensorBoard then discards events with
    /// a larger step from earlier files of this run (those of an interrupted process).
    pub fn session_start(&mut self, step: u64) -> Result<()> {
        let mut ev = Self::event_head(step);
        // field 7 (session_log) = SessionLog { field 1 (status) = 1 (START) }
        len_field(7, &[0x08, 0x01], &mut ev);
        self.record(&ev)
    }

    /// One event holding every finite `(tag, value)` as a scalar at `step`.
    pub fn scalars(&mut self, step: u64, values: &[(&str, f64)]) -> Result<()> {
        let mut summary = Vec::new();
        for (tag, v) in values.iter().filter(|(_, v)| v.is_finite()) {
            let mut val = Vec::new();
            len_field(1, tag.as_bytes(), &mut val);
            val.push(0x15); // field 2 (simple_value), fixed32
            val.extend_from_slice(&(*v as f32).to_le_bytes());
            len_field(1, &val, &mut summary);
        }
        let mut ev = Self::event_head(step);
        len_field(5, &summary, &mut ev);
        self.record(&ev)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crc32c_known_value_and_record_framing() {
        assert_eq!(crc32c(b"123456789"), 0xe306_9283);
        let dir = std::env::temp_dir().join(format!("smile-tb-{}", std::process::id()));
        let mut w = TbWriter::create(&dir).unwrap();
        w.scalars(7, &[("losses/qf_loss", 0.5), ("charts/sps", f64::NAN)])
            .unwrap();
        let bytes = std::fs::read(&w.path).unwrap();
        // Walk the records: every length and payload CRC must check out; two records.
        let (mut at, mut n) = (0usize, 0);
        while at < bytes.len() {
            let len = u64::from_le_bytes(bytes[at..at + 8].try_into().unwrap()) as usize;
            let lcrc = u32::from_le_bytes(bytes[at + 8..at + 12].try_into().unwrap());
            assert_eq!(lcrc, masked_crc(&bytes[at..at + 8]));
            let data = &bytes[at + 12..at + 12 + len];
            let dcrc = u32::from_le_bytes(bytes[at + 12 + len..at + 16 + len].try_into().unwrap());
            assert_eq!(dcrc, masked_crc(data));
            at += 16 + len;
            n += 1;
        }
        assert_eq!(n, 2);
        let text = String::from_utf8_lossy(&bytes);
        assert!(text.contains("losses/qf_loss") && !text.contains("charts/sps"));
        std::fs::remove_dir_all(&dir).ok();
    }

    /// A resume at a checkpoint's step drops the interrupted process's events past it from
    /// the earlier event files (issue 72, item 8: they stayed), and a torn last record.
    #[test]
    fn a_resume_drops_the_events_past_its_checkpoint() {
        let dir = std::env::temp_dir().join(format!("smile-tb-resume-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        {
            let mut log = MetricsLog::open_at(&dir, 0).unwrap();
            for step in [10, 20, 30, 40] {
                log.log(step, &[("charts/x", step as f64)]).unwrap();
            }
        }
        let first = std::fs::read_dir(dir.join("tb"))
            .unwrap()
            .next()
            .unwrap()
            .unwrap()
            .path();
        let mut torn = std::fs::read(&first).unwrap();
        torn.extend_from_slice(&[7, 0, 0]);
        std::fs::write(&first, &torn).unwrap();
        let steps = |bytes: &[u8]| {
            let mut out = Vec::new();
            let mut at = 0;
            while at + 12 <= bytes.len() {
                let len = u64::from_le_bytes(bytes[at..at + 8].try_into().unwrap()) as usize;
                out.push(event_step(&bytes[at + 12..at + 12 + len]).unwrap());
                at += 16 + len;
            }
            out
        };
        assert_eq!(
            steps(&std::fs::read(&first).unwrap()[..torn.len() - 3]),
            [0, 10, 20, 30, 40]
        );
        let _resumed = MetricsLog::open_at(&dir, 20).unwrap();
        assert_eq!(steps(&std::fs::read(&first).unwrap()), [0, 10, 20]);
        let log = std::fs::read_to_string(dir.join(METRICS_FILE)).unwrap();
        assert_eq!(log.lines().count(), 2);
        std::fs::remove_dir_all(&dir).ok();
    }
}
