//! The line between the product and its simulator: no file of `host/src`
//! outside `host/src/sim/` names `hil_sim` (the `sim` feature's module is the
//! only door), so `--no-default-features` builds the product alone.

use std::path::{Path, PathBuf};

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).expect("readable source folder") {
        let path = entry.expect("directory entry").path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// Files under `src` outside `src/sim` whose text names the crate `hil_sim`
/// (a `use`, a path, or a doc link into it).
fn crossings(src: &Path) -> Vec<String> {
    let sim = src.join("sim");
    let mut files = Vec::new();
    rust_files(src, &mut files);
    files
        .iter()
        .filter(|f| !f.starts_with(&sim))
        .filter(|f| {
            let text = std::fs::read_to_string(f).expect("readable source file");
            text.contains("hil_sim")
        })
        .map(|f| f.display().to_string())
        .collect()
}

#[test]
fn only_the_sim_module_names_hil_sim() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let found = crossings(&src);
    assert!(
        found.is_empty(),
        "these files reach into hil-sim outside host/src/sim/: {found:?}"
    );
    // The check finds a crossing when there is one.
    let sim_files = {
        let mut v = Vec::new();
        rust_files(&src.join("sim"), &mut v);
        v
    };
    assert!(sim_files
        .iter()
        .any(|f| std::fs::read_to_string(f).unwrap().contains("hil_sim")));
}

#[test]
fn the_check_catches_a_crossing() {
    let dir = std::env::temp_dir().join(format!("slscan-boundary-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(dir.join("sim")).unwrap();
    std::fs::create_dir_all(dir.join("scan")).unwrap();
    std::fs::write(dir.join("sim/ok.rs"), "use hil_sim::twin::Rig;\n").unwrap();
    std::fs::write(dir.join("scan/clean.rs"), "use crate::rig::Board;\n").unwrap();
    assert!(crossings(&dir).is_empty());
    std::fs::write(dir.join("scan/bad.rs"), "use hil_sim::twin::TwinRig;\n").unwrap();
    let found = crossings(&dir);
    assert_eq!(found.len(), 1);
    assert!(found[0].ends_with("bad.rs"), "{found:?}");
    let _ = std::fs::remove_dir_all(&dir);
}
