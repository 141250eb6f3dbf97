//! Runs a peer's Python script for a bench: probes that `python3` (or
//! `SLSCAN_PYTHON`) can import the peer's package, runs
//! `benches/peers/<script> DIR RUNS` and parses the one JSON line it prints.
//! `Err` says why the peer did not run, for the bench to print in its row.

use std::path::Path;
use std::process::Command;

/// The peer's JSON report, or why there is none.
pub fn run_peer(
    package: &str,
    pip_name: &str,
    script: &str,
    dir: &Path,
    runs: usize,
) -> Result<serde_json::Value, String> {
    let python = std::env::var("SLSCAN_PYTHON").unwrap_or_else(|_| "python3".into());
    let probe = Command::new(&python)
        .args(["-c", &format!("import {package}")])
        .output()
        .map_err(|e| format!("{python} not runnable: {e}"))?;
    if !probe.status.success() {
        return Err(format!(
            "{package} not importable by {python} (pip install {pip_name})"
        ));
    }
    let script = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("benches/peers")
        .join(script);
    let out = Command::new(&python)
        .arg(&script)
        .arg(dir)
        .arg(runs.to_string())
        .output()
        .map_err(|e| format!("{python} failed to start: {e}"))?;
    if !out.status.success() {
        return Err(format!(
            "peer failed: {}",
            String::from_utf8_lossy(&out.stderr).trim()
        ));
    }
    serde_json::from_slice(&out.stdout).map_err(|e| format!("peer's report: {e}"))
}
