//! The files one run of a command writes: cleared of an earlier run's before
//! the command touches any device, and discarded when the run fails, so no
//! output on disk is ever stale or from a failed run.

use std::path::{Path, PathBuf};

/// An output path that cannot be cleared.
#[derive(Debug, thiserror::Error)]
#[error("output {path}: {source}")]
pub struct OutputSetError {
    /// The path.
    pub path: PathBuf,
    /// Why (kind `AlreadyExists` for a path that is not a regular file).
    pub source: std::io::Error,
}

/// Every file a command's run may write.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct OutputSet {
    paths: Vec<PathBuf>,
}

impl OutputSet {
    /// The set of `paths`.
    pub fn new(paths: impl IntoIterator<Item = PathBuf>) -> Self {
        OutputSet {
            paths: paths.into_iter().collect(),
        }
    }

    /// The files `names` inside `dir`.
    pub fn in_dir<S: AsRef<str>>(dir: &Path, names: impl IntoIterator<Item = S>) -> Self {
        Self::new(names.into_iter().map(|n| dir.join(n.as_ref())))
    }

    /// Adds `other`'s paths.
    pub fn with(mut self, other: OutputSet) -> Self {
        self.paths.extend(other.paths);
        self
    }

    /// The paths, in order.
    pub fn paths(&self) -> &[PathBuf] {
        &self.paths
    }

    /// Checks every path first (absent or a regular file; a symlink, folder
    /// or device is an error and nothing is removed), then removes the
    /// earlier run's files.
    pub fn clear(&self) -> Result<(), OutputSetError> {
        for path in &self.paths {
            super::check_replaceable(path).map_err(|source| OutputSetError {
                path: path.clone(),
                source,
            })?;
        }
        for path in &self.paths {
            match std::fs::remove_file(path) {
                Ok(()) => tracing::info!(path = %path.display(), "removed an earlier run's output"),
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
                Err(source) => {
                    return Err(OutputSetError {
                        path: path.clone(),
                        source,
                    })
                }
            }
        }
        Ok(())
    }

    /// After a failed run: removes whichever of the files this run wrote
    /// (regular files only; best effort, a failure to remove is logged).
    pub fn discard(&self) {
        for path in &self.paths {
            let regular = std::fs::symlink_metadata(path).is_ok_and(|m| m.file_type().is_file());
            if regular {
                match std::fs::remove_file(path) {
                    Ok(()) => {
                        tracing::info!(path = %path.display(), "removed a failed run's output")
                    }
                    Err(e) => {
                        tracing::error!(path = %path.display(), "could not remove a failed run's output: {e}")
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dir(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("slscan-outset-{}-{name}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn clear_removes_only_the_named_files_and_discard_only_regular_ones() {
        let d = dir("clear");
        for name in ["cloud.ply", "depth.png", "notes.txt"] {
            std::fs::write(d.join(name), b"old").unwrap();
        }
        let set = OutputSet::in_dir(&d, ["cloud.ply", "depth.png", "report.json"]);
        set.clear().unwrap();
        let left: Vec<_> = std::fs::read_dir(&d)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(left, ["notes.txt"]);
        std::fs::write(d.join("cloud.ply"), b"half").unwrap();
        set.discard();
        assert!(!d.join("cloud.ply").exists());
        std::fs::remove_dir_all(&d).unwrap();
        // No folder at all is fine.
        set.clear().unwrap();
    }

    #[cfg(unix)]
    #[test]
    fn a_symlink_among_the_outputs_stops_clear_before_anything_is_removed() {
        let d = dir("link");
        std::fs::write(d.join("a.ply"), b"old").unwrap();
        std::fs::write(d.join("elsewhere"), b"keep").unwrap();
        std::os::unix::fs::symlink(d.join("elsewhere"), d.join("b.ply")).unwrap();
        let set = OutputSet::in_dir(&d, ["a.ply", "b.ply"]);
        let err = set.clear().unwrap_err();
        assert!(err.to_string().contains("symlink"), "{err}");
        assert!(d.join("a.ply").exists(), "nothing removed before the check");
        set.discard();
        assert!(
            std::fs::symlink_metadata(d.join("b.ply")).is_ok(),
            "a link is never removed"
        );
        assert_eq!(std::fs::read(d.join("elsewhere")).unwrap(), b"keep");
        std::fs::remove_dir_all(&d).unwrap();
    }
}
