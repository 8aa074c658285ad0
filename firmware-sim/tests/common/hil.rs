//! What the hardware-in-the-loop tests read back from `firmware-sim host` and `run`: the
//! trace's columns and `hil.json`.

use std::path::Path;

/// The columns of `trace.csv` in `dir` whose names start with `prefix`, row by row.
pub fn columns(dir: &Path, prefixes: &[&str]) -> Vec<Vec<String>> {
    let text = std::fs::read_to_string(dir.join("trace.csv")).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let keep: Vec<usize> = (0..header.len())
        .filter(|&i| prefixes.iter().any(|p| header[i].starts_with(p)))
        .collect();
    assert!(!keep.is_empty());
    lines
        .map(|l| {
            let cells: Vec<&str> = l.split(',').collect();
            keep.iter().map(|&i| cells[i].to_string()).collect()
        })
        .collect()
}

/// `hil.json` in `dir`, parsed.
pub fn hil_json(dir: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(dir.join("hil.json")).unwrap()).unwrap()
}
