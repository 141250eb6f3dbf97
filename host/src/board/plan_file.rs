//! Scan plans as JSON files: `protocol::ScanPlan` through serde, read for
//! `slscan board run-plan PLAN.json`, written atomically.

use std::path::{Path, PathBuf};

use protocol::ScanPlan;

/// A plan file could not be read or written.
#[derive(Debug, thiserror::Error)]
pub enum PlanFileError {
    /// The file could not be read.
    #[error("could not read plan file {path}")]
    Read {
        /// The file.
        path: PathBuf,
        /// The OS error.
        source: std::io::Error,
    },
    /// The file is not a valid plan (syntax, missing field, over capacity).
    #[error("plan file {path} is not a valid plan")]
    Parse {
        /// The file.
        path: PathBuf,
        /// Where and why (line and column included).
        source: serde_json::Error,
    },
    /// The file could not be written.
    #[error("could not write plan file {path}")]
    Write {
        /// The file.
        path: PathBuf,
        /// The OS error.
        source: std::io::Error,
    },
}

/// Reads a plan from a JSON file. Capacities (heads, exposures, slots) are
/// checked while parsing; timing is validated by the board (or by
/// `ScanPlan::validate`).
pub fn load_plan(path: &Path) -> Result<ScanPlan, PlanFileError> {
    let text = std::fs::read_to_string(path).map_err(|source| PlanFileError::Read {
        path: path.to_path_buf(),
        source,
    })?;
    parse_plan(&text).map_err(|source| PlanFileError::Parse {
        path: path.to_path_buf(),
        source,
    })
}

/// Parses a plan from JSON text.
pub fn parse_plan(text: &str) -> Result<ScanPlan, serde_json::Error> {
    serde_json::from_str(text)
}

/// The plan as pretty JSON, newline-terminated.
pub fn plan_to_json(plan: &ScanPlan) -> String {
    // Plain data with string keys: serialising cannot fail.
    let mut text = serde_json::to_string_pretty(plan).unwrap_or_default();
    text.push('\n');
    text
}

/// Writes `plan` to `path` through a temporary file and a rename, so a
/// reader never sees half a plan.
pub fn save_plan(path: &Path, plan: &ScanPlan) -> Result<(), PlanFileError> {
    let write_err = |source| PlanFileError::Write {
        path: path.to_path_buf(),
        source,
    };
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(".tmp");
    let tmp = PathBuf::from(tmp);
    std::fs::write(&tmp, plan_to_json(plan)).map_err(write_err)?;
    std::fs::rename(&tmp, path).map_err(write_err)
}

/// The example plan files shipped in `host/examples/plans/`, by file name,
/// generated from `protocol::plan::examples`.
pub fn example_plans() -> Vec<(&'static str, ScanPlan)> {
    use protocol::plan::examples;
    vec![
        ("dual_head_psp.json", examples::dual_head_psp(2)),
        ("head_a_only.json", examples::head_only(0, 1)),
        ("head_b_only.json", examples::head_only(1, 1)),
        (
            "multiplexed_24_at_5khz.json",
            examples::multiplexed_24_at_5khz(3),
        ),
        ("flood_preliminaries.json", examples::flood_preliminaries(1)),
        // Issue 21: a rig of three heads, which a board of 4 trigger lines
        // refuses before anything is sent.
        ("three_head_psp.json", examples::all_heads_psp(3, 1)),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn examples_dir() -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/plans")
    }

    /// The shipped files equal the protocol's examples; `REGENERATE=1`
    /// rewrites them.
    #[test]
    fn example_plan_files_match_protocol_examples() {
        let dir = examples_dir();
        for (name, plan) in example_plans() {
            let path = dir.join(name);
            if std::env::var_os("REGENERATE").is_some() {
                std::fs::create_dir_all(&dir).unwrap();
                save_plan(&path, &plan).unwrap();
            }
            let loaded =
                load_plan(&path).unwrap_or_else(|e| panic!("{e} (REGENERATE=1 writes it)"));
            assert_eq!(loaded, plan, "{name} differs from protocol::plan::examples");
        }
    }

    #[test]
    fn json_round_trips() {
        for (_, plan) in example_plans() {
            assert_eq!(parse_plan(&plan_to_json(&plan)).unwrap(), plan);
        }
    }

    #[test]
    fn bad_files_are_typed_errors_naming_the_file() {
        let dir = std::env::temp_dir().join(format!("slscan-plan-file-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let missing = dir.join("missing.json");
        assert!(matches!(
            load_plan(&missing),
            Err(PlanFileError::Read { .. })
        ));

        let broken = dir.join("broken.json");
        std::fs::write(&broken, "{\"heads\": [").unwrap();
        let err = load_plan(&broken).unwrap_err();
        assert!(matches!(err, PlanFileError::Parse { .. }));
        assert!(err.to_string().contains("broken.json"), "{err:?}");

        // One head past the plan's capacity (MAX_HEADS) is caught while
        // parsing; how many the board drives is checked on upload.
        let mut value: serde_json::Value =
            serde_json::from_str(&plan_to_json(&protocol::plan::examples::dual_head_psp(1)))
                .unwrap();
        let head = value["heads"][0].clone();
        while value["heads"].as_array().unwrap().len() <= protocol::limits::MAX_HEADS {
            value["heads"].as_array_mut().unwrap().push(head.clone());
        }
        let too_many = dir.join("too_many.json");
        std::fs::write(&too_many, value.to_string()).unwrap();
        assert!(matches!(
            load_plan(&too_many),
            Err(PlanFileError::Parse { .. })
        ));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
